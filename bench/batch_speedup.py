"""Speed-up of ``flightid batch`` on a Dask LocalCluster against the serial engine (issue 15).

Runs the same batch — the standard cases, each ``--repeat`` times under distinct names, so
nothing is skipped — once per ``--workers`` count into fresh folders, in one process run:

* ``1``: the serial engine (this process; the kernels are already compiled or on disk);
* ``N > 1``: a ``LocalCluster(n_workers=N, threads_per_worker=1)``; the cluster start (worker
  processes importing flightid) is timed apart from the batch itself.

Each case is one task, so the speed-up of N workers is bounded by the number of cases and by
the longest case (the last task to start may run alone), and on a machine shared with other
work by the cores actually free. The tables of all runs are compared: values and σ must be
identical (same code, same data; only where the case ran differs).

Usage::

    python bench/batch_speedup.py [--workers 1 2] [--repeat 2] [--cases attas_short_period ...]
                                  [--figures] [--data-dir DIR]
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
        if not figures and "[output]" not in text:
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
    args = parser.parse_args(argv)

    from flightid.batch import run_batch
    from flightid.batch.engine import DaskEngine, SerialEngine

    cases = _cases(args.cases, args.repeat, args.figures)
    print(
        f"{len(cases)} cases ({', '.join(args.cases)} × {args.repeat}); "
        f"figures {'on' if args.figures else 'off'}; {os.cpu_count()} cores"
    )
    # warm-up: every model compiled (or loaded from the disk cache) once in this process
    with tempfile.TemporaryDirectory() as tmp:
        run_batch(_cases(args.cases, 1, False), tmp, engine=SerialEngine(), data_dir=args.data_dir)
    rows = []
    tables = {}
    for workers in args.workers:
        with tempfile.TemporaryDirectory() as tmp:
            started = time.perf_counter()
            engine = SerialEngine() if workers == 1 else DaskEngine(workers)
            start_s = time.perf_counter() - started
            try:
                t0 = time.perf_counter()
                result = run_batch(cases, tmp, engine=engine, data_dir=args.data_dir)
                batch_s = time.perf_counter() - t0
            finally:
                engine.close()
            if result.failed:
                print(f"failed cases with {workers} worker(s): {result.failed}", file=sys.stderr)
                return 1
            tables[workers] = {
                r["case"]: [(p["value"], p["std"]) for p in r["rows"]] for r in result.records
            }
            compiled = sum(r.get("numba_compilations", 0) for r in result.records)
            task_s = sum(r.get("wall_s", 0.0) for r in result.records)
            rows.append((workers, start_s, batch_s, task_s, compiled))
    base = rows[0][2]
    # task s: the cases' own wall times summed (run_case in the worker, without the report)
    print(
        f"{'workers':>7} {'start s':>8} {'batch s':>8} {'task s':>8} {'speed-up':>8} "
        f"{'compilations':>12}"
    )
    for workers, start_s, batch_s, task_s, compiled in rows:
        print(
            f"{workers:>7} {start_s:>8.1f} {batch_s:>8.1f} {task_s:>8.1f} "
            f"{base / batch_s:>8.2f} {compiled:>12}"
        )
    first = tables[args.workers[0]]
    same = all(t == first for t in tables.values())
    print(f"values and σ identical across engines: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
