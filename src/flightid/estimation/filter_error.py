"""The filter error method: maximum likelihood with process noise (Jategaonkar ch. 5).

Model:

    ẋ(t) = f(x, u, θ) + F w(t),   F = diag(F_11, …) (parameters),  w: unit white noise
    z_k  = g(x_k, u_k, θ) + v_k

A steady-state Kalman filter runs in every evaluation (a *filter pass*):

    ỹ_k = g(x̃_k, u_k)                  x̃_1 = x0 (each maneuver restarts at its x0)
    e_k = z_k − ỹ_k                     (innovation)
    x̂_k = x̃_k + K e_k                   (correction)
    x̃_{k+1} = RK4 of ẋ = f(x, u) from x̂_k over [t_k, t_{k+1}]   (prediction)

with K = P Cᵀ R⁻¹ and P the stabilising solution of A P + P Aᵀ − (1/Δt) P CᵀR⁻¹C P + FFᵀ = 0
(``flightid.filtering.kalman``), A = ∂f/∂x and C = ∂g/∂x by central differences (Δx = 1e-4)
at the linearisation point (x0 of the first maneuver, u_1: the reference's choice; for a
linear model the point does not matter). R is the weighting, the innovations' covariance.

``FilterErrorProblem`` is an ``OutputErrorProblem`` whose "outputs" are the filtered
predictions ỹ and whose residuals are the innovations: for a given weighting R (held in the
problem as ``gain_r``, used for the gain and the cost), the negative log-likelihood is
Σ eᵀR⁻¹e + const, and every piece of output-error machinery — MNR and MNRES, the halving
search, the Gauss–Newton step and the central-difference confirmation — runs on it
unchanged. One filter pass is one equivalent evaluation.

The constraint diag(KC) ≤ 1 (a larger element would mean a negative measurement-noise
variance, R − CPCᵀ) is enforced by the problem: a θ that violates it gives no filter pass
(it is reported like a diverged simulation, cost +∞), so the step control keeps every
accepted iterate feasible; where the optimum lies on the constraint, the estimator *pins*
the state's F element (``FilterErrorProblem(pinned=...)``: solved for every θ from
diag(KC)_i = 1, no longer free) — an active set, released when lowering the element lowers
the cost. The reference schedule (``relaxation="reference"``) instead corrects each
Gauss–Newton step with the linearised constraint, as FVSysID's ``ml_fem2`` does
(``flightid.estimation.filter_reference``).

R and F are both estimated. The estimate the book defines is the fixed point where θ (system
parameters and F) is Gauss–Newton-optimal under the weighting R and R equals the innovations'
covariance, R = diag((1/N) Σ e_k e_kᵀ). ``relaxation="fixed_point"`` (default) reaches it
directly: improve θ with R held (a well-posed ML problem: R fixed, gain and cost consistent),
set R to the innovations' covariance, repeat until R moves by less than ``r_rtol``. With
``cycles="warm"`` (default, MNR) each cycle takes one Gauss–Newton step and the end point is
confirmed once (``_warm_cycles``); ``cycles="full"`` converges and confirms θ under every R. No step
of it needs the book's heuristic F compensation, which only tries to keep K unchanged across
an R update so that a single schedule of steps converges; both schedules stop at the same
fixed point (tests/test_filter_error.py, docs/turbulence.md).
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from flightid.coloured import default_sigma
from flightid.data.flightdata import FlightData
from flightid.errors import InputError, InputTypeError, describe
from flightid.estimation.confirm import confirm_convergence
from flightid.estimation.convergence import Convergence
from flightid.estimation.driver import _covariance, check_call_options
from flightid.estimation.filter_error_linear import LinearFilterErrorProblem
from flightid.estimation.filter_error_problem import (  # noqa: F401 (public here too)
    KC_TOLERANCE,
    LINEARISATIONS,
    FilterErrorProblem,
    FilterPoint,
    process_noise_name,
)
from flightid.estimation.gauss_newton import information_matrix
from flightid.estimation.objective import Objective
from flightid.estimation.progress import RunProgress, next_stage
from flightid.estimation.result import Estimate
from flightid.estimation.solvers import MNR, MNRES
from flightid.filtering.kalman import RiccatiError
from flightid.model.check import check_model
from flightid.model.statespace import StateSpaceModel

__all__ = [
    "FilterErrorProblem",
    "FilterPoint",
    "estimate_filter_error",
    "RELAXATIONS",
    "LINEARISATIONS",
    "process_noise_name",
]

RELAXATIONS = ("fixed_point", "reference")
#: how ``relaxation="fixed_point"`` spends its filter passes between R updates: "warm" (one
#: Gauss–Newton step per R update, the end point confirmed once) or "full" (θ converged and
#: confirmed under every R)
CYCLES = ("warm", "full")


# ---------------------------------------------------------------------- the estimator


@dataclass
class _Trace:
    """Histories over all cycles and active sets."""

    costs: list[float] = field(default_factory=list)
    log_det_r: list[float] = field(default_factory=list)  # ln det of the innovations' R̂
    r_history: list[tuple[float, ...]] = field(default_factory=list)  # R of each cost
    evaluations: list[int] = field(default_factory=list)
    r_updates: list[int] = field(default_factory=list)
    iterations: int = 0
    cycles: int = 0
    passes: int = 0  # filter passes of the problems already finished

    def record(self, objective: Objective, problem: FilterErrorProblem) -> None:
        self.r_updates.append(len(self.costs))
        self.costs.extend(objective.cost_history)
        self.log_det_r.extend(objective.log_det_r_history)
        self.r_history.extend(tuple(float(v) for v in r) for r in objective.r_history)
        # filter passes of the run: finished problems, this problem's before the objective
        # started, the objective's own
        start = self.passes + objective.start_evaluations
        self.evaluations.extend(start + e for e in objective.evaluation_history)


@dataclass
class _Outcome:
    """Where an estimation ended, in the terms ``estimate_filter_error`` reports."""

    problem: FilterErrorProblem
    full: np.ndarray  # full parameter vector (pinned F elements solved)
    outputs: np.ndarray
    r_diag: np.ndarray
    sensitivities: np.ndarray  # G over the free parameters of ``problem``
    accuracy_evaluations: int
    sigma: float
    converged: bool
    status: str
    message: str
    pinned: tuple[str, ...] = ()


def _check_solver(solver):
    solver = MNR() if solver is None else solver
    if not isinstance(solver, (MNR, MNRES)):
        raise InputTypeError(
            f"solver: the filter error method runs with MNR() or MNRES(), got {describe(solver)}"
        )
    if isinstance(solver, MNR) and solver.sensitivities != "differences":
        raise InputError(
            "solver: MNR(sensitivities='equations') is for output error; the filter error "
            "method uses finite differences of filter passes"
        )
    return solver


def _cycles(problem, solver, r_diag, convergence, r_rtol, max_cycles, progress, trace):
    """Converge θ with R held, set R to the innovations' covariance, repeat.

    Returns (theta, confirmation, R, state, message) with state "converged", "stuck" (a
    cycle did not converge) or "max_cycles".
    """
    theta = problem.theta_start
    r_diag = np.array(r_diag, dtype=float)
    change = float("nan")
    for _cycle in range(1, max_cycles + 1):
        problem.gain_r = r_diag.copy()
        # the progress numbers continue over cycles and active sets (filter passes in all)
        next_stage(progress, trace.passes + problem.evaluations)
        objective = Objective(problem, r_diag, "fixed", convergence, progress)
        outcome = solver.minimize(objective, theta)
        confirmation = confirm_convergence(
            objective, outcome, "fixed", fallback=isinstance(solver, MNRES)
        )
        trace.iterations += outcome.iterations + confirmation.passes
        trace.cycles += 1
        trace.record(objective, problem)
        final = confirmation.outcome
        theta = final.theta
        if not final.converged:
            return theta, confirmation, r_diag, "stuck", final.message
        r_new = problem.noise_covariance(final.outputs)
        # largest relative change of an innovation variance: R has settled when ≤ r_rtol
        change = float(np.max(np.abs(r_new - r_diag) / r_diag))
        if change <= r_rtol:
            message = (
                "converged: θ Gauss–Newton-optimal under R, and R equal to the innovations' "
                f"covariance within {change:.2g} (relative; tolerance {r_rtol:g})"
            )
            return theta, confirmation, r_diag, "converged", message
        theta = _compensated_start(problem, theta, r_diag, r_new)
        r_diag = r_new
    message = f"R did not settle within {max_cycles} cycles (last relative change {change:.3g})"
    return theta, confirmation, r_diag, "max_cycles", message


@dataclass
class _Recorded:
    """The sensitivities G (N, n_o, n_f) of the solver's last forward differences."""

    g: np.ndarray | None = None


def _record_differences(problem):
    """Keep the forward differences the solver takes on ``problem`` (their G), for the
    next warm cycle."""
    recorded = _Recorded()
    differences = problem.differences

    def recording(*args, **kwargs):
        result = differences(*args, **kwargs)
        recorded.g = result.g
        return result

    problem.differences = recording
    return recorded


def _warm_cycles(problem, solver, r_diag, convergence, r_rtol, max_cycles, progress, trace):
    """The fixed point with one Gauss–Newton step per R update (the same returns as
    ``_cycles``).

    Each cycle starts from the previous one's θ (its F elements compensated for the new R)
    and takes a single step under the current R, then sets R to the innovations'
    covariance: a cycle stops early because R changes anyway. Every other cycle takes its
    step on the sensitivities of the cycle before (H = ∂ỹ/∂θ depends on R only through the
    gain): one filter pass at the new R instead of n_f + 1. Once the step at the start
    of a cycle is negligible (θ Gauss–Newton-optimal under R) and R moved by at most
    ``r_rtol`` in the cycle before, the end point is confirmed with central differences as
    in ``_cycles`` (the sensitivities the bounds need anyway), and R is checked once more.
    """
    theta = problem.theta_start
    r_diag = np.array(r_diag, dtype=float)
    change = float("inf")
    one_step = replace(convergence, max_iterations=1)
    confirmation = None
    previous_delta = None
    recorded = _record_differences(problem)
    for _cycle in range(1, max_cycles + 1):
        problem.gain_r = r_diag.copy()
        next_stage(progress, trace.passes + problem.evaluations)
        objective = Objective(problem, r_diag, "fixed", one_step, progress)
        state = None
        if recorded.g is not None:
            # the last cycle's sensitivities for this cycle's step (one filter pass at the
            # new R instead of n_f + 1); the cycle after takes fresh ones
            cost, outputs = objective.evaluate_start(theta)
            objective.record(theta, cost)
            state = (theta, outputs, recorded.g, None)
        recorded.g = None
        outcome = solver.minimize(objective, theta, state=state)
        trace.iterations += outcome.iterations
        trace.cycles += 1
        theta = outcome.theta
        final = outcome.converged and outcome.status == "converged" and change <= r_rtol
        if outcome.status == "stalled" and state is not None:
            recorded.g = None  # the stale sensitivities found no step: fresh ones next
        elif final or outcome.status == "stalled":
            objective.convergence = convergence
            confirmation = confirm_convergence(
                objective, outcome, "fixed", fallback=isinstance(solver, MNRES)
            )
            trace.iterations += confirmation.passes
            outcome = confirmation.outcome
            theta = outcome.theta
            if not outcome.converged:
                trace.record(objective, problem)
                return theta, confirmation, r_diag, "stuck", outcome.message
        trace.record(objective, problem)
        if change <= _PIN_AFTER_CHANGE and _on_constraint(problem, theta, r_diag):
            return (
                theta,
                confirmation,
                r_diag,
                "stuck",
                "a free process-noise element reached diag(KC) = 1",
            )
        r_new = problem.noise_covariance(outcome.outputs)
        # largest relative change of an innovation variance: R has settled when ≤ r_rtol
        change = float(np.max(np.abs(r_new - r_diag) / r_diag))
        if confirmation is not None and change <= r_rtol:
            message = (
                "converged: θ Gauss–Newton-optimal under R, and R equal to the innovations' "
                f"covariance within {change:.2g} (relative; tolerance {r_rtol:g})"
            )
            return theta, confirmation, r_diag, "converged", message
        confirmation = None
        r_next, previous_delta = _extrapolated(r_diag, r_new, previous_delta, change)
        theta = _compensated_start(problem, theta, r_diag, r_next)
        r_diag = r_next
    if confirmation is None:
        # the sensitivities (and bounds) at the last point, which is reported as not converged
        confirmation = confirm_convergence(objective, outcome, "fixed")
    message = f"R did not settle within {max_cycles} cycles (last relative change {change:.3g})"
    return confirmation.outcome.theta, confirmation, r_diag, "max_cycles", message


#: the warm cycles extrapolate R once every variance changes by less than this fraction per
#: cycle, and then each variance whose change is at most this fraction of the one before
_EXTRAPOLATE_BELOW = 0.05
_EXTRAPOLATE_RATIO = 0.9


def _extrapolated(r_diag, r_new, previous_delta, change):
    """The next R of the warm cycles and the log-change to remember.

    Late in the relaxation R approaches its fixed point geometrically: each cycle's change
    δ_k = ln(R_new/R) is about ρ times the one before (ρ ≈ 0.7 on the HFB-320 case). Once
    all changes are below 5 %, every variance that does so (0 < ρ_i < 0.9) has the rest of
    its series summed at once (Aitken's extrapolation; the others take R_new):

        ln R_next = ln R + δ_k / (1 − ρ),   ρ_i = δ_k,i / δ_k−1,i

    and the series restarts. Convergence is still judged on the unextrapolated change.
    """
    # δ_k = ln(R_new / R)
    delta = np.log(r_new / r_diag)
    if previous_delta is None or change > _EXTRAPOLATE_BELOW:
        return r_new, delta
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = delta / previous_delta
    geometric = (ratio > 0) & (ratio < _EXTRAPOLATE_RATIO)
    if not np.any(geometric):
        return r_new, delta
    # ln R_next = ln R + δ_k / (1 − ρ) for the variances that shrink geometrically
    factor = np.where(geometric, 1.0 / (1.0 - np.where(geometric, ratio, 0.0)), 1.0)
    return r_diag * np.exp(delta * factor), None


#: diag(KC)_i above which a state's F element is pinned to the constraint: "full" cycles
#: pin the largest once a cycle cannot converge, "warm" ones every state that gets this close
#: after a step (a pinned element is released at the end if lowering it lowers the cost)
_PIN_KC = {"full": 1.0 - 1e-3, "warm": 0.99}
#: ... and only once R changed by at most this fraction in the cycle before (the first
#: cycles, from R₀ of the plain simulation, pass through gains they do not keep)
_PIN_AFTER_CHANGE = 0.5


def _on_constraint(problem: FilterErrorProblem, theta: np.ndarray, r_diag: np.ndarray) -> bool:
    """Whether a state with a free F element has come within the warm cycles' pinning
    distance of diag(KC)_i = 1."""
    free = set(problem.free_index.tolist())
    kc = problem.filter_point(problem.full_theta(theta), r_diag).kc
    return any(
        parameter in free and kc[state] > _PIN_KC["warm"]
        for state, parameter in zip(problem.noise_states, problem.noise_parameters, strict=True)
    )


def _compensated_start(
    problem: FilterErrorProblem, theta: np.ndarray, r_old: np.ndarray, r_new: np.ndarray
) -> np.ndarray:
    """Start values of the next cycle: the free F elements rescaled for the new R so that
    the gain stays about the same (the reference's compensation formula, used here only to
    give the next cycle a feasible, nearby start — the cycle then converges under the new R):

        F_jj ← F_jj · Σ_i C_ij² r_i,old⁻¹ (r_i,new/r_i,old)^½ / Σ_i C_ij² r_i,old⁻¹

    If the gain still violates diag(KC) ≤ 1 there, the free F elements are halved (at most
    20 times) until it does not.
    """
    full = problem.full_theta(theta)
    c2 = problem.filter_point(full, r_old).c ** 2
    theta = np.array(theta, dtype=float)
    free = list(problem.free_index)
    moved, moved_states = [], []
    for state, parameter in zip(problem.noise_states, problem.noise_parameters, strict=True):
        if parameter not in free:
            continue
        moved_states.append(state)
        weights = c2[:, state] / r_old
        if np.sum(weights) <= 0:
            continue
        # F_jj ← F_jj Σ_i C_ij² r_i⁻¹ (r_i,new/r_i)^½ / Σ_i C_ij² r_i⁻¹
        theta[free.index(parameter)] *= np.sum(weights * np.sqrt(r_new / r_old)) / np.sum(weights)
        moved.append(free.index(parameter))
    for _ in range(20):
        try:
            kc = problem.filter_point(problem.full_theta(theta), r_new).kc
        except RiccatiError:
            kc = np.full(len(problem.model.states), np.inf)
        if not moved or np.all(kc[moved_states] <= 1.0 + KC_TOLERANCE):
            break
        theta[moved] *= 0.5
    return theta


def _problem(model, data, process_noise, pinned, values, settings) -> FilterErrorProblem:
    """The problem with the pinned states' F elements fixed (solved from diag(KC) = 1)."""
    parameters = model.parameters.with_values(values)
    names = [process_noise[s] for s in pinned]
    if names:
        parameters = parameters.with_free(names, False)
    return _new_problem(
        model.with_parameters(parameters), data, process_noise, settings, pinned=pinned
    )


#: how the filter error method gets H = ∂ỹ/∂θ: finite differences of filter passes, or
#: analytic for models linear in states and inputs (flightid.estimation.filter_error_linear)
GRADIENTS = ("differences", "analytic")


def _new_problem(model, data, process_noise, settings, **extra) -> FilterErrorProblem:
    """``FilterErrorProblem``, or ``LinearFilterErrorProblem`` for gradients = "analytic"."""
    settings = dict(settings)
    settings.pop("cycles", None)
    if settings.pop("gradients", "differences") == "analytic":
        return LinearFilterErrorProblem(model, data, process_noise, **settings, **extra)
    return FilterErrorProblem(model, data, process_noise, **settings, **extra)


def _joining(problem, free_noise, pinned, kc, warm: bool) -> list[str]:
    """States to pin after a cycle stopped at the constraint: warm cycles pin every free
    state within their distance of diag(KC)_i = 1, full cycles the largest above 1 − 1e-3."""
    threshold = _PIN_KC["warm" if warm else "full"]
    states = problem.model.states
    candidates = [s for s in free_noise if s not in pinned and kc[states.index(s)] > threshold]
    if warm or not candidates:
        return candidates
    return [max(candidates, key=lambda s: kc[states.index(s)])]


def _fixed_point(
    model,
    data,
    process_noise,
    solver,
    r_start,
    convergence,
    r_rtol,
    max_cycles,
    progress,
    trace,
    settings,
) -> _Outcome:
    """Fixed-point relaxation with an active set for diag(KC) ≤ 1.

    A state whose diag(KC) element reaches 1 while the cycle cannot converge becomes
    *pinned*: its F element is solved from diag(KC)_i = 1 for every θ, so the constraint
    holds exactly and the remaining parameters are estimated without it. A pinned element is
    released again when lowering it lowers the cost (the constraint's multiplier has the
    wrong sign). The loop ends when no state joins or leaves.
    """
    states = list(process_noise)
    free_noise = [s for s in states if model.parameters[process_noise[s]].free]
    pinned: list[str] = []
    values = model.parameters.values
    r_diag = np.array(r_start, dtype=float)
    message = ""
    for _ in range(2 * len(states) + 3):
        problem = _problem(model, data, process_noise, pinned, values, settings)
        problem.gain_r = r_diag.copy()
        # warm cycles take one MNR step per R update; MNRES rebuilds its surface in every
        # cycle, so it converges each cycle (full cycles)
        warm = settings.get("cycles", "warm") == "warm" and isinstance(solver, MNR)
        run_cycles = _warm_cycles if warm else _cycles
        theta, confirmation, r_diag, state, message = run_cycles(
            problem, solver, r_diag, convergence, r_rtol, max_cycles, progress, trace
        )
        trace.passes += problem.evaluations
        full = problem.complete(problem.full_theta(theta), r_diag)
        values = full
        kc = problem.filter_point(full, r_diag).kc
        if state == "stuck":
            joining = _joining(problem, free_noise, pinned, kc, warm)
            if joining:
                pinned.extend(joining)
                continue
            break
        if state != "converged":
            break
        # release a pinned element whose decrease lowers the cost
        outputs = confirmation.outcome.outputs
        cost = float(problem.cost(outputs, r_diag))
        released = None
        for s in pinned:
            index = model.parameters.index(process_noise[s])
            trial_values = full.copy()
            trial_values[index] *= 1.0 - 1e-3
            rest = [p for p in pinned if p != s]
            trial = _problem(model, data, process_noise, rest, trial_values, settings)
            trial.gain_r = r_diag.copy()
            trial_batch = trial.run(trial.theta_start)
            trace.passes += trial.evaluations
            if (
                not trial_batch.diverged[0]
                and float(trial.cost(trial_batch.outputs[0], r_diag)) < cost
            ):
                released = s
                break
        if released is None:
            break
        pinned.remove(released)
        values = full
    outcome = confirmation.outcome
    converged = state == "converged"
    status = "converged" if converged else outcome.status
    if not converged and status == "converged":
        status = "max_iterations"
    if pinned:
        names = [process_noise[s] for s in pinned]
        message += (
            f"; the constraint diag(KC) ≤ 1 is active for {pinned}: {names} solved from "
            "diag(KC)_i = 1 (their bounds by the delta method)"
        )
    return _Outcome(
        problem,
        full,
        outcome.outputs,
        r_diag,
        confirmation.sensitivities,
        confirmation.sensitivity_evaluations,
        confirmation.sigma,
        converged,
        status,
        message,
        tuple(pinned),
    )


def _reference(problem, r_start, progress, trace) -> _Outcome:
    from flightid.estimation.filter_reference import reference_relaxation

    run = reference_relaxation(problem, r_start, progress)
    trace.costs, trace.evaluations = run.cost_history, run.evaluation_history
    trace.iterations, trace.cycles, trace.r_updates = run.iterations, run.r_updates, []
    trace.passes = problem.evaluations
    status = "converged" if run.converged else "max_iterations"
    return _Outcome(
        problem,
        problem.full_theta(run.theta),
        run.outputs,
        run.r_diag,
        run.sensitivities,
        0,
        float("nan"),
        run.converged,
        status,
        run.message,
    )


def _pinned_jacobian(outcome: _Outcome, model: StateSpaceModel) -> np.ndarray:
    """T (n_f × n_r): ∂(originally free parameters)/∂(free parameters of the last problem);
    identity rows for the free ones, ∂F_ii/∂θ_r for a pinned element (finite differences of
    the constraint solution, no filter pass)."""
    problem = outcome.problem
    original = np.flatnonzero(model.parameters.free_mask)
    reduced = problem.free_index
    theta = outcome.full[reduced]
    base = problem.complete(outcome.full, outcome.r_diag)
    t = np.zeros((original.size, reduced.size))
    for j, index in enumerate(reduced):
        t[list(original).index(index), j] = 1.0
    pinned = [problem.noise_parameters[i] for i in problem.pinned]
    for j in range(reduced.size):
        step = 1e-6 * max(abs(theta[j]), problem.typical[j])
        moved = outcome.full.copy()
        moved[reduced[j]] += step
        moved = problem.complete(moved, outcome.r_diag)
        for index in pinned:
            # ∂F_ii/∂θ_j ≈ (F_ii(θ + δ e_j) − F_ii(θ)) / δ
            t[list(original).index(index), j] = (moved[index] - base[index]) / step
    return t


def _pinned_weighting_covariance(outcome: _Outcome, model: StateSpaceModel) -> np.ndarray:
    """The covariance (n_f × n_f, original free parameters) a pinned F element takes from the
    estimated weighting R, which the delta method over θ alone leaves out.

    A pinned element is solved from diag(KC)_i = 1 at the estimated R, so it moves with R̂
    (for a directly measured state F_ii ≈ √(R_ii/Δt): half of R̂'s relative error). R̂ is the
    innovations' covariance, R̂_i = (1/N) Σ_k e_ik², whose variance for Gaussian innovations
    is 2 R_i²/N; its error is uncorrelated with θ̂'s to first order:

        Cov_R = J_R diag(2 R²/N) J_Rᵀ,   J_R = ∂F_pin/∂R (finite differences of the
        constraint solution, no filter pass)
    """
    problem = outcome.problem
    original = list(np.flatnonzero(model.parameters.free_mask))
    r_diag = np.asarray(outcome.r_diag, dtype=float)
    base = problem.complete(outcome.full, r_diag)
    pinned = [problem.noise_parameters[i] for i in problem.pinned]
    jacobian = np.zeros((len(original), r_diag.size))
    for i in range(r_diag.size):
        step = 1e-6 * r_diag[i]
        moved_r = r_diag.copy()
        moved_r[i] += step
        moved = problem.complete(outcome.full, moved_r)
        for index in pinned:
            # ∂F_pin/∂R_i ≈ (F_pin(R + δ e_i) − F_pin(R)) / δ
            jacobian[original.index(index), i] = (moved[index] - base[index]) / step
    # Var(R̂_i) = 2 R_i² / N
    variance_r = 2.0 * r_diag**2 / problem.n_samples
    return (jacobian * variance_r) @ jacobian.T


def estimate_filter_error(
    model: StateSpaceModel,
    data: FlightData | Sequence[FlightData],
    process_noise: Mapping[str, str],
    solver: MNR | MNRES | None = None,
    *,
    relaxation: str = "fixed_point",
    method: str = "rk4",
    input_interpolation: str = "linear",
    linearisation: str = "start",
    convergence: Convergence | None = None,
    r_rtol: float = 1e-4,
    max_cycles: int = 30,
    compiled: bool = True,
    progress: Callable[[int, int, float], None] | None = None,
    gradients: str = "differences",
    cycles: str = "warm",
) -> Estimate:
    """Filter-error maximum-likelihood estimate (system parameters and F elements).

    Args:
        model: the model; its parameters include the process-noise elements (e.g. F11).
        data: one maneuver or a list (same sampling interval).
        process_noise: {state: parameter name} of the diagonal F.
        solver: ``MNR()`` (default) or ``MNRES()`` (``relaxation="fixed_point"``); the
            reference schedule always takes its own forward-difference Gauss–Newton steps.
        relaxation: ``"fixed_point"`` (converge θ under R, update R, repeat until R settles;
            the constraint by an active set) or ``"reference"`` (the reference tool's
            schedule: R₀ for 3 steps, then an R update with F compensation after every
            step, linearised constraint; FVSysID's ``ml_fem2``).
        method, input_interpolation: integration as in ``estimate``.
        linearisation: where A and C are taken (``"start"``: x0, u_1).
        convergence: the solver's stopping rules (default ``Convergence()``).
        r_rtol: ``fixed_point``: R has settled when no variance changes by more than this
            fraction in a cycle.
        max_cycles: ``fixed_point``: R updates at most (per active set).
        compiled: numba filter kernel.
        progress: called after every accepted pass with (pass, filter passes, cost), both
            numbers rising over all R cycles and active sets.
        cycles: ``fixed_point``: ``"warm"`` (one Gauss–Newton step per R update, R
            extrapolated once it settles geometrically, the end confirmed once; MNR only,
            MNRES always runs full cycles) or ``"full"`` (θ converged and confirmed under
            every R).
        gradients: ``"differences"`` (H by finite differences of filter passes) or
            ``"analytic"``: a model linear in states and inputs, filtered with the exact
            discretisation Φ = e^{AΔt}, H from the differentiated Riccati equation and
            filter recursion (``LinearFilterErrorProblem``; docs/turbulence.md).

    Returns:
        An ``Estimate``: ``predicted`` are the filtered outputs ỹ, ``residuals`` the
        innovations, ``r_diag`` the final weighting R (the innovations' covariance),
        ``cost`` = Σ eᵀR⁻¹e under it, ``equivalent_evaluations`` the filter passes of the
        optimiser, the Cramér–Rao bounds √diag(M⁻¹) with M from the sensitivities of the
        filtered outputs at θ̂ (central differences; the reference schedule: its last
        forward-difference step, at the iterate it was taken from); ``noise_policy`` is
        ``"filter_error/<relaxation>"`` and the message gives det R and diag(KC).
    """
    if not isinstance(model, StateSpaceModel):
        raise InputTypeError(f"model: expected a StateSpaceModel, got {describe(model)}")
    if relaxation not in RELAXATIONS:
        raise InputError(f"relaxation: expected one of {list(RELAXATIONS)}, got {relaxation!r}")
    solver = _check_solver(solver)
    convergence = Convergence() if convergence is None else convergence
    if not isinstance(convergence, Convergence):
        raise InputTypeError(f"convergence: expected a Convergence, got {describe(convergence)}")
    check_call_options(compiled, progress)
    # pass numbers and filter passes rise over all R cycles and active sets
    progress = RunProgress.wrap(progress)
    started = _time.perf_counter()
    check_model(model, data, method=method)
    settings = {
        "method": method,
        "compiled": compiled,
        "input_interpolation": input_interpolation,
        "linearisation": linearisation,
    }
    if gradients not in GRADIENTS:
        raise InputError(f"gradients: expected one of {list(GRADIENTS)}, got {gradients!r}")
    settings["gradients"] = gradients
    if cycles not in CYCLES:
        raise InputError(f"cycles: expected one of {list(CYCLES)}, got {cycles!r}")
    settings["cycles"] = cycles
    problem = _new_problem(model, data, process_noise, settings)
    problem.check_enough_data()
    # R₀: one pass with K = 0 (a plain simulation) at the start values
    r_start = problem.noise_covariance(problem.simulate(problem.theta_start))
    trace = _Trace()
    if relaxation == "reference":
        outcome = _reference(problem, r_start, progress, trace)
        solver_name = "mnr"
        solver_settings = {"relative_step": 1e-4, "schedule": "reference (ml_fem2)"}
    else:
        trace.passes = problem.evaluations
        outcome = _fixed_point(
            model,
            data,
            process_noise,
            solver,
            r_start,
            convergence,
            r_rtol,
            max_cycles,
            progress,
            trace,
            settings,
        )
        solver_name, solver_settings = solver.name, solver.settings()
    last = outcome.problem
    r_diag, outputs, full = outcome.r_diag, outcome.outputs, outcome.full
    point = last.filter_point(full, r_diag)
    det_r = float(np.prod(last.noise_covariance(outputs)))
    filter_passes = trace.passes
    message = outcome.message + (
        f"; det R = {det_r:.6g} (innovations), diag(KC) = "
        f"{np.array2string(point.kc, precision=4)}, {filter_passes} filter passes"
    )
    if relaxation == "reference" and np.any(point.kc > 1.0 - 1e-3):
        message += "; the constraint diag(KC) ≤ 1 is active"
    m_reduced = information_matrix(outcome.sensitivities, r_diag)
    covariance_r, std_r, undetermined = _covariance(m_reduced, np.zeros(last.n_free, dtype=bool))
    free_mask = model.parameters.free_mask
    n_f = int(free_mask.sum())
    if outcome.pinned:
        # Cov = T Cov_r Tᵀ (delta method for the F elements solved from the constraint)
        t = _pinned_jacobian(outcome, model)
        # the pinned elements also move with R̂: Cov = T Cov_r Tᵀ + J_R Cov(R̂) J_Rᵀ
        covariance_weighting = _pinned_weighting_covariance(outcome, model)
        covariance = t @ covariance_r @ t.T + covariance_weighting
        std_free = np.sqrt(np.maximum(np.diag(covariance), 0.0))
        m = np.linalg.pinv(covariance)
        g = np.zeros((last.n_samples, last.n_outputs, n_f))
        g[:, :, np.any(t[:, :] == 1.0, axis=1)] = outcome.sensitivities
    else:
        covariance, std_free, m, g = covariance_r, std_r, m_reduced, outcome.sensitivities
    if undetermined:
        names = [last.free_names[j] for j in undetermined]
        message += f"; the information matrix is singular: {names} cannot be determined"
    # free process-noise elements: their bound treats the weighting R as known although the
    # gain depends on it; measured (bench/sigma_coverage.py, filter_error: F11 spread 1.26 σ,
    # 2σ coverage 0.83) it is somewhat optimistic
    free_process_noise = [
        name
        for state, name in last.process_noise.items()
        if name in model.parameters.free_names and state not in outcome.pinned
    ]
    if free_process_noise:
        message += (
            f"; the σ of the process-noise parameters {free_process_noise} may be up to about "
            "1.3× too small (their bound takes R as known)"
        )
    residuals = last.residuals(outputs)
    # the default σ from the innovations: Cramér–Rao when white, coloured-residual otherwise
    sigma = default_sigma(
        outcome.sensitivities, residuals, r_diag, covariance_r, last.maneuver_index
    )
    covariance_default = sigma.covariance
    if outcome.pinned:
        # Cov = T Cov_r Tᵀ + J_R Cov(R̂) J_Rᵀ for the default covariance as for the
        # Cramér–Rao one (the pinned elements move with R̂ whatever the residuals' colour)
        covariance_default = t @ covariance_default @ t.T + covariance_weighting
    std_cr = np.full(full.shape, np.nan)
    std_cr[free_mask] = std_free
    std = np.full(full.shape, np.nan)
    std[free_mask] = np.sqrt(np.maximum(np.diag(covariance_default), 0.0))
    std[free_mask] = np.where(np.isfinite(std_free), std[free_mask], std_free)
    estimated_model = model.with_parameters(model.parameters.with_values(full))
    accuracy = outcome.accuracy_evaluations
    return Estimate(
        names=tuple(model.parameters.names),
        values=full,
        initial=model.parameters.values,
        free=free_mask,
        std=std,
        std_cr=std_cr,
        std_kind=sigma.kind,
        residuals_white=sigma.residuals_white,
        coloured_lag=sigma.lag,
        covariance=covariance,
        covariance_default=covariance_default,
        information_matrix=m,
        sensitivities=g,
        r_diag=np.asarray(r_diag, dtype=float),
        cost=float(last.cost(outputs, r_diag)),
        cost_history=tuple(trace.costs),
        evaluation_history=tuple(trace.evaluations),
        noise_update_passes=tuple(trace.r_updates[1:]),
        log_det_r_history=tuple(trace.log_det_r),
        r_history=tuple(trace.r_history),
        equivalent_evaluations=int(filter_passes - accuracy),
        accuracy_evaluations=int(accuracy),
        iterations=int(trace.iterations),
        noise_cycles=int(trace.cycles),
        converged=bool(outcome.converged),
        status=outcome.status,
        message=message,
        time=last.time,
        measured=last.measured,
        predicted=outputs,
        residuals=residuals,
        maneuver_index=last.maneuver_index,
        output_names=tuple(model.outputs),
        output_units=tuple(
            next((m.units[n] for m in last.maneuvers if m.units.get(n)), "") for n in model.outputs
        ),
        solver=solver_name,
        solver_settings=solver_settings,
        noise_policy=f"filter_error/{relaxation}",
        method=method,
        input_interpolation=input_interpolation,
        wall_time_s=_time.perf_counter() - started,
        model=estimated_model,
        optimality_sigma=outcome.sigma,
        # the pinned F elements: solved from diag(KC)_i = 1, not estimated freely
        solved=tuple(last.process_noise[s] for s in outcome.pinned),
    )
