"""A global-model stage that takes its maneuvers from a ``flightid batch`` results folder
(``batch = ...``): each case's maneuvers loaded with its own ``[data]``, its record's
conditions as constant channels, failed cases skipped and listed, the sources recorded.

Reference: the batch cases' data are generated from a known coefficient function of
(alpha, Mach, de) (``truth_CL``), one Mach number per case (a column of the batch's table),
so the global model must select the generating terms and estimate them as ordinary least
squares on those terms (numpy.linalg.lstsq) does.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from flightid.cases import CaseError, load_case
from flightid.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
MACHS = {"m1": 0.3, "m2": 0.45, "m3": 0.6, "m4": 0.75}
TRUTH = {"1": 0.1, "alpha": 4.5, "alpha^2": -3.0, "alpha*Mach": 0.6, "de": 0.4}


def truth_CL(alpha, mach, de):
    return 0.1 + 4.5 * alpha - 3.0 * alpha**2 + 0.6 * mach * alpha + 0.4 * de


# one batch case: a linear model of CL (α and δe as inputs) estimated by output error
TEMPLATE = """\
title = "tiny {{ name }}"
[data]
files = ["{{ file }}"]
data_dir = "."
format = "csv"
time = "time"
[data.inputs]
alpha = "alpha"
de = "de"
[data.outputs]
CL = "CL"
[model]
type = "linear"
states = ["x"]
inputs = ["alpha", "de"]
outputs = ["CL"]
parameters = { k = -1.0, CLa = 4.0, CLde = 0.4 }
[model.derivatives]
x = ["k*x"]
[model.output_equations]
CL = ["CLa*alpha", "CLde*de"]
[parameters]
k = { value = -1.0, free = false }
[initial_state]
x = 0.0
[estimation]
solver = "mnr"
method = "rk4"
noise = "max"
[output]
figures = false
report = false
"""

TABLE = "name,file,Mach,config\n" + "".join(
    f"{name},{name}.csv,{mach},clean\n" for name, mach in MACHS.items()
)
# a fifth case whose data file is missing: it fails in the batch
FAILED_ROW = "broken,no_such_file.csv,0.9,clean\n"

STAGE = """\
[[stages]]
kind = "global_model"
name = "envelope"
batch = "out/envelope"
variables = ["alpha", "Mach", "de"]
orders = { alpha = 3, Mach = 1, de = 1 }
max_order = 3
[stages.coefficients.CL]
"""


def _write_data(directory: Path) -> None:
    """Per case (one Mach each): α sweep and elevator doublets, CL with white noise σ 0.002
    (seed 3)."""
    rng = np.random.default_rng(3)
    t = np.arange(600) * 0.05
    for k, (name, mach) in enumerate(MACHS.items()):
        alpha = 0.05 + 0.12 * (1 + np.sin(0.21 * t + k)) + 0.02 * np.sin(1.7 * t)
        de = 0.05 * np.sign(np.sin(0.9 * t + 0.5 * k)) + 0.01 * rng.standard_normal(t.size)
        cl = truth_CL(alpha, mach, de) + 0.002 * rng.standard_normal(t.size)
        rows = "\n".join(
            ",".join(f"{v:.17g}" for v in row) for row in zip(t, alpha, de, cl, strict=True)
        )
        (directory / f"{name}.csv").write_text("time,alpha,de,CL\n" + rows + "\n")


@pytest.fixture(scope="module")
def batch_folder(tmp_path_factory) -> Path:
    """A real ``flightid batch`` run (serial) over four cases and one failing case."""
    directory = tmp_path_factory.mktemp("envelope")
    _write_data(directory)
    (directory / "case.toml").write_text(TEMPLATE, encoding="utf-8")
    (directory / "conditions.csv").write_text(TABLE + FAILED_ROW, encoding="utf-8")
    (directory / "envelope.toml").write_text(
        '[batch]\ntemplate = "case.toml"\ntable = "conditions.csv"\n'
    )
    out = directory / "out" / "envelope"
    code = main(["batch", str(directory / "envelope.toml"), "--out", str(out), "--workers", "1"])
    assert code != 0 or (out / "cases" / "broken" / "batch.json").is_file()
    return directory


@pytest.fixture
def envelope(batch_folder, tmp_path) -> Path:
    """A copy of the batch's folder (data, template, results) for one test to change."""
    copy = tmp_path / "envelope"
    shutil.copytree(batch_folder, copy)
    return copy


def _case(directory: Path, stage: str = STAGE) -> Path:
    path = directory / "global.toml"
    path.write_text('title = "global model from a batch"\n' + stage)
    return path


def _record(directory: Path, case: str) -> dict:
    return json.loads((directory / "out" / "envelope" / "cases" / case / "batch.json").read_text())


def test_the_record_constants_are_those_the_batch_writes():
    from flightid.batch.task import RECORD_FILE, RECORD_VERSION
    from flightid.cases import batch_source

    assert batch_source.RECORD_FILE == RECORD_FILE
    assert batch_source.RECORD_VERSION == RECORD_VERSION


def test_the_real_batch_wrote_the_folder_the_stage_reads(batch_folder):
    record = _record(batch_folder, "m2")
    assert record["status"] != "failed" and record["conditions"]["Mach"] == 0.45
    assert _record(batch_folder, "broken")["status"] == "failed"
    assert (batch_folder / "out" / "envelope" / "cases" / "m2" / "case.toml").is_file()


def test_a_case_of_batch_stages_alone_needs_no_data_section(batch_folder):
    case = load_case(_case(batch_folder))
    assert case.data == {} and case.maneuvers == ()
    assert case.stages[0].settings["batch"] == "out/envelope"


def test_data_with_batch_stages_alone_is_a_case_error(batch_folder):
    with pytest.raises(CaseError, match=r"^data: .*batch folders"):
        load_case(_case(batch_folder, '[data]\nfiles = ["m1.csv"]\n' + STAGE))


def test_a_case_without_data_and_without_batch_stages_still_needs_data(batch_folder):
    with pytest.raises(CaseError, match=r"^data: missing section \[data\]"):
        load_case(_case(batch_folder, STAGE.replace('batch = "out/envelope"\n', "")))


def test_run_recovers_the_function_of_alpha_and_mach_from_the_batch(batch_folder, capsys):
    assert main(["run", str(_case(batch_folder)), "--json"]) == 0
    captured = capsys.readouterr()
    entry = json.loads(captured.out)["stages"][0]
    model = entry["global_model"]
    cl = {row["term"]: row["value"] for row in model["coefficients"]["CL"]["terms"]}
    assert set(cl) == set(TRUTH)
    # independent reference: least squares on the generating terms over the same samples,
    # the Mach of each sample from the batch's table
    columns, z = [], []
    for name, mach in MACHS.items():
        t, alpha, de, c = np.loadtxt(batch_folder / f"{name}.csv", delimiter=",", skiprows=1).T
        columns.append(np.column_stack([np.ones_like(t), alpha, alpha**2, alpha * mach, de]))
        z.append(c)
    theta = np.linalg.lstsq(np.vstack(columns), np.concatenate(z), rcond=None)[0]
    np.testing.assert_allclose([cl[t] for t in TRUTH], theta, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose([cl[t] for t in TRUTH], list(TRUTH.values()), atol=0.05)
    # the failed case is listed with its reason, and said as progress
    (skipped,) = entry["skipped"]
    assert skipped["case"] == "broken" and "no_such_file.csv" in skipped["reason"]
    assert "batch case broken skipped" in captured.err


def test_the_sources_are_recorded_in_the_model_file(batch_folder, tmp_path):
    out = tmp_path / "run"
    assert main(["run", str(_case(batch_folder)), "--out", str(out), "--quiet"]) == 0
    sources = json.loads((out / "global_model.json").read_text())["sources"]
    assert [(s["case"], s["conditions"]["Mach"], s["n_samples"]) for s in sources] == [
        (name, mach, 600) for name, mach in MACHS.items()
    ]
    results = json.loads((out / "results.json").read_text())
    assert results["stages"][0]["skipped"][0]["case"] == "broken"
    jsonschema = pytest.importorskip("jsonschema")
    schema = json.loads((ROOT / "docs" / "schema" / "results.schema.json").read_text())
    jsonschema.validate(results, schema)


def test_the_stage_conditions_override_the_batch_conditions(batch_folder):
    from flightid.cases.batch_source import batch_stage_data

    stage_text = STAGE + "[stages.conditions]\nm1 = { Mach = 0.35 }\n'm2/m2' = { Mach = 0.5 }\n"
    case = load_case(_case(batch_folder, stage_text))
    data = batch_stage_data(case.stages[0], case.directory)
    index = np.asarray(data.maneuver_index)
    machs = [float(np.unique(data.signals["Mach"][index == k])[0]) for k in range(4)]
    assert machs == [0.35, 0.5, 0.6, 0.75]
    assert [s.conditions["Mach"] for s in data.sources] == machs


def test_validate_fits_nothing(batch_folder, capsys, monkeypatch):
    import flightid.globalmodel as package

    def refuse(*args, **kwargs):
        raise AssertionError("validate must not fit")

    monkeypatch.setattr(package, "fit_global_model", refuse)
    assert main(["validate", str(_case(batch_folder))]) == 0
    out = capsys.readouterr().out
    assert "2400 samples from 4 batch case(s), 1 skipped" in out


def test_a_variable_not_in_the_batch_cases_is_named_by_validate(batch_folder, capsys):
    path = _case(batch_folder, STAGE.replace('"de"]', '"beta"]').replace("de = 1", "beta = 1"))
    assert main(["validate", str(path)]) != 0
    assert "stages[0].variables: ['beta'] are neither channels" in capsys.readouterr().err


def test_a_text_condition_named_in_variables_is_an_error(batch_folder, capsys):
    stage = STAGE.replace('"de"]', '"de", "config"]').replace("de = 1", "de = 1, config = 1")
    assert main(["validate", str(_case(batch_folder, stage))]) != 0
    assert "['config'] of case 'm1' are not numbers (['clean'])" in capsys.readouterr().err


def test_unreadable_records_and_missing_data_are_skipped(envelope, capsys):
    cases = envelope / "out" / "envelope" / "cases"
    (cases / "m3" / "batch.json").write_text("{not json")
    # m4 read as if it had run from the copy, whose data file is gone
    record = _record(envelope, "m4")
    record["case_path"] = str(envelope / "case.toml")
    (cases / "m4" / "batch.json").write_text(json.dumps(record))
    (envelope / "m4.csv").unlink()
    assert main(["validate", str(_case(envelope))]) == 0
    out = capsys.readouterr().out
    assert "1200 samples from 2 batch case(s), 3 skipped" in out
    assert "skipped m3: record batch.json unreadable" in out
    assert "skipped m4: " in out and str(envelope / "m4.csv") in out


def test_no_usable_case_is_a_case_error_naming_the_folder(envelope):
    cases = envelope / "out" / "envelope" / "cases"
    for name in MACHS:
        record = json.loads((cases / name / "batch.json").read_text())
        (cases / name / "batch.json").write_text(json.dumps({**record, "status": "failed"}))
    case = load_case(_case(envelope))
    from flightid.cases.stages import run_stages

    with pytest.raises(CaseError, match="no usable case") as raised:
        run_stages(case)
    assert str(envelope / "out" / "envelope") in str(raised.value)


def test_a_missing_batch_folder_is_a_case_error_with_its_path(batch_folder, tmp_path):
    from flightid.cases.stages import run_stages

    case = load_case(_case(batch_folder, STAGE.replace("out/envelope", str(tmp_path / "none"))))
    with pytest.raises(CaseError, match=r"stages\[0\]\.batch: .* does not exist") as raised:
        run_stages(case)
    assert str(tmp_path / "none") in str(raised.value)


def test_the_data_dir_option_applies_to_every_batch_case(envelope, capsys):
    moved = envelope / "moved"
    moved.mkdir()
    cases = envelope / "out" / "envelope" / "cases"
    for name in MACHS:
        (envelope / f"{name}.csv").rename(moved / f"{name}.csv")
        # each case as if it had run from the copy (its data_dir "." is now empty)
        record = _record(envelope, name)
        record["case_path"] = str(envelope / "case.toml")
        (cases / name / "batch.json").write_text(json.dumps(record))
    path = str(_case(envelope))
    assert main(["validate", path]) != 0
    assert "no usable case" in capsys.readouterr().err
    assert main(["validate", path, "--data-dir", str(moved)]) == 0
    assert "2400 samples from 4 batch case(s), 1 skipped" in capsys.readouterr().out
