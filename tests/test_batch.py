"""flightid batch on the serial engine: template expansion, the results table's contract,
failed cases, skip / resume by fingerprint, the Parquet notice, carpet plots and index page.

The Dask engine (2-worker LocalCluster, a killed worker) is in test_batch_dask.py. Cases on
the real flight data (../shared/data) are skipped when it is absent.
"""

from __future__ import annotations

import csv
import os
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from flightid.batch import BatchCase, BatchError, expand_template, plan_cases, run_batch
from flightid.batch.engine import make_engine
from flightid.batch.table import FIXED_COLUMNS
from flightid.cases import load_case, run_case
from flightid.cases.spec import parse_case
from flightid.cli.main import main
from flightid.parallel import SerialEngine

ROOT = Path(__file__).resolve().parents[1]
CASES = ROOT / "examples" / "cases"
MODEL = ROOT / "examples" / "models" / "attas_short_period.py"
DATA = Path(os.environ.get("FLIGHTID_DATA", ROOT / "../shared/data")).resolve()
needs_data = pytest.mark.skipif(
    not (DATA / "fvsysid").is_dir(),
    reason=f"real flight data not found at {DATA} (set FLIGHTID_DATA)",
)

# a template of the ATTAS short-period case on one maneuver: data file, a start value and the
# title from the table (the model module and the data folder as absolute paths)
TEMPLATE = f"""\
title = "ATTAS short period, {{{{ label }}}}"

[data]
files = ["fvsysid/{{{{file}}}}"]
time = 1
data_dir = "{DATA}"

[data.inputs]
de = {{ column = 22, unit = "deg", to = "rad" }}

[data.outputs]
alpha = {{ column = 13, unit = "deg", to = "rad" }}
q = {{ column = 8, unit = "deg/s", to = "rad/s" }}

[model]
module = "{MODEL}"

[parameters]
Ma = {{ value = {{{{Ma0}}}} }}

[initial_state]
default = "measured"

[estimation]
solver = "mnres"
method = "rk4"
noise = "max"

[output]
figures = false
"""

HEADER = "name,file,label,Ma0,mach\n"
TABLE = HEADER + "elv1,fAttasElv1.mat,Elv1,-2.7,0.4\nelv2,fAttasElv2.mat,Elv2,-2.5,0.5\n"


def _template(tmp_path: Path, table: str = TABLE, template: str = TEMPLATE) -> Path:
    (tmp_path / "case.toml").write_text(template, encoding="utf-8")
    (tmp_path / "conditions.csv").write_text(table, encoding="utf-8")
    batch = tmp_path / "envelope.toml"
    batch.write_text('[batch]\ntemplate = "case.toml"\ntable = "conditions.csv"\n')
    return batch


def _fast(name: str, extra: str = "") -> BatchCase:
    """A shipped case without figures (faster reports), lying where the shipped file lies."""
    path = CASES / f"{name}.toml"
    text = path.read_text(encoding="utf-8") + "\n[output]\nfigures = false\n" + extra
    return BatchCase(name, text, path, {}, path)


def _read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8", newline="") as stream:
        return list(csv.DictReader(stream))


# ------------------------------------------------------------------ planning (no data needed)


def test_template_rows_fill_placeholders_and_carry_conditions(tmp_path):
    cases = expand_template(_template(tmp_path))
    assert [c.name for c in cases] == ["elv1", "elv2"]
    first = cases[0]
    assert "{{" not in first.text
    raw = tomllib.loads(first.text)
    assert raw["data"]["files"] == ["fvsysid/fAttasElv1.mat"]
    assert raw["parameters"]["Ma"]["value"] == -2.7
    assert raw["title"] == "ATTAS short period, Elv1"
    # numbers where the cell is a number, text otherwise; the name is not a condition
    assert first.conditions == {"file": "fAttasElv1.mat", "label": "Elv1", "Ma0": -2.7, "mach": 0.4}
    # the expanded case lies beside the template: relative paths resolve from there
    assert first.path == (tmp_path / "elv1.toml").resolve()
    case = parse_case(raw, first.path)
    assert case.maneuvers[0].file == "fvsysid/fAttasElv1.mat"


def test_inline_rows_are_a_table_too(tmp_path):
    (tmp_path / "case.toml").write_text(TEMPLATE, encoding="utf-8")
    batch = tmp_path / "b.toml"
    batch.write_text(
        '[batch]\ntemplate = "case.toml"\n'
        '[[batch.cases]]\nname = "a"\nfile = "fAttasElv1.mat"\nlabel = "A"\n'
        "Ma0 = -2.6\nmach = 0.45\n"
    )
    (case,) = expand_template(batch)
    assert tomllib.loads(case.text)["parameters"]["Ma"]["value"] == -2.6
    assert case.conditions["mach"] == 0.45


@pytest.mark.parametrize(
    ("table", "template", "message"),
    [
        # a placeholder of the template without a column
        ("name,file,label,mach\nx,f.mat,X,0.4\n", TEMPLATE, r"row 1: .*Ma0.*no column 'Ma0'"),
        # an empty cell for a placeholder in the second row
        (TABLE + "elv3,,E3,-2.4,0.6\n", TEMPLATE, r"row 3: no value in column 'file'"),
        # a value that would change the TOML around it
        (HEADER + 'x,"a""b",X,-2,0.4\n', TEMPLATE, r"row 1, column 'file'.*quote"),
        # names: missing, repeated, not a folder name
        (HEADER + ",f.mat,X,-2,0.4\n", TEMPLATE, r"row 1: no value in column 'name'"),
        (TABLE + "elv1,f.mat,X,-2,0.4\n", TEMPLATE, r"row 3: name 'elv1' repeats row 1"),
        (HEADER + "a/b,f.mat,X,-2,0.4\n", TEMPLATE, r"row 1: name 'a/b'"),
        # a substitution that breaks the TOML
        (HEADER + "x,f.mat,X,-2 -3,0.4\n", TEMPLATE, r"row 1: the expanded template is not valid"),
    ],
    ids=["no-column", "empty-cell", "quote", "no-name", "repeated-name", "bad-name", "bad-toml"],
)
def test_bad_rows_are_named_errors(tmp_path, table, template, message):
    with pytest.raises(BatchError, match=message):
        expand_template(_template(tmp_path, table, template))


def test_case_files_plan_by_stem_and_names_must_be_unique(tmp_path):
    cases = plan_cases([CASES / "attas_short_period.toml", CASES / "hfb320_longitudinal.toml"])
    assert [c.name for c in cases] == ["attas_short_period", "hfb320_longitudinal"]
    copy = tmp_path / "attas_short_period.toml"
    copy.write_text((CASES / "attas_short_period.toml").read_text())
    with pytest.raises(BatchError, match="two cases are named 'attas_short_period'"):
        plan_cases([CASES / "attas_short_period.toml", copy])
    with pytest.raises(BatchError, match="does not exist"):
        plan_cases([tmp_path / "nothing.toml"])


def test_engine_choice():
    assert isinstance(make_engine(1), SerialEngine)
    assert "--workers 1" in make_engine(1).description
    # by default one worker per core, at most one per case: one case runs here
    assert "one case to run" in make_engine(None, None, n_tasks=1).description
    with pytest.raises(BatchError.__mro__[1], match="--workers: expected a number"):
        make_engine(0)


def test_without_dask_the_batch_runs_serially(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    engine = make_engine(4)
    assert isinstance(engine, SerialEngine)
    assert "Dask is not installed" in engine.description


# ------------------------------------------------------------------ batches on real data


@needs_data
def test_serial_batch_table_contract_and_failed_case(tmp_path):
    bad = _fast("attas_short_period").text.replace("fAttasElv2.mat", "no_such_file.mat")
    cases = [
        _fast("attas_short_period"),
        BatchCase("broken", bad, CASES / "broken.toml", {}, None),
    ]
    messages: list[str] = []
    result = run_batch(cases, tmp_path / "out", workers=1, data_dir=DATA, progress=messages.append)
    assert result.ran == ("attas_short_period", "broken") and result.failed == ("broken",)
    assert any("engine serial" in m for m in messages)
    assert any("2/2 done" in m and "1 failed" in m for m in messages)
    rows = _read_csv(tmp_path / "out" / "estimates.csv")
    assert list(rows[0]) == ["case", *FIXED_COLUMNS]
    ok = [r for r in rows if r["case"] == "attas_short_period"]
    (failed,) = [r for r in rows if r["case"] == "broken"]
    assert failed["status"] == "failed" and "no_such_file.mat" in failed["error"]
    assert failed["value"] == "" and failed["converged"] == "False"
    # the independent path: run_case on the same case gives the same numbers
    direct = run_case(load_case(CASES / "attas_short_period.toml"), DATA).estimate
    assert [r["parameter"] for r in ok] == list(direct.names)
    np.testing.assert_array_equal([float(r["value"]) for r in ok], direct.values)
    np.testing.assert_array_equal([float(r["std"]) for r in ok], direct.std)
    assert all(r["status"] == direct.status and r["converged"] == "True" for r in ok)
    assert all(float(r["coloured_std"]) > 0 for r in ok)
    # the Parquet file holds the same table
    import pyarrow.parquet as pq

    table = pq.read_table(tmp_path / "out" / "estimates.parquet").to_pylist()
    assert [t["value"] for t in table[: len(ok)]] == [float(r["value"]) for r in ok]
    assert table[-1]["status"] == "failed" and table[-1]["value"] is None
    # each case's report, as flightid run writes it, and the index page linking it
    folder = tmp_path / "out" / "cases" / "attas_short_period"
    assert {"results.json", "estimates.csv", "report.html", "batch.json"} <= {
        p.name for p in folder.iterdir()
    }
    index = (tmp_path / "out" / "index.html").read_text()
    assert "cases/attas_short_period/report.html" in index and "no_such_file.mat" in index


@needs_data
def test_rerun_skips_unchanged_cases_and_reruns_a_changed_one(tmp_path):
    out = tmp_path / "out"
    a, b = _fast("attas_short_period"), _fast("attas_fpr_biases")
    first = run_batch([a, b], out, workers=1, data_dir=DATA)
    assert first.ran == ("attas_short_period", "attas_fpr_biases")
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("cases/*/batch.json")}
    again = run_batch([a, b], out, workers=1, data_dir=DATA)
    assert again.ran == () and again.skipped == ("attas_short_period", "attas_fpr_biases")
    assert {p: p.stat().st_mtime_ns for p in out.glob("cases/*/batch.json")} == stamps
    assert [(r["fingerprint"], r["rows"]) for r in again.records] == [
        (r["fingerprint"], r["rows"]) for r in first.records
    ]
    # one case's text changes (a comment is enough: the case text is in the fingerprint)
    changed = BatchCase(b.name, b.text + "# changed\n", b.path, {}, b.path)
    third = run_batch([a, changed], out, workers=1, data_dir=DATA)
    assert third.ran == ("attas_fpr_biases",) and third.skipped == ("attas_short_period",)
    # another accuracy option is another fingerprint
    fourth = run_batch([a], out, workers=1, data_dir=DATA, accuracy="cr")
    assert fourth.ran == ("attas_short_period",)


@needs_data
def test_an_interrupted_batch_resumes(tmp_path, monkeypatch):
    out = tmp_path / "out"
    cases = [_fast("attas_short_period"), _fast("attas_fpr_biases")]

    class Interrupting(SerialEngine):
        def map_unordered(self, fn, tasks):
            for i, task in enumerate(tasks):
                if i == 1:
                    raise KeyboardInterrupt  # Ctrl-C while the second case runs
                yield task, fn(task), None

    with pytest.raises(KeyboardInterrupt):
        run_batch(cases, out, engine=Interrupting(), data_dir=DATA)
    # the table of what finished was written on the way out
    assert {r["case"] for r in _read_csv(out / "estimates.csv")} == {"attas_short_period"}
    resumed = run_batch(cases, out, workers=1, data_dir=DATA)
    assert resumed.skipped == ("attas_short_period",) and resumed.ran == ("attas_fpr_biases",)
    assert {r["case"] for r in _read_csv(out / "estimates.csv")} == {
        "attas_short_period",
        "attas_fpr_biases",
    }


@needs_data
def test_template_batch_plots_and_no_parquet_notice(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # pyarrow not installed
    messages: list[str] = []
    result = run_batch(
        [_template(tmp_path)],
        tmp_path / "out",
        workers=1,
        plot_against="mach",
        progress=messages.append,
    )
    assert result.failed == ()
    rows = _read_csv(tmp_path / "out" / "estimates.csv")
    assert list(rows[0])[:5] == ["case", "file", "label", "Ma0", "mach"]
    assert {(r["case"], r["mach"]) for r in rows} == {("elv1", "0.4"), ("elv2", "0.5")}
    assert not (tmp_path / "out" / "estimates.parquet").exists()
    (notice,) = [m for m in messages if "parquet" in m.lower()]
    assert "pyarrow is not installed" in notice and "\n" not in notice
    plots = sorted(p.name for p in (tmp_path / "out" / "plots").iterdir())
    assert "Ma_vs_mach.png" in plots and len(plots) == 8
    index = (tmp_path / "out" / "index.html").read_text()
    assert "plots/Ma_vs_mach.png" in index and "estimates.parquet" not in index
    with pytest.raises(BatchError, match="--plot-against 'altitude': no such column"):
        run_batch([_template(tmp_path)], tmp_path / "out", workers=1, plot_against="altitude")


def test_cli_errors_are_one_line(tmp_path, capsys):
    code = main(["batch", str(tmp_path / "missing.toml"), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    missing = tmp_path / "missing.toml"
    assert code == 1 and err == [f"flightid: error: case file: {missing} does not exist"]
    (tmp_path / "case.toml").write_text("title = 'x {{nope}}'\n")
    (tmp_path / "b.toml").write_text('[batch]\ntemplate = "case.toml"\ntable = "t.csv"\n')
    (tmp_path / "t.csv").write_text("name\nr1\n")
    assert main(["batch", str(tmp_path / "b.toml"), "--out", str(tmp_path / "o")]) == 1
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("flightid: error: batch file") and "row 1" in line and "nope" in line


ENVELOPE = ROOT / "examples" / "batch" / "envelope.toml"


def test_the_shipped_envelope_expands_to_valid_cases():
    cases = plan_cases([ENVELOPE])
    assert [c.name for c in cases] == ["attas_elv1", "attas_elv2", "hfb320_3211"]
    for case in cases:
        parsed = parse_case(tomllib.loads(case.text), case.path)
        assert parsed.model["module"] == "../models/attas_short_period.py"
        assert isinstance(case.conditions["V_mps"], float)
    hfb = parse_case(tomllib.loads(cases[2].text), cases[2].path)
    assert hfb.maneuvers[0].file == "fvsysid/hfb320_1_10.asc"
    assert hfb.data["outputs"]["alpha"] == {"column": 6, "unit": "rad", "to": "rad"}


@pytest.mark.slow
@needs_data
def test_the_shipped_envelope_runs(tmp_path):
    result = run_batch([ENVELOPE], tmp_path, workers=1, data_dir=DATA, plot_against="V_mps")
    assert result.failed == ()
    rows = _read_csv(tmp_path / "estimates.csv")
    assert len(rows) == 3 * 8 and all(r["status"] == "converged" for r in rows)
    assert (tmp_path / "plots" / "Ma_vs_V_mps.png").is_file()
