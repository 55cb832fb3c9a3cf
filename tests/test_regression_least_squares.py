"""Least squares with statistics: closed forms and textbook identities."""

import numpy as np
import pytest
from scipy import stats

from flightid.regression import LeastSquaresError, least_squares


def _line_data(seed=0, n=50):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, n)
    z = 0.5 + 2.0 * x + 0.1 * rng.normal(size=n)
    return x, z


def test_simple_line_matches_closed_form():
    # Reference: simple linear regression closed form (e.g. Draper & Smith, ch. 1):
    # b1 = Sxy/Sxx, b0 = zbar − b1 xbar, var(b1) = s²/Sxx, var(b0) = s²(1/n + xbar²/Sxx).
    x, z = _line_data()
    n = x.size
    res = least_squares(np.column_stack([np.ones(n), x]), z, ["1", "x"])
    sxx = np.sum((x - x.mean()) ** 2)
    sxy = np.sum((x - x.mean()) * (z - z.mean()))
    b1 = sxy / sxx
    b0 = z.mean() - b1 * x.mean()
    rss = np.sum((z - b0 - b1 * x) ** 2)
    s2 = rss / (n - 2)
    np.testing.assert_allclose(res.estimates, [b0, b1], rtol=1e-12)
    np.testing.assert_allclose(
        res.std, np.sqrt([s2 * (1 / n + x.mean() ** 2 / sxx), s2 / sxx]), rtol=1e-10
    )
    assert res.s2 == pytest.approx(s2, rel=1e-12)
    r2 = 1 - rss / np.sum((z - z.mean()) ** 2)
    assert res.r2 == pytest.approx(r2, rel=1e-12)
    assert res.r2_adjusted == pytest.approx(1 - (1 - r2) * (n - 1) / (n - 2), rel=1e-12)
    # with one regressor the overall F equals the partial F (t²) of the slope
    assert res.f_overall == pytest.approx(res.partial_f[1], rel=1e-10)
    assert res.p_values[1] == pytest.approx(2 * stats.t.sf(abs(b1 / np.sqrt(s2 / sxx)), n - 2))
    np.testing.assert_allclose(res.residuals + res.fitted, z, rtol=0, atol=1e-14)


def test_pse_and_vif():
    rng = np.random.default_rng(3)
    n = 200
    x1 = rng.normal(size=n)
    x2 = 0.8 * x1 + 0.6 * rng.normal(size=n)
    z = 1.0 + x1 - x2 + 0.05 * rng.normal(size=n)
    X = np.column_stack([np.ones(n), x1, x2])
    res = least_squares(X, z, ["1", "x1", "x2"], sigma2_max=0.01)
    # PSE = RSS/N + σ²_max n_p / N (METHOD §5)
    assert res.pse == pytest.approx(res.rss / n + 0.01 * 3 / n, rel=1e-12)
    # With two regressors VIF = 1/(1 − r²), r their sample correlation (closed form).
    r = np.corrcoef(x1, x2)[0, 1]
    assert np.isnan(res.vif[0])
    np.testing.assert_allclose(res.vif[1:], 1 / (1 - r**2), rtol=1e-10)
    # default σ²_max is the variance of z about its mean
    assert least_squares(X, z).sigma2_max == pytest.approx(np.var(z), rel=1e-12)


def test_ill_scaled_columns_are_still_accurate():
    # QR with unit-length columns: a column scaled by 1e8 changes only its estimate by 1e-8.
    x, z = _line_data(1)
    n = x.size
    a = least_squares(np.column_stack([np.ones(n), x]), z)
    b = least_squares(np.column_stack([np.ones(n), 1e8 * x]), z)
    assert b.estimates[1] * 1e8 == pytest.approx(a.estimates[1], rel=1e-10)
    assert b.condition_number == pytest.approx(a.condition_number, rel=1e-10)


def test_summary_lists_every_term():
    x, z = _line_data()
    res = least_squares(np.column_stack([np.ones(x.size), x]), z, ["1", "alpha"])
    text = res.summary()
    assert "alpha" in text and "R²" in text and "PSE" in text
    assert res.to_dict()["parameters"][1]["name"] == "alpha"
    with pytest.raises(AttributeError):
        res.rss = 0.0  # frozen


def test_errors_name_the_argument():
    x, z = _line_data()
    with pytest.raises(LeastSquaresError, match="z: expected a series of 50"):
        least_squares(np.column_stack([np.ones(50), x]), z[:-1])
    with pytest.raises(LeastSquaresError, match="linearly dependent"):
        least_squares(np.column_stack([x, 2 * x]), z)
    with pytest.raises(LeastSquaresError, match="more samples than regressors"):
        least_squares(np.ones((2, 2)), np.ones(2))
    with pytest.raises(LeastSquaresError, match="names: expected 2"):
        least_squares(np.column_stack([np.ones(50), x]), z, ["a"])
