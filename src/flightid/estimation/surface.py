"""Sensitivities estimated from a surface fitted through past parameter points (MNRES).

For every sample i and output k, MNRES fits y_ik(θ) through the stored points θ^j
(RP-1153 §4, 4.9–4.23). Parameters are handled in scaled form ϑ = θ / typical so the linear
algebra is well conditioned whatever the parameters' units.

Algebraic (linear-surface) form through n_f + 1 points, expansion point θ⁰ [4.15]:

    ΔX = [ϑ¹ − ϑ⁰; …; ϑ^{n_f} − ϑ⁰]    (n_f × n_f, independent of time)
    ΔY = [y(θ¹) − y(θ⁰); …]            (n_f × N·n_o)
    S  = ΔX⁻¹ ΔY                        (one LU factorisation for all N·n_o right-hand sides)

Least-squares form through n ≥ n_f + 1 points [4.18–4.23]: with X = [1, ϑ^j − ϑ_ref] (rows j),
S = (XᵀX)⁻¹XᵀY, solved by QR (``batch_surface``) or carried by the constant-window recursive
update (``RecursiveSurface``) when a point enters and another leaves [3.9–3.10]:

    P_{k+1} = (P_k⁻¹ + aᵀa − a°ᵀa°)⁻¹
    S_{k+1} = S_k − P_{k+1} [a°ᵀy° − aᵀy + (aᵀa − a°ᵀa°) S_k]

implemented as one rank-one Sherman–Morrison update per row (add, then remove), which is the
same algebra without an explicit inverse of P⁻¹.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from flightid.errors import EstimationError

__all__ = ["algebraic_surface", "batch_surface", "RecursiveSurface"]


def algebraic_surface(
    points: np.ndarray, outputs: np.ndarray, base: int, max_condition: float
) -> np.ndarray:
    """Slopes S (n_f × m) of the linear surface through n_f + 1 points [4.15].

    Args:
        points: scaled parameter points (n_f + 1, n_f).
        outputs: flattened output histories (n_f + 1, m).
        base: index of the expansion point θ⁰.
        max_condition: largest acceptable condition number of ΔX.
    Raises:
        EstimationError: if ΔX is ill-conditioned (the points have collapsed).
    """
    others = np.arange(points.shape[0]) != base
    delta_x = points[others] - points[base]
    delta_y = outputs[others] - outputs[base]
    condition = np.linalg.cond(delta_x)
    if not np.isfinite(condition) or condition > max_condition:
        raise EstimationError(f"MNRES: ΔX is ill-conditioned (condition number {condition:.3g})")
    # S = ΔX⁻¹ ΔY, by LU with partial pivoting, one factorisation for all columns
    return scipy.linalg.lu_solve(scipy.linalg.lu_factor(delta_x), delta_y)


def _design(points: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Rows a_j = [1, ϑ^j − ϑ_ref]."""
    return np.column_stack([np.ones(points.shape[0]), points - reference])


def batch_surface(
    points: np.ndarray, outputs: np.ndarray, reference: np.ndarray, max_condition: float
) -> np.ndarray:
    """Slopes (n_f × m) of the least-squares plane through n ≥ n_f + 1 points (QR)."""
    design = _design(points, reference)
    q, r = np.linalg.qr(design)
    condition = np.linalg.cond(r)
    if not np.isfinite(condition) or condition > max_condition:
        raise EstimationError(
            f"MNRES: the surface design matrix is ill-conditioned (condition {condition:.3g})"
        )
    coefficients = scipy.linalg.solve_triangular(r, q.T @ outputs)
    return coefficients[1:]


class RecursiveSurface:
    """Least-squares plane carried by recursive updates over a window of points.

    ``add`` grows the window, ``remove`` shrinks it; ``replace`` is the paper's constant-window
    step (one point in, one out). ``slopes`` returns the current ∂y/∂ϑ (n_f × m).
    """

    def __init__(self, points: np.ndarray, outputs: np.ndarray, reference: np.ndarray) -> None:
        self.reference = np.array(reference, dtype=float)
        design = _design(points, self.reference)
        information = design.T @ design
        # P = (XᵀX)⁻¹ once at (re)start, through a Cholesky factorisation
        try:
            factor = scipy.linalg.cho_factor(information)
        except np.linalg.LinAlgError:
            raise EstimationError(
                "MNRES: the starting points do not span parameter space"
            ) from None
        self.p = scipy.linalg.cho_solve(factor, np.eye(information.shape[0]))
        self.s = scipy.linalg.cho_solve(factor, design.T @ outputs)

    def add(self, point: np.ndarray, output: np.ndarray) -> None:
        """A new row enters: P ← P − P aᵀ a P / (1 + a P aᵀ); S ← S + P aᵀ (y − a S)."""
        a = np.concatenate([[1.0], point - self.reference])
        pa = self.p @ a
        self.p -= np.outer(pa, pa) / (1.0 + a @ pa)
        self.s += np.outer(self.p @ a, output - a @ self.s)

    def remove(self, point: np.ndarray, output: np.ndarray) -> None:
        """An old row leaves: P ← P + P a°ᵀ a° P / (1 − a° P a°ᵀ); S ← S − P a°ᵀ (y° − a° S)."""
        a = np.concatenate([[1.0], point - self.reference])
        pa = self.p @ a
        denominator = 1.0 - a @ pa
        if denominator <= 1e-12:
            raise EstimationError("MNRES: removing this point would leave the surface undetermined")
        self.p += np.outer(pa, pa) / denominator
        self.s -= np.outer(self.p @ a, output - a @ self.s)

    def replace(self, new_point, new_output, old_point, old_output) -> None:
        """Constant-window step [3.9–3.10]: the new point enters, the old one leaves."""
        self.add(new_point, new_output)
        self.remove(old_point, old_output)

    def slopes(self) -> np.ndarray:
        return self.s[1:]
