"""Built-in airplane model extensions (issue 12 item 6), each against an independent
implementation written here:

* 6-DOF with α̇ and β̇ terms, thrust inclination and offset, engine angular momentum and
  propeller torque, |δ| and product terms, ṗ q̇ ṙ outputs: f and h against a vector-form
  reference (rotation matrices, cross products) whose α̇, β̇ are found by fixed-point
  iteration instead of the closed form;
* the wind-axis model with C_mα̇: a trajectory against a reference integrator, and
  output-error recovery of C_mq = −12.5 and C_mα̇ = −7.3 (without the term the estimates
  are the lumped, biased values);
* longitudinal-only airplanes, named parameters, reference speed, and the named errors.
"""

from __future__ import annotations

import math
from pathlib import Path

import numba
import numpy as np
import pytest

from flightid.aircraft import (
    AeroModel,
    Airplane,
    alpha_q_longitudinal_model,
    lateral_model,
    longitudinal_model,
    six_dof_model,
    wind_axis_longitudinal_model,
)
from flightid.aircraft.airplane import AirplaneDataError
from flightid.data.flightdata import FlightData
from flightid.errors import InputError
from flightid.estimation import MNRES
from flightid.estimation.driver import estimate
from flightid.model.terms import TermError, parse_term
from flightid.simulation.simulator import simulate

G = 9.80665
ROOT = Path(__file__).resolve().parents[1]

# --------------------------------------------------------------------------- 6-DOF reference
SIX_DOF_TERMS = {
    "CD": ["1", "alpha", "abs(de)", "de*de", "alpha*de"],
    "CL": ["1", "alpha", "alphadot_hat", "de"],
    "CY": ["beta", "betadot_hat", "dr"],
    "Cl": ["beta", "phat", "da"],
    "Cm": ["1", "alpha", "qhat", "alphadot_hat", "de"],
    "Cn": ["beta", "rhat", "betadot_hat", "dr"],
}
SIX_DOF_VALUES = {
    "CD_0": 0.03, "CD_alpha": 0.3, "CD_abs_de": 0.08, "CD_de2": 0.5, "CD_alpha_de": 0.2,
    "CL_0": 0.3, "CL_alpha": 4.8, "CL_alphadot_hat": 1.7, "CL_de": 0.4,
    "CY_beta": -0.6, "CY_betadot_hat": -0.3, "CY_dr": 0.15,
    "Cl_beta": -0.08, "Cl_phat": -0.45, "Cl_da": 0.12,
    "Cm_0": 0.02, "Cm_alpha": -0.7, "Cm_qhat": -12.5, "Cm_alphadot_hat": -7.3, "Cm_de": -1.1,
    "Cn_beta": 0.09, "Cn_rhat": -0.12, "Cn_betadot_hat": 0.05, "Cn_dr": -0.07,
}  # fmt: skip


def _airplane_6dof():
    return Airplane(
        mass=1300.0, Ix=1500.0, Iy=3000.0, Iz=4000.0, Ixz=150.0, S=17.0, b=10.5, cbar=1.7,
        density=1.1, thrust_input="T", thrust_inclination=0.05, thrust_x=1.5, thrust_z=0.3,
        engine_momentum=85.0, propeller_torque_input="Q", rotation=-1,
    )  # fmt: skip


def _reference_coefficients(V, alpha, beta, p, q, r, adot, bdot, de, da, dr, airplane, c):
    """The coefficients of SIX_DOF_TERMS written out (α̇̂ = α̇ c̄/2V, β̇̂ = β̇ b/2V); c: the
    parameter values by name."""
    b, cbar = airplane.b, airplane.cbar
    ph, qh, rh = p * b / (2 * V), q * cbar / (2 * V), r * b / (2 * V)
    ah, bh = adot * cbar / (2 * V), bdot * b / (2 * V)
    return {
        "CD": c["CD_0"] + c["CD_alpha"] * alpha + c["CD_abs_de"] * abs(de)
        + c["CD_de2"] * de**2 + c["CD_alpha_de"] * alpha * de,
        "CL": c["CL_0"] + c["CL_alpha"] * alpha + c["CL_alphadot_hat"] * ah + c["CL_de"] * de,
        "CY": c["CY_beta"] * beta + c["CY_betadot_hat"] * bh + c["CY_dr"] * dr,
        "Cl": c["Cl_beta"] * beta + c["Cl_phat"] * ph + c["Cl_da"] * da,
        "Cm": c["Cm_0"] + c["Cm_alpha"] * alpha + c["Cm_qhat"] * qh
        + c["Cm_alphadot_hat"] * ah + c["Cm_de"] * de,
        "Cn": c["Cn_beta"] * beta + c["Cn_rhat"] * rh + c["Cn_betadot_hat"] * bh
        + c["Cn_dr"] * dr,
    }  # fmt: skip


def _reference_6dof(state, controls, airplane, values=SIX_DOF_VALUES, lateral=False):
    """Vector form: v̇ = F/m + g n − ω × v, J ω̇ = M − ω × (J ω + h_E), ṅ = n × ω, with
    α̇, β̇ by fixed-point iteration (``lateral``: β̇ = v̇ √(u²+w²)/V², the lateral model's
    rule with u, w measured). Returns (derivative, specific force F/m, ω̇)."""
    de, da, dr, T, Q = controls
    vb, omega, n = state[0:3], state[3:6], state[6:9]
    u, v, w = vb
    V = np.linalg.norm(vb)
    alpha, beta = math.atan2(w, u), math.asin(v / V)
    J = np.array([[airplane.Ix, 0, -airplane.Ixz], [0, airplane.Iy, 0],
                  [-airplane.Ixz, 0, airplane.Iz]])  # fmt: skip
    qbar_s = 0.5 * airplane.rho * V**2 * airplane.S
    sigma = airplane.thrust_inclination
    thrust = T * np.array([math.cos(sigma), 0.0, -math.sin(sigma)])
    r_thrust = np.array([airplane.thrust_x, 0.0, airplane.thrust_z])
    h_engine = np.array([airplane.rotation * airplane.engine_momentum, 0.0, 0.0])
    # stability → body axes: rotation by α about y
    rot = np.array([[math.cos(alpha), 0, -math.sin(alpha)], [0, 1, 0],
                    [math.sin(alpha), 0, math.cos(alpha)]])  # fmt: skip
    adot = bdot = 0.0
    for _ in range(200):
        c = _reference_coefficients(
            V, alpha, beta, *omega, adot, bdot, de, da, dr, airplane, values
        )
        force = qbar_s * rot @ np.array([-c["CD"], c["CY"], -c["CL"]]) + thrust
        moment = qbar_s * np.array(
            [airplane.b * c["Cl"], airplane.cbar * c["Cm"], airplane.b * c["Cn"]]
        )
        moment = moment + np.cross(r_thrust, thrust) - np.cross(omega, h_engine)
        moment[0] -= airplane.rotation * Q
        vdot = force / airplane.mass + G * n - np.cross(omega, vb)
        wdot = np.linalg.solve(J, moment - np.cross(omega, J @ omega))
        # α = atan(w/u), β = asin(v/V) differentiated
        new_adot = (u * vdot[2] - w * vdot[0]) / (u * u + w * w)
        Vdot = vb @ vdot / V
        new_bdot = (vdot[1] * V - v * Vdot) / (V * V * math.cos(beta))
        if lateral:
            new_bdot = vdot[1] * math.hypot(u, w) / V**2
        done = abs(new_adot - adot) + abs(new_bdot - bdot) < 1e-15
        adot, bdot = new_adot, new_bdot
        if done:
            break
    return np.concatenate([vdot, wdot, np.cross(n, omega)]), force / airplane.mass, wdot


def _random_state(rng):
    theta, phi = rng.uniform(-0.4, 0.4), rng.uniform(-0.6, 0.6)
    n = np.array([-math.sin(theta), math.sin(phi) * math.cos(theta),
                  math.cos(phi) * math.cos(theta)])  # fmt: skip
    return np.concatenate(
        [[rng.uniform(40, 70), rng.uniform(-5, 5), rng.uniform(-4, 8)],
         rng.uniform(-0.5, 0.5, 3), n]
    )  # fmt: skip


def test_six_dof_with_rate_terms_engine_and_thrust_offset_matches_the_vector_reference():
    airplane = _airplane_6dof()
    aero = AeroModel(SIX_DOF_TERMS)
    outputs = ("V", "alpha", "beta", "ax", "ay", "az", "pdot", "qdot", "rdot")
    model = six_dof_model(
        airplane, aero, aero.parameters(SIX_DOF_VALUES), controls=("de", "da", "dr"),
        outputs=outputs,
    )  # fmt: skip
    assert model.inputs == ("de", "da", "dr", "T", "Q")
    theta = model.parameters.values
    rng = np.random.default_rng(612)
    for _ in range(25):
        x = _random_state(rng)
        u = np.array([*rng.uniform(-0.15, 0.15, 3), rng.uniform(0, 3000), rng.uniform(0, 900)])
        expected, specific_force, wdot = _reference_6dof(x, u, airplane)
        np.testing.assert_allclose(model.f(0.0, x, u, theta), expected, rtol=1e-10, atol=1e-11)
        y = model.h(0.0, x, u, theta)
        np.testing.assert_allclose(y[3:6], specific_force / G, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(y[6:9], wdot, rtol=1e-10, atol=1e-11)


def test_six_dof_extensions_compile_with_numba():
    """The compiled f (numba) equals the Python f: closures over numeric tables only."""
    airplane = _airplane_6dof()
    aero = AeroModel(SIX_DOF_TERMS)
    model = six_dof_model(airplane, aero, aero.parameters(SIX_DOF_VALUES))
    theta = model.parameters.values
    x = _random_state(np.random.default_rng(1))
    u = np.array([0.05, -0.03, 0.02, 2000.0, 500.0])
    compiled = numba.njit(cache=False)(model.f)
    np.testing.assert_allclose(compiled(0.0, x, u, theta), model.f(0.0, x, u, theta), rtol=1e-13)


def test_engine_terms_and_rate_terms_change_the_motion():
    """Sanity of the reference comparison: each effect is visible (the test above would
    catch a sign error because these differences are large)."""
    airplane = _airplane_6dof()
    aero = AeroModel(SIX_DOF_TERMS)
    model = six_dof_model(airplane, aero, aero.parameters(SIX_DOF_VALUES))
    theta = model.parameters.values
    x = _random_state(np.random.default_rng(3))
    u = np.array([0.05, -0.03, 0.02, 2000.0, 500.0])
    base = model.f(0.0, x, u, theta)
    no_torque = model.f(0.0, x, np.array([0.05, -0.03, 0.02, 2000.0, 0.0]), theta)
    # L_E = −s Q with s = −1: ṗ grows by (I_z Q)/Γ
    gamma = airplane.Ix * airplane.Iz - airplane.Ixz**2
    assert base[3] - no_torque[3] == pytest.approx(airplane.Iz * 500.0 / gamma, rel=1e-10)
    plain = six_dof_model(
        Airplane(**{**_fields(airplane), "engine_momentum": 0.0}), aero, model.parameters
    )
    # −ω × h_E: Δq̇ = −r h_E/I_y with h_E = s I_p Ω = −85
    dq = plain.f(0.0, x, u, theta)[4] - base[4]
    assert dq == pytest.approx(-x[5] * 85.0 / airplane.Iy, rel=1e-9)


def _fields(airplane):
    import dataclasses

    return {f.name: getattr(airplane, f.name) for f in dataclasses.fields(airplane)}


def test_lateral_model_with_betadot_matches_the_reference():
    """The lateral model (u, w, q measured) with C_Yβ̇, C_nβ̇, engine momentum and propeller
    torque against the reference with the lateral β̇ rule."""
    airplane = _airplane_6dof()
    aero = AeroModel({k: SIX_DOF_TERMS[k] for k in ("CY", "Cl", "Cn")})
    values = {**SIX_DOF_VALUES, "CY_betadot_hat": -3.0, "Cn_betadot_hat": 0.5}
    chosen = {k: v for k, v in values.items() if k in aero.parameter_names}
    model = lateral_model(airplane, aero, aero.parameters(chosen), controls=("da", "dr"))
    assert model.inputs == ("da", "dr", "Q", "u", "w", "q")
    rng = np.random.default_rng(46)
    for _ in range(10):
        x6 = _random_state(rng)
        da, dr, Q = rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), rng.uniform(0, 900)
        d, _, _ = _reference_6dof(x6, (0.0, da, dr, 0.0, Q), airplane, values, lateral=True)
        x = x6[[1, 3, 5, 6, 7, 8]]
        u = np.array([da, dr, Q, x6[0], x6[2], x6[4]])
        np.testing.assert_allclose(
            model.f(0.0, x, u, model.parameters.values), d[[1, 3, 5, 6, 7, 8]], rtol=1e-10,
            atol=1e-11,
        )  # fmt: skip


# ------------------------------------------------------------- longitudinal body model, α̇
def test_longitudinal_body_model_with_alphadot_matches_the_reference():
    """The decoupled longitudinal model (v, p, r measured) with C_Lα̇, C_mα̇ against the 6-DOF
    reference at v = p = r = 0 (same u̇, ẇ, q̇)."""
    airplane = _airplane_6dof()
    terms = {k: SIX_DOF_TERMS[k] for k in ("CD", "CL", "Cm")}
    aero = AeroModel(terms)
    values = {k: v for k, v in SIX_DOF_VALUES.items() if k in aero.parameter_names}
    model = longitudinal_model(
        airplane, aero, aero.parameters(values), outputs=("alpha", "qdot", "ax", "az")
    )
    assert model.inputs == ("de", "T", "v", "p", "r")
    # the reference with no lateral coefficients, no engine momentum effect at p = r = 0
    rng = np.random.default_rng(44)
    theta = model.parameters.values
    for _ in range(10):
        x6 = _random_state(rng)
        x6[1] = x6[3] = x6[5] = 0.0
        x6[6:9] = [x6[6], 0.0, math.sqrt(1 - x6[6] ** 2)]
        de, T = rng.uniform(-0.1, 0.1), rng.uniform(0, 3000)
        expected, specific_force, wdot = _reference_6dof(x6, (de, 0, 0, T, 0), airplane)
        x = x6[[0, 2, 4, 6, 7, 8]]
        u = np.array([de, T, 0.0, 0.0, 0.0])
        np.testing.assert_allclose(
            model.f(0.0, x, u, theta), expected[[0, 2, 4, 6, 7, 8]], rtol=1e-10, atol=1e-11
        )
        np.testing.assert_allclose(
            model.h(0.0, x, u, theta)[1:], [wdot[1], *(specific_force[[0, 2]] / G)], rtol=1e-10
        )


def test_wind_model_with_cl_alphadot_matches_the_reference():
    """C_Lα̇ makes dα/dt implicit (α̇ = D0[1]/(1 − D_α[1])); the reference iterates."""
    fields = _fields(_airplane_6dof())
    fields.update(engine_momentum=0.0, propeller_torque_input=None)
    airplane = Airplane(**fields)
    aero = AeroModel({k: SIX_DOF_TERMS[k] for k in ("CD", "CL", "Cm")})
    # C_Lα̇ large, so that the implicit factor 1/(1 − D_α[1]) is far from 1
    values = {**SIX_DOF_VALUES, "CL_alphadot_hat": 25.0}
    chosen = {k: v for k, v in values.items() if k in aero.parameter_names}
    model = wind_axis_longitudinal_model(airplane, aero, aero.parameters(chosen))
    rng = np.random.default_rng(45)
    for _ in range(10):
        V, alpha, th, q = (rng.uniform(40, 70), rng.uniform(-0.1, 0.2),
                           rng.uniform(-0.3, 0.3), rng.uniform(-0.5, 0.5))  # fmt: skip
        de, T = rng.uniform(-0.1, 0.1), rng.uniform(0, 3000)
        x6 = np.array([V * math.cos(alpha), 0.0, V * math.sin(alpha), 0.0, q, 0.0,
                       -math.sin(th), 0.0, math.cos(th)])  # fmt: skip
        d, _, wdot = _reference_6dof(x6, (de, 0, 0, T, 0), airplane, values)
        u, w = x6[0], x6[2]
        # V̇ = (u u̇ + w ẇ)/V, α̇ = (u ẇ − w u̇)/V²
        expected = [(u * d[0] + w * d[2]) / V, (u * d[2] - w * d[0]) / V**2, q, wdot[1]]
        got = model.f(0.0, np.array([V, alpha, th, q]), np.array([de, T]),
                      model.parameters.values)  # fmt: skip
        np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-12)


# ------------------------------------------------------------------ wind-axis model with α̇
HFB_LIKE = dict(mass=7472.0, Iy=91388.8, S=30.097, cbar=2.43, density=0.792, thrust_input="F",
                thrust_inclination=0.0524, thrust_arm=-0.64)  # fmt: skip
TRUTH = {"CD_0": 0.05, "CD_alpha": 0.3, "CL_0": 0.1, "CL_alpha": 4.5, "Cm_0": 0.02,
         "Cm_alpha": -0.8, "Cm_qhat": -12.5, "Cm_alphadot_hat": -7.3, "Cm_de": -1.2}  # fmt: skip
WIND_OUTPUTS = ("V", "alpha", "theta", "q", "qdot", "ax", "az")
X0 = (100.0, 0.07, 0.07, 0.0)


def _wind_model(with_alphadot, values):
    cm = ["1", "alpha", "qhat", "de"] + (["alphadot_hat"] if with_alphadot else [])
    aero = AeroModel({"CD": ["1", "alpha"], "CL": ["1", "alpha"], "Cm": cm})
    chosen = {k: v for k, v in values.items() if k in aero.parameter_names}
    return wind_axis_longitudinal_model(
        Airplane(**HFB_LIKE), aero, aero.parameters(chosen), controls=["de"],
        outputs=WIND_OUTPUTS, accelerometer={"unit": "m/s^2"}, x0=X0,
    )  # fmt: skip


def _inputs(t):
    de = np.full_like(t, -0.02)
    for a, b, sign in [(1, 4, 1), (4, 6, -1), (6, 7, 1), (7, 8, -1), (15, 16, 1), (16, 17, -1)]:
        de[(t >= a) & (t < b)] += 0.04 * sign
    return de, np.full_like(t, 9000.0)


def _reference_wind_rhs(x, de, F, c=TRUTH):
    """HFB-320 README equations plus C_mα̇ α̇ c̄/(2V) (no C_Lα̇ here, so dα/dt is explicit
    and q̇ uses it)."""
    V, alpha, th, q = x
    m, S, cbar, Iy = HFB_LIKE["mass"], HFB_LIKE["S"], HFB_LIKE["cbar"], HFB_LIKE["Iy"]
    sigma, lt = HFB_LIKE["thrust_inclination"], HFB_LIKE["thrust_arm"]
    qbar = 0.5 * HFB_LIKE["density"] * V * V
    cd = c["CD_0"] + c["CD_alpha"] * alpha
    cl = c["CL_0"] + c["CL_alpha"] * alpha
    # α̇ does not enter C_L here, so dα/dt is explicit; q̇ then uses it
    adot = -S / m * qbar * cl / V - F * math.sin(alpha + sigma) / (m * V) + q
    adot += G * math.cos(alpha - th) / V
    cm = c["Cm_0"] + c["Cm_alpha"] * alpha + c["Cm_qhat"] * q * cbar / (2 * V) + c["Cm_de"] * de
    cm += c["Cm_alphadot_hat"] * adot * cbar / (2 * V)
    vdot = -S / m * qbar * cd + F * math.cos(alpha + sigma) / m + G * math.sin(alpha - th)
    qdot = S * cbar / Iy * qbar * cm + lt / Iy * F
    return np.array([vdot, adot, q, qdot])


def test_wind_model_with_alphadot_reproduces_an_independent_trajectory():
    """RK4 at the sample interval with the mid-step input the mean of the neighbours, as the
    simulator (README "The standard cases, precisely")."""
    t = np.arange(0.0, 10.0, 0.05)
    de, F = _inputs(t)
    model = _wind_model(True, TRUTH)
    y = simulate(model, FlightData(t, {"de": de, "F": F}), compiled=False)
    x = np.array(X0)
    states = [x]
    dt = t[1] - t[0]
    for k in range(len(t) - 1):
        dm, fm = 0.5 * (de[k] + de[k + 1]), 0.5 * (F[k] + F[k + 1])
        k1 = _reference_wind_rhs(x, de[k], F[k])
        k2 = _reference_wind_rhs(x + 0.5 * dt * k1, dm, fm)
        k3 = _reference_wind_rhs(x + 0.5 * dt * k2, dm, fm)
        k4 = _reference_wind_rhs(x + dt * k3, de[k + 1], F[k + 1])
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        states.append(x)
    states = np.array(states)
    np.testing.assert_allclose(y[:, :4], states, rtol=1e-10, atol=1e-12)
    qdot = np.array(
        [_reference_wind_rhs(s, a, b)[3] for s, a, b in zip(states, de, F, strict=True)]
    )
    np.testing.assert_allclose(y[:, 4], qdot, rtol=1e-9, atol=1e-12)
    # the α̇ term matters: without it q̇ differs by C_mα̇ α̇ c̄/(2V) q̄ S c̄/I_y
    plain = simulate(_wind_model(False, TRUTH), FlightData(t, {"de": de, "F": F}), compiled=False)
    assert np.max(np.abs(plain[:, 4] - y[:, 4])) > 0.01


@pytest.fixture(scope="module")
def alphadot_data():
    t = np.arange(0.0, 20.0, 0.05)
    de, F = _inputs(t)
    y = simulate(_wind_model(True, TRUTH), FlightData(t, {"de": de, "F": F}), compiled=False)
    rng = np.random.default_rng(5)
    sigma = np.array([0.1, 0.001, 0.001, 0.001, 0.005, 0.02, 0.05])
    noisy = y + rng.normal(size=y.shape) * sigma
    return FlightData(t, {"de": de, "F": F}, dict(zip(WIND_OUTPUTS, noisy.T, strict=True)))


def test_alphadot_term_recovers_cmq_and_cmalphadot(alphadot_data):
    """Truth C_mq = −12.5, C_mα̇ = −7.3 (simulated, seeded noise); start +20 %."""
    start = {k: 1.2 * v for k, v in TRUTH.items()}
    est = estimate(_wind_model(True, start), alphadot_data, MNRES())
    assert est.converged
    for name, truth in TRUTH.items():
        assert abs(est.value(name) - truth) < 3 * est.stddev(name), name
    # measured at ebbf382 (docs/aircraft.md): C_mq −12.487 ± 0.041, C_mα̇ −7.322 ± 0.057
    assert est.value("Cm_qhat") == pytest.approx(-12.5, abs=0.1)
    assert est.value("Cm_alphadot_hat") == pytest.approx(-7.3, abs=0.2)


def test_without_alphadot_the_estimates_are_lumped(alphadot_data):
    start = {k: 1.2 * v for k, v in TRUTH.items()}
    est = estimate(_wind_model(False, start), alphadot_data, MNRES())
    assert est.converged
    # C_mq absorbs part of C_mα̇ (measured −15.17 ± 0.07): far outside its CR bound
    assert est.value("Cm_qhat") < -13.0
    assert abs(est.value("Cm_qhat") + 12.5) > 10 * est.stddev("Cm_qhat", std="cr")


# ---------------------------------------------------------------------- thrust moment arm
def test_thrust_point_and_arm_give_the_same_pitching_moment():
    aero = AeroModel({"CD": ["1"], "CL": ["1"], "Cm": ["1"]})
    params = aero.parameters({"CD_0": 0.03, "CL_0": 0.4, "Cm_0": 0.01})
    sigma, x_t, z_t = 0.07, 2.0, -0.5
    common = {k: v for k, v in HFB_LIKE.items() if k not in ("thrust_arm",)}
    common["thrust_inclination"] = sigma
    by_point = Airplane(**common, thrust_x=x_t, thrust_z=z_t)
    # M_T = z_T X_T − x_T Z_T = T (z_T cos σ + x_T sin σ)
    arm = z_t * math.cos(sigma) + x_t * math.sin(sigma)
    by_arm = Airplane(**common, thrust_arm=arm)
    x, u = np.array([100.0, 0.05, 0.05, 0.0]), np.array([10000.0])
    outs = ("qdot",)
    m1 = wind_axis_longitudinal_model(by_point, aero, params, outputs=outs)
    m2 = wind_axis_longitudinal_model(by_arm, aero, params, outputs=outs)
    zero = wind_axis_longitudinal_model(Airplane(**common), aero, params, outputs=outs)
    theta = params.values
    q1 = m1.h(0.0, x, u, theta)[0]
    assert q1 == pytest.approx(m2.h(0.0, x, u, theta)[0], rel=1e-13)
    assert q1 - zero.h(0.0, x, u, theta)[0] == pytest.approx(
        arm * 10000.0 / common["Iy"], rel=1e-12
    )
    with pytest.raises(InputError, match="thrust_arm: give the thrust moment arm"):
        Airplane(**common, thrust_arm=arm, thrust_z=1.0)


# ----------------------------------------------------------------- longitudinal-only airplane
LONG_ONLY = dict(mass=1000.0, Iy=2000.0, S=10.0, cbar=1.5, density=1.2)


def test_longitudinal_only_airplane_builds_the_longitudinal_models():
    airplane = Airplane(**LONG_ONLY)
    assert airplane.longitudinal_only
    aero = AeroModel({"CD": ["1", "alpha"], "CL": ["1", "alpha"], "Cm": ["1", "alpha", "qhat"]})
    params = aero.parameters({"CL_alpha": 5.0, "Cm_alpha": -0.8, "Cm_qhat": -10.0})
    wind = wind_axis_longitudinal_model(airplane, aero, params)
    body = longitudinal_model(airplane, aero, params, outputs=("alpha", "q", "qdot"))
    x = np.array([50.0, 0.1, 0.1, 0.05])
    # same q̇ from both forms (symmetric flight, p = r = 0 inputs of the body model)
    xb = np.array([50 * math.cos(0.1), 50 * math.sin(0.1), 0.05, -math.sin(0.1), 0.0,
                   math.cos(0.1)])  # fmt: skip
    qdot_body = body.h(0.0, xb, np.zeros(3), params.values)[2]
    assert qdot_body == pytest.approx(wind.f(0.0, x, np.zeros(0), params.values)[3], rel=1e-12)
    cz = AeroModel({"CZ": ["1", "alpha"], "Cm": ["1", "alpha"]})
    alpha_q_longitudinal_model(airplane, cz, cz.parameters())


@pytest.mark.parametrize(
    ("build", "terms", "message"),
    [
        (lateral_model, {"CY": ["beta"]}, r"the lateral model needs \['Ix', 'Iz', 'b'\]"),
        (six_dof_model, {"CY": ["beta"]}, r"the 6-DOF model needs \['Ix', 'Iz', 'b'\]"),
        (wind_axis_longitudinal_model, {"Cm": ["phat"]}, r"terms in \['phat'\] needs \['b'\]"),
    ],
)
def test_longitudinal_only_airplane_named_errors(build, terms, message):
    aero = AeroModel(terms)
    with pytest.raises(AirplaneDataError, match=message):
        build(Airplane(**LONG_ONLY), aero)


def test_airplane_missing_fields_named():
    with pytest.raises(AirplaneDataError, match="Airplane.S: missing"):
        Airplane(mass=1.0, Iy=1.0, cbar=1.0)
    with pytest.raises(AirplaneDataError, match="give both or neither"):
        Airplane(**LONG_ONLY, Ix=100.0)
    with pytest.raises(AirplaneDataError, match="Γ"):
        _ = Airplane(**LONG_ONLY).gamma


# ------------------------------------------------- reference speed, named parameters, errors
def test_reference_speed_terms_and_rate_speed():
    airplane = Airplane(**LONG_ONLY)
    aero = AeroModel({"CD": {"CD0": "1", "CDV": "Vrel"}, "CL": {"CL0": "1", "CLV": "dVrel"},
                      "Cm": {"Cmq": "qhat"}})  # fmt: skip
    assert aero.parameter_names == ["CD0", "CDV", "CL0", "CLV", "Cmq"]
    params = aero.parameters({"CD0": 0.0, "CDV": 0.1, "CL0": 0.0, "CLV": 0.2, "Cmq": -10.0})
    with pytest.raises(InputError, match="need the reference speed V0"):
        wind_axis_longitudinal_model(airplane, aero, params)
    v0 = 40.0
    outs = ("ax", "az", "qdot")
    fixed = wind_axis_longitudinal_model(
        airplane, aero, params, outputs=outs, reference_speed=v0, rate_speed="V0"
    )
    local = wind_axis_longitudinal_model(airplane, aero, params, outputs=outs, reference_speed=v0)
    V, alpha, q = 50.0, 0.0, 0.2
    x = np.array([V, alpha, 0.0, q])
    ax, az, qdot = fixed.h(0.0, x, np.zeros(0), params.values)
    qbar_s = 0.5 * 1.2 * V * V * 10.0
    # at α = 0: a_x = −q̄S C_D/(m g), a_z = −q̄S C_L/(m g), C_D = 0.1 V/V0, C_L = 0.2 (V−V0)/V0
    assert ax == pytest.approx(-qbar_s * 0.1 * V / v0 / (1000.0 * G), rel=1e-12)
    assert az == pytest.approx(-qbar_s * 0.2 * (V - v0) / v0 / (1000.0 * G), rel=1e-12)
    # q̂ = q c̄/(2 V0) with rate_speed = "V0", q c̄/(2V) by default
    assert qdot == pytest.approx(qbar_s * 1.5 * -10.0 * q * 1.5 / (2 * v0) / 2000.0, rel=1e-12)
    assert local.h(0.0, x, np.zeros(0), params.values)[2] == pytest.approx(qdot * v0 / V)


def test_named_parameters_and_their_errors():
    aero = AeroModel({"CD": {"CD0": "1", "CDde": "abs(de)"}, "Cm": ["1", "de"]})
    assert aero.parameter_names == ["CD0", "CDde", "Cm_0", "Cm_de"]
    assert (aero + AeroModel({"CY": ["beta"]})).parameter_names[:2] == ["CD0", "CDde"]
    with pytest.raises(InputError, match="used twice"):
        AeroModel({"CD": {"X": "1"}, "CL": {"X": "alpha"}})
    with pytest.raises(InputError, match="identifiers"):
        AeroModel({"CD": {"C D": "1"}})


def test_abs_term_parses_and_evaluates():
    term = parse_term("abs(de)*alpha")
    assert term.label == "abs(de)*alpha" and term.identifier == "abs_de_alpha"
    np.testing.assert_allclose(
        term.evaluate({"de": np.array([-0.1, 0.2]), "alpha": np.array([2.0, 3.0])}), [0.2, 0.6]
    )
    with pytest.raises(TermError, match="abs"):
        parse_term("abs(de")


@pytest.mark.parametrize(
    ("build", "terms", "message"),
    [
        (lateral_model, {"CY": ["alphadot_hat"]}, "alphadot_hat terms need the model's own"),
        (wind_axis_longitudinal_model, {"Cm": ["betadot_hat"]}, "betadot_hat terms need"),
        (six_dof_model, {"Cm": ["alphadot_hat^2"]}, "must enter linearly"),
        (six_dof_model, {"Cm": ["abs(alphadot_hat)"]}, "must enter linearly"),
    ],
)
def test_rate_terms_named_errors(build, terms, message):
    airplane = _airplane_6dof()
    with pytest.raises(InputError, match=message):
        build(airplane, AeroModel(terms))


def test_decoupled_models_refuse_the_other_axis_accelerations():
    airplane = _airplane_6dof()
    with pytest.raises(InputError, match="no output"):
        longitudinal_model(airplane, AeroModel({"Cm": ["1"]}), outputs=("pdot",))
    with pytest.raises(InputError, match="no output"):
        lateral_model(airplane, AeroModel({"Cl": ["1"]}), outputs=("qdot",))


# ------------------------------------------------------------------------- case-file keys
def _builtin_case(tmp_path, old, new):
    from flightid.cases import load_case

    text = (ROOT / "examples/cases/hfb320_longitudinal_builtin.toml").read_text()
    assert old in text
    path = tmp_path / "case.toml"
    path.write_text(text.replace(old, new))
    return load_case(path)


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("reference_speed = 104.67", "reference_speed = -1.0", "reference_speed: expected V0"),
        ('rate_speed = "V0"', 'rate_speed = "U"', "rate_speed: expected 'V'"),
        ("reference_speed = 104.67", "", "need the reference speed V0"),
        ('CDa = "alpha" }', "CDa = 1 }", "model.aero.CD: expected a list of terms"),
        ("Iy = 91388.79", "Ix = 1.0\nIy = 91388.79", "give both or neither"),
    ],
)
def test_case_file_model_keys_named_errors(tmp_path, old, new, message):
    from flightid.cases.build import base_model
    from flightid.cases.spec import CaseError

    case = _builtin_case(tmp_path, old, new)
    with pytest.raises(CaseError, match=message):
        base_model(case)
