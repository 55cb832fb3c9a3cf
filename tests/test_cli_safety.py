"""Result folders and CLI output are safe (issue 10 §5).

The output folder is checked and locked before estimating, written all at once, never mixed
with another run; an interrupt or a write failure leaves no half-written run; every JSON
document is strict; every failure is one line ``flightid: error: ...`` (a traceback only with
``--debug``).

Runs are made fast by a cut-down copy of the CSV walk-through (3 s of data, pure Python,
3 passes, no figures) estimated once per module; CLI tests that do not need a fresh
estimation get that run through a patched ``run_case``.
"""

from __future__ import annotations

import dataclasses
import errno
import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

# flightid.cli.run imports run_case from flightid.cases when the command runs (so that
# `flightid --help` stays light): the tests patch it there
import flightid.cases as cli_run
import flightid.report.folder as folder_module
import flightid.report.html as html_module
from flightid import jsonout
from flightid.cases import load_case, run_case
from flightid.cases.run import Prediction
from flightid.cli.main import main
from flightid.errors import InputError
from flightid.report.folder import RUN_MARKER, OutputError, ResultFolder, write_manifest
from flightid.report.html import write_files, write_report

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "examples/csv_walkthrough"


def _strict_loads(text: str):
    """json.loads that refuses NaN / Infinity (which Python's json accepts by default)."""

    def refuse(name: str):
        raise ValueError(f"non-standard JSON constant {name}")

    return json.loads(text, parse_constant=refuse)


def _small_case(directory: Path) -> Path:
    target = directory / "walk"
    shutil.copytree(WALK, target)
    case = target / "my_case.toml"
    text = case.read_text()
    text = text.replace('time = "time"', 'time = "time"\nstop = 3.0')
    text = text.replace("[estimation]\n", "[estimation]\ncompiled = false\n")
    text += "\n[estimation.convergence]\nmax_iterations = 3\n[output]\nfigures = false\n"
    case.write_text(text)
    return case


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """(case file, CaseRun) of the cut-down walk-through."""
    case = _small_case(tmp_path_factory.mktemp("small"))
    return case, run_case(load_case(case))


@pytest.fixture()
def fake_run(small, monkeypatch):
    """``flightid run`` returns the module's run without estimating; yields the case file."""
    case, result = small
    calls = []

    def fake(*args, **kwargs):
        calls.append(args)
        return result

    monkeypatch.setattr(cli_run, "run_case", fake)
    return case, calls


@pytest.fixture()
def no_estimation(small, monkeypatch):
    """``flightid run`` must fail before estimating: run_case may not be called."""

    def forbidden(*args, **kwargs):
        raise AssertionError("run_case was called although --out is unusable")

    monkeypatch.setattr(cli_run, "run_case", forbidden)
    return small[0]


def _leftovers(parent: Path) -> list[str]:
    """Temporary folders, set-aside runs and lock files flightid might leave in ``parent``."""
    return sorted(
        p.name
        for p in parent.iterdir()
        if ".flightid-tmp-" in p.name or ".flightid-old-" in p.name or "flightid-lock" in p.name
    )


def _old_run(directory: Path) -> None:
    """A folder as an earlier run left it, with a figure the new run would not write."""
    (directory / "figures").mkdir(parents=True)
    (directory / "results.json").write_text('{"results": ["old"]}')
    (directory / "report.html").write_text("old report")
    (directory / "figures" / "fit_9_stale.png").write_bytes(b"stale")
    write_manifest(directory)  # as flightid writes it: --overwrite may replace the folder


def _one_error_line(stderr: str) -> str:
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith("flightid: error: "), stderr
    assert "Traceback" not in stderr
    return lines[0]


# ------------------------------------------------------------------ checked before estimating


def test_out_that_is_a_file_is_refused_before_estimating(no_estimation, tmp_path, capsys):
    target = tmp_path / "results"
    target.write_text("not a folder")
    assert main(["run", str(no_estimation), "--out", str(target), "--quiet"]) == 1
    line = _one_error_line(capsys.readouterr().err)
    assert "exists and is a file" in line and str(target) in line
    assert target.read_text() == "not a folder"


def test_out_with_missing_parents_makes_them(no_estimation, tmp_path, capsys):
    # `--out out/my_flight` on a fresh checkout: the parents are made (as mkdir -p) before
    # the estimation starts (which this fixture stops with an error)
    target = tmp_path / "no" / "such" / "run"
    main(["run", str(no_estimation), "--out", str(target), "--quiet"])
    assert (tmp_path / "no" / "such").is_dir()
    assert "parent folder" not in capsys.readouterr().err


def test_out_under_a_file_is_refused_before_estimating(no_estimation, tmp_path, capsys):
    (tmp_path / "plain").write_text("a file")
    target = tmp_path / "plain" / "sub" / "run"
    assert main(["run", str(no_estimation), "--out", str(target), "--quiet"]) == 1
    line = _one_error_line(capsys.readouterr().err)
    assert "cannot be made: part of its path is a file" in line
    assert (tmp_path / "plain").read_text() == "a file"


def test_unwritable_out_is_refused_before_estimating(no_estimation, tmp_path, capsys, monkeypatch):
    # the tests may run as root, for whom chmod does not forbid anything: the permission
    # check itself is made to say no
    monkeypatch.setattr(folder_module.os, "access", lambda path, mode: False)
    assert main(["run", str(no_estimation), "--out", str(tmp_path / "run"), "--quiet"]) == 1
    assert "permission denied" in _one_error_line(capsys.readouterr().err)


def test_full_disk_is_refused_before_estimating(no_estimation, tmp_path, capsys, monkeypatch):
    usage = shutil.disk_usage(tmp_path)._replace(free=4096)
    monkeypatch.setattr(folder_module.shutil, "disk_usage", lambda path: usage)
    assert main(["run", str(no_estimation), "--out", str(tmp_path / "run"), "--quiet"]) == 1
    assert "is full (4096 bytes free" in _one_error_line(capsys.readouterr().err)


def test_folder_holding_a_run_is_not_overwritten_without_asking(no_estimation, tmp_path, capsys):
    target = tmp_path / "run"
    _old_run(target)
    before = {p: p.read_bytes() for p in target.rglob("*") if p.is_file()}
    assert main(["run", str(no_estimation), "--out", str(target), "--quiet"]) == 1
    line = _one_error_line(capsys.readouterr().err)
    assert "already holds a flightid run" in line and "--overwrite" in line
    assert {p: p.read_bytes() for p in target.rglob("*") if p.is_file()} == before


def test_run_of_an_older_flightid_without_marker_counts_as_a_run(tmp_path):
    target = tmp_path / "run"
    target.mkdir()
    (target / "report.html").write_text("older flightid")
    with pytest.raises(OutputError, match=r"already holds a flightid run \(report.html\)"):
        ResultFolder.open(target)


# ------------------------------------------------------------------ written whole, in place


def test_overwrite_replaces_the_whole_folder(fake_run, tmp_path, capsys):
    case, _ = fake_run
    target = tmp_path / "run"
    _old_run(target)
    assert main(["run", str(case), "--out", str(target), "--overwrite", "--quiet"]) == 0
    names = sorted(p.relative_to(target).as_posix() for p in target.rglob("*"))
    # figures = false in this case: no figures folder, and nothing of the old run survives
    assert names == sorted(
        [RUN_MARKER, "estimates.csv", "report.html", "results.json", "time_histories.csv"]
    )
    document = _strict_loads((target / "results.json").read_text())
    assert document["results"][0]["parameters"]
    assert _leftovers(tmp_path) == []


def test_new_and_empty_folders_are_used(fake_run, tmp_path):
    case, _ = fake_run
    empty = tmp_path / "empty"
    empty.mkdir()
    for target in (tmp_path / "new", empty):
        assert main(["run", str(case), "--out", str(target), "--quiet"]) == 0
        assert (target / "results.json").is_file() and (target / RUN_MARKER).is_file()
    assert _leftovers(tmp_path) == []


def test_folder_with_other_files_keeps_them(fake_run, tmp_path):
    case, _ = fake_run
    target = tmp_path / "mine"
    target.mkdir()
    (target / "flight_notes.txt").write_text("keep me")
    assert main(["run", str(case), "--out", str(target), "--quiet"]) == 0
    assert (target / "flight_notes.txt").read_text() == "keep me"
    assert {"results.json", "report.html", "estimates.csv", RUN_MARKER} <= set(os.listdir(target))
    assert _leftovers(tmp_path) == []


def test_second_writer_is_refused_while_the_first_holds_the_folder(fake_run, tmp_path, capsys):
    case, calls = fake_run
    target = tmp_path / "run"
    with ResultFolder.open(target):
        assert main(["run", str(case), "--out", str(target), "--quiet"]) == 1
        line = _one_error_line(capsys.readouterr().err)
        assert f"another flightid run is writing to {target}" in line
        assert calls == []  # refused before estimating
    # the lock is gone with the first writer
    assert main(["run", str(case), "--out", str(target), "--quiet"]) == 0
    assert _leftovers(tmp_path) == []


def test_lock_is_released_when_the_estimation_fails(small, tmp_path, monkeypatch, capsys):
    def failing(*args, **kwargs):
        raise InputError("estimation went wrong")

    monkeypatch.setattr(cli_run, "run_case", failing)
    target = tmp_path / "run"
    assert main(["run", str(small[0]), "--out", str(target), "--quiet"]) == 1
    assert _one_error_line(capsys.readouterr().err) == "flightid: error: estimation went wrong"
    assert not target.exists() and _leftovers(tmp_path) == []


def test_temporary_folders_of_a_killed_run_are_cleared(fake_run, tmp_path):
    case, _ = fake_run
    stale = tmp_path / ".run.flightid-tmp-abc123"
    stale.mkdir()
    (stale / "results.json").write_text("{")
    assert main(["run", str(case), "--out", str(tmp_path / "run"), "--quiet"]) == 0
    assert not stale.exists()


# ------------------------------------------------------------------ summary first, failures


def test_summary_is_printed_before_the_files_are_written(fake_run, tmp_path, capsys, monkeypatch):
    case, _ = fake_run
    seen = []

    def writer(run, directory):
        seen.append(capsys.readouterr().out)  # what stdout held when writing began
        return write_files(run, directory)

    monkeypatch.setattr(html_module, "write_files", writer)
    assert main(["run", str(case), "--out", str(tmp_path / "run"), "--quiet"]) == 0
    assert "Ma" in seen[0] and "Mde" in seen[0]


def test_write_failure_keeps_the_summary_and_says_the_estimate_was_not_saved(
    fake_run, tmp_path, capsys, monkeypatch
):
    case, _ = fake_run

    def disk_full(run, path):
        path.write_text("partial")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(html_module, "write_csv", disk_full)
    target = tmp_path / "run"
    assert main(["run", str(case), "--out", str(target), "--quiet"]) == 1
    captured = capsys.readouterr()
    assert "Mde" in captured.out  # the estimate reached the terminal
    line = _one_error_line(captured.err)
    assert "the estimate was not saved" in line and "No space left on device" in line
    assert "the partial files were removed" in line
    assert not target.exists() and _leftovers(tmp_path) == []


def test_write_failure_names_partial_files_it_could_not_remove(small, tmp_path, monkeypatch):
    _, run = small

    def failing_writer(directory):
        (directory / "half.json").write_text("{")
        raise OSError(errno.EIO, os.strerror(errno.EIO))

    monkeypatch.setattr(folder_module, "_remove", lambda path: False)
    with ResultFolder.open(tmp_path / "run") as folder:
        with pytest.raises(OutputError, match=r"not saved.*partial files remain in .*flightid-tmp"):
            folder.write(failing_writer)


def test_interrupt_while_writing_leaves_the_old_run(fake_run, tmp_path, capsys, monkeypatch):
    case, _ = fake_run
    target = tmp_path / "run"
    _old_run(target)
    before = {p: p.read_bytes() for p in target.rglob("*") if p.is_file()}

    def interrupted(run, path):
        path.write_text("half")
        raise KeyboardInterrupt

    monkeypatch.setattr(html_module, "write_csv", interrupted)
    assert main(["run", str(case), "--out", str(target), "--overwrite", "--quiet"]) == 130
    assert capsys.readouterr().err == "flightid: interrupted\n"
    assert {p: p.read_bytes() for p in target.rglob("*") if p.is_file()} == before
    assert _leftovers(tmp_path) == []


def test_interrupt_during_estimation_writes_nothing(small, tmp_path, capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli_run, "run_case", interrupted)
    assert main(["run", str(small[0]), "--out", str(tmp_path / "run")]) == 130
    assert capsys.readouterr().err == "flightid: interrupted\n"
    assert os.listdir(tmp_path) == []


@pytest.fixture
def sigint_as_at_a_terminal():
    """SIGINT raising KeyboardInterrupt, as in a program started from a terminal: a test run
    started in the background (a CI job, ``cmd &``) inherits SIGINT ignored, and flightid
    rightly leaves an ignored signal ignored."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def test_sigint_during_the_final_rename_is_held_until_the_run_is_in_place(
    small, tmp_path, monkeypatch, sigint_as_at_a_terminal
):
    """A real SIGINT sent while the folder is being moved in arrives after the move."""
    _, run = small
    target = tmp_path / "run"
    _old_run(target)
    real_rename = os.rename
    renames = []

    def rename_then_interrupt(src, dst):
        os.kill(os.getpid(), signal.SIGINT)
        renames.append(Path(dst).name)
        real_rename(src, dst)

    old_manifest = (target / RUN_MARKER).read_text()
    folder = ResultFolder.open(target, overwrite=True)
    real_commit = folder._commit

    def commit(tmp):
        # os.rename interrupts itself only while the folders are being moved
        monkeypatch.setattr(os, "rename", rename_then_interrupt)
        try:
            real_commit(tmp)
        finally:
            monkeypatch.setattr(os, "rename", real_rename)

    folder._commit = commit
    try:
        with pytest.raises(KeyboardInterrupt):
            folder.write(lambda directory: write_files(run, directory))
    finally:
        folder.release()
    # old run set aside, new run moved in: two renames, each with a SIGINT sent during it
    assert len(renames) == 2 and renames[1] == "run"
    assert renames[0].startswith(f".run.flightid-old-{os.getpid()}-")
    # the interrupt came after the commit: the new run is complete and the old one gone
    assert (target / RUN_MARKER).read_text() != old_manifest
    assert not (target / "figures" / "fit_9_stale.png").exists()
    assert _strict_loads((target / "results.json").read_text())["results"][0]["parameters"]
    assert _leftovers(tmp_path) == []


def test_real_sigint_in_a_subprocess(small, tmp_path):
    """A child process receives SIGINT while writing: one line, exit 130, the old run kept.

    Its stdout is a file, so the child can record how much of the summary had reached it
    (flushed, not just buffered) when writing began."""
    case, _ = small
    target = tmp_path / "run"
    _old_run(target)
    before = {p: p.read_bytes() for p in target.rglob("*") if p.is_file()}
    seen = tmp_path / "stdout_bytes_when_writing"
    script = (
        "import os, signal, sys, time\n"
        # as started from a terminal, whatever SIGINT disposition the test run inherited
        "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
        "import flightid.report.html as h\n"
        "real = h.write_csv\n"
        "def write_csv(run, path):\n"
        f"    open({str(seen)!r}, 'w').write(str(os.fstat(1).st_size))\n"
        "    real(run, path)\n"
        "    os.kill(os.getpid(), signal.SIGINT)\n"
        "    time.sleep(30)\n"
        "h.write_csv = write_csv\n"
        "from flightid.cli.main import main\n"
        f"sys.exit(main(['run', {str(case)!r}, '--out', {str(target)!r}, '--overwrite', "
        "'--quiet']))\n"
    )
    stdout = tmp_path / "stdout.txt"
    with stdout.open("w") as stream:
        done = subprocess.run(
            [sys.executable, "-c", script],
            stdout=stream,
            stderr=subprocess.PIPE,
            text=True,
            timeout=60,
            cwd=tmp_path,
        )
    assert done.returncode == 130, done.stderr
    # the last line says so; a fresh process may first show one-line flightid warnings (a
    # kernel cache being written by another process, say), never anything else
    lines = done.stderr.splitlines()
    assert lines[-1] == "flightid: interrupted", done.stderr
    assert all(line.startswith("flightid: ") for line in lines), done.stderr
    summary = stdout.read_text()
    assert "Mde" in summary
    # the whole summary was on its way out before the first file was written
    assert int(seen.read_text()) == len(summary.encode())
    assert {p: p.read_bytes() for p in target.rglob("*") if p.is_file()} == before
    assert _leftovers(tmp_path) == []


# ------------------------------------------------------------------ strict JSON


def test_strict_json_replaces_non_finite_numbers_and_says_where():
    document = {
        "a": [1.0, float("nan"), np.float64(np.inf)],
        "b/c": {"d": -np.inf, "e": np.int64(3), "f": np.bool_(True)},
        "g": np.array([0.5, np.nan]),
    }
    text = jsonout.dumps(document)
    result = _strict_loads(text)
    assert result["a"] == [1.0, None, None]
    assert result["b/c"] == {"d": None, "e": 3, "f": True}
    assert result["g"] == [0.5, None]
    assert result["nonfinite"] == {
        "/a/1": "NaN",
        "/a/2": "inf",
        "/b~1c/d": "-inf",  # RFC 6901 escapes "/" as "~1"
        "/g/1": "NaN",
    }
    assert "nonfinite" not in _strict_loads(jsonout.dumps({"x": [1.0, 2.0]}))


def test_strict_json_cannot_regress_to_nan(monkeypatch):
    """dumps writes with allow_nan=False: without the conversion it fails, never writes NaN."""
    monkeypatch.setattr(jsonout, "strict", lambda document: document)
    with pytest.raises(ValueError, match="not JSON compliant"):
        jsonout.dumps({"x": float("nan")})


def _with_constant_prediction(run):
    """The run with a prediction whose second channel is constant (0.5, exact in binary, so
    Σ(z − z̄)² = 0): its R² = 1 − Σe²/0 is −inf."""
    n = 20
    time = np.arange(n) * 0.1
    measured = np.column_stack([np.sin(time), np.full(n, 0.5)])
    predicted = measured + 0.01
    prediction = Prediction.from_outputs("flat", time, measured, predicted, ("alpha", "q"))
    assert prediction.r2[1] == -np.inf
    return dataclasses.replace(run, predictions=(prediction,))


def test_results_json_and_json_output_are_strict(small, tmp_path, capsys, monkeypatch):
    case, run = small
    run = _with_constant_prediction(run)
    monkeypatch.setattr(cli_run, "run_case", lambda *args, **kwargs: run)
    target = tmp_path / "run"
    assert main(["run", str(case), "--json", "--out", str(target), "--quiet"]) == 0
    for text in (capsys.readouterr().out, (target / "results.json").read_text()):
        document = _strict_loads(text)
        assert document["results"][0]["prediction"][0]["r2"][1] is None
        assert document["nonfinite"]["/results/0/prediction/0/r2/1"] == "-inf"


def test_write_report_api_is_safe_too(small, tmp_path):
    _, run = small
    target = tmp_path / "api"
    path = write_report(run, target)
    assert path == target / "report.html" and path.is_file()
    with pytest.raises(OutputError, match="already holds a flightid run"):
        write_report(run, target)
    write_report(run, target, overwrite=True)
    assert _leftovers(tmp_path) == []


# ------------------------------------------------------------------ one line per failure


def test_unexpected_exception_is_one_line_and_debug_shows_the_traceback(small, capsys, monkeypatch):
    def broken(*args, **kwargs):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(cli_run, "run_case", broken)
    assert main(["run", str(small[0]), "--quiet"]) == 1
    assert _one_error_line(capsys.readouterr().err) == (
        "flightid: error: internal error: ZeroDivisionError: float division by zero "
        "(run with --debug for the traceback)"
    )
    for argv in (["--debug", "run", str(small[0])], ["run", str(small[0]), "--debug"]):
        assert main([*argv, "--quiet"]) == 1
        err = capsys.readouterr().err
        assert "Traceback (most recent call last)" in err and "in broken" in err
        assert err.strip().splitlines()[-1].startswith("flightid: error: internal error:")


def test_named_errors_have_no_traceback_without_debug(tmp_path, capsys):
    missing = tmp_path / "nothing.toml"
    assert main(["run", str(missing)]) == 1
    assert _one_error_line(capsys.readouterr().err) == (
        f"flightid: error: case file: {missing} does not exist"
    )
    assert main(["--debug", "run", str(missing)]) == 1
    assert "Traceback" in capsys.readouterr().err


def test_os_errors_are_one_line(small, capsys, monkeypatch):
    def unreadable(*args, **kwargs):
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), "/data/flight.csv")

    monkeypatch.setattr(cli_run, "run_case", unreadable)
    assert main(["run", str(small[0])]) == 1
    assert _one_error_line(capsys.readouterr().err) == (
        "flightid: error: Permission denied: /data/flight.csv"
    )


def test_paper_plot_folder_is_checked_before_the_example_runs(tmp_path, capsys, monkeypatch):
    import flightid.paper.example3 as example3

    def forbidden(*args, **kwargs):
        raise AssertionError("example 3 ran although --plot is a file")

    monkeypatch.setattr(example3, "run_example3", forbidden)
    plot = tmp_path / "figures"
    plot.write_text("a file")
    assert main(["paper", "example3", "--case", "1", "--plot", str(plot)]) == 1
    assert "exists and is a file" in _one_error_line(capsys.readouterr().err)


def test_run_help_says_model_module_executes_python(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "model.module" in text and "executed as Python code" in text


def test_output_dir_of_the_case_is_the_default_result_folder(small, tmp_path, monkeypatch):
    case, run = small
    copy = tmp_path / "case" / case.name
    shutil.copytree(case.parent, copy.parent)
    copy.write_text(copy.read_text().replace("[output]\n", '[output]\ndir = "results"\n'))
    monkeypatch.setattr(cli_run, "run_case", lambda *args, **kwargs: run)
    assert main(["run", str(copy), "--quiet"]) == 0
    assert (copy.parent / "results" / RUN_MARKER).is_file()
    assert main(["run", str(copy), "--quiet"]) == 1  # the second run asks for --overwrite


def test_regress_json_is_strict(tmp_path, capsys, monkeypatch):
    # `flightid regress` is an alias of `flightid run`, which imports these when the command
    # runs: patch them at their source
    from types import SimpleNamespace

    import flightid.cases
    import flightid.cases.stages

    case = SimpleNamespace(staged=True, stages=(SimpleNamespace(kind="stepwise"),), output={})
    stages = [{"kind": "stepwise", "coefficients": {"Cm": {"r2": float("nan"), "pse": 1.0}}}]
    run = SimpleNamespace(to_dict=lambda: {"results": []}, stages_dict=lambda: stages)
    monkeypatch.setattr(flightid.cases, "load_case", lambda path: case)
    monkeypatch.setattr(flightid.cases.stages, "run_stages", lambda *args, **kwargs: run)
    assert main(["regress", "any.toml", "--json", "--quiet"]) == 0
    document = _strict_loads(capsys.readouterr().out)
    assert document["stages"][0]["coefficients"]["Cm"]["r2"] is None
    assert document["nonfinite"] == {"/stages/0/coefficients/Cm/r2": "NaN"}
