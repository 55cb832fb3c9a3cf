"""Ordinary least squares with the statistics an engineer reads (RP-1153 §3, [3.1–3.8]).

Model: z = X θ + ν, with X the (N, n_p) regressor matrix and z the measured response.

The estimate minimises the residual sum of squares RSS = ‖z − Xθ‖²; it is computed from a
QR factorisation X = Q R (numerically equivalent to θ = (XᵀX)⁻¹Xᵀz [3.4] without forming
XᵀX), with a rank check from the SVD of R.

Statistics (N samples, n_p parameters):

    s²        = RSS / (N − n_p)                         fit error variance
    Cov(θ̂)    = s² (XᵀX)⁻¹                              classical covariance
    t_j       = θ̂_j / std_j ,  partial F_j = t_j²       (F to remove term j, 1 and N − n_p dof)
    R²        = 1 − RSS / TSS                           TSS about the mean when the model has
                                                        a constant column, about zero otherwise
    R²_adj    = 1 − (1 − R²)(N − k0)/(N − n_p)          k0 = 1 with a constant, else 0
    F_overall = ((TSS − RSS)/(n_p − k0)) / s²
    PSE       = RSS/N + σ²_max n_p / N                  predicted squared error (NASA TP-1916)

Default σ: the classical standard errors assume white residuals. Equation-error residuals of
flight data are usually coloured (model error, not measurement noise), and then s²(XᵀX)⁻¹ is
optimistic. ``std`` is therefore the σ the residuals support (``flightid.coloured``,
the residual-autocorrelation sandwich with G_i = x_iᵀ, R = 1):

    Cov_col(θ̂) = (XᵀX)⁻¹ [ Σ_i Σ_j x_i R̂_ν(i − j) x_jᵀ ] (XᵀX)⁻¹ · N/(N − n_p)

when the residuals are autocorrelated at lag 1 (automatic lag L > 0), and the classical
s²(XᵀX)⁻¹ when they are white (L = 0). The classical σ stays beside it as ``std_cr``; the t,
partial F and p statistics (the stepwise tests of term significance) use the classical σ.

Collinearity: the condition number is that of X with its columns scaled to unit length
(so it does not depend on units), and the variance inflation factor of column j is
VIF_j = 1/(1 − R_j²), R_j² from regressing column j on the other columns (with the constant);
equivalently the diagonal of the inverse correlation matrix of the non-constant columns.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy import stats

from flightid.coloured import (
    COLOURED,
    CRAMER_RAO,
    complete_default_sigma,
    default_sigma,
    sigma_ratio,
)
from flightid.errors import InputError, describe
from flightid.numbers import format_with_sigma
from flightid.results import ResultSurface, check_method, finite_or_none, t_intervals

__all__ = ["LeastSquaresResult", "least_squares", "LeastSquaresError"]


class LeastSquaresError(InputError):
    """The regression problem is malformed (shapes, rank, too few samples)."""


@dataclass(frozen=True, eq=False)
class LeastSquaresResult(ResultSurface):
    """Frozen result of a least-squares fit. Arrays are read-only.

    The result surface (``flightid.results``): ``summary()``, ``to_dict()`` / ``to_json()``,
    ``to_frame()`` (pandas), ``conf_int(level=0.95, method="t")`` and ``plot()``.

    Attributes:
        names: regressor names, one per column of X.
        estimates: θ̂ (n_p,).
        std: the default standard errors: ``std_cr`` when the residuals are white, the
            coloured-residual σ when they are not (``std_kind``; module docstring).
        covariance: s² (XᵀX)⁻¹ (n_p, n_p), the classical covariance.
        residuals: z − X θ̂ (N,).
        fitted: X θ̂ (N,).
        rss, tss: residual and total sums of squares.
        n_samples, n_parameters: N and n_p.
        has_constant: whether a column is constant (R², F are then about the mean).
        sigma2_max: the σ²_max used in PSE.
        units: unit of each estimate (``""`` where unknown; ``()`` when not given).
        std_cr: classical standard errors sqrt(diag(s²(XᵀX)⁻¹)) (white residuals).
        covariance_default: the covariance behind ``std``.
        std_kind: ``"cramer_rao"`` (classical) or ``"coloured"``: which σ ``std`` is.
        residuals_white: the residuals' lag-1 autocorrelation inside ±1.96/√N (None: not
            tested, ``coloured=False``).
        coloured_lag: lag L of the coloured-residual correction (samples; 0 when white).
    """

    names: tuple[str, ...]
    estimates: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    residuals: np.ndarray
    fitted: np.ndarray
    rss: float
    tss: float
    n_samples: int
    n_parameters: int
    has_constant: bool
    sigma2_max: float
    condition_number: float
    vif: np.ndarray = field(repr=False)
    units: tuple[str, ...] = ()
    std_cr: np.ndarray | None = None
    covariance_default: np.ndarray | None = None
    std_kind: str = CRAMER_RAO
    residuals_white: bool | None = None
    coloured_lag: int = 0

    def __post_init__(self) -> None:
        # without a separate default σ, the default is the classical σ
        complete_default_sigma(self, LeastSquaresError)

    @property
    def sigma_ratio(self) -> np.ndarray:
        """std / std_cr (n_p,): how much the classical σ understates the default σ."""
        return sigma_ratio(self.std, self.std_cr)

    # ----------------------------------------------------------------- statistics
    @property
    def dof(self) -> int:
        """Residual degrees of freedom N − n_p."""
        return self.n_samples - self.n_parameters

    @property
    def s2(self) -> float:
        """Fit error variance s² = RSS/(N − n_p)."""
        return self.rss / self.dof if self.dof > 0 else float("nan")

    @property
    def r2(self) -> float:
        """Coefficient of determination R² = 1 − RSS/TSS."""
        return 1.0 - self.rss / self.tss if self.tss > 0 else float("nan")

    @property
    def r2_adjusted(self) -> float:
        """R² adjusted for the degrees of freedom."""
        k0 = 1 if self.has_constant else 0
        if self.dof <= 0:
            return float("nan")
        return 1.0 - (1.0 - self.r2) * (self.n_samples - k0) / self.dof

    @property
    def f_overall(self) -> float:
        """Overall F statistic ((TSS − RSS)/(n_p − k0)) / s²."""
        k0 = 1 if self.has_constant else 0
        n_reg = self.n_parameters - k0
        if n_reg <= 0 or self.dof <= 0 or self.s2 == 0:
            return float("nan")
        return ((self.tss - self.rss) / n_reg) / self.s2

    @cached_property
    def t_values(self) -> np.ndarray:
        """t_j = θ̂_j / std_cr,j: the classical t statistic (white residuals)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.estimates / self.std_cr

    @cached_property
    def partial_f(self) -> np.ndarray:
        """Partial F of each term (F to remove it), = t_j²."""
        return self.t_values**2

    @cached_property
    def p_values(self) -> np.ndarray:
        """Two-sided p-values of the t statistics."""
        return 2.0 * stats.t.sf(np.abs(self.t_values), self.dof)

    @property
    def pse(self) -> float:
        """Predicted squared error RSS/N + σ²_max n_p/N (Klein, Batterson & Murphy, TP-1916)."""
        return self.rss / self.n_samples + self.sigma2_max * self.n_parameters / self.n_samples

    def parameter(self, name: str) -> tuple[float, float]:
        """(estimate, standard error) of the regressor ``name``."""
        if name not in self.names:
            raise KeyError(f"no regressor named {name!r}; regressors: {list(self.names)}")
        j = self.names.index(name)
        return float(self.estimates[j]), float(self.std[j])

    @property
    def unit_map(self) -> dict[str, str]:
        """{regressor: unit of its estimate}; ``""`` where none is known."""
        units = tuple(self.units) or ("",) * len(self.names)
        return dict(zip(self.names, units, strict=True))

    @property
    def conf_int_names(self) -> list[str]:
        """The rows of ``conf_int``: the regressors, in order."""
        return list(self.names)

    def conf_int(
        self, level: float = 0.95, method: str = "t", *, std: str = "default"
    ) -> np.ndarray:
        """Individual confidence intervals θ̂_j ± q·σ_j of the estimates.

        Args:
            level: confidence level c, e.g. 0.95.
            method: ``"t"`` (q = t_{(1+c)/2}(N − n_p), exact for Gaussian residuals, default)
                or ``"normal"`` (q = z_{(1+c)/2}, the large-sample limit).
            std: ``"default"`` (σ = ``std``) or ``"cr"`` (the classical σ, ``std_cr``).

        Returns:
            (n_p, 2) array [lower, upper], rows as in ``conf_int_names``.
        """
        check_method(method, ("t", "normal"))
        check_method(std, ("default", "cr"), "std")
        sigma = self.std if std == "default" else self.std_cr
        return t_intervals(self.estimates, sigma, level, self.dof, method)

    def _frame_rows(self) -> list[dict]:
        intervals = self.conf_int() if self.dof > 0 else np.full((len(self.names), 2), np.nan)
        units = self.unit_map
        return [
            {
                "name": name,
                "value": float(self.estimates[j]),
                "std": float(self.std[j]),
                "std_cr": float(self.std_cr[j]),
                "t": float(self.t_values[j]),
                "partial_f": float(self.partial_f[j]),
                "p": float(self.p_values[j]),
                "vif": float(self.vif[j]),
                "lower": float(intervals[j, 0]),
                "upper": float(intervals[j, 1]),
                "unit": units[name],
            }
            for j, name in enumerate(self.names)
        ]

    # ----------------------------------------------------------------- reports
    def summary(self) -> str:
        """A statsmodels-like text table (with a unit column when units are known)."""
        lines = [
            "Least-squares regression",
            "=" * 78,
            f"N = {self.n_samples:<8d} n_p = {self.n_parameters:<4d} dof = {self.dof:<8d}"
            f"R² = {self.r2:.6f}   adj. R² = {self.r2_adjusted:.6f}",
            f"s² = {self.s2:.6g}   s = {np.sqrt(self.s2):.6g}   F = {self.f_overall:.6g}   "
            f"PSE = {self.pse:.6g} (σ²_max = {self.sigma2_max:.4g})",
            f"condition number (unit-length columns) = {self.condition_number:.4g}",
            *self._sigma_lines(),
            "-" * 78,
            f"{'term':<16s}{'estimate':>14s}{'std err':>13s}{'t':>10s}{'partial F':>12s}"
            f"{'p':>8s}{'VIF':>9s}",
            "-" * 78,
        ]
        units = self.unit_map
        show_units = any(units.values())
        if show_units:
            lines[-2] += "  unit"
        for j, name in enumerate(self.names):
            vif = self.vif[j]
            vif_text = "" if np.isnan(vif) else f"{vif:9.3g}"
            # σ to two significant digits, the estimate to σ's decimal place
            value_text, std_text = format_with_sigma(self.estimates[j], self.std[j])
            lines.append(
                f"{name:<16s}{value_text:>14s}{std_text:>13s}"
                f"{self.t_values[j]:>10.3g}{self.partial_f[j]:>12.4g}"
                f"{self.p_values[j]:>8.3f}{vif_text:>9s}"
                + (f"  {units[name]}" if show_units else "")
            )
        lines.append("=" * 78)
        return "\n".join(lines)

    def _sigma_lines(self) -> list[str]:
        """What ``std err`` is, when it is not the classical σ."""
        if self.std_kind != COLOURED:
            return []
        ratio = self.sigma_ratio[np.isfinite(self.sigma_ratio)]
        span = f", {ratio.min():.2g}–{ratio.max():.2g}× the classical σ" if ratio.size else ""
        return [
            f"std err: coloured-residual σ (residuals autocorrelated to lag "
            f"{self.coloured_lag}){span}",
            "(std_cr); t, partial F and p use the classical σ",
        ]

    def to_dict(self) -> dict:
        """Plain-Python dictionary (JSON-ready)."""
        return {
            "parameters": [
                {
                    "name": n,
                    "value": float(v),
                    "std": finite_or_none(s),
                    "std_cr": finite_or_none(c),
                    "unit": self.unit_map[n],
                }
                for n, v, s, c in zip(
                    self.names, self.estimates, self.std, self.std_cr, strict=True
                )
            ],
            "std_kind": self.std_kind,
            "residuals_white": None if self.residuals_white is None else bool(self.residuals_white),
            "coloured_lag": int(self.coloured_lag),
            "r2": float(self.r2),
            "r2_adjusted": float(self.r2_adjusted),
            "s2": float(self.s2),
            "f_overall": float(self.f_overall),
            "pse": float(self.pse),
            "n_samples": self.n_samples,
            "condition_number": float(self.condition_number),
        }


def _fit_sums(
    X: np.ndarray, z: np.ndarray, theta: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, bool, float]:
    """(fitted X θ, residuals z − X θ, RSS, mask of constant columns, whether there is one,
    TSS) of the fit θ: TSS about the mean of z with a constant regressor, else about 0."""
    fitted = X @ theta
    residuals = z - fitted
    # RSS = Σ (z − X θ)²
    rss = float(residuals @ residuals)
    constant = _constant_columns(X)
    has_constant = bool(constant.any())
    # TSS = Σ (z − z̄)² (with a constant regressor) or Σ z²
    tss = float(np.sum((z - z.mean()) ** 2)) if has_constant else float(z @ z)
    return fitted, residuals, rss, constant, has_constant, tss


def _pse_sigma2_max(sigma2_max: float | None, z: np.ndarray, error: type[Exception]) -> float:
    """σ²_max of PSE: the given value (a non-negative finite number, else ``error``) or, by
    default, the variance of z about its mean."""
    if sigma2_max is None:
        # σ²_max = mean((z − z̄)²)
        return float(np.mean((z - z.mean()) ** 2))
    if not (np.isfinite(sigma2_max) and sigma2_max >= 0):
        raise error(f"sigma2_max: expected a non-negative finite number, got {sigma2_max!r}")
    return float(sigma2_max)


def _readonly(array: np.ndarray) -> np.ndarray:
    array = np.array(array, dtype=float)
    array.flags.writeable = False
    return array


def _constant_columns(X: np.ndarray) -> np.ndarray:
    """Mask of columns that are constant and non-zero (a bias term)."""
    if X.shape[0] == 0:
        return np.zeros(X.shape[1], dtype=bool)
    spread = np.ptp(X, axis=0)
    scale = np.max(np.abs(X), axis=0)
    return (scale > 0) & (spread <= 1e-12 * scale)


def _vif(X: np.ndarray, constant: np.ndarray) -> np.ndarray:
    """Variance inflation factors: diag of the inverse correlation matrix (NaN for bias)."""
    vif = np.full(X.shape[1], np.nan)
    varying = np.flatnonzero(~constant)
    if varying.size == 0:
        return vif
    if varying.size == 1:
        vif[varying] = 1.0
        return vif
    Z = X[:, varying]
    if constant.any():
        Z = Z - Z.mean(axis=0)
    norms = np.linalg.norm(Z, axis=0)
    norms[norms == 0] = 1.0
    C = (Z / norms).T @ (Z / norms)
    try:
        vif[varying] = np.diag(np.linalg.inv(C))
    except np.linalg.LinAlgError:
        vif[varying] = np.inf
    return vif


def checked_regression_inputs(
    X: np.ndarray,
    z: np.ndarray,
    names: Sequence[str] | None,
    units: Mapping[str, str] | None,
    error: type[Exception],
    extra_rows: int = 0,
) -> tuple[np.ndarray, np.ndarray, tuple[str, ...], dict[str, str], np.ndarray]:
    """X (N, n_p) and z (N,) as float arrays, names, units and the column norms ‖X_j‖, checked.

    Raises ``error`` naming what was expected and what came: not a matrix / series, N ≤ n_p +
    ``extra_rows``, non-finite values, wrong names or units, an identically zero column.
    """
    X = np.asarray(X, dtype=float)
    z = np.asarray(z, dtype=float)
    if X.ndim == 1:
        X = X[:, None]
    if X.ndim != 2:
        raise error(f"X: expected an (N, n_p) matrix, got {describe(X)}")
    if z.ndim != 1 or z.shape[0] != X.shape[0]:
        raise error(
            f"z: expected a series of {X.shape[0]} samples (the rows of X), got {describe(z)}"
        )
    n, p = X.shape
    if p == 0:
        raise error("X: expected at least one regressor column, got none")
    if n <= p + extra_rows:
        more = "regressors" if extra_rows == 0 else f"regressors + {extra_rows}"
        raise error(f"X: expected more samples than {more}, got N = {n} and n_p = {p}")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(z))):
        raise error("X, z: values must be finite")
    names = tuple(f"x{j}" for j in range(p)) if names is None else tuple(names)
    if len(names) != p:
        raise error(f"names: expected {p} names (columns of X), got {len(names)}")
    units = dict(units or {})
    unknown = sorted(set(units) - set(names))
    if unknown:
        raise error(f"units: expected regressor names from {list(names)}, got {unknown}")
    norms = np.linalg.norm(X, axis=0)
    if np.any(norms == 0):
        zero = [names[j] for j in np.flatnonzero(norms == 0)]
        raise error(f"X: regressor column(s) {zero} are identically zero")
    return X, z, names, units, norms


def _default_sigma(
    X: np.ndarray,
    residuals: np.ndarray,
    xtx_inv: np.ndarray,
    covariance: np.ndarray,
    coloured: bool,
    maneuver_index: np.ndarray | None,
):
    """The default σ of a fit (``flightid.coloured.default_sigma``): G_i = x_iᵀ
    (one output), R = 1, the bread (XᵀX)⁻¹; the classical covariance when white."""
    from flightid.coloured import DefaultSigma

    if not coloured:
        # not tested: residuals_white None
        return DefaultSigma(covariance, np.sqrt(np.diag(covariance)), CRAMER_RAO, 0, None)
    if maneuver_index is not None:
        maneuver_index = np.asarray(maneuver_index)
        if maneuver_index.shape != residuals.shape:
            raise LeastSquaresError(
                f"maneuver_index: expected one entry per sample ({residuals.shape[0]}), got "
                f"shape {maneuver_index.shape}"
            )
    # Cov_col = (XᵀX)⁻¹ [Σ_i Σ_j x_i R̂_ν(i − j) x_jᵀ] (XᵀX)⁻¹ · N/(N − n_p)
    sigma = default_sigma(X[:, None, :], residuals[:, None], np.ones(1), xtx_inv, maneuver_index)
    if sigma.kind == CRAMER_RAO:
        # white: the classical s²(XᵀX)⁻¹ itself (the sandwich at L = 0 differs only by round-off)
        return DefaultSigma(
            covariance, np.sqrt(np.diag(covariance)), CRAMER_RAO, 0, sigma.residuals_white
        )
    return sigma


def least_squares(
    X: np.ndarray,
    z: np.ndarray,
    names: Sequence[str] | None = None,
    *,
    sigma2_max: float | None = None,
    rcond: float = 1e-12,
    units: Mapping[str, str] | None = None,
    coloured: bool = True,
    maneuver_index: np.ndarray | None = None,
) -> LeastSquaresResult:
    """Fit z ≈ X θ by least squares and compute the regression statistics.

    Args:
        X: regressor matrix (N, n_p), N > n_p; any units, one column per term.
        z: response (N,), in the unit of the coefficient being modelled.
        names: regressor names (default ``x0, x1, ...``).
        sigma2_max: σ²_max for PSE, in z's unit squared. Default: the variance of z about its
            mean, (1/N)Σ(z − z̄)² (the mean-square error of the constant-only model, the upper
            bound used by Morelli for PSE).
        rcond: X is rejected as rank deficient when its smallest singular value (of the
            unit-length-scaled columns) is below ``rcond`` times the largest.
        units: {regressor name: unit of its estimate} for reports (any subset of ``names``).
        coloured: compute the coloured-residual σ (module docstring) and report it as
            ``std`` when the residuals are coloured; False gives the classical σ only (the
            stepwise search, which needs only the classical statistics of many fits).
        maneuver_index: (N,) maneuver of each sample when the rows are several maneuvers
            end to end: residual products never pair samples of different maneuvers.

    Returns:
        A frozen ``LeastSquaresResult``.
    """
    X, z, names, units, norms = checked_regression_inputs(X, z, names, units, LeastSquaresError)
    n, p = X.shape
    # Column scaling to unit length makes the rank test and the condition number unit-free.
    Xs = X / norms
    Q, R = np.linalg.qr(Xs)
    singular = np.linalg.svd(R, compute_uv=False)
    condition = float(singular[0] / singular[-1]) if singular[-1] > 0 else float("inf")
    if singular[-1] < rcond * singular[0]:
        raise LeastSquaresError(
            f"X: regressors {list(names)} are linearly dependent (condition number "
            f"{condition:.3g} of the unit-length columns)"
        )
    # θ_s = R⁻¹ Qᵀ z, θ = θ_s / norms   (equivalent to (XᵀX)⁻¹Xᵀz, [3.4])
    theta_scaled = np.linalg.solve(R, Q.T @ z)
    theta = theta_scaled / norms
    fitted, residuals, rss, constant, has_constant, tss = _fit_sums(X, z, theta)
    s2 = rss / (n - p)
    # (XᵀX)⁻¹ = D⁻¹ R⁻¹ R⁻ᵀ D⁻¹ with D = diag(norms)
    R_inv = np.linalg.solve(R, np.eye(p))
    xtx_inv = (R_inv @ R_inv.T) / np.outer(norms, norms)
    # Cov(θ̂) = s² (XᵀX)⁻¹
    covariance = s2 * xtx_inv
    std = np.sqrt(np.diag(covariance))
    sigma2_max = _pse_sigma2_max(sigma2_max, z, LeastSquaresError)
    sigma = _default_sigma(X, residuals, xtx_inv, covariance, coloured, maneuver_index)
    return LeastSquaresResult(
        names=names,
        estimates=_readonly(theta),
        std=_readonly(sigma.std),
        std_cr=_readonly(std),
        covariance=_readonly(covariance),
        covariance_default=_readonly(sigma.covariance),
        std_kind=sigma.kind,
        residuals_white=sigma.residuals_white,
        coloured_lag=sigma.lag,
        residuals=_readonly(residuals),
        fitted=_readonly(fitted),
        rss=rss,
        tss=tss,
        n_samples=n,
        n_parameters=p,
        has_constant=has_constant,
        sigma2_max=sigma2_max,
        condition_number=condition,
        vif=_readonly(_vif(X, constant)),
        units=tuple(str(units.get(n, "")) for n in names) if units else (),
    )
