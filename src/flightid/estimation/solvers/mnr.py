"""MNR — modified Newton–Raphson (Gauss–Newton) with finite-difference sensitivities.

Each pass [RP-1153 4.4–4.8]: sensitivities G_i = ∂y_i/∂θ by forward (n_f integrations, in one
batch) or central (2·n_f) differences at the current θ, the Gauss–Newton step
Δθ = −M⁻¹g, then step-size control (halving) until the cost drops. The integration at the
accepted point is the base of the next pass, so a forward-difference pass costs n_f + 1
equivalent evaluations plus one per halving.

When a pass ends the search (its step is negligible), the forward differences it took at θ̂
go out with the outcome (``SolverOutcome.differences``): the confirmation completes them to
central differences with the n_f backward integrations only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flightid.errors import InputError, SimulationError
from flightid.estimation.objective import Objective, SolverOutcome
from flightid.estimation.solvers.common import (
    bounded_gauss_newton_step,
    budget_status,
    check_setting_types,
    halving_search,
    limit_step,
    named_settings,
)

__all__ = ["MNR"]


@named_settings
@dataclass(frozen=True)
class MNR:
    """Gauss–Newton with finite-difference sensitivities.

    Attributes:
        relative_step: finite-difference step, relative to max(|θ_j|, typical_j).
        central: central differences (2·n_f integrations per pass) instead of forward.
        sensitivities: ``"differences"`` (finite differences of whole integrations, the
            default) or ``"equations"`` (the sensitivity equations integrated with the
            states, "analytic" MNR: 1 + n_s + n_f equivalent evaluations per pass, and
            ``relative_step`` / ``central`` do not apply).
        max_halvings: step-size halvings tried before declaring a stall.
        max_relative_step: no parameter moves more than this fraction of max(|θ_j|, scale_j)
            in one pass (the step is shortened, its direction kept); off by default: on the
            benchmark problems a bound of 0.5 cost MNR 1.3–2× more simulations.
    """

    relative_step: float = 1e-6
    central: bool = False
    sensitivities: str = "differences"
    max_halvings: int = 10
    max_relative_step: float = math.inf

    name = "mnr"

    def __post_init__(self) -> None:
        check_setting_types(self)
        if not 0 < self.relative_step < 1:
            raise InputError(f"MNR.relative_step: expected 0 < step < 1, got {self.relative_step}")
        if self.sensitivities not in ("differences", "equations"):
            raise InputError(
                "MNR.sensitivities: expected 'differences' or 'equations', "
                f"got {self.sensitivities!r}"
            )
        if self.max_halvings < 0:
            raise InputError(f"MNR.max_halvings: expected ≥ 0, got {self.max_halvings}")
        if not self.max_relative_step > 0:
            raise InputError(
                f"MNR.max_relative_step: expected > 0 (math.inf: off), got {self.max_relative_step}"
            )

    def settings(self) -> dict:
        return {
            "relative_step": self.relative_step,
            "central": self.central,
            "sensitivities": self.sensitivities,
            "max_halvings": self.max_halvings,
            "max_relative_step": None
            if math.isinf(self.max_relative_step)
            else self.max_relative_step,
        }

    def minimize(self, objective: Objective, theta0: np.ndarray, state=None) -> SolverOutcome:
        problem = objective.problem
        conv = objective.convergence
        g = None  # sensitivities at θ; they do not depend on R, so a new noise cycle reuses them
        differences = None  # how g was taken, when by this problem's forward differences
        if state is not None:
            theta, outputs, g, differences = state
            cost = float(objective.costs_of(outputs)[0])
        else:
            theta = np.array(theta0, dtype=float)
            cost, outputs = objective.evaluate_start(theta)
            objective.record(theta, cost)

        def outcome(iterations, converged, status, message):
            return SolverOutcome(
                theta,
                outputs,
                cost,
                iterations,
                converged,
                status,
                message,
                state=(theta, outputs, g, differences),
                differences=differences if g is not None else None,
            )

        for iteration in range(1, conv.max_iterations + 1):
            if objective.budget_exhausted():
                return outcome(iteration - 1, False, *budget_status(objective))
            try:
                if g is None and self.sensitivities == "equations":
                    g, _ = problem.sensitivities_from_equations(theta)
                elif g is None and problem.finite_differences:
                    differences = problem.differences(
                        theta, outputs, self.relative_step, self.central
                    )
                    g = differences.g
                elif g is None:
                    g, _ = problem.sensitivities(theta, outputs, self.relative_step, self.central)
            except SimulationError as exc:
                return outcome(
                    iteration - 1,
                    False,
                    "stalled",
                    f"stalled: the perturbed simulations for the sensitivities diverge here "
                    f"({exc})",
                )
            gn = bounded_gauss_newton_step(objective, g, outputs, theta)
            if conv.step_settled(gn, theta, problem.typical, cost):
                return outcome(
                    iteration,
                    True,
                    "converged",
                    "converged: the next step and the cost drop it predicts are below tolerance",
                )
            step = limit_step(gn.step, theta, problem.typical, self.max_relative_step)
            accepted = halving_search(
                objective, theta, cost, step, self.max_halvings, gauss_newton=gn
            )
            if accepted is None:
                if conv.params_settled(gn.step, theta, problem.typical):
                    return outcome(
                        iteration,
                        True,
                        "converged",
                        "converged: the Gauss–Newton step is below the parameter "
                        "tolerance and no shorter step lowers the cost",
                    )
                if objective.budget_exhausted():
                    return outcome(iteration, False, *budget_status(objective))
                return outcome(
                    iteration,
                    False,
                    "stalled",
                    f"stalled: no step length down to 2^-{self.max_halvings} lowered the cost",
                )
            new_theta, new_cost, new_outputs, taken = accepted
            relative = conv.relative_cost_change(cost, new_cost)
            settled = conv.cost_settled(cost, new_cost) and conv.params_settled(
                taken, new_theta, problem.typical
            )
            theta, cost, outputs, g, differences = new_theta, new_cost, new_outputs, None, None
            objective.record(theta, cost)
            noise_settled = objective.maxlik_update(outputs, relative)
            if noise_settled is not None:
                cost = float(objective.costs_of(outputs)[0])
                settled = settled and noise_settled
            if settled:
                return outcome(
                    iteration,
                    True,
                    "converged",
                    "converged: cost and parameter changes below tolerance",
                )
        return outcome(
            conv.max_iterations,
            False,
            "max_iterations",
            f"stopped after {conv.max_iterations} iterations without converging",
        )
