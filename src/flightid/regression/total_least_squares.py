"""Total least squares (errors in variables) beside ordinary least squares.

Ordinary least squares puts all the error in the response: z = X θ + ν with X exact. In
equation-error regressions of flight data the regressors (measured w, q, δe, ...) are noisy
too; OLS is then biased towards zero ("attenuation"). Total least squares (Golub & Van Loan
1980; Van Huffel & Vandewalle, *The Total Least Squares Problem*, 1991; Jategaonkar,
*Flight Vehicle System Identification*, 2nd ed., §9 ``uAC_regTLS``) lets every column of the
composite matrix [X z] carry an error of the same variance and finds the smallest
perturbation [ΔX Δz] (Frobenius norm) for which (X + ΔX) θ = z + Δz has a solution:

    [X z] = U Σ Vᵀ,   σ_1 ≥ … ≥ σ_{n+1}          (SVD of the N × (n+1) composite matrix)
    v = V[:, n+1]     (right singular vector of the smallest singular value σ_{n+1})
    θ̂_TLS = −v_{1..n} / v_{n+1}

Equivalently θ̂_TLS minimises the orthogonal distance Σ_k (z_k − x_kᵀθ)² / (1 + ‖θ‖²), and
solves (XᵀX − σ²_{n+1} I) θ = Xᵀz: OLS with the noise power σ²_{n+1} taken out of XᵀX.

Existence and uniqueness (Van Huffel & Vandewalle, Thm 2.6): the solution exists and is unique
when σ_n([X z]) > σ_{n+1}([X z]) and v_{n+1} ≠ 0. ``v_{n+1} ≈ 0`` means the response is
(almost) orthogonal to the best-fitting hyperplane — the "nongeneric" problem, refused with
``TotalLeastSquaresError``; a repeated smallest singular value (σ_n ≈ σ_{n+1}) makes the
solution non-unique and is refused too.

Standard errors (two choices, ``covariance=``):

* ``"ols"`` (default; as FVSysID's ``uAC_regTLS`` reports them): the OLS formula at the TLS
  estimates,

      res = z − X θ̂_TLS,   s² = Σ res² / (N − n),   Cov = s² (XᵀX)⁻¹.

  It ignores the errors in X and is optimistic when they matter.
* ``"eiv"`` (errors in variables): the sandwich (M-estimator) covariance of θ̂_TLS as the
  minimiser of Σ_k f_k(θ), f_k = r_k² / c, r_k = z_k − x_kᵀθ, c = 1 + θᵀθ. Its estimating
  equation is Σ_k ψ_k(θ) = 0 with

      ψ_k = r_k x_k + r_k² θ / c                       (−c/2 · ∂f_k/∂θ)

  which has zero mean at the true θ when the errors of [x_k z_k] are independent with one
  common variance σ² (E[r δx] = −σ²θ, E[r²] = σ² c), the TLS model. The covariance of the
  root is (Huber 1967)

      A = Σ_k ∂ψ_k/∂θ = Σ_k [ −x_k x_kᵀ − 2 r_k θ x_kᵀ / c + r_k² I / c − 2 r_k² θ θᵀ / c² ]
      B = Σ_k ψ_k ψ_kᵀ
      Cov = A⁻¹ B A⁻ᵀ

  evaluated at θ̂_TLS. It needs no estimate of σ² and is consistent for the asymptotic
  covariance of TLS (Gleser 1981: σ²c[(X₀ᵀX₀)⁻¹ + Nσ²(X₀ᵀX₀)⁻²] for Gaussian errors);
  the seeded Monte Carlo in tests/test_total_least_squares.py checks it against the spread
  of θ̂_TLS over 400 data sets.

TLS assumes equal error variances in all columns of [X z]: it is not invariant to the
columns' units. Scale the columns by their noise standard deviations first where these
differ (the reference case does not scale).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from flightid.regression.least_squares import (
    LeastSquaresError,
    LeastSquaresResult,
    _fit_sums,
    _pse_sigma2_max,
    _readonly,
    _vif,
    checked_regression_inputs,
)

__all__ = [
    "TLS_COVARIANCES",
    "TotalLeastSquaresError",
    "TotalLeastSquaresResult",
    "total_least_squares",
]

TLS_COVARIANCES = ("ols", "eiv")


class TotalLeastSquaresError(LeastSquaresError):
    """The total-least-squares problem has no (unique) solution, or its input is malformed."""


@dataclass(frozen=True, eq=False)
class TotalLeastSquaresResult(LeastSquaresResult):
    """Frozen result of a total-least-squares fit (``LeastSquaresResult`` surface).

    ``estimates`` are θ̂_TLS; ``residuals`` z − X θ̂_TLS (the response-direction residual the
    OLS-formula σ uses); ``std`` / ``covariance`` those of the ``covariance_method`` chosen
    (module docstring); ``std_ols`` and ``std_eiv`` are both always available.

    Extra attributes:
        singular_values: σ_1 ≥ … ≥ σ_{n+1} of [X z] (units of the columns, unscaled).
        v_last: v_{n+1}, the last component of the smallest right singular vector.
        covariance_method: "ols" or "eiv".
        covariance_ols, covariance_eiv: both covariance matrices (n_p, n_p).
    """

    singular_values: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    v_last: float = float("nan")
    covariance_method: str = "ols"
    covariance_ols: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), repr=False)
    covariance_eiv: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), repr=False)

    @property
    def std_ols(self) -> np.ndarray:
        """√diag(s²(XᵀX)⁻¹) at θ̂_TLS, s² = Σ res² / (N − n_p) (as ``uAC_regTLS``)."""
        return np.sqrt(np.diag(self.covariance_ols))

    @property
    def std_eiv(self) -> np.ndarray:
        """√diag of the errors-in-variables sandwich covariance."""
        return np.sqrt(np.abs(np.diag(self.covariance_eiv)))

    def summary(self) -> str:
        """The least-squares table, titled TLS, with the σ used and σ_n+1 of [X z]."""
        text = super().summary().replace("Least-squares regression", "Total least squares", 1)
        if self.covariance_method == "ols":
            kind = "OLS formula s²(XᵀX)⁻¹ at the TLS estimates"
        else:
            kind = "errors-in-variables sandwich covariance"
        return (
            f"{text}\nstd err: {kind}; smallest singular value of [X z] "
            f"σ_n+1 = {self.singular_values[-1]:.6g}"
        )

    def to_dict(self) -> dict:
        """``LeastSquaresResult.to_dict`` plus ``method`` ("tls"), ``covariance``, each
        parameter's ``std_ols`` and ``std_eiv``, and the ``singular_values`` of [X z]."""
        entry = super().to_dict()
        entry["method"] = "tls"
        entry["covariance"] = self.covariance_method
        for row, ols, eiv in zip(entry["parameters"], self.std_ols, self.std_eiv, strict=True):
            row["std_ols"] = float(ols)
            row["std_eiv"] = float(eiv)
        entry["singular_values"] = [float(s) for s in self.singular_values]
        return entry


def _eiv_covariance(X: np.ndarray, residuals: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Sandwich covariance A⁻¹ B A⁻ᵀ of the TLS estimating equation (module docstring)."""
    n_p = theta.shape[0]
    c = 1.0 + float(theta @ theta)
    r = residuals
    # ψ_k = r_k x_k + r_k² θ / c
    psi = r[:, None] * X + (r**2)[:, None] * theta[None, :] / c
    # B = Σ ψ_k ψ_kᵀ
    B = psi.T @ psi
    # A = Σ [−x xᵀ − 2 r θ xᵀ/c + r² I/c − 2 r² θθᵀ/c²]
    A = (
        -(X.T @ X)
        - 2.0 * np.outer(theta, r @ X) / c
        + float(r @ r) * np.eye(n_p) / c
        - 2.0 * float(r @ r) * np.outer(theta, theta) / c**2
    )
    A_inv = np.linalg.inv(A)
    return A_inv @ B @ A_inv.T


def total_least_squares(
    X: np.ndarray,
    z: np.ndarray,
    names: Sequence[str] | None = None,
    *,
    covariance: str = "ols",
    sigma2_max: float | None = None,
    rcond: float = 1e-10,
    units: Mapping[str, str] | None = None,
) -> TotalLeastSquaresResult:
    """Fit z ≈ X θ by total least squares (SVD of [X z]) with standard errors.

    Args:
        X: regressor matrix (N, n_p), N > n_p + 1; one column per term. Every column of
            [X z] is assumed to carry noise of one common variance (module docstring).
        z: response (N,).
        names: regressor names (default ``x0, x1, ...``).
        covariance: ``"ols"`` (s²(XᵀX)⁻¹ at θ̂_TLS, as ``uAC_regTLS``; default) or ``"eiv"``
            (errors-in-variables sandwich covariance).
        sigma2_max: σ²_max for PSE (as ``least_squares``).
        rcond: |v_{n+1}| below ``rcond`` (the vector has unit length), or a gap
            σ_n − σ_{n+1} below ``rcond``·σ_1, is refused as having no unique solution.
        units: {regressor name: unit of its estimate} for reports.

    Returns:
        A frozen ``TotalLeastSquaresResult``.

    Raises:
        TotalLeastSquaresError: malformed input, a zero column, v_{n+1} ≈ 0 (no TLS
            solution) or σ_n ≈ σ_{n+1} (not unique).
    """
    if covariance not in TLS_COVARIANCES:
        raise TotalLeastSquaresError(
            f"covariance: expected one of {list(TLS_COVARIANCES)}, got {covariance!r}"
        )
    X, z, names, units, norms = checked_regression_inputs(
        X, z, names, units, TotalLeastSquaresError, extra_rows=1
    )
    n, p = X.shape

    # [X z] = U Σ Vᵀ
    composite = np.column_stack([X, z])
    _, singular, vt = np.linalg.svd(composite, full_matrices=False)
    v = vt[-1]
    if singular[-2] - singular[-1] <= rcond * singular[0]:
        raise TotalLeastSquaresError(
            f"[X z]: the smallest singular value is repeated (σ_n = {singular[-2]:.6g}, "
            f"σ_n+1 = {singular[-1]:.6g}); the TLS solution is not unique"
        )
    if abs(v[-1]) < rcond:
        raise TotalLeastSquaresError(
            f"[X z]: the smallest right singular vector has v_n+1 = {v[-1]:.3g} ≈ 0 (below "
            f"{rcond:g}): the response is orthogonal to the fitted hyperplane and the TLS "
            "problem has no solution (nongeneric); use ordinary least squares"
        )
    # θ̂_TLS = −v_{1..n} / v_{n+1}
    theta = -v[:-1] / v[-1]
    fitted, residuals, rss, constant, has_constant, tss = _fit_sums(X, z, theta)
    Xs = X / norms
    singular_x = np.linalg.svd(Xs, compute_uv=False)
    condition = float(singular_x[0] / singular_x[-1]) if singular_x[-1] > 0 else float("inf")
    try:
        xtx_inv = np.linalg.inv(Xs.T @ Xs) / np.outer(norms, norms)
    except np.linalg.LinAlgError:
        raise TotalLeastSquaresError(
            f"X: regressors {list(names)} are linearly dependent"
        ) from None
    # s² = Σ res² / (N − n_p);  Cov_OLS = s² (XᵀX)⁻¹   (the OLS formula at θ̂_TLS)
    s2 = rss / (n - p)
    cov_ols = s2 * xtx_inv
    cov_eiv = _eiv_covariance(X, residuals, theta)
    chosen = cov_ols if covariance == "ols" else cov_eiv
    sigma2_max = _pse_sigma2_max(sigma2_max, z, TotalLeastSquaresError)
    return TotalLeastSquaresResult(
        names=names,
        estimates=_readonly(theta),
        std=_readonly(np.sqrt(np.abs(np.diag(chosen)))),
        covariance=_readonly(chosen),
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
        singular_values=_readonly(singular),
        v_last=float(v[-1]),
        covariance_method=covariance,
        covariance_ols=_readonly(cov_ols),
        covariance_eiv=_readonly(cov_eiv),
    )
