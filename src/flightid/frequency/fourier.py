"""Finite Fourier transform of sampled signals at chosen frequencies, on a user band.

The finite Fourier transform of a signal x(t) recorded on [t_0, t_0 + T] is

    X(ω) = ∫_0^T x(t_0 + τ) e^{−jωτ} dτ

(Morelli & Klein, *Aircraft System Identification*, 2nd ed., ch. 7; time is measured from
the first sample so that the transform of a maneuver does not depend on where the
recording clock started). With N samples x_i at τ_i = iΔt it is approximated by a
quadrature rule evaluated exactly at each chosen frequency, never interpolated from an FFT
grid:

    rectangle:  X(ω) ≈ Δt Σ_{i=0}^{N−1} x_i e^{−jωτ_i}
    trapezoid:  X(ω) ≈ Δt Σ_{i=0}^{N−1} x_i e^{−jωτ_i} − (Δt/2)(x_0 + x_{N−1} e^{−jωτ_{N−1}})

    linear:     X(ω) = Δt [W(θ) Σ_i x_i e^{−jωτ_i} + (g(θ) − W(θ)) x_0
                         + (ḡ(θ) − W(θ)) x_{N−1} e^{−jωT}],       θ = ωΔt,
                W(θ) = 2(1 − cos θ)/θ²,   g(θ) = 1/(jθ) − (1 − e^{−jθ})/(jθ)²

The trapezoid rule is the rectangle rule with an end correction; its error grows like
(ωΔt)²/12 relative, about 1 % at ωΔt = 0.35 (1.4 Hz at 25 Hz sampling). The ``linear`` rule
(the default; Filon's idea, as in *Numerical Recipes*' "Fourier integrals" with endpoint
corrections, here derived for the piecewise-linear interpolant) integrates the straight
lines between samples exactly: each interior sample carries the transform of its hat
function, Δt W(θ) e^{−jωτ_i}, and each end sample that of a half hat, Δt g(θ) (start) and
Δt ḡ(θ) e^{−jωT} (end). It tends to the trapezoid rule as θ → 0, is exact for the
piecewise-linear inputs that the time-domain simulator assumes (linear input
interpolation), and keeps the boundary identity used by the frequency-domain estimators,

    ∫_0^T ẋ e^{−jωτ} dτ = jω X(ω) + x(T) e^{−jωT} − x(0),

exact for the interpolated signal. Frequencies may be any real numbers (the "exact DFT at
arbitrary frequencies"). For an evenly spaced grid, the sum is a chirp z-transform (a
spiral on the unit circle, ``scipy.signal.czt``), which costs O((N + K) log(N + K)) instead
of O(NK); ``method="auto"`` picks it when the direct sum would be large.

Before transforming, a mean or a straight line is usually removed (``remove_trend``): a
constant offset puts a large (1 − e^{−jωT})/(jω) component at low frequencies.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.signal import czt

from flightid.errors import InputError, describe
from flightid.frequency.arguments import real_array

__all__ = [
    "spectra_list",
    "TRENDS",
    "QUADRATURES",
    "frequency_grid",
    "remove_trend",
    "finite_fourier_transform",
    "constant_transform",
    "ManeuverSpectra",
    "maneuver_spectra",
]

TRENDS = ("none", "mean", "linear")
QUADRATURES = ("rectangle", "trapezoid", "linear")
_METHODS = ("auto", "direct", "czt")
# above this many products N·K the evenly spaced grid goes to the chirp z-transform
_DIRECT_LIMIT = 2_000_000


def frequency_grid(band_hz: tuple[float, float], step_hz: float) -> np.ndarray:
    """Evenly spaced frequencies f_lo, f_lo + Δf, ... ≤ f_hi (Hz) of the band ``band_hz``.

    Raises:
        InputError: the band is not 0 ≤ f_lo < f_hi (finite) or the step is not positive.
    """
    try:
        lo, hi = (float(v) for v in band_hz)
    except (TypeError, ValueError):
        raise InputError(
            f"band_hz: expected two numbers [low, high] in Hz, got {band_hz!r}"
        ) from None
    if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 <= lo < hi):
        raise InputError(f"band_hz: expected finite 0 ≤ low < high (Hz), got [{lo}, {hi}]")
    if isinstance(step_hz, (bool, np.bool_)) or not isinstance(step_hz, (int, float, np.number)):
        raise InputError(f"step_hz: expected a positive frequency step (Hz), got {step_hz!r}")
    step = float(step_hz)
    if not (np.isfinite(step) and step > 0.0):
        raise InputError(f"step_hz: expected a positive frequency step (Hz), got {step_hz!r}")
    count = int(np.floor((hi - lo) / step + 1e-9)) + 1
    if count < 2:
        raise InputError(
            f"step_hz: a step of {step} Hz leaves fewer than 2 frequencies in [{lo}, {hi}] Hz"
        )
    return lo + step * np.arange(count)


def _as_samples(signals: np.ndarray, argument: str) -> tuple[np.ndarray, bool]:
    x = real_array(signals, argument, "real samples")
    vector = x.ndim == 1
    if vector:
        x = x[:, None]
    if x.ndim != 2 or x.shape[0] < 2:
        raise InputError(
            f"{argument}: expected samples as an (N,) or (N, channels) array with N ≥ 2, "
            f"got shape {np.shape(signals)}"
        )
    if not np.all(np.isfinite(x)):
        raise InputError(
            f"{argument}: expected finite samples, found {int((~np.isfinite(x)).sum())} "
            "NaN or infinite value(s)"
        )
    return x, vector


def _sampling_interval(time_s: np.ndarray, n: int) -> float:
    t = real_array(time_s, "time_s", "sample times (s)")
    if t.ndim != 1 or t.shape[0] != n:
        raise InputError(f"time_s: expected {n} sample times (one per row), got shape {t.shape}")
    dt = np.diff(t)
    if not np.all(np.isfinite(t)) or np.any(dt <= 0.0):
        raise InputError("time_s: expected finite, strictly increasing sample times")
    if (dt.max() - dt.min()) > 1e-6 * dt.mean():
        raise InputError(
            f"time_s: the transform needs uniform sampling; intervals range from "
            f"{dt.min():.6g} to {dt.max():.6g} s"
        )
    return float((t[-1] - t[0]) / (n - 1))


def remove_trend(signals: np.ndarray, time_s: np.ndarray, kind: str = "mean") -> np.ndarray:
    """``signals`` (N,) or (N, channels) less their mean (``"mean"``), their least-squares
    straight line a + b·t (``"linear"``), or unchanged (``"none"``)."""
    if kind not in TRENDS:
        raise InputError(f"detrend: expected one of {list(TRENDS)}, got {kind!r}")
    x, vector = _as_samples(signals, "signals")
    t = real_array(time_s, "time_s", "sample times (s)")
    _sampling_interval(t, x.shape[0])
    if kind == "mean":
        x = x - x.mean(axis=0)
    elif kind == "linear":
        basis = np.column_stack([np.ones_like(t), t - t[0]])
        # x ≈ a + b (t − t_0), least squares per channel
        coefficients, *_ = np.linalg.lstsq(basis, x, rcond=None)
        x = x - basis @ coefficients
    return x[:, 0] if vector else x


def _evenly_spaced(frequencies_hz: np.ndarray) -> bool:
    if frequencies_hz.size < 3:
        return False
    steps = np.diff(frequencies_hz)
    return bool(np.all(steps > 0) and np.ptp(steps) <= 1e-9 * max(abs(steps.mean()), 1e-300))


def finite_fourier_transform(
    signals: np.ndarray,
    time_s: np.ndarray,
    frequencies_hz: np.ndarray,
    *,
    quadrature: str = "linear",
    method: str = "auto",
) -> np.ndarray:
    """Finite Fourier transform X(f) = ∫_0^T x(t_0 + τ) e^{−j2πfτ} dτ of sampled signals.

    Args:
        signals: samples, shape (N,) or (N, channels), in the signal's unit.
        time_s: sample times (N,), uniform, s.
        frequencies_hz: the frequencies (K,), Hz; any real values.
        quadrature: ``"linear"`` (exact for the piecewise-linear interpolant, default),
            ``"trapezoid"`` (rectangle rule with the end correction) or ``"rectangle"``
            (Δt Σ x_i e^{−jωτ_i}).
        method: ``"direct"`` (the sum), ``"czt"`` (chirp z-transform; evenly spaced
            frequencies only) or ``"auto"``.

    Returns:
        Complex array (K,) or (K, channels), in signal unit × s.
    """
    if quadrature not in QUADRATURES:
        raise InputError(f"quadrature: expected one of {list(QUADRATURES)}, got {quadrature!r}")
    if method not in _METHODS:
        raise InputError(f"method: expected one of {list(_METHODS)}, got {method!r}")
    x, vector = _as_samples(signals, "signals")
    n = x.shape[0]
    dt = _sampling_interval(time_s, n)
    f = np.atleast_1d(real_array(frequencies_hz, "frequencies_hz", "frequencies (Hz)"))
    if f.ndim != 1 or f.size == 0 or not np.all(np.isfinite(f)):
        raise InputError(
            f"frequencies_hz: expected a non-empty 1-D array of finite frequencies (Hz), "
            f"got shape {np.shape(frequencies_hz)}"
        )
    omega = 2.0 * np.pi * f
    even = _evenly_spaced(f)
    if method == "czt" and not even:
        raise InputError("method: 'czt' needs evenly spaced, increasing frequencies_hz")
    use_czt = method == "czt" or (method == "auto" and even and n * f.size > _DIRECT_LIMIT)
    if use_czt:
        step = omega[1] - omega[0]
        # Σ_i x_i z_k^{−i} with z_k = a w^{−k}: a = e^{jω_0Δt}, w = e^{−jΔωΔt}
        a = np.exp(1j * omega[0] * dt)
        w = np.exp(-1j * step * dt)
        total = czt(x, m=f.size, w=w, a=a, axis=0)
    else:
        tau = dt * np.arange(n)
        # Σ_i x_i e^{−jω_k τ_i}
        total = np.exp(-1j * np.outer(omega, tau)) @ x
    transform = dt * total
    if quadrature == "linear":
        theta = omega * dt
        small = np.abs(theta) < 1e-4
        safe = np.where(small, 1.0, theta)
        # W(θ) = 2(1 − cos θ)/θ²  (→ 1 − θ²/12)
        weight = np.where(small, 1.0 - theta**2 / 12.0, 2.0 * (1.0 - np.cos(safe)) / safe**2)
        a = 1j * safe
        # g(θ) = ∫_0^1 (1 − v) e^{−jθv} dv = 1/(jθ) − (1 − e^{−jθ})/(jθ)²  (→ 1/2 − jθ/6)
        half = np.where(small, 0.5 - 1j * theta / 6.0, 1.0 / a - (1.0 - np.exp(-a)) / a**2)
        end = np.exp(-1j * omega * dt * (n - 1))
        transform = weight[:, None] * transform + dt * (
            (half - weight)[:, None] * x[0][None, :]
            + ((half.conj() - weight) * end)[:, None] * x[-1][None, :]
        )
    elif quadrature == "trapezoid":
        end = np.exp(-1j * omega * dt * (n - 1))
        # − (Δt/2)(x_0 + x_{N−1} e^{−jωτ_{N−1}})
        transform = transform - 0.5 * dt * (x[0][None, :] + end[:, None] * x[-1][None, :])
    return transform[:, 0] if vector else transform


def constant_transform(
    time_s: np.ndarray, frequencies_hz: np.ndarray, *, quadrature: str = "linear"
) -> np.ndarray:
    """The transform of the constant 1 with the same rule, ≈ (1 − e^{−jωT})/(jω) (K,):
    the regressor of a constant bias on the band."""
    t = real_array(time_s, "time_s", "sample times (s)")
    return finite_fourier_transform(np.ones_like(t), t, frequencies_hz, quadrature=quadrature)


@dataclass(frozen=True)
class ManeuverSpectra:
    """One maneuver on the band: transforms of its inputs and outputs, and the two
    boundary regressors the estimators need.

    Attributes:
        frequencies_hz: (K,) Hz.
        inputs: (K, n_u) complex transforms of the (detrended) inputs, unit × s.
        outputs: (K, n_y) complex transforms of the (detrended) outputs, unit × s.
        constant: (K,) transform of the constant 1, ≈ (1 − e^{−jωT})/(jω), s.
        end_phase: (K,) e^{−jωT}, T = (N − 1)Δt the record length.
        duration_s: T, s.
        n_samples: N.
        name: the maneuver's name.
        input_ends: (2, n_u) the detrended inputs at the first and the last sample (for the
            ends of a delayed input, ``flightid.frequency.output_error.delayed_inputs``);
            None: not known (a delay then enters as e^{−jωτ}U(ω) alone).
    """

    frequencies_hz: np.ndarray
    inputs: np.ndarray
    outputs: np.ndarray
    constant: np.ndarray
    end_phase: np.ndarray
    duration_s: float
    n_samples: int
    name: str = ""
    input_ends: np.ndarray | None = None

    @property
    def end_phase_constant(self) -> bool:
        """True if e^{−jωT} is the same at every frequency (frequencies spaced by a
        multiple of 1/T): then x(0) and x(T) enter only as x(0) − x(T) e^{−jωT}, one
        unknown per state instead of two."""
        # spread of e^{−jωT} over the band below 1e-6 (rad): merged; a spacing close to but
        # not at 1/T leaves x(0) and x(T) nearly collinear (the fit reports it singular)
        return bool(np.ptp(self.end_phase.real) + np.ptp(self.end_phase.imag) < 1e-6)

    @property
    def omega_rad_s(self) -> np.ndarray:
        """ω = 2πf (K,), rad/s."""
        return 2.0 * np.pi * self.frequencies_hz


def maneuver_spectra(
    time_s: np.ndarray,
    inputs: np.ndarray,
    outputs: np.ndarray,
    frequencies_hz: np.ndarray,
    *,
    detrend: str = "mean",
    input_quadrature: str = "linear",
    output_quadrature: str = "trapezoid",
    name: str = "",
) -> ManeuverSpectra:
    """Detrend and transform one maneuver's inputs (N, n_u) and outputs (N, n_y).

    Inputs are taken as the straight lines between their samples (``"linear"``, what the
    time-domain simulator assumes); outputs as smooth responses, for which the trapezoid
    sum is the accurate rule (the piecewise-linear rule would damp them by W(ωΔt))."""
    t = real_array(time_s, "time_s", "sample times (s)")
    if t.ndim != 1 or t.size < 2:
        raise InputError(f"time_s: expected N ≥ 2 sample times (s), got {describe(time_s)}")
    columns = []
    for argument, values in (("inputs", inputs), ("outputs", outputs)):
        array = real_array(values, argument, "real samples")
        if array.ndim not in (1, 2) or array.shape[0] != t.size:
            raise InputError(
                f"{argument}: expected ({t.size},) or ({t.size}, channels) samples, one row per "
                f"sample time, got {describe(values)}"
            )
        columns.append(remove_trend(array.reshape(t.size, -1), t, detrend))
    u, z = columns
    f = real_array(frequencies_hz, "frequencies_hz", "frequencies (Hz)")
    if f.ndim != 1 or f.size == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise InputError(
            f"frequencies_hz: expected a non-empty 1-D array of frequencies > 0 Hz (ω = 0 is "
            f"excluded), got {describe(frequencies_hz)}"
        )
    if not isinstance(name, str):
        raise InputError(f"name: expected the maneuver's name (a string), got {describe(name)}")
    duration = float(t[-1] - t[0])
    if f.max() >= 0.5 * (t.shape[0] - 1) / duration:
        raise InputError(
            f"band_hz: the highest frequency {f.max():.4g} Hz is at or above the Nyquist "
            f"frequency {0.5 * (t.shape[0] - 1) / duration:.4g} Hz of maneuver {name!r}"
        )
    return ManeuverSpectra(
        frequencies_hz=f,
        inputs=finite_fourier_transform(u, t, f, quadrature=input_quadrature),
        outputs=finite_fourier_transform(z, t, f, quadrature=output_quadrature),
        constant=constant_transform(t, f, quadrature="linear"),
        end_phase=np.exp(-2j * np.pi * f * duration),
        duration_s=duration,
        n_samples=int(t.shape[0]),
        name=name,
        input_ends=np.vstack([u[0], u[-1]]),
    )


def spectra_list(value: Any, argument: str = "spectra") -> list:
    """A non-empty sequence of ``ManeuverSpectra`` (one per maneuver)."""
    if isinstance(value, ManeuverSpectra):
        raise InputError(
            f"{argument}: expected a list of ManeuverSpectra (one per maneuver), got one "
            "ManeuverSpectra; pass [spectra]"
        )
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or not value:
        raise InputError(
            f"{argument}: expected at least one maneuver (a non-empty list of ManeuverSpectra), "
            f"got {describe(value)}"
        )
    wrong = [describe(v) for v in value if not isinstance(v, ManeuverSpectra)]
    if wrong:
        raise InputError(f"{argument}: expected ManeuverSpectra, got {wrong[0]}")
    return list(value)
