"""The Gauss–Newton (modified Newton–Raphson) step of output-error ML [RP-1153 4.4–4.8].

    M  = Σ_i G_iᵀ R⁻¹ G_i          (information matrix)
    g  = −Σ_i G_iᵀ R⁻¹ ν_i
    Δθ = −M⁻¹ g

Computed without forming M⁻¹: with the weighted, stacked sensitivities A = R^(−½) G (rows i,k)
and weighted residuals b = R^(−½) ν, Δθ is the least-squares solution of A Δθ ≈ b, obtained
from a QR factorisation of [A | b] and an SVD of its small triangular factor. The QR runs over
blocks of samples (``triangular_factor``): neither A nor any other copy of the (N·n_o × n_f)
sensitivities is formed, and one factor serves every step taken from the same G and ν.

Scale-free by construction: the columns of A are scaled to unit norm before the
factorisation (equivalently, M is scaled to unit diagonal, D⁻¹MD⁻¹ with D = diag(√M_jj)), so
neither the parameters' units nor their start values decide which directions count as
determined. Directions whose singular value is below ``rcond`` times the largest get no step
and are reported; a parameter whose column is zero (it does not move any output) is
undetermined whatever the others do.

The predicted cost drop of the step, ‖AΔθ‖² = ΔθᵀMΔθ, is also the squared length of the step
in Cramér–Rao standard deviations (the Mahalanobis norm under M⁻¹): every component obeys
|Δθ_j| ≤ σ_j·√(ΔθᵀMΔθ). ``flightid.estimation.driver`` uses that to confirm convergence.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.linalg.lapack

__all__ = [
    "GaussNewtonStep",
    "gauss_newton_step",
    "information_matrix",
    "step_from_factor",
    "triangular_factor",
    "undetermined_parameters",
]


@dataclass(frozen=True)
class GaussNewtonStep:
    """A Gauss–Newton step and the facts about it."""

    step: np.ndarray  # Δθ (n_f,), parameter units; 0 for held (active-bound) parameters
    rank: int  # numerical rank of the column-scaled weighted sensitivities
    condition: float  # condition number of the column-scaled weighted sensitivities
    predicted_reduction: float  # J(θ) − J_lin(θ + Δθ) = ΔθᵀMΔθ, the cost drop predicted
    undetermined: tuple[int, ...] = ()  # parameters with weight in the discarded directions
    # the factorisation, kept for damped steps: column norms D, moving mask, R, Qᵀb
    _factors: tuple | None = None

    def damped(self, mu_relative: float, magnitude: np.ndarray) -> np.ndarray:
        """Levenberg–Marquardt step in coordinates relative to the parameters' magnitudes.

        Δθ(μ) = argmin ‖b − AΔθ‖² + μ‖Δθ/m‖², m = max(|θ_j|, floor_j): with A·diag(m) =
        Q R D diag(m) = Q U₂ Σ₂ V₂ᵀ, Δθ = m ⊙ V₂ diag(s/(s² + μ)) U₂ᵀ Qᵀb, μ = μ_rel·s₀².
        μ → 0 gives the Gauss–Newton step; a large μ gives a short step along the steepest
        descent in relative coordinates, which lowers the cost for μ large enough even where
        a barely determined direction makes the Gauss–Newton step huge.
        """
        step = np.zeros_like(self.step)
        if self._factors is None:
            return step
        scale, moving, r, qtb = self._factors
        m = np.asarray(magnitude, dtype=float)[moving]
        u, s, vt = np.linalg.svd(r * (scale * m)[None, :])
        if not s.size or s[0] <= 0:
            return step
        mu = mu_relative * s[0] ** 2
        # Δϑ = V₂ diag(s / (s² + μ)) U₂ᵀ Qᵀ b;  Δθ = m ⊙ Δϑ
        step[moving] = m * (vt.T @ (s / (s**2 + mu) * (u.T @ qtb)))
        return step

    @property
    def sigma_distance(self) -> float:
        """√(ΔθᵀMΔθ): length of the step in Cramér–Rao standard deviations."""
        return float(np.sqrt(max(self.predicted_reduction, 0.0)))


# Rows of R^(−½)[G | ν] factorised per block (128 samples of 8 outputs ≈ 1000 rows): the
# blocks stay in cache and no weighted copy of the whole (N·n_o × n_f) matrix is ever formed.
_BLOCK_ROWS = 1024


def _sample_blocks(n_samples: int, n_outputs: int):
    """(start, stop) sample ranges of about ``_BLOCK_ROWS`` rows each."""
    per_block = max(1, _BLOCK_ROWS // max(n_outputs, 1))
    for start in range(0, n_samples, per_block):
        yield start, min(start + per_block, n_samples)


@functools.cache
def _blas_controller():
    """threadpoolctl's controller of the BLAS libraries loaded in this process (numpy's and
    scipy's OpenBLAS, MKL, ...), made once: it inspects the loaded libraries."""
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


def one_blas_thread():
    """A context in which the BLAS/LAPACK libraries run on one thread (their counts restored
    after; threadpoolctl).

    The QR blocks of ``triangular_factor`` are ~1000 × (n_f + 1) whatever N is: too small
    for threads to pay, and on a loaded 2-core machine a threaded dgeqrf waited for a busy
    core (0.38 s per factor on y13aus_lateral_output_error, 2 ms single-threaded)."""
    return _blas_controller().limit(limits=1, user_api="blas")


def triangular_factor(g: np.ndarray, nu: np.ndarray, r_diag: np.ndarray) -> np.ndarray:
    """The triangular factor T of the weighted least-squares problem, block by block.

    With A = R^(−½)G (rows i,k) and b = R^(−½)ν, [A | b] = Q T with T upper triangular,
    (n_f + 1) × (n_f + 1):

        T = [[R₀, Qᵀb], [0, ρ]],   AᵀA = R₀ᵀR₀ = M,   ‖b − AΔθ‖² = ‖Qᵀb − R₀Δθ‖² + ρ²

    so every Gauss–Newton quantity follows from T alone. Computed as a tall-skinny QR over
    blocks of samples: T ← triangle of QR([T; block]) — the same T (rows' signs aside) as one
    Householder QR of the whole matrix, whose column-wise backward stability also makes it
    independent of the columns' scales (``gauss_newton_step`` scales afterwards).

    Args:
        g: sensitivities (N, n_o, n_f); any strides.
        nu: residuals (N, n_o).
        r_diag: noise variances (n_o,).
    """
    n_samples, n_outputs, n_free = g.shape
    width = n_free + 1
    weight = 1.0 / np.sqrt(np.asarray(r_diag, dtype=float))
    factor = np.zeros((width, width))
    with one_blas_thread():
        for start, stop in _sample_blocks(n_samples, n_outputs):
            rows = (stop - start) * n_outputs
            stacked = np.empty((width + rows, width), order="F")
            stacked[:width] = factor
            # rows of R^(−½)G and R^(−½)ν for samples start … stop − 1
            stacked[width:, :n_free] = (g[start:stop] * weight[None, :, None]).reshape(rows, n_free)
            stacked[width:, n_free] = (nu[start:stop] * weight[None, :]).reshape(rows)
            qr, _, _, info = scipy.linalg.lapack.dgeqrf(stacked, overwrite_a=True)
            if info != 0:  # pragma: no cover - LAPACK argument errors only
                raise RuntimeError(f"LAPACK dgeqrf failed (info = {info})")
            factor = np.triu(qr[:width])
    return factor


def gauss_newton_step(
    g: np.ndarray,
    nu: np.ndarray,
    r_diag: np.ndarray,
    held: np.ndarray | None = None,
    rcond: float = 1e-10,
) -> GaussNewtonStep:
    """Δθ minimising Σ_i (ν_i − G_i Δθ)ᵀ R⁻¹ (ν_i − G_i Δθ).

    Args:
        g: sensitivities (N, n_o, n_f).
        nu: residuals z − y (N, n_o).
        r_diag: noise variances (n_o,).
        held: optional (n_f,) mask of parameters held where they are (Δθ_j = 0), e.g. those
            on an active bound.
        rcond: relative singular-value cut-off on the column-scaled matrix.
    """
    return step_from_factor(triangular_factor(g, nu, r_diag), held, rcond)


def step_from_factor(
    factor: np.ndarray, held: np.ndarray | None = None, rcond: float = 1e-10
) -> GaussNewtonStep:
    """The Gauss–Newton step from ``triangular_factor``'s T (see ``gauss_newton_step``).

    With parameters held, the columns of the others (and Qᵀb, ρ) are refactorised:
    QR([A_moving | b]) = QR(T[:, moving ∪ {b}]), an (n_f + 1)-row problem.
    """
    n_f = factor.shape[0] - 1
    moving = np.ones(n_f, dtype=bool) if held is None else ~np.asarray(held, dtype=bool)
    step = np.zeros(n_f)
    if not moving.any():
        return GaussNewtonStep(step, 0, float("inf"), 0.0, ())
    if moving.all():
        r_moving, qtb = factor[:n_f, :n_f], factor[:n_f, n_f]
    else:
        columns = np.append(np.flatnonzero(moving), n_f)
        reduced = scipy.linalg.qr(factor[:, columns], mode="r", check_finite=False)[0]
        n_moving = int(moving.sum())
        r_moving, qtb = reduced[:n_moving, :n_moving], reduced[:n_moving, n_moving]
    # D = diag(‖A_j‖) = diag(‖R_j‖): unit-norm columns make the rank test independent of
    # units and scales; the scaled problem's triangle is R D⁻¹ (A D⁻¹ = Q R D⁻¹)
    norms = np.linalg.norm(r_moving, axis=0)
    zero_column = norms == 0.0
    scale = np.where(zero_column, 1.0, norms)
    r = r_moving / scale[None, :]
    # R = U Σ Vᵀ: the SVD of the small n_f × n_f factor gives the singular values and
    # directions of the tall A D⁻¹
    u, s, vt = np.linalg.svd(r)
    projected = u.T @ qtb  # Uᵀ Qᵀ b
    keep = s > rcond * s[0] if s.size and s[0] > 0 else np.zeros_like(s, dtype=bool)
    # Δθ_scaled = V Σ⁺ Uᵀ Qᵀ b
    coefficients = np.where(keep, projected / np.where(keep, s, 1.0), 0.0)
    step_scaled = vt.T @ coefficients
    condition = float(s[0] / s[-1]) if s.size and s[-1] > 0 else float("inf")
    # predicted drop ‖b‖² − ‖b − AΔθ‖² = ‖UᵀQᵀb‖² over the kept directions
    predicted = float(np.sum(np.where(keep, projected, 0.0) ** 2))
    step[moving] = step_scaled / scale
    undetermined: list[int] = []
    if not keep.all() or zero_column.any():
        weight = np.sum(vt[~keep, :] ** 2, axis=0) if (~keep).any() else np.zeros(moving.sum())
        bad = (weight > 1e-6) | zero_column
        undetermined = [int(j) for j in np.flatnonzero(moving)[bad]]
    return GaussNewtonStep(
        step,
        int(keep.sum()),
        condition,
        predicted,
        tuple(undetermined),
        (scale, moving, r, qtb),
    )


def information_matrix(g: np.ndarray, r_diag: np.ndarray) -> np.ndarray:
    """M = Σ_i G_iᵀ R⁻¹ G_i (n_f × n_f) [4.6], summed over blocks of samples (no weighted
    copy of G). On one BLAS thread, as ``triangular_factor``: the blocks' products are small,
    and a threaded product waited for a busy core on a loaded machine (220 ms instead of
    0.3 ms for a 1001 × 8 × 22 G on 2 shared cores)."""
    n_samples, n_outputs, n_free = g.shape
    weight = 1.0 / np.sqrt(np.asarray(r_diag, dtype=float))
    m = np.zeros((n_free, n_free))
    with one_blas_thread():
        for start, stop in _sample_blocks(n_samples, n_outputs):
            # A_block = R^(−½) G_i for the block's samples, rows (i, k)
            a = (g[start:stop] * weight[None, :, None]).reshape(-1, n_free)
            m += a.T @ a
    return m


def undetermined_parameters(m: np.ndarray, ratio: float = 1e-12) -> tuple[np.ndarray, list[int]]:
    """Which parameters M cannot determine, judged on M scaled to unit diagonal.

    With D = diag(√M_jj), C = D⁻¹MD⁻¹ has unit diagonal whatever the parameters' units; its
    eigenvalues below ``ratio`` × the largest mark directions the data do not determine, and
    every parameter with weight (> 1e-6) in such a direction is undetermined, as is any
    parameter with M_jj = 0.

    Returns:
        (keep mask over C's eigenvalues, undetermined parameter indices).
    """
    diagonal = np.diag(m).copy()
    zero = ~(diagonal > 0)
    d = np.sqrt(np.where(zero, 1.0, diagonal))
    c = m / np.outer(d, d)
    c[zero, :] = 0.0
    c[:, zero] = 0.0
    eigenvalues, vectors = np.linalg.eigh(c)
    top = eigenvalues[-1] if eigenvalues.size else 0.0
    keep = eigenvalues > ratio * top if top > 0 else np.zeros_like(eigenvalues, dtype=bool)
    weight = np.sum(vectors[:, ~keep] ** 2, axis=1) if (~keep).any() else np.zeros(m.shape[0])
    undetermined = sorted(
        {int(j) for j in np.flatnonzero(weight > 1e-6)} | set(np.flatnonzero(zero).tolist())
    )
    return keep, undetermined
