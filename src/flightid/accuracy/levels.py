"""Beale's correction of the confidence level for a nonlinear model.

The contour level Δ of the likelihood region, its residual variance factor s² and the level
check are shared by every result's ``conf_int`` and live in ``flightid.results``
(``contour_level``, ``residual_variance_factor``, ``check_level``). Beale's correction for a
nonlinear model inflates that level [5.28–5.29]:

    Δ_B = Δ · [1 + N·n_o (n_p + 2) / ((N·n_o − n_p) n_p) · N_φ]

Beale derived it for the simultaneous region; we apply the same factor to the individual
level (a documented choice: the curvature that inflates the joint region inflates each
projection by the same ratio to first order).
"""

from __future__ import annotations

import math

__all__ = ["beale_factor"]


def beale_factor(n_phi: float, n_data: int, n_free: int) -> float:
    """1 + N·n_o (n_p + 2) / ((N·n_o − n_p) n_p) · N_φ [5.28–5.29]; ≥ 1 for N_φ ≥ 0."""
    if not math.isfinite(n_phi):
        return float("nan")
    # factor = 1 + N n_o (n_p + 2) / ((N n_o − n_p) n_p) · N_φ             [5.29]
    return float(1.0 + n_data * (n_free + 2) / ((n_data - n_free) * n_free) * n_phi)
