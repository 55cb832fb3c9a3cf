"""Confidence levels: the likelihood-ratio contour level Δ and the Beale correction.

For the output-error cost J(θ) = Σ_i ν_iᵀ R⁻¹ ν_i with N samples of n_o outputs and n_p free
parameters, the residual variance factor is

    s² = J(θ̂) / (N·n_o − n_p)                                        [5.30]

(≈ 1 when R is the residual estimate R̂ [3.45]; it carries the noise level when R is fixed,
e.g. R = I). A confidence region at level 1 − α is {θ : J(θ) − J(θ̂) ≤ Δ} with

    simultaneous (all n_p parameters at once):
        Δ = n_p s² F_α(n_p, N·n_o − n_p)                              [5.20, 5.23]
    individual (one parameter, the others free):
        Δ = s² F_α(1, N·n_o − n_p) = s² t²_{α/2}(N·n_o − n_p)

``distribution="normal"`` replaces the F quantiles by their large-sample limits,
q·F_α(q, ∞) = χ²_α(q) (q = n_p or 1). For a problem linear in θ the region is the ellipsoid
(θ − θ̂)ᵀ M (θ − θ̂) ≤ Δ, whose projection on axis j is θ̂_j ± √(Δ·(M⁻¹)_jj) [5.24–5.27].

Beale's correction for a nonlinear model inflates the level [5.28–5.29]:

    Δ_B = Δ · [1 + N·n_o (n_p + 2) / ((N·n_o − n_p) n_p) · N_φ]

Beale derived it for the simultaneous region; we apply the same factor to the individual
level (a documented choice: the curvature that inflates the joint region inflates each
projection by the same ratio to first order).
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from flightid.errors import InputError

__all__ = [
    "DISTRIBUTIONS",
    "KINDS",
    "beale_factor",
    "check_level",
    "contour_level",
    "residual_variance_factor",
]

KINDS = ("individual", "simultaneous")
DISTRIBUTIONS = ("t", "normal")


def check_level(level: float) -> float:
    """The confidence level 1 − α as a float in (0, 1); raises InputError otherwise."""
    try:
        value = float(level)
    except (TypeError, ValueError):
        raise InputError(f"level: expected a probability such as 0.95, got {level!r}") from None
    if not 0.0 < value < 1.0:
        raise InputError(f"level: expected a probability strictly between 0 and 1, got {value}")
    return value


def residual_variance_factor(cost: float, n_data: int, n_free: int) -> float:
    """s² = J(θ̂) / (N·n_o − n_p) [5.30] (dimensionless when J is weighted by R⁻¹)."""
    dof = n_data - n_free
    if dof <= 0:
        raise InputError(
            f"n_data: need more scalar measurements (N·n_o = {n_data}) than free parameters "
            f"({n_free}) to estimate s²"
        )
    return float(cost) / dof


def contour_level(
    level: float,
    n_data: int,
    n_free: int,
    s2: float,
    kind: str = "individual",
    distribution: str = "t",
) -> float:
    """Δ such that {J(θ) − J(θ̂) ≤ Δ} is the confidence region at ``level``.

    Args:
        level: confidence level 1 − α, e.g. 0.95.
        n_data: N·n_o, the number of scalar measurements.
        n_free: n_p, the number of free parameters.
        s2: residual variance factor s² [5.30].
        kind: ``"individual"`` (one parameter at a time) or ``"simultaneous"`` [5.24–5.25].
        distribution: ``"t"`` (F quantiles with N·n_o − n_p degrees of freedom, the paper's)
            or ``"normal"`` (χ² quantiles, the large-sample limit).
    Returns:
        Δ in the units of J.
    """
    level = check_level(level)
    if kind not in KINDS:
        raise InputError(f"kind: expected one of {KINDS}, got {kind!r}")
    if distribution not in DISTRIBUTIONS:
        raise InputError(f"distribution: expected one of {DISTRIBUTIONS}, got {distribution!r}")
    q = n_free if kind == "simultaneous" else 1
    dof = n_data - n_free
    if distribution == "t":
        if dof <= 0:
            raise InputError(
                f"n_data: N·n_o = {n_data} must exceed the {n_free} free parameters "
                "for the F distribution"
            )
        # Δ = q s² F_α(q, N·n_o − n_p)                                   [5.20, 5.25]
        return float(q * s2 * stats.f.ppf(level, q, dof))
    # Δ = s² χ²_α(q)  (q F_α(q, ∞) = χ²_α(q))
    return float(s2 * stats.chi2.ppf(level, q))


def beale_factor(n_phi: float, n_data: int, n_free: int) -> float:
    """1 + N·n_o (n_p + 2) / ((N·n_o − n_p) n_p) · N_φ [5.28–5.29]; ≥ 1 for N_φ ≥ 0."""
    if not np.isfinite(n_phi):
        return float("nan")
    # factor = 1 + N n_o (n_p + 2) / ((N n_o − n_p) n_p) · N_φ             [5.29]
    return float(1.0 + n_data * (n_free + 2) / ((n_data - n_free) * n_free) * n_phi)
