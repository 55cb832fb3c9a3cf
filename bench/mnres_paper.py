"""MNRES against MNR on RP-1153 examples 1 and 2 (case 1): evaluations to the optimum, on the
confirmation and on the bounds, beside the paper's tables II and III.

    python -P bench/mnres_paper.py            # the tables, the PASS/FAIL lines, the study
    python -P bench/mnres_paper.py --quick    # the same (it runs in about two seconds)

Every number is a count of equivalent evaluations (one simulation of the model over the
record; a forward-difference sensitivity of n parameters costs n), deterministic, from
``flightid.paper.examples12`` (Euler, R = I fixed, the paper's set-up). Columns:

* to optimum — ``Estimate.evaluations_to_optimum``: evaluations until the first point on
  the path whose cost excess over the final cost, (θ_k − θ̂)ᵀM(θ_k − θ̂) under the final R,
  is within the cost tolerance cost_rtol·J(θ̂) + cost_atol;
* confirming — ``Estimate.confirmation_evaluations``: the optimizer's evaluations after that
  point (the solver's own convergence check and the confirming passes);
* bounds — ``Estimate.accuracy_evaluations``: the central differences at θ̂ (the last
  confirmation test and the Cramér–Rao bounds);
* paper — the paper's equivalent evaluations for the method (each its solver's count to its
  own "converged"; the paper's MNR of example 2 used analytic sensitivities).

Targets, one PASS/FAIL line each: MNRES's evaluations to the optimum at most half of MNR's
(the paper's advantage: 12 : 28 and 12 : 42), and the evaluations after the optimum
(confirming + bounds) at most 2·n + 1, with the solver's own differences at the end point
reused when it stops where it took them. The study below the lines measures what forward
differences at θ̂ would change in the bounds (the one way to meet 2·n + 1 after a confirming
step without stale sensitivities).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402

import numpy as np  # noqa: E402

from flightid.estimation.gauss_newton import information_matrix  # noqa: E402
from flightid.estimation.problem import OutputErrorProblem  # noqa: E402
from flightid.paper.examples12 import (  # noqa: E402
    PAPER_TABLE_II,
    PAPER_TABLE_III,
    example1_data,
    example2_data,
    run_example1,
    run_example2,
)

GUIDE = "docs/benchmarks.md"
# the examples: (label, runner, data, the paper's equivalent evaluations by method)
EXAMPLES = (
    (
        "example 1",
        lambda: run_example1(("mnr", "mnres")),
        example1_data,
        {m: PAPER_TABLE_II[m]["equivalent_evaluations"] for m in ("mnr", "mnres")},
    ),
    (
        "example 2 case 1",
        lambda: run_example2(1, ("mnr", "mnres")),
        lambda: example2_data(1),
        {m: PAPER_TABLE_III[1][m]["equivalent_evaluations"] for m in ("mnr", "mnres")},
    ),
)


def _row(label: str, result, paper: int, mnr_to_optimum: int) -> str:
    ratio = result.evaluations_to_optimum / mnr_to_optimum
    return (
        f"| {label} | {result.solver.upper()} | {result.evaluations_to_optimum} | "
        f"{result.confirmation_evaluations} | {result.accuracy_evaluations} | "
        f"{result.total_evaluations} | {ratio:.2f} | {paper} |"
    )


def _forward_bounds(result, data) -> tuple[float, float]:
    """(largest |σ_forward / σ_central − 1|, √(ΔθᵀMΔθ) of the Gauss–Newton step on the
    forward differences) at the estimate θ̂: what forward-difference bounds would change."""
    problem = OutputErrorProblem(result.model, data, method=result.method)
    theta = problem.theta_start  # the estimated model's free values: θ̂
    outputs = problem.outputs(theta[None, :])[0]
    g, _ = problem.sensitivities(theta, outputs, relative_step=1e-6, central=False)
    m = information_matrix(g, result.r_diag)
    sigma_forward = np.sqrt(np.diag(np.linalg.inv(m)))
    sigma_central = np.asarray(result.std_cr)[np.asarray(result.free, dtype=bool)]
    # the Gauss–Newton step on the forward differences, in σ of the residuals' own R̂
    weights = 1.0 / result.r_diag
    nu = problem.residuals(outputs)
    gradient = np.einsum("ikj,ik,k->j", g, nu, weights)
    step = np.linalg.solve(m, gradient)
    r_hat = problem.noise_covariance(outputs)
    distance = float(np.sqrt(step @ information_matrix(g, r_hat) @ step))
    return float(np.max(np.abs(sigma_forward / sigma_central - 1.0))), distance


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the same run (it is quick)")
    parser.parse_args()
    print(f"<!-- guide: {GUIDE} -->")
    print("<!-- numbers: mnres-paper -->")
    print(
        "| problem | method | to optimum | confirming | bounds | total | to optimum ÷ MNR | paper |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    verdicts, study = [], []
    for label, runner, data, paper in EXAMPLES:
        by_method = {r.solver: r for r in runner().results}
        mnr, mnres = by_method["mnr"], by_method["mnres"]
        for result in (mnr, mnres):
            print(_row(label, result, paper[result.solver], mnr.evaluations_to_optimum))
        ratio = mnres.evaluations_to_optimum / mnr.evaluations_to_optimum
        verdicts.append(
            f"{'PASS' if ratio <= 0.5 else 'FAIL'}: {label}: MNRES to the optimum ≤ 0.5 × "
            f"MNR's: {mnres.evaluations_to_optimum} / {mnr.evaluations_to_optimum} = "
            f"{ratio:.2f} (paper {paper['mnres']} / {paper['mnr']} = "
            f"{paper['mnres'] / paper['mnr']:.2f})"
        )
        n_free = int(np.count_nonzero(mnres.free))
        for result in (mnr, mnres):
            after = result.confirmation_evaluations + result.accuracy_evaluations
            verdicts.append(
                f"{'PASS' if after <= 2 * n_free + 1 else 'FAIL'}: {label}: "
                f"{result.solver.upper()} confirmation and bounds ≤ 2n + 1 = {2 * n_free + 1}: "
                f"{after}"
            )
            spread, distance = _forward_bounds(result, data())
            study.append(f"| {label} | {result.solver.upper()} | {spread:.1e} | {distance:.1e} |")
    print()
    for line in verdicts:
        print(line)
    print()
    print("Forward differences at θ̂ (relative step 1e-6) instead of central ones:")
    print()
    print("| problem | method | largest σ change | their step, σ |")
    print("|---|---|---:|---:|")
    for line in study:
        print(line)
    print("<!-- /numbers -->")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
