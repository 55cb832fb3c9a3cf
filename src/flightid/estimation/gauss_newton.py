"""The Gauss–Newton (modified Newton–Raphson) step of output-error ML [RP-1153 4.4–4.8].

    M  = Σ_i G_iᵀ R⁻¹ G_i          (information matrix)
    g  = −Σ_i G_iᵀ R⁻¹ ν_i
    Δθ = −M⁻¹ g

Computed without forming M⁻¹: with the weighted, stacked sensitivities A = R^(−½) G (rows i,k)
and weighted residuals b = R^(−½) ν, Δθ is the least-squares solution of A Δθ ≈ b, obtained
from a QR factorisation of A (columns scaled to the parameters' typical sizes) and an SVD of
its small triangular factor. Directions the data do
not determine (singular values below ``rcond`` times the largest) get no step and are reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = ["GaussNewtonStep", "gauss_newton_step", "information_matrix"]


@dataclass(frozen=True)
class GaussNewtonStep:
    """A Gauss–Newton step and the facts about it."""

    step: np.ndarray  # Δθ (n_f,), parameter units
    rank: int  # numerical rank of the weighted sensitivity matrix
    condition: float  # condition number of the scaled weighted sensitivities
    predicted_reduction: float  # J(θ) − J_lin(θ + Δθ), the cost drop the linear model predicts


def _weighted(g: np.ndarray, nu: np.ndarray | None, r_diag: np.ndarray):
    weight = 1.0 / np.sqrt(r_diag)
    a = (g * weight[None, :, None]).reshape(-1, g.shape[-1])
    b = None if nu is None else (nu * weight[None, :]).reshape(-1)
    return a, b


def gauss_newton_step(
    g: np.ndarray,
    nu: np.ndarray,
    r_diag: np.ndarray,
    typical: np.ndarray,
    rcond: float = 1e-10,
) -> GaussNewtonStep:
    """Δθ minimising Σ_i (ν_i − G_i Δθ)ᵀ R⁻¹ (ν_i − G_i Δθ).

    Args:
        g: sensitivities (N, n_o, n_f).
        nu: residuals z − y (N, n_o).
        r_diag: noise variances (n_o,).
        typical: parameter scales (n_f,) for column scaling.
        rcond: relative singular-value cut-off.
    """
    a, b = _weighted(g, nu, r_diag)
    a_scaled = a * typical[None, :]
    # A = QR (economic), then R = U Σ Vᵀ: the SVD of the small n_f × n_f factor gives the same
    # singular values and directions as an SVD of the tall A, at a fraction of the cost.
    q, r = scipy.linalg.qr(a_scaled, mode="economic", check_finite=False)
    u, s, vt = np.linalg.svd(r)
    projected = u.T @ (q.T @ b)  # Uᵀ Qᵀ b
    keep = s > rcond * s[0] if s.size and s[0] > 0 else np.zeros_like(s, dtype=bool)
    # Δθ_scaled = V Σ⁺ Uᵀ Qᵀ b
    coefficients = np.where(keep, projected / np.where(keep, s, 1.0), 0.0)
    step_scaled = vt.T @ coefficients
    condition = float(s[0] / s[-1]) if s.size and s[-1] > 0 else float("inf")
    # predicted drop ‖b‖² − ‖b − AΔθ‖² = ‖UᵀQᵀb‖² over the kept directions
    predicted = float(np.sum(np.where(keep, projected, 0.0) ** 2))
    return GaussNewtonStep(step_scaled * typical, int(keep.sum()), condition, predicted)


def information_matrix(g: np.ndarray, r_diag: np.ndarray) -> np.ndarray:
    """M = Σ_i G_iᵀ R⁻¹ G_i (n_f × n_f) [4.6]."""
    a, _ = _weighted(g, None, r_diag)
    return a.T @ a
