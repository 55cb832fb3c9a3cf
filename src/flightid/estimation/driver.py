"""``estimate(model, data, solver)``: the one front door of output-error estimation.

Maximum likelihood with no process noise (RP-1153 §6): minimise J(θ) = Σ νᵀR⁻¹ν with R
either given, or estimated from the residuals under the MAX or MAXLIK policy
(``flightid.estimation.objective``). After the optimizer stops, the information matrix is
computed once by central differences at θ̂ for the Cramér–Rao bounds.
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from flightid.data.flightdata import FlightData
from flightid.errors import EstimationError, InputError, InputTypeError, SimulationError, describe
from flightid.estimation.convergence import Convergence
from flightid.estimation.gauss_newton import information_matrix
from flightid.estimation.objective import NOISE_POLICIES, Objective
from flightid.estimation.problem import OutputErrorProblem
from flightid.estimation.result import Estimate
from flightid.estimation.solvers import FPS, MNR, MNRES
from flightid.model.statespace import StateSpaceModel

__all__ = ["estimate"]

_SOLVERS = (MNRES, MNR, FPS)


def _check_r(r: np.ndarray | Sequence[float] | None, n_outputs: int) -> np.ndarray:
    if r is None:
        return np.ones(n_outputs)
    r = np.asarray(r, dtype=float)
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


def _covariance(m: np.ndarray, typical: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """M⁻¹ via an eigen-decomposition of the scaled M; undetermined directions → inf.

    Returns (covariance, std, indices of undetermined parameters).
    """
    scaled = m * np.outer(typical, typical)
    eigenvalues, vectors = np.linalg.eigh(scaled)
    top = eigenvalues[-1] if eigenvalues.size else 0.0
    keep = eigenvalues > 1e-12 * top if top > 0 else np.zeros_like(eigenvalues, dtype=bool)
    inverse = (vectors[:, keep] / eigenvalues[keep]) @ vectors[:, keep].T
    covariance = inverse * np.outer(typical, typical)
    std = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    undetermined: list[int] = []
    if not keep.all():
        # parameters with weight in the discarded directions cannot be determined
        weight = np.sum(vectors[:, ~keep] ** 2, axis=1)
        undetermined = [int(j) for j in np.flatnonzero(weight > 1e-6)]
        std[undetermined] = np.inf
        covariance[undetermined, :] = np.inf
        covariance[:, undetermined] = np.inf
    return covariance, std, undetermined


def estimate(
    model: StateSpaceModel,
    data: FlightData | Sequence[FlightData],
    solver: MNRES | MNR | FPS | None = None,
    *,
    method: str = "rk4",
    noise: str = "max",
    R: np.ndarray | Sequence[float] | None = None,
    convergence: Convergence | None = None,
    compiled: bool = True,
    progress: Callable[[int, int, float], None] | None = None,
) -> Estimate:
    """Output-error maximum-likelihood estimate of the model's free parameters.

    Args:
        model: the state-space model; free parameters are estimated from their values.
        data: one maneuver or a list of maneuvers (sharing all parameters; per-maneuver
            initial states through the model's ``x0``).
        solver: ``MNRES()`` (default), ``MNR()`` or ``FPS()``.
        method: integration, ``"rk4"`` or ``"euler"``.
        noise: ``"max"`` (default), ``"maxlik"`` or ``"fixed"`` (see ``objective``).
        R: noise variances (n_o,) or a diagonal matrix: the fixed R of ``noise="fixed"``
            (default identity), ignored otherwise.
        convergence: stopping rules (default ``Convergence()``: the paper's 10⁻³ tests).
        compiled: run the numba kernel.
        progress: called after every accepted pass with (pass number, equivalent evaluations
            so far, cost under the current R) — e.g. to print progress.

    Returns:
        A frozen ``Estimate``. Non-convergence is reported in its status, not raised.

    Raises:
        InputError / InputTypeError: bad arguments.
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

    started = _time.perf_counter()
    problem = OutputErrorProblem(model, data, method=method, compiled=compiled)
    r_diag = _check_r(R, problem.n_outputs)
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
    optimizer_evaluations = objective.evaluations

    # Information matrix at θ̂ by central differences (counted separately).
    before = problem.evaluations
    try:
        g, _ = problem.sensitivities(
            outcome.theta, outcome.outputs, relative_step=1e-5, central=True
        )
    except SimulationError as exc:
        raise EstimationError(f"information matrix at the estimate: {exc}") from exc
    accuracy_evaluations = problem.evaluations - before
    m = information_matrix(g, objective.r_diag)
    covariance, std_free, undetermined = _covariance(m, problem.typical)
    status, message = outcome.status, outcome.message
    if undetermined:
        names = [problem.free_names[j] for j in undetermined]
        message += (
            f"; the information matrix is singular: {names} cannot be determined from "
            "these data (their Cramér–Rao bounds are reported as infinite)"
        )

    values = problem.full_theta(outcome.theta)
    std = np.full(values.shape, np.nan)
    std[problem.free_index] = std_free
    estimated_model = model.with_parameters(model.parameters.with_values(values))
    return Estimate(
        names=tuple(model.parameters.names),
        values=values,
        initial=problem.theta_start_full,
        free=problem.free_mask,
        std=std,
        covariance=covariance,
        information_matrix=m,
        sensitivities=g,
        r_diag=objective.r_diag,
        cost=float(outcome.cost),
        cost_history=tuple(objective.cost_history),
        evaluation_history=tuple(objective.evaluation_history),
        equivalent_evaluations=optimizer_evaluations,
        accuracy_evaluations=accuracy_evaluations,
        iterations=iterations,
        noise_cycles=cycles,
        converged=outcome.converged,
        status=status,
        message=message,
        time=problem.time,
        measured=problem.measured,
        predicted=outcome.outputs,
        residuals=problem.residuals(outcome.outputs),
        maneuver_index=problem.maneuver_index,
        output_names=tuple(model.outputs),
        solver=solver.name,
        solver_settings=solver.settings(),
        noise_policy=noise,
        method=method,
        wall_time_s=_time.perf_counter() - started,
        model=estimated_model,
    )
