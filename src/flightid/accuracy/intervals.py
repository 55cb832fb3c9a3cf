"""The correlation matrix of the information-matrix intervals, and their warnings.

With C = M⁻¹ (M = Σ_i G_iᵀ R⁻¹ G_i at θ̂, the Cramér–Rao bound [3.47–3.49]) and a contour
level Δ (``flightid.results.contour_level``), the quadratic approximation of the confidence
region is the ellipsoid (θ − θ̂)ᵀ M (θ − θ̂) ≤ Δ; its extent along parameter j
(``flightid.results.ellipsoid_intervals``) is

    θ̂_j ± √(Δ · C_jj)                                                  [5.24–5.27]

With the individual level this is θ̂_j ± t_{α/2}(N n_o − n_p)·s·σ_j; with the simultaneous one
it is θ̂_j ± √k·s·σ_j, k = n_p F_α(n_p, N n_o − n_p) [5.25]. Parameters that the data cannot
determine (σ = inf) get infinite intervals and a warning.
"""

from __future__ import annotations

import warnings

import numpy as np

__all__ = [
    "AccuracyWarning",
    "correlation_matrix",
    "correlation_warnings",
    "emit",
]

HIGH_CORRELATION = 0.9


class AccuracyWarning(UserWarning):
    """A statement about the estimates' accuracy that the user should read."""


def emit(messages: list[str], stacklevel: int = 3) -> None:
    """Issue each message as an ``AccuracyWarning``."""
    for message in messages:
        warnings.warn(message, AccuracyWarning, stacklevel=stacklevel)


def correlation_matrix(covariance: np.ndarray) -> np.ndarray:
    """ρ_jk = C_jk / √(C_jj C_kk); NaN where a parameter is undetermined."""
    covariance = np.asarray(covariance, dtype=float)
    sigma = np.sqrt(np.abs(np.diag(covariance)))
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = covariance / np.outer(sigma, sigma)
    rho[~np.isfinite(rho)] = np.nan
    np.fill_diagonal(rho, np.where(np.isfinite(sigma) & (sigma > 0), 1.0, np.nan))
    return rho


def correlation_warnings(
    names: list[str], covariance: np.ndarray, threshold: float = HIGH_CORRELATION
) -> list[str]:
    """Messages for undetermined parameters (σ = inf) and for pairs with |ρ| > ``threshold``."""
    covariance = np.asarray(covariance, dtype=float)
    messages = []
    variance = np.diag(covariance)
    undetermined = [n for n, v in zip(names, variance, strict=True) if not np.isfinite(v)]
    if undetermined:
        messages.append(
            f"the data cannot determine {undetermined}: their Cramér–Rao bounds are infinite "
            "(singular information matrix); their intervals are unbounded"
        )
    rho = correlation_matrix(covariance)
    for j in range(len(names)):
        for k in range(j + 1, len(names)):
            if np.isfinite(rho[j, k]) and abs(rho[j, k]) > threshold:
                messages.append(
                    f"the estimates of {names[j]} and {names[k]} are highly correlated "
                    f"(ρ = {rho[j, k]:+.3f}, |ρ| > {threshold}); their separate bounds "
                    "overstate what the data tell apart"
                )
    return messages
