"""The α–q longitudinal output-error model of a case (``[model] type = "alpha_q"``).

α and q are integrated and the other variables are measured inputs (the standard
SIDPAC-style longitudinal case; body axes, β ≈ 0, thrust carried by the measured a_x,
METHOD §3):

    α̇ = q + (q̄ S /(m V)) C_Z cos α − (g a_x / V) sin α + (g / V)(cos φ cos θ cos α + sin θ sin α)
    q̇ = (q̄ S c̄ C_m + (I_z − I_x) p r + I_xz (r² − p²)) / I_y                    [§3, dq/dt]
    outputs α, q, a_z = q̄ S C_Z / (m g)                                          [2.26]

with C_Z, C_m linear in their parameters over the selected terms [2.16–2.18]; the term
signals are α (state, rad), q̂ = q c̄/(2V) (state q and measured V) and any measured input
channel (controls in rad). The α̇ line is (u ẇ − w u̇)/V² with u = V cos α, w = V sin α
and the body-axis force equations of §3, in which (q̄S/m) C_X = g a_x.

The structure (terms of C_Z and C_m) comes from ``[model.aero]`` or, with
``from = "previous"``, from the stepwise / regression stage before the output-error stage
(``flightid.regression.pipeline.LinearAeroStructure``). The constants (``[model.constants]``:
mass, S, cbar, Iy, g, optional Ix, Iz, Ixz, in the data's unit system) are numbers, or
column names / {column = N} whose mean over the first maneuver's file is taken.
(Moved here from ``flightid.regression.pipeline``; it is not yet built from
``flightid.aircraft``.)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from flightid.cases.checks import CaseError
from flightid.data.loaders import read_table
from flightid.data.units import G0
from flightid.errors import InputError
from flightid.model.parameters import Parameter, Parameters
from flightid.model.statespace import StateSpaceModel
from flightid.model.terms import Term, parse_term
from flightid.regression.pipeline import LinearAeroStructure, parameter_name

__all__ = [
    "ALPHA_Q_INPUTS",
    "alpha_q_constants",
    "alpha_q_model",
    "structure_from_terms",
    "zero_parameters",
]

# Measured channels the α–q model reads (besides the controls its terms use).
ALPHA_Q_INPUTS = ("V", "qbar", "theta", "phi", "ax", "p", "r")


def _term_tables(
    entries: Sequence[tuple[str, Term]], signal_names: Sequence[str], parameters: Parameters
) -> tuple[np.ndarray, np.ndarray]:
    """(powers (n_terms, n_signals) int64, parameter index (n_terms,) int64)."""
    powers = np.zeros((len(entries), len(signal_names)), dtype=np.int64)
    index = np.zeros(len(entries), dtype=np.int64)
    for j, (name, term) in enumerate(entries):
        index[j] = parameters.index(name)
        for signal, power in term.factors:
            if not isinstance(signal, str):
                raise InputError(
                    f"term {term.label!r}: spline terms are not supported by the α–q "
                    "output-error model yet; use the built-in airplane models "
                    "(flightid.aircraft) for them"
                )
            powers[j, signal_names.index(signal)] = power
    return powers, index


def alpha_q_model(
    structure: LinearAeroStructure,
    parameters: Parameters,
    *,
    mass: float,
    S: float,
    cbar: float,
    Iy: float,
    Ix: float = 0.0,
    Iz: float = 0.0,
    Ixz: float = 0.0,
    g: float = G0,
    x0: Sequence[float | str] = (0.0, 0.0),
    name: str = "alpha_q_longitudinal",
) -> StateSpaceModel:
    """Longitudinal α–q model with C_Z and C_m from ``structure`` (see module docstring).

    Args:
        structure: must define "CZ" and "Cm"; their terms may use ``alpha``, ``qhat`` and any
            input channel (e.g. ``de`` in rad).
        parameters: values for every parameter of the structure (others are allowed).
        mass, S, cbar, Iy, Ix, Iz, Ixz, g: constants in one consistent unit system.
        x0: initial (α rad, q rad/s), numbers or parameter names.

    Inputs (channels the data must carry): ``ALPHA_Q_INPUTS`` — V, q̄, θ (rad), φ (rad),
    a_x (g), p, r (rad/s) — followed by the term signals other than alpha and qhat.
    """
    for coef in ("CZ", "Cm"):
        if coef not in structure.terms:
            raise InputError(
                f"structure: expected a {coef!r} coefficient, got {list(structure.terms)}"
            )
    extras = [s for s in structure.signals() if s not in ("alpha", "qhat")]
    inputs = tuple(ALPHA_Q_INPUTS) + tuple(s for s in extras if s not in ALPHA_Q_INPUTS)
    signal_names = ["alpha", "qhat", *extras]
    extra_index = np.array([inputs.index(s) for s in extras], dtype=np.int64)
    pz, iz = _term_tables(structure.terms["CZ"], signal_names, parameters)
    pm, im = _term_tables(structure.terms["Cm"], signal_names, parameters)
    n_signals = len(signal_names)
    mass, S, cbar, Iy, Ix, Iz, Ixz, g = (float(v) for v in (mass, S, cbar, Iy, Ix, Iz, Ixz, g))

    def coefficient(powers, index, sig, theta):
        # C = Σ_j θ_j Π_k sig_k^{power_jk}                                  [2.16–2.18]
        total = 0.0
        for j in range(powers.shape[0]):
            regressor = 1.0
            for k in range(powers.shape[1]):
                for _ in range(powers[j, k]):
                    regressor *= sig[k]
            total += theta[index[j]] * regressor
        return total

    def signals(x, u):
        sig = np.empty(n_signals)
        sig[0] = x[0]
        # q̂ = q c̄ / (2 V)
        sig[1] = x[1] * cbar / (2.0 * u[0])
        for k in range(extra_index.shape[0]):
            sig[2 + k] = u[extra_index[k]]
        return sig

    def f(t, x, u, theta):
        alpha = x[0]
        q = x[1]
        V, qbar, theta_e, phi, ax, p, r = u[0], u[1], u[2], u[3], u[4], u[5], u[6]
        sig = signals(x, u)
        cz = coefficient(pz, iz, sig, theta)
        cm = coefficient(pm, im, sig, theta)
        dx = np.empty(2)
        # α̇ = q + (q̄S/(mV)) C_Z cos α − (g a_x/V) sin α + (g/V)(cos φ cos θ cos α + sin θ sin α)
        dx[0] = (
            q
            + qbar * S / (mass * V) * cz * np.cos(alpha)
            - g * ax / V * np.sin(alpha)
            + g
            / V
            * (np.cos(phi) * np.cos(theta_e) * np.cos(alpha) + np.sin(theta_e) * np.sin(alpha))
        )
        # q̇ = (q̄ S c̄ C_m + (I_z − I_x) p r + I_xz (r² − p²)) / I_y
        dx[1] = (qbar * S * cbar * cm + (Iz - Ix) * p * r + Ixz * (r * r - p * p)) / Iy
        return dx

    def h(t, x, u, theta):
        qbar = u[1]
        sig = signals(x, u)
        cz = coefficient(pz, iz, sig, theta)
        y = np.empty(3)
        y[0] = x[0]
        y[1] = x[1]
        # a_z = q̄ S C_Z / (m g)                                              [2.26]
        y[2] = qbar * S * cz / (mass * g)
        return y

    try:
        import numba

        coefficient = numba.njit(cache=False)(coefficient)
        signals = numba.njit(cache=False)(signals)
    except ImportError:  # pragma: no cover - numba is a dependency
        pass
    missing = sorted(set(structure.parameter_names) - set(parameters.names))
    if missing:
        raise InputError(f"parameters: no values for {missing}")
    return StateSpaceModel(
        states=("alpha", "q"),
        inputs=inputs,
        outputs=("alpha", "q", "az"),
        f=f,
        h=h,
        parameters=parameters,
        x0=tuple(x0),
        name=name,
    )


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
