"""Compilation is done once: per process for a model rebuilt by a case builder (the kernel
memo is keyed on what the kernels compute, not on function objects), and across processes
through the on-disk kernel cache (issue 14, part 2).

Counted, not timed: numba's ``numba:compile`` events (one per dispatcher compilation; a
kernel loaded from the disk cache fires none). The data are a first-order system with
known parameters, ẋ = −a x + b u + b_x, y = x + b_y, simulated here (seeded noise); the
estimates are compared between runs (identical), not against a reference.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from numba.core import event

MODEL = """
import numpy as np

STATES = ("x",)
INPUTS = ("u",)
OUTPUTS = ("y",)
PARAMETERS = {"a": 1.5, "b": 0.8}
# a constant only this test's model has (its kernels are compiled by this test)
TAG = 0.0


def f(t, x, u, theta):
    dx = np.empty(1)
    # ẋ = −a x + b u
    dx[0] = -theta[0] * x[0] + theta[1] * u[0] + TAG
    return dx


def h(t, x, u, theta):
    y = np.empty(1)
    y[0] = x[0]
    return y
"""

CASE = """
title = "first-order system with biases"

[data]
file = "data.csv"
data_dir = "."
format = "csv"
time = "time"

[data.inputs]
u = "u"

[data.outputs]
y = "y"

[model]
module = "model.py"

[initial_state]
x = 0.0

[biases.states]
x = 0.01

[biases.outputs]
y = 0.01

[estimation]
solver = "mnres"
method = "rk4"
"""


def write_first_order_data(folder: Path, state_bias: float, output_offset: float, seed: int):
    """``folder/data.csv`` from ẋ = −2x + u + state_bias, y = x + output_offset (+ noise
    σ 0.002, ``seed``), a doublet u; 200 samples of 0.05 s."""
    dt, n = 0.05, 200
    t = np.arange(n) * dt
    u = np.where((t > 1.0) & (t < 2.0), 1.0, 0.0) - np.where((t > 2.0) & (t < 3.0), 1.0, 0.0)
    x = np.zeros(n)
    for k in range(n - 1):  # Euler at a tenth of the sample time (data only)
        xk = x[k]
        for _ in range(10):
            xk += dt / 10 * (-2.0 * xk + u[k] + state_bias)
        x[k + 1] = xk
    y = x + output_offset + 0.002 * np.random.default_rng(seed).standard_normal(n)
    rows = "\n".join(f"{a:.17g},{b:.17g},{c:.17g}" for a, b, c in zip(t, u, y, strict=True))
    (folder / "data.csv").write_text("time,u,y\n" + rows + "\n")


@pytest.fixture
def case_file(tmp_path: Path) -> Path:
    """data.csv from ẋ = −2x + u + 0.05, y = x + 0.1 (+ noise σ 0.002, seed 3), doublet u."""
    write_first_order_data(tmp_path, state_bias=0.05, output_offset=0.1, seed=3)
    tag = float(abs(hash(str(tmp_path))) % 1000) * 1e-18  # keeps the model's own kernels
    (tmp_path / "model.py").write_text(MODEL.replace("TAG = 0.0", f"TAG = {tag!r}"))
    path = tmp_path / "case.toml"
    path.write_text(CASE)
    return path


class _Compiles(event.Listener):
    """Counts numba compilations (nested ones included)."""

    def __init__(self) -> None:
        self.count = 0

    def on_start(self, ev) -> None:
        self.count += 1

    def on_end(self, ev) -> None:
        pass


def _estimate_counting_compiles(case_file: Path) -> tuple[np.ndarray, int]:
    from flightid.cases.run import run_case

    listener = _Compiles()
    with event.install_listener("numba:compile", listener):
        run = run_case(case_file, accuracy="none")
    return np.asarray(run.estimate.values), listener.count


def test_a_case_built_twice_in_a_process_compiles_once(case_file, monkeypatch):
    # no disk cache: every kernel the first estimate needs is compiled in this process
    monkeypatch.setenv("FLIGHTID_KERNEL_CACHE", "0")
    first, compiled_first = _estimate_counting_compiles(case_file)
    # the case builder makes new model functions and bias closures: same content, so the
    # kernels (and the compiled user f and h) of the first estimate are reused
    second, compiled_second = _estimate_counting_compiles(case_file)
    assert compiled_first > 0
    assert compiled_second == 0
    np.testing.assert_array_equal(second, first)


def test_same_content_gives_one_compiled_function_and_one_key():
    from flightid.model.kernel_cache import compiled_function, content_key

    def make(gain):
        def g(x):
            return gain * x

        return g

    one, same, other = make(2.0), make(2.0), make(3.0)
    assert content_key(one) == content_key(same) != content_key(other)
    assert compiled_function(one) is compiled_function(same)
    assert compiled_function(one) is not compiled_function(other)
    assert compiled_function(other)(1.5) == 4.5

    class Opaque:
        scale = 2.0

    opaque = Opaque()

    def undescribable(x):
        return opaque.scale * x

    # no digest: keyed on the function itself, never shared with another one
    assert content_key(undescribable) == ("id", id(undescribable))


# Runs `flightid run` in this interpreter, counting numba compilations; last stdout line JSON
_CHILD = r"""
import json, sys
from numba.core import event

class Compiles(event.Listener):
    count = 0
    def on_start(self, ev):
        Compiles.count += 1
    def on_end(self, ev):
        pass

event.register("numba:compile", Compiles())
from flightid.cli.main import main
rc = main(sys.argv[1:])
print("\n" + json.dumps({"rc": rc, "compiles": Compiles.count}))
"""


def _flightid_run(case_file: Path, cache_dir: Path) -> dict:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache_dir), "FLIGHTID_KERNEL_CACHE": "1"}
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            _CHILD,
            "run",
            str(case_file),
            "--json",
            "--quiet",
            "--accuracy",
            "cr",
        ],  # fmt: skip
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.strip().splitlines()
    counts = json.loads(lines[-1])
    assert counts["rc"] == 0
    return {"compiles": counts["compiles"], "results": json.loads("\n".join(lines[:-1]))}


def test_second_flightid_run_compiles_nothing(case_file, tmp_path):
    cache = tmp_path / "numba-cache"
    first = _flightid_run(case_file, cache)
    second = _flightid_run(case_file, cache)
    assert first["compiles"] > 0
    # every kernel, and the user's f and h the bias wrappers call, come from the disk cache
    assert second["compiles"] == 0
    # the same estimates, bounds, residuals ... (all but the run's wall time)
    entries = [run["results"]["results"][0] for run in (first, second)]
    for entry in entries:
        entry.pop("wall_time_s")
    assert entries[1] == entries[0]
