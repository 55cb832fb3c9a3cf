"""The likelihood contour J(θ) − J(θ̂) = Δ that the search and profile methods trace.

``Contour`` binds an ``OutputErrorProblem`` to a fixed noise covariance R (the estimate's
R̂), the minimum θ̂, J(θ̂) and the level Δ. Every cost goes through ``OutputErrorProblem.run``
(batched), so ``evaluations`` counts the paper's equivalent evaluations spent by a method.

Before the region is traced the minimum is *polished*: a few Gauss–Newton passes at fixed R
with tight tolerances. The estimation stops at |ΔJ/J| < 10⁻³ (RP-1153 §6), i.e. J may still be
≈ 10⁻³·N·n_o above its minimum — a sizeable fraction of Δ (≈ 4 at 95 %) — and the
likelihood-ratio limits are measured from the true minimum.
"""

from __future__ import annotations

import numpy as np

from flightid.estimation.gauss_newton import gauss_newton_step
from flightid.estimation.problem import OutputErrorProblem

__all__ = ["Contour", "polish_minimum"]


class Contour:
    """Costs relative to the minimum under a fixed R.

    Args:
        problem: the output-error problem (its free parameters span the region).
        r_diag: noise variances R (n_o,) used in J.
        theta_hat: the minimum θ̂ (n_f,).
        cost_hat: J(θ̂).
        delta: the contour level Δ.
        outputs_hat: model outputs at θ̂ (N, n_o), if known.
    """

    def __init__(
        self,
        problem: OutputErrorProblem,
        r_diag: np.ndarray,
        theta_hat: np.ndarray,
        cost_hat: float,
        delta: float,
        outputs_hat: np.ndarray | None = None,
    ) -> None:
        self.problem = problem
        self.r_diag = np.asarray(r_diag, dtype=float)
        self.theta_hat = np.asarray(theta_hat, dtype=float)
        self.cost_hat = float(cost_hat)
        self.delta = float(delta)
        self.outputs_hat = outputs_hat
        self.start_evaluations = problem.evaluations
        self.lowest_excess = 0.0  # most negative J − J(θ̂) met (should stay ≈ 0)

    @property
    def n_free(self) -> int:
        return self.problem.n_free

    @property
    def evaluations(self) -> int:
        """Integrations since this contour was made."""
        return self.problem.evaluations - self.start_evaluations

    def with_level(self, delta: float) -> Contour:
        """The same minimum at another level Δ (shares the evaluation count)."""
        other = Contour(
            self.problem, self.r_diag, self.theta_hat, self.cost_hat, delta, self.outputs_hat
        )
        other.start_evaluations = self.start_evaluations
        return other

    def costs(self, thetas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(J − J(θ̂) (B,), outputs (B, N, n_o)) of a batch; inf where a trajectory diverged."""
        thetas = np.atleast_2d(np.asarray(thetas, dtype=float))
        outputs = self.problem.outputs(thetas)
        excess = np.atleast_1d(self.problem.cost(outputs, self.r_diag)) - self.cost_hat
        excess = np.where(np.isfinite(excess), excess, np.inf)
        if excess.size:
            self.lowest_excess = min(self.lowest_excess, float(np.min(excess)))
        return excess, outputs

    def sensitivities(
        self, theta: np.ndarray, outputs: np.ndarray, columns: np.ndarray | None = None
    ) -> np.ndarray | None:
        """Forward-difference G (N, n_o, n_cols) at θ for the given columns; None if diverged.

        Steps 10⁻⁶·max(|θ_j|, typical_j); costs one integration per column (one batch).
        """
        columns = np.arange(self.n_free) if columns is None else np.asarray(columns)
        steps = 1e-6 * np.maximum(np.abs(theta[columns]), self.problem.typical[columns])
        batch = np.repeat(theta[None, :], columns.size, axis=0)
        batch[np.arange(columns.size), columns] += steps
        perturbed = self.problem.outputs(batch)
        if not np.all(np.isfinite(perturbed)):
            return None
        # G_j = (y(θ + δ_j e_j) − y(θ)) / δ_j
        g = (perturbed - outputs[None]) / steps[:, None, None]
        return np.moveaxis(g, 0, -1)


def polish_minimum(
    problem: OutputErrorProblem,
    r_diag: np.ndarray,
    theta: np.ndarray,
    max_passes: int = 10,
    tolerance: float = 1e-9,
) -> tuple[np.ndarray, float, np.ndarray, int]:
    """Gauss–Newton passes at fixed R until the predicted decrease is below ``tolerance``·J.

    Returns (θ̂, J(θ̂), outputs (N, n_o), integrations spent). Never moves uphill.
    """
    start = problem.evaluations
    theta = np.asarray(theta, dtype=float).copy()
    outputs = problem.outputs(theta[None, :])[0]
    cost = float(problem.cost(outputs, r_diag))
    helper = Contour(problem, r_diag, theta, cost, 1.0, outputs)
    for _ in range(max_passes):
        g = helper.sensitivities(theta, outputs)
        if g is None:
            break
        nu = problem.residuals(outputs)
        step = gauss_newton_step(g, nu, r_diag).step
        weighted = (g @ step) / np.sqrt(r_diag)[None, :]
        # predicted decrease of J ≈ 2 νᵀR⁻¹GΔθ − ‖R^(−½)GΔθ‖²
        predicted = float(2.0 * np.sum(nu * (g @ step) / r_diag[None, :]) - np.sum(weighted**2))
        if predicted <= tolerance * max(cost, 1e-300):
            break
        improved = False
        for _halving in range(8):
            trial = theta + step
            trial_outputs = problem.outputs(trial[None, :])[0]
            trial_cost = float(problem.cost(trial_outputs, r_diag))
            if np.isfinite(trial_cost) and trial_cost < cost:
                theta, outputs, cost, improved = trial, trial_outputs, trial_cost, True
                break
            step = 0.5 * step
        if not improved:
            break
    return theta, cost, outputs, problem.evaluations - start
