"""FPS — flexible polyhedron search (Nelder–Mead simplex), the derivative-free benchmark.

n_f + 1 vertices in scaled parameter space ϑ = θ / typical (RP-1153 §8). Each pass replaces
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
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from flightid.errors import InputError
from flightid.estimation.objective import Objective, SolverOutcome
from flightid.estimation.solvers.common import budget_status

__all__ = ["FPS"]


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
        if not self.initial_size > 0:
            raise InputError(f"FPS.initial_size: expected > 0, got {self.initial_size!r}")
        if not (0 < self.contraction < 1 and 0 < self.shrink < 1 and self.expansion > 1):
            raise InputError("FPS: expected 0 < contraction, shrink < 1 and expansion > 1")

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
        typical = objective.typical
        if state is not None:
            vertices, outputs = state
            costs = objective.costs_of(outputs)
        else:
            theta = np.array(theta0, dtype=float)
            if start is None:
                cost, start_outputs = objective.evaluate_start(theta)
                objective.record(theta, cost)
            else:
                cost, start_outputs = start.cost, start.outputs
            magnitude = np.maximum(np.abs(theta), typical)
            others = theta[None, :] + np.diag(self.initial_size * magnitude)
            other_costs, other_outputs = objective.evaluate(others)
            vertices = np.vstack([theta[None, :], others]) / typical
            outputs = np.concatenate([start_outputs[None], other_outputs])
            costs = np.concatenate([[cost], other_costs])

        def trial(point: np.ndarray) -> tuple[float, np.ndarray]:
            c, y = objective.evaluate((point * typical)[None, :])
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
                    typical,
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
                    shrunk_costs, shrunk_outputs = objective.evaluate(vertices[1:] * typical)
                    costs[1:], outputs[1:] = shrunk_costs, shrunk_outputs
            best = int(np.argmin(costs))
            objective.record(vertices[best] * typical, costs[best])
            relative = conv.relative_cost_change(best_previous, costs[best])
            noise_settled = objective.maxlik_update(outputs[best], relative)
            if noise_settled is not None:
                costs = objective.costs_of(outputs)
            spread_cost = float(np.max(costs) - np.min(costs))
            spread_theta = (np.max(vertices, axis=0) - np.min(vertices, axis=0)) * typical
            settled = (
                np.all(np.isfinite(costs))
                and conv.cost_settled(float(np.min(costs)), float(np.min(costs)) + spread_cost)
                and conv.params_settled(spread_theta, vertices[best] * typical, typical)
                and noise_settled is not False
            )
            if settled:
                return self._outcome(
                    vertices,
                    outputs,
                    costs,
                    typical,
                    iteration,
                    True,
                    "converged",
                    "converged: simplex cost and parameter spreads below tolerance",
                )
        return self._outcome(
            vertices,
            outputs,
            costs,
            typical,
            conv.max_iterations,
            False,
            "max_iterations",
            f"stopped after {conv.max_iterations} iterations without converging",
        )

    @staticmethod
    def _outcome(vertices, outputs, costs, typical, iterations, converged, status, message):
        best = int(np.argmin(costs))
        return SolverOutcome(
            vertices[best] * typical,
            outputs[best],
            float(costs[best]),
            iterations,
            converged,
            status,
            message,
            state=(vertices, outputs),
        )
