"""Airplanes: definition, 6-DOF, decoupled and α–q equations of motion, aerodynamic models.

from flightid.aircraft import Airplane, AeroModel, lateral_model, navion
aero = AeroModel({"CY": ["beta", "rhat", "dr"], "Cl": ["beta", "phat", "da"], ...})
model = lateral_model(navion(), aero, aero.parameters({"Cl_beta": -0.1, ...}), x0=...)
"""

from flightid.aircraft.accelerometer import Accelerometer
from flightid.aircraft.aero import COEFFICIENTS, AeroModel, AeroTables, parameter_name
from flightid.aircraft.airplane import Airplane
from flightid.aircraft.equations import (
    ALPHA_Q_INPUTS,
    ALPHA_Q_OUTPUTS,
    BODY_STATES,
    OUTPUTS,
    SIGNALS,
)
from flightid.aircraft.library import airplane_from_table, navion, navion_longitudinal_aero
from flightid.aircraft.models import (
    alpha_q_longitudinal_model,
    lateral_model,
    longitudinal_model,
    six_dof_model,
    wind_axis_longitudinal_model,
)
from flightid.aircraft.trim import TrimPoint, body_state, trim_level_flight
from flightid.model.terms import TermError

__all__ = [
    "ALPHA_Q_INPUTS",
    "ALPHA_Q_OUTPUTS",
    "Accelerometer",
    "AeroModel",
    "AeroTables",
    "Airplane",
    "BODY_STATES",
    "COEFFICIENTS",
    "OUTPUTS",
    "SIGNALS",
    "TermError",
    "TrimPoint",
    "airplane_from_table",
    "alpha_q_longitudinal_model",
    "body_state",
    "lateral_model",
    "longitudinal_model",
    "navion",
    "navion_longitudinal_aero",
    "parameter_name",
    "six_dof_model",
    "trim_level_flight",
    "wind_axis_longitudinal_model",
]
