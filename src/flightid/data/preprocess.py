"""Declared pre-processing of channels: smoothing and numerical differentiation.

A channel specification (``flightid.data.loaders.ChannelSpec``) may name one smoothing and
one differentiation step; they run after source → scale/offset → unit conversion →
subtract, in that order (smooth, then derivative), and restart at every maneuver and
segment boundary (each segment is filtered on its own, as if it were the whole record).

Smoothing (``smooth = ...``):

- ``"smoothMulTS"``: the fixed weights of the smoother ``smoothMulTS`` of FVSysID, the code
  supplement of Jategaonkar's *Flight Vehicle System Identification* (``smooth_mul_ts``);
- ``{savgol = [window, order]}``: Savitzky–Golay (``scipy.signal.savgol_filter``, its
  ``interp`` end rule: the fitted polynomial of the first/last window);
- ``{butter = [order, cutoff_hz]}``: zero-phase Butterworth low-pass
  (``scipy.signal.butter`` run forwards and backwards by ``scipy.signal.filtfilt``; the
  effective order doubles and the gain at the cutoff is 1/2 instead of 1/√2).

Differentiation (``derivative = ...``), giving the channel's rate (unit ``…/s``):

- ``"ndiff8"``: the high-order central difference of FVSysID's ``ndiff_Filter08``
  (``ndiff8``);
- ``{savgol = [window, order]}``: the first derivative of the Savitzky–Golay fit.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from flightid.errors import InputError, describe

__all__ = [
    "PreprocessError",
    "smooth_mul_ts",
    "ndiff8",
    "savgol_smooth",
    "savgol_derivative",
    "butter_smooth",
    "parse_smooth",
    "parse_derivative",
    "apply_steps",
    "segment_slices",
]


class PreprocessError(InputError):
    """A smoothing or differentiation setting that cannot be applied (unknown filter, even
    or too long window, cutoff at or above the Nyquist frequency, too few samples)."""


# ------------------------------------------------------------------ FVSysID's fixed filters

# S(x) interior weights: S_k = [74 x_k + Σ_{j=1..7} w_j (x_{k−j} + x_{k+j})] / 320
_S15 = (74.0, 67.0, 46.0, 21.0, 3.0, -5.0, -6.0, -3.0)
# D(x) interior coefficients c_1..c_8: D_k = Σ_j c_j (x_{k+j} − x_{k−j}) / dt
_C8 = (
    0.88888888887637,
    -0.31111111109862,
    0.11313131312500,
    -0.03535353535135,
    0.00870240870185,
    -0.00155400155390,
    0.00017760017759,
    -0.00000971250971,
)


def smooth_mul_ts(x: np.ndarray) -> np.ndarray:
    """S(x), the smoother of FVSysID's ``smoothMulTS``, over one segment x_1..x_N (any N ≥ 1).

    Rules, the first that applies (k 1-based):
    k ≤ 3 or k ≥ N−2: S_k = x_k;
    4 ≤ k ≤ 8 or N−7 ≤ k ≤ N−3: S_k = [7(x_{k−2}+x_{k+2}) + 24(x_{k−1}+x_{k+1}) + 34 x_k]/96;
    9 ≤ k ≤ N−8: S_k = [74 x_k + 67 s1 + 46 s2 + 21 s3 + 3 s4 − 5 s5 − 6 s6 − 3 s7]/320,
    s_j = x_{k−j} + x_{k+j}.
    """
    x = np.asarray(x, dtype=float)
    n = x.shape[0]
    s = x.copy()
    # 0-based i = k − 1; interior 15-point rule on 9 ≤ k ≤ N−8  ⇔  8 ≤ i ≤ N−9
    if n >= 16:
        i = np.arange(8, n - 8)
        acc = _S15[0] * x[i]
        for j in range(1, 8):
            acc = acc + _S15[j] * (x[i - j] + x[i + j])
        s[i] = acc / 320.0
    # 5-point rule on 4 ≤ k ≤ N−3 outside the interior range (k ≤ 8 or k ≥ N−7)
    k = np.arange(4, n - 2)  # 1-based, k ≤ N−3 (k ≥ N−2 keeps x_k)
    k = k[(k <= 8) | (k >= n - 7)]
    i = k - 1
    # S_k = [7(x_{k−2}+x_{k+2}) + 24(x_{k−1}+x_{k+1}) + 34 x_k] / 96
    s[i] = (7.0 * (x[i - 2] + x[i + 2]) + 24.0 * (x[i - 1] + x[i + 1]) + 34.0 * x[i]) / 96.0
    return s


def ndiff8(x: np.ndarray, dt: float) -> np.ndarray:
    """D(x), the differentiator of FVSysID's ``ndiff_Filter08``, over one segment x_1..x_N
    (N ≥ 5), dt in s.

    Rules (k 1-based):
    10 ≤ k ≤ N−9: D_k = Σ_{j=1..8} c_j (x_{k+j} − x_{k−j}) / dt;
    other 3 ≤ k ≤ N−2 (3 ≤ k ≤ 9 or N−8 ≤ k ≤ N−2):
        D_k = [−0.08333333333333 (x_{k+2}−x_{k−2}) + 0.66666666666667 (x_{k+1}−x_{k−1})] / dt;
    D_1 = D_2 = D_3, D_{N−1} = D_N = D_{N−2}.
    """
    x = np.asarray(x, dtype=float)
    n = x.shape[0]
    if n < 5:
        raise PreprocessError(f"derivative 'ndiff8': expected at least 5 samples, got {n}")
    d = np.empty(n)
    # 5-point rule on 3 ≤ k ≤ N−2  ⇔  0-based 2 ≤ i ≤ N−3
    i = np.arange(2, n - 2)
    d[i] = (
        -0.08333333333333 * (x[i + 2] - x[i - 2]) + 0.66666666666667 * (x[i + 1] - x[i - 1])
    ) / dt
    # 17-point rule on 10 ≤ k ≤ N−9  ⇔  0-based 9 ≤ i ≤ N−10
    if n >= 19:
        i = np.arange(9, n - 9)
        acc = np.zeros(i.shape[0])
        for j, c in enumerate(_C8, start=1):
            acc = acc + c * (x[i + j] - x[i - j])
        d[i] = acc / dt
    # D_1 = D_2 = D_3,  D_{N−1} = D_N = D_{N−2}
    d[0] = d[1] = d[2]
    d[n - 1] = d[n - 2] = d[n - 3]
    return d


# ------------------------------------------------------------------ scipy filters


def _check_savgol(window: int, order: int, n: int, deriv: int, what: str) -> None:
    if window % 2 == 0 or window < 3:
        raise PreprocessError(f"{what}: expected an odd window ≥ 3 samples, got {window}")
    if not deriv <= order < window:
        raise PreprocessError(
            f"{what}: expected {deriv} ≤ order < window ({window}), got order {order}"
        )
    if window > n:
        raise PreprocessError(f"{what}: window {window} is longer than the segment ({n} samples)")


def savgol_smooth(x: np.ndarray, window: int, order: int) -> np.ndarray:
    """Savitzky–Golay smoothing: the value of the least-squares polynomial of degree ``order``
    fitted over ``window`` samples centred on each sample (ends: the first/last window's fit)."""
    from scipy.signal import savgol_filter

    x = np.asarray(x, dtype=float)
    _check_savgol(window, order, x.shape[0], 0, "smooth savgol")
    return savgol_filter(x, window, order, mode="interp")


def savgol_derivative(x: np.ndarray, dt: float, window: int, order: int) -> np.ndarray:
    """First derivative (per s) of the Savitzky–Golay polynomial fit, dt in s."""
    from scipy.signal import savgol_filter

    x = np.asarray(x, dtype=float)
    _check_savgol(window, order, x.shape[0], 1, "derivative savgol")
    return savgol_filter(x, window, order, deriv=1, delta=dt, mode="interp")


def butter_smooth(x: np.ndarray, dt: float, order: int, cutoff_hz: float) -> np.ndarray:
    """Zero-phase Butterworth low-pass: ``butter(order, cutoff_hz, fs = 1/dt)`` applied
    forwards and backwards (``filtfilt``); needs cutoff_hz < the Nyquist frequency 1/(2 dt)
    and more than 3·(order + 1) samples (filtfilt's edge padding)."""
    from scipy.signal import butter, filtfilt

    x = np.asarray(x, dtype=float)
    nyquist = 0.5 / dt
    if not 0 < cutoff_hz < nyquist:
        raise PreprocessError(
            f"smooth butter: expected 0 < cutoff < the Nyquist frequency {nyquist:g} Hz "
            f"(dt = {dt:g} s), got {cutoff_hz:g} Hz"
        )
    if order < 1 or order > 10:
        raise PreprocessError(f"smooth butter: expected an order 1..10, got {order}")
    b, a = butter(order, cutoff_hz, btype="low", fs=1.0 / dt)
    padlen = 3 * max(len(a), len(b))
    if x.shape[0] <= padlen:
        raise PreprocessError(
            f"smooth butter: order {order} needs more than {padlen} samples per segment, "
            f"got {x.shape[0]}"
        )
    return filtfilt(b, a, x, padlen=padlen)


# ------------------------------------------------------------------ declared settings


def _pair(value: Any, key: str, where: str, kinds: tuple) -> tuple:
    if (
        not isinstance(value, Sequence)
        or isinstance(value, str)
        or len(value) != 2
        or any(
            isinstance(v, bool) or not isinstance(v, kind)
            for v, kind in zip(value, kinds, strict=True)
        )
    ):
        names = "[window, order]" if key == "savgol" else "[order, cutoff_hz]"
        raise PreprocessError(f"{where}.{key}: expected {names} (numbers), got {value!r}")
    return tuple(value)


def _mapping_step(value: Mapping, where: str, allowed: tuple[str, ...]) -> tuple:
    if len(value) != 1 or next(iter(value)) not in allowed:
        raise PreprocessError(
            f"{where}: expected one of {{{' | '.join(f'{a} = [...]' for a in allowed)}}}, "
            f"got {dict(value)!r}"
        )
    key, args = next(iter(value.items()))
    if key == "savgol":
        window, order = _pair(args, key, where, (int, int))
        return ("savgol", int(window), int(order))
    order, cutoff = _pair(args, key, where, (int, (int, float)))
    return ("butter", int(order), float(cutoff))


def parse_smooth(value: Any, where: str) -> tuple | None:
    """``smooth`` setting → ("smoothMulTS",) | ("savgol", window, order) |
    ("butter", order, cutoff_hz) | None. Checks what can be checked without data."""
    if value is None:
        return None
    if isinstance(value, tuple) and value and value[0] in ("smoothMulTS", "savgol", "butter"):
        return value
    if value == "smoothMulTS":
        return ("smoothMulTS",)
    if isinstance(value, Mapping):
        step = _mapping_step(value, where, ("savgol", "butter"))
        if step[0] == "savgol":
            _check_savgol(step[1], step[2], step[1], 0, f"{where}.savgol")
        elif step[1] < 1 or step[2] <= 0:
            raise PreprocessError(
                f"{where}.butter: expected order ≥ 1 and cutoff_hz > 0, got {list(step[1:])}"
            )
        return step
    raise PreprocessError(
        f"{where}: expected 'smoothMulTS', {{savgol = [window, order]}} or "
        f"{{butter = [order, cutoff_hz]}}, got {describe(value)}"
    )


def parse_derivative(value: Any, where: str) -> tuple | None:
    """``derivative`` setting → ("ndiff8",) | ("savgol", window, order) | None."""
    if value is None:
        return None
    if isinstance(value, tuple) and value and value[0] in ("ndiff8", "savgol"):
        return value
    if value == "ndiff8":
        return ("ndiff8",)
    if isinstance(value, Mapping):
        step = _mapping_step(value, where, ("savgol",))
        _check_savgol(step[1], step[2], step[1], 1, f"{where}.savgol")
        return step
    raise PreprocessError(
        f"{where}: expected 'ndiff8' or {{savgol = [window, order]}}, got {describe(value)}"
    )


def segment_slices(times: np.ndarray, joined: bool) -> list[slice]:
    """Segments of a maneuver's rows: one, or (rows joined from several recording segments)
    split where the stored time steps back or jumps by more than 1.5 median intervals."""
    n = times.shape[0]
    if not joined or n < 3:
        return [slice(0, n)]
    dt = np.diff(times)
    median = float(np.median(dt))
    cuts = np.flatnonzero((dt <= 0) | (dt > 1.5 * median)) + 1
    edges = [0, *cuts.tolist(), n]
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True)]


def apply_steps(
    values: np.ndarray,
    dt: float,
    segments: Sequence[slice],
    smooth: tuple | None,
    derivative: tuple | None,
    where: str,
) -> np.ndarray:
    """Smooth, then differentiate, each segment on its own (dt in s)."""
    out = np.asarray(values, dtype=float).copy()
    for number, segment in enumerate(segments, start=1):
        part = out[segment]
        try:
            if smooth is not None:
                if smooth[0] == "smoothMulTS":
                    part = smooth_mul_ts(part)
                elif smooth[0] == "savgol":
                    part = savgol_smooth(part, smooth[1], smooth[2])
                else:
                    part = butter_smooth(part, dt, smooth[1], smooth[2])
            if derivative is not None:
                if derivative[0] == "ndiff8":
                    part = ndiff8(part, dt)
                else:
                    part = savgol_derivative(part, dt, derivative[1], derivative[2])
        except PreprocessError as exc:
            raise PreprocessError(f"{where} (segment {number} of {len(segments)}): {exc}") from None
        out[segment] = part
    return out
