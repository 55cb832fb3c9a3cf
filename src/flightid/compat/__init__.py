"""Flight-path reconstruction (data compatibility): the rigid-body kinematic model with
sensor biases, scale factors and time delays, and the reconstructed signals it yields
(docs/compat.md)."""

from flightid.compat.kinematic import (
    DEFAULT_STATES,
    GROUND_OUTPUTS,
    OUTPUTS,
    QUANTITIES,
    RATE_DERIVATIVES,
    SENSOR_INPUTS,
    WIND,
    KinematicSpec,
    kinematic_model,
    kinematic_spec,
)

__all__ = [
    "DEFAULT_STATES",
    "GROUND_OUTPUTS",
    "OUTPUTS",
    "QUANTITIES",
    "RATE_DERIVATIVES",
    "SENSOR_INPUTS",
    "WIND",
    "KinematicSpec",
    "kinematic_model",
    "kinematic_spec",
]
