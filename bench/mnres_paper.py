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
* own stop — evaluations until the solver itself says "converged" (its own 10⁻³ tests, MNR's
  last forward differences included; before the confirmation): the paper's accounting;
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
from types import SimpleNamespace  # noqa: E402

import numpy as np  # noqa: E402

from flightid.estimation import MNR, MNRES, estimate  # noqa: E402
from flightid.estimation.gauss_newton import information_matrix  # noqa: E402
from flightid.estimation.objective import Objective  # noqa: E402
from flightid.estimation.problem import OutputErrorProblem  # noqa: E402
from flightid.paper.examples12 import (  # noqa: E402
    EXAMPLE1_CONVERGENCE,
    EXAMPLE2_CONVERGENCE,
    PAPER_TABLE_II,
    PAPER_TABLE_III,
    example1_data,
    example2_data,
    example_model,
    run_example1,
    run_example2,
)

GUIDE = "docs/benchmarks.md"
# the examples: (label, runner, data, convergence, the paper's equivalent evaluations)
EXAMPLES = (
    (
        "example 1",
        lambda: run_example1(("mnr", "mnres")),
        example1_data,
        EXAMPLE1_CONVERGENCE,
        {m: PAPER_TABLE_II[m]["equivalent_evaluations"] for m in ("mnr", "mnres")},
    ),
    (
        "example 2 case 1",
        lambda: run_example2(1, ("mnr", "mnres")),
        lambda: example2_data(1),
        EXAMPLE2_CONVERGENCE,
        {m: PAPER_TABLE_III[1][m]["equivalent_evaluations"] for m in ("mnr", "mnres")},
    ),
)


def _own_stop(solver, data, convergence) -> int:
    """Evaluations until the solver itself says "converged" (its own tests, before the
    driver's confirmation): the paper's accounting."""
    problem = OutputErrorProblem(example_model(), data, method="euler")
    objective = Objective(problem, np.ones(problem.n_outputs), "fixed", convergence)
    solver.minimize(objective, problem.theta_start)
    return problem.evaluations


def _row(label: str, result, own_stop: int, paper: int, mnr_to_optimum: int) -> str:
    ratio = result.evaluations_to_optimum / mnr_to_optimum
    return (
        f"| {label} | {result.solver.upper()} | {result.evaluations_to_optimum} | "
        f"{result.confirmation_evaluations} | {result.accuracy_evaluations} | "
        f"{result.total_evaluations} | {ratio:.2f} | {own_stop} | {paper} |"
    )


def _forward_bounds(result, data, convergence) -> tuple[float, float, bool]:
    """(largest |σ_forward / σ_central − 1|, √(ΔθᵀMΔθ) of the Gauss–Newton step on the
    forward differences, whether that step passes the confirmation's test) at the estimate
    θ̂: what forward-difference bounds would change."""
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
    # the confirmation's test (noise-free data: the predicted drop cᵀΔθ against cost_atol)
    gauss_newton = SimpleNamespace(step=step, predicted_reduction=float(gradient @ step))
    confirmed = convergence.confirmed(distance, gauss_newton, problem.magnitude(theta))
    return float(np.max(np.abs(sigma_forward / sigma_central - 1.0))), distance, confirmed


# MNRES variants that reach the optimum by other algebra: the paper's surface through n + 1
# points, with the paper's own rules (highest-cost point leaves, full step every pass)
VARIANTS = (
    ("secant (default)", MNRES()),
    ("algebraic surface", MNRES(form="algebraic")),
    (
        "algebraic, the paper's rules",
        MNRES(form="algebraic", replacement="cost", trust_region=False),
    ),
)


def _variants_table() -> list[str]:
    """Evaluations to the optimum of each MNRES variant on both examples."""
    lines = [
        "| MNRES variant | example 1 | example 2 case 1 |",
        "|---|---:|---:|",
    ]
    for label, solver in VARIANTS:
        counts = []
        for _, _, data, convergence, _ in EXAMPLES:
            result = estimate(
                example_model(),
                data(),
                solver,
                method="euler",
                noise="fixed",
                convergence=convergence,
            )
            counts.append(str(result.evaluations_to_optimum))
        lines.append(f"| {label} | " + " | ".join(counts) + " |")
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the same run (it is quick)")
    parser.parse_args()
    print(f"<!-- guide: {GUIDE} -->")
    print("<!-- numbers: mnres-paper -->")
    print(
        "| problem | method | to optimum | confirming | bounds | total | to optimum ÷ MNR | "
        "own stop | paper |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    verdicts, study = [], []
    for label, runner, data, convergence, paper in EXAMPLES:
        by_method = {r.solver: r for r in runner().results}
        mnr, mnres = by_method["mnr"], by_method["mnres"]
        own = {}
        for result, solver in ((mnr, MNR()), (mnres, MNRES())):
            own[result.solver] = _own_stop(solver, data(), convergence)
            print(
                _row(
                    label,
                    result,
                    own[result.solver],
                    paper[result.solver],
                    mnr.evaluations_to_optimum,
                )
            )
        ratio = mnres.evaluations_to_optimum / mnr.evaluations_to_optimum
        verdicts.append(
            f"{'PASS' if ratio <= 0.5 else 'FAIL'}: {label}: MNRES to the optimum ≤ 0.5 × "
            f"MNR's: {mnres.evaluations_to_optimum} / {mnr.evaluations_to_optimum} = "
            f"{ratio:.2f} (each solver's own stop, the paper's accounting: {own['mnres']} / "
            f"{own['mnr']} = {own['mnres'] / own['mnr']:.2f}; the paper {paper['mnres']} / "
            f"{paper['mnr']} = {paper['mnres'] / paper['mnr']:.2f})"
        )
        n_free = int(np.count_nonzero(mnres.free))
        for result in (mnr, mnres):
            after = result.confirmation_evaluations + result.accuracy_evaluations
            # the end point's own simulation is reused: its differences cost at most 2n
            reused = result.accuracy_evaluations <= 2 * n_free
            verdicts.append(
                f"{'PASS' if after <= 2 * n_free + 1 and reused else 'FAIL'}: {label}: "
                f"{result.solver.upper()} confirmation and bounds ≤ 2n + 1 = {2 * n_free + 1} "
                f"and the end point reused (bounds ≤ 2n): {after} "
                f"({result.confirmation_evaluations} + {result.accuracy_evaluations})"
            )
            spread, distance, confirmed = _forward_bounds(result, data(), convergence)
            study.append(
                f"| {label} | {result.solver.upper()} | {spread:.1e} | {distance:.1e} | "
                f"{'yes' if confirmed else 'no'} |"
            )
    print()
    for line in verdicts:
        print(line)
    print()
    print("Forward differences at θ̂ (relative step 1e-6) instead of central ones:")
    print()
    print("| problem | method | largest σ change | their step, σ | confirmed on them |")
    print("|---|---|---:|---:|---|")
    for line in study:
        print(line)
    print()
    print("Evaluations to the optimum of other MNRES forms:")
    print()
    for line in _variants_table():
        print(line)
    print("<!-- /numbers -->")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
