"""Cramér–Rao bounds against the analytic covariance; the result object and its JSON."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flightid.cli.main import main
from flightid.data import FlightData
from flightid.estimation import MNR, MNRES, estimate
from flightid.model import Parameters, StateSpaceModel


def _static_f(t, x, u, theta):
    return np.zeros(1)


def _static_h(t, x, u, theta):
    # y = θ0 + θ1·u1 + θ2·u2 : linear in the parameters
    return np.array([theta[0] + theta[1] * u[0] + theta[2] * u[1]])


def test_cramer_rao_bounds_equal_the_least_squares_covariance_for_a_linear_model():
    rng = np.random.default_rng(3)
    n = 300
    t = np.arange(n) * 0.1
    u1, u2 = rng.normal(size=n), np.sin(t)
    x = np.column_stack([np.ones(n), u1, u2])
    y = x @ np.array([0.5, -2.0, 1.5]) + rng.normal(0.0, 0.2, n)
    model = StateSpaceModel(
        ("dummy",),
        ("u1", "u2"),
        ("y",),
        _static_f,
        _static_h,
        Parameters({"c0": 0.0, "c1": -1.0, "c2": 1.0}),
        x0=(0.0,),
    )
    data = FlightData(t, {"u1": u1, "u2": u2}, {"y": y})
    result = estimate(model, data, MNR(), noise="max")
    # Closed form: ordinary least squares θ̂ = (XᵀX)⁻¹Xᵀy; the ML variance R̂ = RSS/N and
    # the Cramér–Rao covariance R̂ (XᵀX)⁻¹.
    theta_ls, *_ = np.linalg.lstsq(x, y, rcond=None)
    r_hat = np.sum((y - x @ theta_ls) ** 2) / n
    covariance = r_hat * np.linalg.inv(x.T @ x)
    np.testing.assert_allclose(result.values, theta_ls, rtol=1e-6)
    np.testing.assert_allclose(result.r_diag, [r_hat], rtol=1e-6)
    np.testing.assert_allclose(result.covariance, covariance, rtol=1e-5)
    np.testing.assert_allclose(result.std, np.sqrt(np.diag(covariance)), rtol=1e-5)


def test_unidentifiable_parameter_gets_an_infinite_bound_and_a_message():
    n = 50
    t = np.arange(n) * 0.1
    u1 = np.sin(t)
    model = StateSpaceModel(
        ("dummy",),
        ("u1", "u2"),
        ("y",),
        _static_f,
        _static_h,
        Parameters({"c0": 0.0, "c1": 1.0, "c2": 1.0}),
        x0=(0.0,),
    )
    # u2 ≡ 0: c2 has no effect on the output
    data = FlightData(
        t,
        {"u1": u1, "u2": np.zeros(n)},
        {"y": 0.3 + 2.0 * u1 + np.random.default_rng(0).normal(0, 0.01, n)},
    )
    result = estimate(model, data, MNR(), noise="max")
    assert np.isinf(result.stddev("c2"))
    assert "c2" in result.message and "cannot be determined" in result.message
    assert np.isfinite(result.values).all()
    assert result.to_dict()["parameters"][2]["std"] is None


def test_result_is_frozen_and_summary_names_every_parameter(pendulum):
    model, data = pendulum
    result = estimate(model, data, MNRES())
    with pytest.raises(AttributeError):
        result.cost = 0.0
    with pytest.raises(ValueError):
        result.values[0] = 1.0
    text = result.summary()
    for name in model.parameters.names:
        assert name in text
    assert "equivalent evaluations" in text
    document = json.loads(result.to_json())
    assert document["method"] == "mnres"
    assert document["equivalent_evaluations"] == result.equivalent_evaluations
    # the model given by the user keeps its start values
    assert model.parameters.values.tolist() == [8.0, 0.5, 0.2, 2.3]


def test_cli_example1_json_follows_the_output_contract(capsys):
    assert main(["paper", "example1", "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["example"] == 1
    methods = [r["method"] for r in document["results"]]
    assert methods == ["fps", "mnr", "mnres"]
    for entry in document["results"]:
        for key, kind in (
            ("converged", bool),
            ("status", str),
            ("cost", float),
            ("iterations", int),
            ("equivalent_evaluations", int),
            ("wall_time_s", float),
            ("parameters", list),
        ):
            assert isinstance(entry[key], kind), key
        names = [p["name"] for p in entry["parameters"]]
        assert names == [f"theta{i}" for i in range(1, 7)]
        for p in entry["parameters"]:
            assert set(p) >= {"name", "value", "initial", "std", "free"}
            assert abs(p["value"] - p["true"]) < 1e-3


def test_cli_example2_case2_text_table(capsys):
    assert main(["paper", "example2", "--case", "2"]) == 0
    out = capsys.readouterr().out
    assert "table III" in out and "mnres (paper)" in out


def test_quickstart_example_runs_and_recovers_its_parameters(capsys):
    import runpy
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "examples" / "quickstart.py"
    runpy.run_path(str(script), run_name="__main__")
    out = capsys.readouterr().out
    assert "status: converged" in out
    # the truth is k = 9, c = 0.3, b = 2 (set in the script)
    rows = {
        line.split()[0]: float(line.split()[1])
        for line in out.splitlines()
        if line.split() and line.split()[0] in ("k", "c", "b")
    }
    assert rows["k"] == pytest.approx(9.0, rel=0.01)
    assert rows["c"] == pytest.approx(0.3, rel=0.05)
    assert rows["b"] == pytest.approx(2.0, rel=0.01)


def test_progress_callback_sees_every_pass_with_growing_evaluations(pendulum):
    model, data = pendulum
    calls = []
    result = estimate(model, data, MNRES(), progress=lambda *args: calls.append(args))
    assert [c[0] for c in calls] == list(range(len(result.cost_history)))
    evaluations = [c[1] for c in calls]
    assert evaluations == sorted(evaluations) and evaluations[-1] <= result.equivalent_evaluations
    assert [c[2] for c in calls] == list(result.cost_history)
