"""The airplane equations of motion: trim, closed forms, invariants, agreement of forms.

Most simulations here run the pure-Python kernel (``compiled=False``; the same source the
numba kernel compiles) to keep the suite fast; one test checks compiled == pure Python.
"""

import math

import numpy as np
import pytest

from flightid.aircraft import (
    OUTPUTS,
    AeroModel,
    Airplane,
    body_state,
    lateral_model,
    longitudinal_model,
    navion,
    navion_longitudinal_aero,
    six_dof_model,
    trim_level_flight,
    wind_axis_longitudinal_model,
)
from flightid.aircraft.library import NAVION_TRIM_SPEED
from flightid.data import FlightData
from flightid.errors import InputError
from flightid.simulation import simulate

G = 9.80665
# Nelson (1998) App. B, Navion lateral derivatives (per rad): a realistic, stable lateral model
NAVION_LATERAL = {
    "CY_beta": -0.564, "CY_dr": 0.157, "Cl_beta": -0.074, "Cl_phat": -0.410, "Cl_rhat": 0.107,
    "Cl_da": -0.134, "Cl_dr": 0.107, "Cn_beta": 0.071, "Cn_phat": -0.0575, "Cn_rhat": -0.125,
    "Cn_da": -0.0035, "Cn_dr": -0.072,
}  # fmt: skip
LATERAL_AERO = AeroModel(
    {
        "CY": ["beta", "dr"],
        "Cl": ["beta", "phat", "rhat", "da", "dr"],
        "Cn": ["beta", "phat", "rhat", "da", "dr"],
    }
)


def _doublet(t, start, width, amplitude):
    return amplitude * (
        ((t >= start) & (t < start + width)).astype(float)
        - ((t >= start + width) & (t < start + 2 * width)).astype(float)
    )


@pytest.fixture(scope="module")
def navion6():
    """Navion 6-DOF model (Nelson's longitudinal and lateral derivatives), trimmed."""
    lon, lon_values = navion_longitudinal_aero()
    aero = lon + LATERAL_AERO
    model = six_dof_model(navion(), aero, aero.parameters({**lon_values, **NAVION_LATERAL}))
    trim = trim_level_flight(model, NAVION_TRIM_SPEED)
    return model.with_x0(tuple(trim.x)), trim


def _maneuver(trim, names, duration=8.0, dt=0.05):
    t = np.arange(0.0, duration + dt / 2, dt)
    inputs = {n: np.full(t.shape, trim.inputs[n]) for n in names}
    inputs["da"] = inputs["da"] + _doublet(t, 0.5, 1.0, 0.1)
    inputs["dr"] = inputs["dr"] + _doublet(t, 3.0, 1.0, 0.1)
    inputs["de"] = inputs["de"] + _doublet(t, 1.5, 0.5, 0.05)
    return FlightData(t, inputs)


def test_trim_is_steady_level_flight(navion6):
    model, trim = navion6
    assert trim.residual < 1e-10
    # no side-force bias: wings level, zero sideslip, symmetric controls
    assert abs(trim.phi) < 1e-8 and abs(trim.inputs["da"]) < 1e-8
    # lift = weight: C_L = W/(q̄S) ≈ 0.406 → α ≈ (0.406 − 0.41)/4.44 (Nelson App. B values)
    airplane = navion()
    cl = airplane.weight / (0.5 * airplane.rho * NAVION_TRIM_SPEED**2 * airplane.S)
    assert trim.alpha == pytest.approx((cl - 0.41) / 4.44, abs=2e-4)
    assert trim.theta == pytest.approx(trim.alpha, abs=1e-9)  # level: Θ = α
    # thrust = drag q̄S(C_D0 + C_Dα α) at β = 0
    assert trim.inputs["thrust"] == pytest.approx(
        0.5 * airplane.rho * NAVION_TRIM_SPEED**2 * airplane.S * (0.05 + 0.33 * trim.alpha),
        rel=1e-3,
    )


def test_trim_stays_put(navion6):
    model, trim = navion6
    t = np.arange(0.0, 10.0001, 0.05)
    data = FlightData(t, {n: np.full(t.shape, v) for n, v in trim.inputs.items()})
    y = simulate(model, data, compiled=False)
    start = y[0]
    assert np.max(np.abs(y - start)) < 1e-9
    assert y[0, OUTPUTS.index("V")] == pytest.approx(NAVION_TRIM_SPEED, rel=1e-12)
    assert y[0, OUTPUTS.index("az")] == pytest.approx(-math.cos(trim.alpha), rel=1e-6)


def _vacuum(Ixz=0.0):
    """An airplane in vacuum (ρ = 0): no aerodynamic force, pure rigid-body motion."""
    airplane = Airplane(
        mass=1000.0, Ix=1500.0, Iy=4000.0, Iz=5000.0, Ixz=Ixz, S=16.0, b=10.0, cbar=1.6,
        density=0.0,
    )  # fmt: skip
    aero = AeroModel({"CY": ["beta"]})
    return airplane, aero


def test_free_fall_matches_closed_form():
    airplane, aero = _vacuum()
    model = six_dof_model(airplane, aero, x0=tuple(body_state(50.0)))
    t = np.arange(0.0, 3.0001, 0.05)
    y = simulate(model, FlightData(t, {"dummy": np.zeros_like(t)}), compiled=False)
    out = {n: y[:, i] for i, n in enumerate(model.outputs)}
    # u = 50, w = g t  ⇒  V = √(50² + (g t)²), α = atan(g t/50); accelerometers read 0
    np.testing.assert_allclose(out["V"], np.hypot(50.0, G * t), rtol=1e-12)
    np.testing.assert_allclose(out["alpha"], np.arctan2(G * t, 50.0), atol=1e-12)
    np.testing.assert_allclose(out["theta"], 0.0, atol=1e-14)
    for name in ("ax", "ay", "az", "p", "q", "r", "beta", "phi"):
        np.testing.assert_allclose(out[name], 0.0, atol=1e-14)


def test_pure_roll_matches_closed_form():
    airplane, aero = _vacuum()
    p0 = 0.5  # rad/s
    model = six_dof_model(airplane, aero, x0=tuple(body_state(50.0, p=p0)))
    t = np.arange(0.0, 4.0001, 0.05)
    y = simulate(model, FlightData(t, {"dummy": np.zeros_like(t)}), compiled=False)
    out = {n: y[:, i] for i, n in enumerate(model.outputs)}
    # torque-free roll about a principal axis: p constant, Φ = p0 t (RK4 error ~1e-9)
    np.testing.assert_allclose(out["p"], p0, rtol=1e-14)
    np.testing.assert_allclose(out["phi"], p0 * t, atol=1e-8)
    np.testing.assert_allclose(out["theta"], 0.0, atol=1e-12)


def test_torque_free_tumbling_conserves_energy_and_momentum():
    airplane, aero = _vacuum(Ixz=300.0)
    model = six_dof_model(airplane, aero, x0=tuple(body_state(50.0, p=0.8, q=0.3, r=-0.5)))
    t = np.arange(0.0, 10.0001, 0.02)
    y = simulate(model, FlightData(t, {"dummy": np.zeros_like(t)}), compiled=False)
    p, q, r = (y[:, OUTPUTS.index(n)] for n in ("p", "q", "r"))
    inertia = np.array([[1500.0, 0.0, -300.0], [0.0, 4000.0, 0.0], [-300.0, 0.0, 5000.0]])
    omega = np.column_stack([p, q, r])
    momentum = omega @ inertia  # body-axis angular momentum I ω (I symmetric)
    energy = 0.5 * np.einsum("ij,ij->i", omega, momentum)
    # closed form: |H| and T are invariants of torque-free rigid-body motion
    np.testing.assert_allclose(np.linalg.norm(momentum, axis=1), np.linalg.norm(momentum[0]),
                               rtol=1e-8)  # fmt: skip
    np.testing.assert_allclose(energy, energy[0], rtol=1e-8)
    assert np.ptp(p) > 0.1  # it really tumbles


def test_direction_cosine_row_keeps_unit_norm(navion6):
    model, trim = navion6
    data = _maneuver(trim, model.inputs, duration=20.0)
    # integrate the 6-DOF f with the simulator's RK4 scheme and watch the row norm: the
    # equations (2.11–2.13) conserve it exactly (skew-symmetric), RK4 to its truncation error
    x = np.array(trim.x)
    u = np.column_stack([data.input(n) for n in model.inputs])
    theta = model.parameters.values
    dt = data.dt
    worst = 0.0
    for k in range(data.n_samples - 1):
        uh = 0.5 * (u[k] + u[k + 1])
        k1 = model.f(0.0, x, u[k], theta)
        k2 = model.f(0.0, x + 0.5 * dt * k1, uh, theta)
        k3 = model.f(0.0, x + 0.5 * dt * k2, uh, theta)
        k4 = model.f(0.0, x + dt * k3, u[k + 1], theta)
        x = x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        worst = max(worst, abs(np.linalg.norm(x[6:9]) - 1.0))
    assert worst < 1e-5
    assert abs(x[3]) + abs(x[5]) > 0  # the maneuver moved the airplane


def test_output_equations_invert_body_state():
    model = six_dof_model(navion(), LATERAL_AERO)
    x = body_state(60.0, alpha=0.1, beta=-0.05, theta=0.2, phi=-0.4, p=0.1, q=0.2, r=0.3)
    u = np.zeros(len(model.inputs))
    y = dict(zip(model.outputs, model.h(0.0, x, u, model.parameters.values), strict=True))
    expected = {"V": 60.0, "alpha": 0.1, "beta": -0.05, "theta": 0.2, "phi": -0.4,
                "p": 0.1, "q": 0.2, "r": 0.3}  # fmt: skip
    for name, value in expected.items():
        assert y[name] == pytest.approx(value, abs=1e-13), name


def test_decoupled_models_reproduce_six_dof_derivatives(navion6):
    """Exact algebra: with the other axis's motion as inputs, the decoupled f equals the
    6-DOF f entries for the states it keeps (2.27–2.32)."""
    model, trim = navion6
    lon, lon_values = navion_longitudinal_aero()
    airplane = navion()
    values = {**lon_values, **NAVION_LATERAL}
    lat = lateral_model(
        airplane, LATERAL_AERO, LATERAL_AERO.parameters(NAVION_LATERAL), controls=("da", "dr")
    )
    lng = longitudinal_model(airplane, lon, lon.parameters(lon_values))
    assert lat.inputs == ("da", "dr", "u", "w", "q")
    assert lng.inputs == ("de", "thrust", "v", "p", "r")
    rng = np.random.default_rng(0)
    theta6 = model.parameters.values
    for _ in range(5):
        x = body_state(55.0, *rng.uniform(-0.2, 0.2, 4), *rng.uniform(-0.5, 0.5, 3))
        controls = {"de": 0.02, "da": -0.05, "dr": 0.03, "thrust": 1500.0}
        u6 = np.array([controls[n] for n in model.inputs])
        d6 = model.f(0.0, x, u6, theta6)
        y6 = dict(zip(model.outputs, model.h(0.0, x, u6, theta6), strict=True))
        ul = np.array([controls["da"], controls["dr"], x[0], x[2], x[4]])
        dl = lat.f(0.0, x[[1, 3, 5, 6, 7, 8]], ul, lat.parameters.values)
        np.testing.assert_allclose(dl, d6[[1, 3, 5, 6, 7, 8]], rtol=1e-13, atol=1e-13)
        yl = lat.h(0.0, x[[1, 3, 5, 6, 7, 8]], ul, lat.parameters.values)
        np.testing.assert_allclose(yl, [y6[n] for n in lat.outputs], rtol=1e-13, atol=1e-13)
        ug = np.array([controls["de"], controls["thrust"], x[1], x[3], x[5]])
        dg = lng.f(0.0, x[[0, 2, 4, 6, 7, 8]], ug, lng.parameters.values)
        np.testing.assert_allclose(dg, d6[[0, 2, 4, 6, 7, 8]], rtol=1e-13, atol=1e-13)
        yg = lng.h(0.0, x[[0, 2, 4, 6, 7, 8]], ug, lng.parameters.values)
        np.testing.assert_allclose(yg, [y6[n] for n in lng.outputs], rtol=1e-13, atol=1e-13)
    # the 6-DOF model carries both halves' parameters at the values the decoupled ones use
    assert dict(zip(model.parameters.names, theta6, strict=True)) == values


def test_lateral_model_driven_by_six_dof_longitudinal_motion(navion6):
    """Simulation: the decoupled lateral model fed the 6-DOF's sampled u, w, q reproduces the
    6-DOF lateral outputs; the gap is the RK4 half-step interpolation of sampled inputs and
    shrinks ~4× when the step halves (second order)."""
    model, trim = navion6
    lat = lateral_model(
        navion(), LATERAL_AERO, LATERAL_AERO.parameters(NAVION_LATERAL),
        controls=("da", "dr"), x0=tuple(trim.x[[1, 3, 5, 6, 7, 8]]),
    )  # fmt: skip
    gaps = []
    for dt in (0.05, 0.025):
        data = _maneuver(trim, model.inputs, duration=8.0, dt=dt)
        y6 = simulate(model, data, compiled=False)
        out = {n: y6[:, i] for i, n in enumerate(model.outputs)}
        V, a, b = out["V"], out["alpha"], out["beta"]
        dl = FlightData(data.time, {"da": data.input("da"), "dr": data.input("dr"),
                                    "u": V * np.cos(a) * np.cos(b), "w": V * np.sin(a) * np.cos(b),
                                    "q": out["q"]})  # fmt: skip
        yl = simulate(lat, dl, compiled=False)
        gap = max(np.max(np.abs(yl[:, i] - out[n])) for i, n in enumerate(lat.outputs))
        gaps.append(gap)
        assert np.max(np.abs(out["p"])) > 0.1
    assert gaps[0] < 2e-3
    assert 2.5 < gaps[0] / gaps[1] < 6.0


def test_body_and_wind_axis_longitudinal_forms_agree(navion6):
    _, trim = navion6
    lon, lon_values = navion_longitudinal_aero()
    airplane = navion()
    params = lon.parameters(lon_values)
    body = six_dof_model(airplane, lon, params, x0=tuple(trim.x))
    wind = wind_axis_longitudinal_model(
        airplane, lon, params, x0=(trim.V, trim.alpha, trim.theta, 0.0)
    )
    t = np.arange(0.0, 10.0001, 0.02)
    de = trim.inputs["de"] + _doublet(t, 1.0, 0.5, 0.05)
    data = FlightData(t, {"de": de, "thrust": np.full(t.shape, trim.inputs["thrust"])})
    yb = simulate(body, data, compiled=False)
    yw = simulate(wind, data, compiled=False)
    assert wind.outputs == ("V", "alpha", "theta", "q", "ax", "az")
    for i, name in enumerate(wind.outputs):
        np.testing.assert_allclose(yw[:, i], yb[:, body.outputs.index(name)], atol=1e-7,
                                   err_msg=name)  # fmt: skip
    assert np.ptp(yw[:, 1]) > 0.02  # α really moved


def test_compiled_and_python_kernels_agree(navion6):
    model, trim = navion6
    data = _maneuver(trim, model.inputs, duration=6.0)
    y_py = simulate(model, data, compiled=False)
    y_nb = simulate(model, data, compiled=True)
    np.testing.assert_allclose(y_nb, y_py, rtol=1e-12, atol=1e-12)


def test_model_builders_check_their_arguments():
    with pytest.raises(InputError, match="unknown output names"):
        lateral_model(navion(), LATERAL_AERO, outputs=("beta", "gamma"))
    with pytest.raises(InputError, match="no lateral outputs"):
        lon, _ = navion_longitudinal_aero()
        wind_axis_longitudinal_model(navion(), lon, outputs=("V", "beta"))
    with pytest.raises(InputError, match="standard signals"):
        lateral_model(navion(), LATERAL_AERO, controls=("da", "beta"))
    with pytest.raises(InputError, match="missing the aerodynamic model's parameters"):
        lateral_model(navion(), LATERAL_AERO, parameters=[("CY_beta", 0.1)])
    with pytest.raises(InputError, match="six_dof_model"):
        trim_level_flight(lateral_model(navion(), LATERAL_AERO), 50.0)
