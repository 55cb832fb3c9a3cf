"""Convergence rules (RP-1153 §6): the cost and every parameter must have settled, together.

    |ΔJ| ≤ cost_rtol · J + cost_atol                  (|ΔJ/J| < 10⁻³ in the paper)
    |Δθ_j| ≤ param_rtol · max(|θ_j|, typical_j)  ∀ j  (|Δθ_j/θ_j| < 10⁻³; the floor guards θ_j = 0)

A pass may also stop *before* integrating at the new point: when the Gauss–Newton step about
to be taken meets the parameter test and the cost drop it predicts, ‖AΔθ‖², meets the cost
test (``step_settled``). Every solver that takes Gauss–Newton steps uses both tests.

``cost_atol`` (default 0) lets noise-free problems stop once J is negligible, where the
relative test cannot be met by a quadratically converging method.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightid.errors import InputError

__all__ = ["Convergence"]


@dataclass(frozen=True)
class Convergence:
    """Stopping rules shared by all solvers.

    Attributes:
        cost_rtol: relative cost change tolerance.
        param_rtol: relative parameter change tolerance.
        cost_atol: absolute cost change tolerance (cost units).
        max_iterations: passes (parameter updates) at most, per noise cycle.
        max_evaluations: equivalent evaluations at most (None: no limit).
        maxlik_switch: MAXLIK policy updates R every pass once |ΔJ/J| is below this (0.01).
        noise_rtol: R has settled when no variance changes by more than this fraction.
        max_noise_cycles: MAX policy: R updates (re-convergence cycles) at most.
    """

    cost_rtol: float = 1e-3
    param_rtol: float = 1e-3
    cost_atol: float = 0.0
    max_iterations: int = 100
    max_evaluations: int | None = None
    maxlik_switch: float = 1e-2
    noise_rtol: float = 1e-2
    max_noise_cycles: int = 6

    def __post_init__(self) -> None:
        for name in ("cost_rtol", "param_rtol", "cost_atol", "maxlik_switch", "noise_rtol"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise InputError(f"Convergence.{name}: expected a finite number ≥ 0, got {value!r}")
        if self.max_iterations < 1:
            raise InputError(
                f"Convergence.max_iterations: expected ≥ 1, got {self.max_iterations!r}"
            )
        if self.max_evaluations is not None and self.max_evaluations < 1:
            raise InputError(
                f"Convergence.max_evaluations: expected ≥ 1 or None, got {self.max_evaluations!r}"
            )
        if self.max_noise_cycles < 1:
            raise InputError(
                f"Convergence.max_noise_cycles: expected ≥ 1, got {self.max_noise_cycles!r}"
            )

    def cost_settled(self, previous: float, current: float) -> bool:
        """|ΔJ| ≤ cost_rtol·J + cost_atol."""
        return abs(previous - current) <= self.cost_rtol * abs(current) + self.cost_atol

    def params_settled(self, step: np.ndarray, theta: np.ndarray, typical: np.ndarray) -> bool:
        """|Δθ_j| ≤ param_rtol·max(|θ_j|, typical_j) for every j."""
        return bool(np.all(np.abs(step) <= self.param_rtol * np.maximum(np.abs(theta), typical)))

    def step_settled(self, step, theta: np.ndarray, typical: np.ndarray, cost: float) -> bool:
        """The next Gauss–Newton step is negligible: parameters and predicted cost drop."""
        return self.params_settled(step.step, theta, typical) and (
            step.predicted_reduction <= self.cost_rtol * abs(cost) + self.cost_atol
        )

    def relative_cost_change(self, previous: float, current: float) -> float:
        return abs(previous - current) / max(abs(current), np.finfo(float).tiny)
