"""Pieces every Newton-type solver shares: the bounded Gauss–Newton step, the line search by
step halving (along the projected path when parameters have bounds), and stop checks.

Bounds by projected Gauss–Newton with an active set: a parameter on a bound whose step points
outwards is held (Δθ_j = 0) and the step is recomputed for the others; the trial points
θ(λ) = P(θ + λΔθ) are projected onto the box [lower, upper], so no integration ever runs
outside the bounds.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import types
import typing

import numpy as np

from flightid.errors import InputError, InputTypeError, describe
from flightid.estimation.gauss_newton import GaussNewtonStep, step_from_factor, triangular_factor
from flightid.estimation.objective import Objective

__all__ = [
    "halving_search",
    "budget_status",
    "limit_step",
    "bounded_gauss_newton_step",
    "check_setting_types",
    "named_settings",
]


def named_settings(cls: type) -> type:
    """Class decorator for a solver dataclass: an unknown keyword or too many positional
    arguments is an ``InputTypeError`` naming the solver's settings (not Python's bare
    ``TypeError`` of ``__init__``)."""
    init = cls.__init__
    names = [f.name for f in dataclasses.fields(cls) if f.init]

    @functools.wraps(init)
    def __init__(self, *args, **kwargs):
        unknown = sorted(set(kwargs) - set(names))
        if unknown:
            raise InputTypeError(
                f"{cls.__name__}.{unknown[0]}: not a setting of {cls.__name__}; its settings: "
                f"{names}"
            )
        if len(args) > len(names):
            raise InputTypeError(
                f"{cls.__name__}: expected at most {len(names)} settings {names}, got "
                f"{len(args)} positional arguments"
            )
        init(self, *args, **kwargs)

    cls.__init__ = __init__
    return cls


def _setting_type(value: object, hint: object, where: str) -> None:
    """``value`` against one annotation: bool, int, float, str or X | None."""
    arguments = [a for a in typing.get_args(hint) if a is not type(None)]
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        if value is None:
            return
        hint = arguments[0] if len(arguments) == 1 else None
    is_bool = isinstance(value, (bool, np.bool_))
    if hint is bool and not is_bool:
        raise InputTypeError(f"{where}: expected True or False, got {describe(value)}")
    if hint is int and (is_bool or not isinstance(value, numbers.Integral)):
        raise InputTypeError(f"{where}: expected an integer, got {describe(value)}")
    if hint is float:
        if is_bool or not isinstance(value, numbers.Real):
            raise InputTypeError(f"{where}: expected a number, got {describe(value)}")
        if math.isnan(float(value)):
            raise InputError(f"{where}: expected a number, got NaN")
    if hint is str and not isinstance(value, str):
        raise InputTypeError(f"{where}: expected a string, got {describe(value)}")


def check_setting_types(settings: object) -> None:
    """Every field of the solver dataclass ``settings`` has its annotated type (named
    ``InputTypeError`` otherwise), so that range checks compare numbers with numbers."""
    cls = type(settings)
    hints = typing.get_type_hints(cls)
    for field in dataclasses.fields(cls):
        if field.name in hints:
            _setting_type(
                getattr(settings, field.name), hints[field.name], f"{cls.__name__}.{field.name}"
            )


def bounded_gauss_newton_step(
    objective: Objective, g: np.ndarray, outputs: np.ndarray, theta: np.ndarray
) -> GaussNewtonStep:
    """The Gauss–Newton step at θ with parameters on an active bound held.

    Active set: θ_j on its lower bound with Δθ_j < 0, or on its upper bound with Δθ_j > 0.
    Repeated until no held parameter changes (at most n_f times); one triangular factor of
    [R^(−½)G | R^(−½)ν] (one pass over G) serves every repetition.
    """
    problem = objective.problem
    factor = triangular_factor(g, problem.residuals(outputs), objective.r_diag)
    gn = step_from_factor(factor)
    if not problem.bounded:
        return gn
    on_lower = theta <= problem.lower
    on_upper = theta >= problem.upper
    held = np.zeros(theta.shape, dtype=bool)
    for _ in range(theta.size):
        outward = (on_lower & (gn.step < 0)) | (on_upper & (gn.step > 0))
        if not np.any(outward & ~held):
            break
        held |= outward
        gn = step_from_factor(factor, held=held)
    return gn


def limit_step(
    step: np.ndarray, theta: np.ndarray, typical: np.ndarray, max_relative_step: float
) -> np.ndarray:
    """Scale Δθ down (direction kept) so no |Δθ_j| exceeds max_relative_step·max(|θ_j|, typ_j).

    Far from the optimum a Gauss–Newton step along a poorly determined direction can be many
    times the parameters' size and carry the search into a distant basin; this bounds it.
    """
    ratio = np.max(np.abs(step) / (max_relative_step * np.maximum(np.abs(theta), typical)))
    return step / ratio if ratio > 1.0 else step


# Levenberg–Marquardt damping tried when no halving of the Gauss–Newton step lowers the cost
# (μ relative to the largest squared singular value of the column-scaled sensitivities).
DAMPING_SEQUENCE = (1e-6, 1e-4, 1e-3, 1e-2, 1e-1, 1.0)


def halving_search(
    objective: Objective,
    theta: np.ndarray,
    cost: float,
    step: np.ndarray,
    max_halvings: int,
    gauss_newton: GaussNewtonStep | None = None,
) -> tuple[np.ndarray, float, np.ndarray, np.ndarray] | None:
    """Step-size control: try θ + λΔθ with λ = 1, ½, ¼, … until the cost drops.

    If none does and the Gauss–Newton factorisation is given, damped (Levenberg–Marquardt)
    steps with growing μ follow (``DAMPING_SEQUENCE``): far from the optimum a step along a
    barely determined direction can be huge, and halving alone may not shorten it enough.

    Each trial is one integration. Returns (θ_new, J_new, outputs, accepted step) or None if
    no trial lowered the cost (or the budget ran out).
    """
    problem = objective.problem

    def trials():
        # computed one at a time: the damped steps (an SVD each) only once halving failed
        for scale in 0.5 ** np.arange(max_halvings + 1):
            yield scale * step
        if gauss_newton is not None:
            magnitude = problem.magnitude(theta)
            for mu in DAMPING_SEQUENCE:
                yield gauss_newton.damped(mu, magnitude)

    for trial_step in trials():
        if objective.budget_exhausted():
            return None
        # θ(λ) = P(θ + λΔθ): the projected path stays inside the bounds
        trial = problem.project(theta + trial_step)
        if np.array_equal(trial, theta):
            continue
        costs, outputs = objective.evaluate(trial[None, :])
        if costs[0] < cost:
            return trial, float(costs[0]), outputs[0], trial - theta
    return None


def budget_status(objective: Objective) -> tuple[str, str]:
    limit = objective.convergence.max_evaluations
    return "max_evaluations", f"stopped after the evaluation budget ({limit}) was spent"
