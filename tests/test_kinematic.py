"""The kinematic model of flight-path reconstruction (flightid.compat): equations against an
independent vector implementation and a closed-form steady turn, sensor conventions,
recovery of biases, scale factors and a delay from simulated data, named errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flightid.cases.spec import CaseError, parse_case
from flightid.compat import OUTPUTS, QUANTITIES, kinematic_model, kinematic_spec
from flightid.data import FlightData
from flightid.errors import InputError, InputTypeError
from flightid.estimation import MNR, estimate
from flightid.simulation import simulate

G = 9.80
ACC = np.array([-1.010, 0.886, 0.103])  # m, CASES.md §4
BOOM = np.array([13.080, -0.010, -0.027])  # m


# ------------------------------------------------------------------ independent equations


def _euler_matrix(phi: float, theta: float, psi: float) -> np.ndarray:
    """Body → NED rotation R = R_z(ψ) R_y(θ) R_x(φ) (standard aerospace sequence)."""
    cf, sf, ct, st, cp, sp = (
        math.cos(phi),
        math.sin(phi),
        math.cos(theta),
        math.sin(theta),
        math.cos(psi),
        math.sin(psi),
    )
    rx = np.array([[1, 0, 0], [0, cf, -sf], [0, sf, cf]])
    ry = np.array([[ct, 0, st], [0, 1, 0], [-st, 0, ct]])
    rz = np.array([[cp, -sp, 0], [sp, cp, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _reference_derivatives(X, a_sensor, omega, omega_dot, r_acc, g):
    """dX/dt by vectors: a_CG = a_s − ω̇×r − ω×(ω×r); V̇ = a_CG + Rᵀ(0, 0, g) − ω×V;
    Euler-angle rates from ω = E(φ, θ)·(φ̇, θ̇, ψ̇) solved numerically; ḣ = −(R V)_z."""
    u, v, w, phi, theta, psi, _ = X
    vel = np.array([u, v, w])
    a_cg = a_sensor - np.cross(omega_dot, r_acc) - np.cross(omega, np.cross(omega, r_acc))
    R = _euler_matrix(phi, theta, psi)
    vdot = a_cg + R.T @ np.array([0.0, 0.0, g]) - np.cross(omega, vel)
    # ω = (φ̇ − ψ̇ sin θ, θ̇ cos φ + ψ̇ sin φ cos θ, −θ̇ sin φ + ψ̇ cos φ cos θ)
    E = np.array(
        [
            [1.0, 0.0, -math.sin(theta)],
            [0.0, math.cos(phi), math.sin(phi) * math.cos(theta)],
            [0.0, -math.sin(phi), math.cos(phi) * math.cos(theta)],
        ]
    )
    euler_dot = np.linalg.solve(E, omega)
    hdot = -(R @ vel)[2]
    return np.concatenate([vdot, euler_dot, [hdot]])


def _reference_outputs(X, omega, r_boom, beta_asin=False):
    vel = np.array(X[:3])
    boom = vel + np.cross(omega, r_boom)
    v_boom = np.linalg.norm(boom)
    beta = math.asin(boom[1] / v_boom) if beta_asin else math.atan2(boom[1], boom[0])
    return np.array(
        [np.linalg.norm(vel), math.atan2(boom[2], boom[0]), beta, X[3], X[4], X[5], X[6]]
    )


def test_derivatives_and_outputs_match_a_vector_implementation():
    model = kinematic_model(g=G, accelerometer_position=ACC, airdata_position=BOOM)
    theta = model.parameters.values  # biases 0, f = 1
    rng = np.random.default_rng(12)
    for _ in range(20):
        X = np.array(
            [
                rng.uniform(50, 150),
                rng.uniform(-5, 5),
                rng.uniform(-10, 10),
                rng.uniform(-1, 1),
                rng.uniform(-0.5, 0.5),
                rng.uniform(-3, 3),
                rng.uniform(0, 5000),
            ]
        )
        a_s, omega, omega_dot = rng.normal(0, 3, 3), rng.normal(0, 0.3, 3), rng.normal(0, 1, 3)
        u = np.concatenate([a_s, omega, omega_dot])
        expected = _reference_derivatives(X, a_s, omega, omega_dot, ACC, G)
        np.testing.assert_allclose(model.f(0.0, X, u, theta), expected, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(
            model.h(0.0, X, u, theta), _reference_outputs(X, omega, BOOM), rtol=1e-12, atol=1e-13
        )
    asin = kinematic_model(beta="asin", airdata_position=BOOM, accelerometer_position=ACC)
    y = asin.h(0.0, X, u, theta)
    assert y[2] == pytest.approx(_reference_outputs(X, omega, BOOM, beta_asin=True)[2], rel=1e-12)


def test_steady_turn_closed_form():
    """Level turn at bank φ: ψ = ψ0 + Ω t with Ω = g tan φ / V, all else constant; the
    accelerometer away from the CG reads a_CG + ω×(ω×r) and the boom sees V + ω×r."""
    V, phi, psi0, h0, dt, n = 120.0, 0.5, 0.2, 3000.0, 0.04, 251
    omega_turn = G * math.tan(phi) / V
    omega = np.array([0.0, omega_turn * math.sin(phi), omega_turn * math.cos(phi)])
    a_cg = np.array([0.0, 0.0, -G / math.cos(phi)])
    a_sensor = a_cg + np.cross(omega, np.cross(omega, ACC))
    t = np.arange(n) * dt
    inputs = {
        name: np.full(n, value) for name, value in zip(("ax", "ay", "az"), a_sensor, strict=True)
    }
    inputs |= {name: np.full(n, value) for name, value in zip(("p", "q", "r"), omega, strict=True)}
    inputs |= {name: np.zeros(n) for name in ("pdot", "qdot", "rdot")}
    psi = psi0 + omega_turn * t
    boom = np.array([V, 0.0, 0.0]) + np.cross(omega, BOOM)
    outputs = {
        "V": np.full(n, V),
        "α": np.full(n, math.atan2(boom[2], boom[0])),
        "β": np.full(n, math.atan2(boom[1], boom[0])),
        "φ": np.full(n, phi),
        "θ": np.zeros(n),
        "ψ": psi,
        "h": np.full(n, h0),
    }
    data = FlightData(t, inputs, outputs)
    model = kinematic_model(
        g=G, accelerometer_position=ACC, airdata_position=BOOM, x0=(V, 0, 0, phi, 0, psi0, h0)
    )
    y = simulate(model, data)
    assert model.outputs == OUTPUTS[:7]
    expected = np.column_stack([outputs[o] for o in model.outputs])
    np.testing.assert_allclose(y, expected, rtol=1e-10, atol=1e-9)


def test_decoupled_model_reads_measured_quantities():
    """u, w, θ integrated with v and φ measured (SIDPAC's longitudinal model): the inputs
    are the sensors then v, φ, and f equals the full model's rows for u, w, θ."""
    lon = kinematic_model(states=("u", "w", "θ"), outputs=("V", "α", "θ"))
    assert lon.inputs == ("ax", "ay", "az", "p", "q", "r", "v", "φ")
    full = kinematic_model()
    rng = np.random.default_rng(3)
    X = np.array([100.0, 2.0, 8.0, 0.3, 0.1, 1.0, 1000.0])
    sensors = rng.normal(0, 1, 6)
    d_full = full.f(0.0, X, sensors, full.parameters.values)
    d_lon = lon.f(0.0, X[[0, 2, 4]], np.concatenate([sensors, X[[1, 3]]]), lon.parameters.values)
    np.testing.assert_allclose(d_lon, d_full[[0, 2, 4]], rtol=1e-14)
    lat = kinematic_model(states=("v", "φ", "ψ"), outputs=("β", "φ", "ψ"))
    assert lat.inputs[6:] == ("u", "w", "θ")


def test_sensor_conventions():
    """m = f·(x − x_ref) + x_ref ± b for outputs; inputs corrected by the inverse."""
    X = np.array([100.0, 1.0, 5.0, 0.1, 0.05, 0.3, 500.0])
    u = np.array([0.5, 0.2, -9.0, 0.01, 0.02, -0.01])
    base = kinematic_model(input_biases=(), output_biases=(), output_scales=())
    y0 = base.h(0.0, X, u, np.zeros(0))
    d0 = base.f(0.0, X, u, np.zeros(0))
    m = kinematic_model(input_biases=("ax", "q"), input_scales=("ax",))
    names = m.parameters.names
    assert names == ["b_ax", "b_q", "f_ax", "f_α", "b_α", "f_β", "b_β"]
    theta = np.array([0.1, 0.01, 1.05, 1.2, 0.03, 0.9, -0.02])
    # the model sees a_x' = (a_x − b)/f, q' = q − b_q: the same as the unbiased model with
    # corrected inputs
    corrected = u.copy()
    corrected[0] = (u[0] - 0.1) / 1.05
    corrected[4] = u[4] - 0.01
    np.testing.assert_allclose(m.f(0.0, X, u, theta), base.f(0.0, X, corrected, np.zeros(0)))
    assert not np.allclose(m.f(0.0, X, u, theta), d0)
    y_true = base.h(0.0, X, corrected, np.zeros(0))
    y = m.h(0.0, X, u, theta)
    assert y[1] == pytest.approx(1.2 * y_true[1] + 0.03, rel=1e-14)
    assert y[2] == pytest.approx(0.9 * y_true[2] - 0.02, rel=1e-14)
    assert y[0] == pytest.approx(y_true[0], rel=1e-14) and y0[0] == pytest.approx(y[0])
    # SIDPAC: biases added to the measurement, scale as a fraction about a reference
    s = kinematic_model(
        input_biases=("ax",),
        output_biases=(),
        output_scales=("α",),
        bias_convention="correction",
        scale_convention="fraction",
        scale_reference={"α": 0.04},
        names={"b_ax": "ax_bias", "f_α": "alf_scf"},
    )
    assert s.parameters.names == ["ax_bias", "alf_scf"]
    assert list(s.parameters.values) == [0.0, 0.0]
    corrected = u.copy()
    corrected[0] = u[0] + 0.2
    y_true = base.h(0.0, X, corrected, np.zeros(0))
    np.testing.assert_allclose(
        s.f(0.0, X, u, np.array([0.2, 0.1])), base.f(0.0, X, corrected, np.zeros(0))
    )
    assert s.h(0.0, X, u, np.array([0.2, 0.1]))[1] == pytest.approx(
        y_true[1] + 0.1 * (y_true[1] - 0.04), rel=1e-14
    )


def test_compiled_and_python_paths_agree():
    model = kinematic_model(
        accelerometer_position=ACC,
        airdata_position=BOOM,
        x0=(129.4, -0.9, 5.05, 0.02, 0.03, 0.2, 4877.0),
        output_delays={"α": "τ_α"},
        delay_convention="two_sample",
    )
    rng = np.random.default_rng(5)
    n = 200
    t = np.arange(n) * 0.04
    inputs = {name: rng.normal(0, 0.05, n) for name in model.inputs}
    inputs["az"] = inputs["az"] - G
    data = FlightData(t, inputs, {o: np.zeros(n) for o in model.outputs})
    theta = model.parameters.values + rng.normal(0, 0.01, len(model.parameters))
    compiled = simulate(model, data, theta, compiled=True)
    python = simulate(model, data, theta, compiled=False)
    np.testing.assert_allclose(compiled, python, rtol=1e-12, atol=1e-10)


# ------------------------------------------------------------------ recovery from simulation


def _maneuver_inputs(rng, n, dt):
    """Smooth random rates and accelerations (sums of sines), seeded."""
    t = np.arange(n) * dt
    signals = {}
    for name, amplitude, offset in (
        ("ax", 0.5, 0.3),
        ("ay", 0.5, 0.0),
        ("az", 1.0, -G),
        ("p", 0.08, 0.0),
        ("q", 0.05, 0.0),
        ("r", 0.04, 0.0),
    ):
        value = np.full(n, offset)
        for _ in range(3):
            frequency, phase = rng.uniform(0.1, 0.8), rng.uniform(0, 2 * np.pi)
            value = value + amplitude / 3 * np.sin(2 * np.pi * frequency * t + phase)
        signals[name] = value
    for name, rate in (("pdot", "p"), ("qdot", "q"), ("rdot", "r")):
        signals[name] = np.gradient(signals[rate], dt)
    return t, signals


def test_biases_scale_factors_and_delay_recovered_within_three_sigma():
    """Simulated data with known sensor errors (two maneuvers, seeded noise): MNR recovers
    every free parameter within 3 CR bounds."""
    model = kinematic_model(
        g=G,
        accelerometer_position=ACC,
        airdata_position=BOOM,
        output_delays={"α": "τ_α"},
        delay_convention="two_sample",
        x0=[
            (129.0, -0.5, 5.0, 0.02, 0.03, 0.22, 4800.0),
            (128.0, 0.3, 4.8, -0.02, 0.04, 0.2, 4850.0),
        ],
    )
    true = {
        "b_ax": 0.05,
        "b_ay": -0.03,
        "b_az": 0.08,
        "b_p": 0.001,
        "b_q": 0.003,
        "b_r": -0.001,
        "f_α": 0.97,
        "b_α": 0.004,
        "f_β": 1.02,
        "b_β": -0.003,
        "τ_α": 0.02,
    }
    truth = model.parameters.with_values(true)
    rng = np.random.default_rng(2024)
    dt, n = 0.04, 400
    maneuvers = []
    for k in range(2):
        t, signals = _maneuver_inputs(rng, n, dt)
        maneuvers.append(
            FlightData(t, signals, {o: np.zeros(n) for o in model.outputs}, name=f"m{k}")
        )
    y = simulate(model, maneuvers, truth.values)
    noise = np.array([0.1, 0.002, 0.002, 0.003, 0.002, 0.002, 2.0])
    noisy = []
    for k, m in enumerate(maneuvers):
        block = y[k * n : (k + 1) * n] + rng.normal(0, 1, (n, 7)) * noise
        outputs = {o: block[:, j] for j, o in enumerate(model.outputs)}
        noisy.append(FlightData(m.time, {i: m.input(i) for i in m.input_names}, outputs))
    result = estimate(model, noisy, solver=MNR(), noise="max")
    assert result.converged
    for name, value in true.items():
        i = result.names.index(name)
        assert abs(result.values[i] - value) < 3 * result.std[i], (name, result.values[i], value)
    # the start (all errors zero) is far outside: the data carry the errors
    assert (
        abs(result.values[result.names.index("b_az")]) > 10 * result.std[result.names.index("b_az")]
    )


# ------------------------------------------------------------------ errors


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"states": ("u", "x")}, "states: expected names from"),
        ({"states": "u"}, "states: expected a list"),
        ({"states": ()}, "at least one integrated"),
        ({"states": ("u", "w", "θ"), "outputs": ("φ",)}, "'φ' is not an integrated state"),
        ({"accelerometer_position": (1, 2)}, "accelerometer_position: expected three numbers"),
        ({"airdata_position": (1, 2, "a")}, "airdata_position[2]: expected a finite number"),
        ({"g": -1}, "g: expected a positive"),
        ({"beta": "atan"}, "beta: expected one of"),
        ({"bias_convention": "plus"}, "bias_convention: expected one of"),
        ({"names": {"b_x": "bx"}}, "names: 'b_x' is not a parameter"),
        ({"names": {"b_ax": "b_ay"}}, "names:"),
        ({"output_biases": ("α",), "outputs": ("V",)}, "output_biases: expected names from"),
        ({"scale_reference": {"γ": 1.0}}, "scale_reference: 'γ'"),
        ({"output_delays": {"γ": "τ"}}, "output_delays: 'γ' is not an output"),
        ({"input_delays": {"de": "τ"}}, "input_delays: 'de' is not an input"),
        ({"wind": ("W_X",)}, "wind: expected names from ['W_N', 'W_E', 'W_D']"),
        ({"wind": "W_N"}, "wind: expected a list"),
        ({"outputs": ("V", "x_N")}, "'x_N' is not an integrated state"),
        ({"outputs": ()}, "outputs: expected at least one output"),
        ({"g": True}, "g: expected a number (L/s²), got True"),
        ({"g": float("nan")}, "g: expected a positive finite number (L/s²), got nan"),
        ({"scale_reference": {"α": "1"}}, "scale_reference.α: expected a number, got '1'"),
    ],
)
def test_named_errors(arguments, message):
    with pytest.raises((InputError, InputTypeError)) as info:
        kinematic_model(**arguments)
    assert message in str(info.value)


def _case(model: dict) -> dict:
    return {
        "data": {"file": "x.csv", "outputs": {"V": 2}},
        "model": {"type": "kinematic", **model},
    }


@pytest.mark.parametrize(
    ("model", "message"),
    [
        ({"accelerometer": [0, 0, 0]}, "model.accelerometer: unknown key"),
        ({"states": ["u", "q"]}, "model.states: expected names from"),
        ({"output_delays": {"γ": "τ"}}, "model.output_delays.γ: not an output"),
        ({"output_delays": {"α": "1τ"}}, "model.output_delays.α: expected a parameter name"),
        ({"delay_convention": "book"}, "model.delay_convention: expected one of"),
        ({"g": "9.8"}, "model.g:"),
        ({"wind": ["N"]}, "model.wind: expected names from"),
        ({"states": ["u", "x"]}, "model.states: expected names from"),
        ({"input_delays": {"de": "τ"}}, "model.input_delays.de: not an input"),
        ({"input_delays": {"q": "1τ"}}, "model.input_delays.q: expected a parameter name"),
        ({"input_delays": ["q"]}, "model.input_delays: expected a table"),
    ],
)
def test_case_file_errors_name_the_key(tmp_path, model, message):
    with pytest.raises(CaseError) as info:
        parse_case(_case(model), tmp_path / "case.toml")
    assert message in str(info.value)


def test_quantity_names():
    assert QUANTITIES == ("u", "v", "w", "φ", "θ", "ψ", "h", "x_N", "y_E")
    assert kinematic_spec().states == QUANTITIES[:7]
    spec = kinematic_spec(accelerometer_position=ACC)
    assert spec.inputs[6:9] == ("pdot", "qdot", "rdot")
    assert kinematic_spec().inputs == ("ax", "ay", "az", "p", "q", "r")


def test_reconstruction_inverts_the_sensor_model():
    """At the true parameters the reconstruction gives back the true signals: corrected
    inputs = error-free inputs (exactly), corrected α = the undelayed model α (a delay of one
    sample is undone exactly but for the last sample), α_rec, u_rec = the noise-free
    simulation; per-maneuver output biases (b_α per maneuver) are inverted per maneuver."""
    from flightid.compat.kinematic import model_from_spec
    from flightid.compat.reconstruct import reconstruct

    dt, n = 0.04, 300
    x0 = [(129.0, -0.5, 5.0, 0.02, 0.03, 0.22, 4800.0), (128.0, 0.3, 4.8, -0.02, 0.04, 0.2, 4850.0)]
    spec = kinematic_spec(g=G, accelerometer_position=ACC, airdata_position=BOOM, delays=("τ_α",))
    model = model_from_spec(spec, x0=x0, output_delays={"α": "τ_α"}).with_per_maneuver(["b_α"], 2)
    true = {"b_ax": 0.05, "b_q": 0.003, "f_α": 0.97, "b_α_1": 0.004, "b_α_2": -0.006, "τ_α": dt}
    theta = model.parameters.with_values(true).values
    rng = np.random.default_rng(7)
    clean = []
    for _ in range(2):
        t, signals = _maneuver_inputs(rng, n, dt)
        clean.append(FlightData(t, signals, {o: np.zeros(n) for o in model.outputs}))
    # measured inputs: m = x + b; measured outputs: the model with its errors and delay
    measured_in = [
        {
            **{i: m.input(i) for i in m.input_names},
            "ax": m.input("ax") + 0.05,
            "q": m.input("q") + 0.003,
        }
        for m in clean
    ]
    probe = [
        FlightData(m.time, u, {o: np.zeros(n) for o in model.outputs})
        for m, u in zip(clean, measured_in, strict=True)
    ]
    y = simulate(model, probe, theta)
    data = [
        FlightData(m.time, u, {o: y[k * n : (k + 1) * n, j] for j, o in enumerate(model.outputs)})
        for k, (m, u) in enumerate(zip(clean, measured_in, strict=True))
    ]
    error_free = kinematic_model(
        g=G, accelerometer_position=ACC, airdata_position=BOOM, x0=x0,
        input_biases=(), output_biases=(), output_scales=(),
    )  # fmt: skip
    truth = simulate(error_free, clean)
    recs = reconstruct(spec, model, data, theta)
    for k, rec in enumerate(recs):
        cols = rec.columns
        np.testing.assert_allclose(cols["ax [m/s^2]"], clean[k].input("ax"), atol=1e-14)
        np.testing.assert_allclose(cols["q [rad/s]"], clean[k].input("q"), atol=1e-15)
        np.testing.assert_allclose(cols["p [rad/s]"], clean[k].input("p"), atol=0)
        block = truth[k * n : (k + 1) * n]
        np.testing.assert_allclose(cols["α_rec [rad]"], block[:, 1], atol=1e-12)
        np.testing.assert_allclose(cols["u_rec [m/s]"][0], x0[k][0])
        np.testing.assert_allclose(cols["h_rec [m]"], block[:, 6], atol=1e-9)
        # corrected α: delay undone (z(t + dt) = z_{k+1}), bias of this maneuver, factor
        np.testing.assert_allclose(cols["α [rad]"][:-1], block[:-1, 1], atol=1e-12)
        np.testing.assert_allclose(cols["α_fit [rad]"], data[k].output("α"), atol=1e-12)


# ------------------------------------------------------------------ positions, ground speeds, wind


def _steady_climbing_turn_in_wind(n: int, dt: float):
    """A steady climbing turn relative to the air mass in a constant wind, in closed form
    (independent of the model code): attitude φ, θ constant, ψ = ψ0 + Ω t, the air-relative
    body velocity V_a = (u_a, v_a, w_a) constant, so the body rates ω = (−Ω sθ, Ω sφ cθ,
    Ω cφ cθ) and the specific force a = ω × V_a − Rᵀ(0, 0, g) are constant (the wind drops
    out of it); the inertial velocity in body axes is V_a + Rᵀ W, in NED R V_a + W, and the
    position its integral: with c = R_y(θ) R_x(φ) V_a,
    x_N = x_N0 + (c_x (sin ψ − sin ψ0) + c_y (cos ψ − cos ψ0))/Ω + W_N t,
    y_E = y_E0 + (c_y (sin ψ − sin ψ0) − c_x (cos ψ − cos ψ0))/Ω + W_E t,
    h = h0 − (c_z + W_D) t."""
    phi, theta, psi0, Omega = 0.35, 0.08, 0.4, 0.06
    v_air = np.array([110.0, 1.5, 6.0])
    wind = np.array([8.0, -5.0, 0.7])  # W_N, W_E, W_D (m/s)
    h0, xn0, ye0 = 2500.0, 100.0, -300.0
    st, ct, sf, cf = math.sin(theta), math.cos(theta), math.sin(phi), math.cos(phi)
    omega = np.array([-Omega * st, Omega * sf * ct, Omega * cf * ct])
    t = np.arange(n) * dt
    psi = psi0 + Omega * t
    R0 = _euler_matrix(phi, theta, psi0)
    a = np.cross(omega, v_air) - R0.T @ np.array([0.0, 0.0, G])
    c = _euler_matrix(phi, theta, 0.0) @ v_air
    vn = c[0] * np.cos(psi) - c[1] * np.sin(psi) + wind[0]
    ve = c[0] * np.sin(psi) + c[1] * np.cos(psi) + wind[1]
    vd = np.full(n, c[2] + wind[2])
    x0_vel = v_air + R0.T @ wind  # inertial body velocity at t = 0
    boom = v_air + np.cross(omega, BOOM)
    truth = {
        "V": np.full(n, np.linalg.norm(v_air)),
        "α": np.full(n, math.atan2(boom[2], boom[0])),
        "β": np.full(n, math.atan2(boom[1], boom[0])),
        "φ": np.full(n, phi),
        "θ": np.full(n, theta),
        "ψ": psi,
        "h": h0 - (c[2] + wind[2]) * t,
        "x_N": xn0
        + (c[0] * (np.sin(psi) - math.sin(psi0)) + c[1] * (np.cos(psi) - math.cos(psi0))) / Omega
        + wind[0] * t,
        "y_E": ye0
        + (c[1] * (np.sin(psi) - math.sin(psi0)) - c[0] * (np.cos(psi) - math.cos(psi0))) / Omega
        + wind[1] * t,
        "V_N": vn,
        "V_E": ve,
        "V_D": vd,
        "V_G": np.hypot(vn, ve),
        "χ": np.arctan2(ve, vn),
    }
    inputs = {k: np.full(n, v) for k, v in zip(("ax", "ay", "az"), a, strict=True)}
    inputs |= {k: np.full(n, v) for k, v in zip(("p", "q", "r"), omega, strict=True)}
    x0 = (*x0_vel, phi, theta, psi0, h0, xn0, ye0)
    return t, inputs, truth, x0, wind


def test_steady_climbing_turn_in_constant_wind_closed_form():
    """All nine states and fourteen outputs against the closed form: the air data see the
    air-relative velocity (constant), the ground speeds and positions the inertial one."""
    n, dt = 1001, 0.02
    t, inputs, truth, x0, wind = _steady_climbing_turn_in_wind(n, dt)
    model = kinematic_model(
        g=G,
        states=QUANTITIES,
        outputs=OUTPUTS,
        airdata_position=BOOM,
        wind=("W_N", "W_E", "W_D"),
        input_biases=(),
        output_biases=(),
        output_scales=(),
        x0=x0,
    )
    assert model.parameters.names == ["W_N", "W_E", "W_D"]
    assert model.inputs == ("ax", "ay", "az", "p", "q", "r")
    theta = np.array(wind)
    data = FlightData(t, inputs, {o: np.zeros(n) for o in OUTPUTS})
    y = simulate(model, data, theta)
    for j, name in enumerate(OUTPUTS):
        scale = max(1.0, float(np.max(np.abs(truth[name]))))
        np.testing.assert_allclose(y[:, j], truth[name], rtol=0, atol=1e-9 * scale, err_msg=name)
    # the wind makes the difference: without it the air data vary with the heading
    still = simulate(model, data, np.zeros(3))
    assert np.ptp(still[:, 0]) > 10.0 and np.ptp(still[:, 1]) > 0.003
    # a model without wind gives the same numbers as one whose wind is zero
    plain = kinematic_model(
        g=G, states=QUANTITIES, outputs=OUTPUTS, airdata_position=BOOM, input_biases=(),
        output_biases=(), output_scales=(), x0=x0,
    )  # fmt: skip
    np.testing.assert_array_equal(simulate(plain, data, np.zeros(0)), still)


def test_positions_and_wind_in_a_decoupled_model():
    """Positions need the attitude and the velocity: measured when not integrated. With wind
    the air data need φ, θ, ψ too (a measured ψ for a longitudinal model)."""
    spec = kinematic_spec(states=("u", "w", "θ", "x_N"), outputs=("V", "α", "x_N", "V_N"))
    assert spec.inputs[6:] == ("v", "φ", "ψ")
    lon = kinematic_spec(states=("u", "w", "θ"), outputs=("V", "α"), wind=("W_N", "W_E"))
    assert lon.inputs[6:] == ("v", "φ", "ψ")
    assert [p.name for p in lon.parameters][-2:] == ["W_N", "W_E"]
    assert lon.parameters["W_N"].unit == "m/s"
    assert kinematic_spec(states=("u", "w", "θ"), outputs=("V", "α")).inputs[6:] == ("v", "φ")


def test_wind_recovered_within_three_sigma():
    """Simulated air data and GPS-type ground speeds and positions in a turn (heading through
    2.4 rad) with a constant wind and sensor biases (seeded noise): MNR recovers W_N, W_E,
    W_D and the six input biases within 3 CR bounds."""
    n, dt = 1200, 0.05
    rng = np.random.default_rng(31)
    t, inputs, _, x0, _ = _steady_climbing_turn_in_wind(n, dt)
    for name, amplitude in (("ax", 0.3), ("ay", 0.2), ("az", 0.5), ("p", 0.02), ("q", 0.01),
                            ("r", 0.01)):  # fmt: skip
        for _ in range(2):
            frequency, phase = rng.uniform(0.05, 0.4), rng.uniform(0, 2 * np.pi)
            inputs[name] = inputs[name] + amplitude * np.sin(2 * np.pi * frequency * t + phase)
    outputs = ("V", "α", "β", "φ", "θ", "ψ", "h", "x_N", "y_E", "V_N", "V_E", "V_D")
    model = kinematic_model(
        g=G,
        states=QUANTITIES,
        outputs=outputs,
        wind=("W_N", "W_E", "W_D"),
        output_biases=(),
        output_scales=(),
        x0=x0,
    )
    true = {"b_ax": 0.05, "b_ay": -0.03, "b_az": 0.08, "b_p": 0.001, "b_q": 0.002,
            "b_r": -0.001, "W_N": 6.0, "W_E": -4.0, "W_D": 0.5}  # fmt: skip
    data = FlightData(t, inputs, {o: np.zeros(n) for o in outputs})
    y = simulate(model, data, model.parameters.with_values(true).values)
    noise = np.array([0.2, 0.002, 0.002, 0.003, 0.002, 0.002, 2.0, 3.0, 3.0, 0.1, 0.1, 0.1])
    noisy = y + rng.normal(0, 1, y.shape) * noise
    measured = FlightData(t, inputs, {o: noisy[:, j] for j, o in enumerate(outputs)})
    result = estimate(model, measured, solver=MNR(), noise="max")
    assert result.converged
    for name, value in true.items():
        i = result.names.index(name)
        assert abs(result.values[i] - value) < 3 * result.std[i], (name, result.values[i], value)
    for name in ("W_N", "W_E"):
        i = result.names.index(name)
        assert result.std[i] < 0.2 and abs(result.values[i]) > 10 * result.std[i]


def test_input_delay_shifts_the_input():
    """input_delays = {q: τ_q} with τ = 3 samples (fractional rule): the same as the
    undelayed model fed q shifted by three samples (the first sample held)."""
    dt, n, k = 0.04, 200, 3
    rng = np.random.default_rng(9)
    t, signals = _maneuver_inputs(rng, n, dt)
    x0 = (129.0, -0.5, 5.0, 0.02, 0.03, 0.22, 4800.0)
    delayed = kinematic_model(g=G, input_delays={"q": "τ_q"}, x0=x0)
    assert delayed.parameters.names[-1] == "τ_q" and delayed.input_delays == {"q": "τ_q"}
    plain = kinematic_model(g=G, x0=x0)
    data = FlightData(t, signals, {o: np.zeros(n) for o in plain.outputs})
    shifted = dict(signals)
    shifted["q"] = np.concatenate([np.full(k, signals["q"][0]), signals["q"][:-k]])
    data_shifted = FlightData(t, shifted, {o: np.zeros(n) for o in plain.outputs})
    theta = delayed.parameters.with_values({"τ_q": k * dt, "b_q": 0.002}).values
    np.testing.assert_allclose(
        simulate(delayed, data, theta),
        simulate(plain, data_shifted, theta[:-1]),
        rtol=1e-12,
        atol=1e-9,
    )
    assert not np.allclose(simulate(delayed, data, theta), simulate(plain, data, theta[:-1]))


def test_case_file_wind_positions_and_input_delays(tmp_path):
    """[model] wind, positions, ground-speed outputs and input_delays in a case file give
    the model of the Python API (same parameters, same simulation)."""
    from flightid.cases.build import build_model

    raw = _case(
        {
            "states": ["u", "v", "w", "φ", "θ", "ψ", "h", "x_N", "y_E"],
            "outputs": ["V", "α", "β", "x_N", "y_E", "V_N", "V_E", "V_D"],
            "wind": ["W_N", "W_E"],
            "input_delays": {"q": "τ_q"},
        }
    )
    raw["initial_state"] = dict(
        zip(QUANTITIES, (110.0, 1.0, 6.0, 0.3, 0.08, 0.4, 2500.0, 0.0, 0.0), strict=True)
    )
    raw["parameters"] = {"W_N": 6.0, "W_E": -4.0, "τ_q": 0.04}
    case = parse_case(raw, tmp_path / "case.toml")
    n, dt = 300, 0.04
    t, signals = _maneuver_inputs(np.random.default_rng(4), n, dt)
    data = FlightData(t, {k: signals[k] for k in ("ax", "ay", "az", "p", "q", "r")},
                      {o: np.zeros(n) for o in raw["model"]["outputs"]})  # fmt: skip
    model, maneuvers = build_model(case, [data])
    assert model.input_delays == {"q": "τ_q"}
    assert model.parameters.names[-3:] == ["W_N", "W_E", "τ_q"]
    python = kinematic_model(
        states=QUANTITIES,
        outputs=raw["model"]["outputs"],
        wind=("W_N", "W_E"),
        input_delays={"q": "τ_q"},
        x0=tuple(raw["initial_state"].values()),
    )
    assert python.parameters.names == model.parameters.names
    theta = python.parameters.with_values(raw["parameters"]).values
    np.testing.assert_array_equal(model.parameters.values, theta)
    np.testing.assert_allclose(simulate(model, maneuvers), simulate(python, data, theta),
                               rtol=1e-13, atol=1e-9)  # fmt: skip


def test_reconstruction_with_wind_and_positions():
    """The reconstructed signals of a model with wind and positions: x_N_rec … χ_rec and the
    air-relative V_rec, α_rec of the closed-form climbing turn; a model without them writes
    no ground columns."""
    from flightid.compat.kinematic import model_from_spec
    from flightid.compat.reconstruct import reconstruct

    n, dt = 501, 0.02
    t, inputs, truth, x0, wind = _steady_climbing_turn_in_wind(n, dt)
    spec = kinematic_spec(g=G, states=QUANTITIES, outputs=("V", "α", "V_N", "x_N"),
                          airdata_position=BOOM, wind=("W_N", "W_E", "W_D"))  # fmt: skip
    model = model_from_spec(spec, x0=x0)
    data = FlightData(t, inputs, {o: truth[o] for o in model.outputs})
    theta = model.parameters.with_values(dict(zip(("W_N", "W_E", "W_D"), wind, strict=True)))
    (rec,) = reconstruct(spec, model, [data], theta.values)
    for name in ("V", "α", "β", "x_N", "y_E", "V_E", "V_G", "χ"):
        unit = spec.unit(name)
        np.testing.assert_allclose(rec.columns[f"{name}_rec [{unit}]"], truth[name],
                                   rtol=1e-10, atol=1e-8, err_msg=name)  # fmt: skip
    assert rec.columns["x_N_rec [m]"] is not None and spec.unit("W_N") == "m/s"
    (plain,) = reconstruct(kinematic_spec(g=G), kinematic_model(g=G, x0=x0[:7]), [
        FlightData(t, inputs, {o: np.zeros(n) for o in ("V", "α", "β", "φ", "θ", "ψ", "h")})
    ])  # fmt: skip
    assert not any(k.startswith(("x_N", "V_N", "χ")) for k in plain.columns)


def test_reconstruction_keeps_input_delays():
    """With input_delays = {q: τ_q} the reconstructed q column is the input as the model read
    it, q_m(t − τ) − b_q (τ = two samples: q shifted by two samples, the first held), and the
    integration is that of the fit (α_rec = α_fit with f_α = 1, b_α = 0)."""
    from flightid.compat.kinematic import model_from_spec
    from flightid.compat.reconstruct import reconstruct

    dt, n, k = 0.04, 150, 2
    t, signals = _maneuver_inputs(np.random.default_rng(11), n, dt)
    x0 = (129.0, -0.5, 5.0, 0.02, 0.03, 0.22, 4800.0)
    spec = kinematic_spec(g=G, delays=("τ_q",))
    model = model_from_spec(spec, x0=x0, input_delays={"q": "τ_q"})
    theta = model.parameters.with_values({"τ_q": k * dt, "b_q": 0.003}).values
    data = FlightData(t, signals, {o: np.zeros(n) for o in model.outputs})
    (rec,) = reconstruct(spec, model, [data], theta)
    q = signals["q"]
    expected = np.concatenate([np.full(k, q[0]), q[:-k]]) - 0.003
    np.testing.assert_allclose(rec.columns["q [rad/s]"], expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose(rec.columns["α_rec [rad]"], rec.columns["α_fit [rad]"], atol=1e-15)
