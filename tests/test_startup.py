"""Start-up: `flightid --help` must not load the numerical stack (issue 11, item 4).

Structural checks, not timings: after importing ``flightid`` and building the full command-line
parser, none of numpy / scipy / numba / matplotlib / pandas nor the estimation stack is in
``sys.modules`` (each run in a fresh interpreter, because the test process has them loaded).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np

HEAVY = ("numpy", "scipy", "numba", "matplotlib", "pandas")
HEAVY_FLIGHTID = ("flightid.estimation", "flightid.simulation", "flightid.cases", "flightid.data")


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
        "from flightid.simulation import simulator as sim\n"
        "assert estimate is flightid.estimation.estimate\n"
        "assert Simulator is sim.Simulator\n"
        # `flightid.simulate` is the function; the package is `flightid.simulation`
        "import flightid.simulation\n"
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


# --------------------------------------------------------------------------- kernel disk cache

_MODEL = """
import numpy as np

GAIN = 1.0


def f(t, x, u, theta):
    dx = np.empty(1)
    # ẋ = −a x + GAIN·u
    dx[0] = -theta[0] * x[0] + GAIN * u[0]
    return dx


def h(t, x, u, theta):
    return x.copy()
"""

_RUN = """
import importlib.util, json, sys
import numpy as np
spec = importlib.util.spec_from_file_location("startup_model", sys.argv[1])
module = importlib.util.module_from_spec(spec)
if sys.argv[2] == "register":  # as flightid.cases.usermodel does
    sys.modules["startup_model"] = module
spec.loader.exec_module(module)
from flightid.simulation import kernels, sensitivity
kernel, compiled = kernels.make_kernel(module.f, module.h)
t = np.arange(5) * 0.1
u = np.ones((5, 1))
y = np.empty((1, 5, 1))
flag = np.empty(1, dtype=np.int64)
kernel(np.array([[2.0]]), np.zeros((1, 1)), t, u, 1, 0, 1, y, flag)
sens = sensitivity.make_sensitivity_kernel(module.f, module.h)
g = np.empty((5, 1, 1))
ys = np.empty((5, 1))
sens(np.array([2.0]), np.zeros(1), np.zeros((1, 1)), np.array([0]), np.array([1e-6]), 1e-7,
     t, u, 1, 0, 1, ys, g)
stats = [kernel.stats, sens.stats]
print(json.dumps({"hits": [sum(s.cache_hits.values()) for s in stats],
                  "misses": [sum(s.cache_misses.values()) for s in stats],
                  "y": y[0, :, 0].tolist()}))
"""


def _run_model(path, cache_dir, register: bool = True) -> dict:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache_dir), "FLIGHTID_KERNEL_CACHE": "1"}
    done = subprocess.run(
        [sys.executable, "-c", _RUN, str(path), "register" if register else "anonymous"],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_second_process_loads_both_kernels_from_the_disk_cache(tmp_path):
    model = tmp_path / "model.py"
    model.write_text(_MODEL)
    first = _run_model(model, tmp_path / "cache")
    assert first["misses"] == [1, 1] and first["hits"] == [0, 0]
    second = _run_model(model, tmp_path / "cache")
    assert second["hits"] == [1, 1] and second["misses"] == [0, 0]
    assert second["y"] == first["y"]
    # the cached kernels name the model's module; where it is not importable any more, they
    # are compiled again (no failure)
    anonymous = _run_model(model, tmp_path / "cache", register=False)
    assert anonymous["misses"] == [1, 1] and anonymous["y"] == first["y"]
    # ẋ = −2x + u, x(0) = 0: x(0.4) = (1 − e^{−0.8})/2 (closed form; RK4 at Δt = 0.1)
    assert abs(first["y"][-1] - (1.0 - np.exp(-0.8)) / 2.0) < 1e-5
    # a changed model gives another digest (test below), hence a fresh compilation


def test_digest_follows_closures_globals_and_arrays():
    from flightid.model.kernel_cache import kernel_digest

    def make(table):
        def g(x):
            return x * table[0] + OFFSET

        return g

    base = kernel_digest(make(np.array([1.0, 2.0])))
    assert base == kernel_digest(make(np.array([1.0, 2.0])))  # same values, same kernel
    assert base != kernel_digest(make(np.array([1.0, 2.5])))  # a closed-over table changed
    global OFFSET
    OFFSET = 2.0
    try:
        assert base != kernel_digest(make(np.array([1.0, 2.0])))  # a global changed
    finally:
        OFFSET = 1.0

    class Opaque:
        pass

    opaque = Opaque()

    def uses_object(x):
        return x + (opaque is None)

    assert kernel_digest(uses_object) is None  # unknown object: compiled without disk cache


OFFSET = 1.0


def test_a_kernel_calling_a_function_compiled_before_the_cache_is_not_cached():
    # numba names functions qualname$uid with uid counted from 1 in every process; one
    # compiled before flightid's offset could share its name with another process's
    # function, and a cached kernel linking it would run the wrong code: no digest, no cache
    script = """
import numba
@numba.njit
def early(x):
    return x + 1.0
early(1.0)
from flightid.model.kernel_cache import kernel_digest
@numba.njit
def late(x):
    return x + 2.0
late(1.0)
def calls_early(x):
    return early(x)
def calls_late(x):
    return late(x)
print(kernel_digest(calls_early) is None, kernel_digest(calls_late) is not None)
"""
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=True
    )
    assert done.stdout.split() == ["True", "True"]
