"""``flightid run CASE --json`` loads only what its answer needs: not the HTML report (the
result folder's files).
Structural, not timed: the modules in ``sys.modules`` after the command, in a fresh
interpreter (the test process has them loaded)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "examples" / "csv_walkthrough" / "my_case.toml"

_CHILD = r"""
import contextlib, io, json, sys
from flightid.cli.main import main
stdout = io.StringIO()
with contextlib.redirect_stdout(stdout):
    rc = main(["run", *sys.argv[1:], "--json", "--quiet"])
document = json.loads(stdout.getvalue())
entry = document["results"][0]
print(json.dumps({"rc": rc, "modules": sorted(sys.modules),
                  "whiteness": "whiteness" in json.dumps(entry)}))
"""


def _run_json(*arguments: str) -> set[str]:
    """The modules loaded by ``flightid run ARGUMENTS --json`` in a fresh interpreter."""
    done = subprocess.run(
        [sys.executable, "-c", _CHILD, *arguments],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=ROOT,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    found = json.loads(done.stdout.strip().splitlines()[-1])
    assert found["rc"] == 0
    # the answer still carries the residual-whiteness test
    assert found["whiteness"]
    return set(found["modules"])


def test_run_json_does_not_load_the_report():
    modules = _run_json(str(WALK), "--accuracy", "cr")
    assert "flightid.report.html" not in modules


def test_run_json_does_not_load_scipy_special():
    # the whiteness test's χ² survival function is flightid's own (flightid.accuracy.chi_square)
    modules = _run_json(str(WALK))
    assert "flightid.accuracy.whiteness" in modules
    assert (
        sorted(m for m in modules if m == "scipy.special" or m.startswith("scipy.special.")) == []
    )


def test_run_json_loads_neither_the_likelihood_region_nor_the_file_writers():
    # a Cramér–Rao assessment (the case's default) and the modal analysis every run makes
    modules = _run_json(str(WALK), "--accuracy", "cr")
    assert "flightid.export.modal" in modules
    unneeded = (
        "flightid.accuracy.profile",
        "flightid.accuracy.search",
        "flightid.export.statespace",
        "flightid.export.python_module",
        "flightid.export.files",
    )
    assert sorted(set(unneeded) & modules) == []
