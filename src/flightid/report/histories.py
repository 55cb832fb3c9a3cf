"""Time histories of a case run, as one CSV file beside results.json.

``time_histories.csv`` holds every sample a run used or predicted, so that any tool can
replot it. One row per sample, columns

    maneuver, role, time, <input>..., <output>_measured..., <output>_predicted...,
    <output>_residual...

``maneuver`` is the maneuver's name, ``role`` is ``estimation`` (the maneuvers the
estimate was fitted to) or ``prediction`` (held-out maneuvers simulated with the estimated
model), ``time`` is in seconds, the inputs and outputs are in the model's units (after the
case's unit conversions), residual = measured − predicted. An input that a prediction
maneuver does not carry is left empty. Numbers are written with ``repr`` precision (no
rounding). The units of the columns are listed in results.json under ``time_histories``
(``time_history_columns``).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

__all__ = [
    "TIME_HISTORIES_FILE",
    "results_file_document",
    "time_history_columns",
    "write_results_and_histories",
    "write_time_histories",
]

TIME_HISTORIES_FILE = "time_histories.csv"


def _units(run) -> dict[str, str]:
    units: dict[str, str] = {}
    for maneuver in run.maneuvers:
        for name, unit in maneuver.units.items():
            units.setdefault(name, unit)
    units.update({n: u for n, u in run.estimate.output_unit_map.items() if u})
    return units


def time_history_columns(run) -> list[dict]:
    """[{"name": column, "unit": unit}] of ``time_histories.csv`` (unit ``""`` where none is
    known; ``maneuver`` and ``role`` are text)."""
    units = _units(run)
    columns = [
        {"name": "maneuver", "unit": ""},
        {"name": "role", "unit": ""},
        {"name": "time", "unit": "s"},
    ]
    columns += [{"name": n, "unit": units.get(n, "")} for n in run.model.inputs]
    for suffix in ("measured", "predicted", "residual"):
        columns += [
            {"name": f"{n}_{suffix}", "unit": units.get(n, "")} for n in run.estimate.output_names
        ]
    return columns


def _csv_fields(*texts: str) -> str:
    """``texts`` as the start of a CSV row, quoted as ``csv`` quotes them, with a trailing
    comma."""
    out = io.StringIO(newline="")
    csv.writer(out).writerow(texts)
    # csv's own line end taken off (a field holding a line break is quoted as before)
    return out.getvalue().removesuffix("\r\n") + ","


def _rows(maneuver: str, role: str, time, inputs, measured, predicted) -> list[str]:
    """One CSV line per sample (without its line end): the names, then the numbers, each
    as ``repr`` of a Python float (as ``csv`` writes a float), an input that is not finite
    as an empty field. The numbers are converted a matrix at a time (``tolist``), not one
    numpy scalar at a time."""
    residual = measured - predicted
    n = len(time)
    inputs = np.asarray(inputs, dtype=float).reshape(n, -1)
    numbers = np.column_stack(
        [np.asarray(time, dtype=float).reshape(n, 1), inputs, measured, predicted, residual]
    )
    head = _csv_fields(maneuver, role)
    lines = [head + ",".join(map(repr, row)) for row in numbers.tolist()]
    missing = ~np.isfinite(inputs)
    for i in np.flatnonzero(missing.any(axis=1)):
        # an input that is not finite is written as an empty field (column 1 + j)
        fields = [repr(v) for v in numbers[i].tolist()]
        for j in np.flatnonzero(missing[i]):
            fields[1 + j] = ""
        lines[i] = head + ",".join(fields)
    return lines


def write_time_histories(run, path: Path) -> Path:
    """Write ``time_histories.csv`` of a ``CaseRun`` to ``path``; returns the path."""
    estimate = run.estimate
    input_names = list(run.model.inputs)
    rows: list[str] = []
    index = np.asarray(estimate.maneuver_index)
    for k, maneuver in enumerate(run.maneuvers):
        selected = index == k
        inputs = np.column_stack(
            [np.asarray(maneuver.input(n), dtype=float) for n in input_names]
            or [np.empty((int(selected.sum()), 0))]
        )
        rows += _rows(
            maneuver.name,
            "estimation",
            estimate.time[selected],
            inputs,
            estimate.measured[selected],
            estimate.predicted[selected],
        )
    for prediction in run.predictions:
        n = len(prediction.time)
        inputs = np.full((n, len(input_names)), np.nan)
        held = list(getattr(prediction, "input_names", ()) or ())
        values = getattr(prediction, "inputs", None)
        if values is not None:
            values = np.asarray(values, dtype=float).reshape(n, -1)
            for j, name in enumerate(input_names):
                if name in held:
                    inputs[:, j] = values[:, held.index(name)]
        rows += _rows(
            prediction.name,
            "prediction",
            prediction.time,
            inputs,
            np.asarray(prediction.measured, dtype=float),
            np.asarray(prediction.predicted, dtype=float),
        )
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as stream:
        # csv's line end, \r\n, on every row
        csv.writer(stream).writerow([c["name"] for c in time_history_columns(run)])
        if rows:
            stream.write("\r\n".join(rows) + "\r\n")
    return path


def results_file_document(run) -> dict:
    """The results.json document of a run folder: ``results_document([run.to_dict()])``
    (``{"schema_version", "results"}``) plus ``time_histories`` ({"file", "columns"}: the
    CSV beside it and the unit of each column)."""
    from flightid.results import results_document

    document = results_document([run.to_dict()])
    document["time_histories"] = {
        "file": TIME_HISTORIES_FILE,
        "columns": time_history_columns(run),
    }
    return document


def write_results_and_histories(run, directory: Path) -> None:
    """Write results.json (strict JSON, ``results_file_document``) and time_histories.csv
    into ``directory``."""
    from flightid.jsonout import dumps

    directory = Path(directory)
    (directory / "results.json").write_text(
        dumps(results_file_document(run)) + "\n", encoding="utf-8"
    )
    write_time_histories(run, directory / TIME_HISTORIES_FILE)
