"""The lateral model with V and α measured instead of u and w."""

from dataclasses import replace

import numpy as np
import pytest

from flightid.aircraft import AeroModel, lateral_model, longitudinal_model, navion
from flightid.cases import load_case
from flightid.cases.build import base_model
from flightid.errors import InputError, InputTypeError
from flightid.paper.example3 import LATERAL_TERMS, SIMULATION_VALUES


@pytest.fixture(scope="module")
def models():
    aero = AeroModel(LATERAL_TERMS)
    params = aero.parameters(SIMULATION_VALUES)  # RP-1153 table V simulation values
    outputs = ("beta", "p", "r", "phi", "ay")
    common = dict(controls=("da", "dr"), outputs=outputs)
    uw = lateral_model(navion(thrust_input=None), aero, params, **common)
    va = lateral_model(navion(thrust_input=None), aero, params, measured=("V", "alpha", "q"),
                       **common)  # fmt: skip
    return uw, va


def test_inputs_name_the_measured_motion(models):
    uw, va = models
    assert uw.inputs == ("da", "dr", "u", "w", "q")
    assert va.inputs == ("da", "dr", "V", "alpha", "q")


def test_v_alpha_inputs_give_the_same_dynamics_as_u_w(models):
    uw, va = models
    theta = uw.parameters.values
    rng = np.random.default_rng(5)
    for _ in range(20):
        V, alpha, q = rng.uniform(40, 70), rng.uniform(-0.1, 0.2), rng.uniform(-0.2, 0.2)
        v, p, r = rng.uniform(-5, 5), rng.uniform(-0.5, 0.5), rng.uniform(-0.3, 0.3)
        theta_pitch, phi = rng.uniform(-0.3, 0.3), rng.uniform(-0.6, 0.6)
        x = np.array([v, p, r, -np.sin(theta_pitch), np.sin(phi) * np.cos(theta_pitch),
                      np.cos(phi) * np.cos(theta_pitch)])  # fmt: skip
        controls = rng.uniform(-0.1, 0.1, 2)
        # sin β = v/V; u = V cos α cos β, w = V sin α cos β   [2.19–2.21]
        cos_beta = np.sqrt(1 - (v / V) ** 2)
        u_uw = np.array([*controls, V * np.cos(alpha) * cos_beta, V * np.sin(alpha) * cos_beta, q])
        u_va = np.array([*controls, V, alpha, q])
        np.testing.assert_allclose(va.f(0.0, x, u_va, theta), uw.f(0.0, x, u_uw, theta),
                                   rtol=1e-12, atol=1e-13)  # fmt: skip
        y_va = va.h(0.0, x, u_va, theta)
        np.testing.assert_allclose(y_va, uw.h(0.0, x, u_uw, theta), rtol=1e-12, atol=1e-13)
        assert y_va[0] == pytest.approx(np.arcsin(v / V), rel=1e-12)  # β output from v and V


@pytest.mark.parametrize(
    ("measured", "error", "message"),
    [
        (("V", "w", "q"), InputError, "takes u, w, q .* or V, alpha, q"),
        (("V", "alpha"), InputError, "takes u, w, q"),
        ("V,alpha,q", InputTypeError, "expected a list of names"),
    ],
)
def test_bad_measured_inputs_are_named(measured, error, message):
    aero = AeroModel({"Cl": ["beta"]})
    with pytest.raises(error, match=message):
        lateral_model(navion(thrust_input=None), aero, measured=measured)


def test_longitudinal_model_keeps_its_measured_inputs():
    # only the lateral model offers the choice; longitudinal_model has no such argument
    aero = AeroModel({"Cm": ["alpha"]})
    assert longitudinal_model(navion(thrust_input=None), aero).inputs[-3:] == ("v", "p", "r")


def test_case_builder_passes_measured(tmp_path):
    path = tmp_path / "case.toml"
    path.write_text(
        'title = "t"\n[data]\nfile = "none.csv"\ntime = "time"\n[data.outputs]\nbeta = "beta"\n'
        '[model]\ntype = "lateral"\nairplane = { library = "navion" }\n'
        '[model.aero]\nCl = ["beta", "da"]\n'
    )
    case = load_case(path)
    # spec.py decides which [model] keys a file may hold; the builder reads model.measured
    model, _ = base_model(replace(case, model={**case.model, "measured": ["V", "alpha", "q"]}))
    assert model.inputs == ("da", "V", "alpha", "q")
    from flightid.cases.spec import CaseError

    wind = replace(case, model={**case.model, "type": "longitudinal", "measured": ["V"]})
    with pytest.raises(CaseError, match="model.measured: only the lateral model"):
        base_model(wind)
