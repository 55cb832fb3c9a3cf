"""MNRES — modified Newton–Raphson with estimated sensitivities (RP-1153 §4, 4.9–4.24).

Two families of forms. The default, ``form="secant"``, keeps one estimate of the
sensitivities and corrects it with every simulation; the surface forms (``"algebraic"``,
``"batch"``, ``"recursive"``, below) refit a surface through stored points, as the paper does.

Secant form
-----------
The paper's idea — sensitivities estimated from previously computed points instead of
n_p + 1 integrations per pass [4.9–4.15] — kept, its algebra changed. With ϑ = θ / scale
(scale = max(|θ_j|, floor_j) at the last sweep) and J = ∂y/∂ϑ (N·n_o × n_f):

1. Sweep: J by forward differences at θ (n_f integrations in one batch); relative step
   ``initial_perturbation`` (default 1e-3, the surface forms' perturbation) at the start,
   MNR's 1e-6 at every later sweep. Measured: with 1e-6 at the start too, RP-1153 example 3
   case 1 (noise-free, nonlinear) stalled at J = 1.7e7 as MNR does — the wide first
   difference sees past the local curvature there; with 1e-3 at every sweep the bounded
   short-period test of tests/test_honest_convergence.py ended 0.1 σ from the constrained
   optimum (the later sweeps, near the optimum, need the accurate slopes). This
   pass equals the paper's initialisation and one finite-difference MNR pass. The
   per-output blocks are formed once (O(N·n_o·n_f²), amortised over the n_f simulations of
   the sweep).
2. Pass: M = Σ_k J_kᵀJ_k / R_kk, c = JᵀR⁻¹ν; the trust-region step Δϑ (the Gauss–Newton
   step M⁺c, shortened to length Δ if longer, its direction kept; see step control for the
   damped step); one integration at θ + Δθ.
3. Broyden's rank-one update with the output change Δy that step caused:

       u = Δy − JΔϑ,   J ← J + u Δϑᵀ / ‖Δϑ‖²          (afterwards JΔϑ = Δy exactly)
       J_kᵀJ_k ← J_kᵀJ_k + p_k vᵀ + v p_kᵀ + ‖u_k‖² v vᵀ,  p_k = J_kᵀu_k, v = Δϑ/‖Δϑ‖²

   O(N·n_o·n_f) per pass (J_kᵀJ_k recomputed exactly every n_f updates, which costs the
   same amortised); no QR of the N·n_o × n_f sensitivities and no surface refit per pass.
   This is the surface of [4.15] carried along the path: the algebraic surface through
   θ⁰ … θ^{n_p} satisfies the secant condition for every stored difference at once, Broyden's
   update for the newest one, leaving J unchanged in directions orthogonal to the step
   (least change) instead of re-deriving them from old, far-apart points.
4. Which trials update J: an accepted one always (the slopes move with θ); a rejected one
   only a carried J — a J swept at θ is the better local model than a secant over a step
   that was too long.

Memory: one sensitivity array. J is stored as G = ∂y/∂θ = J S⁻¹ (S = diag scale) in the
very (n_f, N·n_o) array the sweep differenced into (``_SecantState.columns``; no scaled
copy); the scaling enters only the n_f × n_f matrices (M_ϑ = S M_θ S, c_ϑ = S c_θ) and the
update (G ← G + u wᵀ, w = S⁻²Δθ / ΔθᵀS⁻²Δθ, the same least-change update in ϑ); the update
and p_k = G_kᵀu_k run in place in one compiled call (``_secant_pass``), so a
pass allocates only vectors of N·n_o. The carried G is released before a new sweep
differences into a new array. Measured (``bench/peers.py --memory``, N = 1e5, 20 free,
G = 128 MB): peak increase 664 MB (5.2 G: the carried G, the differenced one and its scaled
copy at once) before, 190 MB (1.48 G) after.

Step control (trust region, ρ = realised / predicted drop, predicted = 2cᵀΔϑ − ΔϑᵀMΔϑ):
on a freshly swept J, a rejected or disappointing step (ρ < 0.25) halves the radius to
½‖Δϑ‖ (MNR's halving); ρ > 0.75 at the radius doubles it. On a carried J, a disappointing
step blames the model, not the radius: after ``max_rejections`` such passes in a row J is
swept again at the best point (the hybrid: one finite-difference sweep when the secant model
is poor), the radius only halved by a rejected step. Default: one such pass per 20 free
parameters, at least one — a sweep costs n_f simulations, a second chance for the carried
model one. Measured (bench/peers.py, 8 seeds, sims to J* + 0.01): with 22 free parameters
two passes raised the median from 81.5 to 91 (base) — one it is; with 40 (hard40) two
lowered it from 338.5 to 230 and every seed but one to at most scipy lm's (seed 4: 305 →
229, seed 6: 528 → 337). A sweep keeps the radius (what the fresh model learnt about the
nonlinearity) but never below twice the last accepted step; it starts unbounded (the full
Gauss–Newton step) at the first sweep and in each noise cycle. The first trial on a later
sweep is the full Gauss–Newton step too (the paper's rule: a fresh model near the optimum
often reaches it in one step, where the kept radius, shrunk by the carried passes, took
several doublings); if that step disappoints, the radius falls back to the kept one (or
half the step, if shorter), not to half the full step. Measured (8 seeds, sims to
J* + 0.01, same tree): base median 81.5 → 80 (seed 5: 85 → 83, seed 7: 82 → 81; no seed
worse); hard40 median 230 → 239.5, every seed now at most scipy lm's (seed 6: 337 → 284
against lm's 290; seed 0: 484 → 317; seed 7: 231 → 241 against lm's 744). Without the
fall-back (radius ½ the full step) hard40 seed 5 took 515 and seed 0 367.

The damped step: after a trial on freshly swept J was rejected, a radius below 1/8 of the
Gauss–Newton step's length takes the Levenberg–Marquardt step on the radius instead of the
shortened Gauss–Newton direction, damped in the metric of the columns (MINPACK's):
Δϑ = (M + μD²)⁻¹c, D = diag √M_jj, ‖Δϑ‖ = Δ. Why (hard40 seed 6, 5968 simulations to
J* + 0.01 where scipy lm needs 290): near J = 9300 the normal matrix has condition 3e9, the
Gauss–Newton step (4.5 in ϑ) is dominated by a weakly determined combination of the output
biases of V, α, Θ (a bias's ϑ is in units of its output's σ: steps of 30–300 σ) with
initial states, and the cost is curved along it: every shortened step down to 1/25 of it
was rejected, so each sweep bought one tiny step. The damped step turns away from the weak
directions. Damped with D = I (in ϑ): seed 6 1470; with D: 528 (337 with two carried
passes, above). Applied after every fresh rejection, or in every pass, it cost 2–4× the
simulations on hard40 seeds 0, 1, 2, 5 (e.g. seed 1: 259 → 689); with the 1/8 guard the
other 15 seeds of both variants were unchanged.

Convergence is claimed only from a freshly swept J, or from one whose last step realised its
predicted drop (|ρ − 1| ≤ 0.1); a carried J that says "settled" triggers a sweep first. On a
fresh J, ``fresh_rejections`` rejected trials in a row end the search as converged if the
step is below the parameter tolerance or its predicted drop below the cost tolerance;
30 such trials as stalled. The driver then confirms with central differences
(``flightid.estimation.confirm``) whatever the solver said. When the solver stops where
it last swept, with G still exactly that sweep's (MNR's step 1e-6, no update since), the
outcome hands the sweep's forward differences over (``SolverOutcome.differences``), and the
confirmation completes them to central ones with n_f integrations instead of 2·n_f, as it
does for MNR (hfb320_longitudinal: 226 → 203 simulations in all, MNR 205, measured in one
tree; base seed 7: 149 → 127).

Measured (bench/peers.py, 6-DOF Navion, 8 seeds, sims to J* + 0.01): base (22 free) median
80 against 116 for MNR and scipy's ``least_squares`` (lm); hard40 median 239.5 against lm
517 (per seed in docs/benchmarks.md). The full first step after a sweep cost the
HFB-320 case (11 free, four noise cycles) 213 simulations where it took 203 (MNR 205): its
end phases took other paths; the noise-cycle rule below brings it to 119.

Noise cycles
------------
Under the MAX noise policy (``noise="max"``) each cycle re-converges θ under a new R, and
only the last cycle's end point matters: the driver confirms it by central differences
whatever the solver said. So within a cycle, carried sensitivities proven by their last step
(|ρ − 1| ≤ 0.1) whose next trial moved the cost by less than the cost tolerance end the cycle
without the sweep the convergence test would otherwise ask for. Measured on the standard
cases (simulations in all, confirmation included; before → after, MNR): attas_lateral
314 → 152 (324), attas_lateral_two_maneuvers 92 → 78 (105), hfb320_longitudinal 213 → 119
(205), attas_lateral_yaw_delay 333 → 210 (362), attas_short_period 45 → 46 (63),
attas_fpr_biases 51 → 55 (89), twin_otter_longitudinal 43 → 69 (96),
y13aus_lateral_output_error 1534 → 1684 (1748), unstab_sp_output_error 69 → 69 (85); every
estimate within 0.03 σ of MNR's. Where the last cycle ends this way the confirmation needs
2·n_f integrations instead of n_f (no sweep to complete) and sometimes a pass, which is what
the twin otter and y13aus cases pay. Not with a parameter on a bound (the bounded
short-period test of tests/test_honest_convergence.py then ended 0.10 σ from the constrained
optimum, against 0.1 σ allowed). Under a fixed R the rule does not apply: tried there,
the relative cost test (10⁻³·J ≈ 8 on the benchmark) stopped hard40 seeds 0 and 1 far out
and their confirmations cost 1671 and 388 simulations to J* + 0.01 (317 and 191 without).

Surface forms
-------------
The solver keeps a set of parameter points with their output histories. Each pass:

1. take the lowest-cost point as the expansion point θ⁰;
2. estimate the sensitivities G_i from the surface through the stored points
   (``flightid.estimation.surface``: algebraic form [4.15], or least squares [4.18–4.23],
   batch QR or constant-window recursive);
3. take the Gauss–Newton step [4.4–4.8] with those G_i, shortened to the trust radius Δ
   (below), and integrate once at the new point;
4. if the cost dropped, the new point enters the surface and becomes θ⁰; the point that
   leaves is chosen by the geometry of the set (below). A failed trial does not enter: it
   lies where the linearisation broke down, and a secant through it misleads the slopes
   (the earlier ``learn_from_failures`` rule put it in, and on the turbulence data that
   corrupted the surface pass after pass);
5. stop when cost and parameters have settled (``Convergence``) — judged only on a surface
   fresh from perturbations about θ⁰ (a stale one first triggers a restart).

Step control: a trust region in the scaled coordinates ϑ = θ / max(|θ⁰_j|, floor_j) fixed at
(re)initialisation. The step is the Levenberg–Marquardt step Δϑ(μ) = argmin ‖b − AΔϑ‖² +
μ‖Δϑ‖² with the smallest μ ≥ 0 for which ‖Δϑ‖ ≤ Δ (μ = 0: the Gauss–Newton step). With the
cost drop predicted by the surface, pred = ‖b‖² − ‖b − AΔϑ‖², and the drop realised,
ρ = (J(θ⁰) − J(θ⁰ + Δθ)) / pred:

    rejected (J did not drop), or ρ < 0.25
    on a fresh surface:                     Δ ← ½‖Δϑ‖
    ρ > 0.75 and the step reached Δ:        Δ ← 2Δ
    otherwise:                              Δ unchanged

A disappointing but accepted step on a surface carried along the path blames the surface,
not the radius: ``max_rejections`` such passes in a row (ρ < 0.25) renew it (restart).
Δ starts unbounded (the first step is the full Gauss–Newton step) and is kept across
restarts (never below twice the last accepted step); a new noise cycle starts unbounded.
On a strongly nonlinear cost (the turbulence data under output error, where the full step
raises J ten-fold) the solver remembers how far the linearisation
can be trusted, where the paper's rule — try the full step every pass, then halve — pays
for the same discovery every pass.

Which point leaves (``replacement``): the paper drops the highest-cost point. That keeps
the cheapest points but may drop the only point that spans a direction: after one accepted
step s, the set is θ⁰ + s and perturbations δ_j e_j about θ⁰, and dropping the one along e_j
leaves e_j spanned only through s, so the slope along e_j is a difference quotient amplified
by |s|/|s_j|. The default (``"geometry"``, as derivative-free Gauss–Newton methods do)
keeps the interpolation well posed: replacing point t by x multiplies det ΔX by the value
ℓ_t(x) of t's Lagrange polynomial (ℓ_t(ϑ_j) = δ_tj), so the point that leaves maximises

    |ℓ_t(x)| · max(1, ‖ϑ_t − ϑ⁰‖² / ‖x − ϑ⁰‖²)

(the second factor sends points far from θ⁰ — stale ones — out first).

Initialisation and restart perturb each parameter from θ⁰ (n_f integrations, in one batch).
The first perturbations are ``initial_perturbation`` × max(|θ_j|, floor_j) (the floor is the
parameter's ``scale``, or 1e-3); a perturbation that would cross a bound goes the other way.
At a restart they are scaled by parameter importance (RP-1153 §4.B): with M_ℓℓ from the
current surface, δθ_ℓ ∝ 1/√M_ℓℓ — parameters that move the cost little get larger
perturbations — normalised so their geometric-mean relative size equals the restart size,
then clipped to a factor 10 either side of it. The restart size shrinks with the last
accepted step so that the surface stays local near convergence, and by another factor 10
after each restart that found no lower cost (``max_restarts`` such restarts in a row end the
search as stalled).

Restarts happen when ``max_rejections`` passes in a row fail or disappoint on a surface that
has moved on (``fresh_rejections`` on a fresh one), when ΔX (the point cloud) is
ill-conditioned, or when a surface that is neither fresh nor just proven (its last step's
ρ within 0.1 of 1) says the search has converged; the paper's version had no such safeguards
and oscillated on example 2, case 2.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from flightid.errors import EstimationError, InputError, SimulationError
from flightid.estimation.gauss_newton import GaussNewtonStep, information_matrix
from flightid.estimation.objective import Objective, SolverOutcome
from flightid.estimation.problem import FiniteDifferences
from flightid.estimation.solvers.common import (
    bounded_gauss_newton_step,
    budget_status,
    check_setting_types,
    limit_step,
    named_settings,
)
from flightid.estimation.surface import RecursiveSurface, algebraic_surface, batch_surface

__all__ = ["MNRES"]

_FORMS = ("secant", "algebraic", "batch", "recursive")
_REPLACEMENTS = ("geometry", "cost")
# trust-region ratios: below SHRINK the radius halves, above GROW (at the radius) it doubles
_SHRINK, _GROW = 0.25, 0.75
# secant form: relative step of the finite-difference sweeps and the rejected trials in a
# row on swept sensitivities before a stall
_SECANT_STEP = 1e-3
_SURFACE_PERTURBATION = 1e-3
_RESWEEP_STEP = 1e-6
_SECANT_STALL = 30
# secant form: after a rejected trial on swept sensitivities, a radius below 1/_DAMPED_RATIO of
# the Gauss–Newton step's length takes the Levenberg–Marquardt step instead (see _secant_step)
_DAMPED_RATIO = 8.0
# secant form, default max_rejections: disappointing passes on carried sensitivities before a
# sweep, one per this many free parameters (a sweep costs n_f simulations; module docstring)
_PARAMETERS_PER_REJECTION = 20


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
    rejections: int = 0  # consecutive rejected trials since the last accepted step
    last_step: np.ndarray | None = field(default=None)
    scale: np.ndarray | None = field(default=None)  # coordinates of the surface: ϑ = θ / scale
    fresh: bool = True  # the surface comes from perturbations about the current best point
    radius: float = math.inf  # trust radius Δ in ϑ units
    proven: bool = False  # the last accepted step realised its predicted drop (|ρ − 1| ≤ 0.1)


# ---------------------------------------------------------------------------- secant form
@dataclass
class _SecantState:
    """The secant form's model: θ, its outputs and cost, and the estimated sensitivities.

    ``columns`` holds the sensitivities ∂y/∂θ once, parameter by parameter: (n_f, N·n_o),
    C-ordered — the array the finite-difference sweep differenced into, updated in place by
    the secant updates (``jacobian`` is the (N, n_o, n_f) view of it, no copy).
    ``normal_by_output`` the n_o blocks G_kᵀG_k (n_o, n_f, n_f) in θ units, so
    M = Σ_k G_kᵀG_k / R_kk costs O(n_o·n_f²) when R changes. ``scale`` fixes the trust-region
    coordinates ϑ = θ / scale at the last sweep. ``differences``: the sweep's record while G
    is still exactly what it differenced (no secant update since), handed to the driver's
    confirmation when the solver stops at that point.
    """

    theta: np.ndarray
    outputs: np.ndarray
    cost: float
    scale: np.ndarray
    columns: np.ndarray | None
    normal_by_output: np.ndarray | None
    differences: FiniteDifferences | None = None
    fresh: bool = True  # the sensitivities were swept at θ (no secant update since)
    proven: bool = False  # the last accepted step realised its predicted drop (|ρ − 1| ≤ 0.1)
    radius: float = math.inf  # trust radius Δ in ϑ units
    poor: int = 0  # passes in a row whose step disappointed (ρ < 0.25 or rejected)
    updates: int = 0  # secant updates since M was last recomputed exactly
    last_length: float = 0.0  # ‖Δϑ‖ of the last accepted step
    sweeps: int = 0

    @property
    def jacobian(self) -> np.ndarray:
        """G = ∂y/∂θ as an (N, n_o, n_f) view of ``columns``."""
        n_samples, n_outputs = self.outputs.shape
        return np.moveaxis(self.columns.reshape(-1, n_samples, n_outputs), 0, -1)

    @classmethod
    def from_jacobian(
        cls, theta: np.ndarray, outputs: np.ndarray, cost: float, scale: np.ndarray, g
    ) -> _SecantState:
        """A state whose sensitivities are ``g`` (N, n_o, n_f): ``g``'s own memory when it is
        a view of a C-ordered (n_f, N, n_o) array (finite differences), else one copy."""
        columns = _columns_of(np.asarray(g, dtype=float))
        normal = _exact_normal(columns, outputs.shape[1])
        return cls(theta.copy(), outputs, float(cost), scale, columns, normal)


def _columns_of(g: np.ndarray) -> np.ndarray:
    """(n_f, N·n_o) C-ordered columns of G (N, n_o, n_f): a view where G is laid out so."""
    columns = np.moveaxis(g, -1, 0)
    if not columns.flags.c_contiguous:
        columns = np.ascontiguousarray(columns)
    return columns.reshape(columns.shape[0], -1)


def _exact_normal(columns: np.ndarray, n_outputs: int | None = None) -> np.ndarray:
    """G_kᵀG_k for every output k (n_o, n_f, n_f) from the columns (n_f, N·n_o): O(N·n_o·n_f²).

    ``columns`` may also be given as G itself (N, n_o, n_f)."""
    if columns.ndim == 3:
        g = columns
        return np.stack([g[:, k, :].T @ g[:, k, :] for k in range(g.shape[1])])
    n_free = columns.shape[0]
    by_output = columns.reshape(n_free, -1, n_outputs)
    n_o = by_output.shape[2]
    normal = np.empty((n_o, n_free, n_free))
    for k in range(n_o):
        # one output's (n_f, N) block, copied contiguous (N·n_f·8 bytes) for the product
        block = np.ascontiguousarray(by_output[:, :, k])
        normal[k] = block @ block.T
    return normal


def _secant_pass(
    columns: np.ndarray,
    change: np.ndarray,
    step: np.ndarray,
    w: np.ndarray,
    normal: np.ndarray,
    n_outputs: int,
    update_normal: bool,
) -> None:
    """One secant update in place, compiled (``_secant_kernel``): with u = Δy − GΔθ,

        p_k = G_kᵀu_k (old G),  q_k = ‖u_k‖²,  G ← G + u wᵀ,
        G_kᵀG_k ← G_kᵀG_k + p_k wᵀ + w p_kᵀ + q_k w wᵀ     (if ``update_normal``)

    ``columns``: G as (n_f, N·n_o), C-ordered; ``change`` Δy (N·n_o,), ``step`` Δθ and ``w``
    (n_f,), ``normal`` the blocks (n_o, n_f, n_f). Two passes over G (u, then p and the
    update: each element read twice, written once), O(N·n_o·n_f), one temporary of N·n_o.
    In numpy the same is a matrix-vector product, a BLAS rank-one update, n_f strided
    reductions and the n_o·n_f² block update with its temporaries: ~1 ms per pass at
    N·n_o = 8000, n_f = 22 (three simulations of the 6-DOF benchmark; a multithreaded BLAS
    made the rank-one update alone 18 ms on a loaded 2-core machine); the numpy calls around
    it were a third of MNRES's per-pass overhead on the standard cases.
    """
    n_free, size = columns.shape
    n_samples = size // n_outputs
    # u = Δy − GΔθ, column by column (contiguous rows of ``columns``)
    u = change.copy()
    for j in range(n_free):
        sj = step[j]
        if sj != 0.0:
            row = columns[j]
            for m in range(size):
                u[m] -= row[m] * sj
    q = np.zeros(n_outputs)
    for i in range(n_samples):
        base = i * n_outputs
        for k in range(n_outputs):
            q[k] += u[base + k] * u[base + k]
    p = np.zeros((n_outputs, n_free))
    acc = np.zeros(n_outputs)
    for j in range(n_free):
        row = columns[j]
        wj = w[j]
        acc[:] = 0.0
        for i in range(n_samples):
            base = i * n_outputs
            for k in range(n_outputs):
                um = u[base + k]
                # p_kj += G_old[i, k, j] u[i, k];  G[i, k, j] += u[i, k] w_j
                acc[k] += row[base + k] * um
                row[base + k] += um * wj
        for k in range(n_outputs):
            p[k, j] = acc[k]
    if update_normal:
        for k in range(n_outputs):
            for a in range(n_free):
                for b in range(n_free):
                    normal[k, a, b] += p[k, a] * w[b] + w[a] * p[k, b] + q[k] * w[a] * w[b]


_KERNEL = []  # the compiled _secant_pass, once per process (numba's disk cache)


def _secant_kernel():
    """``_secant_pass`` compiled by numba (cached on disk), on first use."""
    if not _KERNEL:
        import numba  # noqa: PLC0415

        _KERNEL.append(numba.njit(cache=True, nogil=True)(_secant_pass))
    return _KERNEL[0]


class _TrustRadiusCollapsed(Exception):
    """The damped step was asked for on a trust radius that is 0 in floating point (a
    trial step too short to change θ halves the radius to 0): no step can be formed."""


def _damped_step(
    normal: np.ndarray, gradient: np.ndarray, moving: np.ndarray, radius: float
) -> np.ndarray:
    """Levenberg–Marquardt step of length ``radius`` (ϑ units) for the ``moving`` parameters,
    damped in the metric of the columns (MINPACK's scaling, D = diag √M_jj):

        Δϑ(μ) = (M + μD²)⁻¹c = D⁻¹ V diag(1 / (λ + μ)) Vᵀ D⁻¹c,   D⁻¹MD⁻¹ = VΛVᵀ

    μ by bisection on log μ so that ‖Δϑ(μ)‖ = Δ (the caller uses it only when the
    Gauss–Newton step is longer than Δ). D measures each parameter by how much it moves the
    weighted outputs, so the damping does not depend on the units of ϑ (an output bias's
    unit is its output's σ). Measured on hard40 seed 6 (see the module docstring): damped
    with D = I instead, 1470 simulations to J* + 0.01; with D, 528.

    Raises _TrustRadiusCollapsed when Δ·min_j d_j is 0 (the bracket below has no upper end).
    """
    m = normal[np.ix_(moving, moving)]
    diagonal = np.diag(m).copy()
    d = np.sqrt(np.where(diagonal > 0, diagonal, 1.0))
    lam, vec = np.linalg.eigh(m / np.outer(d, d))
    lam = np.maximum(lam, 0.0)
    projected = vec.T @ (gradient[moving] / d)

    def step(mu: float) -> np.ndarray:
        # Δϑ(μ) = D⁻¹ V diag(1 / (λ + μ)) Vᵀ D⁻¹c
        return (vec @ (projected / (lam + mu))) / d

    # ‖Δϑ(μ)‖ ≤ ‖Vᵀ D⁻¹c‖ / (μ min_j d_j): the upper end of the bracket is inside the radius
    low = max(1e-16 * float(lam[-1]), 1e-300)
    reach = radius * float(d.min())
    if reach == 0.0:
        raise _TrustRadiusCollapsed
    high = float(np.linalg.norm(projected)) / reach + float(lam[-1])
    for _ in range(200):
        if high / low < 1.0 + 1e-6:
            break
        mid = math.sqrt(low * high)
        low, high = (mid, high) if np.linalg.norm(step(mid)) > radius else (low, mid)
    return step(high)


def _secant_step(
    normal: np.ndarray, gradient: np.ndarray, held: np.ndarray, radius: float, damped: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """(Gauss–Newton step, trust-region step) in ϑ from M and c = JᵀR⁻¹ν.

    Gauss–Newton: Δϑ = M⁺c with M scaled to unit diagonal (D⁻¹MD⁻¹, D = diag √M_jj) and
    eigenvalues below 1e-13 of the largest dropped (directions the data do not determine).
    Trust region: the Gauss–Newton step shortened to length Δ, its direction kept (MNR's
    step halving with the usable length remembered from pass to pass). Measured: a
    Levenberg–Marquardt step on the radius instead, (M + μI)⁻¹c, took the same simulations on
    the 6-DOF benchmark but, from the twin otter start with CZo 1000× off, turned towards the
    poorly determined directions and ended in a region where the simulated cost is rough
    (every ±1e-8 relative perturbation raised it), which the confirmation could not leave.
    Parameters in ``held`` (on an active bound) get no step.
    """
    n = gradient.size
    moving = ~held
    gn = np.zeros(n)
    step = np.zeros(n)
    if not moving.any():
        return gn, step
    m = normal[np.ix_(moving, moving)]
    c = gradient[moving]
    diagonal = np.diag(m).copy()
    d = np.sqrt(np.where(diagonal > 0, diagonal, 1.0))
    # D⁻¹MD⁻¹ = V Λ Vᵀ;  Δϑ = D⁻¹ V Λ⁺ Vᵀ D⁻¹ c
    lam, vec = np.linalg.eigh(m / np.outer(d, d))
    keep = lam > 1e-13 * lam[-1] if lam[-1] > 0 else np.zeros_like(lam, dtype=bool)
    coefficients = np.where(keep, (vec.T @ (c / d)) / np.where(keep, lam, 1.0), 0.0)
    gn[moving] = (vec @ coefficients) / d
    length = float(np.linalg.norm(gn))
    if length <= radius:
        return gn, gn.copy()
    if damped and length > _DAMPED_RATIO * radius:
        # the Gauss–Newton direction failed, and the radius keeps only a small part of it
        step[moving] = _damped_step(normal, gradient, moving, radius)
        return gn, step
    # the Gauss–Newton direction kept, shortened to the radius (MNR's halving, remembered)
    return gn, gn * (radius / length)


@named_settings
@dataclass(frozen=True)
class MNRES:
    """Newton–Raphson with sensitivities from a surface through past points.

    Attributes:
        form: ``"secant"`` (default: one finite-difference sweep, then Broyden rank-one
            updates; see the module docstring), ``"algebraic"`` (n_f + 1 points, [4.15]),
            ``"batch"`` (least-squares plane by QR) or ``"recursive"`` (least-squares plane,
            constant-window recursive update).
        window: points kept by the least-squares forms (≥ n_f + 1; default n_f + 1).
        initial_perturbation: first perturbation, relative to max(|θ_j|, floor_j); for the
            secant form the relative step of the first finite-difference sweep (later ones:
            1e-6). None: 1e-3.
        importance_scaling: scale restart perturbations by 1/√M_ℓℓ (RP-1153 §4.B; surface
            forms).
        max_rejections: disappointing passes in a row on sensitivities carried along the
            path before they are renewed (secant: a sweep; surface forms: a restart).
            None: one per 20 free parameters, at least 1 (secant: 1 up to 39 free
            parameters, 2 from 40), 2 (surface forms).
        fresh_rejections: rejected trials in a row on freshly swept / (re)initialised
            sensitivities before the convergence checks (secant) or a restart (surface).
        max_relative_step: no parameter moves more than this fraction of max(|θ_j|, scale_j)
            in one pass (off by default; see MNR).
        max_condition: largest acceptable condition number of the (scaled) point cloud
            (surface forms; the secant form has no point cloud and ignores it).
        max_restarts: consecutive restarts without progress before declaring a stall; each
            such restart perturbs 10 times less than the previous one (surface forms).
        replacement: which point leaves when a new one enters: ``"geometry"`` (the largest
            distance-weighted Lagrange value, default) or ``"cost"`` (the highest cost, the
            paper's rule); surface forms only.
        trust_region: keep the trust radius from pass to pass (default); ``False`` starts
            every pass from the full Gauss–Newton step and halves it on failure (the paper's
            step-size control).
    """

    form: str = "secant"
    window: int | None = None
    initial_perturbation: float | None = None
    importance_scaling: bool = True
    max_rejections: int | None = None
    fresh_rejections: int = 4
    max_relative_step: float = math.inf
    max_condition: float = 1e8
    max_restarts: int = 6
    replacement: str = "geometry"
    trust_region: bool = True

    name = "mnres"

    def __post_init__(self) -> None:
        check_setting_types(self)
        if self.form not in _FORMS:
            raise InputError(f"MNRES.form: expected one of {_FORMS}, got {self.form!r}")
        if self.replacement not in _REPLACEMENTS:
            raise InputError(
                f"MNRES.replacement: expected one of {_REPLACEMENTS}, got {self.replacement!r}"
            )
        if self.initial_perturbation is not None and not 0 < self.initial_perturbation < 1:
            raise InputError(
                "MNRES.initial_perturbation: expected a fraction between 0 and 1, "
                f"got {self.initial_perturbation!r}"
            )
        rejections = 0 if self.max_rejections is None else self.max_rejections
        if rejections < 0 or self.fresh_rejections < 0 or self.max_restarts < 0:
            raise InputError(
                "MNRES.max_rejections, MNRES.fresh_rejections and MNRES.max_restarts must be "
                f"≥ 0, got {self.max_rejections}, {self.fresh_rejections}, {self.max_restarts}"
            )
        if self.form == "algebraic" and self.window is not None:
            raise InputError("MNRES.window: only the 'batch' and 'recursive' forms take a window")
        if self.window is not None and self.window < 2:
            raise InputError(f"MNRES.window: expected ≥ 2 points (≥ n_f + 1), got {self.window}")
        if not self.max_relative_step > 0:
            raise InputError(
                f"MNRES.max_relative_step: expected > 0 (math.inf: off), got "
                f"{self.max_relative_step}"
            )
        if not self.max_condition > 1:
            raise InputError(f"MNRES.max_condition: expected > 1, got {self.max_condition}")

    def settings(self) -> dict:
        return {
            "form": self.form,
            "window": self.window,
            "initial_perturbation": self._perturbation(),
            "importance_scaling": self.importance_scaling,
            "max_rejections": self._max_rejections()
            if self.max_rejections is not None or self.form != "secant"
            else f"1 per {_PARAMETERS_PER_REJECTION} free parameters (at least 1)",
            "fresh_rejections": self.fresh_rejections,
            "max_relative_step": None
            if math.isinf(self.max_relative_step)
            else self.max_relative_step,
            "max_condition": self.max_condition,
            "max_restarts": self.max_restarts,
            "replacement": self.replacement,
            "trust_region": self.trust_region,
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
        size = self._perturbation()
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

    @staticmethod
    def _trust_region_step(gn: GaussNewtonStep, scale: np.ndarray, radius: float) -> np.ndarray:
        """Δθ of the Levenberg–Marquardt step no longer than ``radius`` in ϑ = θ / scale.

        With A·diag(scale) = Q R D diag(scale) = Q U Σ Vᵀ and c = UᵀQᵀb:
        Δϑ(μ) = V diag(s / (s² + μ)) c, whose length decreases with μ; μ is found by
        bisection on log μ so that ‖Δϑ(μ)‖ = Δ. The Gauss–Newton step is returned as it is
        when it lies inside the radius.
        """
        full = gn.step
        if not math.isfinite(radius) or gn._factors is None:
            return full
        if float(np.linalg.norm(full / scale)) <= radius:
            return full
        column_norms, moving, r, qtb = gn._factors
        m = scale[moving]
        u, s, vt = np.linalg.svd(r * (column_norms * m)[None, :])
        c = u.T @ qtb
        if not s.size or s[0] <= 0 or radius <= 0:
            return np.zeros_like(full)

        def length(mu: float) -> float:
            return float(np.linalg.norm(s * c / (s**2 + mu)))

        # ‖Δϑ(μ)‖ ≤ ‖s ⊙ c‖ / μ: the upper end of the bracket meets the radius
        low, high = 1e-16 * s[0] ** 2, max(float(np.linalg.norm(s * c)) / radius, 1e-300)
        if length(low) <= radius:
            high = low
        for _ in range(100):
            if high / low < 1.0 + 1e-6:
                break
            mid = math.sqrt(low * high)
            low, high = (mid, high) if length(mid) > radius else (low, mid)
        step = np.zeros_like(full)
        # Δϑ = V diag(s / (s² + μ)) UᵀQᵀb;  Δθ = scale ⊙ Δϑ
        step[moving] = m * (vt.T @ (s * c / (s**2 + high)))
        return step

    @staticmethod
    def _predicted_drop(objective: Objective, g: np.ndarray, outputs: np.ndarray, step) -> float:
        """pred = ‖b‖² − ‖b − AΔθ‖² = 2 bᵀAΔθ − ‖AΔθ‖²: the drop the surface promises."""
        weight = 1.0 / np.sqrt(objective.r_diag)
        b = objective.problem.residuals(outputs) * weight[None, :]
        change = (g @ step) * weight[None, :]
        return float(2.0 * np.sum(b * change) - np.sum(change**2))

    def _leaving(self, state: _PointSet, theta: np.ndarray, keep_best: bool) -> int:
        """Index of the point that leaves when θ enters (see the module docstring)."""
        if self.replacement == "cost":
            return int(np.argmax(state.costs))
        scaled = state.points / state.scale
        x = theta / state.scale
        best = int(np.argmin(state.costs))
        # ϑ⁰: the expansion point of the next pass (the new point if it was accepted)
        centre = scaled[best] if keep_best else x
        distance = np.linalg.norm(scaled - centre, axis=1)
        # Lagrange values ℓ(x): [1, ϑ_j − ϑ_b]ᵀ ℓ = [1, x − ϑ_b] (least squares beyond n_f + 1)
        design = np.column_stack([np.ones(scaled.shape[0]), scaled - scaled[best]])
        target = np.concatenate([[1.0], x - scaled[best]])
        lagrange = np.linalg.lstsq(design.T, target, rcond=None)[0]
        reach = max(float(np.linalg.norm(x - centre)), float(np.linalg.norm(x - scaled[best])))
        reach = max(reach, np.finfo(float).tiny)
        # |ℓ_t(x)| · max(1, ‖ϑ_t − ϑ⁰‖² / ‖x − ϑ⁰‖²)
        score = np.abs(lagrange) * np.maximum(1.0, (distance / reach) ** 2)
        if keep_best:
            score[best] = -np.inf
        return int(np.argmax(score))

    # ------------------------------------------------------------------ secant form
    def _sweep(
        self,
        objective: Objective,
        theta: np.ndarray,
        outputs: np.ndarray,
        cost: float,
        previous: _SecantState | None,
    ) -> _SecantState:
        """Forward-difference sensitivities at θ (n_f integrations in one batch); the trust
        radius is kept. Raises SimulationError if the perturbed simulations diverge."""
        problem = objective.problem
        # the first sweep differences widely (sees past local curvature far from the
        # optimum); later ones, near it, with MNR's step
        relative = self._sweep_step() if previous is None else _RESWEEP_STEP
        if previous is not None:
            # one G at a time: the carried sensitivities go before the sweep differences anew
            previous.columns = previous.normal_by_output = previous.differences = None
        differences = None
        if problem.finite_differences:
            differences = problem.differences(theta, outputs, relative)
            g = differences.g
        else:
            g, _ = problem.sensitivities(theta, outputs, relative)
        state = _SecantState.from_jacobian(theta, outputs, cost, problem.magnitude(theta), g)
        del g
        state.differences = differences
        if previous is not None:
            # the radius is kept (what the fresh model learnt about the nonlinearity), but
            # never below twice the last accepted step (carried-model failures shrink it)
            state.radius = max(previous.radius, 2.0 * previous.last_length)
            state.last_length = previous.last_length
            state.sweeps = previous.sweeps + 1
        return state

    def _sweep_step(self) -> float:
        return self._perturbation()

    def _max_rejections(self, n_free: int | None = None) -> int:
        """``max_rejections``, or its default: secant one per ``_PARAMETERS_PER_REJECTION``
        free parameters, at least 1 (1 without ``n_free``); surface forms 2."""
        if self.max_rejections is not None:
            return max(int(self.max_rejections), 1)
        if self.form != "secant":
            return 2
        return 1 if n_free is None else max(1, n_free // _PARAMETERS_PER_REJECTION)

    def _perturbation(self) -> float:
        """``initial_perturbation``, or its default (1e-3, both families)."""
        if self.initial_perturbation is not None:
            return self.initial_perturbation
        return _SECANT_STEP if self.form == "secant" else _SURFACE_PERTURBATION

    @staticmethod
    def _secant_update(state: _SecantState, step: np.ndarray, change: np.ndarray) -> None:
        """Broyden's rank-one update with the step Δθ and the output change Δy it caused,
        least change in the trust-region coordinates ϑ = θ / scale:

            u = Δy − GΔθ,  w = S⁻²Δθ / (ΔθᵀS⁻²Δθ)  (S = diag scale):   G ← G + u wᵀ
            (G_ϑ = G S ← G_ϑ + u Δϑᵀ/‖Δϑ‖²; now GΔθ = Δy exactly)
            G_kᵀG_k ← G_kᵀG_k + p_k wᵀ + w p_kᵀ + ‖u_k‖² w wᵀ,  p_k = G_kᵀu_k (old G)

        In place on ``state.columns``, in one compiled call (``_secant_pass``: u, p_k,
        ‖u_k‖², G and the blocks); O(N·n_o·n_f) and no temporary of G's size. G_kᵀG_k is
        recomputed exactly every n_f updates (amortised the same), so rounding does not
        accumulate. The sweep's record (``differences``) no longer describes G afterwards.
        """
        columns = state.columns
        n_free = columns.shape[0]
        n_outputs = state.outputs.shape[1]
        scaled = step / state.scale**2
        # w = S⁻²Δθ / (ΔθᵀS⁻²Δθ)
        w = scaled / float(step @ scaled)
        state.differences = None
        exact = state.updates + 1 >= n_free
        # u = Δy − GΔθ, p_k = G_kᵀu_k with the old G, G ← G + u wᵀ and the blocks, in place
        _secant_kernel()(
            columns,
            np.ascontiguousarray(change, dtype=float).reshape(-1),
            np.ascontiguousarray(step, dtype=float),
            w,
            state.normal_by_output,
            n_outputs,
            not exact,
        )
        if exact:
            state.normal_by_output = _exact_normal(columns, n_outputs)
            state.updates = 0
            return
        state.updates += 1

    def _secant_start(
        self, objective: Objective, theta0: np.ndarray, state: _SecantState | None
    ) -> _SecantState | SolverOutcome:
        """The model to start from: swept at θ⁰ (the start cost and the first sweep), or the
        previous noise cycle's under the new R; an outcome if the start cannot be swept."""
        if state is not None:
            # a new noise cycle: new weights, so the radius learnt under the old ones goes
            state.cost = float(objective.costs_of(state.outputs)[0])
            state.radius = math.inf
            state.poor = 0
            return state
        theta, cost, outputs = _start_point(objective, theta0)
        try:
            return self._sweep(objective, theta, outputs, cost, None)
        except SimulationError as exc:
            return SolverOutcome(
                theta,
                outputs,
                cost,
                0,
                False,
                "stalled",
                f"stalled: the perturbed simulations for the sensitivities diverge at the "
                f"start values ({exc})",
            )

    def _minimize_secant(
        self, objective: Objective, theta0: np.ndarray, state: _SecantState | None
    ) -> SolverOutcome:
        """The secant form from θ⁰, or from the previous noise cycle's ``state``."""
        # the secant form's allowance counts the start and its first sweep
        spent_before = objective.evaluations
        start = self._secant_start(objective, theta0, state)
        if isinstance(start, SolverOutcome):
            return start
        search = _SecantSearch(self, objective, spent_before, current=start)
        if start.columns is None:
            # the sensitivities were dropped (a sweep that failed): sweep again
            stop = search.sweep()
            if stop is not None:
                return stop
        return search.run()

    # ------------------------------------------------------------------ main loop
    def minimize(self, objective: Objective, theta0: np.ndarray, state=None) -> SolverOutcome:
        """Minimise the objective from θ⁰ (``state``: the previous noise cycle's model, kept
        under the new R)."""
        if self.form == "secant":
            return self._minimize_secant(objective, theta0, state)
        window = self._window(objective.problem.n_free)
        if state is None:
            theta, cost, outputs = _start_point(objective, theta0)
            magnitude = objective.problem.magnitude(theta)
            state = self._initialise(
                objective, theta, outputs, cost, self._perturbation() * magnitude, 0
            )
        else:
            # a new noise cycle: new weights, so the radius learnt under the old ones goes
            state.costs = objective.costs_of(state.outputs)
            state.radius = math.inf
            state.rejections = 0
        # the surface forms' allowance starts after the start and its perturbations
        search = _SurfaceSearch(self, objective, objective.evaluations, state=state, window=window)
        return search.run()

    def _restart(
        self,
        objective: Objective,
        previous: _PointSet,
        theta: np.ndarray,
        outputs: np.ndarray,
        cost: float,
        g: np.ndarray | None,
    ) -> _PointSet:
        """New perturbations about the best point (n_f integrations); the trust radius is
        kept."""
        deltas = self._restart_deltas(objective, theta, g, previous.last_step, previous.failures)
        state = self._initialise(objective, theta, outputs, cost, deltas, previous.restarts + 1)
        state.last_step = previous.last_step
        # the radius is kept, but never below twice the last accepted step
        last = 0.0 if previous.last_step is None else previous.last_step / previous.scale
        state.radius = max(previous.radius, 2.0 * float(np.linalg.norm(last)))
        state.rejections = 0
        # a perturbed point that lowers the cost is progress too (not a rounding-level drop)
        progress = float(np.min(state.costs)) < cost - 1e-9 * abs(cost)
        state.failures = 0 if progress else previous.failures + 1
        return state

    def _insert(
        self,
        state: _PointSet,
        theta: np.ndarray,
        outputs: np.ndarray,
        cost: float,
        window: int,
        keep_best: bool,
    ) -> None:
        """The new point enters; once the window is full another leaves (``_leaving``):
        never the best point while θ is not better (``keep_best``)."""
        scale = state.scale
        if state.points.shape[0] < window:
            if state.surface is not None:
                state.surface.add(theta / scale, outputs.reshape(-1))
            state.points = np.vstack([state.points, theta[None]])
            state.outputs = np.concatenate([state.outputs, outputs[None]])
            state.costs = np.append(state.costs, cost)
            return
        leaving = self._leaving(state, theta, keep_best)
        if state.surface is not None:
            state.surface.replace(
                theta / scale,
                outputs.reshape(-1),
                state.points[leaving] / scale,
                state.outputs[leaving].reshape(-1),
            )
        state.points[leaving] = theta
        state.outputs[leaving] = outputs
        state.costs[leaving] = cost


# ---------------------------------------------------------------------------- the searches
_STEP_SETTLED = "converged: the next step and the cost drop it predicts are below tolerance"
_CHANGES_SETTLED = "converged: cost and parameter changes below tolerance"
_STEP_BELOW_TOLERANCE = (
    "converged: the step is below the parameter tolerance and no shorter step lowers the cost"
)


def _start_point(objective: Objective, theta0: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """θ⁰ as floats, its cost and outputs (one integration), logged as the first pass."""
    theta = np.array(theta0, dtype=float)
    cost, outputs = objective.evaluate_start(theta)
    objective.record(theta, cost)
    return theta, cost, outputs


@dataclass
class _Trial:
    """One trial point θ + Δθ and what it did to the cost.

    ``step``: Δθ actually taken (after the step limit and the projection onto the bounds);
    ``length``: ‖Δϑ‖ in the trust-region coordinates; ``ratio``: ρ = realised / predicted
    drop (0 for a rejected trial or a non-positive prediction); ``was_fresh``: the
    sensitivities were fresh (swept, or a (re)initialised surface) when it was taken.
    """

    point: np.ndarray
    step: np.ndarray
    length: float
    cost: float
    outputs: np.ndarray | None
    accepted: bool
    was_fresh: bool
    ratio: float

    @classmethod
    def judged(
        cls,
        point: np.ndarray,
        step: np.ndarray,
        length: float,
        evaluated: tuple[float, np.ndarray | None],
        cost_before: float,
        predicted: float,
        was_fresh: bool,
    ) -> _Trial:
        """The trial with its acceptance (the cost dropped) and ρ."""
        new_cost, new_outputs = evaluated
        accepted = new_cost < cost_before
        # ρ = realised / predicted drop
        ratio = (cost_before - new_cost) / predicted if accepted and predicted > 0 else 0.0
        return cls(point, step, length, new_cost, new_outputs, accepted, was_fresh, ratio)

    @property
    def poor(self) -> bool:
        """The step disappointed: rejected, or ρ < 0.25."""
        return self.ratio < _SHRINK


def _trial_cost(objective: Objective, point: np.ndarray) -> tuple[float, np.ndarray]:
    """Cost and outputs at one trial point (one integration; a diverged one costs inf)."""
    trial_costs, trial_outputs = objective.evaluate(point[None, :])
    return float(trial_costs[0]), trial_outputs[0]


def _next_radius(
    radius: float, trial: _Trial, trust_region: bool, full_step_trial: bool = False
) -> float:
    """The trust radius Δ after a trial (step control, module docstring).

    Rejected or ρ < 0.25 on fresh sensitivities: Δ ← ½‖Δϑ‖ (a full Gauss–Newton step beyond
    the kept radius falls back to that radius, or half the step if shorter); ρ > 0.75 at
    the radius: Δ ← 2Δ. A carried model that lowered the cost but disappointed keeps Δ (the
    model is suspect, not the radius). Without ``trust_region``: every pass starts from the
    full step, and a rejected one halves it (the paper's step-size control).
    """
    if not trust_region:
        return math.inf if trial.accepted else 0.5 * trial.length
    if trial.poor and (trial.was_fresh or not trial.accepted):
        if full_step_trial and trial.length > radius:
            return min(radius, 0.5 * trial.length)
        return 0.5 * trial.length
    if trial.ratio > _GROW and trial.length >= 0.99 * radius:
        return 2.0 * radius
    return radius


def _record_accepted(
    objective: Objective, cost_before: float, trial: _Trial, recost: Callable[[], None]
) -> bool:
    """Log an accepted pass (MAXLIK may re-estimate R here; ``recost()`` then recomputes the
    stored costs under the new R). Returns whether cost and parameters (and R) settled."""
    conv = objective.convergence
    relative = conv.relative_cost_change(cost_before, trial.cost)
    settled = conv.cost_settled(cost_before, trial.cost) and conv.params_settled(
        trial.step, trial.point, objective.typical
    )
    objective.record(trial.point, trial.cost)
    noise_settled = objective.maxlik_update(trial.outputs, relative)
    if noise_settled is not None:
        recost()
        settled = settled and noise_settled
    return settled


def _fresh_model_settled(
    objective: Objective,
    gn_step: np.ndarray,
    theta: np.ndarray,
    gn_drop: float,
    cost: float,
    predictor: str,
) -> tuple[bool, str, str] | None:
    """(converged, status, message) when fresh sensitivities whose trials all failed say the
    search is over: the Gauss–Newton step Δθ below the parameter tolerance, or its
    predicted drop below the cost tolerance; None otherwise. ``predictor`` names the
    model in the message (with its verb)."""
    conv = objective.convergence
    if conv.params_settled(gn_step, theta, objective.typical):
        return True, "converged", _STEP_BELOW_TOLERANCE
    if gn_drop <= conv.cost_rtol * abs(cost) + conv.cost_atol:
        return (
            True,
            "converged",
            f"converged: the cost drop {predictor} is below the cost tolerance and no step "
            "within the trust region lowers the cost",
        )
    return None


@dataclass
class _Search:
    """One call of an MNRES form: the solver, the objective, the passes so far and the
    iteration allowance.

    A pass of MNRES costs one integration where one of MNR costs n_f + 1: the iteration limit
    is applied in MNR's currency, max_iterations·(n_f + 1) integrations per call, counted
    from ``spent_before`` (the objective's evaluations when the count began).
    """

    solver: MNRES
    objective: Objective
    spent_before: int
    passes: int = 0  # accepted parameter updates

    @property
    def allowance(self) -> int:
        conv = self.objective.convergence
        return conv.max_iterations * (self.objective.problem.n_free + 1)

    def finish(self, iterations: int, converged: bool, status: str, message: str):
        """The outcome at the search's best point."""
        raise NotImplementedError

    def iteration(self) -> SolverOutcome | None:
        """One pass; an outcome when the search ends there."""
        raise NotImplementedError

    def out_of_budget(self) -> SolverOutcome | None:
        """The outcome if the evaluation budget is spent, else None."""
        if self.objective.budget_exhausted():
            return self.finish(self.passes, False, *budget_status(self.objective))
        return None

    def run(self) -> SolverOutcome:
        """Passes until one ends the search or the allowance is spent."""
        while self.objective.evaluations - self.spent_before < self.allowance:
            stop = self.out_of_budget()
            if stop is None:
                stop = self.iteration()
            if stop is not None:
                return stop
        return self.finish(
            self.passes,
            False,
            "max_iterations",
            f"stopped after {self.passes} iterations ({self.allowance} integrations, the cost "
            f"of {self.objective.convergence.max_iterations} finite-difference passes) without "
            "converging",
        )


# ------------------------------------------------------------------------ secant search
@dataclass
class _SecantModel:
    """One pass's linear model in ϑ = θ / scale at the current point: M, c, the Gauss–Newton
    step and the trial step (module docstring, step 2), with θ, J(θ), y(θ) and the scale as
    they were when the pass began."""

    theta: np.ndarray
    cost: float
    outputs: np.ndarray
    scale: np.ndarray
    normal: np.ndarray
    gradient: np.ndarray
    gn: np.ndarray
    step: np.ndarray
    full_step_trial: bool
    on_bound: bool  # a parameter lies on a bound
    gn_drop: float = field(init=False)  # the Gauss–Newton step's predicted drop

    def __post_init__(self) -> None:
        self.gn_drop = self.predicted_drop(self.gn)

    def predicted_drop(self, step: np.ndarray) -> float:
        """Predicted drop of Δϑ: ‖b‖² − ‖b − AΔϑ‖² = 2cᵀΔϑ − ΔϑᵀMΔϑ."""
        return float(2.0 * self.gradient @ step - step @ self.normal @ step)


def _bounded_secant_step(
    normal: np.ndarray,
    gradient: np.ndarray,
    on_lower: np.ndarray,
    on_upper: np.ndarray,
    radius: float,
    damped: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """(Gauss–Newton step, trial step) in ϑ with the active set: a parameter on a bound whose
    Gauss–Newton step points outwards is held, and the step taken again without it."""
    held = np.zeros(gradient.size, dtype=bool)
    for _ in range(gradient.size + 1):
        gn, step = _secant_step(normal, gradient, held, radius, damped)
        outward = (on_lower & (gn < 0)) | (on_upper & (gn > 0))
        if not np.any(outward & ~held):
            break
        held |= outward
    return gn, step


@dataclass
class _SecantSearch(_Search):
    """The secant form's iteration (module docstring): the model ``current`` and the rejected
    trials in a row on freshly swept sensitivities."""

    current: _SecantState | None = None
    fresh_failures: int = 0  # rejected trials in a row on freshly swept sensitivities
    tried_radius: float = math.inf  # the last positive trust radius a pass tried (ϑ units)

    def finish(self, iterations: int, converged: bool, status: str, message: str):
        current = self.current
        # the sweep's forward differences at the end point, if G is still exactly them:
        # the confirmation completes them to central ones with n_f more integrations
        record = current.differences
        if record is not None and not np.array_equal(record.theta, current.theta):
            record = None
        return SolverOutcome(
            current.theta,
            current.outputs,
            current.cost,
            iterations,
            converged,
            status,
            message,
            state=current,
            differences=record,
        )

    def sweep(self) -> SolverOutcome | None:
        """Renew the sensitivities at the current point, or the reason to stop."""
        stop = self.out_of_budget()
        if stop is not None:
            return stop
        current = self.current
        try:
            self.current = self.solver._sweep(
                self.objective, current.theta, current.outputs, current.cost, current
            )
        except SimulationError as exc:
            return self.finish(
                self.passes,
                False,
                "stalled",
                f"stalled: the perturbed simulations for the sensitivities diverge here ({exc})",
            )
        self.fresh_failures = 0
        return None

    def converge_or_sweep(self, trusted: bool, iterations: int, message: str):
        """Settled: converged on sensitivities that may say so (``trusted``: swept, or proven
        by their last step); on carried ones, judged again on swept ones (None: go on)."""
        if trusted:
            return self.finish(iterations, True, "converged", message)
        return self.sweep()

    def iteration(self) -> SolverOutcome | None:
        try:
            model = self.linearise()
        except _TrustRadiusCollapsed:
            return self.radius_collapsed()
        current = self.current
        gn_step = GaussNewtonStep(model.gn * model.scale, -1, math.nan, model.gn_drop)
        conv = self.objective.convergence
        if conv.step_settled(gn_step, model.theta, self.objective.typical, model.cost):
            trusted = current.fresh or current.proven
            return self.converge_or_sweep(trusted, self.passes + 1, _STEP_SETTLED)
        trial = self.try_step(model)
        current.radius = _next_radius(
            current.radius, trial, self.solver.trust_region, model.full_step_trial
        )
        current.poor = current.poor + 1 if trial.poor else 0
        # The secant through the trial point: always after an accepted step (the slopes
        # move with θ); after a rejected one only into carried sensitivities — a swept
        # Jacobian at θ is the better local model than a secant over a step too long.
        if trial.outputs is not None and math.isfinite(trial.cost):
            if trial.accepted or not trial.was_fresh:
                self.solver._secant_update(current, trial.step, trial.outputs - model.outputs)
        if trial.accepted:
            stop = self.accept(model, trial)
        elif trial.was_fresh:
            return self.reject_fresh(model)
        else:
            stop = self.end_of_noise_cycle(model, trial)
        if stop is not None:
            return stop
        # carried sensitivities that mislead max_rejections passes in a row are renewed
        n_free = self.objective.problem.n_free
        if not self.current.fresh and self.current.poor >= self.solver._max_rejections(n_free):
            return self.sweep()
        return None

    def linearise(self) -> _SecantModel:
        """M, c and the steps at the current point (module docstring, step 2)."""
        current, problem = self.current, self.objective.problem
        theta, scale = current.theta, current.scale
        weights = 1.0 / self.objective.r_diag
        # M = S (Σ_k G_kᵀG_k / R_kk) S,  c = S Σ_i G_iᵀR⁻¹ν_i  (ϑ units, S = diag scale)
        # (einsum's own loop, not BLAS: a threaded BLAS took 2 ms for this n_o × n_f²
        # product on a loaded 2-core machine, y13aus 0.36 s of 2.3 s)
        normal = np.einsum("k,kab->ab", weights, current.normal_by_output)
        normal *= np.outer(scale, scale)
        nu = problem.residuals(current.outputs)
        gradient = scale * (current.columns @ (nu * weights[None, :]).reshape(-1))
        # active set: a parameter on a bound whose Gauss–Newton step points outwards
        on_lower = theta <= problem.lower
        on_upper = theta >= problem.upper
        # the first trial on the sensitivities of a later sweep is the full Gauss–Newton
        # step (the paper's rule; the kept radius is what the carried passes learnt, and a
        # fresh model near the optimum often reaches it in one step)
        full_step_trial = current.fresh and self.fresh_failures == 0 and current.sweeps > 0
        radius = math.inf if full_step_trial else current.radius
        if radius > 0.0:
            self.tried_radius = radius
        # after a rejected trial on swept sensitivities: the damped step if the radius has
        # become a small part of the Gauss–Newton step (_secant_step)
        damped = current.fresh and self.fresh_failures > 0
        gn, step = _bounded_secant_step(normal, gradient, on_lower, on_upper, radius, damped)
        return _SecantModel(
            theta,
            current.cost,
            current.outputs,
            scale,
            normal,
            gradient,
            gn,
            step,
            full_step_trial,
            bool(np.any(on_lower) or np.any(on_upper)),
        )

    def try_step(self, model: _SecantModel) -> _Trial:
        """One integration at θ + Δθ (the step limited and projected onto the bounds)."""
        problem = self.objective.problem
        theta, scale = model.theta, model.scale
        step_theta = limit_step(
            model.step * scale, theta, self.objective.typical, self.solver.max_relative_step
        )
        point = problem.project(theta + step_theta)
        taken = (point - theta) / scale
        length = float(np.linalg.norm(taken))
        evaluated = _trial_cost(self.objective, point) if length > 0.0 else (math.inf, None)
        return _Trial.judged(
            point,
            point - theta,
            length,
            evaluated,
            model.cost,
            model.predicted_drop(taken),
            self.current.fresh,
        )

    def accept(self, model: _SecantModel, trial: _Trial) -> SolverOutcome | None:
        """θ ← θ + Δθ; converged when cost and parameters settled on a full step."""
        current = self.current
        self.passes += 1
        current.theta, current.outputs, current.cost = trial.point, trial.outputs, trial.cost
        current.last_length = trial.length
        current.fresh = False
        current.proven = abs(trial.ratio - 1.0) <= 0.1
        self.fresh_failures = 0

        def recost():
            current.cost = float(self.objective.costs_of(trial.outputs)[0])

        settled = _record_accepted(self.objective, model.cost, trial, recost)
        if not (settled and bool(np.array_equal(model.step, model.gn))):
            return None
        trusted = trial.was_fresh or current.proven
        return self.converge_or_sweep(trusted, self.passes, _CHANGES_SETTLED)

    def radius_collapsed(self) -> SolverOutcome:
        """The end of a search whose trust radius fell to 0: the shortest trials no longer
        moved θ in floating point, and none of the longer ones lowered the cost."""
        return self.finish(
            self.passes,
            False,
            "stalled",
            f"stalled: the trust radius collapsed — no step lowered the cost down to a radius "
            f"of {self.tried_radius:.2g} in ϑ = θ / scale (scale = max(|θ|, floor) per "
            "parameter); shorter steps no longer change θ in floating point",
        )

    def reject_fresh(self, model: _SecantModel) -> SolverOutcome | None:
        """A rejected trial on freshly swept sensitivities: after ``fresh_rejections`` in a
        row the convergence checks, after 30 a stall."""
        self.fresh_failures += 1
        if self.fresh_failures >= self.solver.fresh_rejections:
            end = _fresh_model_settled(
                self.objective,
                model.gn * model.scale,
                model.theta,
                model.gn_drop,
                model.cost,
                "freshly swept sensitivities predict",
            )
            if end is not None:
                return self.finish(self.passes, *end)
        if self.fresh_failures >= _SECANT_STALL:
            return self.finish(
                self.passes,
                False,
                "stalled",
                f"stalled: {self.fresh_failures} trials in a row, each half as long, on "
                "freshly swept sensitivities did not lower the cost",
            )
        return None

    def end_of_noise_cycle(self, model: _SecantModel, trial: _Trial) -> SolverOutcome | None:
        """A rejected trial on carried sensitivities that may end a MAX noise cycle.

        Under the MAX noise policy a cycle only has to settle θ for the next estimate of R,
        and the last cycle's end is confirmed by central differences in any case
        (flightid.estimation.confirm): carried sensitivities proven by their last step
        (|ρ − 1| ≤ 0.1) whose next trial moved the cost by less than the cost tolerance end
        the cycle without a sweep (measured: module docstring, "Noise cycles"). Not with a
        parameter on a bound: there the rule ended the bounded short-period test of
        tests/test_honest_convergence.py 0.10 σ from the constrained optimum.
        """
        if (
            self.objective.policy == "max"
            and self.current.proven
            and self.objective.convergence.cost_settled(model.cost, trial.cost)
            and not model.on_bound
        ):
            return self.finish(
                self.passes,
                True,
                "converged",
                "converged: a step on sensitivities proven by the previous step changed "
                "the cost by less than the cost tolerance (end of a noise cycle; the "
                "central-difference confirmation judges the end point)",
            )
        return None


# ----------------------------------------------------------------------- surface search
@dataclass
class _SurfaceSearch(_Search):
    """The surface forms' iteration (module docstring): the point set ``state``, the window
    and the last pass's sensitivities ``g`` (N, n_o, n_f) for restart perturbations."""

    state: _PointSet | None = None
    window: int = 0
    g: np.ndarray | None = None

    def finish(self, iterations: int, converged: bool, status: str, message: str):
        state = self.state
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

    def restart(self, theta, outputs, cost) -> SolverOutcome | None:
        """A restart about θ (None: go on), or the reason the search ends here."""
        stop = self.out_of_budget()
        if stop is not None:
            return stop
        if self.state.failures >= self.solver.max_restarts:
            return self.finish(
                self.passes,
                False,
                "stalled",
                f"stalled: {self.solver.max_restarts} restarts in a row found no lower cost",
            )
        try:
            self.state = self.solver._restart(
                self.objective, self.state, theta, outputs, cost, self.g
            )
        except EstimationError as exc:
            return self.finish(self.passes, False, "stalled", f"stalled: {exc}")
        return None

    def iteration(self) -> SolverOutcome | None:
        state, problem = self.state, self.objective.problem
        base = int(np.argmin(state.costs))
        theta, cost, outputs = state.points[base], state.costs[base], state.outputs[base]
        try:
            slopes = self.solver._slopes(self.objective, state, base)
        except EstimationError:
            slopes = None  # the point cloud has collapsed: restart
        if slopes is None:
            return self.restart(theta, outputs, cost)
        # ∂y/∂θ = ∂y/∂ϑ / scale, reshaped to (N, n_o, n_f)
        self.g = (slopes / state.scale[:, None]).T.reshape(
            problem.n_samples, problem.n_outputs, problem.n_free
        )
        gn = bounded_gauss_newton_step(self.objective, self.g, outputs, theta)
        if self.objective.convergence.step_settled(gn, theta, self.objective.typical, cost):
            # Only a surface fresh from perturbations about this point may say so; a
            # surface carried along the path is judged again on a fresh one.
            if state.fresh or state.proven:
                return self.finish(self.passes + 1, True, "converged", _STEP_SETTLED)
            return self.restart(theta, outputs, cost)
        trial = self.try_step(gn, theta, cost, outputs)
        # Trust radius: a fresh surface that disappoints means the step was too long;
        # a surface carried along the path that disappoints is itself suspect, and is
        # renewed (restart) after max_rejections such passes, the radius kept.
        state.radius = _next_radius(state.radius, trial, self.solver.trust_region)
        state.rejections = state.rejections + 1 if trial.poor else 0
        if trial.accepted:
            stop = self.accept(gn, cost, trial)
            if stop is not None:
                return stop
        limit = self.solver.fresh_rejections if trial.was_fresh else self.solver._max_rejections()
        if state.rejections <= limit:
            return None
        # A surface built from past passes may be stale: only a surface fresh from a
        # (re)initialisation at this point can declare convergence on a failed step.
        if trial.was_fresh and not trial.accepted:
            end = _fresh_model_settled(
                self.objective,
                gn.step,
                theta,
                gn.predicted_reduction,
                cost,
                "a fresh surface predicts",
            )
            if end is not None:
                return self.finish(self.passes, *end)
        base = int(np.argmin(state.costs))
        return self.restart(state.points[base], state.outputs[base], state.costs[base])

    def try_step(self, gn: GaussNewtonStep, theta, cost, outputs) -> _Trial:
        """One integration at θ + Δθ: the trust-region step, limited and projected."""
        state, solver = self.state, self.solver
        step = solver._trust_region_step(gn, state.scale, state.radius)
        step = limit_step(step, theta, self.objective.typical, solver.max_relative_step)
        point = self.objective.problem.project(theta + step)
        taken = point - theta
        length = float(np.linalg.norm(taken / state.scale))
        evaluated = (math.inf, None) if length == 0.0 else _trial_cost(self.objective, point)
        predicted = solver._predicted_drop(self.objective, self.g, outputs, taken)
        return _Trial.judged(point, taken, length, evaluated, cost, predicted, state.fresh)

    def accept(self, gn: GaussNewtonStep, cost: float, trial: _Trial) -> SolverOutcome | None:
        """The new point enters the surface; converged when cost and parameters settled on
        a full step from a fresh or proven surface."""
        state = self.state
        self.solver._insert(state, trial.point, trial.outputs, trial.cost, self.window, False)
        self.passes += 1
        state.last_step = trial.step
        state.fresh = False
        state.proven = abs(trial.ratio - 1.0) <= 0.1
        state.failures = 0

        def recost():
            state.costs = self.objective.costs_of(state.outputs)

        settled = _record_accepted(self.objective, cost, trial, recost)
        full_step = bool(np.array_equal(trial.step, gn.step))
        if settled and full_step and (trial.was_fresh or state.proven):
            return self.finish(self.passes, True, "converged", _CHANGES_SETTLED)
        return None
