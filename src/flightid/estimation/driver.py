"""``estimate(model, data, solver)``: the one front door of output-error estimation.

Maximum likelihood with no process noise (RP-1153 §6): minimise J(θ) = Σ νᵀR⁻¹ν with R
either given, or estimated from the residuals under the MAX or MAXLIK policy
(``flightid.estimation.objective``).

After the optimizer stops, the sensitivities are computed by central differences at θ̂; they
confirm (or deny, or continue) the solver's convergence (``flightid.estimation.confirm``) and
give the information matrix for the Cramér–Rao bounds. Identifiability is judged on M scaled
to unit diagonal (``undetermined_parameters``), so units and start values do not decide it.
Parameters that end on a bound are reported as such; their bounds are those of the free
subspace (M restricted to the parameters off their bounds).
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from flightid.coloured import default_sigma
from flightid.data.flightdata import FlightData
from flightid.errors import EstimationError, InputError, InputTypeError, describe
from flightid.estimation.confirm import Confirmation, confirm_convergence
from flightid.estimation.convergence import Convergence
from flightid.estimation.gauss_newton import information_matrix, undetermined_parameters
from flightid.estimation.objective import NOISE_POLICIES, Objective
from flightid.estimation.problem import OutputErrorProblem
from flightid.estimation.progress import RunProgress, next_stage
from flightid.estimation.result import Estimate
from flightid.estimation.solvers import FPS, MNR, MNRES
from flightid.model.check import check_model
from flightid.model.statespace import StateSpaceModel

__all__ = ["estimate"]

_SOLVERS = (MNRES, MNR, FPS)


def check_call_options(compiled: object, progress: object) -> None:
    """``compiled`` is True or False and ``progress`` None or callable (``InputTypeError``
    naming the argument; a string "no" would otherwise count as true)."""
    if not isinstance(compiled, (bool, np.bool_)):
        raise InputTypeError(f"compiled: expected True or False, got {describe(compiled)}")
    if progress is not None and not callable(progress):
        raise InputTypeError(
            f"progress: expected None or a function (passes, evaluations, cost), got "
            f"{describe(progress)}"
        )


def _check_r(r: np.ndarray | Sequence[float] | None, n_outputs: int) -> np.ndarray:
    if r is None:
        return np.ones(n_outputs)
    if isinstance(r, (str, bytes)) or np.iscomplexobj(r):
        raise InputTypeError(f"R: expected real noise variances, got {describe(r)}")
    try:
        r = np.asarray(r, dtype=float)
    except (TypeError, ValueError):
        raise InputTypeError(f"R: expected real noise variances, got {describe(r)}") from None
    if r.ndim == 2:
        if r.shape != (n_outputs, n_outputs):
            raise InputError(f"R: expected a {n_outputs}×{n_outputs} matrix, got {r.shape}")
        if np.any(np.abs(r - np.diag(np.diag(r))) > 0):
            raise InputError(
                "R: only diagonal noise covariances are supported; got off-diagonal entries"
            )
        r = np.diag(r).copy()
    if r.shape != (n_outputs,) or not np.all(np.isfinite(r)) or np.any(r <= 0):
        raise InputError(
            f"R: expected {n_outputs} positive finite variances (one per output), got {r!r}"
        )
    return r


def _covariance(m: np.ndarray, held: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """M⁻¹ over the parameters not held on a bound, scale-free; undetermined → inf.

    With D = diag(√M_jj) and C = D⁻¹MD⁻¹ (unit diagonal), M⁻¹ = D⁻¹C⁻¹D⁻¹, C⁻¹ from its
    eigen-decomposition over the determined directions. Parameters held on a bound get no
    variance (NaN, like fixed ones): the bounds are those of the free subspace.

    Returns (covariance (n_f × n_f), std (n_f,), indices of undetermined parameters).
    """
    n_f = m.shape[0]
    covariance = np.full((n_f, n_f), np.nan)
    std = np.full(n_f, np.nan)
    active = np.flatnonzero(~held)
    if active.size == 0:
        return covariance, std, []
    sub = m[np.ix_(active, active)]
    keep, undetermined_sub = undetermined_parameters(sub)
    diagonal = np.diag(sub)
    d = np.sqrt(np.where(diagonal > 0, diagonal, 1.0))
    c = sub / np.outer(d, d)
    eigenvalues, vectors = np.linalg.eigh(c)
    inverse = (vectors[:, keep] / eigenvalues[keep]) @ vectors[:, keep].T
    sub_covariance = inverse / np.outer(d, d)
    sub_std = np.sqrt(np.maximum(np.diag(sub_covariance), 0.0))
    sub_std[undetermined_sub] = np.inf
    sub_covariance[undetermined_sub, :] = np.inf
    sub_covariance[:, undetermined_sub] = np.inf
    covariance[np.ix_(active, active)] = sub_covariance
    std[active] = sub_std
    return covariance, std, [int(active[j]) for j in undetermined_sub]


# An MNRES "converged" whose central-difference check puts the optimum more than this many
# σ away was misled by its surface; MNR is then run from the start values as well.
SECOND_OPINION_SIGMA = 10.0


@dataclass
class _Run:
    """One optimisation from the start values: objective, confirmation, passes, R cycles."""

    objective: Objective
    confirmation: Confirmation
    iterations: int
    cycles: int
    note: str = ""


def _optimise(
    problem: OutputErrorProblem,
    solver: MNRES | MNR | FPS,
    r_diag: np.ndarray,
    noise: str,
    convergence: Convergence,
    progress: Callable[[int, int, float], None] | None,
) -> _Run:
    """Solver from the start values, MAX noise cycles, then the confirmation."""
    theta = problem.theta_start
    objective = Objective(problem, r_diag, noise, convergence, progress)
    if noise != "fixed":
        # R from the residuals at the start values; the solver reuses this integration.
        _, start_outputs = objective.evaluate(theta[None, :])
        if not np.all(np.isfinite(start_outputs)):
            raise EstimationError(
                "the simulation at the start values does not stay finite; "
                "check the start values and x0"
            )
        objective.r_diag = problem.noise_covariance(start_outputs[0])
        objective.prime(theta, start_outputs[0])

    outcome = solver.minimize(objective, theta)
    iterations, cycles = outcome.iterations, 0
    if noise == "max":
        # Program MAX: with θ converged, update R and re-converge until a cycle moves nothing.
        while outcome.converged and cycles < convergence.max_noise_cycles:
            change = objective.update_noise(outcome.outputs)
            cycles += 1
            if change <= convergence.noise_rtol:
                break
            outcome = solver.minimize(objective, outcome.theta, state=outcome.state)
            iterations += outcome.iterations
            if outcome.iterations <= 1:
                break
        outcome = replace(outcome, cost=float(objective.costs_of(outcome.outputs)[0]))
    elif noise == "maxlik":
        cycles = objective.noise_updates
    # Central-difference sensitivities at θ̂: confirm the solver's convergence (continuing
    # with Gauss–Newton passes if it stopped short), then the information matrix.
    updates_before = objective.noise_updates
    # handed over, not kept: the outcome's sensitivities become the confirmation's, and a
    # reference held here would keep a second G alive while the confirmation computes anew
    handed = [outcome]
    del outcome
    confirmation = confirm_convergence(
        objective, handed.pop(), noise, fallback=isinstance(solver, MNRES)
    )
    iterations += confirmation.passes
    cycles += objective.noise_updates - updates_before
    return _Run(objective, confirmation, iterations, cycles)


def evaluations_to_optimum(
    objective: Objective,
    theta: np.ndarray,
    cost: float,
    m: np.ndarray,
    offset: int = 0,
) -> int:
    """Equivalent evaluations spent until the path first reached the optimum.

    The path is the points the objective recorded (the start and every accepted pass, the
    confirming passes included), each with the evaluations spent when it was recorded. The
    optimum is reached at the first point θ_k whose cost exceeds the final cost J(θ̂) by no
    more than the convergence's cost tolerance, the excess predicted under the final R by
    the quadratic model at θ̂ (the same under every noise policy, since costs recorded under
    an earlier R do not compare with the final one):

        (θ_k − θ̂)ᵀ M (θ_k − θ̂)  ≤  cost_rtol·J(θ̂) + cost_atol,    M = Σ GᵀR⁻¹G at θ̂

    ``offset``: evaluations spent before this objective began (a first run the driver
    discarded). Later evaluations are the confirmation's (the solver's own checks and the
    confirming passes) and the bounds'.
    """
    conv = objective.convergence
    tolerance = conv.cost_rtol * abs(cost) + conv.cost_atol
    for point, spent in zip(objective.theta_history, objective.evaluation_history, strict=True):
        change = np.asarray(point, dtype=float) - theta
        # predicted excess J(θ_k) − J(θ̂) ≈ ΔθᵀMΔθ (the gradient vanishes at θ̂)
        if float(change @ m @ change) <= tolerance:
            return offset + int(spent)
    return offset + objective.evaluations


def _negative_log_likelihood(problem: OutputErrorProblem, noise: str, run: _Run) -> float:
    """What ML minimises: J under a fixed R, else ln det R̂ (R estimated [3.45])."""
    outputs = run.confirmation.outcome.outputs
    if noise == "fixed":
        return float(problem.cost(outputs, run.objective.r_diag))
    return float(np.sum(np.log(problem.noise_covariance(outputs))))


def second_opinion_message(
    outcome, label: str, criterion: str, values: Sequence[float], distance: float
) -> str:
    """One sentence for a result chosen from MNRES's run and MNR's second opinion: the
    chosen run, why (the likelihoods), what led to it; the reason of an unconverged result
    added as a clause (without its "<status>:")."""
    message = (
        f"{outcome.status}: {label}'s result is reported, the higher likelihood of two runs "
        f"({criterion} = {values[0]:.6g} for MNRES, {values[1]:.6g} for MNR), after MNRES "
        f"stopped {distance:.3g} σ from an optimum (its surface misled it) and MNR ran from "
        "the start values too"
    )
    if outcome.converged:
        return message
    prefix = f"{outcome.status}:"
    reason = outcome.message
    for lead in (prefix, "not converged:"):
        if reason.startswith(lead):
            reason = reason[len(lead) :].strip()
    return f"{message}; {reason}"


def _better(problem: OutputErrorProblem, noise: str, first: _Run, second: _Run) -> _Run:
    """The run with the higher likelihood, its message saying what happened."""
    criterion = "J" if noise == "fixed" else "ln det R"
    values = [_negative_log_likelihood(problem, noise, run) for run in (first, second)]
    chosen, label = (second, "MNR") if values[1] < values[0] else (first, "MNRES")
    outcome = chosen.confirmation.outcome
    message = second_opinion_message(
        outcome, label, criterion, values, first.confirmation.initial_sigma
    )
    confirmation = replace(chosen.confirmation, outcome=replace(outcome, message=message))
    return _Run(
        chosen.objective,
        confirmation,
        first.iterations + second.iterations,
        chosen.cycles,
    )


def estimate(
    model: StateSpaceModel,
    data: FlightData | Sequence[FlightData],
    solver: MNRES | MNR | FPS | None = None,
    *,
    method: str = "rk4",
    input_interpolation: str = "linear",
    noise: str = "max",
    R: np.ndarray | Sequence[float] | None = None,
    convergence: Convergence | None = None,
    compiled: bool = True,
    progress: Callable[[int, int, float], None] | None = None,
    weights: np.ndarray | None = None,
) -> Estimate:
    """Output-error maximum-likelihood estimate of the model's free parameters.

    Args:
        model: the state-space model; free parameters are estimated from their values.
        data: one maneuver or a list of maneuvers (sharing all parameters; per-maneuver
            initial states through the model's ``x0``).
        solver: ``MNRES()`` (default), ``MNR()`` or ``FPS()``.
        method: integration, ``"rk4"`` or ``"euler"``.
        input_interpolation: how the inputs vary between samples: ``"linear"`` (the RK4 half
            step takes the mean of the neighbouring samples) or ``"zoh"`` (zero-order hold:
            u_k over [t_k, t_k+1), as recorded by a sample-and-hold data system).
        noise: ``"max"`` (default), ``"maxlik"`` or ``"fixed"`` (see ``objective``).
        R: noise variances (n_o,) or a diagonal matrix: the fixed R of ``noise="fixed"``
            (default identity), ignored otherwise.
        convergence: stopping rules (default ``Convergence()``: the paper's 10⁻³ tests).
        compiled: run the numba kernel.
        progress: called after every accepted pass with (pass number, equivalent evaluations
            so far, cost under the current R) — e.g. to print progress; both numbers rise
            over the whole run (``flightid.estimation.progress``).
        weights: per-sample weights w ∈ [0, 1] over all maneuvers' samples in order, (N,) or
            (N, n_o): J = Σ w ν²/R; a weight 0 excludes the measurement from the cost, the
            information matrix, R̂ and N (``OutputErrorProblem.set_weights``). None: all 1.
            ``flightid.accuracy.outliers`` finds the samples to exclude or down-weight.

    Returns:
        A frozen ``Estimate``. Non-convergence is reported in its status, not raised.

    Raises:
        InputError / InputTypeError: bad arguments.
        ModelError: f or h break the model contract at the start values (``check_model``).
        EstimationError: the simulation diverges at the start values.
    """
    if not isinstance(model, StateSpaceModel):
        raise InputTypeError(f"model: expected a StateSpaceModel, got {describe(model)}")
    solver = MNRES() if solver is None else solver
    if not isinstance(solver, _SOLVERS):
        raise InputTypeError(f"solver: expected MNRES(), MNR() or FPS(), got {describe(solver)}")
    if noise not in NOISE_POLICIES:
        raise InputError(f"noise: expected one of {NOISE_POLICIES}, got {noise!r}")
    convergence = Convergence() if convergence is None else convergence
    if not isinstance(convergence, Convergence):
        raise InputTypeError(f"convergence: expected a Convergence, got {describe(convergence)}")
    check_call_options(compiled, progress)

    started = _time.perf_counter()
    # The model contract (lengths, indices, finite values at the start), before anything else.
    check_model(model, data, method=method)
    problem = OutputErrorProblem(
        model, data, method=method, compiled=compiled, input_interpolation=input_interpolation
    )
    problem.set_weights(weights)
    problem.check_enough_data()
    r_diag = _check_r(R, problem.n_outputs)
    evaluations_before = problem.evaluations
    # pass numbers and evaluations rise over both runs when MNR gives a second opinion
    progress = RunProgress.wrap(progress)
    run = _optimise(problem, solver, r_diag, noise, convergence, progress)
    if isinstance(solver, MNRES) and run.confirmation.initial_sigma > SECOND_OPINION_SIGMA:
        # MNRES's surface misled it far from any optimum: its path is not to be trusted, so
        # MNR (fresh finite differences every pass) runs from the start values too and the
        # higher likelihood wins.
        next_stage(progress, problem.evaluations - evaluations_before)
        second = _optimise(problem, MNR(), r_diag, noise, convergence, progress)
        run = _better(problem, noise, run, second)
    objective, confirmation = run.objective, run.confirmation
    outcome, iterations, cycles = confirmation.outcome, run.iterations, run.cycles
    accuracy_evaluations = confirmation.sensitivity_evaluations
    optimizer_evaluations = problem.evaluations - evaluations_before - accuracy_evaluations
    g = confirmation.sensitivities
    # the Estimate keeps this G itself (read-only, not copied; nothing else holds it)
    g.flags.writeable = False
    m = information_matrix(g, objective.r_diag)
    final_cost = float(objective.costs_of(outcome.outputs)[0])
    # a discarded first run (MNR's second opinion) counts towards reaching the optimum
    to_optimum = min(
        evaluations_to_optimum(
            objective,
            outcome.theta,
            final_cost,
            m,
            objective.start_evaluations - evaluations_before,
        ),
        optimizer_evaluations,
    )
    on_bound = problem.at_bound(outcome.theta)
    covariance, std_free, undetermined = _covariance(m, on_bound)
    status, message = outcome.status, outcome.message
    at_bound = tuple(problem.free_names[j] for j in np.flatnonzero(on_bound))
    if at_bound:
        message += (
            f"; {list(at_bound)} ended on a bound (no Cramér–Rao bound is given for them; "
            "the others' bounds are those of the free subspace)"
        )
    if undetermined:
        names = [problem.free_names[j] for j in undetermined]
        message += (
            f"; the information matrix is singular: {names} cannot be determined from "
            "these data (their Cramér–Rao bounds are reported as infinite)"
        )

    # every solver keeps θ in its bounds; the projection only guards round-off at a bound
    values = problem.full_theta(problem.project(outcome.theta))
    std_cr = np.full(values.shape, np.nan)
    std_cr[problem.free_index] = std_free
    residuals = problem.residuals(outcome.outputs)[: problem.n_data]
    # the default σ: Cramér–Rao for white residuals, coloured-residual σ otherwise
    sigma = default_sigma(
        g[: problem.n_data], residuals, objective.r_diag, covariance, problem.maneuver_index
    )
    std = np.full(values.shape, np.nan)
    std[problem.free_index] = sigma.std
    estimated_model = model.with_parameters(model.parameters.with_values(values))
    return Estimate(
        names=tuple(model.parameters.names),
        values=values,
        initial=problem.theta_start_full,
        free=problem.free_mask,
        std=std,
        std_cr=std_cr,
        std_kind=sigma.kind,
        residuals_white=sigma.residuals_white,
        coloured_lag=sigma.lag,
        covariance=covariance,
        covariance_default=sigma.covariance,
        information_matrix=m,
        sensitivities=g[: problem.n_data],
        r_diag=objective.r_diag,
        cost=final_cost,
        cost_history=tuple(objective.cost_history),
        evaluation_history=tuple(objective.evaluation_history),
        noise_update_passes=tuple(objective.noise_update_passes),
        log_det_r_history=tuple(objective.log_det_r_history),
        r_history=tuple(tuple(float(v) for v in r) for r in objective.r_history),
        equivalent_evaluations=optimizer_evaluations,
        accuracy_evaluations=accuracy_evaluations,
        evaluations_to_optimum=to_optimum,
        confirmation_evaluations=optimizer_evaluations - to_optimum,
        iterations=iterations,
        noise_cycles=cycles,
        converged=outcome.converged,
        status=status,
        message=message,
        time=problem.time,
        # the data rows (multiple shooting appends continuity-defect rows after them)
        measured=problem.measured[: problem.n_data],
        predicted=(
            outcome.outputs[: problem.n_data]
            if weights is None
            else problem.model_outputs(outcome.theta)
        ),
        residuals=residuals,
        maneuver_index=problem.maneuver_index,
        output_names=tuple(model.outputs),
        # the outputs' units from the data's channel units (the first maneuver that has one)
        output_units=tuple(
            next((m.units[n] for m in problem.maneuvers if m.units.get(n)), "")
            for n in model.outputs
        ),
        solver=solver.name,
        solver_settings=solver.settings(),
        noise_policy=noise,
        method=method,
        input_interpolation=input_interpolation,
        wall_time_s=_time.perf_counter() - started,
        model=estimated_model,
        optimality_sigma=confirmation.sigma,
        at_bound=at_bound,
        weights=problem.weights,
    )
