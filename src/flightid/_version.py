"""The flightid version string, in the small shared core so that every layer may read it."""

__version__ = "0.1.0"
