"""The α–q longitudinal output-error model of a case (``[model] type = "alpha_q"``).

α and q are integrated and V, q̄, θ, φ, a_x (g), p, r are measured inputs (the standard
SIDPAC-style longitudinal case; body axes, β ≈ 0, thrust carried by the measured a_x;
RP-1153 §2.A). The model is ``flightid.aircraft.alpha_q_longitudinal_model``, whose equations
(``flightid.aircraft.equations``) are

    α̇ = q + (q̄ S /(m V)) C_Z cos α − (g a_x / V) sin α + (g / V)(cos φ cos θ cos α + sin θ sin α)
    q̇ = (q̄ S c̄ C_m + (I_z − I_x) p r + I_xz (r² − p²)) / I_y                    [2.9]
    outputs α, q, a_z = q̄ S C_Z / (m g)                                          [2.26]

with C_Z, C_m linear in their parameters over the selected terms [2.16–2.18]; the term
signals are α (state, rad), q̂ = q c̄/(2V) (state q and measured V) and any measured input
channel (controls in rad). The α̇ line is (u ẇ − w u̇)/V² with u = V cos α, w = V sin α
and the body-axis force equations [2.5], [2.7] of RP-1153, in which (q̄S/m) C_X = g a_x.

This module is the adapter from the case to that builder: the structure (terms of C_Z and
C_m) becomes an ``flightid.aircraft.AeroModel`` and the constants an
``flightid.aircraft.Airplane``. The structure comes from ``[model.aero]`` or, with
``from = "previous"``, from the stepwise / regression stage before the output-error stage
(``flightid.regression.pipeline.LinearAeroStructure``). The constants (``[model.constants]``:
mass, S, cbar, Iy, g, optional Ix, Iz, Ixz, in the data's unit system) are numbers, or
column names / {column = N} whose mean over the first maneuver's file is taken.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from flightid.aircraft import ALPHA_Q_INPUTS, AeroModel, Airplane, alpha_q_longitudinal_model
from flightid.cases.checks import CaseError
from flightid.data.loaders import read_table
from flightid.data.units import G0
from flightid.errors import InputError
from flightid.model.parameters import Parameter, Parameters
from flightid.model.statespace import StateSpaceModel
from flightid.model.terms import parse_term
from flightid.regression.pipeline import LinearAeroStructure, parameter_name

__all__ = [
    "ALPHA_Q_INPUTS",
    "alpha_q_aero",
    "alpha_q_airplane",
    "alpha_q_constants",
    "alpha_q_model",
    "structure_from_terms",
    "zero_parameters",
]


def alpha_q_airplane(
    *,
    mass: float,
    S: float,
    cbar: float,
    Iy: float,
    Ix: float | None = None,
    Iz: float | None = None,
    Ixz: float = 0.0,
    g: float = G0,
    name: str = "alpha_q",
) -> Airplane:
    """The ``Airplane`` of the α–q model from the case constants (one consistent unit system).

    Ix and Iz enter the α–q equations only as I_z − I_x: give both, or neither (then
    I_x = I_z = I_y, so (I_z − I_x) p r = 0). The span b is not used by the α–q model and is
    set to c̄ (an ``Airplane`` needs a positive one).
    """
    if (Ix is None) != (Iz is None):
        given, absent = ("Ix", "Iz") if Iz is None else ("Iz", "Ix")
        raise InputError(
            f"{absent}: expected both Ix and Iz or neither (the α–q model uses I_z − I_x), "
            f"got {given} only"
        )
    if Ix is None:
        # I_x = I_z: the (I_z − I_x) p r term of q̇ vanishes, as with no inertias given
        Ix = Iz = Iy
    return Airplane(mass=mass, Ix=Ix, Iy=Iy, Iz=Iz, Ixz=Ixz, S=S, b=cbar, cbar=cbar, g=g, name=name)


def alpha_q_aero(structure: LinearAeroStructure) -> AeroModel:
    """The ``AeroModel`` of ``structure`` (CZ and Cm); its parameter names are the
    structure's (``parameter_name``: ``Cm_alpha``, ``CZ_qhat``…)."""
    for coef in ("CZ", "Cm"):
        if coef not in structure.terms:
            raise InputError(
                f"structure: expected a {coef!r} coefficient, got {list(structure.terms)}"
            )
    aero = AeroModel({c: [t for _, t in entries] for c, entries in structure.terms.items()})
    if aero.parameter_names != structure.parameter_names:
        raise InputError(
            f"structure: parameter names {structure.parameter_names} differ from the "
            f"aerodynamic model's {aero.parameter_names}"
        )
    return aero


def alpha_q_model(
    structure: LinearAeroStructure,
    parameters: Parameters,
    *,
    mass: float,
    S: float,
    cbar: float,
    Iy: float,
    Ix: float | None = None,
    Iz: float | None = None,
    Ixz: float = 0.0,
    g: float = G0,
    x0: Sequence[float | str] = (0.0, 0.0),
    name: str = "alpha_q_longitudinal",
) -> StateSpaceModel:
    """Longitudinal α–q model with C_Z and C_m from ``structure`` (see module docstring):
    ``flightid.aircraft.alpha_q_longitudinal_model`` of ``alpha_q_airplane(...)`` and
    ``alpha_q_aero(structure)``.

    Args:
        structure: must define "CZ" and "Cm" (no other coefficient); their terms may use
            ``alpha``, ``qhat`` and any input channel (e.g. ``de`` in rad).
        parameters: values for every parameter of the structure (others are allowed).
        mass, S, cbar, Iy, Ix, Iz, Ixz, g: constants in one consistent unit system (Ix and
            Iz both or neither, ``alpha_q_airplane``).
        x0: initial (α rad, q rad/s), numbers or parameter names.

    Inputs (channels the data must carry): ``ALPHA_Q_INPUTS`` — V, q̄, θ (rad), φ (rad),
    a_x (g), p, r (rad/s) — followed by the term signals other than alpha, qhat and those.
    """
    airplane = alpha_q_airplane(
        mass=mass, S=S, cbar=cbar, Iy=Iy, Ix=Ix, Iz=Iz, Ixz=Ixz, g=g, name=name
    )
    aero = alpha_q_aero(structure)
    missing = sorted(set(structure.parameter_names) - set(parameters.names))
    if missing:
        raise InputError(f"parameters: no values for {missing}")
    return alpha_q_longitudinal_model(airplane, aero, parameters, x0=tuple(x0), name=name)


def structure_from_terms(aero: Mapping[str, Sequence[str]]) -> LinearAeroStructure:
    """The structure of ``[model.aero]`` ({coefficient: [terms]}) with parameter names
    ``parameter_name(coefficient, term)``."""
    return LinearAeroStructure(
        {
            coefficient: tuple((parameter_name(coefficient, t), parse_term(t)) for t in terms)
            for coefficient, terms in aero.items()
        }
    )


def zero_parameters(structure: LinearAeroStructure) -> Parameters:
    """Free parameters of the structure, each starting at 0 ([parameters] sets start values)."""
    return Parameters([Parameter(name, 0.0) for name in structure.parameter_names])


def alpha_q_constants(
    constants: Mapping[str, Any], first_file: Path, file_format: str = "auto", variable=None
) -> dict[str, float]:
    """``[model.constants]``: numbers as given; columns (by name or ``{column = N}``) as their
    mean over ``first_file`` (the first maneuver's data file)."""
    values: dict[str, float] = {}
    table = None
    for name, value in constants.items():
        if isinstance(value, (int, float)):
            values[name] = float(value)
            continue
        column = value["column"] if isinstance(value, Mapping) else value
        try:
            table = table or read_table(first_file, file_format, variable=variable)
            values[name] = float(np.mean(table.column(column, f"model.constants.{name}")))
        except InputError as exc:
            message = str(exc)
            if not message.startswith("model.constants"):
                message = f"model.constants.{name}: {message}"
            raise CaseError(message) from None
    return values
