"""Random-search confidence limits (after Mereau & Raymond, as used in RP-1153 §5.B).

The limits of θ_j are the extremes of θ_j over the likelihood region {θ : J(θ) − J(θ̂) ≤ Δ},
which for a nonlinear model need be neither ellipsoidal nor symmetric. The search samples the
parameter space, keeps the points that fall inside, and keeps refining, for every parameter,
the inside points that maximise and minimise it. Every point it reports has been simulated and
found inside, so search limits approach the true extremes from within.

Coordinates: u-space is θ = θ̂ + √Δ · L u with L Lᵀ = M⁻¹ (the Cramér–Rao covariance); the
quadratic approximation of the region is the unit ball ‖u‖ ≤ 1.

1. Global phase (``global_fraction`` of the budget): points along random directions at radii
   uniform in [0, ``expand``] (radius-uniform rather than volume-uniform, so that in many
   dimensions points still land inside), in chunks of ``CHUNK`` simulations. Inside points
   seed the 2·n_p extremes.
2. Refinement: each extreme is refined by its own task, from the extremes of the global
   phase, on a share of the remaining budget (remaining / extremes not settled); tasks whose
   extreme settled early leave budget to a next wave for the others (at most ``MAX_WAVES``).
   Within a task, random directions are drawn around the direction of the
   current extreme point, d' = (d + ρ ξ)/‖d + ρ ξ‖, ξ ~ N(0, I/n_p), and the boundary along
   each ray is located (batched root-finding of √(J − J(θ̂)) = √Δ in the radius, which is
   ≈ linear in it, keeping the last inside point). A proposal whose boundary point pushes the
   extreme further is kept; ρ grows by 1.5 after a success and shrinks by 0.6 after a failure
   (a (1 + λ) evolution strategy on the sphere of directions). An extreme is settled when
   ρ < ``rho_min``. Every inside point a task meets updates every extreme; the tasks'
   extremes are merged in task order.
3. Final refinement: from each extreme point, a step along ±e_j to the contour.

Random streams and parallel runs: every task has its own stream,
``numpy.random.SeedSequence(seed, spawn_key=(0, chunk))`` for a global chunk and
``SeedSequence(seed, spawn_key=(1, wave, extreme))`` for a refinement task, and the tasks are
fixed by the budget alone (chunks of ``CHUNK``; one task per extreme). So the limits do not
depend on where the tasks run: ``engine`` (a ``flightid.batch`` engine: serial, or Dask
workers that get a copy of the contour) changes the wall time only, never a number. (Before
the tasks, one stream drove the whole search and all extremes were refined in common rounds;
limits of a given seed changed with the split, within the search's own scatter.)

The budget is in equivalent evaluations (integrations); the search stops when it is spent.
Simulations that diverge count as outside. Points beyond the radius ``max_radius`` (u units)
are not tried; an extreme that reaches it is reported open (±inf).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from flightid.accuracy.contour import Contour
from flightid.accuracy.progress import Progress
from flightid.parallel import Shared, map_ordered

__all__ = ["CHUNK", "MAX_WAVES", "SearchLimits", "random_search"]

CHUNK = 256  # simulations per global-phase task (fixed: not a function of the workers)
MAX_WAVES = 4  # refinement waves at most (a wave: one task per extreme not yet settled)


@dataclass(frozen=True)
class SearchLimits:
    """Random-search limits.

    Attributes:
        intervals: (n_f, 2) [lower, upper] over all inside points found (±inf if open).
        extreme_points: (n_f, 2, n_f) the inside points attaining them.
        evaluations: integrations spent.
        inside: number of evaluated points found inside the region.
        settled: (n_f, 2) whether each extreme's refinement converged before the budget ran out.
        delta: the contour level Δ.
        seed: the random seed.
        history: (evaluations, intervals) snapshots after each refinement round.
    """

    intervals: np.ndarray
    extreme_points: np.ndarray
    evaluations: int
    inside: int
    settled: np.ndarray
    delta: float
    seed: int
    history: tuple = field(repr=False, default=())


def _square_root(covariance: np.ndarray) -> np.ndarray:
    """L with L Lᵀ = C (symmetric square root; non-finite or negative modes dropped)."""
    c = np.asarray(covariance, dtype=float)
    c = np.where(np.isfinite(c), c, 0.0)
    scale = np.sqrt(np.maximum(np.diag(c), 1e-300))
    eigenvalues, vectors = np.linalg.eigh(c / np.outer(scale, scale))
    root = vectors * np.sqrt(np.maximum(eigenvalues, 0.0)) @ vectors.T
    return root * scale[:, None]


class _Tracker:
    """Extremes of every parameter over the inside points met."""

    def __init__(self, contour: Contour):
        n = contour.n_free
        self.contour = contour
        self.points = np.repeat(contour.theta_hat[None, None, :], 2, axis=1).repeat(n, axis=0)
        self.values = np.column_stack([contour.theta_hat, contour.theta_hat]).astype(float)
        self.inside = 0

    def merge(self, values: np.ndarray, points: np.ndarray, inside: int) -> None:
        """Take another tracker's extremes where they go further (strictly)."""
        self.inside += int(inside)
        for j in range(values.shape[0]):
            if values[j, 0] < self.values[j, 0]:
                self.values[j, 0], self.points[j, 0] = values[j, 0], points[j, 0]
            if values[j, 1] > self.values[j, 1]:
                self.values[j, 1], self.points[j, 1] = values[j, 1], points[j, 1]

    def evaluate(self, thetas: np.ndarray) -> np.ndarray:
        excess, _ = self.contour.costs(thetas)
        inside = excess <= self.contour.delta
        self.inside += int(inside.sum())
        if inside.any():
            kept = thetas[inside]
            for j in range(thetas.shape[1]):
                k = int(np.argmin(kept[:, j]))
                if kept[k, j] < self.values[j, 0]:
                    self.values[j, 0], self.points[j, 0] = kept[k, j], kept[k]
                k = int(np.argmax(kept[:, j]))
                if kept[k, j] > self.values[j, 1]:
                    self.values[j, 1], self.points[j, 1] = kept[k, j], kept[k]
        return excess


def _boundary_along(
    tracker: _Tracker,
    origins: np.ndarray,
    directions: np.ndarray,
    first: np.ndarray,
    r_max: float,
    iterations: int,
    rtol: float = 1e-4,
    w_origin: np.ndarray | None = None,
) -> np.ndarray:
    """Distance s ≥ 0 to the contour along θ = origin + s·direction (batched); last inside s.

    √(J − J(θ̂)) is treated as ≈ linear in s between the origin (inside; its √excess is
    ``w_origin``, default 0 for θ̂) and trial points; bracketing keeps it safe.
    """
    delta = tracker.contour.delta
    target = np.sqrt(delta)
    b = origins.shape[0]
    lo = np.zeros(b)
    w_lo = np.zeros(b) if w_origin is None else np.array(w_origin, dtype=float)
    hi = np.full(b, np.inf)
    w_hi = np.full(b, np.inf)
    s = np.minimum(first, r_max)
    active = np.ones(b, dtype=bool)
    for _ in range(iterations):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        thetas = origins[idx] + s[idx, None] * directions[idx]
        excess = tracker.evaluate(thetas)
        w = np.sqrt(np.maximum(excess, 0.0))
        inside = excess <= delta
        lo[idx[inside]], w_lo[idx[inside]] = s[idx[inside]], w[inside]
        hi[idx[~inside]], w_hi[idx[~inside]] = s[idx[~inside]], w[~inside]
        # settled: an inside point within rtol of the contour, or a collapsed bracket
        done = inside & (w >= (1.0 - rtol) * target)
        done |= inside & (s[idx] >= r_max)
        done |= np.isfinite(hi[idx]) & ((hi[idx] - lo[idx]) <= 1e-9 * hi[idx])
        active[idx[done]] = False
        # next trial: secant on w through the bracket (or from the inside end outward)
        for k in np.flatnonzero(active):
            if np.isfinite(hi[k]) and np.isfinite(w_hi[k]) and w_hi[k] > w_lo[k]:
                fraction = (target - w_lo[k]) / (w_hi[k] - w_lo[k])
                s[k] = lo[k] + np.clip(fraction, 0.05, 0.95) * (hi[k] - lo[k])
            elif np.isfinite(hi[k]):
                s[k] = 0.5 * (lo[k] + hi[k])
            else:
                grow = target / w_lo[k] if w_lo[k] > 0 else 2.0
                s[k] = min(lo[k] * min(max(grow, 1.05), 4.0), r_max)
    return lo


@dataclass(frozen=True)
class _Geometry:
    """u-space of the search: θ = θ̂ + scale · root · u, scale = √Δ."""

    root: np.ndarray  # L (n_f, n_f), L Lᵀ = M⁻¹ over the searched parameters
    pseudo_inverse: np.ndarray  # L⁺
    scale: float  # √Δ


@dataclass(frozen=True)
class _Outcome:
    """What a task found: its tracker's extremes, inside count, integrations spent."""

    values: np.ndarray
    points: np.ndarray
    inside: int
    evaluations: int
    lowest_excess: float
    rho: float = np.nan
    settled: bool = False


@dataclass(frozen=True)
class _GlobalChunk:
    shared: Any  # flightid.parallel.Shared of the Contour (loaded once per worker)
    geometry: _Geometry
    size: int
    stream: np.random.SeedSequence
    expand: float


@dataclass(frozen=True)
class _Refinement:
    shared: Any  # flightid.parallel.Shared of the Contour
    geometry: _Geometry
    target: tuple[int, int]  # (j, side): side 0 lower, 1 upper
    values: np.ndarray  # the merged extremes the task starts from
    points: np.ndarray
    rho: float
    share: int  # integrations to spend at most (the last round may overshoot)
    stream: np.random.SeedSequence
    batch: int
    rho_min: float
    ray_iterations: int
    max_radius: float


def _outcome(tracker: _Tracker, spent: int, rho: float = np.nan, settled: bool = False):
    return _Outcome(
        tracker.values.copy(),
        tracker.points.copy(),
        tracker.inside,
        spent,
        tracker.contour.lowest_excess,
        rho,
        settled,
    )


def _run_global(task: _GlobalChunk) -> _Outcome:
    """``task.size`` points along random directions, radii uniform in [0, expand]."""
    contour, g = task.shared.obj, task.geometry
    rng = np.random.default_rng(task.stream)
    tracker = _Tracker(contour)
    before = contour.evaluations
    xi = rng.standard_normal((task.size, contour.n_free))
    xi /= np.linalg.norm(xi, axis=1, keepdims=True)
    radius = task.expand * rng.random(task.size)
    # θ = θ̂ + √Δ · L (r ξ)
    tracker.evaluate(contour.theta_hat + g.scale * (radius[:, None] * xi) @ g.root.T)
    return _outcome(tracker, contour.evaluations - before)


def _run_refinement(task: _Refinement) -> _Outcome:
    """(1 + λ) evolution strategy over directions for one extreme, within ``task.share``."""
    contour, g, t = task.shared.obj, task.geometry, task.target
    n = contour.n_free
    rng = np.random.default_rng(task.stream)
    tracker = _Tracker(contour)
    tracker.values, tracker.points = task.values.copy(), task.points.copy()
    before = contour.evaluations
    rho, settled = task.rho, False
    j, side = t
    while contour.evaluations - before < task.share:
        # u of the current extreme point: u = L⁺ (θ − θ̂) / √Δ
        u = g.pseudo_inverse @ (tracker.points[t] - contour.theta_hat) / g.scale
        norm = np.linalg.norm(u)
        if norm == 0:
            u = rng.standard_normal(n)
            norm = np.linalg.norm(u)
        d = u / norm
        # d' = (d + ρ ξ)/‖d + ρ ξ‖, ξ ~ N(0, I/n_p)
        xi = rng.standard_normal((task.batch, n)) / np.sqrt(n)
        proposal = d[None, :] + rho * xi
        proposal /= np.linalg.norm(proposal, axis=1, keepdims=True)
        before_value = tracker.values[j, side]
        # start each ray at the radius of the extreme's current point
        first = np.full(task.batch, max(norm, 0.25))
        _boundary_along(
            tracker,
            np.repeat(contour.theta_hat[None, :], task.batch, axis=0),
            g.scale * proposal @ g.root.T,
            first,
            task.max_radius,
            task.ray_iterations,
        )
        value = tracker.values[j, side]
        improved = value > before_value if side == 1 else value < before_value
        rho = min(rho * 1.5, 1.0) if improved else rho * 0.6
        if rho < task.rho_min:
            settled = True
            break
    return _outcome(tracker, contour.evaluations - before, rho, settled)


def random_search(
    contour: Contour,
    covariance: np.ndarray,
    budget: int = 50_000,
    seed: int = 0,
    batch: int = 8,
    expand: float = 1.5,
    global_fraction: float = 0.1,
    rho_min: float = 1e-3,
    ray_iterations: int = 8,
    max_radius: float = 50.0,
    progress: bool | None = None,
    engine: Any = None,
) -> SearchLimits:
    """Random-search limits of all free parameters within ``budget`` evaluations.

    Args:
        contour: the minimum, R and level Δ.
        covariance: M⁻¹ at θ̂: shapes the sampling (parameters with inf variance are not
            searched; their limits are reported as ±inf).
        budget: equivalent evaluations to spend at most (each refinement task may overshoot
            its share by less than one round of ``batch`` rays).
        seed: the root of the tasks' ``numpy.random.SeedSequence`` streams.
        batch: proposals per extreme per refinement round (λ).
        expand: global phase radius, in units of the quadratic region.
        global_fraction: share of the budget for the global phase.
        rho_min: direction spread at which an extreme counts as settled.
        ray_iterations: root-finding iterations per ray.
        max_radius: largest radius tried, u units.
        progress: draw a progress bar on stderr (None: if stderr is a terminal).
        engine: a ``flightid.batch`` engine (``make_engine``) for the global chunks and the
            refinement tasks; None runs them here. The limits are the same on any engine.

    Raises:
        TaskError: a task failed (named in the message).
    """
    n = contour.n_free
    shared = Shared(contour)
    covariance = np.asarray(covariance, dtype=float)
    finite = np.isfinite(np.diag(covariance))
    root = _square_root(np.where(np.outer(finite, finite), covariance, 0.0))
    geometry = _Geometry(root, np.linalg.pinv(root), float(np.sqrt(contour.delta)))
    tracker = _Tracker(contour)
    start = contour.evaluations
    bar = Progress(budget, "random search", progress)

    def spent() -> int:
        return contour.evaluations - start

    def run(fn, tasks, labels, what: str) -> list[_Outcome]:
        before = contour.evaluations
        outcomes = map_ordered(engine, fn, tasks, labels)
        # tasks run on copies elsewhere (Dask) spend their integrations there: count them here
        remote = sum(o.evaluations for o in outcomes) - (contour.evaluations - before)
        contour.start_evaluations -= remote
        for o in outcomes:
            tracker.merge(o.values, o.points, o.inside)
            contour.lowest_excess = min(contour.lowest_excess, o.lowest_excess)
        bar.update(spent(), what)
        return outcomes

    # 1. global phase: random directions, radii uniform in [0, expand]
    n_global = int(global_fraction * budget)
    sizes = [CHUNK] * (n_global // CHUNK) + ([n_global % CHUNK] if n_global % CHUNK else [])
    chunks = [
        _GlobalChunk(shared, geometry, size, np.random.SeedSequence(seed, spawn_key=(0, k)), expand)
        for k, size in enumerate(sizes)
    ]
    if chunks:
        run(
            _run_global,
            chunks,
            [f"random search chunk {k}" for k in range(len(chunks))],
            "(global)",
        )

    # 2. refinement of the 2·n_p extremes, one task each, in waves
    targets = [(j, side) for j in range(n) if finite[j] for side in (0, 1)]
    rho = {t: 0.5 for t in targets}
    settled = np.zeros((n, 2), dtype=bool)
    for j in np.flatnonzero(~finite):
        settled[j] = True
    history = []
    for wave in range(MAX_WAVES):
        active = [t for t in targets if not settled[t]]
        left = budget - spent()
        if not active or left < batch * len(active):
            break
        share = left // len(active)
        tasks = [
            _Refinement(
                shared,
                geometry,
                t,
                tracker.values.copy(),
                tracker.points.copy(),
                rho[t],
                share,
                np.random.SeedSequence(seed, spawn_key=(1, wave, targets.index(t))),
                batch,
                rho_min,
                ray_iterations,
                max_radius,
            )
            for t in active
        ]
        labels = [
            f"random search {('lower', 'upper')[side]} extreme of free parameter {j}"
            for j, side in active
        ]
        outcomes = run(_run_refinement, tasks, labels, "(refinement)")
        for t, o in zip(active, outcomes, strict=True):
            rho[t] = o.rho
            settled[t] = o.settled
        history.append((spent(), tracker.values.copy()))
        bar.update(spent(), f"({int(settled.sum())}/{2 * n} extremes settled)")

    # 3. final step along ±e_j from each extreme point to the contour
    scale = geometry.scale
    origins, steps = [], []
    for j in np.flatnonzero(finite):
        for side, sign in ((0, -1.0), (1, 1.0)):
            origins.append(tracker.points[j, side])
            e = np.zeros(n)
            e[j] = sign * scale * np.sqrt(covariance[j, j])
            steps.append(e)
    if origins:
        origins = np.array(origins)
        w_origin = np.sqrt(np.clip(tracker.evaluate(origins), 0.0, contour.delta))
        _boundary_along(
            tracker,
            origins,
            np.array(steps),
            np.full(len(origins), 0.05),
            max_radius,
            ray_iterations,
            w_origin=w_origin,
        )
    intervals = tracker.values.copy()
    reach = np.sqrt(covariance.diagonal().clip(min=0)) * scale * max_radius * 0.999
    for j in range(n):
        if not finite[j]:
            intervals[j] = (-np.inf, np.inf)
            continue
        if contour.theta_hat[j] - intervals[j, 0] >= reach[j]:
            intervals[j, 0] = -np.inf
        if intervals[j, 1] - contour.theta_hat[j] >= reach[j]:
            intervals[j, 1] = np.inf
    bar.close(spent(), f"({int(settled.sum())}/{2 * n} extremes settled)")
    return SearchLimits(
        intervals=intervals,
        extreme_points=tracker.points.copy(),
        evaluations=spent(),
        inside=tracker.inside,
        settled=settled,
        delta=contour.delta,
        seed=seed,
        history=tuple(history),
    )
