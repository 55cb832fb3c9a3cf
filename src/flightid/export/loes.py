"""Low-order equivalent system (LOES) of the pitch response: the short-period equivalent

    q/δe (s) = K (s + 1/T_θ2) e^{−τ_e s} / (s² + 2 ζ_sp ω_sp s + ω_sp²)

fitted to the frequency response of an identified model (time-domain or not: any linear
model, e.g. ``Estimate.linearize()``), so that the equivalent ω_sp, ζ_sp, 1/T_θ2 and time
delay τ_e of a higher-order airplane (with actuators, phugoid, filters) can be held against
the flying-quality limits.

The fit minimises the mismatch of MIL-STD-1797A (Appendix A, equivalent systems) over n
frequencies ω_k, log-spaced on 0.1–10 rad/s by default:

    M = (20/n) Σ_k [ ΔG_k² + 0.01745 ΔΦ_k² ]

ΔG_k = 20 log10 |H_LOES(jω_k) / H(jω_k)| [dB], ΔΦ_k = arg(H_LOES(jω_k) / H(jω_k)) [deg] (the
phase of the ratio, wrapped to ±180°, so that no unwrapping of either phase enters). The
guideline of MIL-STD-1797A is that M below about 10 is a good match. The fit is
``scipy.optimize.least_squares`` on the residuals √(20/n)·(ΔG_k, √0.01745·ΔΦ_k), from ω_sp
and ζ_sp of the start (the short-period mode of the linear model where it has one) with K and
K/T_θ2 from the linear least-squares fit of H(jω)(s² + 2ζωs + ω²) = K s + K/T_θ2 at τ_e = 0;
τ_e ≥ 0, ω_sp > 0.

A delay of the identified model itself (``LinearModel.notes``) is not in A, B, C, D and not
in the frequency response used here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from flightid.errors import InputError

__all__ = ["LoesError", "LoesFit", "fit_short_period_loes", "loes_response", "short_period_loes"]

PHASE_WEIGHT = 0.01745  # dB² per deg², MIL-STD-1797A
DEFAULT_BAND_RAD_S = (0.1, 10.0)
DEFAULT_POINTS = 40


class LoesError(InputError):
    """A LOES fit that cannot be made as asked (channels, frequencies, response)."""


@dataclass(frozen=True)
class LoesFit:
    """The fitted short-period equivalent system and its mismatch (module docstring)."""

    gain: float  # K, (output unit)/(input unit)·1/s
    inverse_t_theta2_1_per_s: float  # 1/T_θ2
    damping_ratio: float  # ζ_sp
    natural_frequency_rad_s: float  # ω_sp
    time_delay_s: float  # τ_e
    mismatch: float  # M
    frequencies_rad_s: np.ndarray
    converged: bool
    message: str

    def response(self, frequencies_rad_s: np.ndarray | None = None) -> np.ndarray:
        """H_LOES(jω) at the frequencies (default: those of the fit)."""
        w = self.frequencies_rad_s if frequencies_rad_s is None else frequencies_rad_s
        return loes_response(w, self.parameters)

    @property
    def parameters(self) -> tuple[float, float, float, float, float]:
        """(K, 1/T_θ2, ζ_sp, ω_sp, τ_e)."""
        return (
            self.gain,
            self.inverse_t_theta2_1_per_s,
            self.damping_ratio,
            self.natural_frequency_rad_s,
            self.time_delay_s,
        )

    def summary(self) -> str:
        return (
            f"short-period LOES q/δe = K (s + 1/T_θ2) e^(−τ_e s)/(s² + 2ζωs + ω²) over "
            f"{self.frequencies_rad_s[0]:.3g}–{self.frequencies_rad_s[-1]:.3g} rad/s: "
            f"ω_sp = {self.natural_frequency_rad_s:.4g} rad/s, ζ_sp = {self.damping_ratio:.4g}, "
            f"1/T_θ2 = {self.inverse_t_theta2_1_per_s:.4g} 1/s, τ_e = {self.time_delay_s:.4f} s, "
            f"K = {self.gain:.4g}; mismatch M = {self.mismatch:.3g}"
        )

    def to_dict(self) -> dict:
        return {
            "form": "K (s + 1/T_theta2) exp(-tau_e s) / (s^2 + 2 zeta omega s + omega^2)",
            "gain": float(self.gain),
            "inverse_t_theta2_1_per_s": float(self.inverse_t_theta2_1_per_s),
            "zeta_sp": float(self.damping_ratio),
            "omega_sp_rad_per_s": float(self.natural_frequency_rad_s),
            "tau_e_s": float(self.time_delay_s),
            "mismatch": float(self.mismatch),
            "frequency_band_rad_per_s": [
                float(self.frequencies_rad_s[0]),
                float(self.frequencies_rad_s[-1]),
            ],
            "points": int(self.frequencies_rad_s.size),
            "converged": bool(self.converged),
        }


def loes_response(frequencies_rad_s, parameters) -> np.ndarray:
    """K (jω + 1/T_θ2) e^{−jωτ} / ((jω)² + 2ζω_sp jω + ω_sp²) for (K, 1/T_θ2, ζ, ω_sp, τ)."""
    gain, inv_t, zeta, wn, tau = parameters
    s = 1j * np.asarray(frequencies_rad_s, dtype=float)
    return gain * (s + inv_t) * np.exp(-tau * s) / (s**2 + 2.0 * zeta * wn * s + wn**2)


def _residuals(parameters, w, h, n) -> np.ndarray:
    ratio = loes_response(w, parameters) / h
    # ΔG = 20 log10|H_LOES/H| [dB],  ΔΦ = arg(H_LOES/H) [deg]
    gain_db = 20.0 * np.log10(np.abs(ratio))
    phase_deg = np.degrees(np.angle(ratio))
    scale = math.sqrt(20.0 / n)
    # Σ r² = (20/n) Σ [ΔG² + 0.01745 ΔΦ²]
    return scale * np.concatenate([gain_db, math.sqrt(PHASE_WEIGHT) * phase_deg])


def _start(w, h, zeta, wn) -> np.ndarray:
    """(K, 1/T_θ2, ζ, ω, 0) with K, K/T_θ2 from H (s² + 2ζωs + ω²) = K s + K/T_θ2."""
    s = 1j * w
    target = h * (s**2 + 2.0 * zeta * wn * s + wn**2)
    design = np.column_stack([s, np.ones_like(s)])
    stacked = np.vstack([design.real, design.imag])
    rhs = np.concatenate([target.real, target.imag])
    (gain, gain_over_t), *_ = np.linalg.lstsq(stacked, rhs, rcond=None)
    inv_t = gain_over_t / gain if gain != 0 else 1.0
    return np.array([gain, inv_t, zeta, wn, 0.0])


def fit_short_period_loes(
    frequencies_rad_s,
    response,
    *,
    start: tuple[float, float] | None = None,
) -> LoesFit:
    """The LOES of a frequency response H(jω_k) (module docstring).

    Args:
        frequencies_rad_s: ω_k > 0, increasing (rad/s).
        response: H(jω_k), complex, non-zero and finite.
        start: (ζ_sp, ω_sp) to start from; default: ω_sp where |H| is largest above the
            lowest frequency, ζ_sp = 0.5.
    """
    w = np.asarray(frequencies_rad_s, dtype=float)
    h = np.asarray(response, dtype=complex)
    if w.ndim != 1 or w.size < 6 or h.shape != w.shape:
        raise LoesError(
            f"frequencies, response: expected two 1-D arrays of the same length ≥ 6, got "
            f"shapes {w.shape} and {h.shape}"
        )
    if not (np.all(np.isfinite(w)) and np.all(w > 0) and np.all(np.diff(w) > 0)):
        raise LoesError("frequencies_rad_s: expected positive, increasing, finite values")
    if not (np.all(np.isfinite(h)) and np.all(np.abs(h) > 0)):
        raise LoesError("response: expected finite, non-zero values at every frequency")
    if start is None:
        zeta0, wn0 = 0.5, float(w[np.argmax(np.abs(h) * w)])
    else:
        zeta0, wn0 = float(start[0]), float(start[1])
    x0 = _start(w, h, zeta0, wn0)
    lower = [-np.inf, -np.inf, -5.0, 1e-6, 0.0]
    upper = [np.inf, np.inf, 5.0, np.inf, 1.0]
    x0 = np.clip(x0, np.array(lower) + 1e-12, np.array(upper) - 1e-12)
    x0[4] = 0.0
    solution = least_squares(
        _residuals, x0, args=(w, h, w.size), bounds=(lower, upper),
        x_scale="jac", xtol=1e-14, ftol=1e-14, gtol=1e-14, max_nfev=5000,
    )  # fmt: skip
    gain, inv_t, zeta, wn, tau = (float(v) for v in solution.x)
    mismatch = float(np.sum(solution.fun**2))
    return LoesFit(
        gain, inv_t, zeta, wn, tau, mismatch, w, bool(solution.success), str(solution.message)
    )


def short_period_loes(
    linear,
    input_name: str = "de",
    output_name: str = "q",
    *,
    band_rad_s: tuple[float, float] = DEFAULT_BAND_RAD_S,
    points: int = DEFAULT_POINTS,
) -> LoesFit:
    """The short-period LOES of the ``output_name``/``input_name`` response of a
    ``LinearModel`` (H(jω) = C (jωI − A)⁻¹ B + D), over ``points`` log-spaced frequencies
    on ``band_rad_s``; started from the model's short-period mode where it has one."""
    inputs, outputs = list(linear.inputs), list(linear.outputs)
    if input_name not in inputs or output_name not in outputs:
        raise LoesError(
            f"input/output: expected an input of {inputs} and an output of {outputs}, got "
            f"{input_name!r}, {output_name!r}"
        )
    low, high = (float(b) for b in band_rad_s)
    if not (0 < low < high and np.isfinite(high)) or int(points) < 6:
        raise LoesError(
            f"band_rad_s, points: expected 0 < low < high and points ≥ 6, got {band_rad_s}, "
            f"{points}"
        )
    w = np.logspace(math.log10(low), math.log10(high), int(points))
    a, b = np.asarray(linear.A, float), np.asarray(linear.B, float)
    c, d = np.asarray(linear.C, float), np.asarray(linear.D, float)
    i, o = inputs.index(input_name), outputs.index(output_name)
    n = a.shape[0]
    h = np.array([c[o] @ np.linalg.solve(1j * wk * np.eye(n) - a, b[:, i]) + d[o, i] for wk in w])
    start = None
    try:
        mode = linear.modes()["short period"]
        start = (mode.damping_ratio, mode.natural_frequency)
    except InputError:
        start = None
    return fit_short_period_loes(w, h, start=start)
