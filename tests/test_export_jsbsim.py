"""JSBSim export: the aircraft folder, its round trip through JSBSim, draws and refusals.

The round trip: (a) the derivatives probed from the exported aircraft in JSBSim (central
differences of its aerodynamic forces and moments, turned back into coefficients with
JSBSim's q̄, S, b, c̄) equal those of the identified model (central differences of
``AeroModel.evaluate``, the closed-form coefficient sums) to 1e-3 relative; (b) the aircraft
flown in JSBSim with the recorded inputs reproduces flightid's simulation of the model within
0.1 of the measurement-noise σ (RMS) per output.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from data_paths import needs_data
from flightid.aircraft import AeroModel, navion, six_dof_model, trim_level_flight
from flightid.data.flightdata import FlightData
from flightid.errors import InputError
from flightid.export.jsbsim import (
    ALPHADOT_RULE,
    JSBSimExportError,
    fly_jsbsim,
    initial_from_body_state,
    write_jsbsim,
)
from flightid.simulation import simulate

jsbsim = pytest.importorskip("jsbsim")

FT = 0.3048

# A 6-DOF model with a term of every kind the export maps: constants, angles, rates,
# controls, a square, a product, a spline and an absolute value (values: Navion-like).
WIND_FORM = {
    "CD": ["1", "alpha", "alpha^2", "de"],
    "CL": ["1", "alpha", "qhat", "de", "spline1(alpha,0.1)"],
    "Cm": ["1", "alpha", "qhat", "de", "alpha*qhat"],
    "CY": ["beta", "rhat", "dr", "phat"],
    "Cl": ["beta", "phat", "rhat", "da", "dr", "abs(da)"],
    "Cn": ["beta", "phat", "rhat", "da", "dr", "beta^3"],
}
# body-axis forces, speed terms, angle-of-sideslip products, rates with V0
BODY_FORM = {
    "CX": ["1", "alpha", "Vrel", "dVrel*alpha", "de"],
    "CZ": ["1", "alpha", "qhat", "de", "alpha*beta"],
    "Cm": ["1", "alpha", "qhat", "de", "dVrel"],
    "CY": ["beta", "rhat", "dr"],
    "Cl": ["beta", "phat", "rhat", "da"],
    "Cn": ["beta", "phat", "rhat", "dr", "u", "w"],
}


def _values(aero: AeroModel, seed: int) -> dict[str, float]:
    """Non-zero values of every parameter (seeded)."""
    rng = np.random.default_rng(seed)
    return {n: float(rng.choice([-1, 1]) * rng.uniform(0.05, 2.0)) for n in aero.parameter_names}


def _load(result, *, flat: bool = True):
    os.environ.setdefault("JSBSIM_DEBUG", "0")
    fdm = jsbsim.FGFDMExec(os.path.dirname(jsbsim.__file__))
    fdm.set_debug_level(0)
    if flat:
        assert fdm.load_planet(str(result.planet_file), False)
    fdm.set_aircraft_path(str(result.folder.parent))
    assert fdm.load_model(result.name)
    if flat:
        fdm["simulation/gravity-model"] = 0
    return fdm


# ------------------------------------------------------------------ (a) probed derivatives
PROBES = ("V", "alpha", "beta", "p", "q", "r", "de", "da", "dr")
POINT = {"V": 60.0, "alpha": 0.13, "beta": 0.04, "p": 0.1, "q": 0.05, "r": -0.08,
         "de": -0.03, "da": 0.02, "dr": 0.01}  # fmt: skip
STEP = {"V": 1e-3, "alpha": 1e-5, "beta": 1e-5, "p": 1e-5, "q": 1e-5, "r": 1e-5,
        "de": 1e-5, "da": 1e-5, "dr": 1e-5}  # fmt: skip
CONTROL_PROPERTY = {"de": "fcs/elevator-pos-rad", "da": "fcs/left-aileron-pos-rad",
                    "dr": "fcs/rudder-pos-rad"}  # fmt: skip


def _jsbsim_coefficients(fdm, point, wind_form: bool) -> dict[str, float]:
    """The model's coefficients at ``point`` from JSBSim's aerodynamic forces and moments:
    C = F/(q̄ S), C_l = L/(q̄ S b) …, and for the drag/lift form [2.15] inverted:
    C_D = −(C_X cos α + C_Z sin α), C_L = C_X sin α − C_Z cos α."""
    V, alpha, beta = point["V"] / FT, point["alpha"], point["beta"]
    # u = V cos α cos β, v = V sin β, w = V sin α cos β (ft/s)
    fdm["ic/u-fps"] = V * math.cos(alpha) * math.cos(beta)
    fdm["ic/v-fps"] = V * math.sin(beta)
    fdm["ic/w-fps"] = V * math.sin(alpha) * math.cos(beta)
    for rate in "pqr":
        fdm[f"ic/{rate}-rad_sec"] = point[rate]
    fdm["ic/theta-rad"] = 0.05
    fdm["ic/h-sl-ft"] = 3000.0
    for control, prop in CONTROL_PROPERTY.items():
        fdm[prop] = point[control]
    fdm.run_ic()
    qs = fdm["aero/qbar-psf"] * fdm["metrics/Sw-sqft"]
    b, c = fdm["metrics/bw-ft"], fdm["metrics/cbarw-ft"]
    cx, cy, cz = (fdm[f"forces/fb{a}-aero-lbs"] / qs for a in "xyz")
    out = {"CY": cy, "Cl": fdm["moments/l-aero-lbsft"] / (qs * b),
           "Cm": fdm["moments/m-aero-lbsft"] / (qs * c),
           "Cn": fdm["moments/n-aero-lbsft"] / (qs * b)}  # fmt: skip
    a = fdm["aero/alpha-rad"]
    if wind_form:
        out["CD"] = -(cx * math.cos(a) + cz * math.sin(a))
        out["CL"] = cx * math.sin(a) - cz * math.cos(a)
    else:
        out["CX"], out["CZ"] = cx, cz
    return out


def _flightid_coefficients(aero, values, airplane, point, v0, rate_speed) -> dict[str, float]:
    """The identified model's coefficients at ``point`` (AeroModel.evaluate)."""
    V, alpha, beta = point["V"], point["alpha"], point["beta"]
    vn = v0 if rate_speed == "V0" else V
    signals = {
        "V": V, "alpha": alpha, "beta": beta, "p": point["p"], "q": point["q"],
        "r": point["r"], "u": V * math.cos(alpha) * math.cos(beta), "v": V * math.sin(beta),
        "w": V * math.sin(alpha) * math.cos(beta),
        # p̂ = p b/2V_n, q̂ = q c̄/2V_n, r̂ = r b/2V_n
        "phat": point["p"] * airplane.b / (2 * vn), "qhat": point["q"] * airplane.cbar / (2 * vn),
        "rhat": point["r"] * airplane.b / (2 * vn), "Vrel": V / v0, "dVrel": (V - v0) / v0,
        "de": point["de"], "da": point["da"], "dr": point["dr"],
    }  # fmt: skip
    evaluated = aero.evaluate({k: np.array([v]) for k, v in signals.items()}, values)
    return {k: float(v[0]) for k, v in evaluated.items()}


def _central_differences(coefficients, point) -> dict[tuple[str, str], float]:
    """{(coefficient, probe): ∂C/∂x} by central differences of ``coefficients(point)``."""
    out = {}
    for probe in PROBES:
        up = coefficients({**point, probe: point[probe] + STEP[probe]})
        down = coefficients({**point, probe: point[probe] - STEP[probe]})
        for name in up:
            out[(name, probe)] = (up[name] - down[name]) / (2 * STEP[probe])
    return out


def _probe_errors(tmp_path, spec, rate_speed, seed):
    airplane = dataclasses.replace(navion(), Ixz=150.0)
    aero = AeroModel(spec)
    values = _values(aero, seed)
    v0 = 55.0
    result = write_jsbsim(values, airplane, tmp_path / "probe", aero=aero,
                          reference_speed=v0, rate_speed=rate_speed)  # fmt: skip
    fdm = _load(result)
    wind = "CD" in spec
    probed = _central_differences(lambda pt: _jsbsim_coefficients(fdm, pt, wind), POINT)
    identified = _central_differences(
        lambda pt: _flightid_coefficients(aero, values, airplane, pt, v0, rate_speed), POINT
    )
    return probed, identified


@pytest.mark.parametrize(
    "spec, rate_speed, seed", [(WIND_FORM, "V", 1), (BODY_FORM, "V0", 2)], ids=["CD-CL", "CX-CZ"]
)
def test_probed_derivatives_equal_the_identified_ones(tmp_path, spec, rate_speed, seed):
    probed, identified = _probe_errors(tmp_path, spec, rate_speed, seed)
    assert set(probed) == set(identified)
    nonzero = {k: v for k, v in identified.items() if abs(v) > 1e-8}
    # every term contributes: dozens of non-zero derivatives
    assert len(nonzero) >= 20
    relative = {k: abs(probed[k] - v) / abs(v) for k, v in nonzero.items()}
    worst = max(relative, key=relative.get)
    assert relative[worst] < 1e-3, (worst, probed[worst], identified[worst])
    # zero derivatives (e.g. ∂C_Y/∂δe) are zero in JSBSim too
    for key in set(identified) - set(nonzero):
        assert abs(probed[key]) < 1e-6, (key, probed[key])


def test_the_probe_sees_a_wrong_value(tmp_path):
    """The probe is sensitive: one parameter changed by 1 % is found."""
    airplane = dataclasses.replace(navion(), Ixz=150.0)
    aero = AeroModel(WIND_FORM)
    values = _values(aero, 1)
    wrong = {**values, "Cl_phat": 1.01 * values["Cl_phat"]}
    result = write_jsbsim(wrong, airplane, tmp_path / "wrong", aero=aero)
    fdm = _load(result)
    probed = _central_differences(lambda pt: _jsbsim_coefficients(fdm, pt, True), POINT)
    identified = _central_differences(
        lambda pt: _flightid_coefficients(aero, values, airplane, pt, 55.0, "V"), POINT
    )
    key = ("Cl", "p")
    assert abs(probed[key] - identified[key]) / abs(identified[key]) > 5e-3


# ------------------------------------------------------------------ (b) the flown trajectory
NAVION_AERO = {
    "CD": ["1", "alpha", "alpha^2"],
    "CL": ["1", "alpha", "qhat", "de"],
    "Cm": ["1", "alpha", "qhat", "de"],
    "CY": ["beta", "rhat", "dr"],
    "Cl": ["beta", "phat", "rhat", "da", "dr"],
    "Cn": ["beta", "phat", "rhat", "da", "dr"],
}
# Navion (Nelson 1998, App. B) lateral values; drag polar and C_m0 chosen for a trim
NAVION_VALUES = dict(
    CD_0=0.03, CD_alpha=0.1, CD_alpha2=1.0, CL_0=0.1, CL_alpha=4.44, CL_qhat=3.8, CL_de=0.355,
    Cm_0=0.02, Cm_alpha=-0.683, Cm_qhat=-9.96, Cm_de=-0.923, CY_beta=-0.564, CY_rhat=0.2,
    CY_dr=0.157, Cl_beta=-0.074, Cl_phat=-0.41, Cl_rhat=0.107, Cl_da=-0.134, Cl_dr=0.0107,
    Cn_beta=0.071, Cn_phat=-0.0575, Cn_rhat=-0.125, Cn_da=-0.0035, Cn_dr=-0.072,
)  # fmt: skip
# measurement-noise σ of the simulated flight data (m/s, rad, rad/s, g)
NOISE_SIGMA = dict(V=0.1, alpha=1e-3, beta=1e-3, theta=1e-3, phi=1e-3, ax=5e-3, ay=5e-3,
                   az=5e-3, p=1e-3, q=1e-3, r=1e-3)  # fmt: skip


def _doublet(t, start, width, amplitude):
    return amplitude * (
        ((t >= start) & (t < start + width)).astype(float)
        - ((t >= start + width) & (t < start + 2 * width)).astype(float)
    )


def _navion_flight(ixz: float):
    """Trimmed 6-DOF Navion (I_xz = ixz), 4 s of elevator, aileron and rudder doublets,
    constant trim thrust: (model, time, inputs)."""
    airplane = dataclasses.replace(navion(), Ixz=ixz)
    aero = AeroModel(NAVION_AERO)
    model = six_dof_model(
        airplane, aero, aero.parameters(NAVION_VALUES), controls=["de", "da", "dr"]
    )
    trim = trim_level_flight(model, 55.0)
    model = six_dof_model(airplane, aero, aero.parameters(NAVION_VALUES),
                          controls=["de", "da", "dr"], x0=trim.x)  # fmt: skip
    t = np.arange(0.0, 4.0 + 1e-9, 0.02)
    inputs = {
        "de": trim.inputs["de"] + _doublet(t, 0.5, 0.5, 0.02),
        "da": trim.inputs["da"] + _doublet(t, 1.5, 0.5, 0.03),
        "dr": trim.inputs["dr"] + _doublet(t, 2.5, 0.5, 0.03),
        "thrust": np.full_like(t, trim.inputs["thrust"]),
    }
    return airplane, aero, model, trim, t, inputs


def _flown_error_over_sigma(tmp_path, flown_ixz: float) -> dict[str, float]:
    """RMS(JSBSim − flightid)/σ per output; JSBSim flies an aircraft exported with
    I_xz = flown_ixz, flightid simulates the model with I_xz = 150 kg·m²."""
    airplane, aero, model, trim, t, inputs = _navion_flight(150.0)
    y = simulate(model, FlightData(t, {k: inputs[k] for k in model.inputs}))
    exported = dataclasses.replace(airplane, Ixz=flown_ixz)
    result = write_jsbsim(NAVION_VALUES, exported, tmp_path / f"navion{int(flown_ixz)}",
                          aero=aero, dynamic_pressure="airplane")  # fmt: skip
    flown = fly_jsbsim(result, t, inputs, initial_from_body_state(trim.x), substeps=10)
    # the maneuver moves every output but V (1 σ) by more than 5 σ
    moved = [o for i, o in enumerate(model.outputs) if np.ptp(y[:, i]) > 5 * NOISE_SIGMA[o]]
    assert moved == [o for o in model.outputs if o != "V"]
    return {
        o: float(np.sqrt(np.mean((flown[o] - y[:, i]) ** 2)) / NOISE_SIGMA[o])
        for i, o in enumerate(model.outputs)
    }


def test_flown_aircraft_reproduces_flightid_simulation(tmp_path):
    ratio = _flown_error_over_sigma(tmp_path, 150.0)
    assert max(ratio.values()) < 0.1, ratio


def test_flown_comparison_sees_a_wrong_inertia_product(tmp_path):
    """The trajectory check is sensitive: I_xz of the wrong sign is seen in p and r."""
    ratio = _flown_error_over_sigma(tmp_path, -150.0)
    assert max(ratio["p"], ratio["r"]) > 0.1, ratio


# ------------------------------------------------------------------ HFB-320 (shared data)
HFB320_CASE = (
    Path(__file__).resolve().parents[1] / "examples/cases/hfb320_longitudinal_builtin.toml"
)


def _hfb320_run():
    """The shipped HFB-320 case run (about 0.2 s), or a skip when its data are absent."""
    from flightid.cases import load_case, resolve_data_dir, run_case

    case = load_case(HFB320_CASE)
    if not (resolve_data_dir(case) / "fvsysid/hfb320_1_10.asc").exists():
        pytest.skip("HFB-320 data (../shared/data) absent")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the case's two 6-σ outliers in α
        return case, run_case(case)


def _hfb320_export(case, estimate, folder, dynamic_pressure, draws=0):
    from flightid.aircraft import airplane_from_table

    spec = case.model
    airplane = airplane_from_table(spec["airplane"])
    aero = AeroModel(spec["aero"])
    result = write_jsbsim(estimate, airplane, folder, aero=aero, draws=draws,
                          reference_speed=spec["reference_speed"], rate_speed=spec["rate_speed"],
                          dynamic_pressure=dynamic_pressure)  # fmt: skip
    return airplane, result


def test_hfb320_probed_derivatives_equal_the_estimates(tmp_path):
    """The estimated derivatives of the HFB-320 case, probed from the exported aircraft:
    C_Lα = ∂C_L/∂α, C_LV = V0 ∂C_L/∂V (V-terms in V/V0), C_mq = (2V0/c̄) ∂C_m/∂q (q̂ with
    V0), C_mδe = ∂C_m/∂δe …, each to 1e-3 relative."""
    case, run = _hfb320_run()
    estimate = run.estimate
    values = dict(zip(estimate.names, estimate.values, strict=True))
    airplane, result = _hfb320_export(case, estimate, tmp_path / "hfb320", "atmosphere")
    fdm = _load(result)
    point = {**POINT, "V": 106.0, "alpha": 0.11, "beta": 0.0, "p": 0.0, "q": 0.01, "r": 0.0,
             "de": -0.05}  # fmt: skip
    probed = _central_differences(lambda pt: _jsbsim_coefficients(fdm, pt, True), point)
    v0 = case.model["reference_speed"]
    expected = {
        ("CD", "alpha"): values["CDa"], ("CD", "V"): values["CDV"] / v0,
        ("CL", "alpha"): values["CLa"], ("CL", "V"): values["CLV"] / v0,
        ("Cm", "alpha"): values["Cma"], ("Cm", "V"): values["CmV"] / v0,
        # ∂C_m/∂q = C_mq c̄/(2 V0)
        ("Cm", "q"): values["Cmq"] * airplane.cbar / (2 * v0), ("Cm", "de"): values["Cmde"],
    }  # fmt: skip
    relative = {k: abs(probed[k] - v) / abs(v) for k, v in expected.items()}
    assert max(relative.values()) < 1e-3, relative
    others = {k: v for k, v in probed.items() if k not in expected}
    assert max(abs(v) for v in others.values()) < 1e-8, others


def test_hfb320_exported_aircraft_flies_like_flightid(tmp_path):
    """The HFB-320 estimate exported (thrust: the recorded F through flightid/thrust-lbs),
    flown in JSBSim with the recorded elevator and thrust over the whole 60 s maneuver,
    equals flightid's simulation of the estimate within 0.1 σ of the estimated measurement
    noise (RMS, every output)."""
    case, run = _hfb320_run()
    estimate, data = run.estimate, run.maneuvers[0]
    airplane, result = _hfb320_export(case, estimate, tmp_path / "hfb320", "airplane", draws=2)
    assert len(result.aerodynamics_files) == 3
    y = simulate(estimate.model, data)
    V, alpha, theta, q = estimate.model.initial_state()
    # u = V cos α, w = V sin α
    initial = {"u": V * math.cos(alpha), "w": V * math.sin(alpha), "theta": theta, "q": q}
    inputs = {n: data.input(n) for n in ("de", "F")}
    flown = fly_jsbsim(result, data.time, inputs, initial, substeps=10)
    # the case's accelerometer gives a_x, a_z in m/s²
    flown["ax"], flown["az"] = flown["ax"] * airplane.g, flown["az"] * airplane.g
    sigma = np.sqrt(estimate.r_diag)
    ratio = {
        o: float(np.sqrt(np.mean((flown[o] - y[:, i]) ** 2)) / sigma[i])
        for i, o in enumerate(estimate.output_names)
    }
    assert max(ratio.values()) < 0.1, ratio
    # draw 2 flown in JSBSim equals flightid's simulation with the drawn values, and differs
    # from the nominal flight
    theta = np.array(estimate.values, dtype=float)
    theta[np.asarray(estimate.free)] = result.draws[1]
    y_draw = simulate(estimate.model, data, theta)
    flown = fly_jsbsim(result, data.time, inputs, initial, substeps=10, aerodynamics=2)
    flown["ax"], flown["az"] = flown["ax"] * airplane.g, flown["az"] * airplane.g
    for i, o in enumerate(estimate.output_names):
        assert np.sqrt(np.mean((flown[o] - y_draw[:, i]) ** 2)) < 0.1 * sigma[i], o
    assert np.sqrt(np.mean((flown["alpha"] - y[:, 1]) ** 2)) > 0.1 * sigma[1]


# ------------------------------------------------------------------ the folder, draws, refusals
def test_folder_contents_and_units(tmp_path):
    airplane = dataclasses.replace(navion(), Ixz=150.0)
    aero = AeroModel(NAVION_AERO)
    result = write_jsbsim(NAVION_VALUES, airplane, tmp_path / "nav", aero=aero)
    assert result.aircraft_file == tmp_path / "nav" / "nav.xml"
    fdm = _load(result, flat=False)
    fdm["ic/u-fps"], fdm["ic/h-sl-ft"] = 150.0, 3000.0
    fdm.run_ic()
    # SI → English units: 1 ft = 0.3048 m, 1 slug = 14.5939 kg, 1 slug·ft² = 1.35582 kg·m²
    assert fdm["metrics/Sw-sqft"] == pytest.approx(airplane.S / FT**2, rel=1e-12)
    assert fdm["metrics/bw-ft"] == pytest.approx(airplane.b / FT, rel=1e-12)
    assert fdm["metrics/cbarw-ft"] == pytest.approx(airplane.cbar / FT, rel=1e-12)
    assert fdm["inertia/mass-slugs"] == pytest.approx(airplane.mass / 14.593902937, rel=1e-9)
    assert fdm["inertia/iyy-slugs_ft2"] == pytest.approx(airplane.Iy / 1.3558179483, rel=1e-9)
    summary = json.loads((result.folder / "export.json").read_text())
    assert summary["controls"] == CONTROL_PROPERTY
    assert summary["thrust_property_lbs"] == "flightid/thrust-lbs"
    assert summary["rules"] == []
    assert summary["unmodelled_axes"] == [] == list(result.unmodelled_axes)


def test_a_lateral_model_names_the_axes_it_leaves_out(tmp_path):
    aero = AeroModel({"CY": ["beta"], "Cl": ["beta"], "Cn": ["beta"]})
    values = dict.fromkeys(aero.parameter_names, 0.1)
    result = write_jsbsim(values, navion(), tmp_path / "lat", aero=aero)
    assert result.unmodelled_axes == ("X", "Z", "PITCH")
    notes = [n.text for n in ET.parse(result.aircraft_file).getroot().iter("note")]
    assert notes == ["no aerodynamic model on the axes X, Z, PITCH"]


def test_thrust_property_acts_along_the_thrust_line(tmp_path):
    """T (lbf) in flightid/thrust-lbs: X = T cos σ_T, Z = −T sin σ_T, M = l_T T."""
    airplane = dataclasses.replace(navion(), thrust_inclination=0.1, thrust_arm=-0.3)
    aero = AeroModel({"CL": ["alpha"]})
    result = write_jsbsim({"CL_alpha": 0.0}, airplane, tmp_path / "t", aero=aero)
    fdm = _load(result)
    fdm["ic/u-fps"], fdm["ic/h-sl-ft"] = 150.0, 3000.0
    fdm["flightid/thrust-lbs"] = 500.0
    fdm.run_ic()
    assert fdm["forces/fbx-aero-lbs"] == pytest.approx(500.0 * math.cos(0.1), rel=1e-12)
    assert fdm["forces/fbz-aero-lbs"] == pytest.approx(-500.0 * math.sin(0.1), rel=1e-12)
    assert fdm["moments/m-aero-lbsft"] == pytest.approx(500.0 * -0.3 / FT, rel=1e-12)


def _estimate_like(aero, values, free, covariance):
    names = tuple(aero.parameter_names)
    return SimpleNamespace(
        names=names,
        values=np.array([values[n] for n in names]),
        free=np.array([n in free for n in names]),
        covariance=covariance,
        covariance_default=None,
    )


def test_draws_follow_the_covariance_and_load(tmp_path):
    aero = AeroModel({"CL": ["1", "alpha"], "Cm": ["1", "alpha"]})
    values = {"CL_0": 0.2, "CL_alpha": 4.5, "Cm_0": 0.01, "Cm_alpha": -0.7}
    free = ["CL_alpha", "Cm_alpha"]
    cov = np.array([[0.04, -0.006], [-0.006, 0.0025]])
    estimate = _estimate_like(aero, values, free, cov)
    airplane = navion()
    result = write_jsbsim(estimate, airplane, tmp_path / "d", aero=aero, draws=400, seed=7)
    assert len(result.aerodynamics_files) == 401
    assert result.free_names == tuple(free)
    # sample mean and covariance of 400 draws: within a few standard errors of θ̂ and C
    assert np.allclose(result.draws.mean(axis=0), [4.5, -0.7], atol=4 * np.sqrt(np.diag(cov) / 400))
    assert np.allclose(np.cov(result.draws.T), cov, rtol=0.25, atol=1e-3)
    again = write_jsbsim(estimate, airplane, tmp_path / "e", aero=aero, draws=3, seed=7)
    assert np.array_equal(again.draws, result.draws[:3])
    # a draw file is a loadable aerodynamics section carrying the drawn values
    text = (tmp_path / "d" / "d.xml").read_text()
    (tmp_path / "d" / "d.xml").write_text(text.replace("aerodynamics/nominal.xml",
                                                       "aerodynamics/draw_0002.xml"))  # fmt: skip
    fdm = _load(result)
    fdm["ic/u-fps"], fdm["ic/w-fps"], fdm["ic/h-sl-ft"] = 150.0, 15.0, 3000.0
    fdm.run_ic()
    alpha = fdm["aero/alpha-rad"]
    cl_alpha, cm_alpha = result.draws[1]
    assert fdm["flightid/coefficient/CL"] == pytest.approx(0.2 + cl_alpha * alpha, rel=1e-12)
    assert fdm["flightid/coefficient/Cm"] == pytest.approx(0.01 + cm_alpha * alpha, rel=1e-12)


def test_alphadot_terms_are_approximated_by_a_named_rule(tmp_path):
    aero = AeroModel({"Cm": ["alpha", "alphadot_hat"]})
    result = write_jsbsim({"Cm_alpha": -0.7, "Cm_alphadot_hat": -4.0}, navion(),
                          tmp_path / "ad", aero=aero)  # fmt: skip
    assert result.rules == (ALPHADOT_RULE,)
    notes = [n.text for n in ET.parse(result.aircraft_file).getroot().iter("note")]
    assert notes[0] == "approximation: " + ALPHADOT_RULE
    assert "aero/alphadot-rad_sec" in result.aerodynamics_files[0].read_text()


def test_refusals_name_the_term_or_quantity(tmp_path):
    airplane = navion()
    # the α–q model's measured q̄ has no JSBSim counterpart
    aero = AeroModel({"CZ": ["alpha", "qbar"], "Cm": ["alpha"]})
    with pytest.raises(JSBSimExportError, match=r"term 'qbar'.*signal 'qbar'"):
        write_jsbsim(dict.fromkeys(aero.parameter_names, 0.1), airplane, tmp_path / "a", aero=aero)
    # an unmapped control; mapped, it is written
    aero = AeroModel({"Cm": ["alpha", "flap"]})
    values = dict.fromkeys(aero.parameter_names, 0.1)
    with pytest.raises(JSBSimExportError, match="signal 'flap'"):
        write_jsbsim(values, airplane, tmp_path / "b", aero=aero)
    result = write_jsbsim(values, airplane, tmp_path / "c", aero=aero,
                          controls={"flap": "fcs/flap-pos-rad"})  # fmt: skip
    assert result.controls == {"flap": "fcs/flap-pos-rad"}
    # an engine's gyroscopic moments are not written
    with pytest.raises(JSBSimExportError, match="engine_momentum"):
        write_jsbsim(values, dataclasses.replace(airplane, engine_momentum=5.0), tmp_path / "d",
                     aero=aero, controls={"flap": "fcs/flap-pos-rad"})  # fmt: skip
    # draws need a covariance
    aero = AeroModel({"Cm": ["alpha"]})
    with pytest.raises(JSBSimExportError, match="covariance"):
        write_jsbsim({"Cm_alpha": -0.5}, airplane, tmp_path / "e", aero=aero, draws=2)
    # missing values, then a non-empty folder is not overwritten
    with pytest.raises(JSBSimExportError, match=r"\['Cm_alpha'\]"):
        write_jsbsim({}, airplane, tmp_path / "f", aero=aero)
    with pytest.raises(JSBSimExportError, match="not empty"):
        write_jsbsim({"Cm_alpha": -0.5}, airplane, tmp_path / "c", aero=aero)
    # fly_jsbsim names missing inputs
    with pytest.raises(InputError, match=r"missing \['flap', 'thrust'\]"):
        fly_jsbsim(result, np.arange(3) * 0.1, {}, {"u": 50.0})
    # and draws that were not written
    inputs = {"flap": np.zeros(3), "thrust": np.zeros(3)}
    with pytest.raises(InputError, match="draw 1 not written"):
        fly_jsbsim(result, np.arange(3) * 0.1, inputs, {"u": 50.0}, aerodynamics=1)


@needs_data("fvsysid/hfb320_1_10.asc")
def test_flightid_export_jsbsim_writes_the_recorded_estimates_and_draws(tmp_path):
    """``flightid export RUN --format jsbsim`` from a result folder: the aircraft's values are
    the run's estimates (results.json), the draws scatter as its covariance says, and an
    existing folder flightid did not export is refused even with --overwrite."""
    from flightid.cli.main import main

    root = Path(__file__).resolve().parents[1]
    run_dir = tmp_path / "run"
    case = root / "examples" / "cases" / "hfb320_longitudinal_builtin.toml"
    assert main(["run", str(case), "--out", str(run_dir), "--quiet"]) == 0
    out = tmp_path / "jsbsim" / "HFB320"
    assert main(["export", str(run_dir), "--format", "jsbsim", "--out", str(out),
                 "--draws", "200", "--seed", "3"]) == 0  # fmt: skip
    entry = json.loads((run_dir / "results.json").read_text())["results"][0]
    recorded = {p["name"]: p["value"] for p in entry["parameters"]}
    exported = json.loads((out / "export.json").read_text())["values"]
    for name, value in exported.items():
        assert value == pytest.approx(recorded[name], rel=1e-12, abs=1e-15)
    draws = json.loads((out / "draws.json").read_text())
    names = draws["free_names"]
    assert sorted(names) == sorted(entry["covariance"]["parameters"])
    sigma = {p["name"]: p["std"] for p in entry["parameters"]}
    values = np.array(draws["draws"], dtype=float)
    spread = values.std(axis=0, ddof=1) / np.array([sigma[n] for n in names])
    # 200 draws: the sample σ within ±20 % of the recorded σ (its own σ is about 5 %)
    assert np.all(np.abs(spread - 1.0) < 0.2), spread
    stranger = tmp_path / "mine"
    stranger.mkdir()
    (stranger / "notes.txt").write_text("mine")
    refused = main(["export", str(run_dir), "--format", "jsbsim", "--out", str(stranger),
                    "--overwrite"])  # fmt: skip
    assert refused != 0
    assert (stranger / "notes.txt").read_text() == "mine"
