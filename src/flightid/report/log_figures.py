"""Overview figure of a flight log (``flightid inspect --out``): one panel per chosen
channel against log time, the excitation segments found in it shaded and labelled by kind,
and a strip on top with the flight-mode intervals and system-identification runs."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from flightid.report.figures import _save

__all__ = ["log_overview_figure", "save_log_overview"]

_KIND_COLOURS = {
    "step": "tab:olive",
    "doublet": "tab:orange",
    "3-2-1-1": "tab:red",
    "pulses": "tab:brown",
    "sweep": "tab:green",
    "multisine": "tab:purple",
}


def _mode_strip(ax, modes: Sequence, runs: Sequence, span: tuple[float, float]) -> None:
    names = sorted({m.name for m in modes})
    colours = {n: f"C{k % 10}" for k, n in enumerate(names)}
    low = 0.5 if runs else 0.0  # modes on top, SysID runs below where there are any
    for interval in modes:
        stop = span[1] if math.isinf(interval.stop_s) else interval.stop_s
        ax.axvspan(interval.start_s, stop, low, 1.0, color=colours[interval.name], alpha=0.35)
        ax.text(
            0.5 * (interval.start_s + stop),
            0.5 * (1.0 + low),
            interval.name,
            ha="center",
            va="center",
            fontsize=7,
            clip_on=True,
        )
    for run in runs:
        ax.axvspan(run.start_s, run.stop_s, 0.0, 0.5, color="tab:red", alpha=0.35)
        ax.text(
            0.5 * (run.start_s + run.stop_s),
            0.25,
            f"SysID: {run.axis}",
            ha="center",
            va="center",
            fontsize=7,
            clip_on=True,
        )
    ax.set_yticks([])
    ax.set_ylabel("modes", fontsize=8)
    ax.set_ylim(0, 1)


def log_overview_figure(
    channels: Sequence[tuple[str, np.ndarray, np.ndarray, str]],
    segments: Sequence = (),
    modes: Sequence = (),
    runs: Sequence = (),
    title: str = "",
) -> Figure:
    """The overview: ``channels`` as (name, time s, values, unit); ``segments``
    (``flightid.logs.excitation.Segment``) shaded in the panel of their channel; ``modes``
    (``ModeInterval``) and ``runs`` (``SysIdRun``) in a strip on top where there are any."""
    strip = bool(modes or runs)
    n = max(len(channels), 1)
    ratios = ([0.5] if strip else []) + [1.0] * n
    figure = Figure(figsize=(11.0, 1.6 * n + (0.8 if strip else 0.0) + 0.6))
    axes = figure.subplots(
        len(ratios), 1, sharex=True, squeeze=False, gridspec_kw={"height_ratios": ratios}
    )[:, 0]
    starts = [float(t[0]) for _, t, _, _ in channels if len(t)]
    stops = [float(t[-1]) for _, t, _, _ in channels if len(t)]
    span = (min(starts, default=0.0), max(stops, default=1.0))
    if strip:
        _mode_strip(axes[0], modes, runs, span)
    for ax, (name, t, values, unit) in zip(axes[int(strip) :], channels, strict=False):
        ax.plot(t, values, linewidth=0.7, color="tab:blue")
        for segment in segments:
            if segment.channel != name:
                continue
            colour = _KIND_COLOURS.get(segment.kind, "0.6")
            ax.axvspan(segment.start_s, segment.stop_s, color=colour, alpha=0.25)
            ax.text(
                segment.start_s,
                0.95,
                segment.kind,
                transform=ax.get_xaxis_transform(),
                fontsize=7,
                va="top",
                color=colour,
            )
        ax.set_ylabel(f"{name}\n[{unit or '–'}]", fontsize=7)
        ax.tick_params(labelsize=7)
        ax.grid(True, linewidth=0.4, alpha=0.5)
    axes[-1].set_xlabel("log time [s]", fontsize=8)
    axes[-1].set_xlim(*span)
    if title:
        figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    return figure


def save_log_overview(figure: Figure, path, dpi: int = 110):
    """Write the overview as PNG (or by the suffix's format); returns the path."""
    return _save(figure, path, dpi)
