"""Step-sequence test inputs timed to a model's natural frequency, and the relative peak factor.

The classic flight-test inputs are sequences of rectangular pulses of alternating sign:

* doublet: widths (1, 1)·Δt; its period 2Δt is placed at the natural period, Δt = 1/(2 f_n);
* 2-1-1: widths (2, 1, 1)·Δt, signs (+, −, +);
* 3-2-1-1: widths (3, 2, 1, 1)·Δt, signs (+, −, +, −), with Δt ≈ 0.3/f_n — the rule of
  Plaetschke & Schulz (DFVLR, "Practical input signal design", AGARD LS-104, 1979), which puts
  the 3-2-1-1's broad power band around the natural frequency f_n (Hz).

``natural_frequency_hz`` finds f_n from the eigenvalues of the model linearised about a
trim point (forward differences of the user's f, ∂f/∂x), so that a design needs nothing but
the model, its parameter values and the flight condition.

The relative peak factor (Morelli & Klein, *Aircraft System Identification*, ch. 9)

    RPF(u) = (max u − min u) / (2·√2·rms(u))

is 1 for a single sinusoid; a flat multisine with Schroeder phases reaches about 1.4–1.8
and an optimised one comes close to 1 (``flightid.design.multisine``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from flightid.errors import InputError

__all__ = [
    "STEP_SIGNALS",
    "PULSE_PATTERNS",
    "doublet",
    "natural_frequency_hz",
    "pulse_sequence",
    "pulse_width_s",
    "relative_peak_factor",
    "sequence_length_s",
    "three_two_one_one",
    "two_one_one",
]

# pulse widths in units of Δt and the pulse signs of each step signal
PULSE_PATTERNS: dict[str, tuple[tuple[int, ...], tuple[int, ...]]] = {
    "doublet": ((1, 1), (1, -1)),
    "211": ((2, 1, 1), (1, -1, 1)),
    "3211": ((3, 2, 1, 1), (1, -1, 1, -1)),
}
STEP_SIGNALS = tuple(PULSE_PATTERNS)
# Δt per natural period 1/f_n: 3-2-1-1 (Plaetschke & Schulz), doublet half period, and the
# 2-1-1 given the same Δt as the 3-2-1-1 (its 2Δt + Δt pair spans the natural period)
_PULSE_PER_PERIOD = {"3211": 0.3, "211": 0.3, "doublet": 0.5}


def _check_positive(value: float, argument: str) -> float:
    number = float(value)
    if not np.isfinite(number) or number <= 0:
        raise InputError(f"{argument}: expected a positive finite number, got {value!r}")
    return number


def _check_time(t: np.ndarray) -> np.ndarray:
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise InputError(
            f"t: expected a 1-D, finite, increasing time vector (s) of at least 2 samples, got "
            f"shape {t.shape}"
        )
    return t


def pulse_width_s(signal: str, natural_frequency_hz: float) -> float:
    """The pulse unit Δt (s) of ``signal`` for a mode of natural frequency f_n (Hz):
    Δt = 0.3/f_n for the 3-2-1-1 and 2-1-1 (Plaetschke & Schulz), 1/(2 f_n) for a doublet."""
    if signal not in _PULSE_PER_PERIOD:
        raise InputError(f"signal: expected one of {list(STEP_SIGNALS)}, got {signal!r}")
    f_n = _check_positive(natural_frequency_hz, "natural_frequency_hz")
    # Δt = c / f_n
    return _PULSE_PER_PERIOD[signal] / f_n


def sequence_length_s(signal: str, pulse_s: float) -> float:
    """Length (s) of one ``signal`` sequence with pulse unit ``pulse_s``: Σ widths · Δt."""
    if signal not in PULSE_PATTERNS:
        raise InputError(f"signal: expected one of {list(STEP_SIGNALS)}, got {signal!r}")
    return float(sum(PULSE_PATTERNS[signal][0])) * _check_positive(pulse_s, "pulse_s")


def pulse_sequence(
    t: np.ndarray,
    start_s: float,
    pulse_s: float,
    widths: Sequence[int],
    signs: Sequence[int],
    amplitude: float,
) -> np.ndarray:
    """Rectangular pulses: from ``start_s`` on, pulse i lasts widths[i]·Δt at signs[i]·amplitude,
    zero before and after. A sample at t belongs to the pulse with edge ≤ t < next edge (edges
    compared with a tolerance of 10⁻⁹ s, so that a pulse of n samples has n samples)."""
    t = _check_time(t)
    pulse_s = _check_positive(pulse_s, "pulse_s")
    if len(widths) != len(signs) or not widths:
        raise InputError(
            f"widths, signs: expected two non-empty sequences of equal length, got "
            f"{len(widths)} and {len(signs)}"
        )
    u = np.zeros_like(t)
    edge = float(start_s)
    for width, sign in zip(widths, signs, strict=True):
        end = edge + width * pulse_s
        inside = (t >= edge - 1e-9) & (t < end - 1e-9)
        u[inside] = sign * amplitude
        edge = end
    return u


def three_two_one_one(
    t: np.ndarray, start_s: float, pulse_s: float, amplitude: float
) -> np.ndarray:
    """3-2-1-1: +A for 3Δt, −A for 2Δt, +A for Δt, −A for Δt, from ``start_s``."""
    widths, signs = PULSE_PATTERNS["3211"]
    return pulse_sequence(t, start_s, pulse_s, widths, signs, amplitude)


def two_one_one(t: np.ndarray, start_s: float, pulse_s: float, amplitude: float) -> np.ndarray:
    """2-1-1: +A for 2Δt, −A for Δt, +A for Δt, from ``start_s``."""
    widths, signs = PULSE_PATTERNS["211"]
    return pulse_sequence(t, start_s, pulse_s, widths, signs, amplitude)


def doublet(t: np.ndarray, start_s: float, pulse_s: float, amplitude: float) -> np.ndarray:
    """Doublet: +A for Δt, −A for Δt, from ``start_s`` (period 2Δt)."""
    widths, signs = PULSE_PATTERNS["doublet"]
    return pulse_sequence(t, start_s, pulse_s, widths, signs, amplitude)


def relative_peak_factor(u: np.ndarray) -> float:
    """RPF = (max u − min u) / (2·√2·rms(u)) (Morelli & Klein ch. 9); 1 for a sinusoid.

    rms is taken about zero (the signal is a perturbation from trim); an all-zero or
    non-finite signal raises ``InputError``.
    """
    u = np.asarray(u, dtype=float)
    if u.ndim != 1 or u.size < 2 or not np.all(np.isfinite(u)):
        raise InputError(
            f"u: expected a finite 1-D signal of at least 2 samples, got shape {u.shape}"
        )
    rms = float(np.sqrt(np.mean(u**2)))
    if rms == 0.0:
        raise InputError("u: the signal is zero everywhere; its peak factor is undefined")
    # RPF = (max u − min u) / (2 √2 rms)
    return float((u.max() - u.min()) / (2.0 * np.sqrt(2.0) * rms))


def natural_frequency_hz(
    f, x_trim: np.ndarray, u_trim: np.ndarray, theta: np.ndarray, relative_step: float = 1e-6
) -> float:
    """Natural frequency (Hz) of the fastest oscillatory mode of ẋ = f(t, x, u, θ) linearised
    about (x_trim, u_trim): ω_n = |λ| of the complex eigenvalue pair of A = ∂f/∂x with the
    largest |λ|, f_n = ω_n / 2π. Without complex eigenvalues, the largest |λ| of the real ones
    (the fastest first-order mode, its corner frequency). A is taken by forward differences
    with step ``relative_step``·max(|x_j|, 1).
    """
    x_trim = np.asarray(x_trim, dtype=float)
    u_trim = np.asarray(u_trim, dtype=float)
    theta = np.asarray(theta, dtype=float)
    base = np.asarray(f(0.0, x_trim, u_trim, theta), dtype=float)
    a = np.empty((base.size, x_trim.size))
    for j in range(x_trim.size):
        step = relative_step * max(abs(x_trim[j]), 1.0)
        shifted = x_trim.copy()
        shifted[j] += step
        # A_ij = ∂f_i/∂x_j ≈ (f_i(x + h e_j) − f_i(x)) / h
        a[:, j] = (np.asarray(f(0.0, shifted, u_trim, theta), dtype=float) - base) / step
    eigenvalues = np.linalg.eigvals(a)
    if not np.all(np.isfinite(eigenvalues)):
        raise InputError("model: the linearised system matrix has non-finite eigenvalues")
    oscillatory = eigenvalues[
        np.abs(eigenvalues.imag) > 1e-9 * np.maximum(np.abs(eigenvalues), 1.0)
    ]
    pool = oscillatory if oscillatory.size else eigenvalues
    omega_n = float(np.max(np.abs(pool)))
    if omega_n <= 0.0:
        raise InputError(
            "model: every eigenvalue of the linearised system is zero; no natural frequency "
            "to time the input to (give design.pulse_s)"
        )
    # f_n = ω_n / 2π
    return omega_n / (2.0 * np.pi)
