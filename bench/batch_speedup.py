"""Scaling of ``flightid batch`` over worker processes, against the serial engine.

The batch: ``--cases`` simulated cases (32 by default) that need no flight data — the ATTAS
short-period model (``examples/models/attas_short_period.py``) fitted to its own response to
a 3-2-1-1 elevator input, simulated here with ``scipy.signal.lsim`` and seeded noise, one
data file per case (seed = case number), each case with the profile-likelihood accuracy
(``--accuracy profile``: well under a tenth of a second per case on a quiet machine, so that
the engine's chunking of short cases into tasks of about half a second is what is measured).
Figures are off.

For each round (``--rounds``, taking turns: serial, then each worker count, round after
round; the best of the rounds is kept):

* ``1``: the serial engine in this process (warm: one untimed case ran first);
* ``N > 1``: a fresh ``DaskEngine(N)``: a LocalCluster of N worker processes with one thread
  each, started warm (one warm-up task per worker imports flightid, then each worker loads the
  batch's model); its start-up (``DaskEngine.startup_s``, with the model loading) is timed
  apart from the batch, and the engine is closed after it.

Then, once each: the batch on an **external** LocalCluster started here, reached by its
scheduler address (``run_batch(scheduler=address)``, as ``flightid batch --scheduler``); and
a small batch through the command line (``flightid batch --workers 2``, 3 cases) in a fresh
process, whose stderr must hold no warning; and the engine choice for a batch smaller than
the Dask threshold and for ``--workers 12`` on 2 cases.

The table: workers, tasks, start-up, batch wall time, total (start-up + batch), speed-up of
the batch and of the total against serial, and the efficiency, speed-up / N (on a machine of
C cores, at most min(N, C)/N: N > C over-subscribes the cores, which is what a 2-core machine
can measure). PASS/FAIL lines:

* batch never slower than serial + its start-up (10 % allowance for a shared machine), for
  the rows of no more workers than cores; the rows of more workers than cores (the cores
  over-subscribed) are printed with their ratio total / (serial + start-up), not checked;
* a small batch runs serially by default, with a note saying why;
* workers ≤ tasks (``--workers 12`` on 2 cases starts 2 worker processes);
* clean shutdown: no ``killing`` or other warning of Dask, in this process or the CLI's stderr;
* the external cluster by scheduler address: same numbers, its workers still up afterwards;
* values and σ identical in every mode.

Usage::

    python bench/batch_speedup.py [--quick] [--cases 32] [--workers 1 2 4 8] [--rounds 2]
"""

from __future__ import annotations

import argparse
import logging
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "examples" / "models" / "attas_short_period.py"
GUIDE = "docs/benchmarks.md"
# the simulated aircraft: ATTAS short period, α̇ = Zα α + (1 + Zq) q + Zδe δe,
# q̇ = Mα α + Mq q + Mδe δe (1/s, 1/s², rad)
TRUE = {"Za": -0.5, "Zq": 0.1, "Zde": 0.7, "Ma": -5.0, "Mq": -2.0, "Mde": -7.0}
NOISE = (2e-4, 5e-4)  # σ of α (rad) and q (rad/s)
SLOWER_ALLOWANCE = 1.10  # a shared machine's noise on "never slower than serial + start-up"


def write_simulated_case(folder: Path, index: int, duration_s: float = 30.0) -> Path:
    """A case file and its CSV (time, de, alpha, q): the ATTAS short-period model's response
    to a 3-2-1-1 elevator input (0.02 rad, 1 s unit), noise seeded with ``index``."""
    import numpy as np
    import scipy.signal

    dt_s = 0.02
    t = np.arange(0.0, duration_s + 1e-9, dt_s)
    de = np.zeros_like(t)
    for start, stop, level in ((1, 4, 0.02), (4, 6, -0.02), (6, 7, 0.02), (7, 8, -0.02)):
        de[(t >= start) & (t < stop)] = level
    p = TRUE
    a = np.array([[p["Za"], 1.0 + p["Zq"]], [p["Ma"], p["Mq"]]])
    b = np.array([[p["Zde"]], [p["Mde"]]])
    _, y, _ = scipy.signal.lsim((a, b, np.eye(2), np.zeros((2, 1))), de, t)
    rng = np.random.default_rng(index)
    y = y + rng.normal(0.0, 1.0, y.shape) * np.asarray(NOISE)
    data = folder / f"sim{index:03d}.csv"
    np.savetxt(
        data, np.column_stack([t, de, y]), delimiter=",", header="time,de,alpha,q", comments=""
    )
    case = folder / f"sim{index:03d}.toml"
    case.write_text(
        f'title = "simulated short period {index}"\n\n[data]\ndata_dir = "{folder}"\n'
        f'file = "{data.name}"\ntime = "time"\n\n[data.inputs]\nde = {{ column = "de" }}\n\n'
        '[data.outputs]\nalpha = { column = "alpha" }\nq = { column = "q" }\n\n'
        f'[model]\nmodule = "{MODEL}"\n\n[initial_state]\ndefault = "measured"\n\n'
        '[estimation]\nsolver = "mnres"\nmethod = "rk4"\nnoise = "max"\n\n'
        "[output]\nfigures = false\n",
        encoding="utf-8",
    )
    return case


class _Warnings(logging.Handler):
    """Collects the warnings Dask logs in this process (the nannies live here)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(f"{record.name}: {record.getMessage()}")


def _values(result) -> dict:
    return {r["case"]: [(p["value"], p["std"]) for p in r["rows"]] for r in result.records}


def _timed_batch(cases, engine, accuracy):
    from flightid.batch import run_batch

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        result = run_batch(cases, tmp, engine=engine, accuracy=accuracy)
        wall_s = time.perf_counter() - t0
    if result.failed:
        raise SystemExit(f"cases failed: {result.failed}")
    return wall_s, result


def _scaling(cases, workers_list, rounds, accuracy):
    """{N: (best start-up s, best batch s)} and the values of every run, taking turns."""
    from flightid.batch.engine import DaskEngine
    from flightid.parallel import SerialEngine

    best: dict[int, tuple[float, float]] = {}
    values = []
    for _ in range(rounds):
        for n in workers_list:
            engine = SerialEngine() if n == 1 else DaskEngine(n)
            try:
                wall_s, result = _timed_batch(cases, engine, accuracy)
            finally:
                engine.close()
            # the models' loading on the workers is start-up (in engine.startup_s), not batch
            wall_s -= result.warm_s
            startup_s = getattr(engine, "startup_s", 0.0)
            values.append(_values(result))
            old = best.get(n, (float("inf"), float("inf")))
            best[n] = (min(old[0], startup_s), min(old[1], wall_s))
    return best, values


def _external(cases, accuracy):
    """The batch on a LocalCluster started here, by its scheduler address."""
    from distributed import Client, LocalCluster

    from flightid.batch import run_batch

    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as cluster:
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            result = run_batch(cases, tmp, scheduler=cluster.scheduler_address, accuracy=accuracy)
            wall_s = time.perf_counter() - t0
        with Client(cluster.scheduler_address) as client:
            still_up = len(client.scheduler_info()["workers"])
    return wall_s, result, still_up


def _cli_stderr(folder: Path) -> str:
    """stderr of ``flightid batch --workers 2`` on 3 cases, in a fresh process."""
    cases = [str(write_simulated_case(folder, 900 + k)) for k in range(3)]
    code = "import sys; from flightid.cli.main import main; sys.exit(main())"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    run = subprocess.run(
        [sys.executable, "-c", code, "batch", *cases, "--out", str(folder / "cli")]
        + ["--workers", "2"],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    if run.returncode != 0:
        raise SystemExit(f"flightid batch failed:\n{run.stderr}")
    return run.stderr


def _verdict(ok: bool, text: str) -> str:
    return f"{'PASS' if ok else 'FAIL'}: {text}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="8 cases, 1 and 2 workers, 1 round")
    parser.add_argument("--cases", type=int, default=32, help="simulated cases (default 32)")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2, 4, 8])
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument(
        "--accuracy", choices=("cr", "profile", "none"), default="profile", help="per case"
    )
    args = parser.parse_args(argv)
    if args.quick:
        args.cases, args.workers, args.rounds = 8, [1, 2], 1
    if 1 not in args.workers:
        args.workers = [1, *args.workers]

    from flightid.batch import plan_cases
    from flightid.batch.engine import choose_workers, make_engine
    from flightid.parallel import SerialEngine

    warnings = _Warnings()
    logging.getLogger("distributed").addHandler(warnings)
    cores = os.cpu_count() or 1
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        cases = plan_cases([write_simulated_case(folder, k) for k in range(args.cases)])
        _timed_batch(cases[:1], SerialEngine(), args.accuracy)  # this process warm
        best, values = _scaling(cases, args.workers, args.rounds, args.accuracy)
        external_s, external, still_up = _external(cases, args.accuracy)
        values.append(_values(external))
        cli_err = _cli_stderr(folder)
    small = choose_workers(None, 3, cores=max(2, cores))
    with make_engine(12, None, n_tasks=2) as clamped:
        clamped_workers = clamped.workers
    logging.getLogger("distributed").removeHandler(warnings)

    serial_s = best[1][1]
    print(f"<!-- guide: {GUIDE} -->")
    print("<!-- numbers: benchmarks-batch-scaling rel=0.5 -->")
    print(
        f"{args.cases} simulated cases (accuracy {args.accuracy}), {cores} cores, best of "
        f"{args.rounds} round(s)\n"
    )
    print(
        "| workers | tasks | start-up (s) | batch wall (s) | total wall (s) | speed-up batch "
        "| speed-up total | efficiency |"
    )
    print("|---|---|---|---|---|---|---|---|")
    slower, oversubscribed = [], []
    for n in args.workers:
        startup_s, wall_s = best[n]
        total_s = startup_s + wall_s
        speedup = serial_s / wall_s
        # never slower than serial by more than the start-up (allowance for a shared machine)
        ratio = total_s / ((serial_s + startup_s) * SLOWER_ALLOWANCE)
        (slower if n <= cores else oversubscribed).append((n, ratio))
        print(
            f"| {n} | {args.cases} | {startup_s:.1f} | {wall_s:.1f} | {total_s:.1f} | "
            f"{speedup:.2f} | {serial_s / total_s:.2f} | {speedup / n:.2f} |"
        )
    # the external cluster: its start-up is the connection and warm-up inside run_batch
    wall_s = external_s - external.startup_s
    print(
        f"| 2 (scheduler address) | {args.cases} | {external.startup_s:.1f} | {wall_s:.1f} | "
        f"{external_s:.1f} | {serial_s / wall_s:.2f} | {serial_s / external_s:.2f} | "
        f"{serial_s / wall_s / 2:.2f} |"
    )
    print()
    killing = [m for m in warnings.messages if "killing" in m]
    cli_warnings = [line for line in cli_err.splitlines() if "WARNING" in line or "killing" in line]
    identical = all(v == values[0] for v in values)
    print(
        _verdict(
            max(r for _, r in slower) <= 1.0,
            f"batch never slower than serial + its start-up, workers ≤ {cores} cores "
            "(10 % allowance; more workers than cores share the cores and are not checked)",
        )
    )
    if oversubscribed:
        print(
            "over-subscribed rows, total / (serial + start-up): "
            + ", ".join(f"{n} workers {r * SLOWER_ALLOWANCE:.2f}" for n, r in oversubscribed)
        )
    print(_verdict(small.workers == 1 and bool(small.note), "a batch of 3 cases runs serially"))
    print(_verdict(clamped_workers == 2, "workers ≤ tasks (--workers 12 on 2 cases: 2 workers)"))
    print(
        _verdict(
            not killing and not warnings.messages and not cli_warnings,
            "clean shutdown (no killing warnings)",
        )
    )
    print(
        _verdict(
            still_up == 2 and values[-1] == values[0],
            "external LocalCluster by scheduler address: same numbers, its 2 workers still up",
        )
    )
    print(_verdict(identical, "values and σ identical in every mode"))
    print("<!-- /numbers -->")
    for message in warnings.messages + cli_warnings:
        print(f"  warning seen: {message}", file=sys.stderr)
    print(f"small batch: {small.note}", file=sys.stderr)
    return 0 if identical and not killing else 1


if __name__ == "__main__":
    sys.exit(main())
