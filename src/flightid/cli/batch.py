"""``flightid batch CASE.toml [CASE.toml ...] --out DIR [--workers N | --scheduler ADDRESS]
[--data-dir D] [--accuracy M] [--plot-against COLUMN] [--retry-failed] [--quiet]``.

Runs many cases (case files, and batch files: a case template with a table of flight
conditions, ``flightid.batch.plan``) on Dask distributed — a LocalCluster with one worker
process per core by default where that pays (else serially, with a note saying why;
``flightid.batch.engine.choose_workers``), ``--workers N`` of them (never more than cases to
run), or any running Dask cluster by its scheduler address (``--scheduler
tcp://host:8786``; never started or closed here) — or serially (``--workers 1``, or Dask
not installed). Writes into DIR:

* ``estimates.csv`` and ``estimates.parquet``: one row per case and parameter (columns
  ``case``, the flight-condition columns, ``parameter``, ``unit``, ``value``, ``std`` (the
  default σ), ``std_cr`` (Cramér–Rao), ``coloured_std``, ``free``, ``converged``,
  ``status``, ``error``; ``flightid.batch.table``);
* ``cases/<name>/``: each case's report as ``flightid run --out`` writes it, plus
  ``batch.json`` (its record and fingerprint) and ``case.toml`` (the text that ran);
* ``plots/*.png`` with ``--plot-against``; ``index.html`` linking every report.

``--multistart N`` (one case file): the case estimated from N start points on the same
engines (``flightid.batch.multistart``), the optima clustered; prints the clusters and
writes ``DIR/multistart.csv`` (one row per start and parameter).

A rerun skips the cases whose inputs are unchanged; an interrupted batch resumes. A failed
case is recorded (``status`` failed, ``error``) and the others go on; the exit status is 0
when the batch ran (read ``status``), 1 when it could not (a bad source, a locked folder).
Progress on stderr.
"""

from __future__ import annotations

import argparse
import sys

from flightid.cli.run import add_data_dir_argument


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "batch",
        help="run many cases (or a case template over a table) on Dask or serially",
        description=(
            "Run case files and case templates with a table of flight conditions, in "
            "parallel on Dask distributed (optional: pip install 'flightid[dask]') or "
            "serially; write one results table, each case's report, carpet plots and an "
            "index page. WARNING: a case with model.module runs that Python file."
        ),
    )
    parser.add_argument(
        "cases", nargs="+", metavar="CASE.toml", help="case files and batch files ([batch])"
    )
    parser.add_argument("--out", required=True, help="the batch folder (made if missing)")
    engine = parser.add_mutually_exclusive_group()
    engine.add_argument(
        "--workers",
        type=int,
        default=None,
        help="worker processes of a Dask LocalCluster, at most one per case to run (default: "
        "one per core where the batch is long enough for that to pay, else serially); 1 runs "
        "the cases serially in this process",
    )
    engine.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="address of a running Dask scheduler (tcp://host:8786): any Dask cluster, e.g. "
        "one of dask-jobqueue on an HPC batch system; used, never started or closed",
    )
    add_data_dir_argument(parser)
    parser.add_argument(
        "--accuracy",
        choices=("cr", "profile", "search", "all", "none"),
        default=None,
        help="accuracy assessment of every case (as flightid run --accuracy; default: each "
        "case's accuracy.methods)",
    )
    parser.add_argument(
        "--plot-against",
        default=None,
        metavar="COLUMN",
        help="carpet plots of each parameter against this flight-condition column",
    )
    parser.add_argument(
        "--retry-failed",
        action="store_true",
        help="run failed cases again even when their inputs did not change",
    )
    parser.add_argument(
        "--multistart",
        type=int,
        default=None,
        metavar="N",
        help="instead of a batch: estimate the one case given from N start points (its own "
        "first, then seeded perturbations) and cluster the optima; writes DIR/multistart.csv",
    )
    parser.add_argument(
        "--spread",
        type=float,
        default=0.3,
        help="relative standard deviation of the multistart perturbations (default 0.3)",
    )
    parser.add_argument(
        "--seed", type=int, default=0, help="seed of the multistart perturbations (default 0)"
    )
    parser.add_argument("--quiet", action="store_true", help="no progress messages on stderr")
    parser.set_defaults(func=run)


def _say(message: str) -> None:
    print(f"flightid: {message}", file=sys.stderr, flush=True)


def _multistart(args: argparse.Namespace) -> int:
    from pathlib import Path

    from flightid.batch import BatchError
    from flightid.batch.multistart import multistart, write_multistart_csv

    if len(args.cases) != 1:
        raise BatchError(f"--multistart: expected one case file, got {len(args.cases)}")
    out = Path(args.out).expanduser()
    if out.exists() and not out.is_dir():
        raise BatchError(f"--out {out}: is a file, expected a folder")
    result = multistart(
        args.cases[0],
        args.multistart,
        spread=args.spread,
        seed=args.seed,
        workers=args.workers,
        scheduler=args.scheduler,
        data_dir=args.data_dir,
        progress=None if args.quiet else _say,
    )
    out.mkdir(parents=True, exist_ok=True)
    path = write_multistart_csv(result, out / "multistart.csv")
    print(result.summary())
    print(f"  {path.resolve()}")
    return 0


def run(args: argparse.Namespace) -> int:
    from flightid.batch import run_batch

    if args.multistart is not None:
        return _multistart(args)
    result = run_batch(
        args.cases,
        args.out,
        workers=args.workers,
        scheduler=args.scheduler,
        data_dir=args.data_dir,
        accuracy=args.accuracy,
        retry_failed=args.retry_failed,
        plot_against=args.plot_against,
        progress=None if args.quiet else _say,
    )
    failed = result.failed
    print(
        f"{len(result.records)} case(s): {len(result.ran)} run, {len(result.skipped)} skipped "
        f"(up to date), {len(failed)} failed{': ' + ', '.join(failed) if failed else ''}"
    )
    for path in result.files:
        if path.name in ("estimates.csv", "estimates.parquet", "index.html"):
            print(f"  {path}")
    return 0
