"""A case with ``eigenvalue_shift`` compiles nothing in its second process (issue 14 part 2).

``with_eigenvalue_shift`` wraps the model's f; it compiled the user's f with an uncached
``njit``, so every process compiled it again and with it every kernel calling it (the
shipped unstab_sp_eigenvalue_transform case: 9 compilations, 8.8 s, in every run). Counted,
not timed, as in tests/test_compile_cache.py (whose subprocess runner and data writer are
used). Data: ẋ = −2x + u, y = x (+ noise σ 0.002, seed 5), a doublet u.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from test_compile_cache import _flightid_run, write_first_order_data

MODEL = """
import numpy as np

STATES = ("x",)
INPUTS = ("u",)
OUTPUTS = ("y",)
PARAMETERS = {"a": 1.5, "b": 0.8}
# a factor only this test's model has (its kernels are compiled by this test)
SCALE = 1.0


def f(t, x, u, theta):
    dx = np.empty(1)
    # ẋ = −a x + b u (linear and homogeneous, as the eigenvalue shift requires)
    dx[0] = SCALE * (-theta[0] * x[0] + theta[1] * u[0])
    return dx


def h(t, x, u, theta):
    y = np.empty(1)
    y[0] = x[0]
    return y
"""

CASE = """
title = "first-order system, eigenvalue shift"

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

[estimation]
solver = "mnr"
method = "rk4"
eigenvalue_shift = 0.5
"""


@pytest.fixture
def case_file(tmp_path: Path) -> Path:
    write_first_order_data(tmp_path, state_bias=0.0, output_offset=0.0, seed=5)
    scale = 1.0 + float(abs(hash(str(tmp_path))) % 1000) * 1e-15
    (tmp_path / "model.py").write_text(MODEL.replace("SCALE = 1.0", f"SCALE = {scale!r}"))
    path = tmp_path / "case.toml"
    path.write_text(CASE)
    return path


def test_second_run_of_an_eigenvalue_shift_case_compiles_nothing(case_file, tmp_path):
    cache = tmp_path / "numba-cache"
    first = _flightid_run(case_file, cache)
    second = _flightid_run(case_file, cache)
    assert first["compiles"] > 0
    assert second["compiles"] == 0
    entries = [run["results"]["results"][0] for run in (first, second)]
    for entry in entries:
        entry.pop("wall_time_s")
    assert entries[1] == entries[0]
