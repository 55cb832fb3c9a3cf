"""A global model exported as a JSBSim aircraft (``flightid.export.globalmodel_jsbsim``).

Reference: JSBSim itself. The exported aircraft is loaded, its state set by ``ic/*``
properties and its controls by the surface properties; the coefficients are recovered from
JSBSim's body-axis aerodynamic forces and moments (C = F/(q̄ S), C_L, C_D by the stability-axis
rotation) and compared with ``GlobalModel.predict`` at the variables JSBSim reports (α, β,
Mach, q̂ = q c̄/2V), inside the data's support and outside it, where the polynomial
extrapolates identically.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import xml.etree.ElementTree as ET
from types import SimpleNamespace

import numpy as np
import pytest

from flightid.aircraft import navion
from flightid.errors import InputTypeError
from flightid.export._jsbsim_terms import JSBSimExportError
from flightid.export.globalmodel_jsbsim import (
    EXTRAPOLATION_NOTE,
    RANGE_FLAG_PROPERTY,
    write_jsbsim_global,
)
from flightid.export.jsbsim import fly_jsbsim
from flightid.globalmodel import GlobalModelSettings, fit_global_model, load_global_model
from test_globalmodel_case import _case, envelope  # noqa: F401  (the fixture of its run folder)

jsbsim = pytest.importorskip("jsbsim")

FT = 0.3048
VARIABLES = ("alpha", "beta", "Mach", "qhat", "de", "da", "dr")
# the data's box of each variable (uniform draws)
BOX = {"alpha": (-0.05, 0.3), "beta": (-0.1, 0.1), "Mach": (0.3, 0.8), "qhat": (-0.02, 0.02),
       "de": (-0.1, 0.1), "da": (-0.1, 0.1), "dr": (-0.1, 0.1)}  # fmt: skip
SURFACES = {"de": "fcs/elevator-pos-rad", "da": "fcs/left-aileron-pos-rad",
            "dr": "fcs/rudder-pos-rad"}  # fmt: skip


def _truth(x: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Known polynomial coefficients over the envelope."""
    a, b, M, q = x["alpha"], x["beta"], x["Mach"], x["qhat"]
    return {
        "CL": 0.1 + 4.5 * a - 3 * a**2 + 0.6 * M * a + 0.4 * x["de"] + 5 * q,
        "CD": 0.02 + 0.3 * a**2 + 0.05 * M**2 + 0.1 * x["de"] * a,
        "CY": -0.6 * b + 0.15 * x["dr"],
        "Cl": -0.08 * b - 0.1 * a * b + 0.1 * x["da"],
        "Cm": -0.02 - 0.8 * a - 1.2 * x["de"] - 10 * q + 0.1 * M * a,
        "Cn": 0.1 * b - 0.07 * x["dr"],
    }


def _uniform(rng, n: int, box=BOX) -> dict[str, np.ndarray]:
    return {name: rng.uniform(*box[name], n) for name in VARIABLES}


@pytest.fixture(scope="module")
def model():
    """A six-coefficient global model fitted to 3000 seeded samples (noise σ 0.001)."""
    rng = np.random.default_rng(7)
    x = _uniform(rng, 3000)
    signals = {**x}
    for name, value in _truth(x).items():
        signals[name] = value + 0.001 * rng.standard_normal(value.size)
    return fit_global_model(
        signals, list(_truth(x)), list(VARIABLES), settings=GlobalModelSettings(max_order=2)
    )


@pytest.fixture(scope="module")
def aircraft(model, tmp_path_factory):
    airplane = dataclasses.replace(navion(), Ixz=150.0)
    return write_jsbsim_global(model, airplane, tmp_path_factory.mktemp("gm") / "Envelope")


def _load(result):
    os.environ.setdefault("JSBSIM_DEBUG", "0")
    fdm = jsbsim.FGFDMExec(os.path.dirname(jsbsim.__file__))
    fdm.set_debug_level(0)
    assert fdm.load_planet(str(result.planet_file), False)
    fdm.set_aircraft_path(str(result.folder.parent))
    assert fdm.load_model(result.name)
    fdm["simulation/gravity-model"] = 0
    return fdm


def _jsbsim_point(fdm, point: dict[str, float], altitude_ft: float):
    """(the variables JSBSim reports, the coefficients of its aerodynamic loads) at a state
    set by ic/mach, ic/alpha-rad, ic/beta-rad, ic/q-rad_sec and the surfaces."""
    fdm["ic/h-sl-ft"] = altitude_ft
    fdm["ic/mach"] = point["Mach"]
    fdm["ic/alpha-rad"] = point["alpha"]
    fdm["ic/beta-rad"] = point["beta"]
    fdm["ic/theta-rad"] = point["alpha"]
    fdm["ic/phi-rad"] = 0.0
    fdm["ic/p-rad_sec"] = 0.0
    fdm["ic/r-rad_sec"] = 0.0
    for name, prop in SURFACES.items():
        fdm[prop] = point[name]
    fdm.run_ic()
    # q = q̂ · 2V/c̄, V = Mach · a of JSBSim's atmosphere at the altitude (known after run_ic)
    fdm["ic/q-rad_sec"] = point["qhat"] * 2.0 * fdm["velocities/vt-fps"] / fdm["metrics/cbarw-ft"]
    fdm.run_ic()
    seen = {
        "alpha": fdm["aero/alpha-rad"],
        "beta": fdm["aero/beta-rad"],
        "Mach": fdm["velocities/mach"],
        # q̂ = q c̄ / 2V
        "qhat": fdm["velocities/q-aero-rad_sec"]
        * fdm["metrics/cbarw-ft"]
        / (2.0 * fdm["velocities/vt-fps"]),
        **{name: fdm[prop] for name, prop in SURFACES.items()},
    }
    qs = fdm["aero/qbar-psf"] * fdm["metrics/Sw-sqft"]
    b, c = fdm["metrics/bw-ft"], fdm["metrics/cbarw-ft"]
    cx, cy, cz = (fdm[f"forces/fb{a}-aero-lbs"] / qs for a in "xyz")
    a = seen["alpha"]
    coefficients = {
        # C_L = C_X sin α − C_Z cos α, C_D = −(C_X cos α + C_Z sin α) (stability axes)
        "CL": cx * math.sin(a) - cz * math.cos(a),
        "CD": -(cx * math.cos(a) + cz * math.sin(a)),
        "CY": cy,
        "Cl": fdm["moments/l-aero-lbsft"] / (qs * b),
        "Cm": fdm["moments/m-aero-lbsft"] / (qs * c),
        "Cn": fdm["moments/n-aero-lbsft"] / (qs * b),
    }
    return seen, coefficients


def _compare(model, aircraft, points: dict[str, np.ndarray], altitude_ft: float):
    """(JSBSim's coefficients, the model's predictions at the states JSBSim reports,
    the reported states), each {name: (n,)}."""
    fdm = _load(aircraft)
    n = len(points["alpha"])
    seen_rows, got_rows = [], []
    for i in range(n):
        seen, got = _jsbsim_point(fdm, {k: float(v[i]) for k, v in points.items()}, altitude_ft)
        seen_rows.append(seen)
        got_rows.append(got)
    seen = {k: np.array([row[k] for row in seen_rows]) for k in seen_rows[0]}
    got = {k: np.array([row[k] for row in got_rows]) for k in got_rows[0]}
    predicted = model.predict(seen)
    return got, {k: predicted[k].value for k in got}, seen, predicted


def test_jsbsim_coefficients_equal_the_model_inside_its_support(model, aircraft):
    rng = np.random.default_rng(11)
    # inside the box, away from its faces (the data fill it uniformly)
    inner = {k: (lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo)) for k, (lo, hi) in BOX.items()}
    points = _uniform(rng, 24, inner)
    got, expected, seen, predicted = _compare(model, aircraft, points, 5000.0)
    # the state JSBSim reports is the one asked for
    for name in ("alpha", "beta", "Mach", "qhat", "de"):
        np.testing.assert_allclose(seen[name], points[name], rtol=1e-6, atol=1e-9)
    assert not any(np.any(predicted[c].outside) for c in got)
    for name in got:
        np.testing.assert_allclose(got[name], expected[name], rtol=0, atol=1e-10, err_msg=name)
    # and the model is the truth it was fitted to, to the noise's order
    truth = _truth(seen)
    for name in got:
        assert np.max(np.abs(got[name] - truth[name])) < 5e-3, name


def test_outside_the_support_the_polynomial_extrapolates_identically(model, aircraft):
    rng = np.random.default_rng(12)
    # 20 states beyond the data's box: α to 0.5 rad, Mach to 1.1, larger sideslip and surfaces
    beyond = {"alpha": (0.35, 0.5), "beta": (0.12, 0.2), "Mach": (0.85, 1.1),
              "qhat": (0.025, 0.04), "de": (-0.2, -0.12), "da": (0.12, 0.2),
              "dr": (-0.2, -0.12)}  # fmt: skip
    points = _uniform(rng, 20, beyond)
    got, expected, _, predicted = _compare(model, aircraft, points, 20000.0)
    assert all(np.all(predicted[c].outside) for c in got)
    for name in got:
        np.testing.assert_allclose(got[name], expected[name], rtol=0, atol=1e-10, err_msg=name)


def test_the_exported_aircraft_flags_a_state_outside_the_data_range(model, aircraft):
    """The aircraft's range flag equals the model's range test (``beyond_range``) at the
    state JSBSim reports: 0 inside the box, 1 with α or Mach beyond it."""
    from flightid.globalmodel.support import beyond_range

    norm = model.normalisation
    fdm = _load(aircraft)
    centre = {k: 0.5 * (lo + hi) for k, (lo, hi) in BOX.items()}
    cases = [centre, {**centre, "alpha": 0.4}, {**centre, "Mach": 0.95}, {**centre, "de": -0.15}]
    flags, expected = [], []
    for point in cases:
        seen, _ = _jsbsim_point(fdm, point, 5000.0)
        flags.append(fdm[RANGE_FLAG_PROPERTY])
        X = np.array([[seen[name] for name in norm.names]])
        expected.append(float(beyond_range(X, norm.low, norm.high, 0.02)[0]))
    assert flags == expected == [0.0, 1.0, 1.0, 1.0]


def test_the_exported_aircraft_flies_a_maneuver(aircraft):
    t = np.arange(151) * 0.02
    pulse = np.where((t > 0.5) & (t < 1.0), 1.0, 0.0) - np.where((t > 1.0) & (t < 1.5), 1.0, 0.0)
    inputs = {"de": -0.03 + 0.02 * pulse, "da": 0.01 * pulse, "dr": -0.01 * pulse,
              "thrust": np.full(t.size, 2000.0)}  # fmt: skip
    # Mach 0.5 at 1000 m: V = 0.5 · 336.4 m/s
    flown = fly_jsbsim(aircraft, t, inputs, {"u": 168.0, "w": 5.0, "theta": 0.03}, substeps=4)
    assert set(flown) >= {"V", "alpha", "q"}
    assert all(np.all(np.isfinite(v)) for v in flown.values())
    # the elevator doublet moves the pitch rate
    assert np.ptp(flown["q"]) > 1e-3


def test_export_json_records_the_support_box_and_the_extrapolation(model, aircraft):
    summary = json.loads((aircraft.folder / "export.json").read_text())
    entry = summary["global_model"]
    norm = model.normalisation
    assert [v["name"] for v in entry["variables"]] == list(VARIABLES)
    for k, variable in enumerate(entry["variables"]):
        assert variable["low"] == norm.low[k] and variable["high"] == norm.high[k]
    mach = next(v for v in entry["variables"] if v["name"] == "Mach")
    assert "velocities/mach" in mach["jsbsim"] and mach["jsbsim_unit"] == "1"
    alpha = next(v for v in entry["variables"] if v["name"] == "alpha")
    assert alpha["jsbsim_unit"] == "rad"
    assert entry["extrapolation"] == EXTRAPOLATION_NOTE and "extrapolate" in EXTRAPOLATION_NOTE
    assert entry["coefficients"]["CL"] == dict(
        zip(model["CL"].parameters, model["CL"].terms, strict=True)
    )
    assert summary["values"] == pytest.approx(model.parameter_values(), rel=0, abs=0)
    notes = [n.text for n in ET.parse(aircraft.aircraft_file).getroot().iter("note")]
    assert any("extrapolate" in n for n in notes)


def _small_model(units=None, variables=("alpha", "de"), coefficient="Cm"):
    rng = np.random.default_rng(5)
    x = {name: rng.uniform(-0.1, 0.2, 400) for name in variables}
    z = -0.8 * x["alpha"] + 0.3 * x[variables[-1]] + 0.001 * rng.standard_normal(400)
    return fit_global_model(
        {**x, "z": z}, {coefficient: "z"}, list(variables), units=units,
        settings=GlobalModelSettings(max_order=1),
    )  # fmt: skip


def test_refusals_name_the_unit_coefficient_or_signal(tmp_path):
    airplane = navion()
    # α in degrees: JSBSim's aero/alpha-rad would be read as degrees
    with pytest.raises(JSBSimExportError, match=r"alpha in 'deg'.*'rad'"):
        write_jsbsim_global(_small_model({"alpha": "deg"}), airplane, tmp_path / "a")
    # the same in radians is written
    write_jsbsim_global(_small_model({"alpha": "rad", "de": "rad"}), airplane, tmp_path / "b")
    with pytest.raises(JSBSimExportError, match=r"\['Cmoment'\]"):
        write_jsbsim_global(_small_model(coefficient="Cmoment"), airplane, tmp_path / "c")
    # an unmapped control, then mapped
    flap = _small_model(variables=("alpha", "flap"))
    with pytest.raises(JSBSimExportError, match="signal 'flap'"):
        write_jsbsim_global(flap, airplane, tmp_path / "d")
    result = write_jsbsim_global(flap, airplane, tmp_path / "e",
                                 controls={"flap": "fcs/flap-pos-rad"})  # fmt: skip
    assert result.controls == {"flap": "fcs/flap-pos-rad"}
    with pytest.raises(InputTypeError, match="GlobalModel"):
        write_jsbsim_global({"Cm_alpha": 1.0}, airplane, tmp_path / "f")


def test_draws_scatter_each_coefficient_by_its_covariance(model, tmp_path):
    result = write_jsbsim_global(model, navion(), tmp_path / "Draws", draws=400, seed=2)
    assert len(result.aerodynamics_files) == 401
    names = list(result.free_names)
    assert names == list(model.parameter_values())
    sigma = np.concatenate([model[c].std for c in model.coefficients])
    spread = result.draws.std(axis=0, ddof=1) / sigma
    # 400 draws: the sample σ within ±20 % of the model's σ (its own σ is about 3.5 %)
    assert np.all(np.abs(spread - 1.0) < 0.2), spread
    # coefficients are fitted separately: their draws are uncorrelated
    cl = [names.index(p) for p in model["CL"].parameters]
    cm = [names.index(p) for p in model["Cm"].parameters]
    cross = np.corrcoef(result.draws[:, cl[0]], result.draws[:, cm[0]])[0, 1]
    assert abs(cross) < 0.2


# ------------------------------------------------------------------ the CLI on a run folder
AIRPLANE = """
[airplane]
library = "navion"
"""


def test_flightid_export_jsbsim_on_a_global_model_run_folder(envelope, capsys):  # noqa: F811
    from flightid.cli.main import main

    run_dir = envelope / "run"
    assert main(["run", str(_case(envelope)), "--out", str(run_dir), "--quiet"]) == 0
    out = envelope / "jsbsim" / "Envelope"
    # without the airplane: refused, naming what is expected
    assert main(["export", str(run_dir), "--format", "jsbsim", "--out", str(out)]) != 0
    assert "--airplane FILE.toml" in capsys.readouterr().err
    assert not out.exists()
    # another format of a global model: refused by name
    assert main(["export", str(run_dir), "--format", "python", "--out", str(out)]) != 0
    assert "exports as --format jsbsim only" in capsys.readouterr().err
    airplane = envelope / "airplane.toml"
    airplane.write_text(AIRPLANE)
    assert main(["export", str(run_dir), "--format", "jsbsim", "--out", str(out),
                 "--airplane", str(airplane)]) == 0  # fmt: skip
    model = load_global_model(run_dir / "global_model.json")
    summary = json.loads((out / "export.json").read_text())
    assert summary["dynamic_pressure"] == "atmosphere"
    assert summary["values"] == pytest.approx(model.parameter_values(), rel=0, abs=0)
    # JSBSim's C_L and C_m at six states inside the support equal the model's
    fdm = _load(SimpleNamespace(folder=out, name="Envelope", planet_file=out / "planet_flat.xml"))
    for alpha, mach, de in [(0.05, 0.35, -0.05), (0.1, 0.5, 0.0), (0.2, 0.6, 0.05),
                            (0.25, 0.7, -0.02), (0.15, 0.4, 0.08), (0.28, 0.74, 0.03)]:  # fmt: skip
        point = {"alpha": alpha, "beta": 0.0, "Mach": mach, "qhat": 0.0, "de": de, "da": 0.0,
                 "dr": 0.0}  # fmt: skip
        seen, got = _jsbsim_point(fdm, point, 5000.0)
        predicted = model.predict({k: [seen[k]] for k in ("alpha", "Mach", "de")})
        for name in ("CL", "Cm"):
            assert got[name] == pytest.approx(predicted[name].value[0], rel=0, abs=1e-8)
    # an existing folder is replaced only with --overwrite
    assert main(["export", str(run_dir), "--format", "jsbsim", "--out", str(out),
                 "--airplane", str(airplane)]) != 0  # fmt: skip
    assert main(["export", str(run_dir), "--format", "jsbsim", "--out", str(out),
                 "--airplane", str(airplane), "--overwrite"]) == 0  # fmt: skip
    # --control maps a variable to another property; a malformed one is named
    assert main(["export", str(run_dir), "--format", "jsbsim", "--out", str(out),
                 "--airplane", str(airplane), "--overwrite", "--control", "de"]) != 0  # fmt: skip
    assert "--control: expected NAME=PROPERTY" in capsys.readouterr().err
    assert main(["export", str(run_dir), "--format", "jsbsim", "--out", str(out),
                 "--airplane", str(airplane), "--overwrite",
                 "--control", "de=fcs/my-elevator-rad"]) == 0  # fmt: skip
    assert json.loads((out / "export.json").read_text())["controls"] == {
        "de": "fcs/my-elevator-rad"
    }
    assert "fcs/my-elevator-rad" in (out / "aerodynamics" / "nominal.xml").read_text()


def test_the_airplane_file_must_hold_an_airplane(envelope, capsys):  # noqa: F811
    from flightid.cli.main import main

    run_dir = envelope / "run"
    assert main(["run", str(_case(envelope)), "--out", str(run_dir), "--quiet"]) == 0
    wrong = envelope / "wrong.toml"
    wrong.write_text("[plane]\nS = 1.0\n")
    out = envelope / "jsbsim" / "Envelope"
    assert main(["export", str(run_dir), "--format", "jsbsim", "--out", str(out),
                 "--airplane", str(wrong)]) != 0  # fmt: skip
    assert "expected an [airplane] table" in capsys.readouterr().err
    assert not out.exists()


# ------------------------------------------------------------------------ table models
TABLE_BREAKPOINTS = {"alpha": [-0.05, 0.05, 0.15, 0.3], "Mach": [0.3, 0.55, 0.8],
                     "de": [-0.1, 0.0, 0.1], "beta": [-0.1, 0.0, 0.1]}  # fmt: skip
TABLE_SETTINGS = {
    # 3-D lift table, a q̂ product table
    "CL": [{"by": ["alpha", "Mach", "de"]}, {"by": ["alpha"], "times": "qhat"}],
    # 2-D drag table
    "CD": [{"by": ["alpha", "Mach"]}],
    # 1-D side-force tables
    "CY": [{"by": ["beta"]}],
}


@pytest.fixture(scope="module")
def table_model():
    """Table models of CL (3-D + q̂·1-D), CD (2-D), CY (1-D) and term models of Cl, Cm, Cn,
    fitted to 3000 seeded samples of the polynomial truth (noise σ 0.001)."""
    rng = np.random.default_rng(8)
    x = _uniform(rng, 3000)
    truth = _truth(x)
    signals = {**x, **{c: truth[c] + 0.001 * rng.standard_normal(3000) for c in truth}}
    settings = {
        name: GlobalModelSettings(method="table", tables=tables, breakpoints=TABLE_BREAKPOINTS)
        for name, tables in TABLE_SETTINGS.items()
    }
    for name in ("Cl", "Cm", "Cn"):
        settings[name] = GlobalModelSettings(max_order=2)
    return fit_global_model(signals, list(truth), list(VARIABLES), settings=settings)


def test_table_models_are_written_as_jsbsim_tables_and_read_back_exactly(table_model, tmp_path):
    airplane = dataclasses.replace(navion(), Ixz=150.0)
    aircraft = write_jsbsim_global(table_model, airplane, tmp_path / "Tables")
    text = (aircraft.folder / "aerodynamics" / "nominal.xml").read_text()
    root = ET.fromstring(text.split("\n", 2)[2])
    cl = next(f for f in root.iter("function") if f.get("name") == "flightid/coefficient/CL")
    assert len(cl.findall(".//table")) == 2
    assert len(cl.findall(".//tableData[@breakPoint]")) == 3  # one per δe breakpoint
    rng = np.random.default_rng(13)
    inner = _uniform(rng, 12)
    # beyond every breakpoint: the tables hold their edge values, as the model does
    beyond = {"alpha": (0.35, 0.45), "beta": (0.12, 0.2), "Mach": (0.85, 0.95),
              "qhat": (0.025, 0.04), "de": (-0.2, -0.12), "da": (0.12, 0.2),
              "dr": (-0.2, -0.12)}  # fmt: skip
    outer = _uniform(rng, 8, beyond)
    points = {k: np.concatenate([inner[k], outer[k]]) for k in inner}
    got, expected, _, predicted = _compare(table_model, aircraft, points, 5000.0)
    for name in got:
        np.testing.assert_allclose(got[name], expected[name], rtol=0, atol=1e-10, err_msg=name)
    assert np.all(predicted["CL"].outside[12:])
    # export.json lists the model's own parameters (the table values), no placeholder
    values = json.loads((aircraft.folder / "export.json").read_text())["values"]
    assert values == pytest.approx(table_model.parameter_values(), rel=0, abs=0)
    assert not any(name.endswith("_tables") for name in values)


def test_a_degree_3_table_or_a_table_without_data_is_refused_by_name(tmp_path):
    rng = np.random.default_rng(9)
    x = _uniform(rng, 800)
    signals = {**x, "CY": _truth(x)["CY"]}
    cubic = GlobalModelSettings(method="table", tables=[{"by": ["beta"], "degree": 3}],
                                breakpoints={"beta": [-0.1, 0.0, 0.1]})  # fmt: skip
    model = fit_global_model(signals, ["CY"], list(VARIABLES), settings=cubic)
    with pytest.raises(JSBSimExportError, match="degree 3"):
        write_jsbsim_global(model, navion(), tmp_path / "Cubic")
    empty = GlobalModelSettings(method="table", tables=[{"by": ["beta"]}],
                                breakpoints={"beta": [-0.1, 0.0, 0.1, 0.5]})  # fmt: skip
    model = fit_global_model(signals, ["CY"], list(VARIABLES), settings=empty)
    with pytest.raises(JSBSimExportError, match="no data"):
        write_jsbsim_global(model, navion(), tmp_path / "Empty")
    linear = GlobalModelSettings(method="table", tables=[{"by": ["beta"]}],
                                 breakpoints={"beta": [-0.1, 0.0, 0.1]})  # fmt: skip
    model = fit_global_model(signals, ["CY"], list(VARIABLES), settings=linear)
    with pytest.raises(JSBSimExportError, match="draws"):
        write_jsbsim_global(model, navion(), tmp_path / "Draws", draws=2)
