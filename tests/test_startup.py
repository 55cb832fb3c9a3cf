"""Start-up: `flightid --help` must not load the numerical stack (issue 11, item 4).

Structural checks, not timings: after importing ``flightid`` and building the full command-line
parser, none of numpy / scipy / numba / matplotlib / pandas nor the estimation stack is in
``sys.modules`` (each run in a fresh interpreter, because the test process has them loaded).
"""

from __future__ import annotations

import json
import subprocess
import sys

HEAVY = ("numpy", "scipy", "numba", "matplotlib", "pandas")
HEAVY_FLIGHTID = ("flightid.estimation", "flightid.simulate", "flightid.cases", "flightid.data")


def _modules_after(code: str) -> list[str]:
    """Top-level and flightid module names loaded in a fresh interpreter after ``code``."""
    script = code + "\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))\n"
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True, timeout=120
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def _loaded(modules: list[str], roots: tuple[str, ...]) -> list[str]:
    return [m for m in modules if any(m == r or m.startswith(r + ".") for r in roots)]


def test_building_the_parser_loads_no_numerical_module():
    modules = _modules_after(
        "from flightid.cli.main import build_parser\n"
        "parser = build_parser()\n"
        "assert {'run', 'validate', 'regress', 'paper'} <= set("
        "parser._subparsers._group_actions[0].choices)"
    )
    assert _loaded(modules, HEAVY) == []
    assert _loaded(modules, HEAVY_FLIGHTID) == []


def test_help_runs_without_the_numerical_stack():
    # `python -X importtime` lists every module the --help run imported, on stderr
    done = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "flightid.cli.main", "--help"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "usage: flightid" in done.stdout and "run" in done.stdout
    imported = {line.split("|")[-1].strip() for line in done.stderr.splitlines() if "|" in line}
    assert "flightid.cli.run" in imported  # the import-time listing was read
    assert _loaded(sorted(imported), HEAVY) == []


def test_import_flightid_is_light_and_exports_resolve_lazily():
    modules = _modules_after("import flightid")
    assert _loaded(modules, HEAVY) == []
    modules = _modules_after(
        "from flightid import FPS, MNR, MNRES, Convergence, Estimate, estimate, FlightData\n"
        "from flightid import Parameter, Parameters, StateSpaceModel, Simulator, simulate\n"
        "import flightid.estimation\n"
        "from flightid.simulate import simulator as sim\n"
        "assert estimate is flightid.estimation.estimate\n"
        "assert Simulator is sim.Simulator\n"
        # `flightid.simulate` stays the function although a sub-package of that name is loaded
        "assert simulate is sim.simulate and flightid.simulate is sim.simulate\n"
    )
    assert "numpy" in modules and "flightid.estimation" in modules


def test_unknown_top_level_name_is_an_attribute_error():
    import flightid

    try:
        flightid.no_such_name  # noqa: B018
    except AttributeError as exc:
        assert "no_such_name" in str(exc)
    else:
        raise AssertionError("flightid.no_such_name did not raise AttributeError")
