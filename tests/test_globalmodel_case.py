"""``[[stages]] kind = "global_model"`` in a case file: parsed and checked, run by
``flightid run`` (results.json entry, model file, terms CSV, carpet plots), dry-checked by
``flightid validate`` without fitting.

Reference: the data are generated from known coefficient functions (``truth_CL``,
``truth_Cm``) at four flight conditions (Mach per maneuver, a case-file condition), so the
selected terms must be the generating ones and the estimates within a few σ of their values.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from flightid.cases import CaseError, load_case
from flightid.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
MACHS = {"m1": 0.3, "m2": 0.45, "m3": 0.6, "m4": 0.75}


def truth_CL(alpha, mach, de):
    return 0.1 + 4.5 * alpha - 3.0 * alpha**2 + 0.6 * mach * alpha + 0.4 * de


def truth_Cm(alpha, mach, de):
    return -0.02 - 0.8 * alpha - 1.2 * de


HEAD = """
title = "global model test"
[data]
files = ["m1.csv", "m2.csv", "m3.csv", "m4.csv"]
data_dir = "."
format = "csv"
time = "time"
[data.inputs]
alpha = "alpha"
de = "de"
[data.outputs]
CL = "CL"
Cm = "Cm"
"""

STAGE = """
[[stages]]
kind = "global_model"
name = "envelope"
variables = ["alpha", "Mach", "de"]
orders = { alpha = 3, Mach = 1, de = 1 }
max_order = 3
[stages.conditions]
m1 = { Mach = 0.3 }
m2 = { Mach = 0.45 }
m3 = { Mach = 0.6 }
m4 = { Mach = 0.75 }
[stages.coefficients.CL]
response = "CL"
[stages.coefficients.Cm]
"""


@pytest.fixture
def envelope(tmp_path: Path) -> Path:
    """Four maneuvers (m1…m4: one Mach each), α sweeps and elevator doublets, white noise
    σ 0.002 on the coefficients (seed 3)."""
    rng = np.random.default_rng(3)
    t = np.arange(600) * 0.05
    for k, (name, mach) in enumerate(MACHS.items()):
        alpha = 0.05 + 0.12 * (1 + np.sin(0.21 * t + k)) + 0.02 * np.sin(1.7 * t)
        de = 0.05 * np.sign(np.sin(0.9 * t + 0.5 * k)) + 0.01 * rng.standard_normal(t.size)
        cl = truth_CL(alpha, mach, de) + 0.002 * rng.standard_normal(t.size)
        cm = truth_Cm(alpha, mach, de) + 0.002 * rng.standard_normal(t.size)
        rows = "\n".join(
            ",".join(f"{v:.17g}" for v in row) for row in zip(t, alpha, de, cl, cm, strict=True)
        )
        (tmp_path / f"{name}.csv").write_text("time,alpha,de,CL,Cm\n" + rows + "\n")
    return tmp_path


def _case(directory: Path, stage: str = STAGE) -> Path:
    path = directory / "case.toml"
    path.write_text(HEAD + stage)
    return path


def test_the_stage_is_parsed_with_its_options_and_conditions(envelope):
    case = load_case(_case(envelope))
    (stage,) = case.stages
    assert stage.kind == "global_model" and stage.name == "envelope"
    assert stage.settings["variables"] == ("alpha", "Mach", "de")
    assert stage.settings["conditions"]["m3"] == {"Mach": 0.6}
    assert stage.settings["options"]["max_order"] == 3
    assert [c[:2] for c in stage.coefficients] == [("CL", "CL"), ("Cm", "Cm")]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (("max_order = 3", "max_order = -1"), "stages[0]: max_order"),
        (("max_order = 3", "max_order = 3\nbogus = 1"), "stages[0].bogus: unknown key"),
        (('variables = ["alpha", "Mach", "de"]', 'variables = ["alpha", "V"]'), "'V'"),
        (("[stages.coefficients.Cm]", '[stages.coefficients.Cm]\nresponse = "Cx"'), "Cx"),
        (("[stages.coefficients.CL]", "[stages.coefficients.CL]\norders = 3"), "coefficients.CL"),
        (("m1 = { Mach = 0.3 }", 'm1 = { Mach = "fast" }'), "stages[0].conditions.m1.Mach"),
    ],
)
def test_a_bad_stage_is_a_case_error_naming_its_key(envelope, change, message):
    with pytest.raises(CaseError, match=None) as raised:
        load_case(_case(envelope, STAGE.replace(*change)))
    assert message in str(raised.value)


def test_a_condition_missing_for_a_maneuver_is_named(envelope, capsys):
    path = _case(envelope, STAGE.replace("m4 = { Mach = 0.75 }\n", ""))
    assert main(["validate", str(path)]) != 0
    assert "'Mach' is not given for the maneuvers ['m4']" in capsys.readouterr().err


def test_run_selects_the_generating_terms_within_their_sigma(envelope, capsys):
    assert main(["run", str(_case(envelope)), "--json", "--quiet"]) == 0
    document = json.loads(capsys.readouterr().out)
    entry = document["stages"][0]
    assert entry["kind"] == "global_model"
    model = entry["global_model"]
    assert model["model_file"] == "global_model.json"
    assert [v["name"] for v in model["variables"]] == ["alpha", "Mach", "de"]
    cl = {row["term"]: row for row in model["coefficients"]["CL"]["terms"]}
    # the generating terms of CL (orders 3/1/1 offer 15 candidates)
    assert set(cl) == {"1", "alpha", "alpha^2", "alpha*Mach", "de"}
    truth = {"1": 0.1, "alpha": 4.5, "alpha^2": -3.0, "alpha*Mach": 0.6, "de": 0.4}
    for term, value in truth.items():
        assert abs(cl[term]["value"] - value) < 4 * cl[term]["std"], term
    cm = {row["term"] for row in model["coefficients"]["Cm"]["terms"]}
    assert cm == {"1", "alpha", "de"}


def test_results_json_of_the_stage_follows_the_schema(envelope, capsys):
    jsonschema = pytest.importorskip("jsonschema")
    assert main(["run", str(_case(envelope)), "--json", "--quiet"]) == 0
    document = json.loads(capsys.readouterr().out)
    schema = json.loads((ROOT / "docs" / "schema" / "results.schema.json").read_text())
    jsonschema.validate(document, schema)


def test_out_writes_the_model_its_terms_and_carpet_plots(envelope):
    out = envelope / "out"
    assert main(["run", str(_case(envelope)), "--out", str(out), "--quiet"]) == 0
    from flightid.globalmodel import load_global_model

    model = load_global_model(out / "global_model.json")
    points = {"alpha": np.array([0.1, 0.2]), "Mach": np.array([0.5, 0.5]), "de": np.zeros(2)}
    prediction = model.predict(points)["CL"]
    np.testing.assert_allclose(
        prediction.value, truth_CL(points["alpha"], 0.5, 0.0), atol=5 * prediction.std_mean.max()
    )
    terms = (out / "global_model_terms.csv").read_text().splitlines()
    assert terms[0] == "coefficient,parameter,term,unit,value,std,std_cr"
    assert len(terms) == 1 + 5 + 3
    for name in ("CL", "Cm"):
        svg = ET.parse(out / "figures" / f"carpet_{name}.svg").getroot()
        # the 10 % beyond the data's α range is drawn dashed (outside the support)
        assert any(
            p.get("stroke-dasharray") for p in svg.iter("{http://www.w3.org/2000/svg}polyline")
        )
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "Global model: stage envelope, CL" in page and "carpet plot" in page


def test_validate_fits_nothing(envelope, capsys, monkeypatch):
    import flightid.globalmodel as package

    def refuse(*args, **kwargs):
        raise AssertionError("validate must not fit")

    monkeypatch.setattr(package, "fit_global_model", refuse)
    assert main(["validate", str(_case(envelope))]) == 0
    out = capsys.readouterr().out
    assert "global_model 'envelope': 2 coefficient(s) over alpha, Mach, de, 2400 samples" in out


def test_the_page_and_estimates_csv_hold_the_global_model(envelope):
    out = envelope / "out"
    assert main(["run", str(_case(envelope)), "--out", str(out), "--quiet"]) == 0
    rows = (out / "estimates.csv").read_text().splitlines()
    names = [row.split(",")[0] for row in rows[1:]]
    assert names[:1] == ["CL_0"] and "Cm_de" in names and len(names) == 5 + 3
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "global model test: global model" in page and "fitted: 1 global model(s)" in page
    # the correlation matrix of each coefficient; no empty residual-analysis section
    assert "CL (global model)" in page and "Residual analysis" not in page


def test_the_model_records_its_maneuvers_and_their_conditions(envelope):
    out = envelope / "out"
    assert main(["run", str(_case(envelope)), "--out", str(out), "--quiet"]) == 0
    sources = json.loads((out / "global_model.json").read_text())["sources"]
    assert [s["maneuver"] for s in sources] == list(MACHS)
    assert [s["conditions"]["Mach"] for s in sources] == list(MACHS.values())
    assert all(s["n_samples"] == 600 for s in sources)
