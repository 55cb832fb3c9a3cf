"""The CSV writers give byte for byte what the plain per-value writers gave (repr of each
number as a Python float; csv's quoting and line ends), on seeded data with NaN, ±inf,
negative zero, integers, booleans, tiny and huge magnitudes."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest

from flightid.compat.reconstruct import Reconstruction


def _awkward_columns(seed: int, n: int = 400) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    values = rng.normal(size=n) * 10.0 ** rng.integers(-20, 20, size=n)
    values[[3, 50]] = np.nan
    values[[7, 8]] = [np.inf, -np.inf]
    values[[11, 12]] = [-0.0, 0.0]
    values[13] = 5e-324  # the smallest subnormal
    return {
        "time [s]": np.arange(n) * 0.04,
        "alpha_rec [rad]": values,
        "count": np.arange(n, dtype=np.int64) - 200,
        "flag": np.arange(n) % 3 == 0,
        "rounded": np.round(rng.normal(size=n), 2),
    }


def _reference_reconstruction_csv(columns: dict[str, np.ndarray]) -> bytes:
    # the per-value writer: one numpy scalar at a time through float and repr
    names = list(columns)
    data = np.column_stack([columns[n] for n in names])
    out = io.StringIO(newline="")
    out.write(",".join(names) + "\n")
    for row in data:
        out.write(",".join(repr(float(v)) for v in row) + "\n")
    return out.getvalue().encode("utf-8")


def test_reconstruction_csv_is_byte_identical(tmp_path):
    for seed in range(3):
        columns = _awkward_columns(seed)
        path = Reconstruction("m", columns).write_csv(tmp_path / f"r{seed}.csv")
        assert path.read_bytes() == _reference_reconstruction_csv(columns)
    # integer columns alone are written as floats too ("3.0"), as before
    ints = {"a": np.arange(5), "b": np.arange(5) * 2}
    path = Reconstruction("m", ints).write_csv(tmp_path / "ints.csv")
    assert path.read_bytes() == _reference_reconstruction_csv(ints)
    assert path.read_text().splitlines()[2] == "1.0,2.0"
    # no rows: the header alone
    empty = {"a": np.array([]), "b": np.array([])}
    path = Reconstruction("m", empty).write_csv(tmp_path / "empty.csv")
    assert path.read_bytes() == b"a,b\n"


def _reference_history_rows(maneuver, role, time, inputs, measured, predicted) -> list[list]:
    # the rows as csv.writer got them: names, then Python floats; a non-finite input ""
    residual = measured - predicted
    n = len(time)
    inputs = np.asarray(inputs, dtype=float).reshape(n, -1)
    rows = []
    for i in range(n):
        shown = [float(v) if np.isfinite(v) else "" for v in inputs[i]]
        numbers = [*measured[i], *predicted[i], *residual[i]]
        rows.append([maneuver, role, float(time[i]), *shown, *map(float, numbers)])
    return rows


@pytest.mark.filterwarnings("ignore:invalid value encountered in subtract")
def test_time_history_rows_are_byte_identical():
    from flightid.report.histories import _rows

    rng = np.random.default_rng(7)
    n = 300
    time = np.arange(n) * 0.02
    inputs = rng.normal(size=(n, 3)) * 10.0 ** rng.integers(-12, 12, size=(n, 3))
    inputs[[4, 9], 1] = np.nan
    inputs[9, 2] = np.inf
    inputs[20, :] = np.nan
    measured = _awkward_columns(3, n)["alpha_rec [rad]"].reshape(n, 1) * [1.0, -1.0]
    predicted = np.round(measured, 3)
    predicted[30, 0] = -0.0
    for name in ("plain", 'with "quotes", and a comma', "", "line\nbreak"):
        expected = io.StringIO(newline="")
        csv.writer(expected).writerows(
            _reference_history_rows(name, "prediction", time, inputs, measured, predicted)
        )
        lines = _rows(name, "prediction", time, inputs, measured, predicted)
        assert "\r\n".join(lines) + "\r\n" == expected.getvalue()
    # no inputs at all
    none = np.empty((n, 0))
    expected = io.StringIO(newline="")
    csv.writer(expected).writerows(
        _reference_history_rows("m", "estimation", time, none, measured, predicted)
    )
    lines = _rows("m", "estimation", time, none, measured, predicted)
    assert "\r\n".join(lines) + "\r\n" == expected.getvalue()
