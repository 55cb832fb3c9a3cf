"""Prediction intervals of global models, by seeded Monte Carlo against the known truth: the
prediction interval covers new observations and the mean band the true mean at the nominal
level (white noise); with AR(1) noise over several maneuvers the coloured-residual band keeps
its level while the classical band under-covers; with noise growing along a variable the
``local`` residual variance keeps the level where ``global`` does not. A saved model predicts
the same after reloading, from strict JSON."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

from flightid.globalmodel import (
    GlobalModel,
    GlobalModelError,
    GlobalModelSettings,
    fit_global_model,
    load_global_model,
)


def _cubic(x):
    return 0.3 + 1.2 * x - 0.8 * x**2 + 0.5 * x**3


CUBIC = GlobalModelSettings(orders={"x": 3}, max_order=3, forced=("1", "x", "x^2", "x^3"))


def test_white_noise_prediction_interval_and_mean_band_cover_at_the_level():
    sigma, n, seeds = 0.05, 60, 400
    new_covered, mean_covered = [], []
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        x = rng.uniform(-1, 1, n)
        z = _cubic(x) + rng.normal(0, sigma, n)
        model = fit_global_model({"x": x, "z": z}, ["z"], ["x"], settings=CUBIC)
        x0 = rng.uniform(-1, 1)
        prediction = model.predict({"x": [x0]}, level=0.95)["z"]
        new = _cubic(x0) + rng.normal(0, sigma)
        new_covered.append(prediction.lower[0] <= new <= prediction.upper[0])
        low, high = prediction.mean_interval()[0]
        mean_covered.append(low <= _cubic(x0) <= high)
    # binomial 3σ at 400 draws ≈ ±0.033
    assert 0.92 <= np.mean(new_covered) <= 0.98
    assert 0.92 <= np.mean(mean_covered) <= 0.98


def test_interval_arithmetic_against_numpy():
    rng = np.random.default_rng(11)
    x = rng.uniform(-1, 1, 80)
    z = _cubic(x) + rng.normal(0, 0.05, 80)
    model = fit_global_model({"x": x, "z": z}, ["z"], ["x"], settings=CUBIC)
    cubic = model["z"]
    x0 = np.array([-0.5, 0.1, 0.7])
    prediction = cubic.predict({"x": x0}, level=0.9)
    # reference: ordinary least squares by numpy, white residuals (N_eff = N, classical σ)
    Phi = np.column_stack([x**0, x, x**2, x**3])
    theta, *_ = np.linalg.lstsq(Phi, z, rcond=None)
    s2 = np.sum((z - Phi @ theta) ** 2) / (80 - 4)
    cov = s2 * np.linalg.inv(Phi.T @ Phi)
    phi0 = np.column_stack([x0**0, x0, x0**2, x0**3])
    std = np.sqrt(np.einsum("ij,jk,ik->i", phi0, cov, phi0) + s2)
    q = stats.t.ppf(0.95, 80 - 4)
    assert cubic.coloured_lag == 0 and cubic.n_eff == 80
    np.testing.assert_allclose(prediction.value, phi0 @ theta, rtol=1e-10)
    np.testing.assert_allclose(prediction.upper, phi0 @ theta + q * std, rtol=1e-10)
    np.testing.assert_allclose(prediction.lower, phi0 @ theta - q * std, rtol=1e-10)


def _ar1_run(seed, phi=0.95, n_maneuvers=8, n=400, sigma=0.02):
    """Slow maneuvers x(t), z = f(x) + AR(1) noise; returns the coloured and the classical
    mean band's coverage of the true mean at a random point, and N_eff."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.02
    xs, noise = [], []
    for _ in range(n_maneuvers):
        period = rng.uniform(3, 8)
        xs.append(
            0.5 * np.sin(2 * np.pi * t / period + rng.uniform(0, 6.3)) + rng.uniform(-0.3, 0.3)
        )
        # e_i = φ e_{i−1} + w_i, stationary variance σ²
        e = np.empty(n)
        e[0] = rng.normal(0, sigma)
        w = rng.normal(0, sigma * np.sqrt(1 - phi**2), n)
        for i in range(1, n):
            e[i] = phi * e[i - 1] + w[i]
        noise.append(e)
    x = np.concatenate(xs)
    z = _cubic(x) + np.concatenate(noise)
    index = np.repeat(np.arange(n_maneuvers), n)
    model = fit_global_model(
        {"x": x, "z": z}, ["z"], ["x"], settings=CUBIC, maneuver_index=index, dt=0.02
    )
    cubic = model["z"]
    x0 = rng.uniform(-0.5, 0.5)
    prediction = cubic.predict({"x": [x0]})
    low, high = prediction.mean_interval()[0]
    # the classical band: φ₀ᵀ s²(ΦᵀΦ)⁻¹ φ₀ with t at N − n_p (white-residual assumption)
    phi0 = cubic.regressors({"x": [x0]})[0]
    std_cr = np.sqrt(phi0 @ cubic.covariance_cr @ phi0)
    q_cr = stats.t.ppf(0.975, cubic.n_samples - 4)
    truth = _cubic(x0)
    return low <= truth <= high, abs(prediction.value[0] - truth) <= q_cr * std_cr, cubic.n_eff


def test_ar1_noise_coloured_band_keeps_the_level_and_the_classical_band_does_not():
    runs = np.array([_ar1_run(seed) for seed in range(300)], dtype=float)
    coloured, classical, n_eff = runs.T
    assert 0.88 <= coloured.mean() <= 0.99
    assert classical.mean() < 0.80
    # 3200 samples, but strongly correlated: far fewer independent ones
    assert np.median(n_eff) < 400


def test_local_residual_variance_follows_heteroscedastic_noise():
    rng = np.random.default_rng(21)
    n = 6000
    x = rng.uniform(0, 1, n)

    def sigma(v):
        # noise grows along x
        return 0.005 + 0.08 * v**2

    z = _cubic(x) + sigma(x) * rng.normal(size=n)
    signals = {"x": x, "z": z}
    local = fit_global_model(
        signals,
        ["z"],
        ["x"],
        settings=GlobalModelSettings(**{**CUBIC.to_dict(), "residual_variance": "local"}),
    )
    common = fit_global_model(signals, ["z"], ["x"], settings=CUBIC)
    x_new = rng.uniform(0, 1, 6000)
    z_new = _cubic(x_new) + sigma(x_new) * rng.normal(size=x_new.size)
    terciles = np.digitize(x_new, [1 / 3, 2 / 3])
    for k in range(3):
        rows = terciles == k
        p = local["z"].predict({"x": x_new[rows]})
        covered = np.mean((p.lower <= z_new[rows]) & (z_new[rows] <= p.upper))
        assert 0.90 <= covered <= 0.99, (k, covered)
    top = terciles == 2
    p = common["z"].predict({"x": x_new[top]})
    covered = np.mean((p.lower <= z_new[top]) & (z_new[top] <= p.upper))
    assert not 0.90 <= covered <= 0.99


def _reject_constant(name):
    raise ValueError(f"non-strict JSON constant {name}")


@pytest.mark.parametrize("residual_variance", ["global", "local"])
def test_a_reloaded_model_predicts_identically_from_strict_json(tmp_path, residual_variance):
    rng = np.random.default_rng(31)
    n = 1500
    alpha, mach = rng.uniform(-0.1, 0.4, n), rng.uniform(0.3, 0.8, n)
    signals = {
        "alpha": alpha,
        "Mach": mach,
        "CL": 0.1 + 5 * alpha + 0.4 * alpha * mach + rng.normal(0, 0.01, n),
        "Cm": -0.02 - 0.6 * alpha + 0.1 * mach**2 + rng.normal(0, 0.002, n),
    }
    settings = GlobalModelSettings(max_order=3, residual_variance=residual_variance)
    model = fit_global_model(
        signals,
        {"CL": "CL", "Cm": "Cm"},
        ["alpha", "Mach"],
        settings=settings,
        maneuver_index=np.repeat([0, 1, 2], 500),
        dt=0.02,
        units={"alpha": "rad", "CL": "", "Cm": ""},
    )
    text = model.to_json()
    document = json.loads(text, parse_constant=_reject_constant)
    reloaded = GlobalModel.from_dict(document)
    written = load_global_model(model.write(tmp_path / "global_model.json"))
    points = {"alpha": np.linspace(-0.3, 0.7, 21), "Mach": np.linspace(0.2, 0.95, 21)}
    before = model.predict(points)
    for other in (reloaded, written):
        after = other.predict(points)
        assert set(after) == {"CL", "Cm"}
        for name in before:
            b, a = before[name], after[name]
            for key in ("value", "std_mean", "std_prediction", "lower", "upper"):
                np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
            np.testing.assert_array_equal(a.distance_ratio, b.distance_ratio)
            np.testing.assert_array_equal(a.leverage_ratio, b.leverage_ratio)
            assert a.outside.tolist() == b.outside.tolist() and a.reason == b.reason
        assert other["CL"].terms == model["CL"].terms
    assert before["CL"].outside.any() and not before["CL"].outside.all()
    assert model["CL"].units[model["CL"].terms.index("alpha")] == "1/rad"


def test_prediction_input_errors_name_the_variable():
    rng = np.random.default_rng(41)
    x = rng.uniform(-1, 1, 50)
    model = fit_global_model({"x": x, "z": _cubic(x)}, ["z"], ["x"], settings=CUBIC)
    with pytest.raises(GlobalModelError, match=r"missing \['x'\]"):
        model.predict({"y": [0.0]})
    with pytest.raises(GlobalModelError, match=r"points\['x'\].*non-finite"):
        model.predict({"x": [0.0, np.inf]})
    with pytest.raises(GlobalModelError, match="kind 'global_model'"):
        GlobalModel.from_dict({"kind": "estimate"})
