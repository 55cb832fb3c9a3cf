"""Prediction intervals of global models, by seeded Monte Carlo against the known truth: the
prediction interval covers new observations and the mean band the true mean at the nominal
level (white noise); with AR(1) noise over several maneuvers the coloured-residual band keeps
its level while the classical band under-covers; with noise growing along a variable the
``local`` residual variance keeps the level where ``global`` does not. A saved model predicts
the same after reloading, from strict JSON.

The function interval (the coefficient itself: model error, no measurement noise), against a
known truth: a misspecified model over trajectories covers the truth at about the level
where the mean band under-covers and the prediction interval over-covers; a correct model
has no model error and the function interval is the mean band; the noise variance from the
residuals' sample-to-sample differences matches the generated noise."""

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
            for key in (
                "value",
                "std_mean",
                "std_prediction",
                "lower",
                "upper",
                "std_function",
                "function_lower",
                "function_upper",
            ):
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


# ------------------------------------------------------------------ the function interval
def _trajectories(rng, n_maneuvers, n=500, dt=0.02):
    """Smooth trajectories through (x, y) ∈ [−1, 1]², one per maneuver, sampled every dt."""
    t = np.arange(n) * dt
    xs, ys = [], []
    for _ in range(n_maneuvers):
        omega, phase = rng.uniform(0.4, 1.5, 2), rng.uniform(0, 2 * np.pi, 2)
        centre, amplitude = rng.uniform(-0.3, 0.3, 2), rng.uniform(0.5, 0.7, 2)
        xs.append(centre[0] + amplitude[0] * np.sin(omega[0] * t + phase[0]))
        ys.append(centre[1] + amplitude[1] * np.sin(omega[1] * t + phase[1]))
    return np.concatenate(xs), np.concatenate(ys), np.repeat(np.arange(n_maneuvers), n)


def _smooth_truth(x, y):
    # not a polynomial: a first-order model of it is misspecified
    return 0.4 * np.sin(2.2 * x + 0.3) + 0.25 * np.cos(1.7 * y) * x + 0.15 * np.exp(y)


def _coverage(prediction, truth):
    """Coverage of the truth inside the support by the function interval, the mean band and
    the prediction interval."""
    inside = ~prediction.outside
    mean_low, mean_high = prediction.mean_interval().T
    return [
        np.mean(((low <= truth) & (truth <= high))[inside])
        for low, high in (
            (prediction.function_lower, prediction.function_upper),
            (mean_low, mean_high),
            (prediction.lower, prediction.upper),
        )
    ]


def _misspecified_run(seed, residual_variance="global", sigma=0.1, decimate=1):
    """A linear model of ``_smooth_truth`` + white noise σ over 8 maneuvers, judged on 200
    points of 4 held-out maneuvers: (coverages, σ²_noise / σ², model)."""
    rng = np.random.default_rng(seed)
    x, y, index = _trajectories(rng, 8)
    z = _smooth_truth(x, y) + rng.normal(0, sigma, x.size)
    settings = GlobalModelSettings(
        max_order=1, residual_variance=residual_variance, decimate=decimate
    )
    model = fit_global_model(
        {"x": x, "y": y, "z": z},
        ["z"],
        ["x", "y"],
        settings=settings,
        maneuver_index=index,
        dt=0.02,
    )
    x_held, y_held, _ = _trajectories(rng, 4)
    rows = rng.choice(x_held.size, 200, replace=False)
    prediction = model.predict({"x": x_held[rows], "y": y_held[rows]})["z"]
    coverage = _coverage(prediction, _smooth_truth(x_held[rows], y_held[rows]))
    return coverage, model["z"].noise_variance / sigma**2, model


@pytest.mark.parametrize("residual_variance", ["global", "local"])
def test_misspecified_model_function_interval_covers_the_truth(residual_variance):
    runs = [_misspecified_run(seed, residual_variance) for seed in range(20)]
    function, mean_band, prediction = np.mean([run[0] for run in runs], axis=0)
    # the mean band leaves the model error out; the prediction interval adds the noise
    assert 0.90 <= function <= 0.99
    assert mean_band < 0.7
    assert prediction > function
    assert all(run[2]["z"].model_error_variance > 0 for run in runs)


def test_noise_variance_from_differences_matches_the_generated_noise():
    ratios = [_misspecified_run(seed)[1] for seed in range(20)]
    # reference: the generated noise variance σ² (closed form); model error (smooth along
    # the trajectories) stays out of the differences
    assert np.all(np.abs(np.array(ratios) - 1.0) < 0.10)
    assert abs(np.mean(ratios) - 1.0) < 0.03


def test_noise_variance_uses_every_sample_when_the_fit_decimates():
    rng = np.random.default_rng(51)
    x, y, index = _trajectories(rng, 6)
    z = _smooth_truth(x, y) + rng.normal(0, 0.05, x.size)
    settings = GlobalModelSettings(max_order=1, decimate=5)
    cm = fit_global_model(
        {"x": x, "y": y, "z": z}, ["z"], ["x", "y"], settings=settings, maneuver_index=index
    )["z"]
    # reference: the selected model on all samples, differences taken maneuver by maneuver
    residuals = z - cm.regressors({"x": x, "y": y}) @ cm.estimates
    squares, count = 0.0, 0
    for k in np.unique(index):
        differences = np.diff(residuals[index == k])
        squares, count = squares + np.sum(differences**2), count + differences.size
    assert count == x.size - 6
    assert cm.noise_variance == pytest.approx(squares / (2 * count), rel=1e-10)
    assert cm.noise_variance == pytest.approx(0.05**2, rel=0.1)
    # the fit's own residuals are every fifth sample: the model error changes between them
    decimated = residuals[::5]
    assert np.sum(np.diff(decimated) ** 2) / (2 * (decimated.size - 1)) > 1.2 * 0.05**2


def _correct_run(seed, sigma=0.05):
    rng = np.random.default_rng(seed)
    x, y, index = _trajectories(rng, 4, n=250)

    def truth(a, b):
        return 0.2 + 0.8 * a - 0.5 * b + 0.6 * a * b - 0.4 * a**2

    z = truth(x, y) + rng.normal(0, sigma, x.size)
    settings = GlobalModelSettings(max_order=2, forced=("1", "x", "y", "x*y", "x^2"), max_terms=5)
    model = fit_global_model(
        {"x": x, "y": y, "z": z},
        ["z"],
        ["x", "y"],
        settings=settings,
        maneuver_index=index,
        dt=0.02,
    )
    x0, y0 = rng.uniform(-0.5, 0.5, 2)
    prediction = model.predict({"x": [x0], "y": [y0]})["z"]
    low, high = prediction.mean_interval()[0]
    f = truth(x0, y0)
    return (
        prediction.function_lower[0] <= f <= prediction.function_upper[0],
        low <= f <= high,
        model["z"].model_error_variance,
        prediction.std_function[0] / prediction.std_mean[0],
    )


def test_correct_model_function_interval_is_the_mean_band():
    runs = np.array([_correct_run(seed) for seed in range(300)], dtype=float)
    function, mean_band, model_error, ratio = runs.T
    # binomial 3σ at 300 draws ≈ ±0.038
    assert 0.92 <= function.mean() <= 0.98
    assert 0.92 <= mean_band.mean() <= 0.98
    # no model error: σ²_model = 0 but where the one-sided 5 % test errs
    assert np.mean(model_error == 0.0) >= 0.9
    np.testing.assert_array_equal(ratio[model_error == 0.0], 1.0)
    assert np.median(ratio) == 1.0


def test_function_interval_arithmetic_and_records():
    coverage, _, model = _misspecified_run(3)
    cm = model["z"]
    s2 = cm.s2
    assert 0 < cm.model_error_variance < s2 and cm.noise_variance > 0
    points = {"x": np.array([-0.4, 0.0, 0.5]), "y": np.array([0.2, -0.1, 0.3])}
    p = cm.predict(points, level=0.9)
    # σ_function² = σ_mean² + σ²_model, σ_prediction² = σ_mean² + s²
    np.testing.assert_allclose(p.std_function**2, p.std_mean**2 + cm.model_error_variance)
    np.testing.assert_allclose(p.std_prediction**2, p.std_mean**2 + s2)
    q = stats.t.ppf(0.95, cm.dof)
    np.testing.assert_allclose(p.function_upper, p.value + q * p.std_function)
    np.testing.assert_allclose(p.function_lower, p.value - q * p.std_function)
    np.testing.assert_allclose(
        p.function_interval(), np.column_stack([p.function_lower, p.function_upper])
    )
    assert np.all(p.lower < p.function_lower) and np.all(p.function_upper < p.upper)
    entry = p.to_dict()
    assert entry["std_function"] == p.std_function.tolist()
    assert entry["function_lower"] == p.function_lower.tolist()
    record = cm.to_dict()
    assert record["noise_variance"] == cm.noise_variance
    assert record["model_error_variance"] == cm.model_error_variance
    assert "σ_noise" in cm.summary() and "σ_model" in cm.summary()
    # a saved model without the noise variance: the function interval is the prediction
    # interval (all of the residual variance counts as model error)
    document = model.to_dict()
    for key in ("noise_variance", "model_error_variance"):
        del document["coefficients"]["z"][key]
    old = GlobalModel.from_dict(document)["z"].predict(points, level=0.9)
    np.testing.assert_allclose(old.std_function, p.std_prediction)
    assert 0.5 < coverage[0] <= 1.0


def test_prediction_frame_has_the_function_interval():
    pytest.importorskip("pandas")
    _, _, model = _misspecified_run(4)
    frame = model["z"].predict({"x": [0.1, 0.2], "y": [0.0, 0.1]}).to_frame()
    for column in ("std_function", "function_lower", "function_upper"):
        assert column in frame.columns


def _heteroscedastic_run(seed):
    """A linear model of a curved truth over 6 maneuvers along x ∈ [0, 1], noise σ growing
    from 0.005 to 0.2 along x; ``"local"`` residual variance. Per tercile of x: the function
    interval's coverage of the truth and σ_function / σ_prediction."""
    rng = np.random.default_rng(seed)
    t = np.arange(1000) * 0.02
    x = np.concatenate(
        [0.5 + 0.5 * np.sin(rng.uniform(0.3, 1.0) * t + rng.uniform(0, 6.3)) for _ in range(6)]
    )

    def truth(v):
        return 0.3 * v**2 + 0.05 * np.sin(9 * v)

    z = truth(x) + (0.005 + 0.2 * x**2) * rng.normal(size=x.size)
    settings = GlobalModelSettings(max_order=1, residual_variance="local")
    model = fit_global_model(
        {"x": x, "z": z},
        ["z"],
        ["x"],
        settings=settings,
        maneuver_index=np.repeat(range(6), 1000),
        dt=0.02,
    )
    x0 = rng.uniform(0, 1, 300)
    p = model["z"].predict({"x": x0})
    covered = (p.function_lower <= truth(x0)) & (truth(x0) <= p.function_upper)
    tercile = np.digitize(x0, [1 / 3, 2 / 3])
    return [
        (np.mean(covered[tercile == k]), np.mean((p.std_function / p.std_prediction)[tercile == k]))
        for k in range(3)
    ]


def test_local_function_interval_leaves_out_noise_that_grows_over_the_space():
    runs = np.array([_heteroscedastic_run(seed) for seed in range(10)])
    coverage, ratio = runs[..., 0].mean(axis=0), runs[..., 1].mean(axis=0)
    # the truth covered in every third of the space, the large noise of the last third left
    # out of the function interval (the noise variance of the neighbours, not a global one)
    assert np.all(coverage >= 0.9), coverage
    assert ratio[2] < 0.5, ratio


def test_the_carpet_shades_the_function_interval_inside_the_prediction_interval():
    import xml.etree.ElementTree as ET

    from flightid.report.globalmodel_reports import _terms_table, carpet_svg

    _, _, model = _misspecified_run(5)
    cm = model["z"]
    svg = ET.fromstring(carpet_svg(cm))
    bands: dict[str, dict[float, np.ndarray]] = {}
    for polygon in svg.iter("{http://www.w3.org/2000/svg}polygon"):
        xy = np.array([p.split(",") for p in polygon.get("points").split()], dtype=float)
        bands.setdefault(polygon.get("fill"), {})[float(polygon.get("fill-opacity"))] = xy
    assert len(bands) == 4  # one pair per curve
    for pair in bands.values():
        (light, lighter), (dark, darker) = sorted(pair.items())
        assert light < dark
        # the darker band lies within the lighter one at every x (pixels: y down)
        half = darker.shape[0] // 2
        assert lighter.shape == darker.shape
        np.testing.assert_array_equal(darker[:, 0], lighter[:, 0])
        assert np.all(darker[:half, 1] >= lighter[:half, 1])  # upper edge below
        assert np.all(darker[half:, 1] <= lighter[half:, 1])  # lower edge above
        assert np.any(darker[:half, 1] > lighter[:half, 1] + 1)  # visibly narrower
    text = "".join(svg.itertext())
    assert "function interval" in text and "prediction interval" in text
    facts = _terms_table(cm)
    assert f"σ_noise = {np.sqrt(cm.noise_variance):.4g}" in facts
    assert f"σ_model = {np.sqrt(cm.model_error_variance):.4g}" in facts


def test_half_squared_differences_against_a_loop_over_each_maneuver():
    """The per-sample noise estimate of the "local" variances: (r_{i+1} − r_i)²/2 to the
    next sample of the same maneuver (the last of a maneuver: to its previous one), by an
    explicit loop; on white noise its mean is the noise variance."""
    from flightid.globalmodel.fit import half_squared_differences

    rng = np.random.default_rng(5)
    r = 0.3 * rng.standard_normal(4000)
    index = np.repeat([0, 1, 2, 3], 1000)
    expected = np.empty(r.size)
    for i in range(r.size):
        j = i + 1 if i + 1 < r.size and index[i + 1] == index[i] else i - 1
        expected[i] = (r[j] - r[i]) ** 2 / 2
    np.testing.assert_allclose(half_squared_differences(r, index), expected, rtol=1e-12)
    assert np.mean(half_squared_differences(r, index)) == pytest.approx(0.09, rel=0.1)
