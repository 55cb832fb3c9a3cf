"""Speed-up of ``flightid batch`` on a Dask LocalCluster against the serial engine.

Runs the same batch — the standard cases, each ``--repeat`` times under distinct names, so
nothing is skipped — once per ``--workers`` count into fresh folders, in one process run:

* ``1``: the serial engine (this process; the kernels are already compiled or on disk);
* ``N > 1``: a ``LocalCluster(n_workers=N, threads_per_worker=1)``; the cluster start is timed
  apart from the batches.

Each engine runs the batch twice: the first ("cold") pays each worker's first imports of the
report and case code and its first load of each model's kernels from the disk cache; the
second ("warm") is what a long-lived cluster gives.

Each case is one task, so the speed-up of N workers is bounded by the number of cases and by
the longest case (the last task to start may run alone), and on a machine shared with other
work by the cores actually free. The tables of all runs are compared: values and σ must be
identical (same code, same data; only where the case ran differs).

Usage::

    python bench/batch_speedup.py [--workers 1 2] [--repeat 2] [--cases attas_short_period ...]
                                  [--figures] [--accuracy profile] [--data-dir DIR]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_CASES = (
    "attas_short_period",
    "twin_otter_longitudinal",
    "hfb320_longitudinal",
    "attas_fpr_biases",
)


def _cases(names: list[str], repeat: int, figures: bool) -> list:
    from flightid.batch import BatchCase

    cases = []
    for name in names:
        path = ROOT / "examples" / "cases" / f"{name}.toml"
        text = path.read_text(encoding="utf-8")
        if not figures:
            if "[output]" in text:
                text = text.replace("figures = true", "figures = false")
            else:
                text += "\n[output]\nfigures = false\n"
        for k in range(repeat):
            cases.append(BatchCase(f"{name}_{k}", text, path, {}, path))
    return cases


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--repeat", type=int, default=2, help="copies of each case")
    parser.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES))
    parser.add_argument("--figures", action="store_true", help="render the report figures")
    parser.add_argument("--data-dir", default=None)
    parser.add_argument(
        "--accuracy",
        choices=("cr", "profile", "search", "all", "none"),
        default=None,
        help="accuracy assessment of every case (longer cases)",
    )
    args = parser.parse_args(argv)

    from flightid.batch import run_batch
    from flightid.batch.engine import DaskEngine
    from flightid.parallel import SerialEngine

    cases = _cases(args.cases, args.repeat, args.figures)
    print(
        f"{len(cases)} cases ({', '.join(args.cases)} × {args.repeat}); "
        f"figures {'on' if args.figures else 'off'}; accuracy {args.accuracy or 'as the case'}; "
        f"{os.cpu_count()} cores"
    )
    # warm-up: every model compiled (or loaded from the disk cache) once in this process
    with tempfile.TemporaryDirectory() as tmp:
        run_batch(
            _cases(args.cases, 1, False),
            tmp,
            engine=SerialEngine(),
            data_dir=args.data_dir,
            accuracy=args.accuracy,
        )
    rows = []
    tables = {}
    for workers in args.workers:
        started = time.perf_counter()
        engine = SerialEngine() if workers == 1 else DaskEngine(workers)
        start_s = time.perf_counter() - started
        times = []
        try:
            # twice on the same engine: the first batch pays each worker's imports and first
            # loads of the kernels (cold), the second shows a warm cluster
            for _ in range(2):
                with tempfile.TemporaryDirectory() as tmp:
                    t0 = time.perf_counter()
                    result = run_batch(
                        cases, tmp, engine=engine, data_dir=args.data_dir, accuracy=args.accuracy
                    )
                    times.append(time.perf_counter() - t0)
                if result.failed:
                    print(f"failed with {workers} worker(s): {result.failed}", file=sys.stderr)
                    return 1
        finally:
            engine.close()
        tables[workers] = {
            r["case"]: [(p["value"], p["std"]) for p in r["rows"]] for r in result.records
        }
        compiled = sum(r.get("numba_compilations", 0) for r in result.records)
        task_s = sum(r.get("wall_s", 0.0) for r in result.records)
        rows.append((workers, start_s, times[0], times[1], task_s, compiled))
    cold0, warm0 = rows[0][2], rows[0][3]
    # task s: the cases' own wall times (run_case in the worker) summed, warm batch
    print(
        f"{'workers':>7} {'start s':>8} {'cold s':>8} {'warm s':>8} {'task s':>8} "
        f"{'speed-up cold':>13} {'speed-up warm':>13} {'compilations':>12}"
    )
    for workers, start_s, cold, warm, task_s, compiled in rows:
        print(
            f"{workers:>7} {start_s:>8.1f} {cold:>8.1f} {warm:>8.1f} {task_s:>8.1f} "
            f"{cold0 / cold:>13.2f} {warm0 / warm:>13.2f} {compiled:>12}"
        )
    first = tables[args.workers[0]]
    same = all(t == first for t in tables.values())
    print(f"values and σ identical across engines: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
