"""Unstable-aircraft options (issue 13 items 2–3): stabilized output error, eigenvalue
transformation, multiple shooting and linear models declared by terms.

Independent references, written out here: the stabilized simulation as a plain Python RK4 loop
with the correction x_k ← x_k + S(z_k − y_k) (CASES.md §3d); the identity y'(t) = e^(−σt)·y(t)
of the eigenvalue transformation for a linear model (exact in continuous time; checked on a
fine grid); multiple-shooting defects and interval outputs from ordinary simulations of the
pieces; the basic and TC06 short-period equations of CASES.md §3 typed in by hand.
"""

from __future__ import annotations

import numpy as np
import pytest

from flightid.data import FlightData
from flightid.errors import InputError
from flightid.estimation import MNR, MNRES, OutputErrorProblem, estimate
from flightid.estimation.shooting import estimate_multiple_shooting
from flightid.model import Parameters, StateSpaceModel
from flightid.model.linear import LinearTermError, linear_model
from flightid.model.unstable import (
    NotLinearError,
    UnstableModel,
    exponentially_weighted,
    with_eigenvalue_shift,
    with_multiple_shooting,
    with_stabilizing_gain,
)
from flightid.simulation import Simulator

U0 = 44.5695  # m/s, CASES.md §3
DT = 0.05  # s
# "truth" of the simulated data below: the unstable short period's regression start-up
# estimates (CASES.md §3b on unStabAC_sim.asc, rounded); eigenvalues +0.63 and −5.77 1/s
TRUE = {"Zw": -1.4249, "Zq": -1.4768, "Zδe": -6.2632, "Mw": 0.21634, "Mq": -3.7121, "Mδe": -12.7687}
# the start values of CASES.md §3
START = {
    "Zw": -1.22871,
    "Zq": -1.4768,
    "Zδe": -4.20491,
    "Mw": 0.116197,
    "Mq": -2.7067,
    "Mδe": -18.7718,
}


def sp_f(t, x, u, theta):
    dx = np.empty(2)
    # ẇ = Zw w + (u0 + Zq) q + Zδe δe;  q̇ = Mw w + Mq q + Mδe δe
    dx[0] = theta[0] * x[0] + (U0 + theta[1]) * x[1] + theta[2] * u[0]
    dx[1] = theta[3] * x[0] + theta[4] * x[1] + theta[5] * u[0]
    return dx


def sp_h(t, x, u, theta):
    y = np.empty(3)
    y[0] = theta[0] * x[0] + theta[1] * x[1] + theta[2] * u[0]
    y[1] = x[0]
    y[2] = x[1]
    return y


def _model(values=TRUE, free_zq: bool = False) -> StateSpaceModel:
    parameters = Parameters(dict(values))
    if not free_zq:
        parameters = parameters.with_free({"Zq": False})
    return StateSpaceModel(("w", "q"), ("de",), ("az", "w", "q"), sp_f, sp_h, parameters)


def _elevator(t: np.ndarray) -> np.ndarray:
    # δe (rad): a 1-1 doublet of 0.02 rad from 1 s, then a 0.01 rad pulse at 6 s
    de = np.where((t >= 1.0) & (t < 1.5), 0.02, 0.0) - np.where((t >= 1.5) & (t < 2.0), 0.02, 0.0)
    return de + np.where((t >= 6.0) & (t < 6.5), 0.01, 0.0)


def _rk4_loop(theta, t, de, z=None, gain=None):
    """Plain RK4 (linear input between samples) with the optional stabilizing correction."""
    theta = np.array([theta[k] for k in TRUE]) if isinstance(theta, dict) else theta
    x = np.zeros(2)
    ys = []
    for k in range(t.size):
        y = sp_h(0.0, x, de[k : k + 1], theta)
        ys.append(y)
        if k == t.size - 1:
            break
        if gain is not None:
            x = x + gain @ (z[k] - y)  # x_k ← x_k + S (z_k − y_k)
        h = t[k + 1] - t[k]
        um = np.array([0.5 * (de[k] + de[k + 1])])
        k1 = sp_f(0, x, de[k : k + 1], theta)
        k2 = sp_f(0, x + h / 2 * k1, um, theta)
        k3 = sp_f(0, x + h / 2 * k2, um, theta)
        k4 = sp_f(0, x + h * k3, de[k + 1 : k + 2], theta)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return np.array(ys)


def _data(noise: float = 0.0, seed: int = 0, n: int = 251) -> FlightData:
    t = np.arange(n) * DT
    de = _elevator(t)
    y = _rk4_loop(TRUE, t, de)
    rng = np.random.default_rng(seed)
    # noise standard deviations: a_z 0.05 m/s², w 0.05 m/s, q 0.002 rad/s (times ``noise``)
    y = y + noise * rng.normal(size=y.shape) * np.array([0.05, 0.05, 0.002])
    return FlightData(t, {"de": de}, {"az": y[:, 0], "w": y[:, 1], "q": y[:, 2]})


GAIN = np.array([[0.0, 0.05, 0.0], [0.0, 0.0, 0.0]])  # CASES.md §3d


# ---------------------------------------------------------------- stabilized output error
@pytest.mark.parametrize("compiled", [True, False])
def test_stabilized_simulation_equals_a_plain_loop_with_the_correction(compiled):
    data = _data(noise=1.0, seed=3)
    wrong = dict(TRUE, Mw=0.3, Zδe=-5.0)  # another θ, so that z − y is not small
    model = with_stabilizing_gain(_model(wrong), {"w": {"w": 0.05}})
    theta = model.parameters.values
    y = Simulator(model, data, compiled=compiled).outputs(theta)
    expected = _rk4_loop(theta, data.time, data.input("de"), data.outputs, GAIN)
    np.testing.assert_allclose(y, expected, rtol=1e-12, atol=1e-12)
    # the correction matters: the open-loop simulation differs
    plain = _rk4_loop(theta, data.time, data.input("de"))
    assert np.max(np.abs(plain - expected)) > 0.1


def test_stabilizing_gain_as_table_equals_the_matrix_and_names_are_checked():
    model = _model()
    table = with_stabilizing_gain(model, {"w": {"w": 0.05}})
    np.testing.assert_array_equal(table.stabilizing_gain, GAIN)
    with pytest.raises(InputError, match="not a state"):
        with_stabilizing_gain(model, {"alpha": {"w": 0.05}})
    with pytest.raises(InputError, match="not an output"):
        with_stabilizing_gain(model, {"w": {"alpha": 0.05}})
    with pytest.raises(InputError, match="2 × 3"):
        with_stabilizing_gain(model, np.zeros((3, 2)))


def test_stabilized_sensitivity_equations_match_differences():
    data = _data(noise=1.0, seed=4)
    model = with_stabilizing_gain(_model(dict(TRUE, Mw=0.3)), GAIN)
    problem = OutputErrorProblem(model, data)
    theta = problem.theta_start
    g_eq, y_eq = problem.sensitivities_from_equations(theta)
    g_fd, y_fd = problem.sensitivities(theta, relative_step=1e-6, central=True)
    np.testing.assert_allclose(y_eq, y_fd, rtol=1e-12, atol=1e-12)
    scale = np.max(np.abs(g_fd), axis=(0, 1))
    assert np.max(np.abs(g_eq - g_fd) / scale) < 1e-5
    # without the −S·G correction of the state sensitivities they would differ
    plain = OutputErrorProblem(_model(dict(TRUE, Mw=0.3)), data)
    g_plain, _ = plain.sensitivities_from_equations(theta)
    assert np.max(np.abs(g_plain - g_fd) / scale) > 1e-2


@pytest.mark.parametrize("solver", [MNR(), MNR(sensitivities="equations"), MNRES()])
def test_stabilized_output_error_recovers_the_unstable_model(solver):
    # small noise (0.005 m/s on w): the correction feeds the measurement noise into the states,
    # so stabilized output error is biased by an amount that grows with the noise variance
    # (measured: Mw 4 % low with 0.05 m/s on w, while within 1.3 σ here)
    data = _data(noise=0.1, seed=1)
    model = with_stabilizing_gain(_model(START), GAIN)
    result = estimate(model, data, solver=solver)
    assert result.converged
    for name in ("Zw", "Zδe", "Mw", "Mq", "Mδe"):
        j = result.names.index(name)
        assert abs(result.values[j] - TRUE[name]) < 3 * result.std[j], name


# ---------------------------------------------------------------- eigenvalue transformation
def test_eigenvalue_transform_is_the_weighted_simulation_for_a_linear_model():
    # fine grid: transformed simulation = e^(−σt) × original simulation up to the
    # discretisation (the weighted input is interpolated linearly between samples, O(dt²):
    # measured 1e-5 relative at dt = 0.01 s, 4e-7 at 0.002 s)
    t = np.arange(0, 5.0 + 1e-9, 0.002)
    data = FlightData(t, {"de": 0.02 * np.sin(1.3 * t)}, {"az": 0 * t, "w": 0 * t, "q": 0 * t})
    model = _model()
    sigma = 0.7
    original = Simulator(model, data).outputs(model.parameters.values)
    weighted = exponentially_weighted(data, sigma)[0]
    np.testing.assert_allclose(weighted.input("de"), np.exp(-sigma * t) * data.input("de"))
    shifted = with_eigenvalue_shift(model, sigma)
    transformed = Simulator(shifted, weighted).outputs(model.parameters.values)
    expected = np.exp(-sigma * t)[:, None] * original
    assert np.max(np.abs(transformed - expected)) < 1e-6 * np.max(np.abs(expected))
    # the shift is what makes it so: without it the weighted simulation is wrong
    unshifted = Simulator(model, weighted).outputs(model.parameters.values)
    assert np.max(np.abs(unshifted - expected)) > 1e-2 * np.max(np.abs(expected))


def test_eigenvalue_transform_refuses_a_model_that_is_not_linear_homogeneous():
    def f_bias(t, x, u, theta):
        return sp_f(t, x, u, theta) + 0.1  # a constant term

    model = StateSpaceModel(
        ("w", "q"), ("de",), ("az", "w", "q"), f_bias, sp_h, Parameters(dict(TRUE))
    )
    with pytest.raises(NotLinearError, match="linear and homogeneous"):
        with_eigenvalue_shift(model, 0.7)
    with_eigenvalue_shift(_model(), 0.7)  # the linear model passes


def test_eigenvalue_transform_recovers_the_unstable_model():
    data = exponentially_weighted(_data(noise=1.0, seed=2), 0.7)
    model = with_eigenvalue_shift(_model(START), 0.7)
    result = estimate(model, data, solver=MNR())
    assert result.converged
    for name in ("Zw", "Zδe", "Mw", "Mq", "Mδe"):
        j = result.names.index(name)
        assert abs(result.values[j] - TRUE[name]) < 4 * result.std[j], name


# ---------------------------------------------------------------- multiple shooting
def test_shooting_defects_and_interval_outputs_from_plain_simulations():
    data = _data(noise=1.0, seed=5)
    model = with_multiple_shooting(_model(dict(TRUE, Mw=0.25)), data, 4)
    assert isinstance(model, UnstableModel)
    starts = [s for s, _ in model.shooting[0]]
    assert starts == [62, 125, 188]  # round(m·250/4)
    names = model.parameters.names[-6:]
    assert names == ["ms2_w", "ms2_q", "ms3_w", "ms3_q", "ms4_w", "ms4_q"]
    theta = model.parameters.values.copy()
    theta[-6:] += np.array([0.1, -0.01, 0.2, 0.02, -0.1, 0.005])  # off the measured states
    batch = Simulator(model, data).run(theta[None, :])
    plain = StateSpaceModel(
        ("w", "q"), ("de",), ("az", "w", "q"), sp_f, sp_h, Parameters(dict(TRUE, Mw=0.25))
    )
    bounds = [0, *starts, data.n_samples]
    for m in range(4):
        first, last = bounds[m], bounds[m + 1]
        stop = min(last + 1, data.n_samples)
        piece = FlightData(data.time[first:stop], {"de": data.input("de")[first:stop]})
        base = theta.size - 6 + 2 * (m - 1)  # ms<m+1>_w, ms<m+1>_q
        x0 = (0.0, 0.0) if m == 0 else tuple(theta[base : base + 2])
        y = Simulator(plain.with_x0(x0), piece).outputs(plain.parameters.values)
        np.testing.assert_allclose(batch.outputs[0, first:last], y[: last - first], rtol=1e-12)
        if m < 3:
            # defect = x(end of interval m) − x0(interval m + 1); x = (w, q) = outputs 2, 3
            nxt = theta[theta.size - 6 + 2 * m : theta.size - 6 + 2 * m + 2]
            np.testing.assert_allclose(batch.defects[0, 2 * m : 2 * m + 2], y[-1, 1:] - nxt)


def test_multiple_shooting_recovers_the_ordinary_output_error_optimum():
    data = _data(noise=1.0, seed=6)
    ordinary = estimate(_model(dict(TRUE, Mw=0.2)), data, solver=MNR())
    model = with_multiple_shooting(_model(START), data, 5)  # weights 1, 10³, 10⁶ in turn
    assert model.shooting_schedule == (1.0, 1e3) and model.shooting_weight == 1e6
    shooting = estimate_multiple_shooting(model, data, solver=MNR())
    assert shooting.converged and ordinary.converged
    for name in ("Zw", "Zδe", "Mw", "Mq", "Mδe"):
        i, j = ordinary.names.index(name), shooting.names.index(name)
        # the same optimum: continuity enforced to 10⁻³ noise σ
        assert abs(shooting.values[j] - ordinary.values[i]) < 0.05 * ordinary.std[i], name
        assert abs(shooting.values[j] - TRUE[name]) < 3 * shooting.std[j], name
    assert shooting.residuals.shape == ordinary.residuals.shape  # defect rows not reported
    assert "w = 1: converged" in shooting.message and "w = 1e+06" in shooting.message
    np.testing.assert_array_equal(shooting.initial, model.parameters.values)


def test_multiple_shooting_progress_numbers_rise_over_all_stages():
    data = _data(noise=1.0, seed=6)
    model = with_multiple_shooting(_model(START), data, 5)  # three stages
    calls = []
    result = estimate_multiple_shooting(
        model, data, solver=MNR(), progress=lambda p, e, cost: calls.append((p, e))
    )
    passes = [p for p, _ in calls]
    evaluations = np.array([e for _, e in calls])
    # every stage's passes follow the last stage's: 0, 1, 2, … over the whole run
    assert passes == list(range(len(calls)))
    assert len(calls) > len(result.cost_history)  # the earlier stages reported too
    assert np.all(np.diff(evaluations) >= 0)


def test_shooting_refuses_states_without_an_output_and_too_many_intervals():
    data = _data()
    hidden = StateSpaceModel(
        ("w", "q"),
        ("de",),
        ("az", "w"),
        sp_f,
        lambda t, x, u, th: sp_h(t, x, u, th)[:2],
        Parameters(dict(TRUE)),
    )
    with pytest.raises(InputError, match=r"\['q'\] have none"):
        with_multiple_shooting(hidden, data, 3)
    with pytest.raises(InputError, match="fewer than 2 samples"):
        with_multiple_shooting(_model(), data, 200)
    with pytest.raises(InputError, match="increasing list"):
        with_multiple_shooting(_model(), data, 3, [1e6, 1.0])


# ---------------------------------------------------------------- linear term models
def _terms_model(derivatives, outputs, inputs=("de",)):
    return linear_model(
        ("w", "q"), inputs, ("az", "w", "q"), dict(TRUE), derivatives, outputs, {"u0": U0}
    )


def test_linear_terms_equal_the_hand_written_basic_model():
    model = _terms_model(
        {"w": ["Zw*w", "u0*q", "Zq*q", "Zδe*de"], "q": ["Mw*w", "Mq*q", "Mδe*de"]},
        {"az": ["Zw*w", "Zq*q", "Zδe*de"], "w": ["w"], "q": ["q"]},
    )
    rng = np.random.default_rng(0)
    for _ in range(5):
        x, u, theta = rng.normal(size=2), rng.normal(size=1), rng.normal(size=6)
        np.testing.assert_allclose(model.f(0.0, x, u, theta), sp_f(0.0, x, u, theta), rtol=1e-14)
        np.testing.assert_allclose(model.h(0.0, x, u, theta), sp_h(0.0, x, u, theta), rtol=1e-14)


def test_linear_terms_mix_measured_and_integrated_states_as_in_tc06():
    model = _terms_model(
        {"w": ["Zw*w_m", "u0*q", "Zq*q_m", "Zδe*de"], "q": ["Mw*w_m", "Mq*q_m", "Mδe*de"]},
        {"az": ["Zw*w_m", "Zq*q_m", "Zδe*de"], "w": ["w"], "q": ["q"]},
        inputs=("de", "w_m", "q_m"),
    )
    zw, zq, zde, mw, mq, mde = (TRUE[k] for k in TRUE)
    x, u = np.array([1.3, -0.2]), np.array([0.05, 2.0, 0.3])
    # CASES.md §3b typed in: ẇ = Zw w_m + u0 q + Zq q_m + Zδe δe (u0·q: integrated q)
    expected_f = [zw * 2.0 + U0 * -0.2 + zq * 0.3 + zde * 0.05, mw * 2.0 + mq * 0.3 + mde * 0.05]
    np.testing.assert_allclose(model.f(0.0, x, u, model.parameters.values), expected_f)
    np.testing.assert_allclose(
        model.h(0.0, x, u, model.parameters.values), [zw * 2.0 + zq * 0.3 + zde * 0.05, 1.3, -0.2]
    )


def test_linear_term_errors_are_named():
    good = {"az": ["Zw*w"], "w": ["w"], "q": ["q"]}
    with pytest.raises(LinearTermError, match="two signals"):
        _terms_model({"w": ["Zw*w*q"], "q": ["q"]}, good)
    with pytest.raises(LinearTermError, match="'Zx' in 'Zx\\*w'"):
        _terms_model({"w": ["Zx*w"], "q": ["q"]}, good)
    with pytest.raises(LinearTermError, match="no equation for \\['q'\\]"):
        _terms_model({"w": ["Zw*w"]}, good)
    # constant terms and numbers: −2·Zq·q + 0.5 (no signal: a constant)
    model = _terms_model({"w": ["-2*Zq*q", "0.5"], "q": ["q"]}, good)
    theta = model.parameters.values
    np.testing.assert_allclose(
        model.f(0.0, np.array([0.0, 3.0]), np.zeros(1), theta), [-2 * TRUE["Zq"] * 3.0 + 0.5, 3.0]
    )
