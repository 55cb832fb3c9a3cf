"""The one result surface (flightid.results): summary, to_dict, to_frame, conf_int, plot and
units on Estimate, AccuracyResult, LeastSquaresResult and StepwiseResult; run_case from a
path; time_histories.csv."""

from __future__ import annotations

import csv
import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure
from scipy import stats

from flightid.accuracy import assess
from flightid.data import FlightData
from flightid.errors import InputError, InputTypeError
from flightid.estimation import MNR, estimate
from flightid.model import Parameters, StateSpaceModel
from flightid.model.parameters import Parameter
from flightid.regression.least_squares import least_squares
from flightid.regression.stepwise import stepwise
from flightid.results import MissingDependencyError

ROOT = Path(__file__).resolve().parents[1]
CSV_CASE = ROOT / "examples" / "csv_walkthrough" / "my_case.toml"


def _static_f(t, x, u, theta):
    return np.zeros(1)


def _static_h(t, x, u, theta):
    # y = θ0 + θ1·u1 + θ2·u2 : linear in the parameters
    return np.array([theta[0] + theta[1] * u[0] + theta[2] * u[1]])


@pytest.fixture(scope="module")
def linear():
    """An output-error estimate of a model linear in θ, with units, and its data."""
    rng = np.random.default_rng(11)
    n = 40
    t = np.arange(n) * 0.1
    u1, u2 = rng.normal(size=n), np.sin(t)
    x = np.column_stack([np.ones(n), u1, u2])
    y = x @ np.array([0.5, -2.0, 1.5]) + rng.normal(0.0, 0.3, n)
    parameters = Parameters(
        [
            Parameter("c0", 0.0, unit="m/s"),
            Parameter("c1", -1.0, unit="m/s/deg"),
            Parameter("c2", 1.0),
        ]
    )
    model = StateSpaceModel(
        ("dummy",), ("u1", "u2"), ("y",), _static_f, _static_h, parameters, x0=(0.0,)
    )
    data = FlightData(t, {"u1": u1, "u2": u2}, {"y": y}, units={"y": "m/s", "u1": "deg"})
    result = estimate(model, data, MNR(), noise="max", compiled=False)
    return result, data, x, y


# ---------------------------------------------------------------------------- conf_int


def test_estimate_conf_int_of_a_linear_model_is_the_classical_t_interval(linear):
    result, _, x, y = linear
    # Independent closed form (ordinary least squares, e.g. statsmodels' conf_int): with
    # R̂ = RSS/N the Cramér–Rao covariance is R̂(XᵀX)⁻¹ and s² = J/(N − p) = N/(N − p), so
    # s·σ_j is the classical standard error √(RSS/(N − p) · (XᵀX)⁻¹_jj).
    n, p = x.shape
    theta, *_ = np.linalg.lstsq(x, y, rcond=None)
    rss = float(np.sum((y - x @ theta) ** 2))
    se = np.sqrt(rss / (n - p) * np.diag(np.linalg.inv(x.T @ x)))
    for level in (0.95, 0.8):
        q = stats.t.ppf(0.5 * (1 + level), n - p)
        expected = np.column_stack([theta - q * se, theta + q * se])
        np.testing.assert_allclose(result.conf_int(level), expected, rtol=1e-5)
    # normal: z instead of t
    z = stats.norm.ppf(0.975)
    np.testing.assert_allclose(
        result.conf_int(distribution="normal"),
        np.column_stack([theta - z * se, theta + z * se]),
        rtol=1e-5,
    )
    # simultaneous: √(p F_c(p, N − p)) instead of t  [RP-1153 5.25]
    k = np.sqrt(p * stats.f.ppf(0.95, p, n - p))
    np.testing.assert_allclose(
        result.conf_int(kind="simultaneous"),
        np.column_stack([theta - k * se, theta + k * se]),
        rtol=1e-5,
    )
    # the same numbers from the least-squares result on the same regression
    fit = least_squares(x, y, ["c0", "c1", "c2"])
    np.testing.assert_allclose(result.conf_int(0.9), fit.conf_int(0.9), rtol=1e-5)
    assert result.conf_int_names == ["c0", "c1", "c2"]


def test_estimate_conf_int_rejects_what_it_cannot_do(linear):
    result = linear[0]
    with pytest.raises(InputError, match=r"method: expected one of \['cr'\], got 'profile'"):
        result.conf_int(method="profile")
    with pytest.raises(InputError, match="level"):
        result.conf_int(1.5)
    with pytest.raises(InputError, match="distribution"):
        result.conf_int(distribution="cauchy")


def test_least_squares_t_interval_covers_at_its_level_and_normal_does_not():
    # Seeded Monte Carlo: N = 6, n_p = 2 (4 dof). The 90 % t interval must cover the true
    # slope in 90 % of the trials; the z interval (too narrow at 4 dof) about 81 %.
    rng = np.random.default_rng(5)
    xs = np.column_stack([np.ones(6), np.arange(6.0)])
    trials, hits_t, hits_z = 3000, 0, 0
    for _ in range(trials):
        z = xs @ np.array([1.0, 0.5]) + rng.normal(0.0, 1.0, 6)
        fit = least_squares(xs, z)
        lo, hi = fit.conf_int(0.9)[1]
        hits_t += lo <= 0.5 <= hi
        lo, hi = fit.conf_int(0.9, method="normal")[1]
        hits_z += lo <= 0.5 <= hi
    # 3σ of a binomial proportion at 0.9 with 3000 trials: 0.016
    assert abs(hits_t / trials - 0.90) < 0.017
    assert hits_z / trials < 0.86
    with pytest.raises(InputError, match=r"method: expected one of \['t', 'normal'\]"):
        fit.conf_int(method="cr")


@pytest.fixture(scope="module")
def assessed(linear):
    result, data, _, _ = linear
    accuracy = assess(result, data, methods=("cr", "profile"), compiled=False, warn=False)
    return result, accuracy


def test_accuracy_conf_int_holds_every_method_and_re_levels_the_quadratic_ones(assessed):
    result, accuracy = assessed
    assert accuracy.methods == ("cr", "cr_simultaneous", "cr_coloured", "cr_beale", "profile")
    for method in accuracy.methods:
        np.testing.assert_array_equal(
            accuracy.conf_int(method=method), getattr(accuracy, f"ci_{method}")
        )
    # The re-levelling path reproduces assess's own intervals: a copy that claims level 0.8
    # asked for 0.95 must give back the 0.95 tables.
    other = dataclasses.replace(accuracy, level=0.8)
    for method in ("cr", "cr_simultaneous", "cr_coloured", "cr_beale"):
        np.testing.assert_allclose(
            other.conf_int(0.95, method), getattr(accuracy, f"ci_{method}"), rtol=1e-12
        )
    # cr at 0.9 is θ̂ ± t_0.95(N − p)·s·σ_j (s² from the polished minimum)
    q = stats.t.ppf(0.95, accuracy.n_data - accuracy.n_free)
    half = q * np.sqrt(accuracy.s2) * accuracy.std
    np.testing.assert_allclose(
        accuracy.conf_int(0.9),
        np.column_stack([accuracy.center - half, accuracy.center + half]),
        rtol=1e-10,
    )
    # Beale: Δ_B/Δ carried over [5.28]; with Δ_B = 4Δ the re-levelled intervals are twice
    # as wide as the plain CR ones
    wide = dataclasses.replace(accuracy, delta_beale=4.0 * accuracy.delta)
    cr, beale = wide.conf_int(0.9, "cr"), wide.conf_int(0.9, "cr_beale")
    np.testing.assert_allclose(beale[:, 1] - beale[:, 0], 2.0 * (cr[:, 1] - cr[:, 0]))
    with pytest.raises(InputError, match="profile limits were traced at level 0.95"):
        accuracy.conf_int(0.9, "profile")
    with pytest.raises(InputError, match=r"'search' was not run in this assessment"):
        accuracy.conf_int(method="search")


# ---------------------------------------------------------------------------- units, frames


def test_units_show_in_summary_dict_frame_and_json(linear, assessed):
    result = linear[0]
    accuracy = assessed[1]
    assert result.parameter_units == ("m/s", "m/s/deg", "")
    assert result.output_units == ("m/s",)
    summary = result.summary()
    assert "m/s/deg" in summary and "unit" in summary
    document = result.to_dict()
    assert [p["unit"] for p in document["parameters"]] == ["m/s", "m/s/deg", ""]
    assert document["output_units"] == ["m/s"]
    assert '"unit": "m/s/deg"' in result.to_json()
    frame = result.to_frame()
    assert list(frame.index) == ["c0", "c1", "c2"]
    assert frame.loc["c1", "unit"] == "m/s/deg"
    np.testing.assert_allclose(frame[["lower", "upper"]].to_numpy(), result.conf_int())
    # the accuracy result carries the units of the free parameters
    assert accuracy.units == ("m/s", "m/s/deg", "")
    assert "m/s/deg" in accuracy.summary()
    assert [p["unit"] for p in accuracy.to_dict()["parameters"]] == ["m/s", "m/s/deg", ""]
    frame = accuracy.to_frame()
    np.testing.assert_array_equal(frame["profile_lower"].to_numpy(), accuracy.ci_profile[:, 0])
    np.testing.assert_array_equal(frame["cr_upper"].to_numpy(), accuracy.ci_cr[:, 1])


def test_least_squares_units_and_frame():
    rng = np.random.default_rng(2)
    x = np.column_stack([np.ones(30), rng.normal(size=30)])
    z = x @ np.array([0.1, 4.0]) + rng.normal(0.0, 0.1, 30)
    fit = least_squares(x, z, ["CL0", "CLa"], units={"CLa": "1/rad"})
    assert fit.units == ("", "1/rad")
    assert "1/rad" in fit.summary()
    assert fit.to_dict()["parameters"][1]["unit"] == "1/rad"
    frame = fit.to_frame()
    assert frame.loc["CLa", "unit"] == "1/rad"
    np.testing.assert_allclose(frame["t"].to_numpy(), fit.estimates / fit.std)
    with pytest.raises(InputError, match=r"units: expected regressor names .* got \['CLb'\]"):
        least_squares(x, z, ["CL0", "CLa"], units={"CLb": "1/rad"})


def test_to_frame_without_pandas_names_the_extra(linear, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas now raises ImportError
    with pytest.raises(
        MissingDependencyError,
        match=r"Estimate.to_frame\(\): needs pandas.*"
        r"flightid\[pandas\]",
    ):
        linear[0].to_frame()


def test_stepwise_result_surface():
    rng = np.random.default_rng(4)
    n = 200
    signals = {"a": rng.normal(size=n), "b": rng.normal(size=n)}
    z = 1.0 + 3.0 * signals["a"] + rng.normal(0.0, 0.2, n)
    result = stepwise(z, ["a", "b"], signals, response="Cm")
    assert result.selected == ("1", "a")
    np.testing.assert_array_equal(result.conf_int(0.9), result.fit.conf_int(0.9))
    assert result.conf_int_names == ["1", "a"]
    frame = result.to_frame()
    assert list(frame.index) == ["1", "a"]
    lo, hi = frame.loc["a", ["lower", "upper"]]
    assert lo < 3.0 < hi
    assert "parameters" in result.to_dict() and '"selected"' in result.to_json()


# ---------------------------------------------------------------------------- plot


def test_plot_returns_a_figure_for_every_result(linear, assessed, tmp_path):
    result, _, x, y = linear
    figure = result.plot(tmp_path / "estimate.png")
    assert isinstance(figure, Figure) and (tmp_path / "estimate.png").stat().st_size > 0
    labels = [ax.get_ylabel() for ax in figure.axes]
    assert "y [m/s]" in labels
    assert isinstance(assessed[1].plot(), Figure)
    fit = least_squares(x, y)
    assert isinstance(fit.plot(), Figure)
    rng = np.random.default_rng(4)
    signals = {"a": rng.normal(size=50)}
    sw = stepwise(2.0 * signals["a"] + rng.normal(0, 0.1, 50), ["a"], signals)
    assert isinstance(sw.plot(), Figure)


def test_figure_of_names_what_it_accepts():
    from flightid.report.result_figures import figure_of

    with pytest.raises(InputTypeError, match="expected an Estimate, AccuracyResult"):
        figure_of(3)


# ---------------------------------------------------------------------------- run_case, CSV


@pytest.fixture(scope="module")
def csv_run():
    from flightid.cases import run_case

    return run_case(str(CSV_CASE), accuracy="none")


def test_run_case_accepts_a_path_and_rejects_other_types(csv_run):
    from flightid.cases import run_case

    assert csv_run.case.path.resolve() == CSV_CASE.resolve()
    assert csv_run.estimate.converged
    with pytest.raises(InputTypeError, match="case: expected a Case .* got int"):
        run_case(3)


def test_time_histories_csv_holds_the_run_samples(csv_run, tmp_path):
    from flightid.report.histories import time_history_columns, write_time_histories

    path = write_time_histories(csv_run, tmp_path / "time_histories.csv")
    with path.open(newline="") as stream:
        rows = list(csv.reader(stream))
    header, body = rows[0], rows[1:]
    assert header == [
        "maneuver",
        "role",
        "time",
        "de",
        "alpha_measured",
        "q_measured",
        "alpha_predicted",
        "q_predicted",
        "alpha_residual",
        "q_residual",
    ]
    assert header == [c["name"] for c in time_history_columns(csv_run)]
    units = {c["name"]: c["unit"] for c in time_history_columns(csv_run)}
    assert units["time"] == "s" and units["q_residual"] == "rad/s" and units["de"] == "rad"
    est = csv_run.estimate
    assert len(body) == est.time.size
    values = np.array([[float(v) for v in row[2:]] for row in body])
    np.testing.assert_array_equal(values[:, 0], est.time)
    np.testing.assert_array_equal(values[:, 1], csv_run.maneuvers[0].input("de"))
    np.testing.assert_array_equal(values[:, 2:4], est.measured)
    np.testing.assert_array_equal(values[:, 4:6], est.predicted)
    # residual = measured − predicted
    np.testing.assert_allclose(values[:, 6:8], est.measured - est.predicted, rtol=0, atol=0)
    assert {row[0] for row in body} == {"my_flight"} and {row[1] for row in body} == {"estimation"}
