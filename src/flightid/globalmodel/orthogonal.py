"""Gram–Schmidt orthogonalisation of modelling functions and its inverse.

For candidate columns ξ_1 … ξ_M (N samples each), modified Gram–Schmidt gives

    p_1 = ξ_1,   p_j = ξ_j − Σ_{k<j} γ_kj p_k,   γ_kj = p_kᵀ ξ_j / p_kᵀ p_k,

so that p_iᵀ p_j = 0 for i ≠ j and Ξ = P Γ with Γ unit upper triangular. A column whose
remaining squared norm is below ``tol`` times its own (a linear combination of the earlier
ones) is dropped as dependent.

In the orthogonal basis least squares decouples: â_j = p_jᵀ z / p_jᵀ p_j, and the cost
J = ½ ‖z − P a‖² falls by ΔJ_j = ½ (p_jᵀ z)² / p_jᵀ p_j for each function, whatever else is in
the model. A model on the functions p_S with coefficients a_S equals the ordinary model
Σ θ_j ξ_j with θ = Γ⁻¹ a (the retransformation), as the columns of P span those of Ξ.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_triangular

__all__ = ["gram_schmidt", "orthogonal_coefficients", "cost_reductions", "retransform"]


def gram_schmidt(Xi: np.ndarray, tol: float = 1e-10) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Modified Gram–Schmidt of the columns of Ξ (N, M).

    Returns:
        (P, Γ, kept): P (N, K) mutually orthogonal columns, Γ (K, K) unit upper triangular
        with Ξ[:, kept] = P Γ, and the indices of the K columns kept (in order; a column
        whose remaining norm² is below ``tol`` ‖ξ_j‖² is dropped as dependent).
    """
    Xi = np.asarray(Xi, dtype=float)
    work = Xi.copy()
    norms2 = np.einsum("ij,ij->j", Xi, Xi)
    n_columns = Xi.shape[1]
    kept: list[int] = []
    gamma = np.zeros((n_columns, n_columns))
    for j in range(n_columns):
        p = work[:, j]
        pp = float(p @ p)
        if pp <= tol * norms2[j] or pp == 0.0:
            continue
        kept.append(j)
        rest = slice(j + 1, n_columns)
        # γ_jk = p_jᵀ w_k / p_jᵀ p_j, then w_k ← w_k − γ_jk p_j for the later columns
        coefficients = (p @ work[:, rest]) / pp
        work[:, rest] -= np.outer(p, coefficients)
        gamma[j, rest] = coefficients
    kept_index = np.array(kept, dtype=int)
    P = work[:, kept_index]
    Gamma = gamma[np.ix_(kept_index, kept_index)] + np.eye(kept_index.size)
    return P, Gamma, kept_index


def orthogonal_coefficients(P: np.ndarray, z: np.ndarray) -> np.ndarray:
    """â_j = p_jᵀ z / p_jᵀ p_j for each orthogonal column."""
    # â_j = p_jᵀ z / p_jᵀ p_j
    return (P.T @ z) / np.einsum("ij,ij->j", P, P)


def cost_reductions(P: np.ndarray, z: np.ndarray) -> np.ndarray:
    """ΔJ_j = ½ (p_jᵀ z)² / p_jᵀ p_j: the fall of J = ½‖z − Pa‖² each column brings."""
    # ΔJ_j = ½ (p_jᵀ z)² / (p_jᵀ p_j)
    return 0.5 * (P.T @ z) ** 2 / np.einsum("ij,ij->j", P, P)


def retransform(Gamma: np.ndarray, a: np.ndarray) -> np.ndarray:
    """θ = Γ⁻¹ a: the ordinary-function coefficients of the orthogonal model a."""
    # Γ θ = a, Γ unit upper triangular
    return solve_triangular(Gamma, a, lower=False, unit_diagonal=True)
