"""Result folders: flightid deletes only what flightid wrote.

``--overwrite`` replaces a folder only when the run's manifest (``.flightid-run``: every file
with its size and SHA-256) vouches for everything in it; the current folder, the home folder
and folders holding the case's inputs are refused as result folders; the lock is made
without following links; SIGTERM cleans up like Ctrl-C; a run set aside by an interrupted
replace is restored or named; folders follow the umask.

CLI runs use a stand-in for the estimation (``run_case`` patched to return one small real
run made once per module), so that each test only exercises the folder handling.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

import flightid.cases as cli_run
from flightid.cases import load_case, run_case
from flightid.cli.main import main
from flightid.report.folder import (
    RUN_MARKER,
    OutputError,
    ResultFolder,
    not_written_by_flightid,
    write_manifest,
)

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "examples/csv_walkthrough"
SRC = ROOT / "src"


def _small_case(directory: Path) -> Path:
    """A copy of the CSV walk-through cut to 3 s, pure Python, 3 passes, no figures."""
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
def small_run(tmp_path_factory):
    return run_case(load_case(_small_case(tmp_path_factory.mktemp("small"))))


@pytest.fixture()
def case(small_run, tmp_path, monkeypatch):
    """A fresh copy of the case (with the user's notes beside it); ``flightid run`` returns
    the module's run without estimating."""
    monkeypatch.setattr(cli_run, "run_case", lambda *args, **kwargs: small_run)
    path = _small_case(tmp_path)
    (path.parent / "notes.md").write_text("my notes on this flight\n")
    return path


def _snapshot(directory: Path) -> dict[str, bytes]:
    return {
        p.relative_to(directory).as_posix(): p.read_bytes()
        for p in sorted(directory.rglob("*"))
        if p.is_file()
    }


def _leftovers(parent: Path) -> list[str]:
    return sorted(
        p.name
        for p in parent.iterdir()
        if ".flightid-tmp-" in p.name or ".flightid-old-" in p.name or "flightid-lock" in p.name
    )


def _run(case: Path, out: str, *extra: str) -> int:
    return main(["run", str(case), "--out", out, "--quiet", *extra])


# ------------------------------------------------------------------ where a run may not go


def test_out_dot_in_the_case_folder_is_refused_and_nothing_is_lost(case, monkeypatch, capsys):
    before = _snapshot(case.parent)
    monkeypatch.chdir(case.parent)
    for extra in ((), ("--overwrite",), ()):
        assert _run(case, ".", *extra) == 1
        assert f"holds {case.name}, an input of this run" in capsys.readouterr().err
    assert _snapshot(case.parent) == before
    assert _leftovers(case.parent.parent) == []


def test_case_folder_named_from_elsewhere_is_refused(case, tmp_path, monkeypatch, capsys):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    before = _snapshot(case.parent)
    # the case folder, and an ancestor of it, hold the case file
    for out in (str(case.parent), "../walk", "../walk/../walk", str(tmp_path)):
        assert _run(case, out) == 1
        assert f"holds {case.name}, an input of this run" in capsys.readouterr().err
    assert _snapshot(case.parent) == before and os.listdir(elsewhere) == []


def test_folder_holding_the_data_or_the_model_module_is_refused(case, tmp_path, capsys):
    # the data and the model live in folders of their own, the case elsewhere
    data = tmp_path / "flights"
    data.mkdir()
    shutil.move(case.parent / "my_flight.csv", data / "my_flight.csv")
    models = tmp_path / "models"
    models.mkdir()
    shutil.move(case.parent / "short_period.py", models / "short_period.py")
    text = case.read_text()
    text = text.replace('data_dir = "."', f'data_dir = "{data}"')
    text = text.replace('module = "short_period.py"', f'module = "{models}/short_period.py"')
    case.write_text(text)
    for folder, name in ((data, "my_flight.csv"), (models, "short_period.py")):
        assert _run(case, str(folder)) == 1
        assert f"holds {name}, an input of this run" in capsys.readouterr().err
        assert os.listdir(folder) == [name]


def test_home_folder_and_its_ancestors_are_refused(case, tmp_path, monkeypatch, capsys):
    home = tmp_path / "users" / "pilot"
    home.mkdir(parents=True)
    monkeypatch.setenv("HOME", str(home))
    for out in (home, home.parent):
        assert _run(case, str(out)) == 1
        assert "the home folder" in capsys.readouterr().err
    assert os.listdir(home) == []


def test_empty_out_and_the_current_folder_are_refused(case, tmp_path, monkeypatch, capsys):
    here = tmp_path / "work" / "here"
    here.mkdir(parents=True)
    (here / "flight_log.ulg").write_bytes(b"ULog")
    monkeypatch.chdir(here)
    for out in ("", "  "):
        assert _run(case, out) == 1
        assert "--out: expected a folder name, got an empty string" in capsys.readouterr().err
    for out in (".", str(here), "../here", ".."):
        assert _run(case, out) == 1
        assert "the current folder" in capsys.readouterr().err
    assert os.listdir(here) == ["flight_log.ulg"]


def test_empty_output_dir_of_the_case_is_refused(case, capsys):
    case.write_text(case.read_text().replace("[output]\n", '[output]\ndir = ""\n'))
    before = _snapshot(case.parent)
    assert main(["run", str(case), "--quiet"]) == 1
    assert "output.dir: expected a folder name" in capsys.readouterr().err
    assert _snapshot(case.parent) == before


def test_design_with_an_empty_out_is_refused_before_designing(tmp_path, monkeypatch, capsys):
    import flightid.cases.design_case as design_case

    def forbidden(*args, **kwargs):
        raise AssertionError("the design ran although --out is empty")

    monkeypatch.setattr(design_case, "run_design_case", forbidden)
    monkeypatch.chdir(tmp_path)
    design = ROOT / "examples/cases/short_period_design.toml"
    assert main(["design", str(design), "--out", "", "--quiet"]) == 1
    assert "--out: expected a folder name, got an empty string" in capsys.readouterr().err
    assert os.listdir(tmp_path) == []


def test_design_refuses_its_case_folder_and_writes_a_manifest(tmp_path, monkeypatch, capsys):
    from types import SimpleNamespace

    import flightid.cases.design_case as design_case
    import flightid.report.estimator_reports as estimator_reports

    def write_files(result, directory: Path, units=None) -> Path:
        (directory / "design.csv").write_text("time,de\n0,0\n")
        return directory / "design.csv"

    result = SimpleNamespace(
        summary=lambda: "design",
        to_dict=lambda: {"inputs": {}, "predicted": {}},
    )
    monkeypatch.setattr(design_case, "run_design_case", lambda *args, **kwargs: result)
    monkeypatch.setattr(estimator_reports, "write_design_files", write_files)
    case = tmp_path / "design" / "short_period_design.toml"
    case.parent.mkdir()
    shutil.copy(ROOT / "examples/cases/short_period_design.toml", case)
    assert main(["design", str(case), "--out", str(case.parent), "--quiet"]) == 1
    assert f"holds {case.name}, an input of this run" in capsys.readouterr().err
    assert os.listdir(case.parent) == [case.name]
    out = tmp_path / "out"
    assert main(["design", str(case), "--out", str(out), "--quiet"]) == 0
    assert set(json.loads((out / RUN_MARKER).read_text())["files"]) == {"design.csv"}


# ------------------------------------------------------------------ the manifest


def test_manifest_lists_every_file_with_size_and_sha256(case, tmp_path):
    target = tmp_path / "run"
    assert _run(case, str(target)) == 0
    manifest = json.loads((target / RUN_MARKER).read_text())
    on_disk = {
        p.relative_to(target).as_posix(): p.read_bytes()
        for p in target.rglob("*")
        if p.is_file() and p.name != RUN_MARKER
    }
    assert set(manifest["files"]) == set(on_disk) and "results.json" in on_disk
    for name, data in on_disk.items():
        assert manifest["files"][name] == {
            "bytes": len(data),
            "sha256": hashlib.sha256(data).hexdigest(),
        }
    assert not_written_by_flightid(target) == []


def test_overwrite_of_an_untouched_run_replaces_it(case, tmp_path):
    target = tmp_path / "run"
    assert _run(case, str(target)) == 0
    first = json.loads((target / RUN_MARKER).read_text())
    time.sleep(0.01)
    assert _run(case, str(target), "--overwrite") == 0
    second = json.loads((target / RUN_MARKER).read_text())["files"]
    # the same files with the same bytes; report.html only up to its "generated (UTC)" time,
    # which may have passed a second between the runs
    assert set(second) == set(first["files"])
    assert {k: v for k, v in second.items() if k != "report.html"} == {
        k: v for k, v in first["files"].items() if k != "report.html"
    }
    assert second["report.html"]["bytes"] == first["files"]["report.html"]["bytes"]
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize(
    ("change", "named"),
    [
        (lambda t: (t / "notes.txt").write_text("mine"), "notes.txt (not written by flightid)"),
        (lambda t: (t / "drafts").mkdir(), "drafts/ (not written by flightid)"),
        (
            lambda t: (t / "results.json").write_text((t / "results.json").read_text() + " "),
            "results.json (changed since flightid wrote it)",
        ),
        (
            lambda t: os.symlink(t / "results.json", t / "link.json"),
            "link.json (not written by flightid)",
        ),
    ],
    ids=["added file", "added folder", "edited file", "added link"],
)
def test_overwrite_refuses_what_flightid_did_not_write_and_names_it(
    case, tmp_path, capsys, change, named
):
    target = tmp_path / "run"
    assert _run(case, str(target)) == 0
    change(target)
    before = _snapshot(target)
    assert _run(case, str(target), "--overwrite") == 1
    err = capsys.readouterr().err
    assert "--overwrite would delete what flightid may not" in err and named in err
    assert "nothing was deleted" in err
    assert _snapshot(target) == before
    assert _leftovers(tmp_path) == []


def test_user_file_added_while_estimating_is_caught_at_the_replace(small_run, tmp_path):
    """The check is repeated on the set-aside folder, right before anything is deleted."""
    from flightid.report.html import write_files

    target = tmp_path / "run"
    with ResultFolder.open(target) as folder:
        folder.write(lambda d: write_files(small_run, d))
    folder = ResultFolder.open(target, overwrite=True)  # passes: only flightid's files
    try:
        (target / "late_notes.txt").write_text("written during the estimation")
        with pytest.raises(OutputError, match=r"not saved.*late_notes\.txt \(not written"):
            folder.write(lambda d: write_files(small_run, d))
    finally:
        folder.release()
    assert (target / "late_notes.txt").read_text() == "written during the estimation"
    assert (target / "results.json").is_file() and _leftovers(tmp_path) == []


def test_run_without_a_manifest_is_not_replaced(case, tmp_path, capsys):
    target = tmp_path / "run"
    target.mkdir()
    (target / "results.json").write_text('{"results": ["older flightid"]}')
    (target / "analysis.ipynb").write_text("{}")
    before = _snapshot(target)
    assert _run(case, str(target), "--overwrite") == 1
    err = capsys.readouterr().err
    assert "without a manifest" in err and "analysis.ipynb" in err
    assert _snapshot(target) == before


def test_run_added_beside_user_files_is_not_replaced_with_them(case, tmp_path, capsys):
    target = tmp_path / "mine"
    target.mkdir()
    (target / "flight_notes.txt").write_text("keep me")
    assert _run(case, str(target)) == 0  # the run's files are added beside the notes
    assert _run(case, str(target), "--overwrite") == 1
    assert "flight_notes.txt (not written by flightid)" in capsys.readouterr().err
    assert (target / "flight_notes.txt").read_text() == "keep me"


# ------------------------------------------------------------------ the lock


def test_symlink_at_the_lock_path_is_refused_and_its_target_kept(case, tmp_path, capsys):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    lock = tmp_path / ".out.flightid-lock"
    lock.symlink_to(victim)
    assert _run(case, str(tmp_path / "out")) == 1
    err = capsys.readouterr().err
    assert "is a symbolic link" in err and str(lock) in err
    assert victim.read_text() == "precious" and lock.is_symlink()
    assert not (tmp_path / "out").exists()


def test_hard_link_at_the_lock_path_is_refused_and_its_target_kept(case, tmp_path, capsys):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    os.link(victim, tmp_path / ".out.flightid-lock")
    assert _run(case, str(tmp_path / "out")) == 1
    assert "not a plain file of its own" in capsys.readouterr().err
    assert victim.read_text() == "precious"


def test_lock_file_left_by_a_killed_run_is_taken_over(case, tmp_path):
    (tmp_path / ".out.flightid-lock").write_text("99999\n")  # no process holds its flock
    assert _run(case, str(tmp_path / "out")) == 0
    assert (tmp_path / "out" / "results.json").is_file() and _leftovers(tmp_path) == []


# ------------------------------------------------------------------ interrupted replace


def _set_aside_run(parent: Path, name: str) -> Path:
    """What ``kill -9`` between the two renames of ``--overwrite`` leaves: the old run under
    its set-aside name, the complete new run in a temporary folder, no target."""
    old = parent / f".{name}.flightid-old-4242"
    old.mkdir()
    (old / "results.json").write_text('{"results": ["the old run"]}')
    (old / "my_comments.txt").write_text("added after that run")
    write_manifest(old)
    new = parent / f".{name}.flightid-tmp-dead"
    new.mkdir()
    (new / "results.json").write_text('{"results": ["the new run"]}')
    write_manifest(new)
    return old


def test_set_aside_run_is_moved_back_when_the_target_is_missing(case, tmp_path, capsys):
    old = _set_aside_run(tmp_path, "run")
    kept = _snapshot(old)
    target = tmp_path / "run"
    assert _run(case, str(target)) == 1  # the old run is back: replacing it needs --overwrite
    err = capsys.readouterr().err
    assert "flightid: note:" in err and "was moved back to" in err
    assert "already holds a flightid run" in err
    assert _snapshot(target) == kept and _leftovers(tmp_path) == []


def test_set_aside_run_is_kept_and_named_when_the_target_exists(case, tmp_path, capsys):
    old = _set_aside_run(tmp_path, "run")
    kept = _snapshot(old)
    target = tmp_path / "run"
    target.mkdir()
    (target / "report_draft.md").write_text("a folder the user made meanwhile")
    assert _run(case, str(target)) == 0
    err = capsys.readouterr().err
    assert f"flightid: note: {old} holds a run that an interrupted --overwrite set aside" in err
    assert _snapshot(old) == kept
    assert (target / "results.json").is_file()


def test_leftovers_of_a_folder_named_with_glob_characters_are_found(case, tmp_path):
    stale = tmp_path / ".run[1].flightid-tmp-dead"
    stale.mkdir()
    (stale / "results.json").write_text("{")
    assert _run(case, str(tmp_path / "run[1]")) == 0
    assert not stale.exists() and _leftovers(tmp_path) == []


# ------------------------------------------------------------------ SIGTERM


def _child(script: str, tmp_path: Path) -> subprocess.Popen:
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]),
    }
    return subprocess.Popen(
        [sys.executable, "-c", script],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
        env=env,
    )


def _wait_for(path: Path, child: subprocess.Popen, seconds: float = 60.0) -> None:
    deadline = time.monotonic() + seconds
    while not path.exists():
        if child.poll() is not None or time.monotonic() > deadline:
            child.kill()
            raise AssertionError(f"the child never got there: {child.communicate()}")
        time.sleep(0.02)


# a stand-in for the estimation (a run with a summary and nothing else), and a report writer
# that writes part of its files, says so and blocks until a signal arrives
_SIGTERM_CHILD = """
import sys, time
from pathlib import Path
from types import SimpleNamespace
import flightid.cases, flightid.report.html as html
ready = Path({ready!r})
estimate = SimpleNamespace(summary=lambda: "Mde  -1.0")
def run_case(*args, **kwargs):
    if {during_estimation!r}:
        ready.write_text("estimating")
        time.sleep(60)
    return SimpleNamespace(estimate=estimate, accuracy=None, predictions=())
def write_files(run, directory):
    (directory / "results.json").write_text("{{half")
    ready.write_text(str(directory))
    time.sleep(60)
flightid.cases.run_case = run_case
html.write_files = write_files
from flightid.cli.main import main
sys.exit(main(["run", {case!r}, "--out", {out!r}, "--overwrite", "--quiet"]))
"""


@pytest.mark.parametrize("during_estimation", [False, True], ids=["writing", "estimating"])
def test_sigterm_cleans_up_like_sigint(case, tmp_path, during_estimation):
    target = tmp_path / "run"
    target.mkdir()
    (target / "results.json").write_text('{"results": ["the old run"]}')
    write_manifest(target)
    before = _snapshot(target)
    ready = tmp_path / "ready"
    script = _SIGTERM_CHILD.format(
        ready=str(ready), during_estimation=during_estimation, case=str(case), out=str(target)
    )
    child = _child(script, tmp_path)
    _wait_for(ready, child)
    if not during_estimation:
        assert Path(ready.read_text()).name.startswith(".run.flightid-tmp-")
    assert _leftovers(tmp_path) != []  # the lock (and the temporary folder) are there now
    child.send_signal(signal.SIGTERM)
    out, err = child.communicate(timeout=60)
    assert child.returncode == 143, err
    assert err == "flightid: terminated\n"
    assert _leftovers(tmp_path) == []
    assert _snapshot(target) == before


# ------------------------------------------------------------------ permissions


@pytest.mark.parametrize("umask", [0o022, 0o027, 0o002])
def test_result_folder_follows_the_umask(case, tmp_path, umask):
    previous = os.umask(umask)
    try:
        assert _run(case, str(tmp_path / "run")) == 0
    finally:
        os.umask(previous)
    mode = stat.S_IMODE((tmp_path / "run").stat().st_mode)
    assert mode == 0o777 & ~umask
    assert stat.S_IMODE((tmp_path / "run" / "results.json").stat().st_mode) == 0o666 & ~umask
