"""Profile-likelihood confidence limits: the extremes of θ_j on the contour, by Gauss–Newton.

The paper's closing wish (RP-1153 §7) was to get the random-search limits with gradient
techniques. The extreme of θ_j over the region {J(θ) − J(θ̂) ≤ Δ} is where the *profile*

    P_j(t) = min_{θ_−j} J(θ_−j, θ_j = t) − J(θ̂)

reaches Δ: for any θ in the region with θ_j = t, P_j(t) ≤ J(θ) − J(θ̂) ≤ Δ, and the minimiser
at P_j(t) = Δ lies on the contour. So each limit is a one-dimensional root-finding problem on
an inner minimisation:

* inner problem: Gauss–Newton on θ_−j with θ_j held at t, forward-difference sensitivities
  (one batch of n_p integrations per pass; the column of θ_j comes in the same batch), step
  halving, stopped when the predicted decrease is below ``inner_tolerance``·Δ;
* outer problem: w(u) = √P_j(θ̂_j ± u) is ≈ u/σ_j (exactly so for a linear model), so Newton
  on w(u) = √Δ converges in a few steps. Its slope comes free from the envelope theorem,
  dP_j/dt = ∂J/∂θ_j = −2 Σ_i G_ijᵀ R⁻¹ ν_i at the inner minimum. The first trial is the
  Cramér–Rao projection u = √(Δ C_jj); once the root is bracketed, steps that leave the bracket
  are replaced by regula falsi / bisection;
* warm starts: each inner problem starts from the previous minimum moved along the linearised
  profile trace dθ_−j/dt = −M_{−j,−j}⁻¹ M_{−j,j} (the conditional mean direction).

A side on which P_j stays below Δ out to ``max_sigmas``·√Δ·σ_j is reported as open (±inf).
Simulations that diverge count as outside the region.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from flightid.accuracy.contour import Contour
from flightid.estimation.gauss_newton import gauss_newton_step
from flightid.parallel import Shared, map_ordered

__all__ = ["ProfileCurve", "ProfileLimits", "profile_curve", "profile_limits"]


@dataclass(frozen=True)
class ProfileLimits:
    """Profile-likelihood limits of every free parameter.

    Attributes:
        intervals: (n_f, 2) [lower, upper]; ±inf where the region is open.
        statuses: per parameter (lower, upper): converged | open | undetermined |
            max_iterations | failed.
        evaluations: integrations per parameter (n_f,).
        delta: the contour level Δ used.
        boundary_points: per parameter (lower point, upper point) on the contour (n_f,) each,
            None where not found.
    """

    intervals: np.ndarray
    statuses: tuple[tuple[str, str], ...]
    evaluations: np.ndarray
    delta: float
    boundary_points: tuple = field(repr=False, default=())

    @property
    def total_evaluations(self) -> int:
        return int(np.sum(self.evaluations))


@dataclass(frozen=True)
class ProfileCurve:
    """P_j(t) = min over the others of J − J(θ̂) along a grid of θ_j."""

    index: int  # free-parameter index j
    values: np.ndarray  # grid of θ_j
    excess: np.ndarray  # P_j at the grid (J units); inf where the simulation diverged
    evaluations: int


@dataclass
class _Point:
    u: float  # signed distance side·(t − θ̂_j)
    w: float  # √P (inf outside / diverged)
    theta: np.ndarray  # inner minimiser
    trace: np.ndarray | None  # dθ/dt along the profile
    slope: float  # dw/du (nan if unknown)


class _Profiler:
    def __init__(self, contour: Contour, j: int, inner_tolerance: float, max_passes: int):
        self.contour = contour
        self.j = j
        self.others = np.array([k for k in range(contour.n_free) if k != j], dtype=int)
        self.tolerance = inner_tolerance * contour.delta
        self.max_passes = max_passes

    def minimise(self, theta: np.ndarray):
        """Inner GN at fixed θ_j: (θ*, P, dP/dθ_j, trace) — P inf if the simulation diverges."""
        contour, j, others = self.contour, self.j, self.others
        problem = contour.problem
        r = contour.r_diag
        theta = np.asarray(theta, dtype=float).copy()
        excess, outputs = contour.costs(theta[None, :])
        excess, outputs = float(excess[0]), outputs[0]
        if not np.isfinite(excess):
            return theta, np.inf, np.nan, None
        g = None
        for _ in range(self.max_passes):
            g = contour.sensitivities(theta, outputs)
            if g is None:
                break
            nu = problem.residuals(outputs)
            if others.size == 0:
                break
            g_o = g[:, :, others]
            step = gauss_newton_step(g_o, nu, r).step
            change = g_o @ step
            # predicted decrease ≈ 2 νᵀR⁻¹GΔθ − ‖R^(−½)GΔθ‖²
            predicted = float(np.sum((2.0 * nu - change) * change / r[None, :]))
            if predicted <= self.tolerance:
                break
            improved = False
            for _halving in range(10):
                trial = theta.copy()
                trial[others] += step
                trial_excess, trial_outputs = contour.costs(trial[None, :])
                if np.isfinite(trial_excess[0]) and trial_excess[0] < excess:
                    theta, excess, outputs = trial, float(trial_excess[0]), trial_outputs[0]
                    improved = True
                    break
                step = 0.5 * step
            if not improved:
                break
        if g is None:
            return theta, excess, np.nan, None
        nu = problem.residuals(outputs)
        # dP/dθ_j = ∂J/∂θ_j = −2 Σ_i G_ijᵀ R⁻¹ ν_i   (envelope theorem)
        derivative = float(-2.0 * np.sum(g[:, :, j] * nu / r[None, :]))
        # trace dθ_−j/dθ_j = −M_{−j,−j}⁻¹ M_{−j,j}
        a = (g / np.sqrt(r)[None, :, None]).reshape(-1, g.shape[-1])
        trace = np.zeros(contour.n_free)
        trace[j] = 1.0
        if others.size:
            solution, *_ = np.linalg.lstsq(a[:, others], a[:, j], rcond=None)
            trace[others] = -solution
        return theta, excess, derivative, trace


def _side(
    profiler: _Profiler,
    side: int,
    sigma: float,
    trace0: np.ndarray,
    rtol: float,
    max_iterations: int,
    max_sigmas: float,
) -> tuple[float, str, np.ndarray | None]:
    contour, j = profiler.contour, profiler.j
    theta_hat = contour.theta_hat
    target = np.sqrt(contour.delta)
    u_max = max_sigmas * target * sigma
    origin = _Point(0.0, 0.0, theta_hat, trace0, 1.0 / sigma)
    lo, hi = origin, None
    u = target * sigma  # Cramér–Rao projection √(Δ C_jj)
    for _ in range(max_iterations):
        base = lo if hi is None or abs(u - lo.u) <= abs(hi.u - u) or hi.trace is None else hi
        trace = base.trace if base.trace is not None else trace0
        # warm start: θ_start = θ*(base) + (t − t_base) · dθ/dt
        start = base.theta + side * (u - base.u) * trace
        start[j] = theta_hat[j] + side * u
        theta, excess, derivative, new_trace = profiler.minimise(start)
        w = np.sqrt(max(excess, 0.0)) if np.isfinite(excess) else np.inf
        slope = side * derivative / (2.0 * w) if np.isfinite(w) and w > 0 else np.nan
        point = _Point(u, w, theta, new_trace, slope)
        if w <= target:
            lo = point
        else:
            hi = point
        if np.isfinite(w) and abs(w - target) <= rtol * target:
            return float(theta[j]), "converged", theta
        if hi is not None and hi.u - lo.u <= 1e-9 * sigma * target:
            return float(lo.theta[j]), "converged", lo.theta
        # Newton on w(u) = √Δ, then safeguards
        if np.isfinite(w) and np.isfinite(slope) and slope > 0:
            u_new = u + (target - w) / slope
        else:
            u_new = np.nan
        if hi is None:
            if not np.isfinite(u_new) or u_new <= lo.u:
                u_new = 2.0 * lo.u
            u_new = min(u_new, 4.0 * max(lo.u, target * sigma))
            if lo.u >= u_max:
                return float(np.copysign(np.inf, side)), "open", None
            u_new = min(u_new, u_max)
        elif not (lo.u < u_new < hi.u):
            if np.isfinite(hi.w):
                # regula falsi on w between the bracket ends
                fraction = (target - lo.w) / (hi.w - lo.w)
                u_new = lo.u + np.clip(fraction, 0.1, 0.9) * (hi.u - lo.u)
            else:
                u_new = 0.5 * (lo.u + hi.u)
        u = float(u_new)
    if hi is None:
        return float(lo.theta[j]), "max_iterations", lo.theta
    return float(lo.theta[j]), "max_iterations", lo.theta


def profile_limits(
    contour: Contour,
    covariance: np.ndarray,
    parameters: list[int] | None = None,
    rtol: float = 1e-4,
    inner_tolerance: float = 1e-5,
    max_iterations: int = 30,
    max_passes: int = 20,
    max_sigmas: float = 50.0,
    engine: Any = None,
) -> ProfileLimits:
    """Profile-likelihood limits of the free parameters on the contour Δ.

    Args:
        contour: the minimum, R and level Δ.
        covariance: M⁻¹ at θ̂ (n_f × n_f): the first trial points and warm-start directions.
        parameters: free-parameter indices to do (default all; others get NaN).
        rtol: stop when |√P − √Δ| ≤ rtol·√Δ (P within ≈ 2·rtol·Δ of Δ).
        inner_tolerance: inner GN stops when its predicted decrease is below this·Δ.
        max_iterations: outer (root-finding) iterations per side.
        max_passes: inner GN passes per trial value.
        max_sigmas: a side is open if P < Δ at max_sigmas·√Δ·σ_j.
        engine: a ``flightid.batch`` engine (``make_engine``): one task per parameter, run
            where the engine runs them (Dask workers get a copy of the contour); None runs
            them here, one after the other. Same numbers, same order, on any engine.

    Raises:
        TaskError: a parameter's task failed (its name in the message).
    """
    n = contour.n_free
    covariance = np.asarray(covariance, dtype=float)
    todo = list(range(n) if parameters is None else parameters)
    intervals = np.full((n, 2), np.nan)
    statuses: list[tuple[str, str]] = [("skipped", "skipped")] * n
    evaluations = np.zeros(n, dtype=int)
    points: list = [None] * n
    shared = Shared(contour)
    tasks = [
        _ProfileTask(
            shared, covariance, j, rtol, inner_tolerance, max_iterations, max_passes, max_sigmas
        )
        for j in todo
    ]
    before = contour.evaluations
    outcomes = map_ordered(
        engine, _profile_one, tasks, labels=[f"profile of free parameter {j}" for j in todo]
    )
    # tasks run on copies elsewhere (Dask) spend their integrations there: count them here
    remote = sum(o.evaluations for o in outcomes) - (contour.evaluations - before)
    contour.start_evaluations -= remote
    for j, outcome in zip(todo, outcomes, strict=True):
        intervals[j] = outcome.interval
        statuses[j] = outcome.statuses
        evaluations[j] = outcome.evaluations
        points[j] = outcome.points
        contour.lowest_excess = min(contour.lowest_excess, outcome.lowest_excess)
    return ProfileLimits(intervals, tuple(statuses), evaluations, contour.delta, tuple(points))


@dataclass(frozen=True)
class _ProfileTask:
    """One parameter's profile limits (picklable: Dask ships the contour with cloudpickle,
    loaded once per worker: ``flightid.parallel.Shared``)."""

    shared: Any
    covariance: np.ndarray
    j: int
    rtol: float
    inner_tolerance: float
    max_iterations: int
    max_passes: int
    max_sigmas: float


@dataclass(frozen=True)
class _ProfileOutcome:
    interval: tuple[float, float]
    statuses: tuple[str, str]
    evaluations: int
    points: tuple | None
    lowest_excess: float


def _profile_one(task: _ProfileTask) -> _ProfileOutcome:
    """Lower and upper profile limit of free parameter ``task.j``."""
    contour, covariance, j = task.shared.obj, task.covariance, task.j
    sigma = np.sqrt(covariance[j, j]) if np.isfinite(covariance[j, j]) else np.inf
    if not (np.isfinite(sigma) and sigma > 0):
        return _ProfileOutcome(
            (-np.inf, np.inf), ("undetermined", "undetermined"), 0, None, contour.lowest_excess
        )
    before = contour.evaluations
    profiler = _Profiler(contour, j, task.inner_tolerance, task.max_passes)
    # initial trace: C[:, j] / C_jj (the conditional-mean direction)
    trace0 = covariance[:, j] / covariance[j, j]
    sides = [
        _side(profiler, side, sigma, trace0, task.rtol, task.max_iterations, task.max_sigmas)
        for side in (-1, +1)
    ]
    (lower, status_lower, point_lower), (upper, status_upper, point_upper) = sides
    return _ProfileOutcome(
        (lower, upper),
        (status_lower, status_upper),
        contour.evaluations - before,
        (point_lower, point_upper),
        contour.lowest_excess,
    )


def profile_curve(
    contour: Contour,
    covariance: np.ndarray,
    j: int,
    values: np.ndarray,
    inner_tolerance: float = 1e-5,
    max_passes: int = 20,
) -> ProfileCurve:
    """P_j on a grid of θ_j values, swept outward from θ̂_j with warm starts."""
    values = np.asarray(values, dtype=float)
    before = contour.evaluations
    profiler = _Profiler(contour, j, inner_tolerance, max_passes)
    covariance = np.asarray(covariance, dtype=float)
    trace0 = covariance[:, j] / covariance[j, j]
    excess = np.full(values.shape, np.nan)
    centre = contour.theta_hat[j]
    for direction in (+1, -1):
        order = [
            k for k in np.argsort(np.abs(values - centre)) if (values[k] - centre) * direction >= 0
        ]
        theta_prev, t_prev, trace = contour.theta_hat.copy(), centre, trace0
        for k in order:
            if direction < 0 and np.isfinite(excess[k]):
                continue
            start = theta_prev + (values[k] - t_prev) * trace
            start[j] = values[k]
            theta, p, _, new_trace = profiler.minimise(start)
            excess[k] = p
            if np.isfinite(p):
                theta_prev, t_prev = theta, values[k]
                trace = new_trace if new_trace is not None else trace
    return ProfileCurve(j, values, excess, contour.evaluations - before)
