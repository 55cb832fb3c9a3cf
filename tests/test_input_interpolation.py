"""Input interpolation between samples: "linear" (u at the RK4 half step = mean of the
neighbouring samples) and "zoh" (zero-order hold, u = u_k on [t_k, t_{k+1})), in the compiled
and pure-Python state kernels and in the sensitivity-equation kernel.

Every reference below is a closed form of the continuous equations (or of the exact integral
of the interpolated input), not an earlier output of flightid.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import PENDULUM_TRUE, pendulum_data, pendulum_model
from flightid.data import FlightData
from flightid.errors import InputError
from flightid.estimation import OutputErrorProblem
from flightid.model import Parameters, StateSpaceModel
from flightid.simulation import Simulator, simulate


def lag_f(t, x, u, theta):
    """First-order lag dx/dt = (K u − x)/τ, θ = (K, τ)."""
    dx = np.empty(1)
    dx[0] = (theta[0] * u[0] - x[0]) / theta[1]
    return dx


def lag_h(t, x, u, theta):
    y = np.empty(1)
    y[0] = x[0]
    return y


def integrator_f(t, x, u, theta):
    """dx/dt = u."""
    dx = np.empty(1)
    dx[0] = u[0]
    return dx


K, TAU = 2.0, 0.5


def _lag(x0: float = 0.0) -> StateSpaceModel:
    return StateSpaceModel(
        ("x",), ("u",), ("y",), lag_f, lag_h, Parameters({"K": K, "tau": TAU}), x0=(x0,)
    )


def _integrator() -> StateSpaceModel:
    return StateSpaceModel(
        ("x",), ("u",), ("y",), integrator_f, lag_h, Parameters({"unused": 1.0}), x0=(0.0,)
    )


def _step_data() -> tuple[np.ndarray, FlightData]:
    """Unit step at t_s = 0.5 s (a sample instant), Δt = 0.02 s, 0..3 s."""
    t = np.arange(151) * 0.02
    u = np.where(np.arange(151) >= 25, 1.0, 0.0)
    y = np.zeros_like(t)
    return t, FlightData(t, {"u": u}, {"y": y})


def _step_response(t: np.ndarray, t_step: float = 0.5) -> np.ndarray:
    # x(t) = K (1 − e^{−(t − t_s)/τ}) for t ≥ t_s, 0 before (x(0) = 0, unit step at t_s)
    s = np.maximum(t - t_step, 0.0)
    return K * (1.0 - np.exp(-s / TAU))


@pytest.mark.parametrize("compiled", [True, False])
def test_zoh_rk4_on_a_lag_with_a_step_input_matches_the_closed_form(compiled):
    t, data = _step_data()
    y_zoh = simulate(_lag(), data, compiled=compiled, input_interpolation="zoh")[:, 0]
    exact = _step_response(t)
    # RK4 per step: e^{−h} to 4th order, relative error ≈ h⁵/120 with h = Δt/τ = 0.04, i.e.
    # ≈ 1e-9 per step; over 125 steps ≲ 2e-7·K
    np.testing.assert_allclose(y_zoh, exact, rtol=0, atol=2e-7)
    # the mean-of-neighbours rule sees a ramp over the sample before the step: it starts one
    # half sample early, an error of about K·(Δt/2)/τ·e^{...} ≈ 0.04 right after the step
    y_linear = simulate(_lag(), data, compiled=compiled, input_interpolation="linear")[:, 0]
    assert np.max(np.abs(y_linear - exact)) > 1e-2


@pytest.mark.parametrize("compiled", [True, False])
def test_linear_rk4_on_a_lag_with_a_ramp_input_matches_the_closed_form(compiled):
    # u = b t: x = K b (t − τ + τ e^{−t/τ}) for x(0) = 0 (solution of τ ẋ + x = K b t)
    t = np.arange(151) * 0.02
    b = 1.5
    data = FlightData(t, {"u": b * t}, {"y": np.zeros_like(t)})
    exact = K * b * (t - TAU + TAU * np.exp(-t / TAU))
    y_linear = simulate(_lag(), data, compiled=compiled, input_interpolation="linear")[:, 0]
    # the ramp part is integrated exactly; the transient K b τ e^{−t/τ} (size 1.5) carries
    # RK4's relative error ≈ h⁵/120 = 8.5e-10 per step (h = Δt/τ = 0.04): ≲ 3e-8 in all
    np.testing.assert_allclose(y_linear, exact, rtol=0, atol=3e-8)
    # held input lags the ramp by Δt/2 on average: x falls behind by ≈ K b Δt/2 = 0.03
    y_zoh = simulate(_lag(), data, compiled=compiled, input_interpolation="zoh")[:, 0]
    assert np.max(np.abs(y_zoh - exact)) > 1e-2


@pytest.mark.parametrize("compiled", [True, False])
def test_integrator_gives_the_exact_integral_of_each_interpolated_input(compiled):
    """dx/dt = u over random samples: "linear" integrates the piecewise-linear interpolant
    (trapezoidal rule), "zoh" the held signal (left Riemann sum) — both exactly."""
    rng = np.random.default_rng(20240610)
    t = np.arange(80) * 0.05
    u = rng.normal(0.0, 1.0, t.size)
    data = FlightData(t, {"u": u}, {"y": np.zeros_like(t)})
    dt = 0.05
    # ∫ of the linear interpolant: x_k = Σ_{j<k} Δt (u_j + u_{j+1})/2
    trapezoid = np.concatenate([[0.0], np.cumsum(dt * 0.5 * (u[:-1] + u[1:]))])
    # ∫ of the held input: x_k = Σ_{j<k} Δt u_j
    held = np.concatenate([[0.0], np.cumsum(dt * u[:-1])])
    y_lin = simulate(_integrator(), data, compiled=compiled, input_interpolation="linear")
    y_zoh = simulate(_integrator(), data, compiled=compiled, input_interpolation="zoh")
    np.testing.assert_allclose(y_lin[:, 0], trapezoid, rtol=0, atol=1e-13)
    np.testing.assert_allclose(y_zoh[:, 0], held, rtol=0, atol=1e-13)


def test_default_is_linear():
    t, data = _step_data()
    default = simulate(_lag(), data)
    linear = simulate(_lag(), data, input_interpolation="linear")
    np.testing.assert_array_equal(default, linear)
    assert Simulator(_lag(), data).input_interpolation == "linear"
    assert OutputErrorProblem(_lag(), data).input_interpolation == "linear"


def test_euler_uses_u_k_under_both_settings():
    t, data = _step_data()
    a = simulate(_lag(), data, method="euler", input_interpolation="linear")
    b = simulate(_lag(), data, method="euler", input_interpolation="zoh")
    np.testing.assert_array_equal(a, b)
    # Euler of the lag with a held step: x_{k+1} = x_k + Δt (K u_k − x_k)/τ; closed form of
    # that recursion: x_k = K (1 − (1 − Δt/τ)^{k − k_s}) for k ≥ k_s = 25
    k = np.arange(t.size)
    expected = np.where(k >= 25, K * (1.0 - (1.0 - 0.02 / TAU) ** np.maximum(k - 25, 0)), 0.0)
    np.testing.assert_allclose(a[:, 0], expected, rtol=0, atol=1e-13)


@pytest.mark.parametrize("interpolation", ["linear", "zoh"])
@pytest.mark.parametrize("method", ["rk4", "euler"])
def test_compiled_and_pure_python_agree(interpolation, method):
    model = pendulum_model(PENDULUM_TRUE)
    data = pendulum_data()
    compiled = Simulator(
        model, data, method=method, compiled=True, input_interpolation=interpolation
    )
    python = Simulator(
        model, data, method=method, compiled=False, input_interpolation=interpolation
    )
    assert compiled.compiled and not python.compiled
    thetas = np.array([PENDULUM_TRUE, (8.5, 0.3, 0.1, 1.9)])
    y_c = compiled.run(thetas).outputs
    y_p = python.run(thetas).outputs
    assert np.max(np.abs(y_c - y_p)) <= 1e-12 * np.max(np.abs(y_p))


def test_the_two_settings_differ_on_the_pendulum():
    """Guards against a kernel that ignores the setting (the pendulum torque has steps)."""
    model, data = pendulum_model(PENDULUM_TRUE), pendulum_data()
    lin = simulate(model, data, input_interpolation="linear")
    zoh = simulate(model, data, input_interpolation="zoh")
    assert np.max(np.abs(lin - zoh)) > 1e-3


@pytest.mark.parametrize("compiled", [True, False])
def test_sensitivity_equations_follow_the_setting(compiled):
    """G from the sensitivity-equation kernel under "zoh": closed forms for the lag with a
    held step, and agreement with central differences of whole zoh integrations."""
    t, data = _step_data()
    problem = OutputErrorProblem(_lag(), data, compiled=compiled, input_interpolation="zoh")
    theta = np.array([K, TAU])
    g, y = problem.sensitivities_from_equations(theta)
    s = np.maximum(t - 0.5, 0.0)
    np.testing.assert_allclose(y[:, 0], _step_response(t), rtol=0, atol=2e-7)
    # ∂x/∂K = (1 − e^{−s/τ}),  ∂x/∂τ = −K s e^{−s/τ}/τ²   (s = t − t_s ≥ 0)
    np.testing.assert_allclose(g[:, 0, 0], 1.0 - np.exp(-s / TAU), rtol=0, atol=1e-6)
    np.testing.assert_allclose(g[:, 0, 1], -K * s * np.exp(-s / TAU) / TAU**2, rtol=0, atol=1e-5)
    g_fd, _ = problem.sensitivities(theta, central=True, relative_step=1e-5)
    assert np.max(np.abs(g - g_fd)) <= 1e-6 * np.max(np.abs(g_fd))
    # the linear setting gives other sensitivities (the kernel does not ignore the setting)
    linear = OutputErrorProblem(_lag(), data, compiled=compiled, input_interpolation="linear")
    g_lin, _ = linear.sensitivities_from_equations(theta)
    assert np.max(np.abs(g_lin - g)) > 1e-2


@pytest.mark.parametrize("bad", ["cubic", "ZOH", "", None, 1])
def test_unknown_setting_is_a_named_input_error(bad):
    _, data = _step_data()
    message = r"input_interpolation: expected one of \['linear', 'zoh'\]"
    with pytest.raises(InputError, match=message):
        Simulator(_lag(), data, input_interpolation=bad)
    with pytest.raises(InputError, match=message):
        simulate(_lag(), data, input_interpolation=bad)
    with pytest.raises(InputError, match=message):
        OutputErrorProblem(_lag(), data, input_interpolation=bad)


@pytest.mark.parametrize(("value", "ok"), [('"zoh"', True), ('"linear"', True), ('"cubic"', False)])
def test_output_error_stage_declares_the_setting(tmp_path, value, ok):
    from pathlib import Path

    from flightid.cases import CaseError, load_case

    source = Path(__file__).resolve().parents[1] / "examples/cases/twin_otter_stepwise.toml"
    text = source.read_text()
    assert 'method = "rk4"\n' in text
    case = tmp_path / "case.toml"
    case.write_text(
        text.replace('method = "rk4"\n', f'method = "rk4"\ninput_interpolation = {value}\n')
    )
    if ok:
        assert load_case(case).estimation["input_interpolation"] == value.strip('"')
    else:
        with pytest.raises(
            CaseError,
            match=r"stages\[1\]\.input_interpolation: expected one of \['linear', 'zoh'\]",
        ):
            load_case(case)


# ------------------------------------------------------------------ the CSV walk-through

WALK = Path(__file__).resolve().parents[1] / "examples/csv_walkthrough"


def _make_flight_module():
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_flight", WALK / "make_flight.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_walkthrough_data_is_what_its_seeded_generator_writes(tmp_path):
    make_flight = _make_flight_module()
    make_flight.write(tmp_path / "my_flight.csv")
    assert (tmp_path / "my_flight.csv").read_bytes() == (WALK / "my_flight.csv").read_bytes()


def test_walkthrough_case_recovers_its_truth_within_3_sigma():
    """The generator holds δe over each sample (zoh); the case says so and the estimates
    lie within 3 Cramér–Rao bounds of the generator's true values (measured: at most
    1.6 σ; a 20-seed Monte Carlo of the generator gives mean deviations ≤ 0.3 σ)."""
    from flightid.cases import load_case, run_case

    truth = _make_flight_module().TRUE  # the values make_flight.py simulates with
    case = load_case(WALK / "my_case.toml")
    assert case.estimation["input_interpolation"] == "zoh"
    est = run_case(case).estimate
    assert est.converged, est.message
    assert set(est.names) == set(truth)
    for name, value, std in zip(est.names, est.values, est.std, strict=True):
        assert abs(value - truth[name]) < 3.0 * std, (name, value, truth[name], std)


def test_walkthrough_with_linear_interpolation_misses_its_truth():
    """The mismatch the zoh setting removes: the same data read with the linear rule put
    five of six parameters 7–17 σ from the truth (measured on main before this setting)."""
    from flightid.cases import load_case
    from flightid.cases.run import prepare_case
    from flightid.estimation import MNR, estimate

    truth = _make_flight_module().TRUE
    prepared = prepare_case(load_case(WALK / "my_case.toml"))
    (data,) = prepared.maneuvers
    est = estimate(prepared.model, data, solver=MNR(), input_interpolation="linear")
    deviation = [
        abs(v - truth[n]) / s for n, v, s in zip(est.names, est.values, est.std, strict=True)
    ]
    assert sum(d > 3.0 for d in deviation) >= 4, deviation


def test_accuracy_assessment_rebuilds_the_problem_with_the_estimate_setting():
    """assess(estimate, data) must integrate as the estimate did (else the profile and search
    limits would belong to another model)."""
    from flightid.accuracy.assess import problem_for
    from flightid.estimation import MNR, estimate

    t, data = _step_data()
    truth = _step_response(t)
    measured = FlightData(t, {"u": data.channel("u")}, {"y": truth})
    for setting in ("zoh", "linear"):
        est = estimate(_lag(), measured, solver=MNR(), input_interpolation=setting)
        assert est.input_interpolation == setting
        assert problem_for(est, measured).input_interpolation == setting
