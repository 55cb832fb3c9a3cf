"""flightid.aircraft's equations of motion against a second, independent rigid-body model.

The reference below is written from the textbook vector form (Stevens & Lewis, *Aircraft
Control and Simulation*, 3rd ed., eqs. 1.7-18 / 1.7-19; Etkin & Reid §4.7), body axes, flat
non-rotating earth, XZ plane of symmetry, I_xz ≠ 0:

    m (dv/dt + ω × v) = F + m g_b            (translational, v = (u, v, w), ω = (p, q, r))
    J dω/dt + ω × (J ω) = M_b                (rotational, J = [[I_x, 0, −I_xz],
                                                              [0, I_y, 0], [−I_xz, 0, I_z]])
    dn/dt = −ω × n                           (n = unit local vertical in body axes, fixed in
                                              the earth frame: Poisson's equation)

solved with numpy (cross products, ``np.linalg.solve``) instead of the scalar Γ formulas the
code uses. The attitude comes from Euler angles through rotation matrices, g_b = g·n with
n = C_bn (0, 0, 1). Aerodynamic forces are built as vectors: drag along −x_s and lift along
−z_s of the stability axes, x_s the unit vector of the velocity's projection on the XZ plane,
z_s = x_s × y_b; thrust along (cos α_T, 0, −sin α_T). Forces and moments are given directly
(random numbers, or constant aerodynamic coefficients) so the aerodynamic model is not what
is under test. States, inputs and inertias are random (seeded).

Each sign error in the code's cross-coupling terms or force resolution changes the compared
derivatives by O(1) at these states (issue 10 §6: before this file, each was caught by a
single test, and the decoupled-vs-6-DOF and body-vs-wind tests compared the code with itself).
"""

from __future__ import annotations

import numpy as np
import pytest

from flightid.aircraft import (
    AeroModel,
    Airplane,
    lateral_model,
    longitudinal_model,
    six_dof_model,
    wind_axis_longitudinal_model,
)
from flightid.aircraft.equations import (
    CONSTANTS,
    forces_and_moments,
    rigid_body_derivatives,
    wind_axis_derivatives,
)

G = 9.80665
N_DRAWS = 40


# ---------------------------------------------------------------- the independent model
def _rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])


def _rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])


def _rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def vertical_in_body(theta, phi, psi):
    """n = C_bn (0, 0, 1), C_bn = R_x(Φ) R_y(Θ) R_z(Ψ) (3-2-1 Euler sequence)."""
    return _rot_x(phi) @ _rot_y(theta) @ _rot_z(psi) @ np.array([0.0, 0.0, 1.0])


def inertia_matrix(ix, iy, iz, ixz):
    return np.array([[ix, 0.0, -ixz], [0.0, iy, 0.0], [-ixz, 0.0, iz]])


def reference_derivatives(state, force, moment, mass, inertia, g=G):
    """d/dt (u, v, w, p, q, r, n_x, n_y, n_z) from the vector equations above."""
    vel, omega, n = state[0:3], state[3:6], state[6:9]
    vel_dot = force / mass + g * n - np.cross(omega, vel)
    omega_dot = np.linalg.solve(inertia, moment - np.cross(omega, inertia @ omega))
    n_dot = -np.cross(omega, n)
    return np.concatenate([vel_dot, omega_dot, n_dot])


def reference_loads(state, coeffs, thrust, airplane):
    """Body-axis force and moment from coefficient values (body and stability axes) and thrust.

    coeffs: mapping with any of CX, CY, CZ, CD, CL, Cl, Cm, Cn (absent ones are zero).
    """
    c = {k: 0.0 for k in ("CX", "CY", "CZ", "CD", "CL", "Cl", "Cm", "Cn")} | dict(coeffs)
    vel = state[0:3]
    speed = np.linalg.norm(vel)
    qbar_s = 0.5 * airplane.rho * speed**2 * airplane.S
    y_b = np.array([0.0, 1.0, 0.0])
    x_s = np.array([vel[0], 0.0, vel[2]]) / np.hypot(vel[0], vel[2])
    z_s = np.cross(x_s, y_b)
    aero = qbar_s * (np.array([c["CX"], c["CY"], c["CZ"]]) - c["CD"] * x_s - c["CL"] * z_s)
    a_t = airplane.thrust_inclination
    force = aero + thrust * np.array([np.cos(a_t), 0.0, -np.sin(a_t)])
    moment = qbar_s * np.array(
        [airplane.b * c["Cl"], airplane.cbar * c["Cm"], airplane.b * c["Cn"]]
    )
    return force, moment


# ---------------------------------------------------------------- random draws (seeded)
def _airplane(rng):
    ix, iy, iz = rng.uniform(1500, 2500), rng.uniform(2500, 4000), rng.uniform(4000, 6000)
    return Airplane(
        mass=rng.uniform(900.0, 1800.0),
        Ix=ix,
        Iy=iy,
        Iz=iz,
        Ixz=rng.choice([-1.0, 1.0]) * rng.uniform(100.0, 600.0),
        S=17.0,
        b=10.5,
        cbar=1.7,
        density=rng.uniform(0.9, 1.2),
        thrust_input="thrust",
        thrust_inclination=rng.uniform(-0.1, 0.1),
    )


def _state(rng):
    """Random body state with the attitude from random Euler angles (Ψ too: it must not
    matter)."""
    uvw = np.array([rng.uniform(30.0, 80.0), rng.uniform(-8.0, 8.0), rng.uniform(-10.0, 10.0)])
    pqr = rng.uniform(-1.0, 1.0, 3)
    angles = rng.uniform(-0.6, 0.6), rng.uniform(-1.2, 1.2), rng.uniform(-np.pi, np.pi)
    return np.concatenate([uvw, pqr, vertical_in_body(*angles)]), angles


def _constants(airplane):
    values = {
        "mass": airplane.mass, "Ix": airplane.Ix, "Iy": airplane.Iy, "Iz": airplane.Iz,
        "Ixz": airplane.Ixz, "S": airplane.S, "b": airplane.b, "cbar": airplane.cbar,
        "rho": airplane.rho, "g": airplane.g, "alpha_T": airplane.thrust_inclination,
    }  # fmt: skip
    return np.array([values[name] for name in CONSTANTS])


def _inertia(airplane):
    return inertia_matrix(airplane.Ix, airplane.Iy, airplane.Iz, airplane.Ixz)


def test_reference_model_is_itself_sound():
    """Checks of the reference, so that agreement with it means something: torque-free motion
    conserves |J ω| and ½ ωᵀJω; the vertical stays a unit vector; a body at rest in vacuum
    falls at g along n."""
    rng = np.random.default_rng(1)
    airplane = _airplane(rng)
    inertia = _inertia(airplane)
    state, _ = _state(rng)
    d = reference_derivatives(state, np.zeros(3), np.zeros(3), airplane.mass, inertia)
    omega, omega_dot = state[3:6], d[3:6]
    # d/dt ½ ωᵀJω = ωᵀ J ω̇ = 0,  d/dt |Jω|² = 2 (Jω)ᵀ J ω̇ = 0 (torque free)
    assert abs(omega @ inertia @ omega_dot) < 1e-12 * np.abs(omega) @ inertia @ np.abs(omega)
    assert abs((inertia @ omega) @ (inertia @ omega_dot)) < 1e-9
    assert abs(state[6:9] @ d[6:9]) < 1e-15  # d|n|²/dt = 0
    rest = np.concatenate([np.zeros(6), state[6:9]])
    d = reference_derivatives(rest, np.zeros(3), np.zeros(3), airplane.mass, inertia)
    np.testing.assert_allclose(d[0:3], G * state[6:9], rtol=1e-15)


def test_rigid_body_derivatives_match_the_reference_at_random_states():
    rng = np.random.default_rng(20261123)
    for _ in range(N_DRAWS):
        airplane = _airplane(rng)
        state, _ = _state(rng)
        force = rng.uniform(-5000.0, 5000.0, 3)  # N
        moment = rng.uniform(-3000.0, 3000.0, 3)  # N·m
        expected = reference_derivatives(state, force, moment, airplane.mass, _inertia(airplane))
        got = rigid_body_derivatives(state, np.concatenate([force, moment]), _constants(airplane))
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("axes", ["body", "stability"])
def test_forces_and_moments_match_the_vector_resolution(axes):
    rng = np.random.default_rng(7 if axes == "body" else 8)
    names = ("CX", "CY", "CZ") if axes == "body" else ("CD", "CL", "CY")
    for _ in range(N_DRAWS):
        airplane = _airplane(rng)
        state, _ = _state(rng)
        coeffs = dict(zip(names + ("Cl", "Cm", "Cn"), rng.uniform(-0.5, 0.5, 6), strict=True))
        thrust = rng.uniform(0.0, 4000.0)
        force, moment = reference_loads(state, coeffs, thrust, airplane)
        speed = np.linalg.norm(state[0:3])
        alpha = np.arctan2(state[2], state[0])
        c_vector = np.array([coeffs.get(k, 0.0) for k in ("CX", "CY", "CZ", "CD", "CL")] +
                            [coeffs["Cl"], coeffs["Cm"], coeffs["Cn"]])  # fmt: skip
        got = forces_and_moments(c_vector, alpha, speed, thrust, _constants(airplane))
        np.testing.assert_allclose(got, np.concatenate([force, moment]), rtol=1e-12, atol=1e-9)


def _constant_aero(names, rng):
    aero = AeroModel({name: ["1"] for name in names})
    values = dict(zip(names, rng.uniform(-0.4, 0.4, len(names)), strict=True))
    parameters = aero.parameters({f"{name}_0": value for name, value in values.items()})
    return aero, parameters, values


@pytest.mark.parametrize(
    "names", [("CX", "CY", "CZ", "Cl", "Cm", "Cn"), ("CD", "CL", "CY", "Cl", "Cm", "Cn")]
)
def test_six_dof_model_f_and_h_match_the_reference(names):
    """The assembled model (signals, q̄, coefficients, forces, equations, outputs) with constant
    aerodynamic coefficients, so the forces are known in closed form."""
    rng = np.random.default_rng(31 if names[0] == "CX" else 32)
    for _ in range(N_DRAWS // 2):
        airplane = _airplane(rng)
        aero, parameters, coeffs = _constant_aero(names, rng)
        model = six_dof_model(airplane, aero, parameters)
        assert model.inputs == ("thrust",)
        state, (theta, phi, _) = _state(rng)
        thrust = rng.uniform(0.0, 4000.0)
        force, moment = reference_loads(state, coeffs, thrust, airplane)
        expected = reference_derivatives(state, force, moment, airplane.mass, _inertia(airplane))
        theta_vec = model.parameters.values
        got = model.f(0.0, state, np.array([thrust]), theta_vec)
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)
        # outputs: textbook definitions [2.19–2.26]; accelerometers sense specific force
        # (dv/dt + ω × v − g_b)/g, in g
        vel, omega = state[0:3], state[3:6]
        speed = np.linalg.norm(vel)
        specific = (expected[0:3] + np.cross(omega, vel) - G * state[6:9]) / G
        y = dict(zip(model.outputs, model.h(0.0, state, np.array([thrust]), theta_vec),
                     strict=True))  # fmt: skip
        reference = {
            "V": speed, "alpha": np.arctan2(vel[2], vel[0]), "beta": np.arcsin(vel[1] / speed),
            "theta": theta, "phi": phi, "ax": specific[0], "ay": specific[1],
            "az": specific[2], "p": omega[0], "q": omega[1], "r": omega[2],
        }  # fmt: skip
        for name, value in reference.items():
            assert y[name] == pytest.approx(value, rel=1e-11, abs=1e-11), name


def test_decoupled_models_match_the_reference():
    """Longitudinal and lateral models, the other axis's motion given as inputs, against the
    reference's entries for the states they keep (not against the code's own 6-DOF)."""
    rng = np.random.default_rng(41)
    names = ("CD", "CL", "CY", "Cl", "Cm", "Cn")
    for _ in range(N_DRAWS // 2):
        airplane = _airplane(rng)
        aero, parameters, coeffs = _constant_aero(names, rng)
        state, _ = _state(rng)
        thrust = rng.uniform(0.0, 4000.0)
        force, moment = reference_loads(state, coeffs, thrust, airplane)
        expected = reference_derivatives(state, force, moment, airplane.mass, _inertia(airplane))
        full = dict(zip(("u", "v", "w", "p", "q", "r", "l_xz", "l_yz", "l_zz"), state,
                        strict=True)) | {"thrust": thrust}  # fmt: skip
        for build in (longitudinal_model, lateral_model):
            model = build(airplane, aero, parameters)
            index = [("u", "v", "w", "p", "q", "r", "l_xz", "l_yz", "l_zz").index(s)
                     for s in model.states]  # fmt: skip
            x = state[index]
            u = np.array([full[name] for name in model.inputs])
            got = model.f(0.0, x, u, model.parameters.values)
            np.testing.assert_allclose(got, expected[index], rtol=1e-12, atol=1e-12,
                                       err_msg=model.name)  # fmt: skip


def test_wind_axis_form_matches_the_reference():
    """V̇ = (u u̇ + w ẇ)/V, α̇ = (u ẇ − w u̇)/(u² + w²), Θ̇ = q, q̇ from the reference, in
    symmetric flight (β = Φ = p = r = 0), for wind_axis_derivatives and the assembled model."""
    rng = np.random.default_rng(51)
    names = ("CD", "CL", "Cm")
    for _ in range(N_DRAWS // 2):
        airplane = _airplane(rng)
        aero, parameters, coeffs = _constant_aero(names, rng)
        speed, alpha = rng.uniform(30.0, 80.0), rng.uniform(-0.3, 0.3)
        theta, q = rng.uniform(-0.6, 0.6), rng.uniform(-1.0, 1.0)
        u, w = speed * np.cos(alpha), speed * np.sin(alpha)
        state = np.array([u, 0.0, w, 0.0, q, 0.0, *vertical_in_body(theta, 0.0, 0.3)])
        thrust = rng.uniform(0.0, 4000.0)
        force, moment = reference_loads(state, coeffs, thrust, airplane)
        d = reference_derivatives(state, force, moment, airplane.mass, _inertia(airplane))
        expected = [
            (u * d[0] + w * d[2]) / speed,
            (u * d[2] - w * d[0]) / (u * u + w * w),
            q,
            d[4],
        ]
        got = wind_axis_derivatives(
            speed, alpha, theta, q, np.concatenate([force, moment]), _constants(airplane)
        )
        np.testing.assert_allclose(got, expected, rtol=1e-11, atol=1e-12)
        model = wind_axis_longitudinal_model(airplane, aero, parameters)
        x = np.array([speed, alpha, theta, q])
        got = model.f(0.0, x, np.array([thrust]), model.parameters.values)
        np.testing.assert_allclose(got, expected, rtol=1e-11, atol=1e-12)
