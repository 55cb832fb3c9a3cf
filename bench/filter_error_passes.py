"""Filter passes of the filter error method: the book's schedule against the fixed point.

For each reference case (y13aus lateral in turbulence, HFB-320 longitudinal) the same case
file is estimated three ways in one process:

* the book's schedule (``relaxation="reference"``: one forward-difference Gauss–Newton step
  per R update with the F compensation, FVSysID's ``ml_fem2``);
* the fixed point with full cycles (``cycles="full"``: θ converged and confirmed under
  every R; the schedule before warm cycles);
* the fixed point with warm cycles (``cycles="warm"``, the default: one step per R update,
  the end point confirmed once).

Counted: filter passes of the whole run, the bounds' sensitivities included (a
forward-difference gradient of n free parameters costs n passes). Likelihood: with R the
innovations' covariance R̂, −ln L = (N/2)·ln det R̂ + const, so Δ(−ln L) against the book
is (N/2)·(ln det R̂ − ln det R̂_book), N the samples. Target per case: passes ≤ 1.5× the
book's at the same or a better likelihood (Δ(−ln L) ≤ 0.5, half a log-likelihood unit —
the book's schedule ends slightly outside diag(KC) ≤ 1, which the fixed point does not).

    PYTHONPATH=src python bench/filter_error_passes.py [--quick] [--data-dir DIR]

``--quick`` leaves out the full-cycle runs (the slow ones). Cases whose data are absent are
skipped with a message.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CASES = ("y13aus_lateral_filter_error", "hfb320_longitudinal_filter_error")
TARGET_RATIO = 1.5
LIKELIHOOD_SLACK = 0.5  # −ln L units


def _run(prepared, case, **options):
    from flightid.cases.run import build_convergence, build_solver, input_interpolation
    from flightid.estimation.filter_error import estimate_filter_error

    started = time.perf_counter()
    estimate = estimate_filter_error(
        prepared.model,
        list(prepared.maneuvers),
        prepared.process_noise,
        solver=build_solver(case),
        method=case.estimation.get("method", "rk4"),
        input_interpolation=input_interpolation(case),
        convergence=build_convergence(case),
        **options,
    )
    wall = time.perf_counter() - started
    passes = estimate.equivalent_evaluations + estimate.accuracy_evaluations
    log_det = float(np.sum(np.log(np.mean(estimate.residuals**2, axis=0))))
    return estimate, passes, log_det, wall


def measure(name: str, data_dir: Path, quick: bool) -> list[str]:
    """Table rows of one case and its PASS/FAIL line."""
    from flightid.cases import load_case
    from flightid.cases.run import prepare_case

    case = load_case(ROOT / "examples" / "cases" / f"{name}.toml")
    prepared = prepare_case(case, data_dir)
    runs = [("book schedule", {"relaxation": "reference"})]
    if not quick:
        runs.append(("fixed point, full cycles", {"cycles": "full"}))
    runs.append(("fixed point, warm cycles (default)", {"cycles": "warm"}))
    results = {label: _run(prepared, case, **options) for label, options in runs}
    book = results["book schedule"]
    n_samples = book[0].residuals.shape[0]
    rows = []
    for label, (estimate, passes, log_det, wall) in results.items():
        delta = 0.5 * n_samples * (log_det - book[2])
        rows.append(
            f"| {name} | {label} | {estimate.status} | {passes} | {passes / book[1]:.2f} | "
            f"{log_det:.5f} | {delta:+.2f} | {wall:.2f} |"
        )
    _, passes, log_det, _ = results["fixed point, warm cycles (default)"]
    delta = 0.5 * n_samples * (log_det - book[2])
    ok = passes <= TARGET_RATIO * book[1] and delta <= LIKELIHOOD_SLACK
    verdict = (
        f"{'PASS' if ok else 'FAIL'} {name}: warm cycles {passes} passes = "
        f"{passes / book[1]:.2f}× the book's {book[1]} (target ≤ {TARGET_RATIO}×), "
        f"Δ(−ln L) = {delta:+.2f} (target ≤ {LIKELIHOOD_SLACK})"
    )
    return rows, verdict


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="leave out the full-cycle runs")
    parser.add_argument("--data-dir", type=Path, default=ROOT.parent / "shared" / "data")
    args = parser.parse_args(argv)
    if not args.data_dir.is_dir():
        print(f"skipped: the reference data ({args.data_dir}) are absent")
        return 0
    print("<!-- guide: docs/benchmarks.md -->")
    print("<!-- numbers: filter-error-passes -->")
    print(
        "| case | schedule | status | filter passes | ÷ book | ln det R̂ | Δ(−ln L) vs book "
        "| wall (s) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    verdicts = []
    for name in CASES:
        rows, verdict = measure(name, args.data_dir, args.quick)
        print("\n".join(rows))
        verdicts.append(verdict)
    print("<!-- /numbers -->")
    print("\n".join(verdicts))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
