"""Prediction and simulation from an estimate: ``Estimate.predict`` / ``Estimate.simulate``,
and output bands from the parameter covariance (delta method) checked by Monte Carlo."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from flightid.data.flightdata import FlightData
from flightid.estimation import estimate
from flightid.model.parameters import Parameters
from flightid.model.statespace import StateSpaceModel
from flightid.simulation import Simulator, simulate
from flightid.simulation.prediction import Prediction, PredictionError

TRUE = {"Za": -1.2, "Zde": -0.15, "Ma": -6.0, "Mq": -1.8, "Mde": -8.0}
TIME = np.arange(0.0, 10.0, 0.02)
NOISE = (2e-4, 5e-4)


def short_period_f(t, x, u, th):
    dx = np.empty(2)
    # α̇ = Z_α α + q + Z_δe δe
    dx[0] = th[0] * x[0] + x[1] + th[1] * u[0]
    # q̇ = M_α α + M_q q + M_δe δe
    dx[1] = th[2] * x[0] + th[3] * x[1] + th[4] * u[0]
    return dx


def short_period_h(t, x, u, th):
    return np.array([x[0], x[1]])


def short_period(values=TRUE, x0=(0.0, 0.0)) -> StateSpaceModel:
    return StateSpaceModel(
        ("alpha", "q"),
        ("de",),
        ("alpha", "q"),
        short_period_f,
        short_period_h,
        Parameters(dict(values)),
        x0=x0,
    )


def maneuver(seed: int, name: str, start=(0.0, 0.0)) -> FlightData:
    """A square-wave elevator input and the true model's outputs with seeded white noise."""
    de = 0.02 * np.sign(np.sin(2.0 * np.pi * TIME / (3.0 + seed)))
    silent = FlightData(TIME, {"de": de}, {"alpha": 0 * TIME, "q": 0 * TIME})
    y = simulate(short_period(x0=start), silent)
    z = y + np.random.default_rng(seed).normal(0.0, NOISE, y.shape)
    return FlightData(
        TIME,
        {"de": de},
        {"alpha": z[:, 0], "q": z[:, 1]},
        name=name,
        units={"alpha": "rad", "q": "rad/s", "de": "rad"},
    )


@pytest.fixture(scope="module")
def fitted():
    estimation, held_out = maneuver(1, "estimation"), maneuver(2, "held out", (0.01, -0.02))
    start = short_period({k: 1.2 * v for k, v in TRUE.items()})
    return estimate(start, estimation), estimation, held_out


def test_predict_gives_the_outputs_residuals_and_fit_numbers_of_the_estimated_model(fitted):
    result, _, held_out = fitted
    prediction = result.predict(held_out)
    assert isinstance(prediction, Prediction)
    # the way users did it by hand: the model at the estimates, x0 at the first measurement
    x0 = (held_out.output("alpha")[0], held_out.output("q")[0])
    by_hand = simulate(
        short_period(dict(zip(result.names, result.values, strict=True)), x0=x0), held_out
    )
    np.testing.assert_allclose(prediction.predicted, by_hand, rtol=0, atol=1e-14)
    z = np.column_stack([held_out.output("alpha"), held_out.output("q")])
    np.testing.assert_array_equal(prediction.measured, z)
    np.testing.assert_allclose(prediction.residuals, z - by_hand, atol=1e-14)
    # RMS error and R² written out here, independently of the module
    rms = np.sqrt(np.mean((z - by_hand) ** 2, axis=0))
    r2 = 1.0 - np.sum((z - by_hand) ** 2, axis=0) / np.sum((z - z.mean(axis=0)) ** 2, axis=0)
    np.testing.assert_allclose(prediction.rms, rms, rtol=1e-12)
    np.testing.assert_allclose(prediction.r2, r2, rtol=1e-12)
    # a held-out maneuver of the true model: the residual is the measurement noise
    np.testing.assert_allclose(prediction.rms, NOISE, rtol=0.1)
    entry = prediction.to_dict()
    assert entry["maneuver"] == "held out" and entry["samples"] == TIME.size
    assert "predicted_std_rms" not in entry
    assert "alpha" in prediction.summary()


def test_predict_of_a_list_gives_one_prediction_per_maneuver(fitted):
    result, estimation, held_out = fitted
    both = result.predict([estimation, held_out])
    assert isinstance(both, tuple) and [p.name for p in both] == ["estimation", "held out"]
    np.testing.assert_array_equal(both[1].predicted, result.predict(held_out).predicted)


def test_simulate_follows_the_closed_form_step_response():
    # ẋ = a x + b u, u = 1 from x0: x(t) = (x0 + b/a) e^{a t} − b/a  (closed form)
    def f(t, x, u, th):
        return np.array([th[0] * x[0] + th[1] * u[0]])

    def h(t, x, u, th):
        return np.array([x[0]])

    a, b, x0 = -2.0, 3.0, 0.4
    t = np.arange(0.0, 3.0, 0.01)
    model = StateSpaceModel(("x",), ("u",), ("x",), f, h, Parameters({"a": -1.0, "b": 1.0}))
    y_true = (x0 + b / a) * np.exp(a * t) - b / a
    noise = np.random.default_rng(3).normal(0.0, 1e-3, t.size)
    data = FlightData(t, {"u": np.ones_like(t)}, {"x": y_true + noise})
    result = estimate(model.with_x0((x0,)), data)
    a_hat, b_hat = result.value("a"), result.value("b")
    inputs_only = FlightData(t, {"u": np.ones_like(t)})
    y = result.simulate(inputs_only, x0=[x0])
    closed = (x0 + b_hat / a_hat) * np.exp(a_hat * t) - b_hat / a_hat
    np.testing.assert_allclose(y[:, 0], closed, atol=1e-8)
    # x0 as a mapping by state name, the same
    np.testing.assert_array_equal(result.simulate(inputs_only, x0={"x": x0}), y)
    # without x0 and without an x channel: the model's own initial state
    np.testing.assert_allclose(result.simulate(inputs_only)[0, 0], x0)


def test_initial_state_rules_and_refusals(fitted):
    result, _, held_out = fitted
    given = result.predict(held_out, x0={"alpha": 0.05})
    assert given.predicted[0, 0] == pytest.approx(0.05)
    assert given.predicted[0, 1] == pytest.approx(held_out.output("q")[0])
    with pytest.raises(PredictionError, match="expected 2 values"):
        result.predict(held_out, x0=[0.1])
    with pytest.raises(PredictionError, match="not states"):
        result.predict(held_out, x0={"beta": 0.1})
    with pytest.raises(PredictionError, match="2 initial-state specifications for 1"):
        result.predict(held_out, x0=[[0.0, 0.0], [0.0, 0.0]])
    inputs_only = FlightData(TIME, {"de": held_out.input("de")})
    with pytest.raises(PredictionError, match="not output channels"):
        result.predict(inputs_only)
    # per-maneuver initial states in the model, no channel of the state, none given
    two = short_period(x0=[(0.0, "Za"), (0.0, 0.0)])
    with pytest.raises(PredictionError, match="'alpha'.*give x0"):
        replace(result, model=two).simulate(inputs_only)


def test_bands_match_a_monte_carlo_over_parameter_draws(fitted):
    result, _, held_out = fitted
    prediction = result.predict(held_out, bands=True)
    sigma = prediction.predicted_std
    assert sigma.shape == prediction.predicted.shape
    assert np.all(sigma[1:] > 0) and "predicted_std_rms" in prediction.to_dict()
    # Monte Carlo: θ ~ N(θ̂, P) (seeded), each draw simulated from the same initial state
    rng = np.random.default_rng(7)
    draws = rng.multivariate_normal(result.values, result.covariance_default, size=400)
    x0 = (held_out.output("alpha")[0], held_out.output("q")[0])
    outputs = Simulator(short_period(x0=x0), held_out).run(draws).outputs
    spread = outputs.std(axis=0, ddof=1)
    # σ of the band vs the sample σ of 400 draws (±3.5 % sampling error at 1σ): within 12 %
    shown = sigma[10:] > 0
    ratio = spread[10:][shown] / sigma[10:][shown]
    assert np.median(ratio) == pytest.approx(1.0, abs=0.06)
    assert np.all((ratio > 0.85) & (ratio < 1.15))
    # coverage of the 95 % band over draws and samples: 0.95 ± 0.02
    lower, upper = prediction.band(0.95)
    inside = (outputs[:, 10:] >= lower[10:]) & (outputs[:, 10:] <= upper[10:])
    assert float(inside.mean()) == pytest.approx(0.95, abs=0.02)


def test_band_needs_bands_and_a_level_inside_0_1(fitted):
    result, _, held_out = fitted
    with pytest.raises(PredictionError, match="bands=True"):
        result.predict(held_out).band()
    with pytest.raises(PredictionError, match="level"):
        result.predict(held_out, bands=True).band(1.5)
    # the 68.27 % band is ±1σ (normal quantile 0.841345 = 1.0000)
    banded = result.predict(held_out, bands=True)
    lower, upper = banded.band(0.682689492)
    np.testing.assert_allclose(0.5 * (upper - lower), banded.predicted_std, rtol=1e-6)
    # the Cramér–Rao covariance on request gives its own band
    assert result.std_kind == "cramer_rao"  # white residuals: the two covariances agree
    cr = result.predict(held_out, bands=True, std="cr").predicted_std
    np.testing.assert_allclose(cr, banded.predicted_std, rtol=1e-12)
    with pytest.raises(ValueError, match="std"):
        result.predict(held_out, bands=True, std="beale")


def test_parameters_per_maneuver_need_as_many_maneuvers(fitted):
    result, estimation, held_out = fitted
    per = short_period(x0=[(0.0, 0.0), (0.0, 0.0)]).with_per_maneuver(["Mde"], 2)
    with pytest.raises(PredictionError, match="parameters per estimation maneuver"):
        replace(result, model=per).predict(held_out)
    # as many maneuvers: maneuver k takes the k-th copies (here equal, so the same outputs)
    both = replace(result, model=per).predict([estimation, held_out])
    np.testing.assert_allclose(
        both[1].predicted, short_period_prediction(held_out), rtol=0, atol=1e-14
    )


def short_period_prediction(data: FlightData) -> np.ndarray:
    """The true model from the first measured states (the prediction's default x0)."""
    x0 = (data.output("alpha")[0], data.output("q")[0])
    return simulate(short_period(x0=x0), data)


def test_a_multiple_shooting_model_predicts_each_maneuver_in_one_integration(fitted):
    from flightid.model.unstable import with_multiple_shooting

    result, estimation, held_out = fitted
    shooting = with_multiple_shooting(short_period(), estimation, 3)
    assert shooting.shooting is not None
    values = dict(zip(shooting.parameters.names, shooting.parameters.values, strict=True))
    values.update(dict(zip(result.names, result.values, strict=True)))
    shooting = shooting.with_parameters(shooting.parameters.with_values(values))
    prediction = replace(result, model=shooting).predict(held_out)
    np.testing.assert_allclose(
        prediction.predicted, result.predict(held_out).predicted, rtol=0, atol=1e-14
    )


def test_bands_do_not_depend_on_the_batch_size(fitted, monkeypatch):
    import importlib

    prediction = importlib.import_module("flightid.simulation.prediction")
    result, _, held_out = fitted
    whole = result.predict(held_out, bands=True).predicted_std
    monkeypatch.setattr(prediction, "BATCH_BYTES", 1)  # one parameter per batch
    np.testing.assert_array_equal(result.predict(held_out, bands=True).predicted_std, whole)
