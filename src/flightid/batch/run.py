"""``run_batch``: plan, skip what is done, run the rest on an engine, write table and pages.

    plan (flightid.batch.plan) ─► fingerprint each case (flightid.batch.fingerprint)
        ─► skip cases whose cases/<name>/batch.json holds the same fingerprint
        ─► run the others as tasks (flightid.batch.task.run_task) on the engine
           (flightid.batch.engine: serial or Dask), each writing its folder atomically
        ─► rebuild estimates.csv / .parquet from the records (flightid.batch.table),
           carpet plots (flightid.batch.plots), index.html (flightid.batch.index)

The batch folder is locked while a batch writes to it (``.flightid-batch-lock``, released
by the system if the process dies). An interrupted batch (Ctrl-C, a killed process, a lost
cluster) keeps every case that finished — their folders were written whole — and the table
is rebuilt at the end of every batch, interrupted or not, from the records on disk; running
the same command again runs only the cases without a current result (resume). Progress on
stderr, one line per finished case::

    batch: 3/8 done (1 skipped), 2 running, 1 failed, about 40 s left — attas_sp: converged
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from flightid.batch.engine import DaskEngine, make_engine
from flightid.batch.fingerprint import fingerprint
from flightid.batch.plan import BatchCase, BatchError, plan_cases
from flightid.batch.task import CaseTask, model_tasks, read_record, run_task, warm_case
from flightid.parallel import SerialEngine

try:  # POSIX
    import fcntl
except ImportError:  # pragma: no cover
    fcntl = None  # type: ignore[assignment]

__all__ = ["BatchResult", "run_batch"]

Progress = Callable[[str], None]


@dataclass(frozen=True)
class BatchResult:
    """What a batch produced.

    Attributes:
        out: the batch folder.
        records: one record per planned case, in plan order (``flightid.batch.task``).
        ran: names of the cases run by this call.
        skipped: names of the cases whose stored result was current.
        engine: which engine ran the tasks ("" when nothing ran).
        files: estimates.csv, estimates.parquet (when written), plots, index.html.
        startup_s: the start-up of the Dask engine this call made (s; connecting or
            starting the cluster, warming its workers and loading the batch's models on
            them); for an engine handed in, the loading of the models (``warm_s``); 0 for
            the serial engine.
        warm_s: of that, the time the workers took to load the batch's models (s).
    """

    out: Path
    records: tuple[dict[str, Any], ...]
    ran: tuple[str, ...] = ()
    skipped: tuple[str, ...] = ()
    engine: str = ""
    files: tuple[Path, ...] = field(default_factory=tuple)
    startup_s: float = 0.0
    warm_s: float = 0.0

    @property
    def failed(self) -> tuple[str, ...]:
        """Names of the cases that failed."""
        return tuple(r["case"] for r in self.records if r.get("status") == "failed")


@contextlib.contextmanager
def _locked(out: Path) -> Iterator[None]:
    if fcntl is None:  # pragma: no cover
        yield
        return
    fd = os.open(out / ".flightid-batch-lock", os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise BatchError(f"--out {out}: another flightid batch is writing to it") from None
        yield
    finally:
        os.close(fd)


def _failed_record(case: BatchCase, fp: str, exc: BaseException) -> dict[str, Any]:
    from flightid.errors import error_line

    if type(exc).__name__ == "KilledWorker":  # distributed.KilledWorker
        message = (
            "the worker processes running it died each time it ran (killed, out of memory, "
            "or a crash in compiled code); see distributed.scheduler.allowed-failures"
        )
    else:
        message = error_line(exc).removeprefix("flightid: error: ")
    return {
        "version": 1,
        "case": case.name,
        "fingerprint": fp,
        "conditions": dict(case.conditions),
        "status": "failed",
        "converged": False,
        "rows": [],
        "error": f"the task did not finish: {message}",
    }


def _eta(started: float, done: int, remaining: int) -> str:
    if done == 0 or remaining == 0:
        return "" if remaining == 0 else ", time left unknown"
    left = (time.monotonic() - started) / done * remaining
    return f", about {left:.0f} s left"


def _sort_cases(
    cases: list[BatchCase],
    out: Path,
    data_dir: str | None,
    accuracy: str | None,
    retry_failed: bool,
) -> tuple[dict[str, dict[str, Any]], list[CaseTask], list[str], list[float]]:
    """(records of the cases whose stored result is current, tasks of the others, names
    skipped, the wall times (s) of every case's earlier run recorded in ``out``)."""
    records: dict[str, dict[str, Any]] = {}
    tasks: list[CaseTask] = []
    skipped: list[str] = []
    earlier_s: list[float] = []
    for case in cases:
        fp = fingerprint(case, data_dir, accuracy)
        folder = out / "cases" / case.name
        stored = read_record(folder)
        if stored is not None and isinstance(stored.get("wall_s"), int | float):
            earlier_s.append(float(stored["wall_s"]))
        if (
            stored is not None
            and stored.get("fingerprint") == fp
            and not (retry_failed and stored.get("status") == "failed")
        ):
            stored["conditions"] = dict(case.conditions)
            records[case.name] = stored
            skipped.append(case.name)
            continue
        tasks.append(CaseTask(case, fp, folder, data_dir, accuracy))
    return records, tasks, skipped, earlier_s


def _run_tasks(
    engine: SerialEngine | DaskEngine,
    tasks: list[CaseTask],
    records: dict[str, dict[str, Any]],
    ran: list[str],
    counts: tuple[int, int],
    say: Progress,
    task_s: float | None = None,
) -> None:
    """Run ``tasks`` on ``engine``, adding each record to ``records`` and its name to
    ``ran`` as it finishes, with a progress line (``counts``: cases skipped, cases);
    ``task_s``: the expected time of a case (s), which sizes a Dask engine's chunks."""
    n_skipped, n_cases = counts
    started = time.monotonic()
    n_failed = 0
    if isinstance(engine, DaskEngine):
        finished = engine.map_unordered(run_task, tasks, task_s=task_s)
    else:
        finished = engine.map_unordered(run_task, tasks)
    for i, (task, record, exc) in enumerate(finished, start=1):
        if exc is not None:
            record = _failed_record(task.case, task.fingerprint, exc)
        records[task.case.name] = record
        ran.append(task.case.name)
        failed = record.get("status") == "failed"
        n_failed += failed
        remaining = len(tasks) - i
        running = min(engine.workers, remaining)
        what = f"failed: {record.get('error')}" if failed else record.get("status")
        say(
            f"batch: {i + n_skipped}/{n_cases} done ({n_skipped} skipped), {running} running, "
            f"{n_failed} failed{_eta(started, i, remaining)} — {task.case.name}: {what}"
        )


STARTUP_FILE = ".flightid-startup.json"  # measured LocalCluster start-ups, by workers


def _read_startups(out: Path) -> dict[int, float]:
    """The LocalCluster start-ups (s) measured by earlier batches into ``out``, by the
    number of workers ({} where none was, or the file is not what this writes)."""
    try:
        raw = json.loads((out / STARTUP_FILE).read_text(encoding="utf-8"))
        return {int(n): float(s) for n, s in raw.items() if float(s) >= 0.0}
    except (OSError, ValueError, TypeError, AttributeError):
        return {}


def _write_startup(out: Path, workers: int, startup_s: float) -> None:
    """Keep the start-up of a LocalCluster of ``workers`` in ``out`` (the next batch's
    choice of serial or Dask uses it)."""
    startups = _read_startups(out)
    startups[workers] = round(startup_s, 3)
    text = json.dumps({str(n): s for n, s in sorted(startups.items())})
    with contextlib.suppress(OSError):
        (out / STARTUP_FILE).write_text(text + "\n", encoding="utf-8")


def _task_estimate_s(earlier_s: list[float]) -> float | None:
    """The expected wall time of one case (s): the median of the earlier runs' wall times
    recorded in the batch folder, None where there are none (``DEFAULT_TASK_S``)."""
    if not earlier_s:
        return None
    ordered = sorted(earlier_s)
    middle = len(ordered) // 2
    # median: the middle value, or the mean of the two middle values
    return ordered[middle] if len(ordered) % 2 else 0.5 * (ordered[middle - 1] + ordered[middle])


def run_batch(
    sources: Sequence[str | Path] | Sequence[BatchCase],
    out: str | Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    engine: SerialEngine | DaskEngine | None = None,
    data_dir: str | Path | None = None,
    accuracy: str | None = None,
    retry_failed: bool = False,
    plot_against: str | None = None,
    progress: Progress | None = None,
) -> BatchResult:
    """Run a batch of cases into the folder ``out`` (see the module docstring).

    Args:
        sources: case files and batch files (``flightid.batch.plan``), or planned cases.
        out: the batch folder (made if missing); cases go to ``out/cases/<name>/``.
        workers: worker processes of a LocalCluster (1: serial; never more than cases to
            run; None: one per core where that pays, else serial,
            ``flightid.batch.engine.choose_workers``, with the earlier runs' median wall
            time in this folder as the estimate of a case's time).
        scheduler: address of a running Dask scheduler (instead of ``workers``).
        engine: an engine to use (not closed here); overrides ``workers``/``scheduler``.
        data_dir: the data directory for every case (overrides the cases').
        accuracy: the accuracy option for every case (``cr``, ``profile``, ...), or None.
        retry_failed: run failed cases again even when their fingerprint is unchanged.
        plot_against: flight-condition column for the carpet plots (None: no plots).
        progress: receives one-line progress messages (None: silent).

    Raises:
        BatchError: a bad source, a locked folder, an unknown plot column.
    """
    from flightid.batch.index import write_index
    from flightid.batch.plots import carpet_plots
    from flightid.batch.table import table_rows, write_table

    say = progress or (lambda message: None)
    if sources and all(isinstance(s, BatchCase) for s in sources):
        cases = list(sources)  # type: ignore[arg-type]
    else:
        cases = plan_cases(sources)  # type: ignore[arg-type]
    out = Path(out).expanduser().resolve()
    if out.exists() and not out.is_dir():
        raise BatchError(f"--out {out}: is a file, expected a folder")
    out.mkdir(parents=True, exist_ok=True)
    data_dir = None if data_dir is None else str(Path(data_dir).expanduser().resolve())
    with _locked(out):
        records, tasks, skipped, earlier_s = _sort_cases(
            cases, out, data_dir, accuracy, retry_failed
        )
        (out / "cases").mkdir(exist_ok=True)
        say(
            f"batch: {len(cases)} case(s), {len(skipped)} up to date (skipped), {len(tasks)} to run"
        )
        ran: list[str] = []
        description = ""
        startup_s = warm_s = 0.0
        try:
            if tasks:
                own = engine is None
                task_s = _task_estimate_s(earlier_s)
                engine = engine or make_engine(
                    workers, scheduler, len(tasks), task_s=task_s, startup_s=_read_startups(out)
                )
                description = engine.description
                started_in = ""
                if isinstance(engine, DaskEngine):
                    # every worker loads the kernels of the batch's models: start-up
                    warm_s = engine.warm_models(warm_case, model_tasks(tasks))
                    startup_s = engine.startup_s if own else warm_s
                    started_in = f", started in {startup_s:.1f} s ({warm_s:.1f} s loading models)"
                    if own and engine.started_cluster:  # a LocalCluster's: for the next batch
                        _write_startup(out, engine.workers, startup_s)
                say(f"batch: engine {description}{started_in}")
                try:
                    counts = (len(skipped), len(cases))
                    _run_tasks(engine, tasks, records, ran, counts, say, task_s)
                finally:
                    if own:
                        engine.close()
        finally:
            # the table of what is on disk now, also after an interrupt
            ordered = []
            for case in cases:
                record = records.get(case.name) or read_record(out / "cases" / case.name)
                if record is not None:
                    record["conditions"] = dict(case.conditions)
                    ordered.append(record)
            files = write_table(ordered, out, notice=say)
        plots: list[Path] = []
        if plot_against is not None:
            _, rows = table_rows(ordered)
            plots = carpet_plots(rows, plot_against, out)
        files += plots
        files.append(write_index(ordered, out, plots, description))
    return BatchResult(
        out,
        tuple(ordered),
        tuple(ran),
        tuple(skipped),
        description,
        tuple(files),
        startup_s,
        warm_s,
    )
