"""Simulation kernels: compiled vs pure Python, closed forms, divergence reporting."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import PENDULUM_TRUE, pendulum_data, pendulum_model
from flightid.data import FlightData
from flightid.errors import SimulationError
from flightid.model import Parameters, StateSpaceModel
from flightid.simulation import Simulator, simulate


@pytest.mark.parametrize("method", ["rk4", "euler"])
def test_compiled_and_pure_python_kernels_agree_to_round_off(method):
    model = pendulum_model(PENDULUM_TRUE)
    data = pendulum_data()
    compiled = Simulator(model, data, method=method, compiled=True)
    python = Simulator(model, data, method=method, compiled=False)
    assert compiled.compiled and not python.compiled
    thetas = np.array([PENDULUM_TRUE, (8.5, 0.3, 0.1, 1.9)])
    y_c = compiled.run(thetas).outputs
    y_p = python.run(thetas).outputs
    assert np.max(np.abs(y_c - y_p)) <= 1e-12 * np.max(np.abs(y_p))


def _integrator_model():
    """dx/dt = u (a pure integrator), y = x."""

    def f(t, x, u, theta):
        return np.array([u[0]])

    def h(t, x, u, theta):
        return np.array([x[0]])

    return StateSpaceModel(("x",), ("u",), ("y",), f, h, Parameters({"unused": 1.0}), x0=(0.0,))


def test_rk4_with_half_step_input_mean_integrates_a_ramp_exactly():
    # u = t is linear, so the mean of neighbouring samples is the exact mid-step value and
    # RK4 (Simpson's rule here) integrates x = t²/2 exactly.
    t = np.linspace(0.0, 2.0, 41)
    y = simulate(_integrator_model(), FlightData(t, {"u": t}))
    np.testing.assert_allclose(y[:, 0], t**2 / 2, rtol=0, atol=1e-13)


def test_euler_integrates_a_ramp_with_its_known_first_order_error():
    t = np.linspace(0.0, 2.0, 41)
    dt = t[1] - t[0]
    y = simulate(_integrator_model(), FlightData(t, {"u": t}), method="euler")
    # Euler: x_k = Σ_{j<k} dt·t_j = dt²·k(k−1)/2
    k = np.arange(t.size)
    np.testing.assert_allclose(y[:, 0], dt**2 * k * (k - 1) / 2, atol=1e-13)


def test_rk4_matches_the_closed_form_of_a_first_order_lag():
    # dx/dt = −a x, x(0) = 1 → x = e^{−a t}. RK4's growth factor per step is the Taylor
    # series of e^{−a·dt} to 4th order, so the relative error at time t is ≈ t·a⁵·dt⁴/120
    # = 3·32·1e-8/120 = 8e-9 at t = 3 s.
    def f(t, x, u, theta):
        return -theta[0] * x

    def h(t, x, u, theta):
        return x.copy()

    model = StateSpaceModel(("x",), (), ("x",), f, h, Parameters({"a": 2.0}), x0=(1.0,))
    t = np.arange(0.0, 3.0 + 1e-9, 0.01)
    y = simulate(model, FlightData(t))
    np.testing.assert_allclose(y[:, 0], np.exp(-2.0 * t), rtol=1e-8)


def test_diverging_simulation_is_reported_not_returned_as_numbers():
    def f(t, x, u, theta):
        return theta[0] * x * x

    def h(t, x, u, theta):
        return x.copy()

    model = StateSpaceModel(("x",), (), ("x",), f, h, Parameters({"a": 50.0}), x0=(1.0,))
    t = np.arange(0.0, 2.0, 0.05)
    with pytest.raises(SimulationError, match="diverged"):
        simulate(model, FlightData(t))
    batch = Simulator(model, FlightData(t)).run(np.array([[50.0], [0.0]]))
    assert batch.diverged.tolist() == [True, False]
    assert "t =" in batch.messages[0]
    np.testing.assert_allclose(batch.outputs[1, :, 0], 1.0)


def test_model_numba_cannot_compile_falls_back_to_python_with_a_warning():
    table = {"gain": 2.0}  # a dict lookup numba cannot type

    def f(t, x, u, theta):
        return np.array([table["gain"] * u[0] - theta[0] * x[0]])

    def h(t, x, u, theta):
        return np.array([x[0]])

    model = StateSpaceModel(("x",), ("u",), ("y",), f, h, Parameters({"a": 1.0}), x0=(0.0,))
    t = np.arange(0.0, 1.0, 0.1)
    with pytest.warns(RuntimeWarning, match="runs in pure Python"):
        simulator = Simulator(model, FlightData(t, {"u": np.ones_like(t)}))
    assert not simulator.compiled
    y = simulator.outputs(np.array([1.0]))
    assert y[-1, 0] == pytest.approx(2.0 * (1 - np.exp(-t[-1])), rel=1e-4)


def test_batch_counts_one_equivalent_evaluation_per_parameter_vector():
    model = pendulum_model(PENDULUM_TRUE)
    simulator = Simulator(model, pendulum_data())
    simulator.run(np.tile(PENDULUM_TRUE, (5, 1)))
    simulator.outputs(np.array(PENDULUM_TRUE))
    assert simulator.evaluations == 6


def test_several_maneuvers_with_per_maneuver_initial_states():
    def f(t, x, u, theta):
        return -theta[0] * x

    def h(t, x, u, theta):
        return x.copy()

    parameters = Parameters({"a": 1.0, "x0_second": 3.0})
    model = StateSpaceModel(("x",), (), ("x",), f, h, parameters, x0=[(2.0,), ("x0_second",)])
    t = np.arange(0.0, 1.0 + 1e-9, 0.01)
    y = simulate(model, [FlightData(t), FlightData(t)])
    np.testing.assert_allclose(y[: t.size, 0], 2.0 * np.exp(-t), rtol=1e-9)
    np.testing.assert_allclose(y[t.size :, 0], 3.0 * np.exp(-t), rtol=1e-9)


@pytest.mark.parametrize("compiled", [True, False])
def test_sensitivity_equations_match_central_differences_of_whole_integrations(compiled):
    from flightid.estimation import OutputErrorProblem

    problem = OutputErrorProblem(pendulum_model(), pendulum_data(), compiled=compiled)
    theta = problem.theta_start
    g_eq, y_eq = problem.sensitivities_from_equations(theta)
    g_fd, y_fd = problem.sensitivities(theta, central=True, relative_step=1e-5)
    np.testing.assert_allclose(y_eq, y_fd, rtol=0, atol=1e-14)
    # two approximations of the same derivative: sensitivity equations with forward-difference
    # Jacobians of f, and central differences of whole RK4 integrations (measured 4e-8)
    assert np.max(np.abs(g_eq - g_fd)) <= 1e-6 * np.max(np.abs(g_fd))


def test_sensitivity_of_an_estimated_initial_state_is_the_closed_form():
    from flightid.estimation import OutputErrorProblem

    def f(t, x, u, theta):
        return -theta[0] * x

    def h(t, x, u, theta):
        return x.copy()

    t = np.arange(0.0, 2.0 + 1e-9, 0.01)
    model = StateSpaceModel(
        ("x",), (), ("x",), f, h, Parameters({"a": 1.5, "x_start": 2.0}), x0=("x_start",)
    )
    data = FlightData(t, outputs={"x": np.exp(-t)})
    g, y = OutputErrorProblem(model, data).sensitivities_from_equations(np.array([1.5, 2.0]))
    # y = x0·e^{−a t}: ∂y/∂a = −t·x0·e^{−a t}, ∂y/∂x0 = e^{−a t}
    np.testing.assert_allclose(g[:, 0, 1], np.exp(-1.5 * t), rtol=1e-8)
    np.testing.assert_allclose(g[:, 0, 0], -t * 2.0 * np.exp(-1.5 * t), rtol=1e-5, atol=1e-9)
