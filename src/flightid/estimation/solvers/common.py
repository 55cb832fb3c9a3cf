"""Pieces every Newton-type solver shares: the line search by step halving, and stop checks."""

from __future__ import annotations

import numpy as np

from flightid.estimation.objective import Objective

__all__ = ["halving_search", "budget_status", "limit_step"]


def limit_step(
    step: np.ndarray, theta: np.ndarray, typical: np.ndarray, max_relative_step: float
) -> np.ndarray:
    """Scale Δθ down (direction kept) so no |Δθ_j| exceeds max_relative_step·max(|θ_j|, typ_j).

    Far from the optimum a Gauss–Newton step along a poorly determined direction can be many
    times the parameters' size and carry the search into a distant basin; this bounds it.
    """
    ratio = np.max(np.abs(step) / (max_relative_step * np.maximum(np.abs(theta), typical)))
    return step / ratio if ratio > 1.0 else step


def halving_search(
    objective: Objective,
    theta: np.ndarray,
    cost: float,
    step: np.ndarray,
    max_halvings: int,
) -> tuple[np.ndarray, float, np.ndarray, np.ndarray] | None:
    """Step-size control: try θ + λΔθ with λ = 1, ½, ¼, … until the cost drops.

    Each trial is one integration. Returns (θ_new, J_new, outputs, accepted step) or None if
    no trial lowered the cost (or the budget ran out).
    """
    scale = 1.0
    for _ in range(max_halvings + 1):
        if objective.budget_exhausted():
            return None
        trial = theta + scale * step
        costs, outputs = objective.evaluate(trial[None, :])
        if costs[0] < cost:
            return trial, float(costs[0]), outputs[0], scale * step
        scale *= 0.5
    return None


def budget_status(objective: Objective) -> tuple[str, str]:
    limit = objective.convergence.max_evaluations
    return "max_evaluations", f"stopped after the evaluation budget ({limit}) was spent"
