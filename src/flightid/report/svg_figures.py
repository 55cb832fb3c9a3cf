"""The output-error report's figures as SVG text, written from the arrays (numpy and the
standard library; ``flightid.report.svg_axes`` draws the panels).

The three figures show what ``flightid.report.figures`` draws with matplotlib, with the
same arguments:

* ``maneuver_svg``: the inputs on top (full width; held steps for zero-order-hold inputs),
  then per output the measured (``+``) and predicted (line) response on the left (3/5 of the
  width) and the residual z − y with its zero line on the right, against t − t₀;
* ``autocorrelation_svg``: per output the residual autocorrelation ρ(k) as stems (outside
  the white-noise band ±1.96/√N in red), the band, and the coloured-residual correction's
  lag L;
* ``cost_history_svg``: the cost J at fixed R per pass (log scale, one line per stretch
  under one R), the R re-estimations as dashed lines, and ln det R̂ above it when given.

Each returns one ``<svg>`` element (a standalone ``.svg`` file, and inline in report.html).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from flightid.errors import InputError
from flightid.report import svg_axes as ax
from flightid.report.svg_axes import Panel, PanelText, axis_label

__all__ = ["maneuver_svg", "autocorrelation_svg", "cost_history_svg", "SVG_FUNCTIONS"]

BLUE, RED, ORANGE, GREEN, DARK = "#1f77b4", "#d62728", "#ff7f0e", "#2ca02c", "#404040"
WIDTH_PX = 11.0 * ax.PX_PER_IN
# heights (px): an input panel, an output panel; the gap above a panel (its offset text),
# above a titled one (title and offset text); the figure title's room; below the bottom row
INPUT_PX, OUTPUT_PX = 0.8 * ax.PX_PER_IN, 1.15 * ax.PX_PER_IN
GAP_PX, TITLED_GAP_PX, SUPTITLE_PX, BOTTOM_PX, RIGHT_PX = 16.0, 34.0, 30.0, 44.0, 20.0


def _matrix(values, n: int, argument: str) -> np.ndarray:
    matrix = np.asarray(values, dtype=float)
    if matrix.ndim == 1:
        matrix = matrix[:, None]
    if matrix.ndim != 2 or matrix.shape[0] != n:
        raise InputError(
            f"{argument}: expected an array of {n} rows (one per time sample), "
            f"got shape {matrix.shape}"
        )
    return matrix


def _x_axis(low: float, high: float, integer: bool = False):
    """The common x axis' limits, round ticks inside and their labels."""
    if not high > low:
        high = low + 1.0
    ticks = ax.nice_ticks(low, high, 8 if integer else 7, integer)
    labels, _ = ax.tick_labels(ticks)
    return low, high, ticks, labels


def maneuver_svg(
    time: np.ndarray,
    inputs: np.ndarray | None,
    input_names: Sequence[str],
    measured: np.ndarray,
    predicted: np.ndarray,
    output_names: Sequence[str],
    units: Mapping[str, str],
    title: str,
    input_steps: bool = False,
    dpi: float | None = None,
) -> str:
    """One maneuver's time histories (see the module docstring) as SVG text. The arguments
    are ``flightid.report.figures.maneuver_figure``'s (``dpi`` is not used: an SVG is drawn
    at the viewer's resolution; lines go through their envelope per pixel column of the
    figure at 96 px per inch)."""
    time = np.asarray(time, dtype=float)
    n = time.shape[0]
    t0 = float(time[0]) if n else 0.0
    t = time - t0
    z = _matrix(measured, n, "measured")
    y = _matrix(predicted, n, "predicted")
    has_inputs = inputs is not None and len(input_names)
    u = _matrix(inputs, n, "inputs") if has_inputs else np.zeros((n, 0))
    n_u, n_o = u.shape[1], len(output_names)
    with np.errstate(invalid="ignore"):
        residuals = z - y
    input_scales = [ax.y_scale(u[:, i], bins=3) for i in range(n_u)]
    output_scales = [ax.y_scale(np.concatenate([z[:, j], y[:, j]])) for j in range(n_o)]
    residual_scales = [ax.y_scale(residuals[:, j]) for j in range(n_o)]
    left = ax.y_label_margin(input_scales + output_scales)
    residual_left = ax.y_label_margin(residual_scales)
    usable = WIDTH_PX - left - RIGHT_PX
    output_width = 0.6 * usable
    residual_width = max(usable - output_width - residual_left, 40.0)
    x0, x1, x_ticks, x_labels = _x_axis(float(t[0]) if n else 0.0, float(t[-1]) if n else 1.0)
    body: list[str] = []
    top = SUPTITLE_PX
    for i in range(n_u):
        top += TITLED_GAP_PX if i == 0 else GAP_PX
        panel = Panel(left, top, usable, INPUT_PX, x0, x1, input_scales[i])
        ax.polyline(panel, t, u[:, i], "black", 1.1, steps=input_steps)
        label = axis_label(input_names[i], units.get(input_names[i]))
        text = PanelText(label, "inputs" if i == 0 else "", face="#f6f6ee")
        text.x_labelled = n_o == 0 and i == n_u - 1
        body.append(ax.render_panel(panel, x_ticks, x_labels, text))
        top += INPUT_PX
    for j, name in enumerate(output_names):
        top += TITLED_GAP_PX if j == 0 else GAP_PX
        last = j == n_o - 1
        unit = units.get(name)
        panel = Panel(left, top, output_width, OUTPUT_PX, x0, x1, output_scales[j])
        ax.markers(panel, t, z[:, j], DARK)
        ax.polyline(panel, t, y[:, j], BLUE, 1.2)
        text = PanelText(axis_label(name, unit), x_labelled=last)
        if j == 0:
            text.title = "outputs: measured vs predicted"
            text.legend = (("plus", DARK, "measured z"), ("line", BLUE, "predicted y"))
        if last:
            text.xlabel = f"t − t₀ [s]   (t₀ = {t0:g} s)"
        body.append(ax.render_panel(panel, x_ticks, x_labels, text))
        res_left = left + output_width + residual_left
        panel = Panel(res_left, top, residual_width, OUTPUT_PX, x0, x1, residual_scales[j])
        ax.hline(panel, 0.0, "black", 0.5)
        ax.polyline(panel, t, residuals[:, j], RED, 0.8)
        text = PanelText(axis_label("z − y", unit), "residuals" if j == 0 else "", "", last)
        text.xlabel = "t − t₀ [s]" if last else ""
        body.append(ax.render_panel(panel, x_ticks, x_labels, text))
        top += OUTPUT_PX
    return ax.document(WIDTH_PX, top + BOTTOM_PX, body, title)


def _autocorrelation_panel(panel: Panel, lags_s, rho, band: float, dt: float, lag_used):
    """One output's stems, band, zero line and correction lag; the lags outside the band."""
    outside = np.abs(rho) > band
    outside[0] = False
    ax.band(panel, -band, band, "#d9d9d9")
    ax.hline(panel, 0.0, "black", 0.5)
    ax.stems(panel, lags_s[~outside], rho[~outside], BLUE)
    ax.stems(panel, lags_s[outside], rho[outside], RED)
    if lag_used:
        ax.vline(panel, lag_used * dt, ORANGE, 0.9, "4 2")
    return int(outside.sum())


def autocorrelation_svg(
    rho: np.ndarray, band: float, dt: float, names: Sequence[str], lag_used: int | None = None
) -> str:
    """Residual autocorrelation ρ_o(k) per output against the lag in seconds, with the
    white-noise band ±``band``; ``lag_used`` marks the coloured-residual correction's L
    (``flightid.report.figures.autocorrelation_figure``'s arguments)."""
    rho = np.asarray(rho, dtype=float).reshape(len(rho), -1)
    lags_s = np.arange(rho.shape[0]) * dt
    columns = max(min(len(names), 3), 1)
    panel_width, panel_height = 3.0 * ax.PX_PER_IN, 1.6 * ax.PX_PER_IN
    scales = [
        ax.y_scale(rho[:, j], 4, (min(-0.3, float(np.nanmin(rho[:, j])) - 0.05), 1.05))
        for j in range(len(names))
    ]
    left = ax.y_label_margin(scales)
    x0, x1, x_ticks, x_labels = _x_axis(0.0, float(lags_s[-1]) if lags_s.size > 1 else 1.0)
    gap = TITLED_GAP_PX + 6.0
    body = []
    for j, name in enumerate(names):
        row, column = divmod(j, columns)
        top = SUPTITLE_PX + gap + row * (gap + panel_height + 12.0)
        panel = Panel(
            column * (left + panel_width) + left, top, panel_width, panel_height, x0, x1, scales[j]
        )
        count = _autocorrelation_panel(panel, lags_s, rho[:, j], band, dt, lag_used)
        lowest = j + columns >= len(names)
        text = PanelText(
            "ρ(k) [–]" if column == 0 else "",
            f"{name}: {count} of {len(rho) - 1} lags outside",
            "lag [s]" if lowest else "",
            lowest,
        )
        body.append(ax.render_panel(panel, x_ticks, x_labels, text))
    rows = -(-len(names) // columns)
    width = columns * (left + panel_width) + RIGHT_PX
    # the legend in the figure title's row, at the right
    entries = (("patch", "#d9d9d9", "±1.96/√N"),)
    if lag_used:
        entries += (("dash", ORANGE, f"correction lag L = {lag_used}"),)
    body += ax.legend(width - RIGHT_PX, 20.0, entries)
    height = SUPTITLE_PX + rows * (gap + panel_height + 12.0) + BOTTOM_PX
    return ax.document(width, height, body, "residual autocorrelation")


def _cost_panel(panel: Panel, costs: np.ndarray, noise_update_passes: Sequence[int]) -> None:
    """The cost per pass, one line per stretch under one R (a cost under a new R is not
    comparable with the last)."""
    passes = np.arange(costs.size, dtype=float)
    edges = sorted({0, costs.size, *(p for p in noise_update_passes if 0 < p < costs.size)})
    for a, b in zip(edges[:-1], edges[1:], strict=False):
        positive = costs[a:b] > 0
        ax.polyline(panel, passes[a:b][positive], costs[a:b][positive], BLUE, 1.2)
        ax.markers(panel, passes[a:b][positive], costs[a:b][positive], BLUE, 7.0, circles=True)


def cost_history_svg(
    costs: Sequence[float],
    noise_update_passes: Sequence[int] = (),
    title: str = "cost history",
    log_det_r: Sequence[float] = (),
) -> str:
    """Convergence per recorded pass: ln det R̂ (top panel, when ``log_det_r`` has a
    finite entry per pass) and the cost J at fixed R (log scale), a dashed line at each R
    re-estimation (``flightid.report.figures.cost_history_figure``'s arguments)."""
    costs = np.asarray(costs, dtype=float).ravel()
    log_det_r = np.asarray(log_det_r, dtype=float).ravel()
    with_log_det = log_det_r.size == costs.size and bool(np.any(np.isfinite(log_det_r)))
    width, panel_height = 6.5 * ax.PX_PER_IN, 2.0 * ax.PX_PER_IN
    scales = [ax.y_scale(log_det_r, 6)] if with_log_det else []
    scales.append(ax.log_scale(costs))
    left = ax.y_label_margin(scales)
    x0, x1, x_ticks, x_labels = _x_axis(-0.7, costs.size - 0.3, integer=True)
    passes = np.arange(costs.size, dtype=float)
    legend = (("dash", ORANGE, "R re-estimated"),) if len(noise_update_passes) else ()
    body, top = [], 10.0
    for k, scale in enumerate(scales):
        top += TITLED_GAP_PX if k == 0 else GAP_PX
        panel = Panel(left, top, width - left - RIGHT_PX, panel_height, x0, x1, scale)
        for p in noise_update_passes:
            ax.vline(panel, p - 0.5, ORANGE, 1.0, "4 2")
        cost = k == len(scales) - 1
        if cost:
            _cost_panel(panel, costs, noise_update_passes)
            text = PanelText("cost J at fixed R = Σ νᵀR⁻¹ν [–]", "", "pass [–]", True)
        else:
            finite = np.isfinite(log_det_r)
            ax.polyline(panel, passes[finite], log_det_r[finite], GREEN, 1.2)
            ax.markers(panel, passes[finite], log_det_r[finite], GREEN, 7.0, circles=True)
            text = PanelText("ln det R̂ [–]")
        if k == 0:
            text.title, text.legend = title, legend
        body.append(ax.render_panel(panel, x_ticks, x_labels, text))
        top += panel_height
    return ax.document(width, top + BOTTOM_PX, body)


# the SVG writer of each figure function of flightid.report.figures (same arguments)
SVG_FUNCTIONS = {
    "maneuver_figure": maneuver_svg,
    "autocorrelation_figure": autocorrelation_svg,
    "cost_history_figure": cost_history_svg,
}
