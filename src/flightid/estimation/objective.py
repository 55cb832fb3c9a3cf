"""The objective the solvers minimise, with the noise-covariance policy and the accounting.

Noise policies (RP-1153 §6):

* ``"fixed"`` — R is given (or the identity) and never changes;
* ``"max"`` — program MAX: R is held while the parameters converge, then re-estimated from
  the residuals [3.45] and the parameters re-converged; repeated until a cycle moves nothing
  (the driver in ``estimate`` runs the cycles);
* ``"maxlik"`` — program MAXLIK: R is re-estimated after every pass once the relative cost
  change is below ``Convergence.maxlik_switch`` (0.01).

Every system integration goes through ``OutputErrorProblem.run`` and is counted there.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from flightid.errors import EstimationError
from flightid.estimation.convergence import Convergence
from flightid.estimation.problem import FiniteDifferences, OutputErrorProblem

__all__ = ["Objective", "SolverOutcome", "NOISE_POLICIES"]

NOISE_POLICIES = ("fixed", "max", "maxlik")

# evaluated points whose ln det R̂ is kept for the pass that records one of them
_REMEMBERED_POINTS = 4096


@dataclass(frozen=True)
class SolverOutcome:
    """What a solver returns to the driver."""

    theta: np.ndarray  # free parameters at the end
    outputs: np.ndarray  # (N, n_o) model outputs there
    cost: float
    iterations: int
    converged: bool
    status: str  # converged | max_iterations | max_evaluations | stalled
    message: str
    state: object = None  # solver-specific warm-start state for the next noise cycle
    # forward differences the solver's last pass took at ``theta`` itself (None if it has
    # none there): the confirmation completes them to central differences with n_f more
    # integrations instead of 2·n_f (``OutputErrorProblem.complete_central``)
    differences: FiniteDifferences | None = None


class Objective:
    """Cost evaluations under the current R, with history and budget.

    Args:
        problem: the output-error problem.
        r_diag: initial noise variances (n_o,).
        policy: one of ``NOISE_POLICIES``.
        convergence: stopping rules.
        progress: called after every recorded pass with (pass number, equivalent
            evaluations so far, cost).
    """

    def __init__(
        self,
        problem: OutputErrorProblem,
        r_diag: np.ndarray,
        policy: str,
        convergence: Convergence,
        progress: Callable[[int, int, float], None] | None = None,
    ) -> None:
        self.problem = problem
        self.progress = progress
        self.r_diag = np.asarray(r_diag, dtype=float)
        self.policy = policy
        self.convergence = convergence
        self.start_evaluations = problem.evaluations
        self.cost_history: list[float] = []
        self.evaluation_history: list[int] = []
        self.theta_history: list[np.ndarray] = []
        self.noise_updates = 0
        # per R re-estimation, the index in cost_history of the first cost under the new R
        self.noise_update_passes: list[int] = []
        # per recorded pass: ln det R̂ of its residuals [3.45] and the R its cost is under
        self.log_det_r_history: list[float] = []
        self.r_history: list[np.ndarray] = []
        # ln det R̂ of the points evaluated lately, by θ (a pass records one of them)
        self._log_det_r: dict[bytes, float] = {}
        self._cached: tuple[np.ndarray, np.ndarray] | None = None

    # ------------------------------------------------------------------ accounting
    @property
    def evaluations(self) -> int:
        return self.problem.evaluations - self.start_evaluations

    @property
    def typical(self) -> np.ndarray:
        return self.problem.typical

    def budget_exhausted(self) -> bool:
        limit = self.convergence.max_evaluations
        return limit is not None and self.evaluations >= limit

    def record(self, theta: np.ndarray, cost: float, outputs: np.ndarray | None = None) -> None:
        """Log one pass (an accepted parameter update, or the start): its cost under the
        current R, the R, and ln det R̂ of its residuals (from ``outputs``, else from the
        evaluation of θ; NaN when neither is at hand)."""
        theta = np.array(theta, dtype=float)
        if outputs is not None:
            log_det = self.log_det_noise_covariance(outputs)
        else:
            log_det = self._log_det_r.get(theta.tobytes(), float("nan"))
        self.cost_history.append(float(cost))
        self.evaluation_history.append(self.evaluations)
        self.theta_history.append(theta)
        self.log_det_r_history.append(log_det)
        self.r_history.append(np.array(self.r_diag, dtype=float))
        if self.progress is not None:
            self.progress(len(self.cost_history) - 1, self.evaluations, float(cost))

    # ------------------------------------------------------------------ evaluations
    def prime(self, theta: np.ndarray, outputs: np.ndarray) -> None:
        """Remember the outputs at ``theta`` so the next request for them costs nothing."""
        self._cached = (np.array(theta, dtype=float), outputs)

    def evaluate(self, thetas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Costs (B,) and outputs (B, N, n_o) of a batch; diverged trajectories cost inf."""
        thetas = np.atleast_2d(np.asarray(thetas, dtype=float))
        if (
            self._cached is not None
            and thetas.shape[0] == 1
            and np.array_equal(thetas[0], self._cached[0])
        ):
            outputs = self._cached[1][None]
            self._cached = None
        else:
            outputs = self.problem.run(thetas).outputs
        costs = self.costs_of(outputs)
        self._remember_log_det(thetas, costs, outputs)
        return costs, outputs

    def log_det_noise_covariance(self, outputs: np.ndarray) -> float:
        """ln det R̂ = Σ_k ln R̂_kk of the residuals of (N, n_o) ``outputs`` [3.45]: under an
        estimated R the negative log-likelihood up to constants, whatever R weights J."""
        with np.errstate(divide="ignore", invalid="ignore"):
            # ln det R̂ = Σ_k ln R̂_kk (R̂ diagonal)
            value = float(np.sum(np.log(self.problem.noise_covariance(outputs))))
        return value if np.isfinite(value) else float("nan")

    def _remember_log_det(self, thetas: np.ndarray, costs: np.ndarray, outputs) -> None:
        """ln det R̂ of each finite evaluation, for ``record`` (the last few thousand)."""
        for theta, cost, output in zip(thetas, costs, outputs, strict=True):
            if np.isfinite(cost):
                self._log_det_r[theta.tobytes()] = self.log_det_noise_covariance(output)
        while len(self._log_det_r) > _REMEMBERED_POINTS:
            del self._log_det_r[next(iter(self._log_det_r))]

    def evaluate_start(self, theta: np.ndarray) -> tuple[float, np.ndarray]:
        """Cost and outputs at a start point; a start that diverges is an error."""
        costs, outputs = self.evaluate(theta[None, :])
        if not np.isfinite(costs[0]):
            sim = self.problem.run(theta[None, :])  # re-run to get the message
            raise EstimationError(
                "the simulation at the start values does not stay finite: "
                f"{sim.messages[0] or 'non-finite outputs'}; check the start values and x0"
            )
        return float(costs[0]), outputs[0]

    def costs_of(self, outputs: np.ndarray) -> np.ndarray:
        """Costs under the current R of stored outputs (no integration)."""
        return np.atleast_1d(self.problem.cost(outputs, self.r_diag))

    # ------------------------------------------------------------------ noise policy
    def maxlik_update(self, outputs: np.ndarray, relative_cost_change: float) -> bool | None:
        """MAXLIK: re-estimate R from ``outputs`` once the cost change is below the switch.

        Returns None if R was not touched, else whether R has settled (largest relative
        variance change ≤ ``Convergence.noise_rtol``). Callers recompute stored costs.
        """
        if self.policy != "maxlik" or relative_cost_change >= self.convergence.maxlik_switch:
            return None
        return self.update_noise(outputs) <= self.convergence.noise_rtol

    def update_noise(self, outputs: np.ndarray) -> float:
        """Set R = R̂(outputs) [3.45]; returns the largest relative change of a variance."""
        new = self.problem.noise_covariance(outputs)
        change = float(np.max(np.abs(new - self.r_diag) / self.r_diag))
        self.r_diag = new
        self.noise_updates += 1
        self.noise_update_passes.append(len(self.cost_history))
        return change
