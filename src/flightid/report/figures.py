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

from flightid.errors import InputError

__all__ = ["plot_measured_vs_predicted", "plot_inputs", "plot_residuals", "plot_time_histories"]

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


def _save(figure: Figure, path: str | Path, dpi: int) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
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
