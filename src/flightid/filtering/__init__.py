"""Kalman filters used by estimators: the steady-state gain of the filter error method."""

from flightid.filtering.kalman import (
    RiccatiError,
    linearise,
    potter_solution,
    riccati_solution,
    steady_state_gain,
)

__all__ = [
    "RiccatiError",
    "linearise",
    "potter_solution",
    "riccati_solution",
    "steady_state_gain",
]
