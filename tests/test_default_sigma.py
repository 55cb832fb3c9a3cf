"""The default σ is the one the residuals support, on every surface.

Independent references: a first-order system simulated here by its exact zero-order-hold
discretisation (scipy.signal.lfilter, not flightid's simulator) with AR(1)-coloured or white
measurement noise; sensitivities by central differences of that simulator; the
coloured-residual sandwich written out as a plain double sum; seeded Monte Carlo coverage.
"""

import csv
import io
import json
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.signal
from scipy import stats

from flightid.data.flightdata import FlightData
from flightid.estimation import MNR, estimate
from flightid.model.parameters import Parameter, Parameters
from flightid.model.statespace import StateSpaceModel
from flightid.regression.least_squares import least_squares

A_TRUE, B_TRUE, DT, NOISE_SD = -1.5, 2.0, 0.05, 0.05


def f_first_order(t, x, u, theta):
    # ẋ = a x + b u
    return np.array([theta[0] * x[0] + theta[1] * u[0]])


def h_state(t, x, u, theta):
    return np.array([x[0]])


def _model() -> StateSpaceModel:
    parameters = Parameters([Parameter("a", 1.1 * A_TRUE), Parameter("b", 0.9 * B_TRUE)])
    return StateSpaceModel(("x",), ("u",), ("y",), f_first_order, h_state, parameters)


def _square_wave(n: int) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) * DT
    return t, np.where((t % 3.0) < 1.5, 1.0, -1.0)


def _response(a: float, b: float, u: np.ndarray) -> np.ndarray:
    """Exact ZOH discretisation: x_{k+1} = e^{aΔt} x_k + (e^{aΔt} − 1)/a · b u_k, x_0 = 0."""
    ad = np.exp(a * DT)
    bd = (ad - 1.0) / a * b
    return scipy.signal.lfilter([0.0, bd], [1.0, -ad], u)


def _data(seed: int, n: int, phi: float) -> FlightData:
    """y = x + v, v AR(1): v_k = φ v_{k−1} + e_k with stationary σ = NOISE_SD (seeded)."""
    rng = np.random.default_rng(seed)
    t, u = _square_wave(n)
    e = rng.normal(size=n) * NOISE_SD * np.sqrt(1.0 - phi**2)
    noise = scipy.signal.lfilter([1.0], [1.0, -phi], e)
    return FlightData(t, {"u": u}, {"y": _response(A_TRUE, B_TRUE, u) + noise})


def _estimate(seed: int, n: int = 200, phi: float = 0.6):
    return estimate(_model(), _data(seed, n, phi), MNR(), input_interpolation="zoh")


def _sensitivities(a: float, b: float, n: int) -> np.ndarray:
    """∂y/∂(a, b) (N, 2) by central differences of the exact discretisation."""
    _, u = _square_wave(n)
    columns = []
    for j, h in ((0, 1e-6), (1, 1e-6)):
        step = np.array([h if j == 0 else 0.0, h if j == 1 else 0.0])
        plus = _response(a + step[0], b + step[1], u)
        minus = _response(a - step[0], b - step[1], u)
        columns.append((plus - minus) / (2 * h))
    return np.column_stack(columns)


def _sandwich_written_out(g: np.ndarray, nu: np.ndarray, lag: int) -> np.ndarray:
    """Cov = M⁻¹ [Σ_i Σ_j g_i R̂(i − j) g_jᵀ] M⁻¹ · N/(N − n_p), one output, R = 1, with
    R̂(k) = (1/N) Σ_i ν_i ν_{i+k} for |i − j| ≤ L (Morelli & Klein §6.4), as a plain loop."""
    n, p = g.shape
    m_inv = np.linalg.inv(g.T @ g)
    r_hat = [float(nu[: n - k] @ nu[k:]) / n for k in range(lag + 1)]
    middle = np.zeros((p, p))
    for i in range(n):
        for j in range(max(0, i - lag), min(n, i + lag + 1)):
            middle += r_hat[abs(i - j)] * np.outer(g[i], g[j])
    return m_inv @ middle @ m_inv * n / (n - p)


# ------------------------------------------------------------------- (a) coverage
def test_coloured_noise_monte_carlo_coverage_of_the_default_sigma():
    """AR(1) noise (φ = 0.6), N = 200, 200 seeds: the default σ's 2σ coverage is 90–98 %, the
    Cramér–Rao σ's far below (measured 0.925 and 0.69; ratio std/std_cr ≈ 1.8)."""
    inside, inside_cr, ratios = [], [], []
    for seed in range(200):
        est = _estimate(seed)
        assert est.converged, est.message
        error = np.abs(est.values - np.array([A_TRUE, B_TRUE]))
        inside += list(error <= 2.0 * est.std)
        inside_cr += list(error <= 2.0 * est.std_cr)
        ratios.append(est.std / est.std_cr)
    coverage, coverage_cr = float(np.mean(inside)), float(np.mean(inside_cr))
    assert 0.90 <= coverage <= 0.98, coverage
    assert coverage_cr < 0.80, coverage_cr
    assert np.mean(ratios) > 1.5


def test_coloured_default_sigma_is_the_written_out_sandwich():
    est = _estimate(3)
    assert est.std_kind == "coloured" and not est.residuals_white and est.coloured_lag > 0
    g = _sensitivities(*est.values, 200)
    covariance = _sandwich_written_out(g, est.residuals[:, 0], est.coloured_lag)
    np.testing.assert_allclose(est.std, np.sqrt(np.diag(covariance)), rtol=2e-3)
    # the Cramér–Rao σ beside it: √diag((GᵀR⁻¹G)⁻¹), R = mean ν² (program MAX)
    r = float(np.mean(est.residuals**2))
    np.testing.assert_allclose(est.std_cr, np.sqrt(np.diag(np.linalg.inv(g.T @ g / r))), rtol=2e-3)
    np.testing.assert_allclose(est.sigma_ratio, est.std / est.std_cr)


# ------------------------------------------------------------------- (b) white noise
def test_white_noise_default_sigma_is_the_cramer_rao_sigma():
    est = _estimate(0, phi=0.0)
    assert est.residuals_white and est.std_kind == "cramer_rao" and est.coloured_lag == 0
    np.testing.assert_array_equal(est.std, est.std_cr)
    np.testing.assert_array_equal(est.covariance_default, est.covariance)
    g = _sensitivities(*est.values, 200)
    r = float(np.mean(est.residuals**2))
    np.testing.assert_allclose(est.std, np.sqrt(np.diag(np.linalg.inv(g.T @ g / r))), rtol=2e-3)
    np.testing.assert_array_equal(est.conf_int(), est.conf_int(std="cr"))


def test_regression_default_sigma_coloured_and_white():
    rng = np.random.default_rng(5)
    n = 400
    x = np.column_stack([np.ones(n), np.sin(np.arange(n) * 0.05), np.cos(np.arange(n) * 0.013)])
    theta = np.array([0.3, -1.2, 0.7])
    coloured_noise = scipy.signal.lfilter([1.0], [1.0, -0.7], 0.05 * rng.normal(size=n))
    fit = least_squares(x, x @ theta + coloured_noise, ("1", "s", "c"))
    residuals = fit.residuals
    # classical σ: √diag(s²(XᵀX)⁻¹), s² = RSS/(N − n_p)
    s2 = residuals @ residuals / (n - 3)
    np.testing.assert_allclose(fit.std_cr, np.sqrt(np.diag(s2 * np.linalg.inv(x.T @ x))))
    assert fit.std_kind == "coloured" and fit.coloured_lag > 0
    expected = _sandwich_written_out(x, residuals, fit.coloured_lag)
    np.testing.assert_allclose(fit.std, np.sqrt(np.diag(expected)), rtol=1e-9)
    assert np.all(fit.std > 1.5 * fit.std_cr)
    # t intervals from the default σ, or from the classical σ on request
    q = stats.t.ppf(0.975, n - 3)
    np.testing.assert_allclose(np.diff(fit.conf_int(), axis=1)[:, 0], 2 * q * fit.std)
    np.testing.assert_allclose(np.diff(fit.conf_int(std="cr"), axis=1)[:, 0], 2 * q * fit.std_cr)
    # white noise (seed 2: its lag-1 autocorrelation inside the band, as for 95 % of seeds)
    white = least_squares(x, x @ theta + 0.05 * np.random.default_rng(2).normal(size=n))
    assert white.residuals_white and white.std_kind == "cramer_rao"
    np.testing.assert_array_equal(white.std, white.std_cr)


# ------------------------------------------------------------------- (c) every surface
@pytest.fixture(scope="module")
def coloured_estimate():
    return _estimate(3)


def test_summary_json_frame_and_intervals_show_the_default_sigma(coloured_estimate):
    est = coloured_estimate
    text = est.summary()
    assert "CR σ" in text and "coloured-residual σ" in text
    for j in range(2):
        # σ to two significant digits (flightid.numbers)
        assert f"{est.std[j]:.2g}" in text and f"{est.std_cr[j]:.2g}" in text
    document = json.loads(est.to_json())
    assert document["std_kind"] == "coloured" and document["residuals_white"] is False
    assert document["coloured_lag"] == est.coloured_lag
    for j, entry in enumerate(document["parameters"]):
        assert entry["std"] == pytest.approx(est.std[j], rel=1e-12)
        assert entry["std_cr"] == pytest.approx(est.std_cr[j], rel=1e-12)
    frame = est.to_frame()
    np.testing.assert_allclose(frame["std"].to_numpy(), est.std)
    np.testing.assert_allclose(frame["std_cr"].to_numpy(), est.std_cr)
    # individual 95 % t intervals: θ̂ ± t·σ (default) and θ̂ ± t·s·σ_CR (std="cr")
    dof = est.n_data - 2
    q = stats.t.ppf(0.975, dof)
    s = np.sqrt(est.cost / dof)
    np.testing.assert_allclose(np.diff(est.conf_int(), axis=1)[:, 0], 2 * q * est.std, rtol=1e-9)
    np.testing.assert_allclose(
        np.diff(est.conf_int(std="cr"), axis=1)[:, 0], 2 * q * s * est.std_cr, rtol=1e-9
    )
    np.testing.assert_allclose(frame["lower"].to_numpy(), est.conf_int()[:, 0])
    assert est.stddev("a") == est.std[0] and est.stddev("a", std="cr") == est.std_cr[0]


def test_estimates_csv_and_batch_table_show_the_default_sigma(coloured_estimate, tmp_path):
    from flightid.batch.table import table_rows
    from flightid.batch.task import _rows
    from flightid.report.html import write_csv

    est = coloured_estimate
    run = SimpleNamespace(estimate=est, case=SimpleNamespace(accuracy={}), accuracy=None)
    write_csv(run, tmp_path / "estimates.csv")
    rows = list(csv.DictReader(io.StringIO((tmp_path / "estimates.csv").read_text())))
    for j, row in enumerate(rows):
        assert float(row["std"]) == pytest.approx(est.std[j], rel=1e-12)
        assert float(row["std_cr"]) == pytest.approx(est.std_cr[j], rel=1e-12)
        assert row["std_kind"] == "coloured"
    table, _ = _rows(run)
    columns, batch = table_rows([{"case": "c", "rows": table, "converged": True}])
    assert "std" in columns and "std_cr" in columns
    np.testing.assert_allclose([r["std"] for r in batch], est.std)
    np.testing.assert_allclose([r["std_cr"] for r in batch], est.std_cr)


# ------------------------------------------------------------------- (d) terminal note
def test_terminal_note_says_how_much_the_cr_bounds_understate(coloured_estimate, capsys):
    from flightid.cli.run import print_sigma_note

    est = coloured_estimate
    print_sigma_note(est)
    err = capsys.readouterr().err
    low, high = np.min(est.sigma_ratio), np.max(est.sigma_ratio)
    assert err.count("\n") == 1 and err.startswith("flightid: note: residuals are coloured")
    assert f"lag L = {est.coloured_lag} samples" in err
    assert "σ shown are the coloured-residual σ" in err
    assert f"{low:.2g}–{high:.2g}× the Cramér–Rao bounds (std_cr)" in err
    print_sigma_note(_estimate(0, phi=0.0))
    assert capsys.readouterr().err == ""


def test_strongly_coloured_residuals_add_that_the_coloured_sigma_may_be_optimistic():
    from types import SimpleNamespace

    from flightid.report.text import STRONGLY_COLOURED, sigma_note

    def result(ratio_high: float):
        return SimpleNamespace(
            std_kind="coloured",
            coloured_lag=12,
            residuals=np.zeros((400, 2)),
            sigma_ratio=np.array([1.2, ratio_high]),
        )

    mild = sigma_note(result(0.99 * STRONGLY_COLOURED))
    strong = sigma_note(result(1.01 * STRONGLY_COLOURED))
    assert "turbulence" not in mild and "\n" not in mild
    assert "even the coloured σ can be too small" in strong and "filter error" in strong
    assert "\n" not in strong


# ------------------------------------------------------------------- long lags
def test_long_lag_sandwich_equals_the_written_out_double_sum():
    """L = 100 > 64 takes the FFT correlation (a loop over N·L products is hours at N = 10⁵
    with a long lag); it must give the written-out double sum."""
    from flightid.coloured import coloured_covariance

    rng = np.random.default_rng(11)
    n, lag = 300, 100
    g = rng.normal(size=(n, 3))
    nu = scipy.signal.lfilter([1.0], [1.0, -0.95], rng.normal(size=n))
    got, used = coloured_covariance(
        g[:, None, :], nu[:, None], np.ones(1), np.linalg.inv(g.T @ g), max_lag=lag
    )
    assert used == lag
    np.testing.assert_allclose(got * n / (n - 3), _sandwich_written_out(g, nu, lag), rtol=1e-10)
