"""The measured numbers of docs/unstable.md: every unstable-aircraft case file, and the solvers.

    python docs/unstable_numbers.py [--data-dir DIR] [--record] [--write] [--check]

Runs each ``examples/cases/unstab_sp_*.toml`` (output error and its stabilised variants,
filter error, multiple shooting, least squares) with ``flightid run CASE --json`` and prints
the comparison table of the guide (status, Gauss–Newton passes, simulations, wall time, ln
det R, each estimate ± its Cramér–Rao bound or, for least squares, its regression standard
error); then the stabilised, eigenvalue-transform and multiple-shooting cases again with the
solver swapped (MNR, MNRES, FPS); and multiple shooting with one defect weight against the
continuation of weights, for 2 to 25 intervals. About 4 minutes on one core. Wall times are
the whole process's (start-up and compilation from the cache included) and are not compared
by the tests.
"""

from __future__ import annotations

import case_numbers as cn

NAMES = ("Zw", "Zq", "Zδe", "Mw", "Mq", "Mδe")
STATE_SPACE = (
    ("3a", "plain OEM", "unstab_sp_output_error"),
    ("3b", "regression start-up", "unstab_sp_regression_startup"),
    ("3c", "equation decoupling", "unstab_sp_equation_decoupling"),
    ("3d", "stabilized OEM", "unstab_sp_stabilized_output_error"),
    ("3e", "eigenvalue transform σ = 0.7", "unstab_sp_eigenvalue_transform"),
    ("3f", "filter error", "unstab_sp_filter_error"),
    ("MS", "multiple shooting, 10 intervals", "unstab_sp_multiple_shooting"),
)
LEAST_SQUARES = (
    ("3g", "equation error, OLS", "unstab_sp_equation_error_ls"),
    ("3h", "equation error, TLS", "unstab_sp_equation_error_tls"),
)
SOLVERS = (
    ("3d stabilized", "unstab_sp_stabilized_output_error"),
    ("3e eigenvalue", "unstab_sp_eigenvalue_transform"),
    ("multiple shooting", "unstab_sp_multiple_shooting"),
)


def _final(output: dict) -> dict:
    """The last estimation of a run (a start-up case runs a regression stage first)."""
    return output["results"][-1]


COMPARISON_HEADING = ["case", "method", "status", "passes", "evaluations", "wall (s)"]
COMPARISON_HEADING += ["ln det R", *NAMES]


def least_squares_rows(data_dir: str | None) -> list[list[str]]:
    """The rows 3g and 3h of the comparison table (a few seconds: no integration)."""
    rows = []
    for label, method, case in LEAST_SQUARES:
        output = cn.run(case, data_dir)
        coefficients = output["stages"][-1]["coefficients"]
        items = {p["name"]: p for c in coefficients.values() for p in c["parameters"]}
        row = [label, method, "solved", "—", "—", f"{output['wall_s']:.1f}", "—"]
        row += [cn.estimate(items[name]) for name in NAMES]
        rows.append(row)
    return rows


def comparison(data_dir: str | None) -> str:
    rows = []
    for label, method, case in STATE_SPACE:
        output = cn.run(case, data_dir)
        entry = _final(output)
        row = [label, method, entry["status"], str(entry["iterations"])]
        row += [str(entry["equivalent_evaluations"]), f"{output['wall_s']:.1f}"]
        row += [f"{cn.ln_det_r(entry):.1f}".replace("-", "−")]
        row += [cn.estimate(cn.parameter(entry, name)) for name in NAMES]
        rows.append(row)
    rows += least_squares_rows(data_dir)
    return cn.table(COMPARISON_HEADING, rows)


def solvers(data_dir: str | None) -> str:
    heading = ["case", "solver", "status", "passes", "evaluations", "ln det R"]
    free = [name for name in NAMES if name != "Zq"]
    rows = []
    for label, case in SOLVERS:
        for solver in ("mnr", "mnres", "fps"):
            replace = {'solver = "mnr"': f'solver = "{solver}"'} if solver != "mnr" else None
            entry = _final(cn.run(case, data_dir, replace))
            row = [label, solver.upper(), entry["status"], str(entry["iterations"])]
            row += [str(entry["equivalent_evaluations"]), cn.significant(cn.ln_det_r(entry), 4)]
            row += [cn.significant(cn.parameter(entry, name)["value"], 5) for name in free]
            rows.append(row)
    return cn.table(heading + free, rows)


def continuation(data_dir: str | None) -> str:
    """ln det R of multiple shooting with one defect weight against the continuation, for
    2–25 intervals; "(local)" marks a result far above the output-error optimum (ln det R
    above −20 where the optimum is −44.7)."""
    weights = ("[1e2]", "[1e4]", "[1e6]", "[1, 1e3, 1e6]")
    rows = []
    for intervals in (2, 5, 10, 25):
        row = [str(intervals)]
        for weight in weights:
            if intervals == 25 and weight == weights[-1]:
                row.append("—")
                continue
            replace = {
                "shooting_intervals = 10": f"shooting_intervals = {intervals}",
                "shooting_weight = [1, 1e3, 1e6]": f"shooting_weight = {weight}",
            }
            entry = _final(cn.run("unstab_sp_multiple_shooting", data_dir, replace))
            ln_det = cn.ln_det_r(entry)
            cell = cn.significant(ln_det, 4) + (" (local)" if ln_det > -20 else "")
            if weight == weights[-1]:
                cell += f" ({entry['equivalent_evaluations']} evaluations)"
            row.append(cell)
        rows.append(row)
    heading = ["intervals", "w = 10² only", "10⁴ only", "10⁶ only", "continuation 1, 10³, 10⁶"]
    return cn.table(heading, rows)


def build(data_dir: str | None) -> list[str]:
    return [
        cn.region("unstable-continuation", continuation(data_dir)),
        cn.region("unstable-comparison", comparison(data_dir)),
        cn.region("unstable-solvers", solvers(data_dir)),
    ]


if __name__ == "__main__":
    raise SystemExit(cn.main("unstable.md", "unstable_numbers", build))
