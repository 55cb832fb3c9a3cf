"""Spline-in-α terms: parsing, numpy vs compiled evaluation, and recovery by output error."""

import numba
import numpy as np
import pytest

from flightid.aircraft import AeroModel, navion, parameter_name, wind_axis_longitudinal_model
from flightid.aircraft.library import NAVION_TRIM_SPEED, navion_longitudinal_aero
from flightid.data.flightdata import FlightData
from flightid.estimation import MNRES, estimate
from flightid.model.terms import Spline, TermError, parse_term
from flightid.simulation import simulate


@pytest.mark.parametrize(
    ("text", "label", "name"),
    [
        ("spline1(alpha,0.15)", "spline1(alpha,0.15)", "CL_alpha_s0p15"),
        (" spline1( alpha , 0.15 ) ^2", "spline1(alpha,0.15)^2", "CL_alpha_s0p15_2"),
        ("spline1(alpha,-0.05)", "spline1(alpha,-0.05)", "CL_alpha_sm0p05"),
        ("spline1(alpha,1e-5)*phat", "spline1(alpha,1e-05)*phat", "CL_alpha_s1em05_phat"),
        ("spline1(alpha,0)", "spline1(alpha,0)", "CL_alpha_s0"),
        ("spline1(alpha,-0.0)", "spline1(alpha,0)", "CL_alpha_s0"),
        ("alpha*spline1(alpha,.1)*spline1(alpha,0.1)", "alpha*spline1(alpha,0.1)^2",
         "CL_alpha_alpha_s0p1_2"),
    ],
)  # fmt: skip
def test_spline_terms_parse_to_canonical_labels_and_names(text, label, name):
    term = parse_term(text)
    assert term.label == label
    assert parse_term(term.label) == term  # the label reads back as the same term
    assert parameter_name("CL", term) == name
    assert term.signals == ("alpha",) or term.signals == ("alpha", "phat")


def test_spline_evaluates_to_max_of_signal_minus_knot():
    alpha = np.array([-0.1, 0.0, 0.15, 0.2, 0.4])
    phat = np.array([0.01, 0.02, 0.03, 0.04, 0.05])
    term = parse_term("spline1(alpha,0.15)^2*phat")
    # (α − 0.15)₊² p̂ by hand: 0, 0, 0, 0.05²·0.04, 0.25²·0.05
    expected = np.array([0.0, 0.0, 0.0, 0.0025 * 0.04, 0.0625 * 0.05])
    np.testing.assert_allclose(term.evaluate({"alpha": alpha, "phat": phat}), expected, atol=1e-15)
    assert term.splines == (Spline("alpha", 0.15),)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("spline2(alpha,0.1)", "unknown function 'spline2'"),
        ("spline1(alpha)", "expected ','"),
        ("spline1(0.1,alpha)", "expected a signal name as the first argument"),
        ("spline1(alpha,knot)", "expected a number"),
        ("spline1(alpha,0.1", "expected '\\)'"),
        ("spline1(alpha,0.1)x", "unexpected 'x'"),
        ("spline1(spline1(alpha,0.1),0.2)", "expected ',' after 'spline1'"),
    ],
)
def test_malformed_spline_terms_are_named_errors(text, message):
    with pytest.raises(TermError, match=message):
        parse_term(text)


def test_unknown_spline_signal_is_named():
    with pytest.raises(TermError, match="unknown signal 'gamma'"):
        parse_term("spline1(gamma,0.1)").evaluate({"alpha": np.zeros(3)})


def test_tables_encode_splines():
    aero = AeroModel({"CL": ["alpha", "spline1(alpha,0.1)^2*qhat"], "Cm": ["spline1(beta,-0.02)"]})
    tables = aero.tables(("alpha", "beta", "qhat"), aero.parameters())
    assert list(tables.factor_signal) == [0, 0, 2, 1]
    assert list(tables.factor_power) == [1, 2, 1, 1]
    assert list(tables.factor_spline) == [0, 1, 0, 1]
    np.testing.assert_array_equal(tables.factor_knot, [0.0, 0.1, 0.0, -0.02])


def _doublets(t, amplitude):
    """Elevator doublets (rad) at 1 s and 5 s, 0.5 s + 0.5 s."""
    first = np.where((t >= 1.0) & (t < 1.5), -1.0, 0.0) + np.where((t >= 1.5) & (t < 2.0), 1.0, 0)
    second = np.where((t >= 5.0) & (t < 5.5), 1.0, 0.0) + np.where((t >= 5.5) & (t < 6.0), -1.0, 0)
    return amplitude * (first + second)


# Navion wind-axis longitudinal model (Nelson 1998, App. B derivatives) with a lift-curve
# slope that drops by 2.0 per rad past α = 0.03 rad: C_L = … + C_Lα α + C_Lα,s (α − 0.03)₊,
# and a small fixed second-order spline in C_D.
AERO = {
    "CD": ["1", "alpha", "spline1(alpha,0.03)^2"],
    "CL": ["1", "alpha", "spline1(alpha,0.03)", "qhat", "de"],
    "Cm": ["1", "alpha", "qhat", "de"],
}
FREE = ["CL_alpha", "CL_alpha_s0p03", "Cm_alpha", "Cm_qhat", "Cm_de"]


@pytest.fixture(scope="module")
def spline_flight():
    truth = {**navion_longitudinal_aero()[1], "CL_alpha_s0p03": -2.0, "CD_alpha_s0p03_2": 3.0}
    aero = AeroModel(AERO)
    parameters = aero.parameters(truth, fixed=[n for n in aero.parameter_names if n not in FREE])
    airplane = navion(thrust_input=None)
    model = wind_axis_longitudinal_model(
        airplane,
        aero,
        parameters,
        outputs=("V", "alpha", "theta", "q", "az"),
        x0=(NAVION_TRIM_SPEED, 0.0, 0.0, 0.0),  # trim α ≈ 0 (C_L0 = 0.41 is the trim C_L)
    )
    t = np.arange(0.0, 10.0 + 0.025, 0.05)
    inputs = {"de": _doublets(t, 0.06)}
    # pure Python keeps the test fast (one numba compilation of h below, not of the kernel)
    y = simulate(model, FlightData(t, inputs), compiled=False)
    return airplane, aero, truth, model, t, inputs, y


def test_compiled_model_with_splines_equals_numpy_evaluation(spline_flight):
    airplane, aero, truth, model, _, inputs, y = spline_flight
    V, alpha, q = y[:, 0], y[:, 1], y[:, 3]
    assert alpha.max() > 0.04 and alpha.min() < 0.0  # α passes the knot both ways
    # the outputs V, α, Θ, q are the wind-axis states: evaluate the compiled h on them
    h = numba.njit(cache=False)(model.h)
    theta = model.parameters.values
    az = np.array(
        [h(0.0, y[k, :4].copy(), np.array([inputs["de"][k]]), theta)[4] for k in range(len(y))]
    )
    signals = {"alpha": alpha, "qhat": q * airplane.cbar / (2 * V), "de": inputs["de"]}
    C = aero.evaluate(signals, truth)
    # a_z = Z/(m g), Z = q̄S(−C_L cos α − C_D sin α)   [2.15, 2.26], no thrust
    qbar = 0.5 * airplane.rho * V**2
    expected = qbar * airplane.S * (-C["CL"] * np.cos(alpha) - C["CD"] * np.sin(alpha))
    np.testing.assert_allclose(az, expected / airplane.weight, rtol=1e-12)
    np.testing.assert_allclose(az, y[:, 4], rtol=1e-12)  # compiled h = pure-Python h
    # the spline terms matter: without them a_z differs by more than 1e-3 g somewhere
    C_plain = aero.evaluate(signals, truth | {"CL_alpha_s0p03": 0.0, "CD_alpha_s0p03_2": 0.0})
    plain = qbar * airplane.S * (-C_plain["CL"] * np.cos(alpha) - C_plain["CD"] * np.sin(alpha))
    assert np.max(np.abs(plain - expected) / airplane.weight) > 1e-3


def test_output_error_recovers_a_spline_coefficient(spline_flight):
    _, _, truth, model, t, inputs, y = spline_flight
    rng = np.random.default_rng(2024)
    sigma = np.array([0.1, 0.002, 0.002, 0.002, 0.01])  # m/s, rad, rad, rad/s, g
    measured = y + sigma * rng.standard_normal(y.shape)
    data = FlightData(t, inputs, dict(zip(model.outputs, measured.T, strict=True)))
    start = {n: 1.15 * truth[n] for n in FREE} | {"CL_alpha_s0p03": -1.0}
    initial = model.with_parameters(model.parameters.with_values(start))
    result = estimate(initial, data, MNRES(), compiled=False)
    assert result.converged, result.message
    k = result.names.index("CL_alpha_s0p03")
    value, std = result.values[k], result.std[k]
    print(f"CL_alpha_s0p03 = {value:.4f} ± {std:.4f}, {result.iterations} iterations")
    assert abs(value - truth["CL_alpha_s0p03"]) < 3 * std
    assert abs(value / truth["CL_alpha_s0p03"] - 1) < 0.15
    for name in FREE:
        j = result.names.index(name)
        assert abs(result.values[j] - truth[name]) < 3 * result.std[j], name
