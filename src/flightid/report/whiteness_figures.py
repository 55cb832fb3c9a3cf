"""Residual-whiteness figure for any estimator (``flightid.accuracy.whiteness.Whiteness``):
ρ_o(k) per output against the lag with the white-noise band ±1.96/√N, the lags outside the
band in red, and the Ljung–Box Q and p-value in each panel's title."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

__all__ = ["whiteness_figure"]


def whiteness_figure(whiteness, title: str = "residual autocorrelation") -> Figure:
    """One panel per output of a ``Whiteness``; the lag axis in s when ``dt`` is known,
    else in samples."""
    rho = np.asarray(whiteness.rho, dtype=float)
    names = list(whiteness.names)
    band = float(whiteness.band)
    dt = whiteness.dt
    lags = np.arange(rho.shape[0]) * (dt if dt else 1.0)
    columns = min(len(names), 3)
    rows = -(-len(names) // columns)
    figure = Figure(figsize=(3.7 * columns, 2.4 * rows + 0.5))
    axes = figure.subplots(rows, columns, squeeze=False)
    for j, name in enumerate(names):
        ax = axes[j // columns, j % columns]
        outside = np.abs(rho[:, j]) > band
        outside[0] = False
        ax.vlines(lags, 0.0, rho[:, j], color=np.where(outside, "tab:red", "tab:blue"), lw=1.2)
        ax.axhspan(-band, band, color="0.85", zorder=0, label="±1.96/√N")
        ax.axhline(0.0, color="k", linewidth=0.5)
        verdict = "white" if whiteness.white[j] else "coloured"
        ax.set_title(
            f"{name}: {int(outside.sum())} of {rho.shape[0] - 1} lags outside\n"
            f"Ljung–Box Q({whiteness.ljung_box_lags}) = {whiteness.ljung_box[j]:.4g}, "
            f"p = {whiteness.p_value[j]:.2g} ({verdict})",
            fontsize=8,
        )
        ax.set_xlabel("lag [s]" if dt else "lag [samples]", fontsize=8)
        ax.set_ylabel("ρ(k) [–]", fontsize=8)
        ax.set_ylim(min(-0.3, rho[:, j].min() - 0.05), 1.05)
        ax.tick_params(labelsize=7)
        ax.grid(True, linewidth=0.4, alpha=0.5)
        if j == 0:
            ax.legend(fontsize=7, frameon=False, loc="upper right")
    for k in range(len(names), rows * columns):
        axes[k // columns, k % columns].set_visible(False)
    figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    return figure
