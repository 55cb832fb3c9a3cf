"""From stepwise regression to maximum likelihood (RP-1153 stages 2 → 3).

Stepwise regression (equation error) picks the terms of each aerodynamic coefficient and
gives their least-squares estimates; these become the structure and the start values of the
output-error ML estimation, which removes the bias that noisy regressors cause in least
squares [3.28–3.30].

Parameter names: coefficient name, underscore, term label with "*" → "_" and "^k" → "k",
the constant term "1" → "0": ("Cm", "alpha") → ``Cm_alpha``, ("Cm", "1") → ``Cm_0``,
("CZ", "alpha*de") → ``CZ_alpha_de``, ("CZ", "alpha^2") → ``CZ_alpha2``.

The α–q output-error model these start values feed is built in ``flightid.cases.alpha_q``
(``alpha_q_model``); ``regression`` fits regressions and knows nothing about simulation.
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
    "PipelineResult",
    "regression_to_ml",
]


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


@dataclass(frozen=True, eq=False)
class PipelineResult:
    """Stepwise results, the structure and start values derived from them, and the ML estimate."""

    regression: Mapping[str, StepwiseResult]
    structure: LinearAeroStructure
    start: Parameters
    model: StateSpaceModel
    estimate: object  # flightid.estimation.Estimate

    def comparison(self) -> str:
        """Table: regression estimate ± std next to ML estimate ± its default σ."""
        est = self.estimate
        lines = [
            f"{'parameter':<16s}{'regression':>14s}{'std':>11s}{'ML':>14s}{'ML σ':>11s}",
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
            around ``flightid.cases.alpha_q.alpha_q_model`` with the airplane's constants.
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
