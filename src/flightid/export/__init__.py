"""Exports of identified models to simulators and other tools."""
