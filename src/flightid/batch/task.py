"""One batch case as a task: run it, write its result folder, return its record.

``run_task`` is what a worker (a Dask worker process, or this process for the serial engine)
executes. It reads the case from its text (``flightid.cases.spec.parse_case``, the case lying
at ``BatchCase.path``), runs it with ``flightid.cases.run_case`` — the code path of
``flightid run`` — and writes ``cases/<name>/`` with the report writer of ``flightid run``
(``flightid.report.html.write_files``: results.json, estimates.csv, figures, report.html)
plus ``batch.json``, the record the results table is built from. The folder is written to a
temporary folder and renamed into place (``flightid.report.folder.ResultFolder``): a killed
worker leaves either the old result or the new one, never half of one.

A case that fails (any ``FlightIdError``: bad data path, a model that breaks its contract, a
diverging simulation, ...) is a record with ``status = "failed"`` and the one-line message of
``flightid: error: …`` in ``error``; an unexpected exception is recorded the same way as an
internal error with its type. The batch goes on either way.

The record counts the numba compilations the task caused (``numba_compilations``, and their
time ``numba_compile_s``, from numba's ``numba:compile`` events, which fire only when a
function is really compiled, not when it is loaded from the disk cache): with flightid's
kernel cache (``flightid.model.kernel_cache``) shared by the processes of one machine, only the
first task of a model compiles.
"""

from __future__ import annotations

import json
import math
import os
import time
import tomllib
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from flightid.batch.plan import BatchCase

__all__ = [
    "RECORD_FILE",
    "WARM_MODELS_MAX",
    "CaseTask",
    "model_tasks",
    "read_record",
    "run_task",
    "warm_case",
]

RECORD_FILE = "batch.json"
RECORD_VERSION = 2
# the most distinct models of a batch whose kernels every worker loads before the first case
WARM_MODELS_MAX = 4


@dataclass(frozen=True)
class CaseTask:
    """What a worker needs to run one case (picklable: plain data).

    Attributes:
        case: the planned case (name, text, path, conditions).
        fingerprint: its fingerprint (``flightid.batch.fingerprint``), stored with the result.
        folder: the case's result folder (``DIR/cases/<name>``), absolute.
        data_dir: the ``--data-dir`` override, or None.
        accuracy: the ``--accuracy`` option, or None (the case's ``accuracy.methods``).
    """

    case: BatchCase
    fingerprint: str
    folder: Path
    data_dir: str | None = None
    accuracy: str | None = None


@contextmanager
def _count_compilations() -> Iterator[dict[str, float]]:
    """Count numba compilations (``numba:compile`` events) and their outermost time, s."""
    from numba.core import event

    counts = {"n": 0, "s": 0.0}

    class Counter(event.Listener):
        depth = 0
        start = 0.0

        def on_start(self, ev) -> None:
            counts["n"] += 1
            if self.depth == 0:
                self.start = time.perf_counter()
            self.depth += 1

        def on_end(self, ev) -> None:
            self.depth -= 1
            if self.depth == 0:
                counts["s"] += time.perf_counter() - self.start

    with event.install_listener("numba:compile", Counter()):
        yield counts


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _rows(run) -> tuple[list[dict[str, Any]], str | None]:
    """Per parameter: name, unit, value, the default σ, the Cramér–Rao σ, the coloured σ (free
    parameters)."""
    est = run.estimate
    coloured: dict[str, float] = {}
    note = None
    try:
        from flightid.report.html import _coloured

        result = _coloured(run)
        coloured = dict(zip(result.names, (float(s) for s in result.std_coloured), strict=True))
    except Exception as exc:  # the corrected σ is a diagnostic: its absence is noted
        note = f"coloured σ not computed ({type(exc).__name__}: {exc})"
    units = tuple(getattr(est, "parameter_units", ()) or ("",) * len(est.names))
    rows = []
    for i, name in enumerate(est.names):
        free = bool(est.free[i])
        rows.append(
            {
                "parameter": name,
                "unit": units[i],
                "value": _finite(float(est.values[i])),
                "std": _finite(float(est.std[i])) if free else None,
                "std_cr": _finite(float(est.std_cr[i])) if free else None,
                "coloured_std": _finite(coloured[name]) if name in coloured else None,
                "free": free,
            }
        )
    return rows, note


def read_record(folder: Path) -> dict[str, Any] | None:
    """The record stored in a case folder (None: none, or unreadable)."""
    try:
        record = json.loads((folder / RECORD_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) and record.get("version") == RECORD_VERSION else None


def _record_json(record: dict[str, Any]) -> str:
    return json.dumps(record, indent=2, allow_nan=False) + "\n"


def run_task(task: CaseTask) -> dict[str, Any]:
    """Run one case and write its folder; returns its record (also in ``batch.json``).

    Never raises for a failing case (the record says ``failed``); raises ``OutputError``
    only when the folder cannot be written.
    """
    from flightid.cases.run import run_case
    from flightid.cases.spec import CaseError, parse_case
    from flightid.cases.stages import has_regression_stages
    from flightid.errors import error_line
    from flightid.report.folder import ResultFolder

    case = task.case
    record: dict[str, Any] = {
        "version": RECORD_VERSION,
        "case": case.name,
        "fingerprint": task.fingerprint,
        "conditions": dict(case.conditions),
        "case_path": str(case.path),
        "worker_pid": os.getpid(),
    }
    started = time.perf_counter()
    run = None
    with _count_compilations() as counts:
        try:
            try:
                raw = tomllib.loads(case.text)
            except tomllib.TOMLDecodeError as exc:
                raise CaseError(f"case {case.path}: not valid TOML ({exc})") from None
            parsed = parse_case(raw, case.path)
            if parsed.staged and has_regression_stages(parsed):
                raise CaseError(
                    f"case {case.name}: cases with regression stages are not run by "
                    "`flightid batch` yet; run it with `flightid run`"
                )
            run = run_case(parsed, task.data_dir, accuracy=task.accuracy)
        except Exception as exc:  # every failure is data: recorded, the batch goes on
            record["error"] = error_line(exc).removeprefix("flightid: error: ")
    record["wall_s"] = time.perf_counter() - started
    record["numba_compilations"] = int(counts["n"])
    record["numba_compile_s"] = float(counts["s"])
    if run is None:
        record.update(status="failed", converged=False, rows=[])
    else:
        rows, note = _rows(run)
        record.update(
            status=str(run.estimate.status),
            converged=bool(run.estimate.converged),
            rows=rows,
            report="report.html" if run.case.output.get("report", True) else None,
        )
        if note:
            record["note"] = note

    def write(directory: Path) -> None:
        if run is not None:
            from flightid.report.html import write_files

            write_files(run, directory)
        (directory / "case.toml").write_text(case.text, encoding="utf-8")
        (directory / RECORD_FILE).write_text(_record_json(record), encoding="utf-8")

    written = time.perf_counter()
    folder = ResultFolder.open(task.folder, overwrite=True, label="batch case folder")
    try:
        folder.write(write)
    finally:
        folder.release()
    # the time spent writing the report (not in batch.json: it is known only afterwards)
    record["write_s"] = time.perf_counter() - written
    return record


def _model_key(task: CaseTask) -> str | None:
    """What makes the compiled kernels of a case: its ``[model]`` table and its
    ``[estimation]`` table (method, input interpolation, ...); None for a case whose text is
    not TOML (it fails when it runs)."""
    try:
        raw = tomllib.loads(task.case.text)
    except tomllib.TOMLDecodeError:
        return None
    model = raw.get("model")
    if isinstance(model, dict) and isinstance(model.get("module"), str):
        # a relative module path is relative to the case file
        model = {**model, "module": str((task.case.path.parent / model["module"]).resolve())}
    parts = {"model": model, "estimation": raw.get("estimation"), "stages": raw.get("stages")}
    return json.dumps(parts, sort_keys=True, default=str)


def model_tasks(tasks: list[CaseTask], limit: int = WARM_MODELS_MAX) -> dict[str, CaseTask]:
    """The first task of each distinct model of ``tasks`` (by the key of its ``[model]`` and
    ``[estimation]`` tables), ``limit`` of them at most, in plan order."""
    chosen: dict[str, CaseTask] = {}
    for task in tasks:
        key = _model_key(task)
        if key is not None and key not in chosen:
            chosen[key] = task
            if len(chosen) >= limit:
                break
    return chosen


def warm_case(task: CaseTask) -> None:
    """Run a case once exactly as its task runs it (``run_task``), into a temporary folder
    that is then deleted, so that the process loads (from the disk cache) or compiles every
    kernel of its model, its accuracy assessment and the report writer's code; nothing of
    it is kept. Raises what ``run_task`` raises."""
    import dataclasses
    import tempfile

    with tempfile.TemporaryDirectory(prefix="flightid-warm-") as folder:
        run_task(dataclasses.replace(task, folder=Path(folder) / task.case.name))
