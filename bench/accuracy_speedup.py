"""Speed-up of the parallel accuracy methods on 2 workers against 1.

In one run, on the ATTAS short-period case (``examples/cases/attas_short_period.toml``,
8 free parameters, 1252 samples × 2 outputs):

* profile-likelihood limits (``flightid.accuracy.profile_limits``): one task per parameter;
* random search (``flightid.accuracy.search.random_search``, ``--budget`` evaluations,
  seed 0): global chunks of 256 simulations, then one refinement task per extreme;

and a small Monte Carlo coverage study (``bench/coverage_study.py``, ``--coverage-case``,
default ``ex3``: RP-1153 example 3, ≈ 6 s per realisation; ``--n`` realisations, seeds
1000…): one task per realisation (the small cases ``ex2``/``exp`` take ≈ 0.02–0.1 s per
realisation, less than a Dask round trip) —

each timed on the serial engine (1 worker, this process) and on a Dask ``LocalCluster`` of
2 worker processes (``flightid.batch.DaskEngine(2)``). Both are warm before timing: the
kernels are compiled/loaded in this process and in every worker by a first untimed pass of
each computation. The two engines alternate run by run (serial, 2 workers, serial, …) so
that both see the same load. Wall times are the smallest of ``--repeat`` runs (s; the coverage
study: ``--repeat`` − 1 runs); ratio = 1 worker / 2 workers. The results of 1 and 2 workers
are compared exactly (limits, statuses, evaluation counts, coverage rows);
``identical`` says whether they are bit-for-bit equal.

Usage::

    python bench/accuracy_speedup.py [--budget 20000] [--n 4] [--coverage-case ex3] [--repeat 3]

The machine's load (``os.getloadavg``) is printed before and after: on a shared machine the
ratio is a measurement of that moment, not of the method. So are numba's thread counts: the
serial engine runs the parallel batch kernels on all cores, each LocalCluster worker on
``cores // workers`` (``worker_environment``); on a loaded machine numba's thread pool can be
many times slower than one thread, so run it also with ``NUMBA_NUM_THREADS=1`` (both sides
then use one thread per process) to see the engine's own speed-up.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "bench"))

CASE = ROOT / "examples" / "cases" / "attas_short_period.toml"


def _load() -> str:
    one, five, fifteen = os.getloadavg()
    return f"load average {one:.2f}, {five:.2f}, {fifteen:.2f} on {os.cpu_count()} cores"


def _contour():
    """Contour and covariance of the case's estimate (as ``assess`` builds them)."""
    from flightid.accuracy import assess, region_contour
    from flightid.cases.run import run_case

    run = run_case(CASE, accuracy="none")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        accuracy = assess(run.estimate, run.maneuvers, methods="cr", warn=False)
    return region_contour(run.estimate, run.maneuvers, accuracy), accuracy.covariance


def _profile_key(limits) -> tuple:
    return (limits.intervals.tobytes(), limits.statuses, limits.evaluations.tobytes())


def _search_key(limits) -> tuple:
    return (
        limits.intervals.tobytes(),
        limits.extreme_points.tobytes(),
        limits.evaluations,
        limits.inside,
        limits.settled.tobytes(),
    )


def _jobs(engine, contour, covariance, budget: int, n: int, coverage_case: str) -> dict:
    """name → (run on ``engine``, key of the result for the comparison, tasks)."""
    import coverage_study
    from flightid.accuracy.profile import profile_limits
    from flightid.accuracy.search import random_search

    return {
        "profile limits": (
            lambda: profile_limits(contour, covariance, engine=engine),
            _profile_key,
            contour.n_free,
        ),
        f"random search ({budget} evaluations)": (
            lambda: random_search(contour, covariance, budget=budget, seed=0, engine=engine),
            _search_key,
            None,
        ),
        f"coverage study ({coverage_case}, {n} realisations)": (
            lambda: coverage_study.study([coverage_case], n, 1000, engine, quiet=True),
            lambda report: json.dumps(report, sort_keys=True),
            n,
        ),
    }


def warm(engine, contour, covariance, budget: int, coverage_case: str) -> None:
    """One untimed pass of each computation: kernels compiled/loaded here and on every
    worker, the workers' imports done."""
    import coverage_study
    from flightid.accuracy.profile import profile_limits
    from flightid.accuracy.search import random_search

    profile_limits(contour, covariance, engine=engine)
    random_search(contour, covariance, budget=min(budget, 3000), seed=1, engine=engine)
    workers = getattr(engine, "workers", 1)
    coverage_study.study([coverage_case], workers, 1, engine, quiet=True)


def measure(engines: dict, budget: int, n: int, repeat: int, coverage_case: str) -> dict:
    """Time each computation on each engine, the engines alternating run by run (so that both
    see the same load); the best of ``repeat`` runs (the coverage study: ``max(1, repeat − 1)``)."""
    contour, covariance = _contour()
    for engine in engines.values():
        warm(engine, contour, covariance, budget, coverage_case)
    jobs = {
        label: _jobs(engine, contour, covariance, budget, n, coverage_case)
        for label, engine in engines.items()
    }
    out: dict = {label: {} for label in engines}
    first = next(iter(jobs.values()))
    for name in first:
        runs = max(1, repeat - 1) if name.startswith("coverage") else repeat
        for _ in range(runs):
            for label in engines:
                fn, key, tasks = jobs[label][name]
                started = time.perf_counter()
                result = fn()
                seconds = time.perf_counter() - started
                best = out[label].get(name, (np.inf,))[0]
                out[label][name] = (min(best, seconds), key(result), tasks, result)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--budget", type=int, default=20_000, help="random-search budget")
    parser.add_argument("--n", type=int, default=4, help="coverage-study realisations")
    parser.add_argument(
        "--coverage-case", default="ex3", help="coverage-study case (bench/coverage_study.py)"
    )
    parser.add_argument("--repeat", type=int, default=3, help="timed runs, the best kept")
    args = parser.parse_args(argv)

    import cloudpickle

    import coverage_study
    from flightid.batch.engine import DaskEngine
    from flightid.parallel import SerialEngine

    # the study's task function travels by value (the workers need not import bench/)
    cloudpickle.register_pickle_by_value(coverage_study)
    from flightid.batch.engine import worker_environment

    threads = os.environ.get("NUMBA_NUM_THREADS", f"unset (numba: {os.cpu_count()})")
    workers_threads = worker_environment(2).get("NUMBA_NUM_THREADS", threads)
    print(
        f"numba threads: this process (1 worker) {threads}; each of the 2 Dask workers "
        f"{workers_threads}"
    )
    print(f"before: {_load()}", flush=True)
    engine = DaskEngine(workers=2)
    try:
        print(f"engine: {engine.description}", flush=True)
        times = measure(
            {"serial": SerialEngine(), "dask": engine},
            args.budget,
            args.n,
            args.repeat,
            args.coverage_case,
        )
    finally:
        engine.close()
    serial, parallel = times["serial"], times["dask"]
    print(f"after: {_load()}\n")
    header = f"{'computation':40s} {'tasks':>6s} {'1 worker':>9s} {'2 workers':>10s} {'ratio':>6s}"
    print(header + "  identical")
    for name, (t1, key1, tasks, result) in serial.items():
        t2, key2, _, _ = parallel[name]
        if tasks is None:  # the search: chunks + refinement tasks of the first wave
            from flightid.accuracy.search import CHUNK

            n_global = int(0.1 * args.budget)
            tasks = -(-n_global // CHUNK) + 2 * result.settled.shape[0]
        print(
            f"{name:40s} {tasks:6d} {t1:8.2f}s {t2:9.2f}s {t1 / t2:6.2f}  "
            f"{'yes' if key1 == key2 else 'NO'}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
