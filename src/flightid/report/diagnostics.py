"""Numbers the report shows beside the estimates: fit quality, whiteness, corrected σ, det R.

Theil inequality coefficient of output o (0 = perfect fit, 1 = no fit at all; Morelli &
Klein, *Aircraft System Identification*, 2nd ed., §5.5):

    U_o = √(Σ_i ν_io² / N) / ( √(Σ_i z_io² / N) + √(Σ_i y_io² / N) ),   ν = z − y

Residual autocorrelation of output o at lag k (products never pair samples of different
maneuvers, ``flightid.accuracy.coloured.residual_autocovariance``):

    ρ_o(k) = R̂_ν,oo(k) / R̂_ν,oo(0),   white-noise band ±1.96/√N

(the fraction of lags outside the band and the Ljung–Box test of the same ρ, for any
estimator's residuals, are ``flightid.accuracy.whiteness``; the report's outputs table shows
them beside these numbers)

Coloured-residual σ: the sandwich covariance of ``flightid.accuracy.coloured_covariance``
(automatic lag) scaled by N·n_o/(N·n_o − n_p) exactly as ``flightid.accuracy.assess`` does;
it is compared with the Cramér–Rao σ scaled by the residual factor s [5.30], s·σ_j, so that
white residuals give a ratio near 1 whatever R the cost used. No simulation is needed: the
sensitivities and residuals at θ̂ are in the ``Estimate``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightid.accuracy.coloured import coloured_covariance, residual_autocovariance
from flightid.errors import InputError
from flightid.results import residual_variance_factor

__all__ = [
    "COLOURED_RATIO_WARNING",
    "ColouredSigma",
    "autocorrelation_lags",
    "coloured_sigma",
    "log_det_r",
    "residual_autocorrelation",
    "theil_u",
]

# corrected σ / (s·σ_CR) above this for some parameter: the report warns in plain words
COLOURED_RATIO_WARNING = 1.5


def theil_u(measured: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """Theil inequality coefficient per output, (n_o,), dimensionless in [0, 1].

    Args:
        measured: z (N, n_o), output units.
        predicted: y (N, n_o), the same units.
    """
    z = np.asarray(measured, dtype=float)
    y = np.asarray(predicted, dtype=float)
    if z.ndim != 2 or z.shape != y.shape:
        raise InputError(
            f"measured, predicted: expected two (N, n_o) arrays of one shape, got {z.shape} "
            f"and {y.shape}"
        )
    rms = lambda a: np.sqrt(np.mean(a**2, axis=0))  # noqa: E731
    # U = √(Σν²/N) / (√(Σz²/N) + √(Σy²/N))
    with np.errstate(invalid="ignore", divide="ignore"):
        return rms(z - y) / (rms(z) + rms(y))


def autocorrelation_lags(n_samples: int, shortest_maneuver: int, cap: int = 100) -> int:
    """Largest lag shown: a quarter of the shortest maneuver, at most ``cap`` samples."""
    return int(max(1, min(cap, shortest_maneuver // 4, n_samples - 1)))


def residual_autocorrelation(
    residuals: np.ndarray, max_lag: int, maneuver_index: np.ndarray | None = None
) -> tuple[np.ndarray, float]:
    """ρ_o(k) for k = 0 … max_lag, (max_lag + 1, n_o), and the white-noise band 1.96/√N.

    An output with zero residual variance gets ρ = 0 at every lag.
    """
    nu = np.asarray(residuals, dtype=float)
    if nu.ndim != 2:
        raise InputError(f"residuals: expected an (N, n_o) array, got shape {nu.shape}")
    gamma = residual_autocovariance(nu, int(max_lag), maneuver_index)
    autocovariance = np.einsum("kii->ki", gamma)
    variance = autocovariance[0].copy()
    variance[variance <= 0] = np.inf
    # ρ_o(k) = R̂_ν,oo(k) / R̂_ν,oo(0)
    rho = autocovariance / variance[None, :]
    # band of a white sequence of N samples: ±1.96/√N
    return rho, 1.96 / np.sqrt(nu.shape[0])


@dataclass(frozen=True)
class ColouredSigma:
    """Cramér–Rao and coloured-residual standard errors of the free parameters.

    Attributes:
        names: free parameters.
        std_cr: s·σ_j, the Cramér–Rao bound scaled by the residual factor s (parameter units).
        std_coloured: the corrected σ (parameter units).
        ratio: std_coloured / std_cr (NaN where either is not finite).
        lag: the correction's lag L (samples); 0 means white residuals.
        s2: the residual variance factor s².
    """

    names: tuple[str, ...]
    std_cr: np.ndarray
    std_coloured: np.ndarray
    ratio: np.ndarray
    lag: int
    s2: float

    @property
    def worst(self) -> tuple[str, float] | None:
        """(parameter, ratio) with the largest finite ratio, or None."""
        finite = np.isfinite(self.ratio)
        if not finite.any():
            return None
        j = int(np.nanargmax(np.where(finite, self.ratio, -np.inf)))
        return self.names[j], float(self.ratio[j])

    @property
    def understated(self) -> bool:
        """Residuals coloured and some CR bound too small by more than the warning ratio."""
        worst = self.worst
        return self.lag > 0 and worst is not None and worst[1] > COLOURED_RATIO_WARNING


def coloured_sigma(estimate, accuracy=None) -> ColouredSigma:
    """The corrected σ beside s·σ_CR for an ``Estimate`` (from ``accuracy`` when given: an
    ``AccuracyResult`` already holds both)."""
    names = tuple(estimate.free_names)
    if accuracy is not None:
        std_cr = np.asarray(accuracy.std_scaled, dtype=float)
        std_col = np.asarray(accuracy.std_coloured, dtype=float)
        lag, s2 = int(accuracy.coloured_lag), float(accuracy.s2)
    else:
        n_data, n_free = int(estimate.n_data), len(names)
        covariance = np.asarray(estimate.covariance, dtype=float)
        s2 = residual_variance_factor(float(estimate.cost), n_data, n_free)
        std = np.sqrt(np.abs(np.diag(covariance))) if n_free else np.zeros(0)
        std_cr = np.sqrt(s2) * std
        if n_free:
            cov_col, lag = coloured_covariance(
                estimate.sensitivities,
                estimate.residuals,
                estimate.r_diag,
                covariance,
                max_lag="auto",
                maneuver_index=estimate.maneuver_index,
            )
            # R̂_ν(0) divides by N; × N·n_o/(N·n_o − n_p) as s² [5.30] (flightid.accuracy.assess)
            cov_col = cov_col * (n_data / (n_data - n_free))
            std_col = np.sqrt(np.abs(np.diag(cov_col)))
        else:
            std_col, lag = np.zeros(0), 0
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = std_col / std_cr
    ratio = np.where(np.isfinite(ratio), ratio, np.nan)
    return ColouredSigma(names, std_cr, std_col, ratio, int(lag), float(s2))


def log_det_r(r_diag: np.ndarray) -> tuple[float, float]:
    """(det R, ln det R) of the diagonal noise covariance; ln det R = Σ ln R_oo."""
    r = np.asarray(r_diag, dtype=float)
    # ln det R = Σ_o ln R_oo (diagonal R)
    log_det = float(np.sum(np.log(r)))
    return float(np.exp(log_det)), log_det
