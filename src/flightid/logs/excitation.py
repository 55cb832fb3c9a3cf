"""Excitation segments in an input channel: where the input moves well above its quiet
level, what kind of input it is, its frequency band and how strongly it excites.

Detection (on a uniform copy of the channel at its median rate, for analysis only):

1. Quiet level σ_q: the median of the moving standard deviation s(t) over a window W
   (``window_s``, default 0.25 s) where s(t) is below three times its 10th percentile:
   the noise of the input where it is held.
2. Seeds: where s(t) > K·σ_q (K = ``threshold``, default 4), i.e. where the input moves.
3. Each seed grows into a segment around the level x₀ held before it (the median over the
   second before): it goes on while the input stays away from x₀ (|x − x₀| > K·σ_q),
   takes in the next seed when that starts less than G = 0.5 s after the input is back, and
   ends where the input has been back at x₀ for G — or, where it is held away from x₀ (a
   step) without moving, ``max_hold_s`` (default 5 s) after its last movement.
4. Start and stop: the first and last sample where |x − x₀| > max(K·σ_q, 10 % of the peak).

Kind, from y = x − x₀ on the segment (A: the median of |y| where |y| > peak/2):
- square-wave inputs (at least 75 % of the samples within ±25 % of ±A): the runs of one
  sign with |y| > A/2 give "step" (one), "doublet" (two of opposite sign, durations within
  a factor 1.6), "3-2-1-1" (four alternating, durations 3:2:1:1 within 35 %), else "pulses";
- smooth inputs: "pulse" when y keeps one sign (it never swings from beyond +A/4 to
  beyond −A/4 or back: one smooth excursion, such as a controller's return to level at a
  mode change); "sweep" when the frequency from the zero crossings (with hysteresis ±A/4)
  rises or falls monotonically (Spearman |ρ| ≥ 0.9) over more than a factor 1.5, else
  "multisine" (any other multi-frequency input).

Band: for sweeps the frequency at the segment's start and stop of a straight line fitted
to the zero-crossing frequencies against time (f, or log f where that fits better); otherwise
the frequencies below which 5 % and 95 % of the energy of y lie (|FFT(y)|², zero-padded).

Figure of merit: the excitation ratio RMS(y) / σ_q in dB, 20·log10(RMS(y)/σ_q) — how far
above the input's own noise the segment drives it (σ_q is floored at 10⁻³ of the channel's
peak-to-peak range, so noise-free data give finite numbers).

Limits: one channel at a time; trims that drift faster than the input moves, inputs that
end at another trim (the segment then runs ``max_hold_s`` past the last movement), and
excitations weaker than ~K·σ_q are not separated; classification needs the input well
above its noise (≳ 20 dB).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.stats import spearmanr

__all__ = ["Segment", "detect_excitation", "KINDS"]

KINDS = ("step", "doublet", "3-2-1-1", "pulses", "pulse", "sweep", "multisine")
_GAP_S = 0.5  # s: the input back at its level this long ends a segment
_PRE_S = 1.0  # s: the level before a segment is the median over this long
_FLAT_SHARE = 0.75
_MIN_SAMPLES = 20


@dataclass(frozen=True)
class Segment:
    """One excitation segment of one channel.

    Attributes:
        channel: the channel's name; unit: its unit ("" where unknown).
        kind: one of ``KINDS``.
        start_s, stop_s: the segment (s, log time).
        band_hz: (low, high) frequency band (Hz), see the module docstring.
        amplitude: peak |x − x₀| in the channel's unit.
        level: x₀, the level held before the segment (channel unit).
        ratio_db: 20·log10(RMS(x − x₀) / σ_q), the excitation above the quiet level (dB).
    """

    channel: str
    kind: str
    start_s: float
    stop_s: float
    band_hz: tuple[float, float]
    amplitude: float
    level: float
    ratio_db: float
    unit: str = ""

    @property
    def duration_s(self) -> float:
        return self.stop_s - self.start_s


def _moving_std(x: np.ndarray, n: int) -> np.ndarray:
    # s² = E[x²] − E[x]² over a centred window of n samples (x centred first for accuracy)
    x = x - np.median(x)
    mean = uniform_filter1d(x, n, mode="nearest")
    mean_sq = uniform_filter1d(x * x, n, mode="nearest")
    return np.sqrt(np.maximum(mean_sq - mean * mean, 0.0))


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True."""
    edges = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1, strict=True))


@dataclass(frozen=True)
class _Grid:
    t: np.ndarray
    x: np.ndarray
    fs: float  # Hz

    def samples(self, seconds: float) -> int:
        return max(1, int(round(seconds * self.fs)))


def _uniform(time: np.ndarray, values: np.ndarray) -> _Grid | None:
    t = np.asarray(time, dtype=float)
    x = np.asarray(values, dtype=float)
    keep = np.isfinite(t) & np.isfinite(x)
    t, x = t[keep], x[keep]
    if t.size < _MIN_SAMPLES:
        return None
    order = np.argsort(t, kind="stable")
    t, x = t[order], x[order]
    dt = np.diff(t)
    step = float(np.median(dt[dt > 0])) if np.any(dt > 0) else 0.0
    if step <= 0:
        return None
    grid = t[0] + np.arange(int(math.floor((t[-1] - t[0]) / step)) + 1) * step
    return _Grid(grid, np.interp(grid, t, x), 1.0 / step)


def _stays(mask: np.ndarray, n: int) -> np.ndarray:
    """stays[i]: mask holds on samples i .. i+n−1 (past the end counts as holding)."""
    padded = np.r_[mask, np.ones(n, dtype=bool)].astype(np.int64)
    count = np.r_[0, np.cumsum(padded)]
    # samples holding in i .. i+n−1 = C[i+n] − C[i]
    return (count[n : n + mask.size] - count[: mask.size]) == n


def _level_before(g: _Grid, a: int, n_pre: int) -> float:
    lo = max(0, a - n_pre)
    if a - lo >= 3:
        return float(np.median(g.x[lo:a]))
    return float(np.median(g.x[: max(a, 1)]))


def _grow(g, seeds, x0, back, k, threshold_d, n_gap, n_hold):
    """Grow seed ``k`` (merging later seeds) into (first, last, index of the next seed)."""
    a, b = seeds[k]
    n = g.x.size
    while True:
        # the first index ≥ b from which the input stays back at x₀ for n_gap samples
        returned = np.flatnonzero(back[b:])
        end = n - 1 if returned.size == 0 else b + int(returned[0]) - 1
        end = min(end, b + n_hold)
        if k + 1 < len(seeds) and seeds[k + 1][0] <= end + n_gap:
            k += 1
            b = max(end, seeds[k][1])
            continue
        break
    deviation = np.abs(g.x - x0)
    lo = max(0, a - n_gap)
    window = deviation[lo : end + 1]
    peak = float(window.max())
    significant = np.flatnonzero(window > max(threshold_d, 0.1 * peak))
    if significant.size == 0:
        return None, k + 1
    first, last = lo + int(significant[0]), lo + int(significant[-1])
    return (first, last), k + 1


def _square_kind(y: np.ndarray, A: float, fs: float) -> str:
    # the pulses: runs of one sign with |y| > A/2 (shorter dips between same-sign runs,
    # noise, are joined)
    sign = np.where(np.abs(y) > 0.5 * A, np.sign(y), 0.0)
    merged: list[list[float]] = []
    for value in (1.0, -1.0):
        for i, j in _runs(sign == value):
            if j > i:
                merged.append([i, value, (j - i + 1) / fs])
    merged.sort()
    joined: list[list[float]] = []
    for _, value, duration in merged:
        if joined and joined[-1][0] == value:
            joined[-1][1] += duration
        else:
            joined.append([value, duration])
    merged = joined
    signs = [s for s, _ in merged]
    durations = np.array([d for _, d in merged])
    alternating = all(signs[i] != signs[i + 1] for i in range(len(signs) - 1))
    if len(merged) == 1:
        return "step"
    if len(merged) == 2 and alternating and 1 / 1.6 <= durations[0] / durations[1] <= 1.6:
        return "doublet"
    if len(merged) == 4 and alternating:
        # durations relative to the 3-2-1-1 pattern: each within 35 % of 3:2:1:1
        unit = durations.sum() / 7.0
        if np.all(
            np.abs(durations / unit - np.array([3, 2, 1, 1])) <= 0.35 * np.array([3, 2, 1, 1])
        ):
            return "3-2-1-1"
    return "pulses"


def _crossing_times(y: np.ndarray, t: np.ndarray, h: float) -> np.ndarray:
    """The times (s) where y swings from beyond +h to beyond −h or back (Schmitt trigger
    with hysteresis ±h)."""
    state, crossings = 0, []
    above, below = y > h, y < -h
    for i in np.flatnonzero(above | below):
        new = 1 if above[i] else -1
        if new != state:
            if state != 0:
                crossings.append(t[i])
            state = new
    return np.asarray(crossings)


def _crossing_frequencies(y: np.ndarray, t: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(times, Hz) of the local frequency from crossings of ±h (Schmitt trigger): each
    half period between alternate-sign crossings gives f = 1 / (2·half period)."""
    crossings = _crossing_times(y, t, h)
    if crossings.size < 3:
        return np.empty(0), np.empty(0)
    half = np.diff(crossings)
    return 0.5 * (crossings[1:] + crossings[:-1]), 1.0 / (2.0 * half)


def _sweep_band(times, freqs, start, stop) -> tuple[float, float]:
    """The band of a sweep: a line f = a + b·t (linear sweep) or log f = a + b·t
    (logarithmic sweep), whichever fits the crossing frequencies better, at start and stop."""
    linear = np.polyfit(times, freqs, 1)
    logarithmic = np.polyfit(times, np.log(freqs), 1)
    linear_error = np.sum((np.polyval(linear, times) - freqs) ** 2)
    log_error = np.sum((np.exp(np.polyval(logarithmic, times)) - freqs) ** 2)
    ends = np.array([start, stop])
    if log_error < linear_error:
        f_ends = np.exp(np.polyval(logarithmic, ends))
    else:
        f_ends = np.maximum(np.polyval(linear, ends), float(freqs.min()) / 2)
    return float(f_ends.min()), float(f_ends.max())


def _energy_band(y: np.ndarray, fs: float) -> tuple[float, float]:
    n = int(2 ** math.ceil(math.log2(max(4 * y.size, 256))))
    energy = np.abs(np.fft.rfft(y, n)) ** 2
    freq = np.fft.rfftfreq(n, 1.0 / fs)
    cumulative = np.cumsum(energy) / energy.sum()
    return float(freq[np.searchsorted(cumulative, 0.05)]), float(
        freq[min(np.searchsorted(cumulative, 0.95), freq.size - 1)]
    )


def _classify(y: np.ndarray, t: np.ndarray, fs: float) -> tuple[str, tuple[float, float]]:
    peak = float(np.max(np.abs(y)))
    A = float(np.median(np.abs(y[np.abs(y) > 0.5 * peak])))
    flat = float(np.mean(np.abs(np.abs(y) - A) < 0.25 * A))
    if flat >= _FLAT_SHARE:
        return _square_kind(y, A, fs), _energy_band(y, fs)
    if _crossing_times(y, t, 0.25 * A).size == 0:
        # one sign throughout: a single smooth excursion from x₀ and back
        return "pulse", _energy_band(y, fs)
    times, freqs = _crossing_frequencies(y - np.mean(y), t, 0.25 * A)
    if freqs.size >= 6:
        rho = spearmanr(times, freqs).statistic
        lo, hi = _sweep_band(times, freqs, t[0], t[-1])
        if abs(rho) >= 0.9 and hi >= 1.5 * lo:
            return "sweep", (lo, hi)
    return "multisine", _energy_band(y - np.mean(y), fs)


def detect_excitation(
    time: np.ndarray,
    values: np.ndarray,
    channel: str = "",
    unit: str = "",
    *,
    window_s: float = 0.25,
    threshold: float = 4.0,
    max_hold_s: float = 5.0,
) -> list[Segment]:
    """The excitation segments of one input channel (module docstring), in time order;
    empty for a quiet channel. ``time`` (s) may be uneven: the analysis runs on a uniform
    copy at the median rate."""
    g = _uniform(time, values)
    if g is None:
        return []
    n_window = max(g.samples(window_s), 5)
    moving = _moving_std(g.x, n_window)
    span = float(np.ptp(g.x))
    if span == 0.0:
        return []
    # σ_q: the median moving std of the quiet windows (those below 3× its 10th percentile),
    # floored at 10⁻³ of the range
    low = float(np.percentile(moving, 10))
    quiet = max(float(np.median(moving[moving <= 3.0 * low])), 1e-3 * span)
    threshold_d = threshold * quiet
    seeds = _runs(moving > threshold_d)
    n_gap, n_pre, n_hold = g.samples(_GAP_S), g.samples(_PRE_S), g.samples(max_hold_s)
    segments: list[Segment] = []
    k = 0
    while k < len(seeds):
        x0 = _level_before(g, seeds[k][0], n_pre)
        back = np.abs(g.x - x0) <= threshold_d
        # back_run[i]: the input stays back at x₀ for n_gap samples from i
        back_run = _stays(back, n_gap)
        span_k, k = _grow(g, seeds, x0, back_run, k, threshold_d, n_gap, n_hold)
        if span_k is None or span_k[1] - span_k[0] < 3:
            continue
        first, last = span_k
        y = g.x[first : last + 1] - x0
        kind, band = _classify(y, g.t[first : last + 1], g.fs)
        rms = float(np.sqrt(np.mean(y * y)))
        segments.append(
            Segment(
                channel,
                kind,
                float(g.t[first]),
                float(g.t[last]),
                band,
                float(np.max(np.abs(y))),
                x0,
                # 20·log10(RMS(y) / σ_q)
                20.0 * math.log10(rms / quiet),
                unit,
            )
        )
    return segments
