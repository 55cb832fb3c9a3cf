"""Monte Carlo coverage of 95 % confidence intervals.

For each case, ``--n`` noise realisations (seeds ``--seed`` … ``--seed + n − 1``) are drawn,
each is estimated from the case's start values (output-error ML, R estimated, program MAX),
and for every free parameter we record whether the true value lies inside the individual
95 % interval of each method:

* ``cr``         θ̂ ± t·s·σ_j (Cramér–Rao, [5.24–5.27] at the individual level);
* ``cr_beale``   the same ellipsoid at Beale's corrected level [5.28];
* ``cr_col``     Cramér–Rao corrected for coloured residuals (automatic lag);
* ``profile``    profile-likelihood limits (the likelihood-ratio region, traced by Gauss–Newton).

Cases: ``ex2`` (RP-1153 example 2 case 2: linear system, σ = 10⁻³, 3 s); ``ex2x30`` (the same
with 30× the noise, σ = 0.03, to make the problem nonlinear); ``exp`` (y = a e^(−bt) + c,
σ = 0.1, 4 s at 0.1 s: nonlinear in b); ``expx3`` (the same with σ = 0.3); ``ex3`` (RP-1153
example 3 case 2, the nonlinear lateral airplane; profile limits only for CY_beta, Cl_beta
and the two nonlinear derivatives, as each of its 19 profiles costs ≈ 120 simulations).

Usage::

    python bench/coverage_study.py [--n 200] [--case ex2 ex2x30 exp ex3]
                                   [--workers 2 | --scheduler tcp://host:8786]

The realisations are tasks on the batch engine (``flightid.batch.make_engine``: serial for
``--workers 1``, else a Dask LocalCluster or the scheduler given); realisation i has the noise
seed ``--seed + i`` whichever worker runs it, and the rows are gathered in realisation order,
so the tables are the same for any number of workers.

Prints one table per case (coverage per method: mean over parameters, and the smallest and
largest per-parameter coverage) and the N_φ distribution; ``--json FILE`` keeps the raw counts.
The binomial standard error of a coverage near 0.95 over 200 realisations is ≈ 0.015.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "tests"))

METHODS = ("cr", "cr_beale", "cr_col", "profile")
EX3_PROFILE = ("CY_beta", "Cl_beta", "Cl_alpha_phat", "Cn_alpha_rhat")


def _ex2_case(sigma: float):
    from flightid.data import FlightData
    from flightid.paper.examples12 import example2_data, example_model
    from flightid.paper.linear_system import NAMES, TRUE_VALUES

    def make(seed: int):
        data = example2_data(2, seed)
        if sigma != 1e-3:  # rescale the case-2 noise (same realisation pattern)
            from flightid.paper.linear_system import linear_model
            from flightid.simulation import simulate

            clean = simulate(linear_model(TRUE_VALUES), data, method="euler")
            z = clean + (data.outputs - clean) * (sigma / 1e-3)
            data = FlightData(data.time, {"u": data.input("u")}, {"x1": z[:, 0], "x2": z[:, 1]})
        return example_model(), data, "euler", dict(zip(NAMES, TRUE_VALUES, strict=True)), None

    return make


def _exp_case(sigma: float = 0.1):
    from test_accuracy_models import EXP_TRUE, exp_data, exp_model

    def make(seed: int):
        return (
            exp_model(),
            exp_data(sigma, seed),
            "rk4",
            dict(zip("abc", EXP_TRUE, strict=True)),
            None,
        )

    return make


def _ex3_case(profile_names):
    from flightid.paper.example3 import (
        SIMULATION_VALUES,
        example3_data,
        example3_model,
        example3_start_values,
    )

    def make(seed: int):
        model = example3_model(example3_start_values())
        truth = {n: float(SIMULATION_VALUES[n]) for n in model.parameters.names}
        return model, example3_data(2, seed), "rk4", truth, list(profile_names)

    return make


def _one(task: tuple[str, int]) -> dict:
    """One realisation (a task on the engine): estimate and assess, coverage per method."""
    case, seed = task
    for path in (str(ROOT / "src"), str(ROOT / "tests")):  # on a Dask worker too
        if path not in sys.path:
            sys.path.insert(0, path)
    from flightid.accuracy import assess
    from flightid.estimation import MNR, estimate

    make = CASES[case]()
    model, data, method, truth, subset = make(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = estimate(model, data, MNR(), method=method, noise="max")
        accuracy = assess(result, data, methods="profile", warn=False, parameters=subset)
    names = list(accuracy.names)
    true = np.array([truth[n] for n in names])
    tables = {
        "cr": accuracy.ci_cr,
        "cr_beale": accuracy.ci_cr_beale,
        "cr_col": accuracy.ci_cr_coloured,
        "profile": accuracy.ci_profile,
    }
    covered = {}
    for method_name, table in tables.items():
        inside = (table[:, 0] <= true) & (true <= table[:, 1])
        inside = np.where(np.isnan(table[:, 0]), np.nan, inside)
        covered[method_name] = inside.tolist()
    return {
        "seed": seed,
        "names": names,
        "covered": covered,
        "n_phi": accuracy.nonlinearity.n_phi,
        "converged": bool(result.converged),
        "evaluations": dict(accuracy.evaluations),
    }


CASES = {
    "ex2": lambda: _ex2_case(1e-3),
    "ex2x30": lambda: _ex2_case(3e-2),
    "exp": _exp_case,
    "expx3": lambda: _exp_case(0.3),
    "ex3": lambda: _ex3_case(EX3_PROFILE),
}


def _table(case: str, rows: list[dict]) -> str:
    names = rows[0]["names"]
    lines = [f"case {case}: {len(rows)} realisations, {len(names)} free parameters"]
    header = f"{'method':10s} {'mean':>6s} {'min':>6s} {'max':>6s}   per parameter"
    lines.append(header)
    for method in METHODS:
        matrix = np.array([r["covered"][method] for r in rows], dtype=float)
        per = np.nanmean(matrix, axis=0)
        done = ~np.isnan(per)
        if not done.any():
            continue
        detail = " ".join(f"{n}={p:.3f}" for n, p in zip(names, per, strict=True) if np.isfinite(p))
        lines.append(
            f"{method:10s} {np.mean(per[done]):6.3f} {np.min(per[done]):6.3f} "
            f"{np.max(per[done]):6.3f}   {detail}"
        )
    n_phi = np.array([r["n_phi"] for r in rows])
    lines.append(
        f"N_phi: median {np.median(n_phi):.3g}, 5–95 % [{np.quantile(n_phi, 0.05):.3g}, "
        f"{np.quantile(n_phi, 0.95):.3g}]; converged {sum(r['converged'] for r in rows)}/"
        f"{len(rows)}; profile evaluations per realisation (median) "
        f"{int(np.median([r['evaluations'].get('profile', 0) for r in rows]))}"
    )
    return "\n".join(lines)


def make_figures(directory: Path) -> list[Path]:
    """The docs' figures: profile of c and the (b, c) slice for the exponential case (seed 3),
    and the profile of θ1 for example 2 case 2."""
    from flightid.accuracy import assess, cost_slice, profile_curve, region_contour
    from flightid.estimation import MNR, estimate
    from flightid.paper.examples12 import example2_data, example_model
    from flightid.report.accuracy_figures import plot_profile, plot_region_slice
    from test_accuracy_models import exp_estimate

    paths = []
    result, data = exp_estimate(sigma=0.1, seed=3)
    accuracy = assess(result, data, methods="profile", warn=False)
    contour = region_contour(result, data, accuracy)
    for j in (1, 2):
        lo, hi = accuracy.ci_profile[j]
        span = hi - lo
        grid = np.linspace(lo - 0.5 * span, hi + 0.5 * span, 41)
        curve = profile_curve(contour, accuracy.covariance, j, grid)
        name = accuracy.names[j]
        paths.append(plot_profile(curve, accuracy, directory / f"accuracy_profile_exp_{name}.png"))
    b_lo, b_hi = accuracy.ci_profile[1]
    c_lo, c_hi = accuracy.ci_profile[2]
    grid_b = np.linspace(b_lo - 0.6 * (b_hi - b_lo), b_hi + 0.6 * (b_hi - b_lo), 81)
    grid_c = np.linspace(c_lo - 0.6 * (c_hi - c_lo), c_hi + 0.6 * (c_hi - c_lo), 81)
    piece = cost_slice(contour, 1, 2, grid_b, grid_c)
    paths.append(plot_region_slice(piece, accuracy, directory / "accuracy_slice_exp_b_c.png"))

    data = example2_data(2, 1)
    result = estimate(example_model(), data, MNR(), method="euler", noise="max")
    accuracy = assess(result, data, methods="profile", warn=False)
    contour = region_contour(result, data, accuracy)
    lo, hi = accuracy.ci_profile[0]
    grid = np.linspace(lo - 0.5 * (hi - lo), hi + 0.5 * (hi - lo), 31)
    curve = profile_curve(contour, accuracy.covariance, 0, grid)
    paths.append(plot_profile(curve, accuracy, directory / "accuracy_profile_ex2_theta1.png"))
    return paths


def study(cases: list[str], n: int, seed: int, engine=None, quiet: bool = False) -> dict:
    """Coverage rows per case: realisations ``seed … seed + n − 1`` as tasks on ``engine``
    (None: in this process), rows in realisation order; prints the tables unless ``quiet``."""
    from flightid.parallel import map_ordered

    report = {}
    workers = getattr(engine, "workers", 1)
    for case in cases:
        started = time.perf_counter()
        tasks = [(case, seed + i) for i in range(n)]
        labels = [f"{case} realisation {seed + i}" for i in range(n)]
        rows = map_ordered(engine, _one, tasks, labels)
        if not quiet:
            print(_table(case, rows))
            print(f"({time.perf_counter() - started:.0f} s, {workers} worker(s))\n", flush=True)
        report[case] = rows
    return report


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, default=200, help="noise realisations per case")
    parser.add_argument(
        "--case", nargs="+", default=["ex2", "ex2x30", "exp", "expx3"], choices=CASES
    )
    parser.add_argument("--seed", type=int, default=1000, help="first noise seed")
    parser.add_argument("--workers", type=int, default=2, help="Dask worker processes (1: serial)")
    parser.add_argument("--scheduler", default=None, help="address of a running Dask scheduler")
    parser.add_argument("--json", type=Path, default=None, help="write raw results here")
    parser.add_argument(
        "--figures", type=Path, default=None, help="only draw the docs' figures into this folder"
    )
    args = parser.parse_args(argv)
    if args.figures is not None:
        for path in make_figures(args.figures):
            print(path)
        return 0
    from flightid.batch.engine import make_engine

    engine = make_engine(None if args.scheduler else args.workers, args.scheduler)
    try:
        report = study(args.case, args.n, args.seed, engine)
    finally:
        engine.close()
    if args.json is not None:
        args.json.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
