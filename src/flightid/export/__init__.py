"""Exports of an identified model: flying-quality checks and equivalent systems."""
