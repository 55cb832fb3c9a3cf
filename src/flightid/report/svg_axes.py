"""The parts of an SVG figure written straight from arrays: round ticks and their labels,
panels (frame, grid, axis labels), lines drawn through their min/max envelope per pixel
column, ``+`` markers and stems as one path each. numpy and the standard library only: the
report's figures (``flightid.report.svg_figures``) cost a few milliseconds each and no
matplotlib import.

Coordinates are SVG pixels (96 per inch), y downwards. A panel's data are drawn inside a
nested ``<svg>`` element at the panel's rectangle (``overflow='hidden'`` clips them) whose
``data-xlim`` and ``data-ylim`` attributes give the data limits the rectangle spans (``log``
in ``data-yscale`` for a logarithmic y axis): point (px, py) inside it is the datum
x = x₀ + px·(x₁ − x₀)/width, y = y₁ − py·(y₁ − y₀)/height.
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "Panel",
    "YScale",
    "axis_label",
    "envelope_indices",
    "escape",
    "log_scale",
    "nice_ticks",
    "tick_labels",
    "y_scale",
]

PX_PER_IN = 96.0
# font sizes (px): tick labels, axis labels, panel titles, figure titles (matplotlib's 7, 8,
# 9 and 10 pt at 96 dpi)
TICK_PX = 9.3
LABEL_PX = 10.7
TITLE_PX = 12.0
SUPTITLE_PX = 13.3
FONT = "DejaVu Sans, Arial, Helvetica, sans-serif"
GRID = "stroke='#b0b0b0' stroke-width='0.5' stroke-opacity='0.6'"
MINUS = "\u2212"
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")
# the steps of a round tick interval (× 10^k), as matplotlib's MaxNLocator
_STEPS = (1.0, 2.0, 2.5, 5.0, 10.0)
_INTEGER_STEPS = (1.0, 2.0, 5.0, 10.0)


def escape(text: object) -> str:
    """Text safe inside an SVG/HTML element or a quoted attribute (``<``, ``&``, quotes)."""
    return html.escape(str(text), quote=True)


def axis_label(name: str, unit: str | None) -> str:
    """``"alpha [rad]"``; a channel without a known unit shows ``[?]`` rather than nothing."""
    unit = (unit or "?").replace("^2", "²").replace("^3", "³")
    return f"{name} [{unit}]"


def envelope_indices(values: np.ndarray, bins: int) -> np.ndarray:
    """The sample indices that keep the look of a time history drawn ``bins`` pixels wide:
    per pixel column (``bins`` equal runs of consecutive samples) the sample of the smallest
    and of the largest value, in time order (min/max envelope decimation). Every pixel
    column's extremes, and so every peak, are kept; the line through them covers the same
    pixels as the line through all samples. All indices when there are at most two samples
    per column. NaN samples are kept (they break the line as before).

    Args:
        values: the samples (N,) of one channel.
        bins: the plot's width in pixels (≥ 1).

    Returns:
        Increasing indices into ``values`` (at most 2·bins plus the NaN samples).
    """
    values = np.asarray(values, dtype=float)
    n = values.shape[0]
    bins = max(int(bins), 1)
    if n <= 2 * bins:
        return np.arange(n)
    # bin b holds the samples [edges[b], edges[b + 1])
    edges = (np.arange(bins + 1) * n) // bins
    finite = np.where(np.isfinite(values), values, np.nan)
    lows = np.fmin.reduceat(np.where(np.isnan(finite), np.inf, finite), edges[:-1])
    highs = np.fmax.reduceat(np.where(np.isnan(finite), -np.inf, finite), edges[:-1])
    owner = np.repeat(np.arange(bins), np.diff(edges))
    # the first sample of each bin equal to its minimum, and to its maximum
    is_low = values == lows[owner]
    is_high = values == highs[owner]
    first_low = np.full(bins, -1)
    first_high = np.full(bins, -1)
    index = np.arange(n)
    # reversed assignment leaves the first matching index of each bin
    first_low[owner[is_low][::-1]] = index[is_low][::-1]
    first_high[owner[is_high][::-1]] = index[is_high][::-1]
    keep = np.concatenate([first_low, first_high, index[np.isnan(values)]])
    return np.unique(keep[keep >= 0])


# ------------------------------------------------------------------------------ ticks


def _step_candidates(raw: float, integer: bool) -> list[float]:
    """Round intervals from the smallest not below ``raw`` downwards: 1, 2, 2.5, 5 × 10^k
    (1, 2, 5 × 10^k, at least 1, with ``integer``)."""
    steps = _INTEGER_STEPS if integer else _STEPS
    scale = 10.0 ** math.floor(math.log10(raw))
    k = next(i for i, s in enumerate(steps) if s * scale >= raw * (1 - 1e-12))
    candidates = [steps[k] * scale]
    candidates += [s * scale for s in reversed(steps[:k])] + [s * scale / 10 for s in steps[-2::-1]]
    return [c for c in candidates if c >= 1.0] or [1.0] if integer else candidates


def nice_ticks(low: float, high: float, bins: int = 4, integer: bool = False) -> np.ndarray:
    """Round tick values inside [low, high]: the interval is the smallest 1, 2, 2.5 or
    5 × 10^k (1, 2 or 5 × 10^k, at least 1, with ``integer``) not below (high − low)/bins,
    as matplotlib's ``MaxNLocator``, so at most ``bins + 1`` ticks; where that leaves fewer
    than three inside, the next smaller round interval (up to twice)."""
    low, high = float(low), float(high)
    if not (math.isfinite(low) and math.isfinite(high)) or not high > low:
        return np.array([low]) if math.isfinite(low) else np.zeros(0)
    raw = (high - low) / max(int(bins), 1)
    ticks = np.zeros(0)
    for step in _step_candidates(raw, integer)[:3]:
        first = math.ceil(low / step - 1e-9)
        last = math.floor(high / step + 1e-9)
        ticks = np.arange(first, last + 1) * step
        # 0.1 · 3 is 0.30000000000000004: rounded to the interval's decimals
        ticks = np.round(ticks, max(0, 12 - math.floor(math.log10(step))))
        if ticks.size >= 3:
            break
    return ticks


def _superscript(exponent: int) -> str:
    return str(exponent).translate(_SUPERSCRIPT)


def _decimals(step: float) -> int:
    """The decimal places that show every multiple of ``step`` exactly (2.5 needs one)."""
    places = 0
    while places < 15 and abs(round(step, places) - step) > 1e-9 * abs(step):
        places += 1
    return places


def tick_labels(ticks: np.ndarray) -> tuple[list[str], str]:
    """The labels of round ticks and the axis' offset text, as matplotlib's ScalarFormatter
    writes them: an offset (``+1.1×10⁴``) subtracted where the labels would otherwise need
    more than four significant digits to tell the ticks apart, a multiplier (``×10⁻⁶``)
    where the largest label is below 10⁻⁴ or at least 10⁵; minus signs as ``−``."""
    ticks = np.asarray(ticks, dtype=float)
    if ticks.size == 0:
        return [], ""
    step = float(np.min(np.diff(ticks))) if ticks.size > 1 else abs(float(ticks[0])) or 1.0
    offset = 0.0
    largest = float(np.max(np.abs(ticks)))
    if ticks.size > 1 and largest / step >= 1e4:
        # the offset: the ticks' common leading digits (a multiple of 10^m above the span)
        power = 10.0 ** math.ceil(math.log10(float(ticks[-1] - ticks[0]) + step))
        offset = math.floor(float(ticks[0]) / power) * power
    shown = ticks - offset
    top = float(np.max(np.abs(shown))) or 1.0
    exponent = math.floor(math.log10(top))
    exponent = exponent if exponent < -4 or exponent >= 5 else 0
    scale = 10.0**exponent
    decimals = _decimals(step / scale)
    labels = [f"{v / scale:.{decimals}f}" for v in shown]
    # no "−0.0": a zero shows unsigned
    labels = [(t.lstrip("-") if float(t) == 0 else t).replace("-", MINUS) for t in labels]
    text = f"×10{_superscript(exponent)}" if exponent else ""
    if offset:
        sign = "+" if offset > 0 else MINUS
        text += f"{sign}{abs(offset):.6g}".replace("e+0", "e").replace("e+", "e")
    return labels, text


def text_width_px(text: str, size_px: float) -> float:
    """An upper bound of the width (px) of a label in DejaVu Sans: 0.64 em a digit, 0.32 em
    for ``.`` and ``,``, at most 0.84 em any other glyph."""
    em = sum(0.64 if c.isdigit() else 0.32 if c in ".," else 0.84 for c in text)
    return em * size_px


@dataclass
class YScale:
    """A y axis: its limits (log10 of the values on a log axis), tick positions (in the
    same units), their labels and the offset/multiplier text."""

    low: float
    high: float
    ticks: np.ndarray
    labels: list[str]
    offset: str = ""
    log: bool = False

    def label_width_px(self) -> float:
        return max((text_width_px(t, TICK_PX) for t in self.labels), default=0.0)


def data_limits(values: np.ndarray, margin: float = 0.05) -> tuple[float, float]:
    """The finite values' range widened by ``margin`` of it on each side (matplotlib's
    default margins); a flat series gets ±5 % of its size (±1 at zero)."""
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return -1.0, 1.0
    low, high = float(values.min()), float(values.max())
    if high == low:
        pad = 0.05 * abs(low) or 1.0
        return low - pad, high + pad
    pad = margin * (high - low)
    return low - pad, high + pad


def y_scale(values: np.ndarray, bins: int = 4, limits: tuple | None = None) -> YScale:
    """A linear y axis over the values (or the given limits) with round ticks."""
    low, high = limits if limits is not None else data_limits(values)
    ticks = nice_ticks(low, high, bins)
    labels, offset = tick_labels(ticks)
    return YScale(low, high, ticks, labels, offset)


def log_scale(values: np.ndarray) -> YScale:
    """A logarithmic y axis over the positive values: ticks at the decades inside, or at
    1, 2, 3 and 5 × 10^k where fewer than two decades are inside."""
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values) & (values > 0)]
    if values.size == 0:
        values = np.array([1.0])
    low, high = data_limits(np.log10(values))
    decades = np.arange(math.ceil(low), math.floor(high) + 1)
    ticks = [(float(k), f"10{_superscript(int(k))}") for k in decades]
    if len(ticks) < 2:
        decades = range(math.floor(low), math.ceil(high) + 1)
        candidates = [m * 10.0**k for k in decades for m in (1, 2, 3, 5)]
        inside = sorted(v for v in candidates if low <= math.log10(v) <= high)
        ticks = [(math.log10(v), f"{v:g}".replace("-", MINUS)) for v in inside]
    if len(ticks) < 2:
        linear = nice_ticks(10.0**low, 10.0**high, 3)
        labels, _ = tick_labels(linear)
        ticks = [(math.log10(v), t) for v, t in zip(linear, labels, strict=True) if v > 0]
    return YScale(low, high, np.array([t[0] for t in ticks]), [t[1] for t in ticks], "", log=True)


# ------------------------------------------------------------------------------ panels


@dataclass
class Panel:
    """A panel's rectangle in the figure (px) and the data limits it spans."""

    left: float
    top: float
    width: float
    height: float
    x0: float
    x1: float
    y: YScale
    parts: list[str] = field(default_factory=list)

    def px(self, x: np.ndarray) -> np.ndarray:
        """x in data units → px from the panel's left edge."""
        span = self.x1 - self.x0 or 1.0
        return (np.asarray(x, dtype=float) - self.x0) * (self.width / span)

    def py(self, y: np.ndarray) -> np.ndarray:
        """y in data units → px from the panel's top edge (log10 first on a log axis)."""
        y = np.asarray(y, dtype=float)
        if self.y.log:
            with np.errstate(divide="ignore", invalid="ignore"):
                y = np.log10(y)
        span = self.y.high - self.y.low or 1.0
        return (self.y.high - y) * (self.height / span)

    def ty(self, position: float) -> float:
        """A tick position (log10 on a log axis) → px from the top edge."""
        return (self.y.high - position) * (self.height / (self.y.high - self.y.low or 1.0))


def _pairs(x: np.ndarray, y: np.ndarray) -> str:
    xy = np.empty(2 * x.size)
    xy[0::2], xy[1::2] = x, y
    return ("%.1f,%.1f " * x.size % tuple(xy)).rstrip()


def _runs(finite: np.ndarray) -> list[tuple[int, int]]:
    """The [start, stop) of each run of True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], finite.astype(np.int8), [0]])))
    return list(zip(edges[0::2].tolist(), edges[1::2].tolist(), strict=True))


def polyline(
    panel: Panel, x, y, colour: str, width: float = 1.2, steps: bool = False, dash: str = ""
) -> None:
    """A line through (x, y), drawn through its envelope per pixel column of the panel
    (every peak kept), broken at NaN; ``steps``: held steps (each value until the next
    sample)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    keep = envelope_indices(y, int(math.ceil(panel.width)))
    px, py = panel.px(x[keep]), panel.py(y[keep])
    if steps and px.size > 1:
        # steps-post: (x_i, y_i) → (x_{i+1}, y_i) → (x_{i+1}, y_{i+1})
        px = np.repeat(px, 2)[1:]
        py = np.repeat(py, 2)[:-1]
    style = f" stroke-dasharray='{dash}'" if dash else ""
    for start, stop in _runs(np.isfinite(py) & np.isfinite(px)):
        panel.parts.append(
            f"<polyline fill='none' stroke='{colour}' stroke-width='{width}'{style} "
            f"stroke-linejoin='round' points='{_pairs(px[start:stop], py[start:stop])}'/>"
        )


def markers(panel: Panel, x, y, colour: str, size: float = 5.0, circles: bool = False) -> None:
    """A ``+`` marker (or a dot with ``circles``) at each finite (x, y), as one path;
    drawn at the envelope's samples where they are denser than the pixels."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    keep = envelope_indices(y, int(math.ceil(panel.width)))
    px, py = panel.px(x[keep]), panel.py(y[keep])
    finite = np.isfinite(px) & np.isfinite(py)
    px, py = px[finite], py[finite]
    if not px.size:
        return
    half = 0.5 * size
    xy = np.empty(2 * px.size)
    if circles:
        xy[0::2], xy[1::2] = px - half, py
        shape = f"M%.1f %.1fa{half:g} {half:g} 0 1 0 {size:g} 0a{half:g} {half:g} 0 1 0 -{size:g} 0"
        paint = f"fill='{colour}' stroke='none'"
    else:
        xy[0::2], xy[1::2] = px - half, py
        shape = f"M%.1f %.1fh{size:g}m-{half:g} -{half:g}v{size:g}"
        paint = f"fill='none' stroke='{colour}' stroke-width='0.8'"
    panel.parts.append(f"<path {paint} d='{shape * px.size % tuple(xy)}'/>")


def stems(panel: Panel, x, heights, colour: str) -> None:
    """A vertical line from 0 to each height, as one path."""
    px, py = panel.px(x), panel.py(heights)
    if not px.size:
        return
    base = float(panel.py(0.0))
    xy = np.empty(3 * px.size)
    xy[0::3], xy[1::3], xy[2::3] = px, base, py - base
    path = "M%.1f %.1fv%.1f" * px.size % tuple(xy)
    panel.parts.append(f"<path fill='none' stroke='{colour}' stroke-width='1.2' d='{path}'/>")


def hline(panel: Panel, y: float, colour: str, width: float = 0.6, dash: str = "") -> None:
    style = f" stroke-dasharray='{dash}'" if dash else ""
    panel.parts.append(
        f"<path d='M0 {float(panel.py(y)):.1f}h{panel.width:.1f}' stroke='{colour}' "
        f"stroke-width='{width}'{style}/>"
    )


def vline(panel: Panel, x: float, colour: str, width: float = 0.9, dash: str = "") -> None:
    style = f" stroke-dasharray='{dash}'" if dash else ""
    panel.parts.append(
        f"<path d='M{float(panel.px(x)):.1f} 0v{panel.height:.1f}' stroke='{colour}' "
        f"stroke-width='{width}'{style}/>"
    )


def band(panel: Panel, low: float, high: float, colour: str) -> None:
    """A horizontal band between two y values, under the data."""
    top, bottom = float(panel.py(high)), float(panel.py(low))
    panel.parts.insert(
        0,
        f"<rect x='0' y='{top:.1f}' width='{panel.width:.1f}' height='{bottom - top:.1f}' "
        f"fill='{colour}'/>",
    )


def band_between(panel: Panel, x, low, high, colour: str, opacity: float = 0.2) -> None:
    """The region between the curves ``low`` and ``high`` over ``x``, translucent, under the
    data; one polygon per run of finite values (a NaN leaves a gap)."""
    px, lo, hi = panel.px(x), panel.py(low), panel.py(high)
    finite = np.isfinite(px) & np.isfinite(lo) & np.isfinite(hi)
    for start, stop in _runs(finite):
        xs = np.concatenate([px[start:stop], px[start:stop][::-1]])
        ys = np.concatenate([hi[start:stop], lo[start:stop][::-1]])
        panel.parts.insert(
            0,
            f"<polygon fill='{colour}' fill-opacity='{opacity}' stroke='none' "
            f"points='{_pairs(xs, ys)}'/>",
        )


@dataclass
class PanelText:
    """What is written around a panel: the y label, a title (left), the x tick labels and
    x label (under the bottom row only), a legend above the panel's right end as (kind,
    colour, text) with kind ``line``, ``dash``, ``plus``, ``dot`` or ``patch``."""

    ylabel: str = ""
    title: str = ""
    xlabel: str = ""
    x_labelled: bool = False
    legend: tuple = ()
    face: str = "white"


def _text(x: float, y: float, text: str, size: float, anchor: str = "start", extra="") -> str:
    return (
        f"<text x='{x:.1f}' y='{y:.1f}' font-size='{size}' text-anchor='{anchor}'{extra}>"
        f"{escape(text)}</text>"
    )


def legend(right: float, y: float, entries: tuple) -> list[str]:
    """Legend entries (kind, colour, text) in a row ending at ``right``, baseline ``y``."""
    parts = []
    for kind, colour, label in reversed(entries):
        right -= text_width_px(label, TICK_PX) * 0.75
        parts.append(_text(right, y, label, TICK_PX))
        key = right - 22.0
        if kind == "plus":
            sample = f"<path d='M{key + 5:.1f} {y - 3:.1f}h6m-3 -3v6' stroke='{colour}'/>"
        elif kind == "patch":
            sample = f"<rect x='{key:.1f}' y='{y - 7:.1f}' width='16' height='7' fill='{colour}'/>"
        else:
            dash = " stroke-dasharray='4 2'" if kind == "dash" else ""
            sample = (
                f"<path d='M{key:.1f} {y - 3:.1f}h16' stroke='{colour}' stroke-width='1.4'{dash}/>"
            )
        parts.append(sample)
        right = key - 12.0
    return parts


def render_panel(panel: Panel, x_ticks: np.ndarray, x_labels: list[str], text: PanelText) -> str:
    """The panel as SVG: background, grid, its data (``panel.parts``) clipped to the
    rectangle, frame, tick marks and labels, axis labels, title and legend."""
    left, top, width, height = panel.left, panel.top, panel.width, panel.height
    x_px = panel.px(x_ticks)
    y_px = np.array([panel.ty(t) for t in panel.y.ticks])
    grid = "".join(f"M{v:.1f} 0v{height:.1f}" for v in x_px)
    grid += "".join(f"M0 {v:.1f}h{width:.1f}" for v in y_px)
    out = [
        f"<rect x='{left:.1f}' y='{top:.1f}' width='{width:.1f}' height='{height:.1f}' "
        f"fill='{text.face}'/>",
        f"<svg x='{left:.1f}' y='{top:.1f}' width='{width:.1f}' height='{height:.1f}' "
        f"overflow='hidden' data-xlim='{panel.x0!r} {panel.x1!r}' "
        f"data-ylim='{panel.y.low!r} {panel.y.high!r}'"
        + (" data-yscale='log'" if panel.y.log else "")
        + ">",
        f"<path fill='none' {GRID} d='{grid}'/>" if grid else "",
        *panel.parts,
        "</svg>",
        f"<rect x='{left:.1f}' y='{top:.1f}' width='{width:.1f}' height='{height:.1f}' "
        "fill='none' stroke='black' stroke-width='0.8'/>",
    ]
    out += _panel_labels(panel, x_px, y_px, x_labels, text)
    return "\n".join(p for p in out if p)


def _panel_labels(panel: Panel, x_px, y_px, x_labels: list[str], text: PanelText) -> list[str]:
    """Tick marks and labels, the offset text, axis labels, title and legend of a panel."""
    left, top, width, height = panel.left, panel.top, panel.width, panel.height
    out = []
    # tick marks outside the frame: 3.5 px
    marks = "".join(f"M{left:.1f} {top + v:.1f}h-3.5" for v in y_px)
    if text.x_labelled:
        marks += "".join(f"M{left + v:.1f} {top + height:.1f}v3.5" for v in x_px)
    if marks:
        out.append(f"<path d='{marks}' stroke='black' stroke-width='0.8'/>")
    for v, label in zip(y_px, panel.y.labels, strict=True):
        out.append(_text(left - 6.0, top + v + 3.2, label, TICK_PX, "end"))
    if panel.y.offset:
        out.append(_text(left, top - 3.0, panel.y.offset, TICK_PX))
    if text.x_labelled:
        for v, label in zip(x_px, x_labels, strict=True):
            out.append(_text(left + v, top + height + 14.0, label, TICK_PX, "middle"))
    if text.xlabel:
        out.append(_text(left + width / 2, top + height + 30.0, text.xlabel, LABEL_PX, "middle"))
    if text.ylabel:
        x = left - 10.0 - panel.y.label_width_px() - 4.0
        out.append(
            f"<text transform='translate({x:.1f},{top + height / 2:.1f}) rotate(-90)' "
            f"font-size='{LABEL_PX}' text-anchor='middle'>{escape(text.ylabel)}</text>"
        )
    if text.title:
        # above the offset text where there is one
        lift = 16.0 if panel.y.offset else 5.0
        out.append(_text(left, top - lift, text.title, TITLE_PX))
    out += legend(left + width, top - 6.0, text.legend)
    return out


def y_label_margin(scales: list[YScale]) -> float:
    """The room (px) left of a panel for its y label and the widest tick label."""
    return 10.0 + max((s.label_width_px() for s in scales), default=0.0) + 4.0 + LABEL_PX + 6.0


def document(width: float, height: float, body: list[str], title: str = "") -> str:
    """The figure as one ``<svg>`` element (a standalone file, and inline in HTML)."""
    head = (
        f"<svg xmlns='http://www.w3.org/2000/svg' width='{width:.0f}' height='{height:.0f}' "
        f"viewBox='0 0 {width:.0f} {height:.0f}' font-family='{FONT}' "
        "style='max-width:100%;height:auto'>"
    )
    parts = [head, "<rect width='100%' height='100%' fill='white'/>"]
    if title:
        parts.append(_text(width / 2, 20.0, title, SUPTITLE_PX, "middle"))
    return "\n".join([*parts, *body, "</svg>"]) + "\n"
