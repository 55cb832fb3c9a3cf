"""Two-parameter slices of the cost surface, for pictures of the confidence region.

A slice holds every other parameter at θ̂ and maps J(θ) − J(θ̂) over a grid of (θ_a, θ_b).
Its quadratic approximation is (δ_a, δ_b) M_ab (δ_a, δ_b)ᵀ, with M_ab the 2 × 2 block of the
information matrix (the slice's Cramér–Rao ellipse); the *projection* of the full region on
the same plane is bounded instead by the ellipse of the 2 × 2 block of M⁻¹.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightid.accuracy.contour import Contour

__all__ = ["CostSlice", "cost_slice"]


@dataclass(frozen=True)
class CostSlice:
    """J − J(θ̂) on a grid: ``excess[k, l]`` at (values_a[k], values_b[l])."""

    a: int  # free-parameter index on the horizontal axis
    b: int  # free-parameter index on the vertical axis
    values_a: np.ndarray
    values_b: np.ndarray
    excess: np.ndarray  # (len(values_a), len(values_b)); inf where the simulation diverged
    center: np.ndarray  # the point the slice passes through (n_f,)
    evaluations: int


def cost_slice(
    contour: Contour, a: int, b: int, values_a: np.ndarray, values_b: np.ndarray
) -> CostSlice:
    """Evaluate the slice through ``contour.theta_hat`` (one batch of len(a)·len(b) runs)."""
    values_a = np.asarray(values_a, dtype=float)
    values_b = np.asarray(values_b, dtype=float)
    before = contour.evaluations
    grid_a, grid_b = np.meshgrid(values_a, values_b, indexing="ij")
    points = np.repeat(contour.theta_hat[None, :], grid_a.size, axis=0)
    points[:, a] = grid_a.ravel()
    points[:, b] = grid_b.ravel()
    excess = np.empty(grid_a.size)
    for start in range(0, grid_a.size, 2048):
        excess[start : start + 2048], _ = contour.costs(points[start : start + 2048])
    return CostSlice(
        a=a,
        b=b,
        values_a=values_a,
        values_b=values_b,
        excess=excess.reshape(grid_a.shape),
        center=contour.theta_hat.copy(),
        evaluations=contour.evaluations - before,
    )
