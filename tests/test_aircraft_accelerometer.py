"""Accelerometer output conventions: axis signs and g vs m/s² in the model output map."""

import numba
import numpy as np
import pytest

from flightid.aircraft import (
    Accelerometer,
    AeroModel,
    longitudinal_model,
    navion,
    navion_longitudinal_aero,
    six_dof_model,
    trim_level_flight,
)
from flightid.aircraft.library import NAVION_TRIM_SPEED
from flightid.aircraft.units import G0
from flightid.errors import InputError, InputTypeError

OUTPUTS = ("V", "alpha", "ax", "ay", "az", "q")


@pytest.fixture(scope="module")
def trimmed():
    """The Navion (Nelson 1998, App. B) trimmed in level flight with a steady side force, so
    that the bank Φ ≠ 0 and all three accelerations are non-zero."""
    lon, values = navion_longitudinal_aero()
    aero = lon + AeroModel({"CY": ["1", "beta"], "Cl": ["beta"], "Cn": ["beta"]})
    values = values | {"CY_0": 0.05, "CY_beta": -0.4, "Cl_beta": -0.1, "Cn_beta": 0.07}
    airplane = navion()
    model = six_dof_model(airplane, aero, aero.parameters(values))
    return airplane, aero, aero.parameters(values), trim_level_flight(model, NAVION_TRIM_SPEED)


def _outputs(trimmed, accelerometer):
    airplane, aero, parameters, trim = trimmed
    model = six_dof_model(airplane, aero, parameters, outputs=OUTPUTS, accelerometer=accelerometer)
    u = trim.input_vector(model.inputs)
    return dict(zip(OUTPUTS, model.h(0.0, trim.x, u, parameters.values), strict=True))


def test_default_is_body_axes_in_g(trimmed):
    *_, trim = trimmed
    y = _outputs(trimmed, None)
    # steady level flight: 0 = g l + F/m  ⇒  a = F/(m g) = −(l_xz, l_yz, l_zz)   [2.5–2.7]
    np.testing.assert_allclose([y["ax"], y["ay"], y["az"]], -trim.x[6:9], atol=1e-8)
    assert y["az"] < -0.9  # ≈ −1 g in level flight
    assert abs(y["ay"]) > 0.01  # the bank leaves a lateral component


@pytest.mark.parametrize(
    ("convention", "factors"),
    [
        ("body", (1, 1, 1)),
        ("load_factor", (1, 1, -1)),  # a_z ≈ +1 g in level flight
        ({"az": "up"}, (1, 1, -1)),
        ({"unit": "m/s^2"}, (G0, G0, G0)),
        ({"unit": "m/s^2", "az": "up", "ay": "left", "ax": "aft"}, (-G0, -G0, -G0)),
        (Accelerometer(ay="left"), (1, -1, 1)),
    ],
)
def test_conventions_scale_and_flip_only_the_accelerations(trimmed, convention, factors):
    body = _outputs(trimmed, None)
    y = _outputs(trimmed, convention)
    for axis, factor in zip(("ax", "ay", "az"), factors, strict=True):
        assert y[axis] == pytest.approx(factor * body[axis], rel=1e-14)
    for name in ("V", "alpha", "q"):
        assert y[name] == body[name]


def test_load_factor_convention_reads_plus_one_g_in_level_flight(trimmed):
    *_, trim = trimmed
    y = _outputs(trimmed, "load_factor")
    # a_n = −a_z = l_zz = cos Φ cos Θ
    assert y["az"] == pytest.approx(trim.x[8], rel=1e-8)
    assert 0.9 < y["az"] <= 1.0


def test_compiled_output_map_uses_the_convention(trimmed):
    *_, trim = trimmed
    aero, values = navion_longitudinal_aero()
    convention = Accelerometer(unit="m/s^2", az="up")
    model = longitudinal_model(
        navion(thrust_input="thrust"),
        aero,
        aero.parameters(values),
        outputs=("az", "ax", "V"),
        accelerometer=convention,
    )
    # longitudinal state (u, w, q, l_xz, l_yz, l_zz), inputs (de, thrust, v, p, r)
    x = trim.x[[0, 2, 4, 6, 7, 8]]
    u = np.array([trim.inputs["de"], trim.inputs["thrust"], 0.0, 0.0, 0.0])
    theta = model.parameters.values
    compiled = numba.njit(cache=False)(model.h)(0.0, x, u, theta)
    np.testing.assert_allclose(compiled, model.h(0.0, x, u, theta), rtol=1e-13)
    body = longitudinal_model(navion(thrust_input="thrust"), aero, aero.parameters(values),
                              outputs=("az", "ax", "V"))  # fmt: skip
    reference = body.h(0.0, x, u, theta)
    # a_z in m/s², positive up: −g·Z/(m g); a_x in m/s²: g·X/(m g)
    np.testing.assert_allclose(compiled[:2], [-G0 * reference[0], G0 * reference[1]], rtol=1e-13)
    assert compiled[2] == pytest.approx(reference[2], rel=1e-15)


@pytest.mark.parametrize(
    ("value", "error", "message"),
    [
        ({"unit": "ft/s^2"}, InputError, "accelerometer.unit: expected one of"),
        ({"az": "upward"}, InputError, "accelerometer.az: expected one of \\['down', 'up'\\]"),
        ({"ay": "up"}, InputError, "accelerometer.ay"),
        ({"sign": -1}, InputError, "accelerometer.sign: unknown key"),
        ("instrument", InputError, "expected a preset"),
        (-1, InputTypeError, "accelerometer: expected None"),
    ],
)
def test_bad_conventions_are_named(value, error, message):
    with pytest.raises(error, match=message):
        Accelerometer.from_value(value)
    airplane = navion(thrust_input=None)
    aero = AeroModel({"CL": ["alpha"]})
    with pytest.raises(error, match=message):
        longitudinal_model(airplane, aero, accelerometer=value)
