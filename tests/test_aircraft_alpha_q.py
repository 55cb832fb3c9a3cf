"""The α–q model kind of flightid.aircraft (``alpha_q_longitudinal_model``) and the case
adapter built on it (``flightid.cases.alpha_q.alpha_q_model``) against an independent numpy
implementation of the α–q equations.

The reference below does not restate the code's α̇ line: it builds u = V cos α, w = V sin α,
takes u̇ and ẇ from the body-axis force equations (RP-1153 2.5, 2.7 with v = 0, the attitude
as l_xz = −sin Θ, l_zz = cos Φ cos Θ, X/m = g a_x measured, Z = q̄ S C_Z) and forms
α̇ = (u ẇ − w u̇)/V²; q̇ is the y row of the vector moment equation J ω̇ + ω × (J ω) = M with
J = [[I_x, 0, −I_xz], [0, I_y, 0], [−I_xz, 0, I_z]] (np.cross), M = q̄ S c̄ C_m; a_z = Z/(m g).
C_Z and C_m are written term by term from their signals. States, inputs, constants and
parameters are random (seeded).
"""

from __future__ import annotations

import numba
import numpy as np
import pytest

from flightid.aircraft import (
    ALPHA_Q_INPUTS,
    AeroModel,
    Airplane,
    alpha_q_longitudinal_model,
)
from flightid.cases.alpha_q import alpha_q_model, structure_from_terms
from flightid.errors import InputError
from flightid.model.parameters import Parameter, Parameters

N_DRAWS = 30

# the α–q structure under test: constant, state, q̂, control, power, product and spline terms
TERMS = {
    "CZ": ["1", "alpha", "qhat", "de", "alpha^2", "alpha*de"],
    "Cm": ["1", "alpha", "qhat", "de", "alpha*qhat", "theta", "spline1(alpha,0.1)"],
}
# the same terms for the reference: parameter name → regressor from the signals
REGRESSORS = {
    "CZ_0": lambda s: 1.0,
    "CZ_alpha": lambda s: s["alpha"],
    "CZ_qhat": lambda s: s["qhat"],
    "CZ_de": lambda s: s["de"],
    "CZ_alpha2": lambda s: s["alpha"] ** 2,
    "CZ_alpha_de": lambda s: s["alpha"] * s["de"],
    "Cm_0": lambda s: 1.0,
    "Cm_alpha": lambda s: s["alpha"],
    "Cm_qhat": lambda s: s["qhat"],
    "Cm_de": lambda s: s["de"],
    "Cm_alpha_qhat": lambda s: s["alpha"] * s["qhat"],
    "Cm_theta": lambda s: s["theta"],
    # (α − 0.1)₊
    "Cm_alpha_s0p1": lambda s: max(s["alpha"] - 0.1, 0.0),
}


def reference(x, u, values, c):
    """(d(α, q)/dt, (α, q, a_z in g)) of the α–q model, independent form (module docstring).

    x = (α, q); u = (V, q̄, Θ, Φ, a_x, p, r, de); values: parameters by name; c: constants.
    """
    alpha, q = x
    V, qbar, theta, phi, ax, p, r, de = u
    signals = {"alpha": alpha, "qhat": q * c["cbar"] / (2 * V), "de": de, "theta": theta}
    cz = sum(values[n] * f(signals) for n, f in REGRESSORS.items() if n.startswith("CZ_"))
    cm = sum(values[n] * f(signals) for n, f in REGRESSORS.items() if n.startswith("Cm_"))
    m, g = c["mass"], c["g"]
    Z = qbar * c["S"] * cz
    # body velocity (v = 0) and direction cosines of the local vertical
    bu, bw = V * np.cos(alpha), V * np.sin(alpha)
    l_xz, l_zz = -np.sin(theta), np.cos(phi) * np.cos(theta)
    # u̇ = −q w + g l_xz + X/m, ẇ = q u + g l_zz + Z/m  (v = 0), with X/m = g a_x
    du = -q * bw + g * l_xz + g * ax
    dw = q * bu + g * l_zz + Z / m
    dalpha = (bu * dw - bw * du) / V**2
    # J ω̇ = M − ω × (J ω), y row
    J = np.array([[c["Ix"], 0.0, -c["Ixz"]], [0.0, c["Iy"], 0.0], [-c["Ixz"], 0.0, c["Iz"]]])
    omega = np.array([p, q, r])
    moment = qbar * c["S"] * c["cbar"] * cm
    dq = (moment - np.cross(omega, J @ omega)[1]) / c["Iy"]
    return np.array([dalpha, dq]), np.array([alpha, q, Z / (m * g)])


def _draw(rng):
    """Random constants, parameters, state and inputs (seeded generator)."""
    c = {
        "mass": rng.uniform(200.0, 5000.0),
        "S": rng.uniform(10.0, 500.0),
        "cbar": rng.uniform(1.0, 8.0),
        "Ix": rng.uniform(1e3, 1e5),
        "Iy": rng.uniform(1e3, 1e5),
        "Iz": rng.uniform(1e3, 1e5),
        "g": rng.choice([9.80665, 32.174]),
    }
    c["Ixz"] = rng.uniform(-0.3, 0.3) * min(c["Ix"], c["Iz"])
    values = {name: rng.normal(0.0, 2.0) for name in REGRESSORS}
    x = np.array([rng.uniform(-0.3, 0.4), rng.uniform(-0.6, 0.6)])
    u = np.array(
        [
            rng.uniform(30.0, 300.0),  # V
            rng.uniform(500.0, 8000.0),  # q̄
            rng.uniform(-0.5, 0.5),  # Θ
            rng.uniform(-0.8, 0.8),  # Φ
            rng.uniform(-0.3, 0.3),  # a_x, g
            rng.uniform(-1.0, 1.0),  # p
            rng.uniform(-1.0, 1.0),  # r
            rng.uniform(-0.3, 0.3),  # de
        ]
    )
    return c, values, x, u


def _aircraft_model(c, values, **options):
    airplane = Airplane(
        mass=c["mass"], Ix=c["Ix"], Iy=c["Iy"], Iz=c["Iz"], Ixz=c["Ixz"], S=c["S"],
        b=2.0 * c["cbar"], cbar=c["cbar"], g=c["g"],
    )  # fmt: skip
    aero = AeroModel(TERMS)
    return alpha_q_longitudinal_model(airplane, aero, aero.parameters(values), **options)


def test_the_model_is_shaped_as_documented():
    model = _aircraft_model(_draw(np.random.default_rng(0))[0], {})
    assert model.states == ("alpha", "q")
    assert (
        model.inputs
        == (*ALPHA_Q_INPUTS, "de")
        == ("V", "qbar", "theta", "phi", "ax", "p", "r", "de")
    )
    assert model.outputs == ("alpha", "q", "az")
    # NASA names, the ones a stepwise case reports (flightid.regression.pipeline.parameter_name)
    assert model.parameters.names[:3] == ["CZ_0", "CZ_alpha", "CZ_qhat"]
    assert {"Cm_alpha", "Cm_alpha_qhat", "Cm_alpha_s0p1"} <= set(model.parameters.names)


@pytest.mark.parametrize("compiled", [False, True], ids=["python", "numba"])
def test_aircraft_alpha_q_matches_the_independent_equations(compiled):
    rng = np.random.default_rng(20261123)
    # numba: 3 compiled models (one per set of constants), 10 states, inputs, parameters each
    for _ in range(3 if compiled else N_DRAWS):
        c, values, _, _ = _draw(rng)
        model = _aircraft_model(c, values)
        f, h = (numba.njit(model.f), numba.njit(model.h)) if compiled else (model.f, model.h)
        for _ in range(10 if compiled else 1):
            _, values, x, u = _draw(rng)
            theta = np.array([values[n] for n in model.parameters.names])
            dx, y = reference(x, u, values, c)
            np.testing.assert_allclose(f(0.0, x, u, theta), dx, rtol=1e-11, atol=1e-12)
            np.testing.assert_allclose(h(0.0, x, u, theta), y, rtol=1e-11, atol=1e-12)


def test_case_adapter_matches_the_independent_equations():
    rng = np.random.default_rng(11)
    structure = structure_from_terms(TERMS)
    for _ in range(10):
        c, values, x, u = _draw(rng)
        parameters = Parameters([Parameter(n, v) for n, v in values.items()])
        model = alpha_q_model(structure, parameters, **c)
        assert model.name == "alpha_q_longitudinal" and model.initial_state().tolist() == [0, 0]
        dx, y = reference(x, u, values, c)
        theta = model.parameters.values
        np.testing.assert_allclose(model.f(0.0, x, u, theta), dx, rtol=1e-11, atol=1e-12)
        np.testing.assert_allclose(model.h(0.0, x, u, theta), y, rtol=1e-11, atol=1e-12)
        # without Ix, Iz the (I_z − I_x) p r term is absent (the reference with I_x = I_z = 0)
        bare = {k: v for k, v in c.items() if k not in ("Ix", "Iz")}
        model = alpha_q_model(structure, parameters, **bare)
        dx, _ = reference(x, u, values, {**c, "Ix": 0.0, "Iz": 0.0})
        np.testing.assert_allclose(model.f(0.0, x, u, theta), dx, rtol=1e-11, atol=1e-12)


def test_accelerometer_convention_and_output_choice():
    c, values, x, u = _draw(np.random.default_rng(3))
    _, y = reference(x, u, values, c)
    model = _aircraft_model(c, values, accelerometer={"az": "up", "unit": "m/s^2"}, outputs=["az"])
    az = model.h(0.0, x, u, model.parameters.values)
    # a_n = −a_z, in m/s²: −g · q̄ S C_Z/(m g)
    np.testing.assert_allclose(az, [-c["g"] * y[2]], rtol=1e-12)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"aero": AeroModel({"CZ": ["alpha"], "Cm": ["alpha"], "CX": ["1"]})}, "CZ and Cm"),
        ({"aero": AeroModel({"Cm": ["alpha"]})}, "CZ and Cm"),
        ({"outputs": ["alpha", "V"]}, r"outputs: .*got \['V'\]"),
        ({"controls": ["q"]}, r"controls: \['q'\]"),
        ({"measured": ["V", "alpha", "q"]}, "measured"),
        ({"thrust_input": "T"}, "thrust_input"),
    ],
)
def test_aircraft_alpha_q_refuses_what_it_cannot_model(change, message):
    c, values, _, _ = _draw(np.random.default_rng(5))
    airplane = Airplane(
        mass=1.0, Ix=1.0, Iy=1.0, Iz=1.0, Ixz=0.0, S=1.0, b=1.0, cbar=1.0,
        thrust_input=change.pop("thrust_input", None),
    )  # fmt: skip
    aero = change.pop("aero", AeroModel({"CZ": ["alpha"], "Cm": ["alpha", "de"]}))
    with pytest.raises(InputError, match=message):
        alpha_q_longitudinal_model(airplane, aero, **change)


def test_case_adapter_wants_both_inertias_or_neither():
    structure = structure_from_terms({"CZ": ["alpha"], "Cm": ["alpha"]})
    parameters = Parameters([Parameter("CZ_alpha", 0.0), Parameter("Cm_alpha", 0.0)])
    constants = {"mass": 1.0, "S": 1.0, "cbar": 1.0, "Iy": 1.0}
    with pytest.raises(InputError, match=r"Iz: expected both Ix and Iz or neither.*Ix only"):
        alpha_q_model(structure, parameters, Ix=2.0, **constants)
    with pytest.raises(InputError, match=r"parameters: no values for \['Cm_alpha'\]"):
        alpha_q_model(structure, Parameters([Parameter("CZ_alpha", 0.0)]), **constants)


# two α–q models that share their code and differ in constants and term tables
_SIMULATE = """
import sys
import numpy as np
from flightid.cases.alpha_q import alpha_q_model, structure_from_terms, zero_parameters
from flightid.data.flightdata import FlightData
from flightid.simulation import simulate

MODELS = {
    "A": ({"CZ": ["1", "alpha"], "Cm": ["alpha", "qhat", "de"]}, dict(mass=1000.0, S=10.0,
          cbar=1.5, Iy=2000.0)),
    "B": ({"CZ": ["1", "alpha", "de"], "Cm": ["1", "alpha", "qhat", "de", "alpha*de"]},
          dict(mass=338.0, S=422.0, cbar=6.5, Iy=21000.0, g=32.174)),
}
t = np.arange(101) * 0.02
inputs = {"V": np.full_like(t, 150.0), "qbar": np.full_like(t, 25.0), "de": 0.05 * np.sin(3 * t)}
inputs |= {n: np.zeros_like(t) for n in ("theta", "phi", "ax", "p", "r")}
data = FlightData(t, inputs, {n: np.zeros_like(t) for n in ("alpha", "q", "az")}, name="sim")
for key in sys.argv[1]:
    terms, constants = MODELS[key]
    structure = structure_from_terms(terms)
    parameters = zero_parameters(structure)
    parameters = parameters.with_values(np.linspace(-1.0, 1.0, len(parameters.names)))
    print(key, repr(simulate(alpha_q_model(structure, parameters, **constants), data)[-1].tolist()))
"""


def test_kernels_cached_in_two_processes_stay_apart_in_a_third(tmp_path):
    """Regression test: numba names compiled functions qualname$uid with a per-process
    counter; two processes doing the same work gave two α–q models (one code, other
    constants) the same names, and a process that had compiled one and loaded the other
    from the disk cache ran one's code for the other (the Twin Otter estimate went wrong
    after another α–q case had run). A loaded model must simulate as it did when compiled."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "FLIGHTID_KERNEL_CACHE": "1"}

    def run(keys: str) -> dict[str, str]:
        out = subprocess.run(
            [sys.executable, "-c", _SIMULATE, keys], env=env, capture_output=True, text=True
        )
        assert out.returncode == 0, out.stderr
        return dict(line.split(" ", 1) for line in out.stdout.splitlines())

    # A compiled and cached by one process; B compiled by a second doing the same work
    # (hence the same function names), which then loads A from the cache
    first, second = run("A"), run("BA")
    assert second["B"] != first["A"]
    assert second["A"] == first["A"]
