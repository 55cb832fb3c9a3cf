"""The shipped example examples/cases/globalmodel_f16.toml runs on the data beside it
(examples/data/globalmodel_f16, written by ``bench/globalmodel_jsbsim.py --quick
--write-data``; no JSBSim needed): ``flightid run --json`` gives a global-model stage whose
results.json follows the schema, and the model it writes predicts the JSBSim truth stored
in the data (``truth_CL``, ``truth_CD``, ``truth_Cm``) on the held-out maneuvers that the
case does not fit, an independent reference."""

from __future__ import annotations

import contextlib
import io
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from flightid.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "examples" / "cases" / "globalmodel_f16.toml"
DATA = ROOT / "examples" / "data" / "globalmodel_f16"
COEFFICIENTS = ("CL", "CD", "Cm")
VARIABLES = {"alpha": "alpha_rad", "Mach": "Mach", "de": "de_rad", "qhat": "qhat",
             "lef": "lef_rad"}  # fmt: skip


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """``flightid run --json --quiet --out`` on the shipped case: (results.json as printed,
    the output folder)."""
    out = tmp_path_factory.mktemp("globalmodel_f16") / "run"
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        code = main(["run", str(CASE), "--json", "--quiet", "--out", str(out)])
    assert code == 0
    return json.loads(buffer.getvalue()), out


def test_the_shipped_data_are_small_and_complete():
    index = json.loads((DATA / "flights.json").read_text(encoding="utf-8"))
    assert len(index) == 18 and sum(e["held_out"] for e in index) == 6
    total = sum(p.stat().st_size for p in DATA.iterdir())
    assert total < 400_000
    case = tomllib.loads(CASE.read_text(encoding="utf-8"))
    # the case fits the maneuvers not held out, every one of them
    assert case["data"]["files"] == [e["file"] for e in index if not e["held_out"]]


def test_the_case_runs_and_selects_its_terms(run):
    document, _ = run
    (stage,) = document["stages"]
    assert stage["kind"] == "global_model"
    model = stage["global_model"]
    assert [v["name"] for v in model["variables"]] == list(VARIABLES)
    counts = {c: len(model["coefficients"][c]["terms"]) for c in COEFFICIENTS}
    # regression values (this data, these settings): the quick study fits the same samples
    # (50 Hz decimated by 5) with the same settings and prints the same counts
    assert counts == {"CL": 46, "CD": 64, "Cm": 68}, counts
    for c in COEFFICIENTS:
        entry = model["coefficients"][c]
        assert entry["terms"][0]["term"] == "1"
        assert counts[c] < entry["n_candidates"]
    assert len(model["sources"]) == 12


def test_results_json_follows_the_schema(run):
    jsonschema = pytest.importorskip("jsonschema")
    document, _ = run
    schema = json.loads((ROOT / "docs" / "schema" / "results.schema.json").read_text())
    jsonschema.validate(document, schema)


def test_the_model_predicts_the_held_out_truth(run):
    """On the held-out maneuvers: the model's RMS error against JSBSim's truth, where the
    model says it is inside its support, is within 10 % of each coefficient's spread over
    the data and below 0.01."""
    from flightid.globalmodel import load_global_model

    _, out = run
    model = load_global_model(out / "global_model.json")
    index = json.loads((DATA / "flights.json").read_text(encoding="utf-8"))
    held = [np.genfromtxt(DATA / e["file"], delimiter=",", names=True)
            for e in index if e["held_out"]]  # fmt: skip
    fitted = [np.genfromtxt(DATA / e["file"], delimiter=",", names=True)
              for e in index if not e["held_out"]]  # fmt: skip
    points = {v: np.concatenate([h[column] for h in held]) for v, column in VARIABLES.items()}
    predictions = model.predict(points)
    for c in COEFFICIENTS:
        truth = np.concatenate([h[f"truth_{c}"] for h in held])
        spread = np.std(np.concatenate([f[f"truth_{c}"] for f in fitted]))
        p = predictions[c]
        inside = ~np.asarray(p.outside, dtype=bool)
        assert inside.mean() > 0.8, c
        rms = np.sqrt(np.mean((p.value - truth)[inside] ** 2))
        assert rms < min(0.1 * spread, 0.01), (c, rms, spread)
