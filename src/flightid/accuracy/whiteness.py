"""Residual whiteness of any estimator: autocorrelation with its white-noise band and the
Ljung–Box portmanteau test, per output.

Every estimator that leaves residuals (output error: z − y; equation-error regression:
z − Xθ̂; filter error: the innovations z − ỹ) can call ``residual_whiteness(residuals)``. The
Cramér–Rao and least-squares standard errors assume white residuals; coloured residuals say
that the model (or the noise model: output error without process noise in turbulence) is
wrong, and that the standard errors are optimistic (``flightid.accuracy.coloured_covariance``).

Per output o, with ν the residuals of N samples in M maneuvers (products never pair samples of
different maneuvers, ``flightid.accuracy.coloured.residual_autocovariance``):

    R̂_o(k) = (1/N) Σ_i ν_i,o ν_{i+k},o ,   ρ_o(k) = R̂_o(k) / R̂_o(0),   k = 0 … L

For a white sequence each ρ_o(k), k ≥ 1, is approximately N(0, 1/N) (Bartlett), so 95 % of the
lags fall inside the band ±1.96/√N. Two numbers per output:

* ``fraction_outside``: the fraction of the lags 1 … L with |ρ_o(k)| > 1.96/√N (≈ 0.05 for
  white residuals; a smooth, coloured residual gives most of the first lags outside);
* the Ljung–Box statistic over the first m lags (Ljung & Box, Biometrika 65, 1978),

      Q_o = N (N + 2) Σ_{k=1..m} ρ_o(k)² / (N − M k)

  (N − M k is the number of products at lag k, N − k for one maneuver), approximately
  χ²(m) for white residuals; the p-value is P(χ²(m) > Q_o). No degrees of freedom are
  subtracted for the estimated parameters (the Box–Pierce correction is for ARMA
  parameters, not for regression or output-error parameters), so the test is slightly
  conservative. ``white`` is p ≥ 1 − level (0.05 by default).

Lags: L defaults to a quarter of the shortest maneuver, at most 100 samples (the report's
figure); m defaults to min(20, L) (Box & Jenkins' customary 20 lags; fewer on short records).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from flightid.accuracy.chi_square import chi_square_survival
from flightid.accuracy.coloured import residual_autocovariance
from flightid.errors import InputError, describe

__all__ = [
    "Whiteness",
    "WhitenessError",
    "default_lags",
    "estimate_whiteness",
    "residual_whiteness",
]


class WhitenessError(InputError):
    """The residuals or lags given to ``residual_whiteness`` are malformed."""


@dataclass(frozen=True)
class Whiteness:
    """Residual autocorrelation and whiteness tests per output (module docstring).

    Attributes:
        names: output names.
        rho: ρ_o(k), (L + 1, n_o), k = 0 … L; ρ(0) = 1 (0 for a zero residual).
        band: 1.96/√N, the 95 % white-noise band of ρ(k).
        n_samples: N.
        n_maneuvers: M.
        fraction_outside: fraction of the lags 1 … L outside the band, (n_o,).
        ljung_box_lags: m.
        ljung_box: Q_o, (n_o,).
        p_value: P(χ²(m) > Q_o), (n_o,).
        level: the test's level (``white`` is p ≥ 1 − level).
        dt: sample interval in s (lag axis of the figure), or None.
    """

    names: tuple[str, ...]
    rho: np.ndarray
    band: float
    n_samples: int
    n_maneuvers: int
    fraction_outside: np.ndarray
    ljung_box_lags: int
    ljung_box: np.ndarray
    p_value: np.ndarray
    level: float = 0.95
    dt: float | None = None

    @property
    def max_lag(self) -> int:
        """L, the largest lag of ``rho`` (samples)."""
        return int(self.rho.shape[0] - 1)

    @property
    def white(self) -> np.ndarray:
        """Per output: Ljung–Box does not reject whiteness at the level (p ≥ 1 − level)."""
        return self.p_value >= 1.0 - self.level

    def to_dict(self) -> dict:
        """JSON entry: ``method`` ("ljung_box"), ``band``, ``max_lag``, ``ljung_box_lags``,
        ``level``, and per output ``outputs[name]`` = {``rho_1``, ``fraction_outside``,
        ``lags_outside``, ``ljung_box_q``, ``p_value``, ``white``, ``rho`` (k = 0 … L)}."""
        outputs = {}
        for j, name in enumerate(self.names):
            rho = self.rho[:, j]
            outputs[name] = {
                "rho_1": float(rho[1]) if rho.shape[0] > 1 else None,
                "fraction_outside": float(self.fraction_outside[j]),
                "lags_outside": int(np.sum(np.abs(rho[1:]) > self.band)),
                "ljung_box_q": float(self.ljung_box[j]),
                "p_value": float(self.p_value[j]),
                "white": bool(self.white[j]),
                "rho": [float(v) for v in rho],
            }
        return {
            "method": "ljung_box",
            "band": float(self.band),
            "max_lag": self.max_lag,
            "ljung_box_lags": int(self.ljung_box_lags),
            "level": float(self.level),
            "n_samples": int(self.n_samples),
            "outputs": outputs,
        }

    def summary(self) -> str:
        """One line per output: ρ(1), lags outside the band, Q, p, white or coloured."""
        lines = [
            f"residual whiteness (N = {self.n_samples}, band ±{self.band:.3g}, "
            f"Ljung–Box over {self.ljung_box_lags} lags)"
        ]
        for j, name in enumerate(self.names):
            rho1 = self.rho[1, j] if self.max_lag >= 1 else float("nan")
            verdict = "white" if self.white[j] else "coloured"
            lines.append(
                f"  {name:<10s} ρ(1) {rho1:+.3f}   outside {100 * self.fraction_outside[j]:5.1f} %"
                f" of {self.max_lag} lags   Q {self.ljung_box[j]:10.4g}   p {self.p_value[j]:.3g}"
                f"   {verdict}"
            )
        return "\n".join(lines)


def _maneuver_lengths(maneuver_index: np.ndarray | None, n: int) -> list[int]:
    if maneuver_index is None:
        return [n]
    index = np.asarray(maneuver_index)
    if index.shape != (n,):
        raise WhitenessError(
            f"maneuver_index: expected {n} entries (one per residual row), got {describe(index)}"
        )
    return [int(np.sum(index == k)) for k in np.unique(index)]


def default_lags(n_samples: int, shortest_maneuver: int, cap: int = 100) -> int:
    """L: a quarter of the shortest maneuver, at most ``cap`` samples, at least 1."""
    return int(max(1, min(cap, shortest_maneuver // 4, n_samples - 1)))


def residual_whiteness(
    residuals: np.ndarray,
    names: Sequence[str] | None = None,
    *,
    max_lag: int | None = None,
    ljung_box_lags: int | None = None,
    maneuver_index: np.ndarray | None = None,
    level: float = 0.95,
    dt: float | None = None,
) -> Whiteness:
    """Autocorrelation, band, fraction outside and Ljung–Box test of each residual column.

    Args:
        residuals: ν (N,) or (N, n_o) in the outputs' units (output error, regression or
            filter-error innovations).
        names: output names (default ``y0, y1, ...``).
        max_lag: L, the largest lag (samples); default ``default_lags``.
        ljung_box_lags: m, lags of the Ljung–Box sum; default min(20, L); at most L.
        maneuver_index: (N,) maneuver of each row; lags never pair different maneuvers.
        level: confidence level of the band's companion test (``white``: p ≥ 1 − level).
        dt: sample interval in s, kept for plotting.
    """
    nu = np.asarray(residuals, dtype=float)
    if nu.ndim == 1:
        nu = nu[:, None]
    if nu.ndim != 2 or nu.shape[0] < 3:
        raise WhitenessError(
            f"residuals: expected an (N,) or (N, n_o) array with N ≥ 3, got {describe(nu)}"
        )
    if not np.all(np.isfinite(nu)):
        raise WhitenessError("residuals: values must be finite")
    n, n_o = nu.shape
    names = tuple(f"y{j}" for j in range(n_o)) if names is None else tuple(names)
    if len(names) != n_o:
        raise WhitenessError(f"names: expected {n_o} names (columns of residuals), got {names}")
    if not 0.0 < level < 1.0:
        raise WhitenessError(f"level: expected a number in (0, 1), got {level!r}")
    lengths = _maneuver_lengths(maneuver_index, n)
    shortest = min(lengths)
    if max_lag is None:
        max_lag = default_lags(n, shortest)
    if isinstance(max_lag, bool) or not isinstance(max_lag, (int, np.integer)):
        raise WhitenessError(f"max_lag: expected a positive integer, got {max_lag!r}")
    if not 1 <= max_lag < shortest:
        raise WhitenessError(
            f"max_lag: expected 1 … {shortest - 1} (below the shortest maneuver's "
            f"{shortest} samples), got {max_lag}"
        )
    m = min(20, int(max_lag)) if ljung_box_lags is None else ljung_box_lags
    if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or not 1 <= m <= max_lag:
        raise WhitenessError(f"ljung_box_lags: expected 1 … {max_lag} (max_lag), got {m!r}")
    gamma = residual_autocovariance(nu, int(max_lag), maneuver_index)
    autocovariance = np.einsum("kii->ki", gamma)
    variance = autocovariance[0].copy()
    variance[variance <= 0] = np.inf
    # ρ_o(k) = R̂_o(k) / R̂_o(0)
    rho = autocovariance / variance[None, :]
    # band of a white sequence of N samples: ±1.96/√N
    band = 1.96 / np.sqrt(n)
    fraction = np.mean(np.abs(rho[1:]) > band, axis=0)
    k = np.arange(1, m + 1)
    pairs = n - len(lengths) * k
    # Q_o = N (N + 2) Σ_{k=1..m} ρ_o(k)² / (N − M k)
    q = n * (n + 2) * np.sum(rho[1 : m + 1] ** 2 / pairs[:, None], axis=0)
    # p = P(χ²_m > Q): the χ² survival function (what scipy.stats.chi2.sf evaluates)
    p_value = np.asarray(chi_square_survival(m, q), dtype=float)
    return Whiteness(
        names=names,
        rho=rho,
        band=float(band),
        n_samples=n,
        n_maneuvers=len(lengths),
        fraction_outside=fraction,
        ljung_box_lags=int(m),
        ljung_box=q,
        p_value=p_value,
        level=float(level),
        dt=None if dt is None else float(dt),
    )


def estimate_whiteness(estimate, level: float = 0.95) -> Whiteness:
    """``residual_whiteness`` of an estimate's residuals with the default lags.

    Works for any result carrying ``residuals`` (N, n_o), ``output_names`` and
    ``maneuver_index`` (N,) — the output-error ``Estimate``, or a filter-error result whose
    residuals are its innovations — and, when present, ``time`` (s) for ``dt``.
    """
    residuals = np.asarray(estimate.residuals, dtype=float)
    index = getattr(estimate, "maneuver_index", None)
    time = getattr(estimate, "time", None)
    dt = None
    if time is not None and np.size(time) > 1:
        steps = np.diff(np.asarray(time, dtype=float))
        dt = float(np.median(steps[steps > 0])) if np.any(steps > 0) else None
    return residual_whiteness(
        residuals,
        tuple(estimate.output_names),
        maneuver_index=None if index is None else np.asarray(index),
        level=level,
        dt=dt,
    )
