"""Figures of the recursive, input-design and regression reports
(``flightid.report.estimator_reports``), every axis labelled with its unit.

Drawn with matplotlib's object interface (no pyplot, no global backend change); the
callers turn them into PNG bytes with ``flightid.report.figures.png_bytes``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from flightid.report.figures import axis_label

__all__ = [
    "coefficient_fit_figure",
    "design_input_figure",
    "innovations_figure",
    "parameter_history_figure",
    "predicted_sigma_figure",
]


def _grid(n: int, columns: int, width: float, height: float) -> tuple[Figure, list]:
    rows = -(-n // columns)
    figure = Figure(figsize=(width * columns, height * rows + 0.7))
    axes = figure.subplots(rows, columns, squeeze=False)
    flat = list(axes.flat)
    for ax in flat[n:]:
        ax.set_visible(False)
    return figure, flat[:n]


def _finish(figure: Figure, axes: list, title: str) -> Figure:
    for ax in axes:
        ax.tick_params(labelsize=7)
        ax.grid(True, linewidth=0.4, alpha=0.5)
    figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    return figure


def parameter_history_figure(
    time_s: np.ndarray,
    theta: np.ndarray,
    sigma: np.ndarray,
    names: Sequence[str],
    units: Sequence[str],
    reported: np.ndarray,
    title: str,
) -> Figure:
    """One panel per parameter: its estimate against time with the ±σ band (where σ is
    finite) and the reported value dashed."""
    columns = 2 if len(names) > 3 else 1
    figure, axes = _grid(len(names), columns, 4.6, 1.7)
    for j, ax in enumerate(axes):
        value, band = theta[:, j], sigma[:, j]
        if np.all(np.isfinite(band)):
            ax.fill_between(
                time_s, value - band, value + band, color="C0", alpha=0.25, lw=0, label="±σ"
            )
        ax.plot(time_s, value, color="C0", lw=0.9, label="estimate")
        ax.axhline(reported[j], color="C3", lw=0.7, ls="--", label="reported")
        # a y range about the settled part, not the start transient
        tail = value[len(value) // 5 :]
        spread = float(np.ptp(tail)) + (
            4 * float(np.median(band[len(value) // 2 :])) if np.all(np.isfinite(band)) else 0.0
        )
        if np.isfinite(spread) and spread > 0:
            ax.set_ylim(reported[j] - 1.5 * spread, reported[j] + 1.5 * spread)
        ax.set_ylabel(axis_label(names[j], units[j]), fontsize=8)
        ax.set_xlabel("time [s]", fontsize=8)
    if axes:
        axes[0].legend(fontsize=7, frameon=False)
    return _finish(figure, axes, title)


def innovations_figure(
    time_s: np.ndarray,
    innovations: np.ndarray,
    names: Sequence[str],
    units: Sequence[str],
    title: str,
) -> Figure:
    """One panel per output: the innovation ν = z − ỹ against time."""
    figure, axes = _grid(len(names), 1, 7.5, 1.5)
    for j, ax in enumerate(axes):
        ax.plot(time_s, innovations[:, j], color="C2", lw=0.7)
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel(axis_label(f"ν {names[j]}", units[j]), fontsize=8)
        ax.set_xlabel("time [s]", fontsize=8)
    return _finish(figure, axes, title)


def design_input_figure(
    time_s: np.ndarray,
    perturbations: np.ndarray,
    input_names: Sequence[str],
    input_units: Sequence[str],
    amplitudes: Sequence[float],
    outputs: np.ndarray,
    output_names: Sequence[str],
    output_units: Sequence[str],
    title: str,
) -> Figure:
    """The designed perturbations Δu (dotted: ± the amplitude limit) and the predicted
    outputs y against time (the response limits, about the trim-input response, are in
    the report's table)."""
    n = len(input_names) + len(output_names)
    figure, axes = _grid(n, 1, 7.5, 1.5)
    for j, name in enumerate(input_names):
        ax = axes[j]
        ax.plot(time_s, perturbations[:, j], lw=0.9)
        for sign in (1, -1):
            ax.axhline(sign * amplitudes[j], color="0.6", ls=":", lw=0.8)
        ax.set_ylabel(axis_label(f"Δ{name}", input_units[j]), fontsize=8)
    for i, name in enumerate(output_names):
        ax = axes[len(input_names) + i]
        ax.plot(time_s, outputs[:, i], lw=0.9, color="C1")
        ax.set_ylabel(axis_label(name, output_units[i]), fontsize=8)
    for ax in axes:
        ax.set_xlabel("time [s]", fontsize=8)
    return _finish(figure, axes, title)


def predicted_sigma_figure(
    names: Sequence[str],
    designed_percent: np.ndarray,
    reference_percent: np.ndarray | None,
    label: str,
    title: str,
) -> Figure:
    """Predicted relative σ (σ/max(|θ|, typical) in %) per parameter, designed input beside
    the reference maneuver's when there is one."""
    figure = Figure(figsize=(7.5, 2.8))
    ax = figure.subplots()
    x = np.arange(len(names))
    width = 0.4 if reference_percent is not None else 0.8
    ax.bar(x, designed_percent, width, label=label)
    if reference_percent is not None:
        ax.bar(x + width, reference_percent, width, label="reference maneuver")
    ax.set_xticks(x + (width / 2 if reference_percent is not None else 0))
    ax.set_xticklabels(names, fontsize=7)
    ax.set_ylabel("predicted σ / |θ| [%]", fontsize=8)
    ax.set_xlabel("parameter", fontsize=8)
    ax.legend(fontsize=7, frameon=False)
    return _finish(figure, [ax], title)


def coefficient_fit_figure(
    time_s: np.ndarray,
    measured: np.ndarray,
    fitted: np.ndarray,
    names: Sequence[str],
    title: str,
) -> Figure:
    """Per coefficient: measured (+) and fitted (line) against time, and the residual
    below (non-dimensional coefficients: unit [–])."""
    figure, axes = _grid(2 * len(names), 1, 7.5, 1.4)
    for j, name in enumerate(names):
        top, bottom = axes[2 * j], axes[2 * j + 1]
        top.plot(
            time_s, measured[:, j], ls="none", marker="+", ms=3, color="0.25", label="measured"
        )
        top.plot(time_s, fitted[:, j], lw=1.0, color="tab:blue", label="fitted")
        top.set_ylabel(axis_label(name, "–"), fontsize=8)
        bottom.plot(time_s, measured[:, j] - fitted[:, j], lw=0.7, color="C3")
        bottom.axhline(0.0, color="k", lw=0.5)
        bottom.set_ylabel(axis_label(f"residual {name}", "–"), fontsize=8)
        bottom.set_xlabel("time [s]", fontsize=8)
        if j == 0:
            top.legend(fontsize=7, frameon=False)
    return _finish(figure, axes, title)
