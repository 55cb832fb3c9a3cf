"""From stepwise regression to maximum likelihood (RP-1153 stages 2 → 3).

Stepwise regression (equation error) picks the terms of each aerodynamic coefficient and
gives their least-squares estimates; these become the structure and the start values of the
output-error ML estimation, which removes the bias that noisy regressors cause in least
squares [3.28–3.30].

Parameter names: coefficient name, underscore, term label with "*" → "_" and "^k" → "k",
the constant term "1" → "0": ("Cm", "alpha") → ``Cm_alpha``, ("Cm", "1") → ``Cm_0``,
("CZ", "alpha*de") → ``CZ_alpha_de``, ("CZ", "alpha^2") → ``CZ_alpha2``.

``alpha_q_model`` builds the longitudinal model in which α and q are integrated and the other
variables are measured inputs (the standard SIDPAC-style longitudinal case; body axes,
β ≈ 0, thrust carried by the measured a_x, METHOD §3):

    α̇ = q + (q̄ S /(m V)) C_Z cos α − (g a_x / V) sin α + (g / V)(cos φ cos θ cos α + sin θ sin α)
    q̇ = (q̄ S c̄ C_m + (I_z − I_x) p r + I_xz (r² − p²)) / I_y                    [§3, dq/dt]
    outputs α, q, a_z = q̄ S C_Z / (m g)                                          [2.26]

with C_Z, C_m linear in their parameters over the selected terms [2.16–2.18]; the term
signals are α (state, rad), q̂ = q c̄/(2V) (state q and measured V) and any measured input
channel (controls in rad). The α̇ line is (u ẇ − w u̇)/V² with u = V cos α, w = V sin α
and the body-axis force equations of §3, in which (q̄S/m) C_X = g a_x.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from flightid.errors import InputError
from flightid.model.parameters import Parameter, Parameters
from flightid.model.statespace import StateSpaceModel
from flightid.model.terms import Term, parse_term
from flightid.regression.stepwise import StepwiseResult

__all__ = [
    "parameter_name",
    "LinearAeroStructure",
    "starting_parameters",
    "alpha_q_model",
    "PipelineResult",
    "regression_to_ml",
    "ALPHA_Q_INPUTS",
]

# Measured channels the α–q model reads (besides the controls its terms use).
ALPHA_Q_INPUTS = ("V", "qbar", "theta", "phi", "ax", "p", "r")


def parameter_name(coefficient: str, term: str | Term) -> str:
    """Identifier of the parameter multiplying ``term`` in ``coefficient`` (module docstring)."""
    term = parse_term(term) if isinstance(term, str) else term
    name = f"{coefficient}_{term.identifier}"
    if not name.isidentifier():
        raise InputError(f"coefficient: {coefficient!r} does not make a valid parameter name")
    return name


@dataclass(frozen=True)
class LinearAeroStructure:
    """Terms of each coefficient with their parameter names: {coef: ((name, Term), ...)}."""

    terms: Mapping[str, tuple[tuple[str, Term], ...]]

    @classmethod
    def from_stepwise(cls, results: Mapping[str, StepwiseResult]) -> LinearAeroStructure:
        terms = {
            coef: tuple((parameter_name(coef, t), t) for t in result.selected_terms)
            for coef, result in results.items()
        }
        names = [n for entries in terms.values() for n, _ in entries]
        repeated = sorted({n for n in names if names.count(n) > 1})
        if repeated:
            raise InputError(f"results: parameter names collide: {repeated}")
        return cls(terms)

    @property
    def parameter_names(self) -> list[str]:
        return [n for entries in self.terms.values() for n, _ in entries]

    def signals(self) -> list[str]:
        """All signal names used by the terms, in first-use order."""
        seen: list[str] = []
        for entries in self.terms.values():
            for _, term in entries:
                for s in term.signals:
                    if s not in seen:
                        seen.append(s)
        return seen


def starting_parameters(results: Mapping[str, StepwiseResult]) -> Parameters:
    """Free parameters valued at the regression estimates.

    Each parameter's ``scale`` (typical magnitude: first perturbation size and convergence
    floor of the ML step) is max(|θ̂|, σ̂) with σ̂ the regression standard error, so a
    parameter estimated near zero is still perturbed by a statistically meaningful amount.
    """
    params = []
    for coef, result in results.items():
        for label, value, std in zip(
            result.fit.names, result.fit.estimates, result.fit.std, strict=True
        ):
            scale = max(abs(float(value)), float(std)) if np.isfinite(std) else None
            params.append(Parameter(parameter_name(coef, label), float(value), scale=scale or None))
    return Parameters(params)


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
    g: float = 9.80665,
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


@dataclass(frozen=True, eq=False)
class PipelineResult:
    """Stepwise results, the structure and start values derived from them, and the ML estimate."""

    regression: Mapping[str, StepwiseResult]
    structure: LinearAeroStructure
    start: Parameters
    model: StateSpaceModel
    estimate: object  # flightid.estimation.Estimate

    def comparison(self) -> str:
        """Table: regression estimate ± std next to ML estimate ± Cramér–Rao bound."""
        est = self.estimate
        lines = [
            f"{'parameter':<16s}{'regression':>14s}{'std':>11s}{'ML':>14s}{'CR bound':>11s}",
        ]
        for coef, entries in self.structure.terms.items():
            fit = self.regression[coef].fit
            for name, term in entries:
                value, std = fit.parameter(term.label)
                j = list(est.names).index(name)
                lines.append(
                    f"{name:<16s}{value:>14.6g}{std:>11.3g}{est.values[j]:>14.6g}"
                    f"{est.std[j]:>11.3g}"
                )
        return "\n".join(lines)


def regression_to_ml(
    results: Mapping[str, StepwiseResult],
    build_model: Callable[[LinearAeroStructure, Parameters], StateSpaceModel],
    data,
    **estimate_options,
) -> PipelineResult:
    """Seed output-error ML with the stepwise structure and estimates, and run it.

    Args:
        results: stepwise results per coefficient (e.g. from ``run_case``).
        build_model: ``(structure, start_parameters) -> StateSpaceModel``, e.g. a closure
            around ``alpha_q_model`` with the airplane's constants.
        data: ``FlightData`` or a list of them (outputs and inputs of the model).
        **estimate_options: passed to ``flightid.estimation.estimate`` (solver, noise, ...).
    """
    from flightid.estimation import estimate

    structure = LinearAeroStructure.from_stepwise(results)
    start = starting_parameters(results)
    model = build_model(structure, start)
    result = estimate(model, data, **estimate_options)
    return PipelineResult(dict(results), structure, start, model, result)


def fit_statistics(
    measured: np.ndarray, predicted: np.ndarray, names: Sequence[str]
) -> dict[str, dict[str, float]]:
    """Per output: RMS error √(mean ν²) and R² = 1 − Σν² / Σ(z − z̄)² of a time-history match.

    Args:
        measured, predicted: (N, n_o) in the outputs' units.
        names: output names.
    """
    measured = np.asarray(measured, dtype=float)
    predicted = np.asarray(predicted, dtype=float)
    if measured.shape != predicted.shape or measured.ndim != 2:
        raise InputError(
            f"measured, predicted: expected two (N, n_o) arrays of the same shape, got "
            f"{measured.shape} and {predicted.shape}"
        )
    out = {}
    for j, name in enumerate(names):
        residual = measured[:, j] - predicted[:, j]
        spread = measured[:, j] - measured[:, j].mean()
        out[name] = {
            "rms": float(np.sqrt(np.mean(residual**2))),
            "r2": float(1.0 - residual @ residual / (spread @ spread)),
        }
    return out
