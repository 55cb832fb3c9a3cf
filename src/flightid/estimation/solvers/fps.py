"""FPS — flexible polyhedron search (Nelder–Mead simplex), the derivative-free benchmark.

n_f + 1 vertices in scaled parameter space ϑ (RP-1153 §8). Each pass replaces
the worst vertex x_h, using the centroid x̄ of the others:

    reflection   x_r = x̄ + α (x̄ − x_h)           α = 1
    expansion    x_e = x̄ + γ (x_r − x̄)           γ = 2     (if x_r is the new best)
    contraction  x_c = x̄ + ρ (x_h − x̄)  or  x̄ + ρ (x_r − x̄)   ρ = ½
    shrink       x_j = x_l + σ (x_j − x_l)         σ = ½     (if contraction fails)

Each trial vertex is one integration. The simplex has converged when the spread of the vertex
costs and of every parameter across the vertices meet the ``Convergence`` tolerances. Because
a Nelder–Mead simplex can collapse away from the minimum, the search then restarts from the
best vertex with a fresh simplex (``initial_size``) and stops only when a restart converges
without lowering the cost beyond the tolerance (or after ``max_restarts``).

Coordinates and bounds. An unbounded parameter enters as ϑ_j = θ_j / m_j with m_j =
max(|θ_j|, floor_j) at the start of each search. A bounded one enters through the transforms
MINUIT and lmfit use, so every vertex maps inside the box whatever the simplex does:

    two bounds:   θ = l + (u − l)(sin ϑ + 1)/2
    lower only:   θ = l − 1 + √(ϑ² + 1)
    upper only:   θ = u + 1 − √(ϑ² + 1)
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from flightid.errors import InputError
from flightid.estimation.objective import Objective, SolverOutcome
from flightid.estimation.solvers.common import (
    budget_status,
    check_setting_types,
    named_settings,
)

__all__ = ["FPS"]


class _Coordinates:
    """θ ↔ ϑ: scaled for unbounded parameters, transformed into the box for bounded ones."""

    def __init__(self, lower: np.ndarray, upper: np.ndarray, magnitude: np.ndarray) -> None:
        self.lower, self.upper, self.magnitude = lower, upper, magnitude
        has_lower, has_upper = np.isfinite(lower), np.isfinite(upper)
        self.both = has_lower & has_upper
        self.only_lower = has_lower & ~has_upper
        self.only_upper = has_upper & ~has_lower
        self.free = ~(has_lower | has_upper)

    def internal(self, theta: np.ndarray) -> np.ndarray:
        theta = np.clip(theta, self.lower, self.upper)
        z = np.where(self.free, theta / self.magnitude, 0.0)
        lo, up = self.lower, self.upper
        with np.errstate(invalid="ignore", divide="ignore"):
            # ϑ = arcsin(2(θ − l)/(u − l) − 1)
            both = np.arcsin(np.clip(2.0 * (theta - lo) / (up - lo) - 1.0, -1.0, 1.0))
            # ϑ = √((θ − l + 1)² − 1),  ϑ = √((u − θ + 1)² − 1)
            lower = np.sqrt(np.maximum((theta - lo + 1.0) ** 2 - 1.0, 0.0))
            upper = np.sqrt(np.maximum((up - theta + 1.0) ** 2 - 1.0, 0.0))
        z = np.where(self.both, both, z)
        z = np.where(self.only_lower, lower, z)
        return np.where(self.only_upper, upper, z)

    def external(self, z: np.ndarray) -> np.ndarray:
        lo, up = self.lower, self.upper
        with np.errstate(invalid="ignore"):
            both = lo + (up - lo) * (np.sin(z) + 1.0) / 2.0
            lower = lo - 1.0 + np.sqrt(z**2 + 1.0)
            upper = up + 1.0 - np.sqrt(z**2 + 1.0)
        theta = np.where(self.free, z * self.magnitude, 0.0)
        theta = np.where(self.both, both, theta)
        theta = np.where(self.only_lower, lower, theta)
        theta = np.where(self.only_upper, upper, theta)
        return np.clip(theta, lo, up)


@named_settings
@dataclass(frozen=True)
class FPS:
    """Nelder–Mead flexible polyhedron search.

    Attributes:
        initial_size: edge of the starting simplex, relative to max(|θ_j|, typical_j).
        reflection, expansion, contraction, shrink: the classical coefficients.
    """

    initial_size: float = 0.05
    reflection: float = 1.0
    expansion: float = 2.0
    contraction: float = 0.5
    shrink: float = 0.5
    max_restarts: int = 5

    name = "fps"

    def __post_init__(self) -> None:
        check_setting_types(self)
        if not self.initial_size > 0:
            raise InputError(f"FPS.initial_size: expected > 0, got {self.initial_size!r}")
        if not (0 < self.contraction < 1 and 0 < self.shrink < 1 and self.expansion > 1):
            raise InputError("FPS: expected 0 < contraction, shrink < 1 and expansion > 1")
        if not self.reflection > 0:
            raise InputError(f"FPS.reflection: expected > 0, got {self.reflection!r}")
        if self.max_restarts < 0:
            raise InputError(f"FPS.max_restarts: expected ≥ 0, got {self.max_restarts!r}")

    def settings(self) -> dict:
        return {
            "initial_size": self.initial_size,
            "reflection": self.reflection,
            "expansion": self.expansion,
            "contraction": self.contraction,
            "shrink": self.shrink,
            "max_restarts": self.max_restarts,
        }

    def minimize(self, objective: Objective, theta0: np.ndarray, state=None) -> SolverOutcome:
        """Simplex searches restarted from the best vertex until a restart gains nothing."""
        conv = objective.convergence
        outcome = self._search(objective, theta0, state)
        iterations = outcome.iterations
        for _ in range(self.max_restarts):
            if not outcome.converged:
                break
            previous = outcome
            outcome = self._search(objective, previous.theta, None, start=previous)
            iterations += outcome.iterations
            if outcome.converged and conv.cost_settled(previous.cost, outcome.cost):
                break
        return replace(outcome, iterations=iterations)

    def _search(
        self,
        objective: Objective,
        theta0: np.ndarray,
        state=None,
        start: SolverOutcome | None = None,
    ) -> SolverOutcome:
        conv = objective.convergence
        problem = objective.problem
        typical = objective.typical
        if state is not None:
            vertices, outputs, coordinates = state
            costs = objective.costs_of(outputs)
        else:
            theta = np.array(theta0, dtype=float)
            if start is None:
                cost, start_outputs = objective.evaluate_start(theta)
                objective.record(theta, cost)
            else:
                cost, start_outputs = start.cost, start.outputs
            magnitude = problem.magnitude(theta)
            coordinates = _Coordinates(problem.lower, problem.upper, magnitude)
            deltas = self.initial_size * magnitude
            # a vertex that would cross a bound goes the other way (and stays inside the box)
            deltas = np.where(theta + deltas > problem.upper, -deltas, deltas)
            others = problem.project(theta[None, :] + np.diag(deltas))
            other_costs, other_outputs = objective.evaluate(others)
            vertices = coordinates.internal(np.vstack([theta[None, :], others]))
            outputs = np.concatenate([start_outputs[None], other_outputs])
            costs = np.concatenate([[cost], other_costs])
        to_theta = coordinates.external

        def trial(point: np.ndarray) -> tuple[float, np.ndarray]:
            c, y = objective.evaluate(to_theta(point)[None, :])
            return float(c[0]), y[0]

        for iteration in range(1, conv.max_iterations + 1):
            order = np.argsort(costs)
            vertices, outputs, costs = vertices[order], outputs[order], costs[order]
            best_previous = costs[0]
            if objective.budget_exhausted():
                return self._outcome(
                    vertices,
                    outputs,
                    costs,
                    coordinates,
                    iteration - 1,
                    False,
                    *budget_status(objective),
                )
            centroid = vertices[:-1].mean(axis=0)
            worst = vertices[-1]
            reflected = centroid + self.reflection * (centroid - worst)
            c_r, y_r = trial(reflected)
            if c_r < costs[0]:
                expanded = centroid + self.expansion * (reflected - centroid)
                c_e, y_e = trial(expanded)
                if c_e < c_r:
                    vertices[-1], outputs[-1], costs[-1] = expanded, y_e, c_e
                else:
                    vertices[-1], outputs[-1], costs[-1] = reflected, y_r, c_r
            elif c_r < costs[-2]:
                vertices[-1], outputs[-1], costs[-1] = reflected, y_r, c_r
            else:
                if c_r < costs[-1]:
                    contracted = centroid + self.contraction * (reflected - centroid)
                else:
                    contracted = centroid + self.contraction * (worst - centroid)
                c_c, y_c = trial(contracted)
                if c_c < min(c_r, costs[-1]):
                    vertices[-1], outputs[-1], costs[-1] = contracted, y_c, c_c
                else:
                    vertices[1:] = vertices[0] + self.shrink * (vertices[1:] - vertices[0])
                    shrunk_costs, shrunk_outputs = objective.evaluate(to_theta(vertices[1:]))
                    costs[1:], outputs[1:] = shrunk_costs, shrunk_outputs
            best = int(np.argmin(costs))
            objective.record(to_theta(vertices[best]), costs[best])
            relative = conv.relative_cost_change(best_previous, costs[best])
            noise_settled = objective.maxlik_update(outputs[best], relative)
            if noise_settled is not None:
                costs = objective.costs_of(outputs)
            spread_cost = float(np.max(costs) - np.min(costs))
            in_theta = to_theta(vertices)
            spread_theta = np.max(in_theta, axis=0) - np.min(in_theta, axis=0)
            settled = (
                np.all(np.isfinite(costs))
                and conv.cost_settled(float(np.min(costs)), float(np.min(costs)) + spread_cost)
                and conv.params_settled(spread_theta, in_theta[best], typical)
                and noise_settled is not False
            )
            if settled:
                return self._outcome(
                    vertices,
                    outputs,
                    costs,
                    coordinates,
                    iteration,
                    True,
                    "converged",
                    "converged: simplex cost and parameter spreads below tolerance",
                )
        return self._outcome(
            vertices,
            outputs,
            costs,
            coordinates,
            conv.max_iterations,
            False,
            "max_iterations",
            f"stopped after {conv.max_iterations} iterations without converging",
        )

    @staticmethod
    def _outcome(vertices, outputs, costs, coordinates, iterations, converged, status, message):
        best = int(np.argmin(costs))
        return SolverOutcome(
            coordinates.external(vertices[best]),
            outputs[best],
            float(costs[best]),
            iterations,
            converged,
            status,
            message,
            state=(vertices, outputs, coordinates),
        )
