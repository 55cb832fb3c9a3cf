"""Model definition: named parameters and user-written state-space models."""

from flightid.model.check import ModelCheck, check_model
from flightid.model.parameters import Parameter, Parameters
from flightid.model.statespace import StateSpaceModel

__all__ = ["ModelCheck", "Parameter", "Parameters", "StateSpaceModel", "check_model"]
