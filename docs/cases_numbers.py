"""The measured numbers of docs/cases.md outside its standard-case tables (those are printed
by docs/standard_cases.py): the CSV walk-through, the aerodynamic regression cases and the
yaw-rate delay case.

    python docs/cases_numbers.py [--data-dir DIR] [--record] [--write] [--check]

Runs ``examples/csv_walkthrough/my_case.toml`` (against the truth ``make_flight.py``
simulates), ``attas_aero_regression_linear``, ``attas_aero_regression_polar``,
``attas_qst_kirchhoff`` and ``attas_lateral_yaw_delay`` with ``flightid run CASE --json``.
About 1 minute on one core. Wall times are not compared by the tests.
"""

from __future__ import annotations

import importlib.util

import case_numbers as cn

WALKTHROUGH = cn.ROOT / "examples" / "csv_walkthrough"
LABELS = {"Za": "Zα", "Zq": "Zq", "Zde": "Zδe", "Ma": "Mα", "Mq": "Mq", "Mde": "Mδe"}
REGRESSION = (
    ("attas_aero_regression_linear", "TC23"),
    ("attas_aero_regression_polar", "TC24"),
    ("attas_qst_kirchhoff", "TC27"),
)


def _truth() -> dict:
    spec = importlib.util.spec_from_file_location("make_flight", WALKTHROUGH / "make_flight.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return dict(module.TRUE)


def walkthrough(data_dir: str | None) -> str:
    entry = cn.run(WALKTHROUGH / "my_case.toml")["results"][-1]
    truth = _truth()
    rows = []
    for name, label in LABELS.items():
        item = cn.parameter(entry, name)
        # (θ̂ − θ_true) / σ_CR
        z = (item["value"] - truth[name]) / item["std_cr"]
        rows.append(
            [
                label,
                cn.significant(truth[name], 3),
                cn.significant(item["value"], 6),
                cn.significant(item["std_cr"], 3),
                f"{z:+.1f}".replace("-", "−"),
            ]
        )
    line = f"{entry['status']}, {entry['iterations']} passes, J = {entry['cost']:.4g}:"
    table = cn.table(["parameter", "truth", "estimate", "CR bound", "(estimate − truth)/CR"], rows)
    return f"{line}\n\n{table}"


def regression(data_dir: str | None) -> str:
    rows, lists = [], []
    for case, label in REGRESSION:
        output = cn.run(case, data_dir)
        entry = output["results"][-1]
        free = [p for p in entry["parameters"] if p["free"]]
        samples = sum(m.get("samples", 0) for m in entry.get("maneuvers", []))
        what = f"{label}, {len(free)} parameters, {len(entry['maneuvers'])} maneuvers"
        what += f", N = {samples}" if samples else ""
        rows.append(
            [
                f"`{case}` ({what})",
                entry["status"],
                str(entry["iterations"]),
                str(entry["equivalent_evaluations"]),
                f"{output['wall_s']:.1f}",
            ]
        )
        estimates = ", ".join(
            f"{p['name']} {cn.significant(p['value'], 5)} ± {cn.significant(p['std_cr'], 3)}"
            for p in free
        )
        lists.append(f"`{case}` (estimate ± CR bound): {estimates}.")
    table = cn.table(["case", "status", "passes", "evaluations", "wall (s)"], rows)
    return table + "\n\n" + "\n\n".join(lists)


def yaw_delay(data_dir: str | None) -> str:
    entry = cn.run("attas_lateral_yaw_delay", data_dir)["results"][-1]
    delay, lp = cn.parameter(entry, "tDelay_r"), cn.parameter(entry, "Lp")
    return (
        f"{entry['status']}, {entry['iterations']} passes, "
        f"{entry['equivalent_evaluations']} simulations; "
        f"tDelay_r = {cn.estimate(delay, digits=3)} s, L_p = {cn.estimate(lp)}"
    )


def build(data_dir: str | None) -> list[str]:
    return [
        cn.region("cases-csv-walkthrough", walkthrough(data_dir)),
        cn.region("cases-aero-regression", regression(data_dir)),
        cn.region("cases-yaw-delay", yaw_delay(data_dir)),
    ]


if __name__ == "__main__":
    raise SystemExit(cn.main("cases.md", "cases_numbers", build))
