"""The Gauss–Newton (modified Newton–Raphson) step of output-error ML [RP-1153 4.4–4.8].

    M  = Σ_i G_iᵀ R⁻¹ G_i          (information matrix)
    g  = −Σ_i G_iᵀ R⁻¹ ν_i
    Δθ = −M⁻¹ g

Computed without forming M⁻¹: with the weighted, stacked sensitivities A = R^(−½) G (rows i,k)
and weighted residuals b = R^(−½) ν, Δθ is the least-squares solution of A Δθ ≈ b, obtained
from a QR factorisation of A and an SVD of its small triangular factor.

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

from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = [
    "GaussNewtonStep",
    "gauss_newton_step",
    "information_matrix",
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


def _weighted(g: np.ndarray, nu: np.ndarray | None, r_diag: np.ndarray):
    weight = 1.0 / np.sqrt(r_diag)
    a = (g * weight[None, :, None]).reshape(-1, g.shape[-1])
    b = None if nu is None else (nu * weight[None, :]).reshape(-1)
    return a, b


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
    a, b = _weighted(g, nu, r_diag)
    n_f = a.shape[1]
    moving = np.ones(n_f, dtype=bool) if held is None else ~np.asarray(held, dtype=bool)
    step = np.zeros(n_f)
    if not moving.any():
        return GaussNewtonStep(step, 0, float("inf"), 0.0, ())
    a_moving = a[:, moving]
    # D = diag(‖A_j‖): unit-norm columns make the rank test independent of units and scales
    norms = np.linalg.norm(a_moving, axis=0)
    zero_column = norms == 0.0
    scale = np.where(zero_column, 1.0, norms)
    a_scaled = a_moving / scale[None, :]
    # A = QR (economic), then R = U Σ Vᵀ: the SVD of the small n_f × n_f factor gives the same
    # singular values and directions as an SVD of the tall A, at a fraction of the cost.
    q, r = scipy.linalg.qr(a_scaled, mode="economic", check_finite=False)
    u, s, vt = np.linalg.svd(r)
    qtb = q.T @ b
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
    """M = Σ_i G_iᵀ R⁻¹ G_i (n_f × n_f) [4.6]."""
    a, _ = _weighted(g, None, r_diag)
    return a.T @ a


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
