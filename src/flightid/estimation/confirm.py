"""Confirming a solver's "converged" with sensitivities that are not its own.

A solver stops on its own tests (``Convergence``), judged with its own sensitivities — for
MNRES a surface through past points that may be stale, for MNR forward differences. Before
``estimate`` reports convergence it recomputes the sensitivities by central differences at
the solver's end point (2·n_f integrations, the ones the Cramér–Rao bounds need anyway) and
takes the Gauss–Newton step Δθ they give, with parameters on an active bound held:

    √(ΔθᵀMΔθ) ≤ confirm_sigma     →  confirmed (the optimum is within that many σ)

Otherwise it continues with Gauss–Newton passes (on central differences, or on their forward
half, below; step halving along the projected path; under the MAX / MAXLIK policies R is
re-estimated [3.45] after each pass) until the test holds, no step lowers the cost
(``stalled``), or the passes or the evaluation budget run out. A solver that *stalled* is
continued the same way, and so is MNRES when it reached ``max_iterations`` (it falls back to
finite-difference Gauss–Newton steps, within ``max_confirmation_passes``). A solver that
spent the evaluation budget, or MNR / FPS at ``max_iterations``, is not continued. Whatever
the solver said, its end point counts as converged exactly when the test holds there;
otherwise its status stands and the message says how far the optimum may be, in σ. M is
weighted by the residuals' own R̂ (see ``Convergence``), so the σ are those of the data's
noise even under a fixed R.

Central differences at the end point, half of them already paid for: when the solver's last
pass took forward differences at that very point with the confirmation's own steps
δ_j = 10⁻⁶·max(|θ_j|, floor_j) (MNR's default; ``SolverOutcome.differences``), only the n_f
backward integrations are run, and (G⁺_j + G⁻_j)/2 = (y(θ + δ_j e_j) − y(θ − δ_j e_j))/(2δ_j)
is the central difference, equal to rounding to the one computed from scratch
(``OutputErrorProblem.complete_central``). The derivatives stay fresh (all taken at θ̂, none
from an earlier point), so the test means what it meant. Why the relative step 10⁻⁶ rather
than 10⁻⁷: the central difference's error is about δ²·|y‴|/6 + ε·|y|/δ, and at 10⁻⁷ the
rounding term is ten times that at 10⁻⁶ while the truncation term is negligible at both.

Forward half first: where the forward differences can be completed, the forward
half is taken first (n_f integrations, or the solver's) and the Gauss–Newton step on it
judged. If it fails the test, its *full* step is tried (one integration); a step that lowers
the cost shows the point was not the minimum, so it is taken and the backward half there is
never run — n_f + 1 integrations for the pass instead of 2·n_f + 1, the cost of an MNR pass.
The forward differences are completed to central ones when their step passes the test, or
when the full step does not lower the cost (then central differences, with halving and
damping, decide every later pass too). So "converged" is still decided only on central
differences at the end point, and the Cramér–Rao bounds use them; forward differences only
choose steps that lower the cost, as in MNR. Not for problems with bounds (their differences
are not ``FiniteDifferences.plain``), analytic sensitivities, or a solver that stalled.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightid.errors import SimulationError
from flightid.estimation.gauss_newton import GaussNewtonStep
from flightid.estimation.objective import Objective, SolverOutcome
from flightid.estimation.problem import FiniteDifferences
from flightid.estimation.solvers.common import bounded_gauss_newton_step, halving_search

__all__ = [
    "Confirmation",
    "confirm_convergence",
    "confirmed_message",
    "continued_message",
    "solver_stop",
]

# relative step of the central differences (also those of the CR bounds); MNR's default
# forward step, so that MNR's last forward differences are half of them (module docstring)
_CENTRAL_STEP = 1e-6


@dataclass(frozen=True)
class Confirmation:
    """The outcome after confirmation, with the sensitivities at its point."""

    outcome: SolverOutcome
    sensitivities: np.ndarray  # central-difference G at outcome.theta (N, n_o, n_f)
    step: GaussNewtonStep  # the Gauss–Newton step from there
    passes: int  # Gauss–Newton passes taken after the solver stopped
    initial_sigma: float  # √(ΔθᵀMΔθ) where the solver stopped (on the first G taken there)
    sigma: float  # √(ΔθᵀMΔθ) at the end point (M weighted by R̂)
    sensitivity_evaluations: int  # integrations of the last central-difference G (both
    # halves when the confirmation took its forward half; the backward half alone when the
    # solver's last pass had taken the forward one)


def _reusable(problem, forward: FiniteDifferences | None, theta: np.ndarray) -> bool:
    """Are ``forward`` the plain forward half of the central differences at θ?"""
    return (
        forward is not None
        and forward.plain
        and not forward.central
        and np.array_equal(forward.theta, theta)
        and np.array_equal(forward.steps, _CENTRAL_STEP * problem.magnitude(theta))
    )


def _advance(objective, accepted, policy: str):
    """(θ, cost, outputs) after an accepted confirming step ``accepted`` (a
    ``halving_search`` result): the pass recorded, R re-estimated from the new outputs and
    the cost recomputed under it unless the noise policy is "fixed"."""
    theta, cost, outputs, _ = accepted
    objective.record(theta, cost, outputs)
    if policy != "fixed":
        objective.update_noise(outputs)
        cost = float(objective.costs_of(outputs)[0])
    return theta, cost, outputs


def _central(
    objective: Objective,
    theta: np.ndarray,
    outputs: np.ndarray,
    forward: FiniteDifferences | None = None,
):
    """Central-difference G at θ (one-sided where a perturbation diverges), its cost in
    integrations, and None or the reason it could not be computed. ``forward``: the
    solver's forward differences at θ, completed in place when they are the plain forward
    half (``_reusable``)."""
    problem = objective.problem
    before = problem.evaluations
    if _reusable(problem, forward, theta):
        completed = problem.complete_central(forward)
        if completed is not None:
            return completed.g, problem.evaluations - before, None
        # a backward integration diverged: from scratch (one-sided there, as always)
    try:
        g, _ = problem.sensitivities(theta, outputs, relative_step=_CENTRAL_STEP, central=True)
    except SimulationError as exc:
        g = np.zeros((problem.n_samples, problem.n_outputs, problem.n_free))
        return g, problem.evaluations - before, str(exc)
    return g, problem.evaluations - before, None


def _sigma_distance(problem, g: np.ndarray, step: np.ndarray, outputs: np.ndarray) -> float:
    """√(ΔθᵀMΔθ) with M = Σ GᵀR̂⁻¹G, R̂ the residuals' covariance [3.45] at ``outputs``.

    ΔθᵀMΔθ = Σ_i Σ_k (G_i Δθ)_k² / R̂_k: the step's length in Cramér–Rao σ of the data's own
    noise level, whatever R the cost is weighted with.
    """
    r_hat = problem.noise_covariance(outputs)
    change = np.einsum("ikj,j->ik", g, step)  # (N, n_o): G_i Δθ, no copy of a strided G
    return float(np.sqrt(np.sum(change**2 / r_hat[None, :])))


def _noise_settled(objective: Objective, policy: str, outputs: np.ndarray) -> bool:
    """Re-estimate R at ``outputs`` (MAX / MAXLIK) if it moved more than noise_rtol."""
    if policy == "fixed":
        return True
    new = objective.problem.noise_covariance(outputs)
    change = float(np.max(np.abs(new - objective.r_diag) / objective.r_diag))
    if change <= objective.convergence.noise_rtol:
        return True
    objective.update_noise(outputs)
    return False


# how the solver's stop reads inside a confirmation's message (by the solver's status)
_SOLVER_STOPS = {
    "converged": "its own tests stopped the solver",
    "stalled": "the solver stalled",
    "max_iterations": "the solver reached its pass limit",
    "max_evaluations": "the solver spent its evaluation budget",
}


def solver_stop(status: str) -> str:
    """The solver's stop in a few words, by its status (its own message is not quoted)."""
    return _SOLVER_STOPS.get(status, f"the solver stopped ({status})")


def continued_message(passes: int, distance: float, initial: float, status: str) -> str:
    """One sentence for an end point reached by confirming passes: what they did and why."""
    plural = "es" if passes != 1 else ""
    return (
        f"converged: {passes} further Gauss–Newton pass{plural} on central differences reached "
        f"the optimum (next step {distance:.2g} σ) after {solver_stop(status)} "
        f"{initial:.3g} σ short of it"
    )


def confirmed_message(distance: float, status: str) -> str:
    """One sentence for a solver's end point that central differences confirm although
    the solver did not call it converged."""
    return (
        f"converged: central differences confirm the optimum within {distance:.2g} σ where "
        f"{solver_stop(status)}"
    )


@dataclass
class _Walk:
    """Where the confirming passes stand (the loop's state, shared with its helpers)."""

    theta: np.ndarray
    cost: float
    outputs: np.ndarray
    # the solver's last forward differences at θ (consumed: completed in place, then dropped)
    forward: FiniteDifferences | None
    # steps on forward differences (module docstring): where they can be completed, while a
    # step is possible at all, and until a full step on them fails to lower the cost
    on_forward: bool
    forward_used: int = 0  # integrations spent on ``forward`` here (0: the solver's)
    passes: int = 0
    initial: float = float("nan")

    def advance(self, objective: Objective, accepted, policy: str) -> None:
        self.theta, self.cost, self.outputs = _advance(objective, accepted, policy)
        self.passes += 1

    def judged(self, objective: Objective, g: np.ndarray) -> tuple[GaussNewtonStep, float]:
        """The Gauss–Newton step on ``g`` at θ and its length in σ (the first one kept)."""
        gn = bounded_gauss_newton_step(objective, g, self.outputs, self.theta)
        distance = _sigma_distance(objective.problem, g, gn.step, self.outputs)
        if np.isnan(self.initial):
            self.initial = distance
        return gn, distance


def _forward_step(objective: Objective, walk: _Walk, policy: str) -> bool:
    """A pass on forward differences when they show the point is not the optimum and their
    full step lowers the cost (module docstring); True when it was taken."""
    problem, conv = objective.problem, objective.convergence
    if walk.on_forward and walk.forward is None and not objective.budget_exhausted():
        before = problem.evaluations
        try:
            walk.forward = problem.differences(
                walk.theta, walk.outputs, _CENTRAL_STEP, central=False
            )
        except SimulationError:
            walk.forward = None  # central differences below say what diverges
        walk.forward_used = problem.evaluations - before
    if not (walk.on_forward and _reusable(problem, walk.forward, walk.theta)):
        return False
    gn, distance = walk.judged(objective, walk.forward.g)
    if (
        conv.confirmed(distance, gn, problem.magnitude(walk.theta))
        or walk.passes >= conv.max_confirmation_passes
    ):
        return False
    # far enough that forward differences can tell: the full step, if it lowers the cost,
    # is taken without the backward half
    accepted = halving_search(objective, walk.theta, walk.cost, gn.step, 0)
    if accepted is None:
        # it did not: central differences decide from here on
        walk.on_forward = False
        return False
    walk.forward = None
    walk.advance(objective, accepted, policy)
    return True


def _confirmed_here(objective: Objective, walk: _Walk, policy: str, g: np.ndarray):
    """(confirmed, Gauss–Newton step, its length in σ) on central differences ``g`` at the
    walk's point; R re-estimated there first when it moved (MAX / MAXLIK)."""
    problem, conv = objective.problem, objective.convergence
    gn, distance = walk.judged(objective, g)
    if not conv.confirmed(distance, gn, problem.magnitude(walk.theta)):
        return False, gn, distance
    if _noise_settled(objective, policy, walk.outputs):
        return True, gn, distance
    # R moved: same sensitivities, new weights
    walk.cost = float(objective.costs_of(walk.outputs)[0])
    gn, distance = walk.judged(objective, g)
    return conv.confirmed(distance, gn, problem.magnitude(walk.theta)), gn, distance


def _stop(objective: Objective, walk: _Walk, may_continue: bool, outcome, gn, distance):
    """(status, message) when the passes must end unconfirmed here, else None."""
    conv = objective.convergence
    if not may_continue:
        return outcome.status, (
            f"{outcome.message}; a Gauss–Newton step from central differences would still "
            f"move the estimate by {distance:.3g} Cramér–Rao σ (predicted cost drop "
            f"{gn.predicted_reduction:.3g})"
        )
    if walk.passes >= conv.max_confirmation_passes or objective.budget_exhausted():
        status = "max_evaluations" if objective.budget_exhausted() else "max_iterations"
        return status, (
            f"not converged: the solver stopped, but after {walk.passes} Gauss–Newton passes "
            f"on central differences the next step would still move the estimate by "
            f"{distance:.3g} Cramér–Rao σ (tolerance {conv.confirm_sigma})"
        )
    return None


def confirm_convergence(
    objective: Objective, outcome: SolverOutcome, policy: str, fallback: bool = False
) -> Confirmation:
    """Confirm (or continue, or deny) the solver's outcome; see the module docstring.

    The outcome's message is one sentence, "status: what happened last (why)": the solver's
    own message when its end point is confirmed as it stands, else one composed here that
    names the solver's stop in a few words (``solver_stop``) without quoting its message.

    Args:
        objective: the objective the solver minimised (its R and budget).
        outcome: where the solver stopped.
        policy: the noise policy ("fixed", "max", "maxlik").
        fallback: continue from ``max_iterations`` too (MNRES falls back to these passes).
    """
    problem = objective.problem
    solver_status = outcome.status
    may_continue = (
        outcome.converged
        or outcome.status == "stalled"
        or (fallback and outcome.status == "max_iterations")
    )
    # not after a stall: the solver's own step on its forward differences failed there
    walk = _Walk(
        outcome.theta,
        float(objective.costs_of(outcome.outputs)[0]),
        outcome.outputs,
        outcome.differences,
        may_continue
        and outcome.status != "stalled"
        and problem.finite_differences
        and not problem.bounded,
    )
    outcome = _replace(
        outcome,
        walk.theta,
        walk.outputs,
        walk.cost,
        outcome.converged,
        outcome.status,
        outcome.message,
    )
    while True:
        g = None  # the last pass's G goes before the next is computed (one G at a time)
        if _forward_step(objective, walk, policy):
            continue
        g, used, failure = _central(objective, walk.theta, walk.outputs, walk.forward)
        # the forward half taken here at this point belongs to the end point's G too
        used += walk.forward_used
        walk.forward, walk.forward_used = None, 0
        if failure is not None:
            # no sensitivities here: nothing can be confirmed, and there are no CR bounds
            gn = GaussNewtonStep(np.zeros(problem.n_free), 0, float("inf"), float("nan"))
            message = (
                f"not converged: the perturbed simulations for the sensitivities diverge at "
                f"the end point ({failure}), where {solver_stop(solver_status)}"
            )
            outcome = _replace(
                outcome, walk.theta, walk.outputs, walk.cost, False, "stalled", message
            )
            return Confirmation(outcome, g, gn, walk.passes, walk.initial, float("nan"), used)
        confirmed, gn, distance = _confirmed_here(objective, walk, policy, g)
        if confirmed:
            break
        stop = _stop(objective, walk, may_continue, outcome, gn, distance)
        if stop is None:
            accepted = halving_search(
                objective, walk.theta, walk.cost, gn.step, 10, gauss_newton=gn
            )
            if accepted is not None:
                walk.advance(objective, accepted, policy)
                continue
            stop = (
                "stalled",
                (
                    "not converged: the solver stopped, but a Gauss–Newton step from "
                    f"central-difference sensitivities predicts a cost drop of "
                    f"{gn.predicted_reduction:.3g} ({distance:.3g} Cramér–Rao σ) that no step "
                    "length down to 2^-10 nor any Levenberg–Marquardt damping realises"
                ),
            )
        outcome = _replace(outcome, walk.theta, walk.outputs, walk.cost, False, *stop)
        return Confirmation(outcome, g, gn, walk.passes, walk.initial, distance, used)
    if walk.passes:
        message = continued_message(walk.passes, distance, walk.initial, solver_status)
    elif not outcome.converged:
        message = confirmed_message(distance, solver_status)
    else:
        message = outcome.message
    outcome = _replace(outcome, walk.theta, walk.outputs, walk.cost, True, "converged", message)
    return Confirmation(outcome, g, gn, walk.passes, walk.initial, distance, used)


def _replace(outcome, theta, outputs, cost, converged, status, message) -> SolverOutcome:
    return SolverOutcome(
        theta,
        outputs,
        cost,
        outcome.iterations,
        converged,
        status,
        message,
        # the solver's warm-start state and forward differences end here (their G may have
        # been completed in place into the confirmation's)
    )
