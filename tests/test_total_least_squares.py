"""Total least squares (flightid.regression.total_least_squares) against an SVD written here,
the closed-form identity (XᵀX − σ²_{n+1} I) θ = Xᵀz, the errors-in-variables behaviour
(seeded: TLS unbiased where OLS is attenuated), the two covariances, and named errors."""

from __future__ import annotations

import numpy as np
import pytest

from flightid.errors import InputError
from flightid.regression import (
    TotalLeastSquaresError,
    TotalLeastSquaresResult,
    least_squares,
    total_least_squares,
)


def _eiv_data(seed: int, n: int = 400, noise: float = 0.4):
    """Errors in variables: true regressors x₀ ~ N(0, 1), θ = (1.5, −0.8); every column of
    [X z] carries independent N(0, noise²) errors (the TLS model)."""
    rng = np.random.default_rng(seed)
    x0 = rng.normal(size=(n, 2))
    theta = np.array([1.5, -0.8])
    X = x0 + noise * rng.normal(size=x0.shape)
    z = x0 @ theta + noise * rng.normal(size=n)
    return X, z, theta


def _tls_by_hand(X: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Independent TLS: eigenvector of [X z]ᵀ[X z] for its smallest eigenvalue (eigh, not the
    SVD the library uses), θ = −v_1..n / v_n+1."""
    C = np.column_stack([X, z])
    _, vectors = np.linalg.eigh(C.T @ C)
    v = vectors[:, 0]
    return -v[:-1] / v[-1]


def test_estimates_equal_an_independent_eigen_solution():
    X, z, _ = _eiv_data(3)
    fit = total_least_squares(X, z, ["a", "b"])
    np.testing.assert_allclose(fit.estimates, _tls_by_hand(X, z), rtol=1e-10)
    assert isinstance(fit, TotalLeastSquaresResult)
    assert fit.names == ("a", "b")


def test_estimates_solve_the_deflated_normal_equations():
    # closed form (Van Huffel & Vandewalle Thm 2.7): (XᵀX − σ²_{n+1} I) θ = Xᵀz
    X, z, _ = _eiv_data(4)
    fit = total_least_squares(X, z)
    sigma = np.linalg.svd(np.column_stack([X, z]), compute_uv=False)[-1]
    theta = np.linalg.solve(X.T @ X - sigma**2 * np.eye(2), X.T @ z)
    np.testing.assert_allclose(fit.estimates, theta, rtol=1e-9)
    np.testing.assert_allclose(fit.singular_values[-1], sigma, rtol=1e-12)


def test_exact_data_give_the_ols_solution():
    rng = np.random.default_rng(5)
    X = rng.normal(size=(50, 3))
    z = X @ np.array([2.0, -1.0, 0.5])
    np.testing.assert_allclose(total_least_squares(X, z).estimates, [2.0, -1.0, 0.5], atol=1e-10)


def test_ols_std_is_the_q15_formula_at_the_tls_estimates():
    X, z, _ = _eiv_data(6)
    fit = total_least_squares(X, z)
    theta = _tls_by_hand(X, z)
    res = z - X @ theta
    # CASES.md Q15: s² = Σ res²/(N − n), σ = √diag(s²(XᵀX)⁻¹)
    s2 = res @ res / (X.shape[0] - 2)
    std = np.sqrt(np.diag(s2 * np.linalg.inv(X.T @ X)))
    np.testing.assert_allclose(fit.std, std, rtol=1e-9)
    np.testing.assert_allclose(fit.std_ols, std, rtol=1e-9)
    np.testing.assert_allclose(fit.residuals, res, rtol=1e-8, atol=1e-12)
    assert fit.covariance_method == "ols"


def test_tls_is_unbiased_where_ols_is_attenuated():
    # 40 seeded data sets: OLS shrinks θ by the reliability ratio 1/(1 + 0.4²) ≈ 0.862
    # (classical attenuation), TLS is consistent. Means over the sets:
    ols, tls = [], []
    for seed in range(40):
        X, z, theta = _eiv_data(100 + seed)
        ols.append(least_squares(X, z).estimates)
        tls.append(total_least_squares(X, z).estimates)
    ols_mean, tls_mean = np.mean(ols, axis=0), np.mean(tls, axis=0)
    spread = np.std(tls, axis=0) / np.sqrt(40)
    # attenuation of OLS: 1/(1 + σ_δ²/σ_x²) = 1/1.16
    np.testing.assert_allclose(ols_mean / theta, 1 / 1.16, rtol=0.03)
    assert np.all(np.abs(tls_mean - theta) < 3 * spread)
    assert np.all(np.abs(ols_mean - theta) > 10 * spread)


def test_eiv_std_matches_the_monte_carlo_spread_and_ols_std_understates_it():
    estimates, std_eiv, std_ols = [], [], []
    for seed in range(400):
        X, z, _ = _eiv_data(1000 + seed, n=200, noise=0.6)
        fit = total_least_squares(X, z, covariance="eiv")
        estimates.append(fit.estimates)
        std_eiv.append(fit.std)
        std_ols.append(fit.std_ols)
    spread = np.std(estimates, axis=0, ddof=1)
    # the sandwich σ agrees with the spread of θ̂_TLS to within the Monte Carlo error (≈ 4 %)
    np.testing.assert_allclose(np.mean(std_eiv, axis=0) / spread, 1.0, atol=0.1)
    # the OLS formula ignores the errors in X: too small by about 1/(1 + 0.6²) = 0.74 here
    assert np.all(np.mean(std_ols, axis=0) / spread < 0.85)


def test_to_dict_and_summary_carry_the_method_and_both_sigmas():
    X, z, _ = _eiv_data(7)
    fit = total_least_squares(X, z, ["a", "b"], covariance="eiv")
    entry = fit.to_dict()
    assert entry["method"] == "tls" and entry["covariance"] == "eiv"
    assert entry["parameters"][0]["std"] == pytest.approx(entry["parameters"][0]["std_eiv"])
    assert entry["parameters"][1]["std_ols"] == pytest.approx(fit.std_ols[1])
    assert len(entry["singular_values"]) == 3
    assert "Total least squares" in fit.summary() and "sandwich" in fit.summary()


def test_response_orthogonal_to_the_regressors_has_no_tls_solution():
    # [X z] with z orthogonal to X and larger in norm than X's columns: the smallest right
    # singular vector lies in the X columns, v_{n+1} = 0 (the nongeneric problem)
    X = np.zeros((6, 2))
    X[:3, 0] = [1.0, 1.0, 0.0]
    X[3:, 1] = [1.0, -1.0, 0.5]
    z = np.array([3.0, -3.0, 0.0, 0.0, 0.0, 0.0])
    with pytest.raises(TotalLeastSquaresError, match="v_n\\+1"):
        total_least_squares(X, z)


def test_repeated_smallest_singular_value_is_refused():
    # orthogonal columns of equal norm: σ_n = σ_n+1, the TLS solution is not unique
    X = np.eye(4)[:, :2]
    z = np.eye(4)[:, 2]
    with pytest.raises(TotalLeastSquaresError, match="not unique"):
        total_least_squares(X, z)


@pytest.mark.parametrize(
    ("X", "z", "options", "match"),
    [
        (np.ones((5, 2)), np.ones(4), {}, "z: expected a series of 5"),
        (np.ones((3, 2)), np.ones(3), {}, "more samples than regressors"),
        (np.column_stack([np.arange(9.0), np.zeros(9)]), np.arange(9.0), {}, "identically zero"),
        (np.eye(9)[:, :2], np.arange(9.0), {"covariance": "robust"}, "covariance: expected"),
        (np.eye(9)[:, :2], np.arange(9.0), {"names": ["a"]}, "names: expected 2"),
        (np.full((9, 2), np.nan), np.arange(9.0), {}, "finite"),
    ],
)
def test_named_errors(X, z, options, match):
    with pytest.raises(TotalLeastSquaresError, match=match) as info:
        total_least_squares(X, z, **options)
    assert isinstance(info.value, InputError)
