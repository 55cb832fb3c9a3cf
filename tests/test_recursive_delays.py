"""Fixed input delays in the recursive estimators: the filters (EKF, UKF, UKF_aug, EFRLS) feed
the model u(t − τ) from a delay line (``flightid.recursive.delay.InputDelayLine``), the FTR
regresses on the delayed input.

The delay line is compared with the time-domain simulator's whole-record rule
(``flightid.simulation.delayed_inputs``, a separate implementation of both conventions) and
with numpy's own interpolation. The rate-loop data are those of test_frequency_delays.py
(scipy.signal.lsim fed the exactly delayed multisine).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from flightid.cases import CaseError, load_case
from flightid.cases.recursive_case import run_recursive_case
from flightid.errors import InputError
from flightid.model import Parameter, Parameters, StateSpaceModel
from flightid.recursive import (
    AugmentedModel,
    AugmentedUnscentedKalmanFilter,
    ExtendedForgettingRLS,
    ExtendedKalmanFilter,
    FourierTransformRegression,
    RecursiveEstimator,
    UnscentedKalmanFilter,
)
from flightid.recursive.delay import InputDelayLine
from flightid.simulation.simulator import delayed_inputs
from test_frequency_delays import DT, TAU, WN, ZETA, loop_f, loop_h, multisine, rate_loop_record


def loop_model(tau: float | None, free: bool = False, convention: str = "fractional"):
    parameters = [Parameter("wn", 30.0), Parameter("zeta", 0.5)]
    if tau is not None:
        parameters.append(Parameter("tau", tau, free=free))
    return StateSpaceModel(
        states=("p", "r"),
        inputs=("p_cmd",),
        outputs=("p",),
        f=loop_f,
        h=loop_h,
        parameters=Parameters(parameters),
        input_delays={"p_cmd": "tau"} if tau is not None else None,
        delay_convention=convention,
    )


# ------------------------------------------------------------------ the delay line


@pytest.mark.parametrize("convention", ["fractional", "two_sample"])
@pytest.mark.parametrize("tau", [0.0, 0.3 * DT, DT, 3.7 * DT, 25 * DT])
def test_delay_line_matches_the_simulators_whole_record_rule(convention, tau):
    if convention == "two_sample" and tau > DT:
        tau = 0.6 * DT  # the two-sample rule is meant for a delay within one interval
    rng = np.random.default_rng(3)
    # jittery times: dt ∈ [0.8, 1.2]·DT
    t = np.cumsum(np.r_[0.0, DT * (0.8 + 0.4 * rng.random(299))])
    u = np.column_stack([np.sin(7 * t), rng.standard_normal(t.size)])
    model = StateSpaceModel(
        states=("x",),
        inputs=("a", "b"),
        outputs=("x",),
        f=lambda t, x, u, th: np.array([-x[0]]),
        h=lambda t, x, u, th: np.array([x[0]]),
        parameters=Parameters([Parameter("ta", tau), Parameter("tb", 0.5 * tau)]),
        input_delays={"a": "ta", "b": "tb"},
        delay_convention=convention,
    )
    reference = delayed_inputs(model, t, u, model.parameters.values)
    line = InputDelayLine([tau, 0.5 * tau], convention)
    streamed = np.array([line.push(tk, uk) for tk, uk in zip(t, u, strict=True)])
    np.testing.assert_allclose(streamed, reference, rtol=0, atol=1e-12)
    if convention == "fractional":
        # numpy's linear interpolation with the first value held
        np.testing.assert_allclose(streamed[:, 0], np.interp(t - tau, t, u[:, 0]), atol=1e-12)


def test_delay_line_keeps_only_the_samples_it_needs():
    line = InputDelayLine([0.05])
    for k in range(1000):
        line.push(k * DT, np.array([float(k)]))
    # τ = 10 samples: the bracket and what follows it
    assert len(line._times) <= 12


@pytest.mark.parametrize(
    "delays, convention, message",
    [
        ([-0.01], "fractional", r"delays_s: expected finite delays >= 0 s"),
        ([np.nan], "fractional", r"delays_s: expected finite delays"),
        ("0.1", "fractional", r"delays_s: expected one delay"),
        ([0.01], "linear", r"delay_convention: expected one of"),
    ],
)
def test_delay_line_arguments_are_named_errors(delays, convention, message):
    with pytest.raises(InputError, match=message):
        InputDelayLine(delays, convention)


# ------------------------------------------------------------------ the filters


@pytest.fixture(scope="module")
def record():
    return rate_loop_record(seed=1)


def _run(filter_class, model, record, **settings):
    t, u, y = record
    estimator = filter_class(AugmentedModel(model, [0.0, 0.0]), **settings)
    online = RecursiveEstimator(estimator)
    online.feed_block(t, u[:, None], y[:, None])
    return estimator


KALMAN = dict(p0=[1e-4, 1e-2, 100.0, 0.1], q_states=[1e-8, 1e-4], r0=[0.02**2])


@pytest.mark.parametrize(
    "filter_class", [ExtendedKalmanFilter, UnscentedKalmanFilter, AugmentedUnscentedKalmanFilter]
)
def test_kalman_filters_with_the_fixed_delay_recover_the_loop(filter_class, record):
    settings = dict(KALMAN)
    if filter_class is AugmentedUnscentedKalmanFilter:
        settings["q_states"] = [1e-6, 1e-2]  # variances of a noise on ẋ, not per step
    estimator = _run(filter_class, loop_model(TAU), record, **settings)
    theta, std = estimator.theta, estimator.theta_std
    assert np.all(np.abs(theta - [WN, ZETA]) < 3.0 * std), (theta, std)
    # without the delay the same filter settles far from the loop
    plain = _run(filter_class, loop_model(None), record, **settings)
    assert WN - plain.theta[0] > 10.0
    assert abs(plain.theta[0] - WN) > 30.0 * plain.theta_std[0]


def test_efrls_with_the_fixed_delay_lands_near_the_loop(record):
    delayed = _run(ExtendedForgettingRLS, loop_model(TAU), record, p0=1e3, forgetting=0.999)
    plain = _run(ExtendedForgettingRLS, loop_model(None), record, p0=1e3, forgetting=0.999)
    # the EFRLS std is not a noise-based σ: compare errors instead
    assert abs(delayed.theta[0] - WN) < 0.02 * WN
    assert abs(plain.theta[0] - WN) > 10 * abs(delayed.theta[0] - WN)


def test_feeding_one_by_one_or_in_a_block_gives_the_same_delayed_run(record):
    t, u, y = record
    n = 400
    one = ExtendedKalmanFilter(AugmentedModel(loop_model(TAU), [0.0, 0.0]), **KALMAN)
    for k in range(n):
        one.feed(t[k], [u[k]], [y[k]])
    block = ExtendedKalmanFilter(AugmentedModel(loop_model(TAU), [0.0, 0.0]), **KALMAN)
    RecursiveEstimator(block).feed_block(t[:n], u[:n, None], y[:n, None])
    np.testing.assert_array_equal(one.x, block.x)
    block.reset()  # reset forgets the delay line too
    RecursiveEstimator(block).feed_block(t[:n], u[:n, None], y[:n, None])
    np.testing.assert_array_equal(one.x, block.x)


@pytest.mark.parametrize(
    "model, message",
    [
        (loop_model(TAU, free=True), r"input delay 'tau' of 'p_cmd' is free; .*fixed, known"),
        (loop_model(-0.01), r"input delay 'tau' of 'p_cmd' is -0.01 s; .*>= 0"),
    ],
)
def test_free_or_negative_delays_are_named_errors(model, message):
    with pytest.raises(InputError, match=message):
        AugmentedModel(model, [0.0, 0.0])


def test_output_delays_are_refused_with_the_reason():
    model = StateSpaceModel(
        states=("p", "r"),
        inputs=("p_cmd",),
        outputs=("p",),
        f=loop_f,
        h=loop_h,
        parameters=Parameters(
            [Parameter("wn", 30.0), Parameter("zeta", 0.5), Parameter("tau", TAU, free=False)]
        ),
        output_delays={"p": "tau"},
    )
    with pytest.raises(InputError, match=r"output delays are not available .*input_delays"):
        AugmentedModel(model, [0.0, 0.0])


# ------------------------------------------------------------------ FTR


def _roll_record(tau: float):
    # ṗ = Lp p + Lda δ(t − τ), Lp = −8 1/s, Lda = 30 1/s², scipy on a 2 kHz grid
    fine = np.arange(40001) * DT / 10
    _, p, _ = signal.lsim(signal.lti([30.0], [1.0, 8.0]), multisine(fine - tau), fine)
    t = fine[::10]
    return t, multisine(t), p[::10]


@pytest.mark.parametrize("delay", [0.05, 0.0])
def test_ftr_with_a_fixed_input_delay(delay):
    t, u, p = _roll_record(0.05)
    ftr = FourierTransformRegression(
        1, 1, np.arange(0.2, 8.01, 0.1), 200, [["Lp", "Lda"]], input_delays_s=[delay]
    )
    RecursiveEstimator(ftr).feed_block(t, u[:, None], p[:, None])
    error = np.abs(ftr.theta - [-8.0, 30.0])
    if delay:
        # noise-free: near exact with the delay
        assert np.all(error < [0.1, 0.3]), ftr.theta
    else:
        assert np.all(error > [1.0, 3.0]), ftr.theta


def test_ftr_delay_argument_is_a_named_error():
    with pytest.raises(InputError, match=r"input_delays_s: expected 1 delays"):
        FourierTransformRegression(1, 1, [1, 2, 3], 10, input_delays_s=[0.1, 0.2])
    with pytest.raises(InputError, match=r"input_delays_s: expected finite delays >= 0"):
        FourierTransformRegression(1, 1, [1, 2, 3], 10, input_delays_s=[-0.1])


# ------------------------------------------------------------------ case files

_MODULE = """
import numpy as np

STATES = ("p", "r")
INPUTS = ("p_cmd",)
OUTPUTS = ("p",)
PARAMETERS = {"wn": 30.0, "zeta": 0.5}


def f(t, x, u, theta):
    wn, zeta = theta[0], theta[1]
    return np.array([x[1], -wn**2 * x[0] - 2 * zeta * wn * x[1] + wn**2 * u[0]])


def h(t, x, u, theta):
    return np.array([x[0]])
"""


def write_case(tmp_path, parameters: str, recursive: str):
    t, u, y = rate_loop_record()
    rows = np.column_stack([t, u, y])
    np.savetxt(tmp_path / "loop.csv", rows, delimiter=",", header="t,p_cmd,p", comments="")
    (tmp_path / "loop.py").write_text(_MODULE)
    (tmp_path / "case.toml").write_text(
        f"""title = "rate loop, recursive"
[data]
data_dir = "."
file = "loop.csv"
time = "t"
[data.inputs]
p_cmd = {{ column = "p_cmd" }}
[data.outputs]
p = {{ column = "p" }}
[model]
module = "loop.py"
input_delays = {{ p_cmd = "tau" }}
[parameters]
{parameters}
[initial_state]
default = 0.0
[recursive]
{recursive}
"""
    )
    return tmp_path / "case.toml"


EKF_TABLE = """method = "ekf"
compiled = false
p0 = [1e-4, 1e-2, 100.0, 0.1]
q_states = [1e-8, 1e-4]
r0 = 4e-4"""


def test_case_file_runs_the_ekf_with_a_fixed_delay(tmp_path):
    path = write_case(tmp_path, "tau = { value = 0.025, free = false }", EKF_TABLE)
    result = run_recursive_case(load_case(path))
    final = result.to_dict()["parameters"]
    rows = {p["name"]: p for p in final}
    assert set(rows) == {"wn", "zeta"}
    assert abs(rows["wn"]["value"] - WN) < 3.0 * rows["wn"]["std"]


def test_case_file_with_a_free_delay_is_a_named_case_error(tmp_path):
    path = write_case(tmp_path, "", EKF_TABLE)
    with pytest.raises(CaseError, match=r"model: .*input delay 'tau' of 'p_cmd' is free"):
        run_recursive_case(load_case(path))
