"""Confidence levels, information-matrix intervals, correlation warnings, coloured residuals."""

from __future__ import annotations

import numpy as np
import pytest

from flightid.accuracy import (
    AccuracyWarning,
    assess,
    beale_factor,
    coloured_covariance,
    contour_level,
    correlation_warnings,
    ellipsoid_intervals,
)
from flightid.accuracy.coloured import automatic_lag
from flightid.errors import InputError
from test_accuracy_models import linear_estimate


def test_contour_levels_match_tables():
    # t_{0.975}(10) = 2.2281 (any t table), so F_{0.95}(1, 10) = 4.9646
    assert contour_level(0.95, 12, 2, 1.0, "individual", "t") == pytest.approx(2.2281**2, rel=1e-4)
    # χ²_{0.95}(1) = 3.8415, χ²_{0.95}(3) = 7.8147 (χ² table)
    assert contour_level(0.95, 100, 3, 1.0, "individual", "normal") == pytest.approx(3.8415, 1e-4)
    assert contour_level(0.95, 100, 3, 2.0, "simultaneous", "normal") == pytest.approx(
        2 * 7.8147, 1e-4
    )
    # k = n_p F_{0.95}(n_p, N − n_p): F_{0.95}(3, 20) = 3.0984 (F table)  [5.25]
    assert contour_level(0.95, 23, 3, 1.0, "simultaneous", "t") == pytest.approx(
        3 * 3.0984, rel=1e-4
    )


@pytest.mark.parametrize(
    "kwargs",
    [{"level": 1.0}, {"level": 0.0}, {"kind": "joint"}, {"distribution": "chi"}],
)
def test_contour_level_rejects_bad_arguments(kwargs):
    args = {"level": 0.95, "kind": "individual", "distribution": "t"} | kwargs
    with pytest.raises(InputError):
        contour_level(args["level"], 50, 3, 1.0, args["kind"], args["distribution"])


def test_beale_factor_formula():
    # [5.29]: 1 + N n_o (n_p + 2) / ((N n_o − n_p) n_p) N_φ with N n_o = 100, n_p = 4, N_φ = 0.02
    assert beale_factor(0.02, 100, 4) == pytest.approx(1 + 100 * 6 / (96 * 4) * 0.02)
    assert beale_factor(0.0, 100, 4) == 1.0


def test_ellipsoid_projection_and_undetermined():
    c = np.array([[4.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, np.inf]])
    ci = ellipsoid_intervals(np.array([1.0, 2.0, 3.0]), c, 9.0)
    # half width √(Δ C_jj): √36 = 6, √9 = 3
    np.testing.assert_allclose(ci[:2], [[-5.0, 7.0], [-1.0, 5.0]])
    assert ci[2, 0] == -np.inf and ci[2, 1] == np.inf


def test_correlation_warnings_name_the_pairs():
    c = np.array([[1.0, 0.95, 0.0], [0.95, 1.0, 0.0], [0.0, 0.0, 1.0]])
    messages = correlation_warnings(["a", "b", "c"], c)
    assert len(messages) == 1 and "a and b" in messages[0] and "+0.950" in messages[0]
    c[2, 2] = np.inf
    messages = correlation_warnings(["a", "b", "c"], c)
    assert any("cannot determine ['c']" in m for m in messages)


def test_coloured_correction_for_an_ar1_mean():
    # One parameter, the mean of y: G_i = 1, R = σ². For AR(1) residuals with coefficient φ,
    # Var(mean) ≈ (σ²/N)(1 + φ)/(1 − φ) (long-run variance of an AR(1) process).
    rng = np.random.default_rng(7)
    n, phi = 20000, 0.8
    e = rng.normal(size=n)
    nu = np.empty(n)
    nu[0] = e[0] / np.sqrt(1 - phi**2)
    for i in range(1, n):
        nu[i] = phi * nu[i - 1] + e[i]
    nu = (nu - nu.mean())[:, None]
    r = np.array([np.mean(nu**2)])
    g = np.ones((n, 1, 1))
    plain = np.array([[r[0] / n]])  # M⁻¹ = (N/σ²)⁻¹
    corrected, lag = coloured_covariance(g, nu, r, plain, max_lag=60)
    ratio = corrected[0, 0] / plain[0, 0]
    assert lag == 60
    assert ratio == pytest.approx((1 + phi) / (1 - phi), rel=0.15)
    # white residuals: the automatic lag stops at once and the bound is unchanged
    white = rng.normal(size=(n, 1))
    r_white = np.array([np.mean(white**2)])
    same, lag = coloured_covariance(g, white, r_white, np.array([[r_white[0] / n]]))
    assert lag <= 2
    assert same[0, 0] / (r_white[0] / n) == pytest.approx(1.0, abs=0.05)
    # an AR(1) residual needs more lags than white noise
    assert automatic_lag(nu) > 5


def test_coloured_lags_do_not_cross_maneuvers():
    nu = np.array([[1.0], [1.0], [-1.0], [-1.0]])
    g = np.ones((4, 1, 1))
    whole, _ = coloured_covariance(g, nu, np.ones(1), np.eye(1), max_lag=1)
    split, _ = coloured_covariance(
        g, nu, np.ones(1), np.eye(1), max_lag=1, maneuver_index=np.array([0, 0, 1, 1])
    )
    # R̂(1) = (1/N)Σ ν_i ν_{i+1}: whole record (1 − 1 + 1)/4 = 1/4, split (1 + 1)/4 = 1/2;
    # middle = 4·R̂(0) + 2·(pairs within maneuvers)·R̂(1)
    assert whole[0, 0] == pytest.approx(4 * 1.0 + 2 * 3 * 0.25)
    assert split[0, 0] == pytest.approx(4 * 1.0 + 2 * 2 * 0.5)


def test_assess_cr_intervals_and_warnings_on_a_linear_model():
    result, data = linear_estimate(collinear=0.9)
    with pytest.warns(AccuracyWarning, match="highly correlated"):
        accuracy = assess(result, data, methods="cr")
    # t interval: θ̂ ± t_{0.975}(N n_o − n_p) s σ_j  [5.24–5.27 with one parameter]
    from scipy import stats

    t = stats.t.ppf(0.975, result.n_data - 4)
    half = t * np.sqrt(accuracy.s2) * accuracy.std
    np.testing.assert_allclose(accuracy.ci_cr[:, 1] - accuracy.center, half, rtol=1e-10)
    # simultaneous: √(n_p F_{0.95}(n_p, N n_o − n_p)) s σ_j [5.25]
    k = 4 * stats.f.ppf(0.95, 4, result.n_data - 4)
    np.testing.assert_allclose(
        accuracy.ci_cr_simultaneous[:, 1] - accuracy.center, np.sqrt(k) * half / t, rtol=1e-10
    )
    assert accuracy.profile is None and accuracy.search is None
    assert any("p1 and" in w or "and p1" in w for w in accuracy.warnings)


def test_autocovariance_fft_path_matches_direct_sums():
    from flightid.accuracy.coloured import residual_autocovariance

    nu = np.random.default_rng(2).normal(size=(300, 3))
    direct = residual_autocovariance(nu, 31)  # ≤ 32 lags: direct sums
    fft = residual_autocovariance(nu, 100)  # FFT
    np.testing.assert_allclose(fft[:32], direct, atol=1e-12)
