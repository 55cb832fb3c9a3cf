"""Figures of the confidence region: a one-parameter profile and a two-parameter slice.

* ``plot_profile`` — after RP-1153 figure 4: the profile cost J(θ_j) (minimised over the other
  parameters) against θ_j, its quadratic approximation J(θ̂) + (θ_j − θ̂_j)²/C_jj, the levels
  J(θ̂) + Δ and the Beale-corrected J(θ̂) + Δ_B, and the two intervals: Cramér–Rao (dashed
  verticals, symmetric) and profile likelihood (solid verticals, where the curve meets Δ).
* ``plot_region_slice`` — J − J(θ̂) over a grid of two parameters with the others held at θ̂:
  the contour at Δ (the slice of the likelihood region), the slice's Cramér–Rao ellipse
  δᵀ M_ab δ = Δ, and, dotted, the ellipse of the 2 × 2 block of M⁻¹ (the CR region's
  projection, whose extent is the CR interval).

Inputs are results only (``ProfileCurve``, ``CostSlice``, ``AccuracyResult``); matplotlib's
object interface on an Agg canvas, saved as PNG.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from flightid.report.figures import _save

__all__ = ["plot_profile", "plot_region_slice"]


def _ellipse(matrix: np.ndarray, level: float, n: int = 200) -> np.ndarray:
    """Points δ (n, 2) with δᵀ matrix δ = level."""
    eigenvalues, vectors = np.linalg.eigh(matrix)
    angle = np.linspace(0.0, 2 * np.pi, n)
    circle = np.column_stack([np.cos(angle), np.sin(angle)])
    return (circle * np.sqrt(level / eigenvalues)) @ vectors.T


def plot_profile(curve, accuracy, path: str | Path, *, dpi: int = 120) -> Path:
    """Profile of J against one parameter with the quadratic approximation and both intervals.

    Args:
        curve: ``ProfileCurve`` from ``flightid.accuracy.profile_curve``.
        accuracy: the ``AccuracyResult`` (levels, CR and profile intervals).
        path: PNG file to write.
    """
    j = curve.index
    name = accuracy.names[j]
    centre = accuracy.theta_min[j]
    cost = accuracy.cost_min
    finite = np.isfinite(curve.excess)
    figure = Figure(figsize=(7.0, 4.5))
    axes = figure.add_subplot(1, 1, 1)
    axes.plot(
        curve.values[finite],
        cost + curve.excess[finite],
        "-",
        color="tab:blue",
        lw=1.8,
        label="profile J(θ) (others re-optimised)",
    )
    grid = np.linspace(curve.values.min(), curve.values.max(), 300)
    # quadratic approximation J(θ̂) + (θ_j − θ̂_j)² / C_jj
    quadratic = cost + (grid - centre) ** 2 / accuracy.covariance[j, j] * 1.0
    axes.plot(grid, quadratic, "--", color="0.35", lw=1.2, label="quadratic approximation (CR)")
    axes.axhline(
        cost + accuracy.delta,
        color="tab:red",
        lw=1.0,
        ls="-",
        label=f"J(θ̂) + Δ ({accuracy.level:g}, {accuracy.kind})",
    )
    if accuracy.delta_beale > accuracy.delta * (1 + 1e-6):
        axes.axhline(
            cost + accuracy.delta_beale,
            color="tab:red",
            lw=1.0,
            ls=":",
            label="J(θ̂) + Δ, Beale-corrected",
        )
    lo, hi = accuracy.ci_cr[j]
    for value in (lo, hi):
        axes.axvline(value, color="0.35", ls="--", lw=1.0)
    if accuracy.profile is not None and np.all(np.isfinite(accuracy.ci_profile[j])):
        for value in accuracy.ci_profile[j]:
            axes.axvline(value, color="tab:blue", ls="-", lw=1.0)
        p_lo, p_hi = accuracy.ci_profile[j]
        text = f"profile [{p_lo:.4g}, {p_hi:.4g}]\nCR [{lo:.4g}, {hi:.4g}]"
        axes.text(0.02, 0.97, text, transform=axes.transAxes, va="top", fontsize=9)
    axes.plot([centre], [cost], "k+", ms=10)
    top = cost + 2.5 * max(accuracy.delta_beale, accuracy.delta)
    axes.set_ylim(cost - 0.1 * accuracy.delta, top)
    axes.set_xlabel(name)
    axes.set_ylabel("J(θ)")
    axes.set_title(f"Confidence interval of {name}: likelihood profile vs quadratic (CR)")
    axes.legend(fontsize=8, loc="upper right")
    figure.tight_layout()
    return _save(figure, path, dpi)


def plot_region_slice(cost_slice, accuracy, path: str | Path, *, dpi: int = 120) -> Path:
    """Two-parameter slice of the likelihood region with the Cramér–Rao ellipses.

    Args:
        cost_slice: ``CostSlice`` from ``flightid.accuracy.cost_slice``.
        accuracy: the ``AccuracyResult``.
        path: PNG file to write.
    """
    a, b = cost_slice.a, cost_slice.b
    names = accuracy.names
    centre = cost_slice.center[[a, b]]
    figure = Figure(figsize=(6.5, 5.5))
    axes = figure.add_subplot(1, 1, 1)
    excess = np.where(np.isfinite(cost_slice.excess), cost_slice.excess, np.nan)
    levels = accuracy.delta * np.array([0.25, 0.5, 1.0, 2.0, 4.0])
    shaded = axes.contourf(
        cost_slice.values_a,
        cost_slice.values_b,
        excess.T,
        levels=[0, accuracy.delta],
        colors=["tab:blue"],
        alpha=0.15,
    )
    del shaded
    lines = axes.contour(
        cost_slice.values_a,
        cost_slice.values_b,
        excess.T,
        levels=levels,
        colors="0.6",
        linewidths=0.7,
    )
    axes.clabel(lines, fmt=lambda v: f"{v / accuracy.delta:g}Δ", fontsize=7)
    axes.contour(
        cost_slice.values_a,
        cost_slice.values_b,
        excess.T,
        levels=[accuracy.delta],
        colors="tab:blue",
        linewidths=1.8,
    )
    information = np.linalg.inv(accuracy.covariance)
    # slice CR ellipse: δᵀ M_ab δ = Δ
    ring = centre + _ellipse(information[np.ix_([a, b], [a, b])], accuracy.delta)
    axes.plot(ring[:, 0], ring[:, 1], "--", color="k", lw=1.2, label="CR ellipse of the slice")
    # projection of the CR ellipsoid: δᵀ (C_ab)⁻¹ δ = Δ
    block = np.linalg.inv(accuracy.covariance[np.ix_([a, b], [a, b])])
    ring = accuracy.center[[a, b]] + _ellipse(block, accuracy.delta)
    axes.plot(ring[:, 0], ring[:, 1], ":", color="k", lw=1.0, label="CR ellipsoid, projected")
    axes.plot([], [], "-", color="tab:blue", lw=1.8, label="J − J(θ̂) = Δ (slice)")
    axes.plot(*centre, "k+", ms=10)
    axes.set_xlabel(names[a])
    axes.set_ylabel(names[b])
    axes.set_title(f"Slice of the {accuracy.level:g} likelihood region ({accuracy.kind} level)")
    axes.legend(fontsize=8, loc="upper right")
    figure.tight_layout()
    return _save(figure, path, dpi)
