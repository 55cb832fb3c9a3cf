"""time_histories.csv rows built a matrix at a time: the same fields as one value at a time
(a Python float per number, written by ``csv`` with ``repr`` precision; an input that is not
finite as an empty field)."""

from __future__ import annotations

import csv
import io

import numpy as np

from flightid.report.histories import _rows


def _one_at_a_time(maneuver, role, time, inputs, measured, predicted):
    # the independent reference: each field converted on its own
    rows = []
    for i in range(len(time)):
        row = [maneuver, role, float(time[i])]
        row += ["" if not np.isfinite(v) else float(v) for v in inputs[i]]
        row += [float(v) for v in measured[i]]
        row += [float(v) for v in predicted[i]]
        row += [float(measured[i, j] - predicted[i, j]) for j in range(measured.shape[1])]
        rows.append(row)
    return rows


def _lines(lines) -> str:
    # ``_rows`` gives each CSV line without its line end (csv's default "\r\n")
    return "".join(line + "\r\n" for line in lines)


def _text(rows) -> str:
    stream = io.StringIO()
    csv.writer(stream).writerows(rows)
    return stream.getvalue()


def test_rows_match_the_fields_converted_one_at_a_time():
    rng = np.random.default_rng(11)
    n = 50
    time = 12.34 + 0.02 * np.arange(n)
    inputs = rng.normal(size=(n, 3)) * 1e-7
    inputs[[3, 17], [0, 2]] = np.nan
    inputs[20, 1] = np.inf
    measured = rng.normal(size=(n, 2)) * 1e5
    measured[5, 1] = np.nan
    predicted = measured + rng.normal(size=(n, 2))
    ours = _rows("m1", "prediction", time, inputs, measured, predicted)
    reference = _one_at_a_time("m1", "prediction", time, inputs, measured, predicted)
    assert _lines(ours) == _text(reference)
    fields = [line.split(",") for line in ours]
    assert fields[3][3] == "" and fields[20][4] == "" and fields[0][2] == repr(float(time[0]))


def test_rows_without_inputs():
    time = np.arange(4.0)
    measured = np.arange(8.0).reshape(4, 2)
    ours = _rows("m", "estimation", time, np.empty((4, 0)), measured, measured / 2)
    assert ours[1] == "m,estimation,1.0,2.0,3.0,1.0,1.5,1.0,1.5"
