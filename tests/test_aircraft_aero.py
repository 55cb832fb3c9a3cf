"""Aerodynamic models: parameter naming, tables, evaluation and errors."""

import numpy as np
import pytest

from flightid.aircraft import AeroModel, TermError, lateral_model, navion, parameter_name
from flightid.errors import InputError
from flightid.model.terms import parse_term


@pytest.mark.parametrize(
    ("coefficient", "term", "name"),
    [
        ("Cl", "beta", "Cl_beta"),  # C_lβ
        ("Cl", "alpha*phat", "Cl_alpha_phat"),  # C_lαp̂
        ("CY", "alpha*beta", "CY_alpha_beta"),  # C_Yαβ
        ("CY", "beta^3", "CY_beta3"),  # C_Yβ³
        ("Cn", "1", "Cn_0"),  # C_n0
        ("Cn", "dr", "Cn_dr"),  # C_nδr
        ("Cm", "alpha^2*de", "Cm_alpha2_de"),
    ],
)
def test_nasa_parameter_names(coefficient, term, name):
    assert parameter_name(coefficient, parse_term(term)) == name


def test_model_parameters_and_spec():
    aero = AeroModel({"CY": ["beta", "dr"], "Cl": ["1", "beta", "alpha*phat"]})
    assert aero.parameter_names == ["CY_beta", "CY_dr", "Cl_0", "Cl_beta", "Cl_alpha_phat"]
    assert aero.signals == ("beta", "dr", "alpha", "phat")
    params = aero.parameters({"Cl_beta": -0.1}, fixed=["Cl_0"], scales={"Cl_beta": 0.1})
    assert params["Cl_beta"].value == -0.1
    assert params["CY_beta"].value == 0.0
    assert not params["Cl_0"].free
    assert params["Cl_beta"].typical == 0.1
    with pytest.raises(InputError, match="unknown parameter names"):
        aero.parameters({"Cl_gamma": 1.0})
    combined = aero + AeroModel({"Cn": ["beta"]})
    assert combined.parameter_names[-1] == "Cn_beta"
    with pytest.raises(InputError, match="both define"):
        aero + AeroModel({"Cl": ["beta"]})


def test_evaluate_matches_hand_computation():
    aero = AeroModel({"Cl": ["1", "beta", "alpha*phat", "beta^3"]})
    signals = {"beta": np.array([0.1, -0.2]), "alpha": np.array([0.05, 0.1]),
               "phat": np.array([0.02, 0.03])}  # fmt: skip
    values = {"Cl_0": 0.01, "Cl_beta": -0.1, "Cl_alpha_phat": 2.0, "Cl_beta3": 0.5}
    cl = aero.evaluate(signals, values)["Cl"]
    b, a, p = signals["beta"], signals["alpha"], signals["phat"]
    np.testing.assert_allclose(cl, 0.01 - 0.1 * b + 2.0 * a * p + 0.5 * b**3, rtol=1e-14)


def test_tables_encode_terms():
    aero = AeroModel({"Cl": ["1", "alpha*beta^2"]})
    params = aero.parameters()
    tables = aero.tables(("alpha", "beta"), params)
    assert list(tables.term_coef) == [5, 5]  # Cl is entry 5 of COEFFICIENTS
    assert list(tables.term_param) == [0, 1]
    assert list(tables.factor_start) == [0, 0, 2]
    assert list(tables.factor_signal) == [0, 1]
    assert list(tables.factor_power) == [1, 2]


def test_errors_are_named():
    with pytest.raises(InputError, match="unknown coefficient 'CQ'"):
        AeroModel({"CQ": ["beta"]})
    with pytest.raises(InputError, match="not both"):
        AeroModel({"CX": ["1"], "CL": ["alpha"]})
    with pytest.raises(TermError, match="expected a signal name"):
        AeroModel({"Cl": ["beta*"]})
    with pytest.raises(TermError, match="repeated"):
        AeroModel({"Cl": ["beta", "beta^1"]})
    with pytest.raises(InputError, match="at least one term"):
        AeroModel({"Cl": []})
    aero = AeroModel({"Cl": ["gamma"]})
    # 'gamma' is neither a standard signal nor a declared control
    with pytest.raises(TermError, match="unknown signal 'gamma'"):
        lateral_model(navion(), aero, controls=("da",))
