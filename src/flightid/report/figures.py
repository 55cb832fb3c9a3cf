"""Time-history figures: measured vs predicted outputs, control inputs, residuals.

The layout follows RP-1153: figures 10 and 12 stack one panel per output, measured response
as ``+`` markers and predicted response as a solid line against time; figure 11 stacks the
control inputs. Figures are drawn with matplotlib's object interface on an Agg canvas (no
pyplot, no global backend change) and saved as PNG.

Every function takes plain arrays and names; ``plot_measured_vs_predicted`` also takes an
``Estimate``-like object (anything with ``time``, ``output_names``, ``measured`` and
``predicted``, and optionally ``maneuver_index``). With several maneuvers each gets its own
column of panels.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from flightid.errors import InputError

# the envelope decimation and the axis labels are the SVG figures' (one implementation)
from flightid.report.svg_axes import axis_label, envelope_indices

__all__ = ["plot_measured_vs_predicted", "plot_inputs", "plot_residuals", "plot_time_histories"]

# the width of a maneuver's time-history figure (inches): inputs full width, outputs and
# residuals side by side, 3 : 2
MANEUVER_FIGURE_WIDTH_IN = 11.0
_MEASURED_STYLE = {"linestyle": "none", "marker": "+", "markersize": 4, "color": "0.25"}
_PREDICTED_STYLE = {"linestyle": "-", "linewidth": 1.2, "color": "tab:blue"}


def _as_matrix(values, n: int, argument: str) -> np.ndarray:
    matrix = np.asarray(values, dtype=float)
    if matrix.ndim == 1:
        matrix = matrix[:, None]
    if matrix.ndim != 2 or matrix.shape[0] != n:
        raise InputError(
            f"{argument}: expected an array of {n} rows (one per time sample), "
            f"got shape {matrix.shape}"
        )
    return matrix


def _segments(maneuver_index: np.ndarray | None, n: int) -> list[np.ndarray]:
    if maneuver_index is None:
        return [np.arange(n)]
    index = np.asarray(maneuver_index)
    return [np.flatnonzero(index == m) for m in np.unique(index)]


def _draw_png(figure: Figure, target, dpi: float) -> None:
    """One Agg draw at ``dpi``, written as PNG: what ``savefig`` writes, without its extra
    draw — a figure that has been through ``tight_layout`` keeps a placeholder layout
    engine, for which ``savefig`` first draws the whole figure with rendering switched off
    (ticks and text measured) and then again. The pixels are the same; the report's three
    figures of a 7-output maneuver took 1.60 s of CPU time with ``savefig``, 1.32 s so
    (measured)."""
    import matplotlib.image

    canvas = figure.canvas if isinstance(figure.canvas, FigureCanvasAgg) else None
    canvas = canvas or FigureCanvasAgg(figure)
    original = figure.dpi
    figure.set_dpi(dpi)
    try:
        canvas.draw()
        pixels = np.asarray(canvas.buffer_rgba())
        # an opaque figure is written without its alpha channel, at zlib level 3: the same
        # pixels, a smaller file, 45 % less encoding time than RGBA at level 6 (measured)
        if bool(np.all(pixels[:, :, 3] == 255)):
            pixels = pixels[:, :, :3]
        matplotlib.image.imsave(
            target,
            pixels,
            format="png",
            origin="upper",
            dpi=dpi,
            metadata={"Software": "flightid (matplotlib Agg)"},
            pil_kwargs={"compress_level": 3},
        )
    finally:
        figure.set_dpi(original)


def _save(figure: Figure, path: str | Path, dpi: int) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".png":
        _draw_png(figure, path, dpi)
    else:
        FigureCanvasAgg(figure)
        figure.savefig(path, dpi=dpi)
    return path


def plot_time_histories(
    time: np.ndarray,
    series: Sequence[tuple[str, np.ndarray, Mapping]],
    names: Sequence[str],
    path: str | Path,
    *,
    labels: Mapping[str, str] | None = None,
    title: str | None = None,
    maneuver_index: np.ndarray | None = None,
    panel_height: float = 1.6,
    width: float = 7.5,
    dpi: int = 120,
) -> Path:
    """Stacked panels, one per channel in ``names``; each series is (legend, (N, n) array,
    matplotlib line style) drawn in every panel. Returns the PNG path."""
    time = np.asarray(time, dtype=float)
    n = time.shape[0]
    names = list(names)
    if not names:
        raise InputError("names: expected at least one channel to plot, got none")
    labels = dict(labels or {})
    matrices = [(legend, _as_matrix(values, n, legend), style) for legend, values, style in series]
    for legend, matrix, _ in matrices:
        if matrix.shape[1] != len(names):
            raise InputError(
                f"{legend}: {matrix.shape[1]} columns but {len(names)} channel names {names}"
            )
    segments = _segments(maneuver_index, n)
    columns = len(segments)
    total_width = width if columns == 1 else width * 0.6 * min(columns, 4)
    figure = Figure(figsize=(total_width, panel_height * len(names) + 0.9))
    axes = figure.subplots(len(names), columns, sharex="col", squeeze=False)
    for c, rows in enumerate(segments):
        t = time[rows]
        for i, name in enumerate(names):
            ax = axes[i, c]
            for legend, matrix, style in matrices:
                ax.plot(t, matrix[rows, i], label=legend, **style)
            if c == 0:
                ax.set_ylabel(labels.get(name, name))
            ax.grid(True, linewidth=0.4, alpha=0.5)
            ax.margins(x=0)
        axes[-1, c].set_xlabel("t, s")
        if columns > 1:
            axes[0, c].set_title(f"maneuver {c + 1}", fontsize=9)
    if len(matrices) > 1:
        axes[0, 0].legend(loc="upper right", fontsize=8, frameon=False, ncol=len(matrices))
    if title:
        figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    return _save(figure, path, dpi)


def plot_measured_vs_predicted(
    result=None,
    path: str | Path = "measured_vs_predicted.png",
    *,
    time: np.ndarray | None = None,
    measured: np.ndarray | None = None,
    predicted: np.ndarray | None = None,
    names: Sequence[str] | None = None,
    labels: Mapping[str, str] | None = None,
    title: str | None = None,
    maneuver_index: np.ndarray | None = None,
    dpi: int = 120,
) -> Path:
    """Measured (+) and predicted (line) time histories of every output (RP-1153 figs. 10, 12).

    Args:
        result: an ``Estimate``-like object (``time``, ``output_names``, ``measured``,
            ``predicted``); or None and the arrays below.
        path: PNG file to write.
        time (N,), measured (N, n_o), predicted (N, n_o), names (n_o): used when ``result``
            is None (and override its fields when given).
        labels: {output name: axis label with unit}.
        title: figure title.
        maneuver_index: (N,) maneuver number per sample (one column of panels each).
    """
    if result is not None:
        time = result.time if time is None else time
        measured = result.measured if measured is None else measured
        predicted = result.predicted if predicted is None else predicted
        names = result.output_names if names is None else names
        if maneuver_index is None:
            maneuver_index = getattr(result, "maneuver_index", None)
    if time is None or measured is None or predicted is None or names is None:
        raise InputError(
            "result: pass an Estimate-like object, or time, measured, predicted and names"
        )
    return plot_time_histories(
        time,
        [("measured", measured, _MEASURED_STYLE), ("predicted", predicted, _PREDICTED_STYLE)],
        names,
        path,
        labels=labels,
        title=title,
        maneuver_index=maneuver_index,
        dpi=dpi,
    )


def plot_inputs(
    time: np.ndarray,
    inputs: Mapping[str, np.ndarray] | np.ndarray,
    path: str | Path = "inputs.png",
    *,
    names: Sequence[str] | None = None,
    labels: Mapping[str, str] | None = None,
    title: str | None = None,
    maneuver_index: np.ndarray | None = None,
    dpi: int = 120,
) -> Path:
    """Control-input time histories, one panel each (RP-1153 fig. 11).

    ``inputs`` is a mapping {name: series} or an (N, n) matrix with ``names``.
    """
    if isinstance(inputs, Mapping):
        names = list(inputs) if names is None else list(names)
        matrix = np.column_stack([np.asarray(inputs[n], dtype=float) for n in names])
    else:
        if names is None:
            raise InputError("names: an input matrix needs its channel names")
        matrix = np.asarray(inputs, dtype=float)
    style = {"linestyle": "-", "linewidth": 1.2, "color": "k", "drawstyle": "steps-post"}
    return plot_time_histories(
        time,
        [("input", matrix, style)],
        names,
        path,
        labels=labels,
        title=title,
        maneuver_index=maneuver_index,
        panel_height=1.4,
        dpi=dpi,
    )


def plot_residuals(
    result,
    path: str | Path = "residuals.png",
    *,
    labels: Mapping[str, str] | None = None,
    title: str | None = None,
    dpi: int = 120,
) -> Path:
    """Residuals ν = z − y of every output against time, for an ``Estimate``-like object."""
    residuals = np.asarray(result.measured, dtype=float) - np.asarray(result.predicted)
    style = {"linestyle": "-", "linewidth": 0.8, "color": "tab:red"}
    return plot_time_histories(
        result.time,
        [("residual", residuals, style)],
        result.output_names,
        path,
        labels=labels,
        title=title,
        maneuver_index=getattr(result, "maneuver_index", None),
        dpi=dpi,
    )


# ------------------------------------------------------------------ report figures
# The HTML report embeds these (``flightid.report.html``): each function returns a Figure,
# ``png_bytes`` renders it. Axis labels carry units as "name [unit]".


def png_bytes(figure: Figure, dpi: int = 90) -> bytes:
    """The figure as PNG bytes (Agg canvas)."""
    import io

    buffer = io.BytesIO()
    _draw_png(figure, buffer, dpi)
    return buffer.getvalue()


def _shown(values: np.ndarray, width_px: float | None) -> np.ndarray | slice:
    """The samples of one time history to draw in a panel ``width_px`` pixels wide (all of
    them when the width is not known)."""
    if width_px is None:
        return slice(None)
    return envelope_indices(values, int(np.ceil(width_px)))


# The report's figures are laid out by arithmetic in inches rather than by ``tight_layout``:
# that measures every tick label and text of every panel by drawing the figure's text once
# more, as much CPU time as the draw itself. Text heights follow from the font sizes, the
# width of a panel's y tick labels from their strings (the tick values and the formatter
# that will label them); the panels share their time axis, with tick labels under the
# bottom row only, and carry few ticks (``MaxNLocator``).

_TICK_PT = 7.0  # tick labels
_LABEL_PT = 8.0  # axis labels
_PT_IN = 1.0 / 72.0
# one line of text of size s: s · 1.25 (ascent + descent of DejaVu Sans) points high
_LINE = 1.25
# the tick mark and its pad to the label (matplotlib: 3.5 pt + 3.5 pt), and the axis label's
# pad (4 pt)
_TICK_SPACE_IN = 7.0 * _PT_IN
_LABEL_PAD_IN = 4.0 * _PT_IN
# left of a panel: the y label's line, its pad, the tick marks, plus the tick labels' width
_LEFT_FIXED_IN = 0.06 + _LINE * _LABEL_PT * _PT_IN + _LABEL_PAD_IN + _TICK_SPACE_IN
# below the bottom row: tick marks, a tick label line, the pad, an x label line, a margin
_BOTTOM_IN = 0.06 + _TICK_SPACE_IN + _LINE * (_TICK_PT + _LABEL_PT) * _PT_IN + _LABEL_PAD_IN
# above a panel: the y axis' offset text (×10ⁿ, +c) of a tick label's height and pads
_GAP_IN = 0.1 + _LINE * _TICK_PT * _PT_IN
# above a panel with a title: the title's line (9 pt) above the offset text
_TITLED_GAP_IN = _GAP_IN + 0.08 + _LINE * 9.0 * _PT_IN
# above the panels: the figure title's line (10 pt) and a margin
_SUPTITLE_IN = 0.1 + _LINE * 10.0 * _PT_IN
_RIGHT_IN = 0.2


def _text_width_in(text: str, size_pt: float) -> float:
    """An upper bound of the width (inches) of a tick label in DejaVu Sans: advance widths
    0.636 em for digits, 0.318 em for ``.`` and ``,``, at most 0.84 em for any other glyph;
    mathtext markup (``$\\mathdefault{10^{3}}$``) counted by its shown characters,
    superscripts at 0.7 em."""
    em = 0.0
    superscript = False
    for part in text.replace("\\mathdefault", "").replace("\\times", "×").split("^"):
        for char in part:
            if char in "${}\\":
                continue
            width = 0.64 if char.isdigit() else 0.32 if char in ".," else 0.84
            em += 0.7 * width if superscript else width
        superscript = True
    return em * size_pt * _PT_IN


def _tick_labels(axis) -> tuple[list[str], str]:
    """The tick labels an axis will show (major, and minor where it labels them) and its
    offset text (``×10⁻³``, ``+1.1e4``; empty when none)."""
    from matplotlib.ticker import NullFormatter, NullLocator

    low, high = sorted(axis.get_view_interval())
    slack = 1e-9 * (high - low)
    labels: list[str] = []
    offset = ""
    for ticker in (axis.major, axis.minor):
        if isinstance(ticker.locator, NullLocator) or isinstance(ticker.formatter, NullFormatter):
            continue
        locations = [v for v in ticker.locator() if low - slack <= v <= high + slack]
        labels += [label for label in ticker.formatter.format_ticks(locations) if label]
        if ticker is axis.major:
            offset = ticker.formatter.get_offset() if locations else ""
    return labels, offset


def _y_tick_width_in(ax) -> float:
    """The width (inches) of the widest y tick label the panel will show."""
    labels, _ = _tick_labels(ax.yaxis)
    return max((_text_width_in(label, _TICK_PT) for label in labels), default=0.0)


def _left_in(panels) -> float:
    """The margin (inches) left of a column of panels: its y labels and tick labels."""
    return _LEFT_FIXED_IN + max((_y_tick_width_in(ax) for ax in panels), default=0.0)


def _fix_text_positions(figure: Figure) -> None:
    """Place every panel's axis labels and titles where matplotlib would, from the tick
    label widths (``_text_width_in``) rather than from measured text: the y label beside
    the widest tick label, the x label under the tick labels, a title above the y offset
    text where there is one. Matplotlib then does not measure every tick label of the
    panel, and of every panel sharing its axes, when it draws."""
    width, height = figure.get_size_inches()
    for ax in figure.axes:
        box = ax.get_position()
        panel_width_in, panel_height_in = box.width * width, box.height * height
        labels, offset = _tick_labels(ax.yaxis)
        if ax.get_ylabel():
            tick_width_in = max((_text_width_in(t, _TICK_PT) for t in labels), default=0.0)
            # the label's right edge (its baseline side, rotated): pad + labels + ticks
            x_in = _TICK_SPACE_IN + tick_width_in + _LABEL_PAD_IN
            ax.yaxis.set_label_coords(-x_in / panel_width_in, 0.5)
        if ax.get_xlabel():
            # the label's top: below the tick marks, a tick label line and the pad
            y_in = _TICK_SPACE_IN + _LINE * _TICK_PT * _PT_IN + _LABEL_PAD_IN
            ax.xaxis.set_label_coords(0.5, -y_in / panel_height_in)
        # a title 6 pt above the panel, or above the y offset text (7 pt high, 3 pt pad)
        pad_pt = 6.0 + (_LINE * _TICK_PT + 3.0 if offset else 0.0)
        for loc in ("left", "center", "right"):
            text = ax.get_title(loc)
            if text:
                size = {"left": ax._left_title, "center": ax.title, "right": ax._right_title}
                fontsize = size[loc].get_fontsize()
                ax.set_title(text, loc=loc, y=1.0, pad=pad_pt, fontsize=fontsize)


# the grid lines (matplotlib's grid colour)
_GRID_STYLE = {"colors": "#b0b0b0", "linewidth": 0.4, "alpha": 0.5}


class _ViewTicks(MaxNLocator):
    """``MaxNLocator``'s ticks inside the view interval only: matplotlib makes a tick object
    (two lines, a grid line, two texts) for every location a locator returns, and
    ``MaxNLocator`` returns one beyond each end of the view as well."""

    def __call__(self) -> np.ndarray:
        low, high = sorted(self.axis.get_view_interval())
        locations = np.asarray(super().__call__())
        slack = 1e-9 * (high - low)
        return locations[(locations >= low - slack) & (locations <= high + slack)]


def _style_panel(ax, y_bins: int = 4) -> None:
    """Few y ticks, small tick labels, a light grid along y (per panel, before its ticks
    exist)."""
    ax.yaxis.set_major_locator(_ViewTicks(nbins=y_bins, steps=[1, 2, 2.5, 5, 10]))
    ax.tick_params(labelsize=_TICK_PT)
    ax.grid(True, axis="y", linewidth=0.4, alpha=0.5)


def _place(ax, figure: Figure, left_in: float, bottom_in: float, width_in: float, height_in):
    """Put a panel at a rectangle given in inches from the figure's lower left corner."""
    width, height = figure.get_size_inches()
    ax.set_position([left_in / width, bottom_in / height, width_in / width, height_in / height])


def _time_ticks(low: float, high: float, integer: bool = False) -> np.ndarray:
    """About six round tick values within [low, high] (whole numbers with ``integer``)."""
    steps = [1, 2, 5, 10] if integer else [1, 2, 2.5, 5, 10]
    locator = MaxNLocator(nbins=8 if integer else 7, steps=steps, integer=integer)
    ticks = locator.tick_values(low, high)
    slack = 1e-9 * (high - low)
    return ticks[(ticks >= low - slack) & (ticks <= high + slack)]


def _common_x_axis(panels, low: float, high: float, labelled, integer: bool = False) -> None:
    """The panels' common x axis [low, high] with the same ticks in each: tick marks and
    labels on the ``labelled`` panels; a vertical grid line at each tick in every panel,
    drawn as one line collection (an inner panel then needs no tick objects, which cost
    most of a figure's drawing time)."""
    from matplotlib.ticker import FixedLocator, NullLocator

    if not high > low:
        high = low + 1.0
    ticks = _time_ticks(low, high, integer)
    for ax in panels:
        ax.set_xlim(low, high)
        if ax in labelled:
            ax.xaxis.set_major_locator(FixedLocator(ticks))
            ax.grid(True, axis="x", linewidth=0.4, alpha=0.5)
        else:
            ax.xaxis.set_major_locator(NullLocator())
            ax.vlines(
                ticks, 0.0, 1.0, transform=ax.get_xaxis_transform(), zorder=1.5, **_GRID_STYLE
            )


def maneuver_figure(
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
) -> Figure:
    """One maneuver: the inputs on top (full width), then per output the measured (+) and
    predicted (line) response on the left and the residual z − y on the right, against the
    time from the maneuver's first sample.

    Args:
        time: the sample times (N,), s (absolute; shown as t − t₀).
        inputs: the inputs (N, n_u) in the inputs' units, or None.
        input_names: the names of the input columns (n_u).
        measured: the measured outputs (N, n_o) in the outputs' units.
        predicted: the model's outputs (N, n_o) in the outputs' units.
        output_names: the names of the output columns (n_o).
        units: the unit of each channel, as a mapping from channel name to unit.
        title: the figure's title.
        input_steps: draw the inputs as held steps (zero-order-hold interpolation).
        dpi: the resolution the figure will be rendered at: each time history is then
            drawn through its min/max envelope per pixel column of its panel
            (``envelope_indices``), no more points than the pixels show, every peak kept.
            None: every sample is drawn.

    Returns:
        The matplotlib figure (not yet saved).
    """
    time = np.asarray(time, dtype=float)
    n = time.shape[0]
    t0 = float(time[0]) if n else 0.0
    time = time - t0
    z = _as_matrix(measured, n, "measured")
    y = _as_matrix(predicted, n, "predicted")
    u = None if inputs is None or not len(input_names) else _as_matrix(inputs, n, "inputs")
    n_u = 0 if u is None else u.shape[1]
    n_o = len(output_names)
    # panel heights (inches): an input 0.8, an output 1.15; the gaps above each row
    input_in, output_in = 0.8, 1.15
    gaps = [_TITLED_GAP_IN if k in (0, n_u) else _GAP_IN for k in range(n_u + n_o)]
    heights = [input_in] * n_u + [output_in] * n_o
    figure_height = _SUPTITLE_IN + sum(gaps) + sum(heights) + _BOTTOM_IN
    figure = Figure(figsize=(MANEUVER_FIGURE_WIDTH_IN, figure_height))
    width_px = None if dpi is None else MANEUVER_FIGURE_WIDTH_IN * dpi
    input_panels = []
    for i in range(n_u):
        ax = figure.add_axes((0, 0, 1, 1))
        shown = _shown(u[:, i], width_px)
        ax.plot(
            time[shown],
            u[shown, i],
            color="k",
            linewidth=1.1,
            drawstyle="steps-post" if input_steps else "default",
        )
        ax.set_ylabel(axis_label(input_names[i], units.get(input_names[i])), fontsize=_LABEL_PT)
        ax.set_facecolor("#f6f6ee")
        if i == 0:
            ax.set_title("inputs", fontsize=9, loc="left")
        input_panels.append(ax)
    # the output panels take 3/5 of the width, the residual panels 2/5
    output_panels, residual_panels = _output_rows(
        figure,
        time,
        z,
        y,
        output_names,
        units,
        None if width_px is None else (0.6 * width_px, 0.4 * width_px),
        t0,
    )
    bottom_row = {output_panels[-1], residual_panels[-1]} if n_o else set(figure.axes[-1:])
    for ax in figure.axes:
        _style_panel(ax, y_bins=3 if ax in input_panels else 4)
    # the time tick labels only under the bottom row
    span = (float(time[0]), float(time[-1])) if n else (0.0, 1.0)
    _common_x_axis(figure.axes, *span, bottom_row)
    _place_maneuver_panels(figure, input_panels, output_panels, residual_panels, heights, gaps)
    _fix_text_positions(figure)
    figure.suptitle(title, fontsize=10, y=1.0 - 0.06 / figure_height, va="top")
    return figure


def _output_rows(figure, time, z, y, output_names, units, widths_px, t0: float):
    """Per output a panel of the measured (+) and predicted (line) response and one of the
    residual z − y; the panels' widths in pixels (output, residual) choose the samples
    drawn (None: all). Returns the output panels and the residual panels."""
    output_panels, residual_panels = [], []
    output_px, residual_px = widths_px or (None, None)
    last = len(output_names) - 1
    for j, name in enumerate(output_names):
        ax = figure.add_axes((0, 0, 1, 1))
        shown = _shown(z[:, j], output_px)
        ax.plot(time[shown], z[shown, j], label="measured z", **_MEASURED_STYLE)
        shown = _shown(y[:, j], output_px)
        ax.plot(time[shown], y[shown, j], label="predicted y", **_PREDICTED_STYLE)
        ax.set_ylabel(axis_label(name, units.get(name)), fontsize=_LABEL_PT)
        res = figure.add_axes((0, 0, 1, 1))
        residual = z[:, j] - y[:, j]
        shown = _shown(residual, residual_px)
        res.plot(time[shown], residual[shown], color="tab:red", linewidth=0.8)
        res.axhline(0.0, color="k", linewidth=0.5)
        res.set_ylabel(axis_label("z − y", units.get(name)), fontsize=_LABEL_PT)
        if j == 0:
            ax.set_title("outputs: measured vs predicted", fontsize=9, loc="left")
            res.set_title("residuals", fontsize=9, loc="left")
            ax.legend(fontsize=7, loc="upper right", frameon=False, ncol=2)
        if j == last:
            ax.set_xlabel(f"t − t₀ [s]   (t₀ = {t0:g} s)", fontsize=_LABEL_PT)
            res.set_xlabel("t − t₀ [s]", fontsize=_LABEL_PT)
        output_panels.append(ax)
        residual_panels.append(res)
    return output_panels, residual_panels


def _place_maneuver_panels(figure, input_panels, output_panels, residual_panels, heights, gaps):
    """The rows top down (``heights``, ``gaps`` above each, inches); the left column's
    margin fits the widest y tick labels of the inputs and outputs, the residual column's
    its own."""
    width, height = figure.get_size_inches()
    left = _left_in(input_panels + output_panels)
    residual_left = _left_in(residual_panels)
    usable = width - left - _RIGHT_IN
    # the output column takes 3/5 of the width right of the margin, the residual column
    # the rest after its own margin
    output_width = max(0.6 * usable, 1.0)
    residual_width = max(usable - output_width - residual_left, 0.5)
    top = height - _SUPTITLE_IN
    rows = [[ax] for ax in input_panels] + [
        [a, b] for a, b in zip(output_panels, residual_panels, strict=True)
    ]
    for row, row_height, gap in zip(rows, heights, gaps, strict=True):
        top -= gap + row_height
        if len(row) == 1:
            _place(row[0], figure, left, top, usable, row_height)
        else:
            _place(row[0], figure, left, top, output_width, row_height)
            _place(
                row[1], figure, left + output_width + residual_left, top, residual_width, row_height
            )


def _stems(ax, x: np.ndarray, heights: np.ndarray, color: str) -> None:
    """Vertical lines from 0 to each height, as one line broken by NaN (a line collection
    makes one path object per stem: 0.1 s for a figure of 7 × 376 lags)."""
    # x, x, NaN and 0, height, NaN per stem
    xs = np.repeat(np.asarray(x, dtype=float), 3)
    ys = np.zeros_like(xs)
    xs[2::3] = np.nan
    ys[1::3] = heights
    ys[2::3] = np.nan
    ax.plot(xs, ys, color=color, linewidth=1.2, solid_capstyle="butt")


def autocorrelation_figure(
    rho: np.ndarray, band: float, dt: float, names: Sequence[str], lag_used: int | None = None
) -> Figure:
    """Residual autocorrelation ρ_o(k) per output against the lag in seconds, with the
    white-noise band ±1.96/√N; ``lag_used`` marks the coloured-residual correction's L."""
    rho = np.asarray(rho, dtype=float)
    lags_s = np.arange(rho.shape[0]) * dt
    columns = min(len(names), 3)
    rows = -(-len(names) // columns)
    panel_width_in, panel_height_in = 3.0, 1.6
    panels = []
    figure = Figure(figsize=(1.0, 1.0))
    for j, name in enumerate(names):
        ax = figure.add_axes((0, 0, 1, 1))
        outside = np.abs(rho[:, j]) > band
        outside[0] = False
        # a stem per lag: inside the band blue, outside red
        _stems(ax, lags_s[~outside], rho[~outside, j], "tab:blue")
        _stems(ax, lags_s[outside], rho[outside, j], "tab:red")
        ax.axhspan(-band, band, color="0.85", zorder=0, label="±1.96/√N")
        ax.axhline(0.0, color="k", linewidth=0.5)
        if lag_used:
            ax.axvline(
                lag_used * dt,
                color="tab:orange",
                linestyle="--",
                linewidth=0.9,
                label=f"correction lag L = {lag_used}",
            )
        ax.set_title(f"{name}: {int(outside.sum())} of {len(rho) - 1} lags outside", fontsize=8)
        ax.set_ylim(min(-0.3, rho[:, j].min() - 0.05), 1.05)
        _style_panel(ax)
        # the lag axis is labelled under the lowest panel of each column only
        lowest = j + columns >= len(names)
        if lowest:
            ax.set_xlabel("lag [s]", fontsize=_LABEL_PT)
        if j % columns == 0:
            ax.set_ylabel("ρ(k) [–]", fontsize=_LABEL_PT)
        if j == 0:
            ax.legend(fontsize=7, frameon=False, loc="upper right")
        panels.append(ax)
    labelled = [ax for j, ax in enumerate(panels) if j + columns >= len(names)]
    _common_x_axis(panels, 0.0, float(lags_s[-1]) if lags_s.size else 1.0, labelled)
    # columns share one left margin: the widest y tick labels of all panels
    left = _left_in(panels)
    gap = 0.1 + _TITLED_GAP_IN - _GAP_IN + _GAP_IN
    width_in = columns * (left + panel_width_in) + _RIGHT_IN
    height_in = _SUPTITLE_IN + rows * (gap + panel_height_in) + _BOTTOM_IN
    figure.set_size_inches(width_in, height_in)
    for j, ax in enumerate(panels):
        row, column = divmod(j, columns)
        bottom = height_in - _SUPTITLE_IN - (row + 1) * (gap + panel_height_in)
        _place(
            ax,
            figure,
            column * (left + panel_width_in) + left,
            bottom,
            panel_width_in,
            panel_height_in,
        )
    _fix_text_positions(figure)
    figure.suptitle("residual autocorrelation", fontsize=10, y=1.0 - 0.06 / height_in, va="top")
    return figure


def cost_history_figure(
    costs: Sequence[float],
    noise_update_passes: Sequence[int] = (),
    title: str = "cost history",
    log_det_r: Sequence[float] = (),
) -> Figure:
    """Convergence per recorded pass: ln det R̂ of the pass's residuals (top panel, when
    ``log_det_r`` has a finite entry per pass) and the cost J at fixed R (log scale, one line
    per stretch under one R), a dashed line at each R re-estimation in both.

    ln det R̂ does not depend on the R that weights J, so it runs on across R updates and
    shows convergence where the cost, recomputed under each new R, jumps.
    """
    costs = np.asarray(costs, dtype=float)
    log_det_r = np.asarray(log_det_r, dtype=float)
    with_log_det = log_det_r.size == costs.size and bool(np.any(np.isfinite(log_det_r)))
    panel_height_in, width_in = 2.0, 6.5
    count = 2 if with_log_det else 1
    figure = Figure(figsize=(width_in, 1.0))
    # top down: ln det R̂ (where shown), the cost
    axes = [figure.add_axes((0, 0, 1, 1)) for _ in range(count)]
    passes = np.arange(costs.size)
    if with_log_det:
        finite = np.isfinite(log_det_r)
        axes[0].plot(passes[finite], log_det_r[finite], "o-", markersize=3.5, color="tab:green")
        axes[0].set_ylabel("ln det R̂ [–]", fontsize=_LABEL_PT)
        axes[0].set_title(title, fontsize=9)
    ax = axes[-1]
    # one line per stretch under one R: a cost under a new R is not comparable with the last
    edges = sorted({0, costs.size, *(p for p in noise_update_passes if 0 < p < costs.size)})
    for a, b in zip(edges[:-1], edges[1:], strict=False):
        part = slice(a, b)
        positive = costs[part] > 0
        ax.semilogy(
            passes[part][positive], costs[part][positive], "o-", markersize=3.5, color="tab:blue"
        )
    for axis in axes:
        for k, p in enumerate(noise_update_passes):
            axis.axvline(
                p - 0.5,
                color="tab:orange",
                linestyle="--",
                linewidth=1.0,
                label="R re-estimated" if k == 0 else None,
            )
        axis.tick_params(which="both", labelsize=_TICK_PT)
        axis.grid(True, axis="y", which="both", linewidth=0.3)
    if with_log_det:
        axes[0].yaxis.set_major_locator(_ViewTicks(nbins=6, steps=[1, 2, 2.5, 5, 10]))
    # whole passes on the pass axis, labelled under the cost panel
    # (an R re-estimation after the last pass, at size − 0.5, inside the view)
    _common_x_axis(axes, -0.7, costs.size - 0.3, [ax], integer=True)
    if len(noise_update_passes):
        axes[0].legend(fontsize=7, frameon=False)
    ax.set_xlabel("pass [–]", fontsize=_LABEL_PT)
    ax.set_ylabel("cost J at fixed R = Σ νᵀR⁻¹ν [–]", fontsize=_LABEL_PT)
    if not with_log_det:
        ax.set_title(title, fontsize=9)
    left = _left_in(axes)
    # the title above the top panel, an offset text's room above the second
    height_in = 0.1 + _TITLED_GAP_IN + count * panel_height_in + (count - 1) * _GAP_IN
    height_in += _BOTTOM_IN
    figure.set_size_inches(width_in, height_in)
    top = height_in - 0.1 - _TITLED_GAP_IN
    for axis in axes:
        _place(
            axis, figure, left, top - panel_height_in, width_in - left - _RIGHT_IN, panel_height_in
        )
        top -= panel_height_in + _GAP_IN
    _fix_text_positions(figure)
    return figure
