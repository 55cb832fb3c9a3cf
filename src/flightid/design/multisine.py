"""Orthogonal phase-optimised multisines for several inputs at once.

Following Morelli, "Multiple input design for real-time parameter estimation in the frequency
domain" (IFAC SYSID 2003) and Morelli & Klein, *Aircraft System Identification*, ch. 9:

1. Over a period T the harmonics of f₀ = 1/T that fall in the band [f_lo, f_hi] are
   k = ⌈f_lo T⌉ … ⌊f_hi T⌋ (k ≥ 1). They are dealt to the m inputs alternately — input j
   gets k_j, k_j + m, k_j + 2m, … — so no two inputs share a frequency.
2. Each input is a sum of cosines with a flat power spectrum,

       u_j(t) = Σ_{k ∈ K_j} a cos(2π k t / T + φ_k),

   and because ∫₀ᵀ cos(2πkt/T + φ) cos(2πlt/T + ψ) dt = 0 for k ≠ l, the inputs are mutually
   orthogonal over [0, T] (and on T/Δt uniform samples of one period, for k + l below the
   sample count) whatever the phases: an estimator sees each input's effect separately.
3. Phases start from Schroeder's flat-spectrum formula (Schroeder, IEEE Trans. Inf. Theory
   16, 1970), for the i-th of the M_j harmonics of input j,

       φ_i = −π i (i − 1) / M_j,

   and are then optimised to minimise the peak of u_j for its fixed rms: the smooth surrogate
   ‖u‖_p = (mean u^p)^(1/p) over a fine grid of one period (p = 8, 32, 128 in turn, even, so
   ‖u‖_p → max |u|), minimised by scipy's L-BFGS-B with the analytic gradient

       ∂‖u‖_p/∂φ_k = ‖u‖_p^(1−p) · mean(u^(p−1) · (−a sin(2π k t/T + φ_k))).

   The phases with the lowest relative peak factor RPF = (max − min)/(2√2 rms) seen (the
   Schroeder start included) are kept, so the optimised RPF is never above Schroeder's.
4. Each input is shifted in time (φ_k ← φ_k + 2π k τ/T, τ its first zero crossing) so that
   it starts — and, being periodic, ends — at zero: the excitation can be switched on and off
   without a jump. A time shift changes neither the power spectrum, nor the peak factor, nor
   the orthogonality.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from flightid.design.signals import relative_peak_factor
from flightid.errors import InputError

__all__ = [
    "Multisine",
    "assign_harmonics",
    "design_multisine",
    "optimize_phases",
    "schroeder_phases",
    "sum_of_cosines",
]

# surrogate exponents p of ‖u‖_p, in turn (even: u^p ≥ 0)
_P_NORMS = (8, 32, 128)


def assign_harmonics(
    n_inputs: int, period_s: float, band_hz: tuple[float, float]
) -> list[np.ndarray]:
    """The harmonic indices k (f = k/T) of each input: those in ``band_hz``, dealt alternately.

    Raises ``InputError`` when the band holds fewer harmonics than there are inputs.
    """
    if not isinstance(n_inputs, int) or n_inputs < 1:
        raise InputError(f"n_inputs: expected a positive integer, got {n_inputs!r}")
    period_s = float(period_s)
    if not np.isfinite(period_s) or period_s <= 0:
        raise InputError(f"period_s: expected a positive duration (s), got {period_s!r}")
    low, high = (float(b) for b in band_hz)
    if not (0 <= low < high) or not np.isfinite(high):
        raise InputError(f"band_hz: expected [low, high] with 0 ≤ low < high (Hz), got {band_hz!r}")
    # k = ⌈f_lo T⌉ … ⌊f_hi T⌋, k ≥ 1 (1e-9 tolerates f·T landing a rounding error off an integer)
    first = max(1, int(np.ceil(low * period_s - 1e-9)))
    last = int(np.floor(high * period_s + 1e-9))
    k = np.arange(first, last + 1)
    if k.size < n_inputs:
        raise InputError(
            f"band_hz: [{low}, {high}] Hz over T = {period_s} s holds {k.size} harmonics of "
            f"1/T = {1 / period_s:.4g} Hz, fewer than the {n_inputs} inputs; widen the band or "
            "lengthen the input"
        )
    # input j: k_j, k_j + m, k_j + 2m, …
    return [k[j::n_inputs] for j in range(n_inputs)]


def schroeder_phases(n_harmonics: int) -> np.ndarray:
    """Schroeder's flat-spectrum phases φ_i = −π i(i − 1)/M, i = 1 … M (rad)."""
    if not isinstance(n_harmonics, (int, np.integer)) or n_harmonics < 1:
        raise InputError(f"n_harmonics: expected a positive integer, got {n_harmonics!r}")
    i = np.arange(1, n_harmonics + 1)
    # φ_i = −π i (i − 1) / M
    return -np.pi * i * (i - 1) / n_harmonics


def sum_of_cosines(
    t: np.ndarray,
    period_s: float,
    harmonics: np.ndarray,
    phases_rad: np.ndarray,
    amplitudes: np.ndarray | float = 1.0,
) -> np.ndarray:
    """u(t) = Σ_k a_k cos(2π k t / T + φ_k)."""
    t = np.asarray(t, dtype=float)
    k = np.asarray(harmonics, dtype=float)
    phases = np.asarray(phases_rad, dtype=float)
    if k.shape != phases.shape or k.ndim != 1:
        raise InputError(
            f"harmonics, phases_rad: expected two 1-D arrays of one length, got {k.shape} and "
            f"{phases.shape}"
        )
    a = np.broadcast_to(np.asarray(amplitudes, dtype=float), k.shape)
    # u(t) = Σ_k a_k cos(2π k t / T + φ_k)
    return np.cos(2.0 * np.pi * np.outer(t, k) / period_s + phases[None, :]) @ a


def _grid(harmonics: np.ndarray, period_s: float, per_cycle: int = 16) -> np.ndarray:
    """A grid over one period: ≥ ``per_cycle`` points per period of the highest harmonic."""
    n = max(512, per_cycle * int(np.max(harmonics)))
    return np.arange(n) * (period_s / n)


# points per cycle of the highest harmonic where peak factors are reported: a cosine sampled
# so misses its peak by at most 1 − cos(π/128) ≈ 3·10⁻⁴
_RPF_PER_CYCLE = 128


def _peak_factor(harmonics: np.ndarray, phases: np.ndarray, period_s: float) -> float:
    """RPF of the unit multisine over one period on the dense reporting grid."""
    t = _grid(harmonics, period_s, _RPF_PER_CYCLE)
    return relative_peak_factor(sum_of_cosines(t, period_s, harmonics, phases))


def optimize_phases(
    harmonics: np.ndarray, period_s: float, start_rad: np.ndarray | None = None
) -> np.ndarray:
    """Phases (rad) that lower the peak factor of a flat multisine (module docstring, step 3).

    Starts from ``start_rad`` (default: Schroeder's phases); returns the phases with the
    lowest RPF (dense grid, 128 points per cycle of the highest harmonic) among the start and
    the optimised ones.
    """
    from scipy.optimize import minimize

    harmonics = np.asarray(harmonics)
    phases = schroeder_phases(harmonics.size) if start_rad is None else np.asarray(start_rad, float)
    if harmonics.size == 1:
        return phases.copy()
    t = _grid(harmonics, period_s)
    arguments = 2.0 * np.pi * np.outer(t, harmonics) / period_s

    def rpf(phi: np.ndarray) -> float:
        return _peak_factor(harmonics, phi, period_s)

    best, best_rpf = phases.copy(), rpf(phases)
    current = phases.copy()
    for p in _P_NORMS:

        def norm_and_gradient(phi: np.ndarray, p: int = p) -> tuple[float, np.ndarray]:
            angle = arguments + phi[None, :]
            u = np.cos(angle).sum(axis=1)
            # scaled by c = max|u| (‖u‖_p = c ‖u/c‖_p exactly; keeps u^p finite)
            c = float(np.max(np.abs(u)))
            v = u / c
            mean_p = float(np.mean(v**p))
            # ‖u‖_p = c (mean (u/c)^p)^(1/p)
            norm = c * mean_p ** (1.0 / p)
            # ∂‖u‖_p/∂φ_k = ‖u/c‖_p^(1−p) mean((u/c)^(p−1) (−sin(2πkt/T + φ_k)))
            gradient = mean_p ** (1.0 / p - 1.0) * (v ** (p - 1) @ (-np.sin(angle))) / t.size
            return norm, gradient

        result = minimize(norm_and_gradient, current, jac=True, method="L-BFGS-B")
        if np.all(np.isfinite(result.x)):
            current = result.x
            value = rpf(current)
            if value < best_rpf:
                best, best_rpf = current.copy(), value
    return np.mod(best + np.pi, 2.0 * np.pi) - np.pi


def _zero_start(harmonics: np.ndarray, phases: np.ndarray, period_s: float) -> np.ndarray:
    """Phases shifted by τ, the first zero crossing of u: φ_k + 2π k τ / T (step 4)."""
    t = _grid(harmonics, period_s)
    u = sum_of_cosines(t, period_s, harmonics, phases)
    crossing = np.flatnonzero(np.sign(u[:-1]) * np.sign(u[1:]) <= 0)
    if crossing.size == 0:  # pragma: no cover - a zero-mean sum of cosines crosses zero
        return phases
    i = int(crossing[0])
    # τ by linear interpolation between the samples around the sign change
    denominator = u[i] - u[i + 1]
    tau = t[i] + (t[i + 1] - t[i]) * (u[i] / denominator if denominator != 0 else 0.0)
    # refine τ by Newton steps on u(τ) = 0 (u' = −Σ 2πk/T sin(·))
    for _ in range(5):
        angle = 2.0 * np.pi * harmonics * tau / period_s + phases
        value = np.sum(np.cos(angle))
        slope = -np.sum(2.0 * np.pi * harmonics / period_s * np.sin(angle))
        if slope == 0:
            break
        tau -= value / slope
    # φ_k ← φ_k + 2π k τ / T  (u_new(t) = u(t + τ))
    shifted = phases + 2.0 * np.pi * harmonics * tau / period_s
    return np.mod(shifted + np.pi, 2.0 * np.pi) - np.pi


@dataclass(frozen=True)
class Multisine:
    """Orthogonal multisines: per input its harmonics (k, f = k/T), phases (rad) and peak
    amplitude (input units); ``rpf`` and ``rpf_schroeder`` over one period on a dense grid
    (128 points per cycle of the highest harmonic)."""

    names: tuple[str, ...]
    period_s: float
    harmonics: tuple[np.ndarray, ...]
    phases_rad: tuple[np.ndarray, ...]
    amplitudes: tuple[float, ...]
    rpf: tuple[float, ...]
    rpf_schroeder: tuple[float, ...]

    def frequencies_hz(self, name: str) -> np.ndarray:
        """The frequencies (Hz) of input ``name``: k / T."""
        return self.harmonics[self.names.index(name)] / self.period_s

    def unit_signals(self, t: np.ndarray) -> np.ndarray:
        """(N, m): each input with unit-amplitude cosines (before scaling to the peak)."""
        return np.column_stack(
            [
                sum_of_cosines(t, self.period_s, k, phi)
                for k, phi in zip(self.harmonics, self.phases_rad, strict=True)
            ]
        )

    def signals(self, t: np.ndarray) -> np.ndarray:
        """(N, m): input j scaled so that its peak |u_j| over one fine-grid period and the
        samples ``t`` equals its amplitude (so no sample exceeds it)."""
        columns = []
        for k, phi, a in zip(self.harmonics, self.phases_rad, self.amplitudes, strict=True):
            unit = sum_of_cosines(t, self.period_s, k, phi)
            fine = sum_of_cosines(_grid(k, self.period_s), self.period_s, k, phi)
            # the peak over the fine grid and the requested samples: scaling by it keeps every
            # sample within ±a without clipping (which would spoil the orthogonality)
            peak = float(max(np.max(np.abs(fine)), np.max(np.abs(unit))))
            columns.append(unit * (a / peak))
        return np.column_stack(columns)

    def with_amplitudes(self, amplitudes: Sequence[float]) -> Multisine:
        """The same multisine with other peak amplitudes."""
        return Multisine(
            self.names,
            self.period_s,
            self.harmonics,
            self.phases_rad,
            tuple(float(a) for a in amplitudes),
            self.rpf,
            self.rpf_schroeder,
        )


def design_multisine(
    names: Sequence[str],
    period_s: float,
    band_hz: tuple[float, float] | Sequence[tuple[float, float]],
    amplitudes: Sequence[float],
    optimize: bool = True,
) -> Multisine:
    """Orthogonal multisines for the inputs ``names`` over ``period_s`` (module docstring).

    ``band_hz`` is one band for all inputs (harmonics dealt alternately), or one band per input
    (each input its own harmonics; bands must not share harmonics, else ``InputError``).
    """
    names = tuple(names)
    if not names or len(set(names)) != len(names):
        raise InputError(f"names: expected distinct input names, got {list(names)}")
    if len(amplitudes) != len(names):
        raise InputError(
            f"amplitudes: expected one per input ({len(names)}), got {len(amplitudes)}"
        )
    for name, a in zip(names, amplitudes, strict=True):
        if not np.isfinite(a) or a <= 0:
            raise InputError(f"amplitudes[{name}]: expected a positive number, got {a!r}")
    bands = np.asarray(band_hz, dtype=float)
    if bands.shape == (2,):
        harmonics = assign_harmonics(len(names), period_s, tuple(bands))
    elif bands.shape == (len(names), 2):
        harmonics = [assign_harmonics(1, period_s, tuple(b))[0] for b in bands]
        seen: set[int] = set()
        for name, k in zip(names, harmonics, strict=True):
            if seen & set(k.tolist()):
                raise InputError(
                    f"band_hz[{name}]: shares harmonics with another input's band; the inputs "
                    "would not be orthogonal (give one band for all inputs to deal them)"
                )
            seen |= set(k.tolist())
    else:
        raise InputError(
            f"band_hz: expected [low, high] or one [low, high] per input, got shape {bands.shape}"
        )
    phases, rpf, rpf_schroeder = [], [], []
    for k in harmonics:
        start = schroeder_phases(k.size)
        rpf_schroeder.append(_peak_factor(k, start, period_s))
        phi = optimize_phases(k, period_s, start) if optimize else start
        phi = _zero_start(k, phi, period_s)
        phases.append(phi)
        rpf.append(_peak_factor(k, phi, period_s))
    return Multisine(
        names,
        float(period_s),
        tuple(harmonics),
        tuple(phases),
        tuple(float(a) for a in amplitudes),
        tuple(rpf),
        tuple(rpf_schroeder),
    )
