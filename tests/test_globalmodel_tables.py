"""Table models (flightid.globalmodel.tables) against independent references: scipy's
B-splines (BSpline.design_matrix, make_lsq_spline), RegularGridInterpolator, numpy least
squares, closed-form tables, and seeded Monte Carlo for the σ of the table values."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats
from scipy.interpolate import BSpline, RegularGridInterpolator, make_lsq_spline

from flightid.errors import InputError
from flightid.globalmodel.tables import (
    BreakpointChoice,
    PenalisedLeastSquaresResult,
    TableComponent,
    TableError,
    TableFit,
    auto_breakpoints,
    choose_breakpoints,
    cubic_bspline_functions,
    fit_table_model,
    hat_functions,
    table_basis,
)
from flightid.regression.least_squares import least_squares

ALPHA = np.array([-0.1, 0.0, 0.08, 0.2, 0.35])
DE = np.array([-0.3, -0.15, 0.0, 0.15, 0.3])
MACH = np.array([0.3, 0.5, 0.7, 0.9])


def _uniform_points(rng, n, low_high):
    return {name: rng.uniform(low, high, n) for name, (low, high) in low_high.items()}


def _grid_truth(alpha, de, table):
    """An independent evaluation of a 2-D linear table (scipy)."""
    interpolate = RegularGridInterpolator((ALPHA, DE), table, method="linear")
    return interpolate(np.column_stack([alpha, de]))


# ------------------------------------------------------------------------------ bases


def test_hat_functions_partition_of_unity_and_scipy_linear_bspline():
    b = np.array([-1.0, -0.2, 0.0, 0.5, 2.0])
    x = np.random.default_rng(0).uniform(-1.0, 2.0, 500)
    phi = hat_functions(x, b)
    assert phi.shape == (500, 5)
    np.testing.assert_allclose(phi.sum(axis=1), 1.0, atol=1e-14)
    assert np.all(phi >= 0) and np.all((phi > 0).sum(axis=1) <= 2)
    # independent reference: scipy's linear B-splines on the knots (b_0, b, b_{K−1})
    knots = np.concatenate([[b[0]], b, [b[-1]]])
    reference = BSpline.design_matrix(x, knots, 1).toarray()
    np.testing.assert_allclose(phi, reference, atol=1e-14)
    # 1 at its own breakpoint, 0 at the others
    np.testing.assert_array_equal(hat_functions(b, b), np.eye(5))


def test_bases_clamp_outside_the_breakpoints():
    b = np.array([0.0, 1.0, 3.0])
    outside = np.array([-5.0, -0.1, 3.1, 100.0])
    edges = np.array([0.0, 0.0, 3.0, 3.0])
    np.testing.assert_array_equal(hat_functions(outside, b), hat_functions(edges, b))
    np.testing.assert_array_equal(
        cubic_bspline_functions(outside, b), cubic_bspline_functions(edges, b)
    )
    cubic = cubic_bspline_functions(np.linspace(0, 3, 50), b)
    assert cubic.shape == (50, 5)
    np.testing.assert_allclose(cubic.sum(axis=1), 1.0, atol=1e-14)


def test_table_basis_tensor_product_times_and_identifiability_rule():
    rng = np.random.default_rng(3)
    limits = {"alpha": (-0.1, 0.35), "de": (-0.3, 0.3), "q": (-1, 1), "mach": (0.3, 0.9)}
    signals = _uniform_points(rng, 60, limits)
    grid = TableComponent(("alpha", "de"), {"alpha": ALPHA, "de": DE})
    mach = TableComponent(("mach",), {"mach": MACH})
    rate = TableComponent(("alpha",), {"alpha": ALPHA}, times="q")
    B, labels = table_basis([grid, rate, mach], signals)
    # 25 + 5 (a times group of its own: nothing dropped) + 4 − 1 (second untimed: first dropped)
    assert B.shape == (60, 33)
    assert labels[0] == "alpha:de[0,0]" and labels[6] == "alpha:de[1,1]"
    assert labels[25] == "q*alpha[0]" and labels[30] == "mach[1]"
    a = hat_functions(signals["alpha"], ALPHA)
    d = hat_functions(signals["de"], DE)
    m = hat_functions(signals["mach"], MACH)
    np.testing.assert_allclose(B[:, :25], np.einsum("ni,nj->nij", a, d).reshape(60, 25))
    np.testing.assert_allclose(B[:, 25:30], a * signals["q"][:, None])
    np.testing.assert_allclose(B[:, 30:], m[:, 1:])
    # the columns are linearly independent (numpy's rank); with mach's first column not
    assert np.linalg.matrix_rank(B) == B.shape[1]
    assert np.linalg.matrix_rank(np.hstack([B, m[:, :1]])) == B.shape[1]


# ------------------------------------------------------------------- exact recovery


def test_piecewise_linear_2d_table_recovered_exactly():
    rng = np.random.default_rng(5)
    table = rng.normal(size=(ALPHA.size, DE.size))
    signals = _uniform_points(rng, 600, {"alpha": (-0.1, 0.35), "de": (-0.3, 0.3)})
    z = _grid_truth(signals["alpha"], signals["de"], table)
    component = TableComponent(("alpha", "de"), {"alpha": ALPHA, "de": DE})
    fit = fit_table_model(z, component, signals)
    np.testing.assert_allclose(fit.values[0], table, atol=1e-10)
    np.testing.assert_allclose(fit.coefficients[0], table, atol=1e-10)
    assert not fit.filled[0].any() and not fit.dropped[0].any()
    # evaluate = regressors @ θ̂
    np.testing.assert_allclose(
        fit.regressors(signals) @ fit.estimates, fit.evaluate(signals), atol=1e-13
    )


@pytest.mark.parametrize("degree", [1, 3])
def test_one_dimensional_fit_equals_scipy_make_lsq_spline(degree):
    rng = np.random.default_rng(11 + degree)
    x = np.sort(rng.uniform(-0.2, 0.6, 400))
    z = np.sin(6 * x) + 0.3 * x**2 + rng.normal(0, 0.05, x.size)
    b = np.array([-0.2, -0.05, 0.1, 0.15, 0.3, 0.45, 0.6])
    knots = np.concatenate([np.repeat(b[0], degree), b, np.repeat(b[-1], degree)])
    reference = make_lsq_spline(x, z, knots, k=degree)
    fit = fit_table_model(z, TableComponent(("alpha",), {"alpha": b}, degree=degree), {"alpha": x})
    xs = np.linspace(-0.2, 0.6, 301)
    np.testing.assert_allclose(fit.evaluate({"alpha": xs}), reference(xs), atol=1e-9)
    np.testing.assert_allclose(fit.coefficients[0], reference.c, atol=1e-9)
    # the table values are the spline at the breakpoints
    np.testing.assert_allclose(fit.values[0], reference(b), atol=1e-9)


def test_two_dimensional_evaluation_equals_regular_grid_interpolator():
    rng = np.random.default_rng(8)
    signals = _uniform_points(rng, 800, {"alpha": (-0.1, 0.35), "de": (-0.3, 0.3)})
    z = np.cos(4 * signals["alpha"]) * (1 + signals["de"]) + rng.normal(0, 0.02, 800)
    fit = fit_table_model(z, TableComponent(("alpha", "de"), {"alpha": ALPHA, "de": DE}), signals)
    interpolate = RegularGridInterpolator((ALPHA, DE), fit.values[0], method="linear")
    points = _uniform_points(rng, 500, {"alpha": (-0.3, 0.6), "de": (-0.5, 0.5)})
    # the table holds its edge value outside: the reference at the clipped points
    clipped = np.column_stack(
        [np.clip(points["alpha"], ALPHA[0], ALPHA[-1]), np.clip(points["de"], DE[0], DE[-1])]
    )
    np.testing.assert_allclose(fit.evaluate(points), interpolate(clipped), atol=1e-12)


def test_times_component_recovers_rate_derivative_table():
    rng = np.random.default_rng(21)
    signals = _uniform_points(rng, 900, {"alpha": (-0.1, 0.35), "qhat": (-0.02, 0.02)})
    cl0 = np.array([0.1, 0.2, 0.5, 0.9, 1.1])
    clq = np.array([4.0, 5.0, 6.5, 7.0, 3.0])  # C_Lq(α): non-zero at the first breakpoint
    a = signals["alpha"]
    # z = C_L0(α) + C_Lq(α)·q̂, both linear between the breakpoints (numpy's interp)
    z = np.interp(a, ALPHA, cl0) + np.interp(a, ALPHA, clq) * signals["qhat"]
    components = [
        TableComponent(("alpha",), {"alpha": ALPHA}),
        TableComponent(("alpha",), {"alpha": ALPHA}, times="qhat"),
    ]
    fit = fit_table_model(z, components, signals, units={"qhat*alpha": "1/rad"})
    np.testing.assert_allclose(fit.values[0], cl0, atol=1e-10)
    np.testing.assert_allclose(fit.values[1], clq, atol=1e-8)
    assert fit.names[5] == "qhat*alpha[0]"
    assert fit.fit.unit_map["qhat*alpha[4]"] == "1/rad" and fit.fit.unit_map["alpha[4]"] == ""


def test_second_component_values_relative_to_its_first_breakpoint():
    rng = np.random.default_rng(4)
    signals = _uniform_points(rng, 700, {"alpha": (-0.1, 0.35), "de": (-0.3, 0.3)})
    f_alpha = np.array([0.3, 0.1, 0.0, 0.4, 0.9])
    g_de = np.array([-0.2, 0.1, 0.5, 0.6, 0.4])
    z = np.interp(signals["alpha"], ALPHA, f_alpha) + np.interp(signals["de"], DE, g_de)
    components = [
        TableComponent(("alpha",), {"alpha": ALPHA}),
        TableComponent(("de",), {"de": DE}),
    ]
    fit = fit_table_model(z, components, signals)
    # the constant goes to the first table: g shifted to 0 at its first breakpoint
    np.testing.assert_allclose(fit.values[0], f_alpha + g_de[0], atol=1e-10)
    np.testing.assert_allclose(fit.values[1], g_de - g_de[0], atol=1e-10)
    assert fit.value_std[1][0] == 0.0 and fit.coefficients[1][0] == 0.0


# ------------------------------------------------------------------- cells without data


def _data_with_hole(rng, n=1500):
    """(α, δe) samples with none within one grid cell of the node (α = 0.08, δe = 0)."""
    signals = _uniform_points(rng, n, {"alpha": (-0.1, 0.35), "de": (-0.3, 0.3)})
    hole = (
        (signals["alpha"] > ALPHA[1])
        & (signals["alpha"] < ALPHA[3])
        & (signals["de"] > DE[1])
        & (signals["de"] < DE[3])
    )
    return {k: v[~hole] for k, v in signals.items()}


def _multilinear(alpha, de):
    # linear along each axis: second differences of its table are zero
    return 0.2 + 1.5 * alpha - 0.7 * de + 2.0 * alpha * de


def test_empty_cell_filled_and_flagged_with_smoothing():
    rng = np.random.default_rng(31)
    signals = _data_with_hole(rng)
    z = _multilinear(signals["alpha"], signals["de"])
    component = TableComponent(("alpha", "de"), {"alpha": ALPHA, "de": DE})
    fit = fit_table_model(z, component, signals, smoothing=1e-3)
    expected = np.zeros((5, 5), dtype=bool)
    expected[2, 2] = True
    np.testing.assert_array_equal(fit.filled[0], expected)
    assert not fit.dropped[0].any()
    # noise-free and penalty-free truth: the filled value is the truth's value there
    truth = _multilinear(ALPHA[:, None], DE[None, :])
    np.testing.assert_allclose(fit.values[0], truth, atol=1e-9)
    assert isinstance(fit.fit, PenalisedLeastSquaresResult)
    # statistics over the data rows only: N samples, N − edf dof
    assert fit.fit.n_samples == signals["alpha"].size and fit.fit.n_parameters == 25
    # the filled value has no data column: edf ≤ rank B = 24
    assert 23 < fit.fit.effective_parameters < 24
    assert fit.dof == pytest.approx(fit.fit.n_samples - fit.fit.effective_parameters)


def test_empty_cell_dropped_and_flagged_without_smoothing():
    rng = np.random.default_rng(31)
    signals = _data_with_hole(rng)
    z = _multilinear(signals["alpha"], signals["de"])
    component = TableComponent(("alpha", "de"), {"alpha": ALPHA, "de": DE})
    fit = fit_table_model(z, component, signals)
    assert fit.dropped[0][2, 2] and fit.dropped[0].sum() == 1
    assert not fit.filled[0].any()
    assert np.isnan(fit.values[0][2, 2]) and np.isnan(fit.value_std[0][2, 2])
    assert "alpha:de[2,2]" not in fit.names and len(fit.names) == 24
    truth = _multilinear(ALPHA[:, None], DE[None, :])
    mask = ~fit.dropped[0]
    np.testing.assert_allclose(fit.values[0][mask], truth[mask], atol=1e-10)
    # NaN where the dropped value acts (its four cells), the truth elsewhere
    points = {"alpha": np.array([0.1, 0.05, 0.3]), "de": np.array([0.0, 0.1, -0.2])}
    value = fit.evaluate(points)
    assert np.isnan(value[0]) and np.isnan(value[1])
    np.testing.assert_allclose(value[2], _multilinear(0.3, -0.2), atol=1e-10)
    assert np.isnan(fit.regressors(points)[0]).all()


def test_smoothing_to_zero_matches_least_squares():
    rng = np.random.default_rng(2)
    signals = _uniform_points(rng, 600, {"alpha": (-0.1, 0.35), "de": (-0.3, 0.3)})
    # AR(1) noise in 3 maneuvers: the coloured σ path of both fits
    e = np.zeros(600)
    for k in range(1, 600):
        e[k] = 0.9 * e[k - 1] + rng.normal(0, 0.01)
    z = np.sin(3 * signals["alpha"]) + signals["de"] ** 2 + e
    maneuvers = np.repeat([0, 1, 2], 200)
    component = TableComponent(("alpha", "de"), {"alpha": ALPHA, "de": DE})
    smoothed = fit_table_model(z, component, signals, smoothing=1e-12, maneuver_index=maneuvers)
    B, names = table_basis([component], signals)
    reference = least_squares(B, z, names, maneuver_index=maneuvers)
    assert smoothed.fit.std_kind == reference.std_kind == "coloured"
    np.testing.assert_allclose(smoothed.estimates, reference.estimates, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(smoothed.fit.std_cr, reference.std_cr, rtol=1e-6)
    np.testing.assert_allclose(smoothed.fit.std, reference.std, rtol=1e-6)
    assert smoothed.fit.dof == pytest.approx(reference.dof, abs=1e-6)
    assert smoothed.fit.pse == pytest.approx(reference.pse, rel=1e-9)
    # R² about the mean: the tables hold the constant
    r2 = 1 - reference.rss / np.sum((z - z.mean()) ** 2)
    assert smoothed.fit.r2 == pytest.approx(r2, rel=1e-9)


# ------------------------------------------------------------------- σ by Monte Carlo


def _coverage(smoothing, signals, seeds=300, sigma=0.05):
    component = TableComponent(("alpha", "de"), {"alpha": ALPHA, "de": DE})
    truth = _multilinear(ALPHA[:, None], DE[None, :])
    clean = _multilinear(signals["alpha"], signals["de"])
    inside = []
    filled_inside = []
    for seed in range(seeds):
        noise = np.random.default_rng(1000 + seed).normal(0, sigma, clean.size)
        fit = fit_table_model(clean + noise, component, signals, smoothing=smoothing)
        q = stats.t.ppf(0.975, fit.dof)
        hit = np.abs(fit.values[0] - truth) <= q * fit.value_std[0]
        inside.append(hit.ravel())
        filled_inside.append(hit[fit.filled[0]])
    return np.array(inside), np.concatenate(filled_inside)


def test_value_sigma_covers_in_monte_carlo_plain_fit():
    signals = _uniform_points(
        np.random.default_rng(40), 200, {"alpha": (-0.1, 0.35), "de": (-0.3, 0.3)}
    )
    inside, _ = _coverage(0.0, signals)
    assert inside.shape == (300, 25)
    assert 0.92 <= inside.mean() <= 0.98
    # every value on its own within binomial 4σ of 0.95 (300 seeds)
    assert np.all(np.abs(inside.mean(axis=0) - 0.95) <= 4 * np.sqrt(0.95 * 0.05 / 300))


def test_value_sigma_covers_in_monte_carlo_smoothed_fit_with_filled_cell():
    signals = _data_with_hole(np.random.default_rng(41), n=260)
    inside, filled = _coverage(1e-2, signals)
    assert 0.92 <= inside.mean() <= 0.98
    assert filled.size == 300
    assert 0.90 <= filled.mean() <= 0.99


# ------------------------------------------------------------------ JSON round trip


def test_to_dict_from_dict_evaluates_identically_and_is_strict_json():
    rng = np.random.default_rng(9)
    signals = _data_with_hole(rng, 900)
    n = signals["alpha"].size
    signals["qhat"] = rng.normal(0, 0.01, n)
    z = np.sin(5 * signals["alpha"]) + 3 * signals["qhat"] + rng.normal(0, 0.01, n)
    components = [
        TableComponent(("alpha", "de"), {"alpha": ALPHA, "de": DE}),
        TableComponent(("alpha",), {"alpha": ALPHA}, times="qhat", degree=3),
    ]
    limits = {"alpha": (-0.3, 0.5), "de": (-0.4, 0.4), "qhat": (-0.02, 0.02)}
    points = _uniform_points(rng, 300, limits)
    for smoothing in (0.0, 1e-4):
        fit = fit_table_model(z, components, signals, smoothing=smoothing)
        text = json.dumps(fit.to_dict(), allow_nan=False)
        again = TableFit.from_dict(json.loads(text))
        np.testing.assert_array_equal(again.evaluate(points), fit.evaluate(points))
        np.testing.assert_array_equal(again.regressors(points), fit.regressors(points))
        for a, b in zip(again.values + again.filled, fit.values + fit.filled, strict=True):
            np.testing.assert_array_equal(a, b)
        assert again.names == fit.names and again.dof == fit.dof
        # λ = 0 dropped the node without data (null in JSON, NaN where it acts)
        assert again.dropped[0][2, 2] == (smoothing == 0.0)
        assert np.isnan(again.evaluate(points)).any() == (smoothing == 0.0)


# ------------------------------------------------------------------- breakpoints


def test_auto_breakpoints_cover_the_data_rounded_and_unique():
    x = np.random.default_rng(6).uniform(-0.137, 0.5712, 5000)
    b = auto_breakpoints(x, 6)
    assert b[0] <= x.min() and b[-1] >= x.max()
    assert np.all(np.diff(b) > 0) and b.size == 6
    # two significant digits of the spacing 0.14: multiples of 0.01
    np.testing.assert_allclose(b * 100, np.round(b * 100), atol=1e-9)
    # a variable that takes few values gives fewer breakpoints
    few = np.repeat([0.0, 1.0, 2.0], 50)
    np.testing.assert_array_equal(auto_breakpoints(few, 8), [0.0, 1.0, 2.0])


def test_choose_breakpoints_by_pse():
    rng = np.random.default_rng(12)
    x = rng.uniform(0.0, 1.0, 3000)
    wavy = np.sin(4 * np.pi * x) + rng.normal(0, 0.05, x.size)
    straight = 2.0 * x + rng.normal(0, 0.05, x.size)
    choice = choose_breakpoints(wavy, "alpha", {"alpha": x})
    assert isinstance(choice, BreakpointChoice)
    assert choice.breakpoints.size >= 9  # two periods need many breakpoints
    assert choose_breakpoints(straight, "alpha", {"alpha": x}).breakpoints.size == 3
    # PSE of a count = RSS/N + σ²_max n_p/N of numpy's least squares on that basis
    count = choice.counts.index(5)
    B = hat_functions(x, auto_breakpoints(x, 5))
    theta, *_ = np.linalg.lstsq(B, wavy, rcond=None)
    rss = np.sum((wavy - B @ theta) ** 2)
    expected = rss / x.size + np.var(wavy) * B.shape[1] / x.size
    assert choice.pse[count] == pytest.approx(expected, rel=1e-10)


# --------------------------------------------------------------------- bad inputs


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            {"variables": ("alpha",), "breakpoints": {"alpha": [0.0, 0.0, 1.0]}},
            "strictly increasing",
        ),
        ({"variables": ("alpha",), "breakpoints": {"alpha": [0.0]}}, "at least 2"),
        ({"variables": ("alpha",), "breakpoints": {"alpha": [0.0, np.nan]}}, "finite"),
        ({"variables": ("alpha",), "breakpoints": {}}, "missing ['alpha']"),
        ({"variables": ("a", "b", "c", "d"), "breakpoints": {}}, "1 to 3"),
        ({"variables": ("a", "a"), "breakpoints": {"a": [0, 1]}}, "distinct"),
        ({"variables": ("a",), "breakpoints": {"a": [0, 1]}, "degree": 2}, "expected 1 or 3"),
        ({"variables": ("a",), "breakpoints": {"a": [0, 1]}, "times": ""}, "times"),
    ],
)
def test_bad_components_raise_table_error(kwargs, message):
    with pytest.raises(TableError, match="expected") as info:
        TableComponent(**kwargs)
    assert message in str(info.value)
    assert isinstance(info.value, InputError)


def test_bad_fit_inputs_raise_named_errors():
    rng = np.random.default_rng(1)
    signals = _uniform_points(rng, 100, {"alpha": (-0.1, 0.35), "de": (-0.3, 0.3)})
    z = signals["alpha"].copy()
    alpha = TableComponent(("alpha",), {"alpha": ALPHA})
    alpha_de = TableComponent(("alpha", "de"), {"alpha": ALPHA, "de": DE})
    with pytest.raises(TableError, match=r"missing \['de'\]"):
        fit_table_model(z, alpha_de, {"alpha": signals["alpha"]})
    with pytest.raises(TableError, match="expected 100 samples, got 99"):
        fit_table_model(z[:-1], alpha, signals)
    bad = dict(signals, alpha=np.where(np.arange(100) == 7, np.inf, signals["alpha"]))
    with pytest.raises(TableError, match="finite values, got inf at sample 7"):
        fit_table_model(z, alpha, bad)
    with pytest.raises(TableError, match="smoothing: expected a non-negative"):
        fit_table_model(z, alpha, signals, smoothing=-1.0)
    with pytest.raises(TableError, match="sigma2_max: expected a non-negative"):
        fit_table_model(z, alpha, signals, smoothing=1.0, sigma2_max=float("nan"))
    with pytest.raises(TableError, match="no variable in common"):
        fit_table_model(z, [alpha_de, alpha], signals)
    with pytest.raises(TableError, match="units: expected component labels"):
        fit_table_model(z, alpha, signals, units={"beta": "1/rad"})
    with pytest.raises(TableError, match="maneuver_index"):
        fit_table_model(z, alpha, signals, maneuver_index=np.zeros(5))
    with pytest.raises(TableError, match="n: expected an integer"):
        auto_breakpoints(signals["alpha"], 1)
    with pytest.raises(TableError, match="spread over an interval"):
        auto_breakpoints(np.ones(10), 4)
    with pytest.raises(TableError, match="expected a mapping with keys"):
        TableFit.from_dict({"tables": []})
    written = fit_table_model(z, alpha, signals, units={"alpha": "1/rad"}).to_dict()
    with pytest.raises(TableError, match=r"one name per fitted table coefficient \(5\), got 4"):
        TableFit.from_dict(dict(written, parameters=written["parameters"][:4]))
    # a table times a constant signal repeats the plain table: named, not a silent split
    ones = dict(signals, one=np.ones(100))
    doubled = [alpha, TableComponent(("alpha",), {"alpha": ALPHA}, times="one")]
    with pytest.raises(TableError, match="do not determine the table values"):
        fit_table_model(z, doubled, ones)
    # data on the line δe ∝ α − 0.1: the multilinear δe − k(α − 0.1) vanishes on the data and
    # has no second differences, so even smoothing cannot determine it
    line = {"alpha": signals["alpha"], "de": 1.2 * (signals["alpha"] - 0.1)}
    with pytest.raises(TableError, match="do not determine the table values"):
        fit_table_model(z, alpha_de, line, smoothing=1e-3)
    # all data at α = 0.35: only the last value has data, the others dropped, nothing fits
    edge = {"alpha": np.full(100, 0.35)}
    fit = fit_table_model(z, alpha, edge)
    assert fit.dropped[0].tolist() == [True, True, True, True, False]
