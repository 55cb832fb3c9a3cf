"""Declared resampling: streams sampled unevenly or at different rates → one uniform grid.

A stream is a set of channels sampled at the same stored instants (a log message, or all
the columns of a table). ``resample_streams`` puts every stream on the grid t_k = k/R
(R the declared rate, Hz):

1. Gaps. A stream's samples are split where the interval exceeds ``max_gap_s`` (default
   ``GAP_INTERVALS`` × the coarser of the stream's median interval and 1/R). Gaps are never
   bridged: the record is cut into segments, the spans that every stream covers without a gap.
2. Anti-alias low-pass, where a stream is faster than R (it may hold content above the
   grid's Nyquist frequency R/2): the stream is interpolated by a cubic spline onto the
   uniform fine grid k/(M·R), M = ⌈1/(h·R)⌉ with h its median interval, filtered by a
   Butterworth low-pass of order ``ANTI_ALIAS_ORDER`` at f_c = ``ANTI_ALIAS_CUTOFF`` · R,
   run forward and backward (``scipy.signal.sosfiltfilt``: zero phase, so no time shift —
   a shift would bias identified time delays; the magnitude is |H(f)|², −6 dB at f_c),
   and read at the grid times, every M-th fine sample. The first and last ≈ 1/f_c s of a
   segment carry the filter's edge transient.
3. A stream not faster than R is linearly interpolated onto the grid: it holds nothing
   above its own Nyquist frequency, which is not above R/2.

Segments with fewer than ``MIN_SEGMENT_SAMPLES`` grid samples are left out and named in the
notes. Every step is described in ``Resampling.notes``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from flightid.data.timebase import TimeBaseError
from flightid.errors import describe

__all__ = [
    "ANTI_ALIAS_ORDER",
    "ANTI_ALIAS_CUTOFF",
    "GAP_INTERVALS",
    "MIN_SEGMENT_SAMPLES",
    "StreamSamples",
    "ResampledSegment",
    "Resampling",
    "check_rate",
    "check_max_gap",
    "stream_spans",
    "resample_span",
    "resample_streams",
]

# Butterworth order of the anti-alias low-pass (applied twice: forward and backward)
ANTI_ALIAS_ORDER = 4
# its cutoff as a fraction of the grid rate R: f_c = 0.4·R, below the grid's Nyquist R/2
ANTI_ALIAS_CUTOFF = 0.4
# default largest bridged interval, in intervals of the coarser of the stream and the grid
GAP_INTERVALS = 4.0
# a segment with fewer grid samples is left out (named in the notes)
MIN_SEGMENT_SAMPLES = 10


@dataclass(frozen=True)
class StreamSamples:
    """One stream as stored: ``time_s`` (n,), strictly increasing, and ``values`` (n, k)."""

    name: str
    time_s: np.ndarray
    values: np.ndarray


@dataclass(frozen=True)
class ResampledSegment:
    """One gap-free segment on the grid: ``time_s`` (m,) = k/R, and per stream its
    (m, k_s) values, in the order of the streams given."""

    time_s: np.ndarray
    values: tuple[np.ndarray, ...]


@dataclass(frozen=True)
class Resampling:
    """The segments of a resampled record and what was done, in words."""

    segments: tuple[ResampledSegment, ...]
    notes: tuple[str, ...]


def _positive(value, where: str, unit: str) -> float:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not (math.isfinite(value) and value > 0)
    ):
        raise TimeBaseError(f"{where}: expected a positive number ({unit}), got {describe(value)}")
    return float(value)


def check_rate(rate_hz, where: str = "resample_hz") -> float:
    """R as a float; a ``TimeBaseError`` unless it is a positive finite number."""
    return _positive(rate_hz, where, "Hz")


def check_max_gap(max_gap_s, where: str = "max_gap_s") -> float | None:
    """The largest bridged interval (s), or None for the default."""
    return None if max_gap_s is None else _positive(max_gap_s, where, "s")


def _median_interval(time_s: np.ndarray) -> float:
    return float(np.median(np.diff(time_s)))


def stream_spans(time_s: np.ndarray, max_gap_s: float) -> list[tuple[int, int]]:
    """Row ranges [i0, i1) of a stream with no interval above ``max_gap_s`` (s), each of at
    least 2 rows."""
    cuts = np.flatnonzero(np.diff(time_s) > max_gap_s) + 1
    edges = [0, *cuts.tolist(), time_s.shape[0]]
    return [(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True) if b - a >= 2]


def _interp_columns(at: np.ndarray, time_s: np.ndarray, values: np.ndarray) -> np.ndarray:
    # x(t) = x_j + (x_{j+1} − x_j)·(t − t_j)/(t_{j+1} − t_j),  t_j ≤ t ≤ t_{j+1}
    return np.column_stack([np.interp(at, time_s, values[:, c]) for c in range(values.shape[1])])


def resample_span(
    time_s: np.ndarray, values: np.ndarray, grid_s: np.ndarray, rate_hz: float
) -> np.ndarray:
    """One gap-free stretch of a stream (``time_s`` (n,), ``values`` (n, k)) at the grid
    times ``grid_s`` = k/R (inside ``time_s[0]..time_s[-1]``).

    Slower than R (median interval h ≥ 1/R): linear interpolation. Faster: the stream is
    interpolated by a cubic spline onto the fine grid k/(M·R), M = ⌈1/(h·R)⌉ (at least the
    stream's own rate, and holding every grid time), low-passed there (zero phase), and
    read at the grid times (every M-th fine sample: no second interpolation).
    """
    from scipy.interpolate import CubicSpline
    from scipy.signal import butter, sosfiltfilt

    values = np.asarray(values, dtype=float).reshape(time_s.shape[0], -1)
    if values.shape[1] == 0:
        return np.zeros((grid_s.shape[0], 0))
    step = _median_interval(time_s)
    if 1.0 / step <= rate_hz * (1 + 1e-9):
        return _interp_columns(grid_s, time_s, values)
    factor = math.ceil(1.0 / (step * rate_hz) - 1e-9)  # M
    fine_rate = factor * rate_hz  # Hz
    first = math.ceil(time_s[0] * fine_rate - 1e-9)
    last = math.floor(time_s[-1] * fine_rate + 1e-9)
    index = np.arange(first, last + 1)
    fine = np.clip(index / fine_rate, time_s[0], time_s[-1])
    uniform = CubicSpline(time_s, values, axis=0)(fine)
    # Butterworth low-pass at f_c = 0.4·R for the sampling rate M·R, run forward and backward
    sos = butter(ANTI_ALIAS_ORDER, ANTI_ALIAS_CUTOFF * rate_hz, fs=fine_rate, output="sos")
    if index.shape[0] >= 2:
        # odd extension over about 6 periods of f_c at each end, against edge transients
        pad = min(math.ceil(6 * fine_rate / (ANTI_ALIAS_CUTOFF * rate_hz)), index.shape[0] - 1)
        uniform = sosfiltfilt(sos, uniform, axis=0, padlen=pad)
    # grid time k/R is fine sample k·M
    rows = np.round(grid_s * rate_hz).astype(np.int64) * factor - first
    return uniform[rows]


def _grid(lo: float, hi: float, rate_hz: float) -> np.ndarray:
    """t_k = k/R for lo ≤ t_k ≤ hi (s)."""
    first = math.ceil(lo * rate_hz - 1e-9)
    last = math.floor(hi * rate_hz + 1e-9)
    return np.arange(first, last + 1) / rate_hz


def _intersect(a: list[tuple[float, float]], b: list[tuple[float, float]]):
    out = []
    for lo_a, hi_a in a:
        for lo_b, hi_b in b:
            lo, hi = max(lo_a, lo_b), min(hi_a, hi_b)
            if lo < hi:
                out.append((lo, hi))
    return sorted(out)


def _stream_note(stream: StreamSamples, rate_hz: float, gap_s: float, spans) -> str:
    steps = np.diff(stream.time_s)
    step = float(np.median(steps))
    how = (
        f"cubic spline, low-pass {ANTI_ALIAS_CUTOFF * rate_hz:.4g} Hz (Butterworth order "
        f"{ANTI_ALIAS_ORDER}, forward and backward: zero phase)"
        if 1.0 / step > rate_hz * (1 + 1e-9)
        else "linear interpolation (not faster than the grid: no low-pass needed)"
    )
    gaps = len(spans) - 1
    return (
        f"{stream.name}: {stream.time_s.shape[0]} samples, median interval {step:.4g} s "
        f"({1.0 / step:.4g} Hz), intervals {steps.min():.4g}..{steps.max():.4g} s; {how}; "
        f"{gaps} gap(s) longer than {gap_s:.4g} s"
    )


def _check_stream(stream: StreamSamples) -> None:
    time_s = stream.time_s
    if time_s.ndim != 1 or time_s.shape[0] < 2 or not np.all(np.isfinite(time_s)):
        raise TimeBaseError(
            f"{stream.name}: expected at least 2 finite time stamps, got {describe(time_s)}"
        )
    steps = np.diff(time_s)
    if np.any(steps <= 0):
        k = int(np.argmax(steps <= 0))
        raise TimeBaseError(
            f"{stream.name}: time stamps must increase to be resampled; t = {time_s[k]:.6g} s "
            f"at row {k + 1} is followed by {time_s[k + 1]:.6g} s"
        )


def resample_streams(
    streams: Sequence[StreamSamples],
    rate_hz: float,
    max_gap_s: float | None = None,
    *,
    start: float | None = None,
    stop: float | None = None,
) -> Resampling:
    """Every stream on the grid t_k = k/R over the spans all of them cover without a gap.

    Args:
        streams: the streams (each strictly increasing in time).
        rate_hz: R, Hz.
        max_gap_s: the longest interval bridged by interpolation, s (default per stream:
            ``GAP_INTERVALS`` × max(median interval, 1/R)).
        start: keep grid times ≥ start (s); filtering uses the samples outside too.
        stop: keep grid times ≤ stop (s).

    Raises:
        TimeBaseError: bad settings, unordered stamps, or no segment of at least
        ``MIN_SEGMENT_SAMPLES`` grid samples.
    """
    rate_hz = check_rate(rate_hz)
    max_gap_s = check_max_gap(max_gap_s)
    covered = [(-math.inf, math.inf)]
    notes = [f"resampled at {rate_hz:.6g} Hz onto t_k = k/{rate_hz:.6g} s"]
    spans_of = []
    for stream in streams:
        _check_stream(stream)
        step = _median_interval(stream.time_s)
        gap_s = max_gap_s or GAP_INTERVALS * max(step, 1.0 / rate_hz)
        spans = stream_spans(stream.time_s, gap_s)
        spans_of.append(spans)
        notes.append(_stream_note(stream, rate_hz, gap_s, spans))
        t = stream.time_s
        covered = _intersect(covered, [(float(t[a]), float(t[b - 1])) for a, b in spans])
    lo_keep = -math.inf if start is None else start - 1e-9
    hi_keep = math.inf if stop is None else stop + 1e-9
    segments, kept, left_out = [], [], []
    for lo, hi in covered:
        grid = _grid(max(lo, lo_keep), min(hi, hi_keep), rate_hz)
        if grid.shape[0] == 0:
            continue
        if grid.shape[0] < MIN_SEGMENT_SAMPLES:
            left_out.append(f"{lo:.6g}..{hi:.6g} s ({grid.shape[0]} samples)")
            continue
        values = []
        for stream, spans in zip(streams, spans_of, strict=True):
            # the stream's gap-free stretch that holds this segment
            a, b = next(
                (a, b) for a, b in spans if stream.time_s[a] <= lo and hi <= stream.time_s[b - 1]
            )
            own = np.asarray(stream.values, dtype=float).reshape(stream.time_s.shape[0], -1)
            values.append(resample_span(stream.time_s[a:b], own[a:b], grid, rate_hz))
        segments.append(ResampledSegment(grid, tuple(values)))
        kept.append(f"{grid[0]:.6g}..{grid[-1]:.6g} s ({grid.shape[0]} samples)")
    if not segments:
        shown = covered[:10]
        raise TimeBaseError(
            f"resample_hz = {rate_hz:g}: no stretch of at least {MIN_SEGMENT_SAMPLES} grid "
            f"samples is covered by every stream without a gap"
            + (
                f" inside start/stop [{start}, {stop}]"
                if start is not None or stop is not None
                else ""
            )
            + f"; spans covered by all streams: {[(round(a, 6), round(b, 6)) for a, b in shown]}"
            + "; set max_gap_s to bridge longer gaps, or choose other start/stop"
        )
    notes.append(f"{len(segments)} segment(s): " + ", ".join(kept))
    if left_out:
        notes.append(
            f"left out, shorter than {MIN_SEGMENT_SAMPLES} samples: " + ", ".join(left_out)
        )
    return Resampling(tuple(segments), tuple(notes))
