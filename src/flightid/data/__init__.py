"""Flight data: the validated ``FlightData`` container (loaders live beside it)."""

from flightid.data.flightdata import FlightData

__all__ = ["FlightData"]
