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
from flightid.simulate import simulate

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
    expected = np.column_stack([outputs[o] for o in OUTPUTS])
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
    ],
)
def test_case_file_errors_name_the_key(tmp_path, model, message):
    with pytest.raises(CaseError) as info:
        parse_case(_case(model), tmp_path / "case.toml")
    assert message in str(info.value)


def test_quantity_names():
    assert QUANTITIES == ("u", "v", "w", "φ", "θ", "ψ", "h")
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
