"""Low-order equivalent system (LOES) fit to a frequency response.

A high-order (measured) frequency response H(jω) is matched by a low-order transfer
function with an equivalent time delay (MIL-STD-1797A, "Flying qualities of piloted
aircraft", appendix A, the LOES procedure; Hodgkinson, *Aircraft Handling Qualities*, ch. 3;
Morelli & Klein ch. 10):

    G(s) = (b_m s^m + ... + b_0) / (s^n + a_{n−1} s^{n−1} + ... + a_0) · e^{−τ s}

e.g. the short-period pitch rate to elevator

    q/δe (s) = K_q (s + 1/T_θ2) e^{−τ s} / (s² + 2 ζ_sp ω_sp s + ω_sp²).

The coefficients are chosen to minimise the mismatch of gain (dB) and phase (deg) at the
n_ω frequencies of the band,

    J = (20 / n_ω) Σ_ω [ (G_dB − Ĝ_dB)² + 0.01745 (φ − φ̂)² ]

(the weight 0.01745 makes 1 dB as costly as 7.57 deg; MIL-STD-1797A suggests J ≲ 10 for a
good match). The phase difference is taken on (−180°, 180°] so that an unwrapping
difference of 360° does not count. Minimised by ``scipy.optimize.least_squares`` on the
residuals √(20/n_ω)·[ΔG_dB, √0.01745·Δφ].
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from flightid.errors import EstimationError, InputError, describe
from flightid.frequency.arguments import finite_number, flag, real_array

__all__ = ["LoesFit", "fit_loes", "short_period_loes", "loes_response"]

PHASE_WEIGHT = 0.01745  # per deg², MIL-STD-1797A LOES cost


@dataclass(frozen=True)
class LoesFit:
    """Fitted numerator b (m+1,) and denominator a (n,) coefficients (highest power first;
    the denominator is monic), delay τ (s), cost J, and the fitted response."""

    numerator: np.ndarray
    denominator: np.ndarray
    delay_s: float
    cost: float
    frequencies_rad_s: np.ndarray
    response: np.ndarray
    message: str

    def evaluate(self, omega_rad_s: np.ndarray) -> np.ndarray:
        """G(jω) of the fit."""
        return loes_response(self.numerator, self.denominator, self.delay_s, omega_rad_s)


def loes_response(
    numerator: Sequence[float], denominator: Sequence[float], delay_s: float, omega_rad_s
) -> np.ndarray:
    """G(jω) = b(jω)/(jω^n + a(jω)) e^{−jωτ}; ``denominator`` without the leading 1."""
    s = 1j * real_array(omega_rad_s, "omega_rad_s", "frequencies (rad/s)")
    numerator = _coefficients(numerator, "numerator")
    denominator = _coefficients(denominator, "denominator", empty=True)
    delay_s = finite_number(delay_s, "delay_s")
    den = np.polyval(np.concatenate([[1.0], denominator]), s)
    return np.polyval(numerator, s) / den * np.exp(-s * delay_s)


def _coefficients(value, argument: str, empty: bool = False) -> np.ndarray:
    """Polynomial coefficients as a finite 1-D float array (non-empty unless ``empty``)."""
    array = real_array(value, argument, "polynomial coefficients")
    if array.ndim != 1 or (array.size == 0 and not empty) or not np.all(np.isfinite(array)):
        raise InputError(
            f"{argument}: expected a list of finite coefficients, highest power first, got "
            f"{describe(value)}"
        )
    return array


def _wrap_deg(angle: np.ndarray) -> np.ndarray:
    # on (−180, 180]
    return -((-angle + 180.0) % 360.0 - 180.0)


def fit_loes(
    omega_rad_s: np.ndarray,
    response: np.ndarray,
    numerator_start: Sequence[float],
    denominator_start: Sequence[float],
    *,
    delay_start_s: float = 0.0,
    fit_delay: bool = True,
) -> LoesFit:
    """Fit G(s) to the complex ``response`` at ``omega_rad_s`` by the MIL-STD-1797A cost.

    The starts give the orders (numerator highest power first; the monic denominator's
    coefficients below s^n).
    """
    w = real_array(omega_rad_s, "omega_rad_s", "frequencies (rad/s)")
    try:
        H = np.asarray(response, dtype=complex)
    except (TypeError, ValueError):
        raise InputError(f"response: expected complex values, got {describe(response)}") from None
    if w.ndim != 1 or H.shape != w.shape or w.size < 3:
        raise InputError(
            f"response: expected one complex value per frequency (≥ 3), got {H.shape} for "
            f"{w.shape} frequencies"
        )
    if not (np.all(np.isfinite(H)) and np.all(np.abs(H) > 0) and np.all(w > 0)):
        raise InputError("response: expected finite, non-zero responses at positive frequencies")
    b0 = _coefficients(numerator_start, "numerator_start")
    a0 = _coefficients(denominator_start, "denominator_start", empty=True)
    delay_start_s = finite_number(delay_start_s, "delay_start_s")
    fit_delay = flag(fit_delay, "fit_delay")
    n_b = b0.size
    if a0.size + n_b + int(fit_delay) >= 2 * w.size:
        raise InputError("response: too few frequencies for the number of LOES coefficients")
    gain_db = 20.0 * np.log10(np.abs(H))
    phase_deg = np.rad2deg(np.angle(H))
    scale = np.sqrt(20.0 / w.size)

    def split(p):
        return p[:n_b], p[n_b : n_b + a0.size], (p[-1] if fit_delay else delay_start_s)

    def residuals(p):
        b, a, tau = split(p)
        G = loes_response(b, a, tau, w)
        # ΔG_dB, √0.01745 Δφ (deg, wrapped)
        d_gain = gain_db - 20.0 * np.log10(np.abs(G))
        d_phase = _wrap_deg(phase_deg - np.rad2deg(np.angle(G)))
        return scale * np.concatenate([d_gain, np.sqrt(PHASE_WEIGHT) * d_phase])

    start = np.concatenate([b0, a0, [delay_start_s] if fit_delay else []])
    solution = least_squares(residuals, start, method="lm", x_scale="jac", max_nfev=5000)
    if not np.all(np.isfinite(solution.x)):
        raise EstimationError("fit_loes: the fit left non-finite coefficients")
    b, a, tau = split(solution.x)
    cost = float(np.sum(residuals(solution.x) ** 2))
    return LoesFit(b, a, float(tau), cost, w, loes_response(b, a, tau, w), solution.message)


def short_period_loes(
    omega_rad_s: np.ndarray,
    response: np.ndarray,
    *,
    gain_start: float = -1.0,
    inverse_t_theta2_start: float = 1.0,
    damping_start: float = 0.7,
    frequency_start_rad_s: float = 2.0,
    delay_start_s: float = 0.05,
) -> tuple[LoesFit, dict[str, float]]:
    """q/δe = K_q (s + 1/T_θ2) e^{−τs} / (s² + 2ζω s + ω²): the fit and its named values
    K_q (1/s), 1/T_θ2 (1/s), ζ_sp (−), ω_sp (rad/s), τ (s)."""
    for name, value in (
        ("gain_start", gain_start),
        ("inverse_t_theta2_start", inverse_t_theta2_start),
        ("damping_start", damping_start),
        ("frequency_start_rad_s", frequency_start_rad_s),
    ):
        finite_number(value, name)
    fit = fit_loes(
        omega_rad_s,
        response,
        [gain_start, gain_start * inverse_t_theta2_start],
        [2.0 * damping_start * frequency_start_rad_s, frequency_start_rad_s**2],
        delay_start_s=delay_start_s,
    )
    b1, b0 = fit.numerator
    a1, a0 = fit.denominator
    if a0 <= 0.0:
        raise EstimationError(
            f"short_period_loes: the fitted denominator s² + {a1:.4g} s + {a0:.4g} has no "
            "oscillatory short-period pair (ω² ≤ 0)"
        )
    omega = float(np.sqrt(a0))
    values = {
        "K_q": float(b1),
        "inverse_T_theta2": float(b0 / b1),
        "zeta_sp": float(a1 / (2.0 * omega)),
        "omega_sp_rad_s": omega,
        "delay_s": fit.delay_s,
    }
    return fit, values
