"""MNRES — modified Newton–Raphson with estimated sensitivities (RP-1153 §4, 4.9–4.24).

The solver keeps a set of parameter points with their output histories. Each pass:

1. take the lowest-cost point as the expansion point θ⁰;
2. estimate the sensitivities G_i from the surface through the stored points
   (``flightid.estimation.surface``: algebraic form [4.15], or least squares [4.18–4.23],
   batch QR or constant-window recursive);
3. take the Gauss–Newton step [4.4–4.8] with those G_i, integrate once at the new point;
4. if the cost dropped, the new point enters and the highest-cost point leaves; otherwise the
   failed point itself enters the surface and the pass is repeated (at most
   ``learn_from_failures`` times in a row), then the step is halved (one integration each)
   and, failing that, the solver restarts;
5. stop when cost and parameters have settled (``Convergence``).

Initialisation and restart perturb each parameter from θ⁰ (n_f integrations, in one batch).
The first perturbations are ``initial_perturbation`` × max(|θ_j|, floor_j) (the floor is the
parameter's ``scale``, or 1e-3); a perturbation that would cross a bound goes the other way.
The surface works in coordinates ϑ = θ / max(|θ⁰_j|, floor_j) fixed at (re)initialisation.
At a restart they are scaled by parameter importance (§7): with M_ℓℓ from the current surface,
δθ_ℓ ∝ 1/√M_ℓℓ — parameters that move the cost little get larger perturbations — normalised
so their geometric-mean relative size equals the restart size, then clipped to a factor 10
either side of it. The restart size shrinks with the last accepted step so that the surface
stays local near convergence, and by another factor 10 after each restart that found no
lower cost (``max_restarts`` such restarts in a row end the search as stalled).

Restarts happen when the cost will not drop, or when ΔX (the point cloud) is ill-conditioned;
the paper's version had no such safeguards and oscillated on example 2, case 2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from flightid.errors import EstimationError, InputError
from flightid.estimation.gauss_newton import information_matrix
from flightid.estimation.objective import Objective, SolverOutcome
from flightid.estimation.solvers.common import (
    bounded_gauss_newton_step,
    budget_status,
    halving_search,
    limit_step,
)
from flightid.estimation.surface import RecursiveSurface, algebraic_surface, batch_surface

__all__ = ["MNRES"]

_FORMS = ("algebraic", "batch", "recursive")
_LEARNT = object()  # marker: a failed trial point entered the surface; repeat the pass


@dataclass
class _PointSet:
    """The stored parameter points (unscaled), their outputs and costs."""

    points: np.ndarray  # (n, n_f)
    outputs: np.ndarray  # (n, N, n_o)
    costs: np.ndarray  # (n,)
    reference: np.ndarray  # expansion reference of the least-squares forms (n_f,)
    surface: RecursiveSurface | None = None
    restarts: int = 0  # restarts so far in this run
    failures: int = 0  # consecutive restarts without an accepted step
    corrections: int = 0  # failed trials inserted since the last accepted step
    last_step: np.ndarray | None = field(default=None)
    scale: np.ndarray | None = field(default=None)  # coordinates of the surface: ϑ = θ / scale
    fresh: bool = True  # the surface comes from perturbations about the current best point


@dataclass(frozen=True)
class MNRES:
    """Newton–Raphson with sensitivities from a surface through past points.

    Attributes:
        form: ``"algebraic"`` (n_f + 1 points, [4.15]), ``"batch"`` (least-squares plane by
            QR) or ``"recursive"`` (least-squares plane, constant-window recursive update).
        window: points kept by the least-squares forms (≥ n_f + 1; default n_f + 1).
        initial_perturbation: first perturbation, relative to max(|θ_j|, floor_j).
        importance_scaling: scale restart perturbations by 1/√M_ℓℓ (§7).
        max_halvings: step halvings before a restart.
        fresh_halvings: step halvings from a freshly (re)initialised surface.
        max_relative_step: no parameter moves more than this fraction of max(|θ_j|, scale_j)
            in one pass (off by default; see MNR).
        max_condition: largest acceptable condition number of the (scaled) point cloud.
        learn_from_failures: failed full steps whose points enter the surface before the
            step is halved (0: halve at once, as the paper's step-size control).
        max_restarts: consecutive restarts without progress before declaring a stall; each
            such restart perturbs 10 times less than the previous one.
    """

    form: str = "algebraic"
    window: int | None = None
    initial_perturbation: float = 0.001
    importance_scaling: bool = True
    max_halvings: int = 3
    fresh_halvings: int = 10
    max_relative_step: float = math.inf
    max_condition: float = 1e8
    max_restarts: int = 6
    learn_from_failures: int = 2

    name = "mnres"

    def __post_init__(self) -> None:
        if self.form not in _FORMS:
            raise InputError(f"MNRES.form: expected one of {_FORMS}, got {self.form!r}")
        if not 0 < self.initial_perturbation < 1:
            raise InputError(
                "MNRES.initial_perturbation: expected a fraction between 0 and 1, "
                f"got {self.initial_perturbation!r}"
            )
        if self.max_halvings < 0 or self.max_restarts < 0:
            raise InputError("MNRES.max_halvings and MNRES.max_restarts must be ≥ 0")
        if self.form == "algebraic" and self.window is not None:
            raise InputError("MNRES.window: only the 'batch' and 'recursive' forms take a window")

    def settings(self) -> dict:
        return {
            "form": self.form,
            "window": self.window,
            "initial_perturbation": self.initial_perturbation,
            "importance_scaling": self.importance_scaling,
            "max_halvings": self.max_halvings,
            "fresh_halvings": self.fresh_halvings,
            "max_relative_step": None
            if math.isinf(self.max_relative_step)
            else self.max_relative_step,
            "max_condition": self.max_condition,
            "max_restarts": self.max_restarts,
            "learn_from_failures": self.learn_from_failures,
        }

    # ------------------------------------------------------------------ helpers
    def _window(self, n_free: int) -> int:
        window = n_free + 1 if self.window is None else int(self.window)
        if window < n_free + 1:
            raise InputError(
                f"MNRES.window: expected at least n_free + 1 = {n_free + 1} points, got {window}"
            )
        return window

    def _initialise(
        self,
        objective: Objective,
        theta: np.ndarray,
        outputs: np.ndarray,
        cost: float,
        deltas: np.ndarray,
        restarts: int,
    ) -> _PointSet:
        """Perturb each parameter from θ (n_f integrations in one batch)."""
        problem = objective.problem
        # a perturbation that would cross a bound goes the other way (and stays in the box)
        deltas = np.where(theta + deltas > problem.upper, -deltas, deltas)
        deltas = problem.project(theta + deltas) - theta
        trial = theta[None, :] + np.diag(deltas)
        costs, trial_outputs = objective.evaluate(trial)
        # A perturbation that makes the simulation diverge is retried 10 times smaller.
        for _ in range(3):
            bad = ~np.isfinite(costs)
            if not bad.any():
                break
            deltas = np.where(bad, deltas / 10.0, deltas)
            retry_costs, retry_outputs = objective.evaluate(theta[None, :] + np.diag(deltas)[bad])
            costs[bad], trial_outputs[bad] = retry_costs, retry_outputs
        if not np.all(np.isfinite(costs)):
            raise EstimationError("MNRES: perturbed simulations diverge around the current point")
        points = np.vstack([theta[None, :], theta[None, :] + np.diag(deltas)])
        all_outputs = np.concatenate([outputs[None], trial_outputs])
        all_costs = np.concatenate([[cost], costs])
        scale = problem.magnitude(theta)
        point_set = _PointSet(
            points, all_outputs, all_costs, theta.copy(), restarts=restarts, scale=scale
        )
        if self.form == "recursive":
            point_set.surface = RecursiveSurface(
                points / scale, all_outputs.reshape(points.shape[0], -1), theta / scale
            )
        return point_set

    def _restart_deltas(
        self,
        objective: Objective,
        theta: np.ndarray,
        g: np.ndarray | None,
        last_step: np.ndarray | None,
        failures: int,
    ) -> np.ndarray:
        """Perturbations for a restart: importance-scaled, shrinking with the last step and
        by a factor 10 for each consecutive restart that found no lower cost."""
        magnitude = objective.problem.magnitude(theta)
        size = self.initial_perturbation
        if last_step is not None:
            # 10 × the last relative step, between 1e-5 and the initial perturbation
            size = float(np.clip(10.0 * np.max(np.abs(last_step) / magnitude), 1e-5, size))
        size = max(size * 0.1**failures, 1e-8)
        relative = np.full(theta.shape, size)
        if self.importance_scaling and g is not None:
            diagonal = np.diag(information_matrix(g, objective.r_diag)) * magnitude**2
            if np.all(diagonal > 0) and np.all(np.isfinite(diagonal)):
                # δθ_ℓ ∝ 1/√M_ℓℓ, geometric mean of δθ_ℓ/|θ_ℓ| equal to `size`
                weights = 1.0 / np.sqrt(diagonal)
                weights /= np.exp(np.mean(np.log(weights)))
                relative = size * np.clip(weights, 0.1, 10.0)
        return relative * magnitude

    def _slopes(self, objective: Objective, state: _PointSet, base: int) -> np.ndarray:
        scale = state.scale
        flat = state.outputs.reshape(state.points.shape[0], -1)
        if self.form == "algebraic":
            return algebraic_surface(state.points / scale, flat, base, self.max_condition)
        if self.form == "batch":
            return batch_surface(
                state.points / scale, flat, state.reference / scale, self.max_condition
            )
        return state.surface.slopes()

    # ------------------------------------------------------------------ main loop
    def minimize(self, objective: Objective, theta0: np.ndarray, state=None) -> SolverOutcome:
        problem = objective.problem
        conv = objective.convergence
        typical = objective.typical
        window = self._window(problem.n_free)
        if state is None:
            theta = np.array(theta0, dtype=float)
            cost, outputs = objective.evaluate_start(theta)
            objective.record(theta, cost)
            magnitude = problem.magnitude(theta)
            state = self._initialise(
                objective, theta, outputs, cost, self.initial_perturbation * magnitude, 0
            )
        else:
            state.costs = objective.costs_of(state.outputs)

        def finish(iterations: int, converged: bool, status: str, message: str):
            best = int(np.argmin(state.costs))
            return SolverOutcome(
                state.points[best],
                state.outputs[best],
                float(state.costs[best]),
                iterations,
                converged,
                status,
                message,
                state=state,
            )

        g = None
        for iteration in range(1, conv.max_iterations + 1):
            base = int(np.argmin(state.costs))
            theta, cost, outputs = state.points[base], state.costs[base], state.outputs[base]
            if objective.budget_exhausted():
                return finish(iteration - 1, False, *budget_status(objective))
            try:
                slopes = self._slopes(objective, state, base)
            except EstimationError:
                slopes = None  # the point cloud has collapsed: restart below
            step, accepted = None, None
            if slopes is not None:
                # ∂y/∂θ = ∂y/∂ϑ / scale, reshaped to (N, n_o, n_f)
                g = (slopes / state.scale[:, None]).T.reshape(
                    problem.n_samples, problem.n_outputs, problem.n_free
                )
                gn = bounded_gauss_newton_step(objective, g, outputs, theta)
                # The predicted drop is trusted from an interpolating surface (n_f + 1 points)
                # or a fresh one; a smoothed least-squares plane must prove it with a pass.
                trusted = state.fresh or state.points.shape[0] == problem.n_free + 1
                if trusted and conv.step_settled(gn, theta, typical, cost):
                    return finish(
                        iteration,
                        True,
                        "converged",
                        "converged: the next step and the cost drop it predicts are "
                        "below tolerance",
                    )
                step = limit_step(gn.step, theta, typical, self.max_relative_step)
                accepted = self._try_step(objective, state, theta, cost, step, window, gn)
                if accepted is _LEARNT:
                    continue
            if accepted is None:
                # A surface built from past passes may be stale: only a surface fresh from a
                # (re)initialisation at this point can declare convergence on a failed step.
                if step is not None and state.fresh and conv.params_settled(step, theta, typical):
                    return finish(
                        iteration,
                        True,
                        "converged",
                        "converged: the step is below the parameter tolerance and no "
                        "shorter step lowers the cost",
                    )
                if objective.budget_exhausted():
                    return finish(iteration, False, *budget_status(objective))
                if state.failures >= self.max_restarts:
                    return finish(
                        iteration,
                        False,
                        "stalled",
                        f"stalled: {self.max_restarts} restarts in a row found no lower cost",
                    )
                state = self._restart(objective, state, theta, outputs, cost, g)
                continue
            new_theta, new_cost, new_outputs, taken = accepted
            self._insert(objective, state, new_theta, new_outputs, new_cost, window)
            state.last_step = taken
            state.fresh = False
            state.failures = 0
            state.corrections = 0
            relative = conv.relative_cost_change(cost, new_cost)
            settled = conv.cost_settled(cost, new_cost) and conv.params_settled(
                taken, new_theta, typical
            )
            objective.record(new_theta, new_cost)
            noise_settled = objective.maxlik_update(new_outputs, relative)
            if noise_settled is not None:
                state.costs = objective.costs_of(state.outputs)
                settled = settled and noise_settled
            if settled:
                return finish(
                    iteration,
                    True,
                    "converged",
                    "converged: cost and parameter changes below tolerance",
                )
        return finish(
            conv.max_iterations,
            False,
            "max_iterations",
            f"stopped after {conv.max_iterations} iterations without converging",
        )

    def _try_step(
        self,
        objective: Objective,
        state: _PointSet,
        theta: np.ndarray,
        cost: float,
        step: np.ndarray,
        window: int,
        gn=None,
    ):
        """Integrate along the step: an accepted (θ, J, y, Δθ), None, or ``_LEARNT``."""
        # a fresh surface's step may also be damped (Levenberg–Marquardt) when halving fails
        damping = gn if state.fresh else None
        # a fresh surface is as good as a finite-difference gradient: search its step as far
        # down as MNR does before giving up on it
        halvings = max(self.max_halvings, self.fresh_halvings) if state.fresh else self.max_halvings
        if not (self.learn_from_failures and state.corrections < self.learn_from_failures):
            return halving_search(objective, theta, cost, step, halvings, gauss_newton=damping)
        # Try the full step once; if it fails, its outputs still teach the surface about the
        # direction where it was wrong: the point enters the set (the highest-cost point
        # leaves) and the pass is repeated.
        trial = objective.problem.project(theta + step)
        if np.array_equal(trial, theta):
            return None
        trial_costs, trial_outputs = objective.evaluate(trial[None, :])
        if trial_costs[0] < cost:
            return trial, float(trial_costs[0]), trial_outputs[0], trial - theta
        if np.isfinite(trial_costs[0]):
            self._insert(
                objective,
                state,
                trial,
                trial_outputs[0],
                float(trial_costs[0]),
                window,
                replace_only=True,
            )
            state.corrections += 1
            return _LEARNT
        return halving_search(
            objective, theta, cost, 0.5 * step, halvings - 1, gauss_newton=damping
        )

    def _restart(
        self,
        objective: Objective,
        previous: _PointSet,
        theta: np.ndarray,
        outputs: np.ndarray,
        cost: float,
        g: np.ndarray | None,
    ) -> _PointSet:
        """New perturbations about the best point (n_f integrations)."""
        deltas = self._restart_deltas(objective, theta, g, previous.last_step, previous.failures)
        state = self._initialise(objective, theta, outputs, cost, deltas, previous.restarts + 1)
        state.last_step = previous.last_step
        # a perturbed point that lowers the cost is progress too
        progress = float(np.min(state.costs)) < cost
        state.failures = 0 if progress else previous.failures + 1
        return state

    def _insert(
        self,
        objective: Objective,
        state: _PointSet,
        theta: np.ndarray,
        outputs: np.ndarray,
        cost: float,
        window: int,
        replace_only: bool = False,
    ) -> None:
        """The new point enters; the highest-cost point leaves once the window is full (or
        at once with ``replace_only``)."""
        scale = state.scale
        if state.points.shape[0] < window and not replace_only:
            if state.surface is not None:
                state.surface.add(theta / scale, outputs.reshape(-1))
            state.points = np.vstack([state.points, theta[None]])
            state.outputs = np.concatenate([state.outputs, outputs[None]])
            state.costs = np.append(state.costs, cost)
            return
        worst = int(np.argmax(state.costs))
        if state.surface is not None:
            state.surface.replace(
                theta / scale,
                outputs.reshape(-1),
                state.points[worst] / scale,
                state.outputs[worst].reshape(-1),
            )
        state.points[worst] = theta
        state.outputs[worst] = outputs
        state.costs[worst] = cost
