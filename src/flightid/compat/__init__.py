"""Flight-path reconstruction (data compatibility): the rigid-body kinematic model with
sensor biases, scale factors and time delays, and the reconstructed signals it yields
(docs/compat.md)."""

from flightid.compat.kinematic import (
    OUTPUTS,
    QUANTITIES,
    RATE_DERIVATIVES,
    SENSOR_INPUTS,
    KinematicSpec,
    kinematic_model,
    kinematic_spec,
)

__all__ = [
    "OUTPUTS",
    "QUANTITIES",
    "RATE_DERIVATIVES",
    "SENSOR_INPUTS",
    "KinematicSpec",
    "kinematic_model",
    "kinematic_spec",
]
