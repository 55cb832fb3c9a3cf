"""Model definition: named parameters and user-written state-space models."""

from flightid.model.parameters import Parameter, Parameters
from flightid.model.statespace import StateSpaceModel

__all__ = ["Parameter", "Parameters", "StateSpaceModel"]
