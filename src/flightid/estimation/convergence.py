"""Convergence rules (RP-1153 §6): the cost and every parameter must have settled, together.

    |ΔJ| ≤ cost_rtol · J + cost_atol                  (|ΔJ/J| < 10⁻³ in the paper)
    |Δθ_j| ≤ param_rtol · max(|θ_j|, typical_j)  ∀ j  (|Δθ_j/θ_j| < 10⁻³; the floor guards θ_j = 0)

A pass may also stop *before* integrating at the new point: when the Gauss–Newton step about
to be taken meets the parameter test and the cost drop it predicts, ‖AΔθ‖², meets the cost
test (``step_settled``). Every solver that takes Gauss–Newton steps uses both tests.

``cost_atol`` (default 0) lets noise-free problems stop once J is negligible, where the
relative test cannot be met by a quadratically converging method.

Confirmation. The tests above are the solver's own, judged with its own (for MNRES possibly
stale) sensitivities, and the relative cost test 10⁻³·J allows a step of √(10⁻³·J) standard
deviations — about 1.7 σ when J ≈ N·n_o = 3000. So ``estimate`` never takes a solver's word
for it: at the point where the solver stops it computes the sensitivities by central
differences (the ones the Cramér–Rao bounds need anyway) and the Gauss–Newton step Δθ they
give. Convergence is confirmed only when

    √(ΔθᵀMΔθ) ≤ confirm_sigma          (default 0.02),  M = Σ GᵀR̂⁻¹G

i.e. the optimum the linearised model predicts lies within ``confirm_sigma`` Cramér–Rao
standard deviations (|Δθ_j| ≤ σ_j·√(ΔθᵀMΔθ) for every j). M is weighted by R̂, the
residuals' own covariance [3.45], whatever R the cost uses: with a fixed R = I the σ of the
cost's units would say nothing about the data. Also confirmed: when the step's predicted
cost drop is below a positive ``cost_atol`` (the user's own absolute tolerance), or every
|Δθ_j| is below ``numerical_rtol``·max(|θ_j|, floor_j) (noise-free data, where σ is at
rounding level).
Otherwise the estimation continues with Gauss–Newton passes on those sensitivities (with
step halving, and R re-estimated each pass under the MAX / MAXLIK policies) until it is
confirmed, or reports that it is not converged and by how many σ.
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
        confirm_sigma: a converged estimate lies within this many Cramér–Rao standard
            deviations (Mahalanobis norm √(ΔθᵀMΔθ)) of the optimum predicted by a
            Gauss–Newton step on central-difference sensitivities.
        numerical_rtol: ... or that step is below this fraction of max(|θ_j|, floor_j) for
            every parameter (for noise-free data).
        max_confirmation_passes: Gauss–Newton passes taken after a solver stopped short.
    """

    cost_rtol: float = 1e-3
    param_rtol: float = 1e-3
    cost_atol: float = 0.0
    max_iterations: int = 100
    max_evaluations: int | None = None
    maxlik_switch: float = 1e-2
    noise_rtol: float = 1e-2
    max_noise_cycles: int = 6
    confirm_sigma: float = 0.02
    numerical_rtol: float = 1e-8
    max_confirmation_passes: int = 50

    def __post_init__(self) -> None:
        for name in ("max_iterations", "max_noise_cycles", "max_confirmation_passes"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer):
                raise InputError(f"Convergence.{name}: expected an integer, got {value!r}")
        if self.max_evaluations is not None and (
            isinstance(self.max_evaluations, bool)
            or not isinstance(self.max_evaluations, int | np.integer)
        ):
            raise InputError(
                f"Convergence.max_evaluations: expected an integer or None, "
                f"got {self.max_evaluations!r}"
            )
        for name in (
            "cost_rtol",
            "param_rtol",
            "cost_atol",
            "maxlik_switch",
            "noise_rtol",
            "confirm_sigma",
            "numerical_rtol",
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float | np.number):
                raise InputError(f"Convergence.{name}: expected a number, got {value!r}")
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
        if self.confirm_sigma <= 0:
            raise InputError(f"Convergence.confirm_sigma: expected > 0, got {self.confirm_sigma!r}")
        if self.max_confirmation_passes < 0:
            raise InputError(
                "Convergence.max_confirmation_passes: expected ≥ 0, "
                f"got {self.max_confirmation_passes!r}"
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

    def confirmed(self, sigma_distance: float, step, magnitude: np.ndarray) -> bool:
        """The central-difference Gauss–Newton step confirms convergence (see module doc).

        Args:
            sigma_distance: √(ΔθᵀMΔθ) with M weighted by the residuals' own R̂.
            step: the ``GaussNewtonStep`` (its predicted drop is under the R in use).
            magnitude: max(|θ_j|, floor_j).
        """
        if sigma_distance <= self.confirm_sigma:
            return True
        if self.cost_atol > 0 and step.predicted_reduction <= self.cost_atol:
            return True
        return bool(np.all(np.abs(step.step) <= self.numerical_rtol * magnitude))

    def relative_cost_change(self, previous: float, current: float) -> float:
        return abs(previous - current) / max(abs(current), np.finfo(float).tiny)
