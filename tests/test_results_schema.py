"""results.json follows its versioned JSON Schema (docs/schema/results.schema.json), and the
time histories are written beside it."""

from __future__ import annotations

import contextlib
import copy
import csv
import io
import json
import shutil
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from flightid.cli.main import main
from flightid.results import SCHEMA_VERSION

ROOT = Path(__file__).resolve().parents[1]
SCHEMA = ROOT / "docs" / "schema" / "results.schema.json"
CSV_CASE = ROOT / "examples" / "csv_walkthrough" / "my_case.toml"


@pytest.fixture(scope="module")
def schema() -> dict:
    document = json.loads(SCHEMA.read_text(encoding="utf-8"))
    jsonschema.Draft202012Validator.check_schema(document)
    return document


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """One `flightid run --json --out` of the CSV walk-through case (a copy in which M_α has a
    unit), with profile limits: (result folder, printed document, printed text)."""
    folder = tmp_path_factory.mktemp("case")
    shutil.copytree(CSV_CASE.parent, folder, dirs_exist_ok=True)
    case = folder / CSV_CASE.name
    text = case.read_text(encoding="utf-8")
    assert text.count("Ma = -3.0") == 1
    text = text.replace("Ma = -3.0", 'Ma = { value = -3.0, unit = "1/s²" }')
    # the same flight once more as a held-out prediction maneuver
    case.write_text(text + '\n[prediction]\nfile = "my_flight.csv"\n', "utf-8")
    out = folder / "run"
    stream = io.StringIO()
    with contextlib.redirect_stdout(stream):
        code = main(["run", str(case), "--json", "--out", str(out), "--accuracy", "profile"])
    assert code == 0
    printed = json.loads(stream.getvalue())
    stream = io.StringIO()
    with contextlib.redirect_stdout(stream):
        assert main(["run", str(case), "--accuracy", "none", "--quiet"]) == 0
    return out, printed, stream.getvalue()


def _validator(schema: dict) -> jsonschema.Draft202012Validator:
    return jsonschema.Draft202012Validator(schema)


def test_results_json_of_a_run_validates(schema, written):
    out, printed, _ = written
    document = json.loads((out / "results.json").read_text(encoding="utf-8"))
    _validator(schema).validate(document)
    _validator(schema).validate(printed)  # the --json output is the same document
    assert document["schema_version"] == SCHEMA_VERSION == "1"
    (entry,) = document["results"]
    assert entry["output_units"] == ["rad", "rad/s"]
    assert all("ci_profile" in p and "unit" in p for p in entry["parameters"])
    assert document["results"] == printed["results"]


def test_the_schema_rejects_what_it_describes_as_wrong(schema, written):
    # the schema is not a rubber stamp: a wrong version, a missing key, a wrong type fail
    document = json.loads((written[0] / "results.json").read_text(encoding="utf-8"))
    validator = _validator(schema)
    wrong = copy.deepcopy(document)
    wrong["schema_version"] = "2"
    assert not validator.is_valid(wrong)
    wrong = copy.deepcopy(document)
    del wrong["results"][0]["parameters"][0]["unit"]
    assert not validator.is_valid(wrong)
    wrong = copy.deepcopy(document)
    wrong["results"][0]["parameters"][0]["ci_cr"] = [1.0]
    assert not validator.is_valid(wrong)
    wrong = copy.deepcopy(document)
    wrong["results"][0]["status"] = "finished"
    assert not validator.is_valid(wrong)


def test_time_histories_are_written_beside_results_json(written):
    out, _, _ = written
    document = json.loads((out / "results.json").read_text(encoding="utf-8"))
    histories = document["time_histories"]
    path = out / histories["file"]
    assert path.name == "time_histories.csv"
    with path.open(newline="", encoding="utf-8") as stream:
        rows = list(csv.reader(stream))
    assert rows[0] == [c["name"] for c in histories["columns"]]
    (maneuver,) = document["results"][0]["maneuvers"]
    (prediction,) = document["results"][0]["prediction"]
    n = maneuver["samples"]
    assert len(rows) - 1 == n + prediction["samples"] == 2 * n
    units = {c["name"]: c["unit"] for c in histories["columns"]}
    assert units["alpha_measured"] == "rad" and units["de"] == "rad"
    header, estimation, predicted = rows[0], rows[1 : n + 1], rows[n + 1 :]
    assert {r[1] for r in estimation} == {"estimation"}
    assert {r[1] for r in predicted} == {"prediction"}
    # the held-out maneuver is the same flight: same time, input and measurements
    assert [r[2:5] for r in predicted] == [r[2:5] for r in estimation]
    # its residuals are measured − predicted of its own simulation, RMS as in results.json
    q = header.index("q_residual")
    residual = np.array([float(r[q]) for r in predicted])
    np.testing.assert_allclose(
        np.sqrt(np.mean(residual**2)), prediction["rms_error"][1], rtol=1e-12
    )


def test_a_parameter_unit_shows_in_summary_json_csv_and_report(written):
    out, printed, text = written
    (entry,) = printed["results"]
    units = {p["name"]: p["unit"] for p in entry["parameters"]}
    assert units["Ma"] == "1/s²" and units["Mq"] == ""
    with (out / "estimates.csv").open(newline="", encoding="utf-8") as stream:
        rows = {row["name"]: row for row in csv.DictReader(stream)}
    assert rows["Ma"]["unit"] == "1/s²"
    line = next(line for line in text.splitlines() if line.startswith("Ma "))
    assert "1/s²" in line
    assert "1/s²" in (out / "report.html").read_text(encoding="utf-8")


def test_an_output_error_run_names_its_method_and_roles(written):
    out, printed, text = written
    (entry,) = printed["results"]
    assert text.splitlines()[0].startswith("flightid output-error estimate — ")
    # the status line names the status once (the message's own "converged:" is dropped)
    (status,) = [line for line in text.splitlines() if line.startswith("status: ")]
    assert status.startswith(f"status: {entry['status']} — ")
    assert status.count(f"{entry['status']}:") == 0 and entry["message"].endswith(
        status.split(" — ", 1)[1]
    )
    assert entry["estimator"] == "output_error" and entry["solved"] == []
    assert {p["role"] for p in entry["parameters"]} <= {"free", "fixed"}
    with (out / "estimates.csv").open(newline="", encoding="utf-8") as stream:
        rows = list(csv.DictReader(stream))
    assert all(row["role"] == ("free" if row["free"] == "True" else "fixed") for row in rows)


def test_a_staged_run_validates(schema, tmp_path):
    """A case with [[stages]] (regression stage, then output error from it) validates, its
    "stages" entries included; the data are the walk-through's, its coefficient a channel."""
    shutil.copytree(CSV_CASE.parent, tmp_path, dirs_exist_ok=True)
    case = tmp_path / CSV_CASE.name
    text = case.read_text(encoding="utf-8")
    # a regression stage on the measured q (as a stand-in coefficient), then output error
    head, _, _ = text.partition("[estimation]")
    staged = head + (
        '\n[[stages]]\nkind = "regression"\n'
        '[stages.coefficients.qfit]\nresponse = "q"\nterms = ["alpha", "de"]\n'
        '\n[[stages]]\nkind = "output_error"\nsolver = "mnr"\ninput_interpolation = "zoh"\n'
    )
    case.write_text(staged, "utf-8")
    stream = io.StringIO()
    with contextlib.redirect_stdout(stream):
        assert main(["run", str(case), "--json", "--quiet", "--accuracy", "none"]) == 0
    document = json.loads(stream.getvalue())
    assert [s["kind"] for s in document["stages"]] == ["regression", "output_error"]
    _validator(schema).validate(document)
    wrong = copy.deepcopy(document)
    wrong["stages"][0]["kind"] = "bootstrap"
    assert not _validator(schema).is_valid(wrong)
