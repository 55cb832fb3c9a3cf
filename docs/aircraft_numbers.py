"""The measured numbers of docs/aircraft.md: the built-in HFB-320 model against the
hand-written module of the standard case.

    python docs/aircraft_numbers.py [--data-dir DIR] [--record] [--write] [--check]

Runs ``hfb320_longitudinal_builtin`` and ``hfb320_longitudinal`` with ``flightid run CASE
--json`` and prints each run's status, iterations, simulations and cost, and both estimates
± Cramér–Rao bound with their difference in bounds; then RP-1153 example 3 (``flightid paper
example3 --case 1|2|3 --json``, seed 3, case 3 also at seeds 11 and 12). About 40 seconds
on one core.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import case_numbers as cn

CASES = (("built-in", "hfb320_longitudinal_builtin"), ("module", "hfb320_longitudinal"))


def comparison(data_dir: str | None) -> str:
    entries = {label: cn.run(case, data_dir)["results"][-1] for label, case in CASES}
    lines = [
        f"{label}: {e['status']} in {e['iterations']} iterations, "
        f"{e['equivalent_evaluations']} simulations, cost {e['cost']:.6g}"
        for label, e in entries.items()
    ]
    builtin, module = entries["built-in"], entries["module"]
    rows = []
    for item in builtin["parameters"]:
        if not item["free"]:
            continue
        other = cn.parameter(module, item["name"])
        # (θ_built-in − θ_module) / σ_module, σ the Cramér–Rao bound
        difference = (item["value"] - other["value"]) / other["std_cr"]
        rows.append(
            [
                item["name"],
                f"{cn.significant(item['value'], 6)} ± {cn.significant(item['std_cr'], 3)}",
                f"{cn.significant(other['value'], 6)} ± {cn.significant(other['std_cr'], 3)}",
                f"{difference:+.4f}".replace("-", "−"),
            ]
        )
    table = cn.table(["parameter", "built-in", "module", "difference / σ"], rows)
    return "\n".join(f"* {line}" for line in lines) + "\n\n" + table


def example3(case: int, seed: int = 3) -> dict:
    """The result entry of ``flightid paper example3 --case CASE --seed SEED --json``."""
    environment = dict(os.environ, PYTHONPATH=str(cn.ROOT / "src"))
    command = [sys.executable, "-m", "flightid.cli.main", "paper", "example3"]
    command += ["--case", str(case), "--seed", str(seed), "--json"]
    done = subprocess.run(command, capture_output=True, text=True, env=environment, check=True)
    return json.loads(done.stdout)["results"][0]


SELECTED = (("Cl_alpha_phat", "C_lαp̂"), ("Cn_alpha_rhat", "C_nαr̂"), ("CY_phat", "C_Yp̂"),
            ("CY_da", "C_Yδa"))  # fmt: skip


def example3_table() -> str:
    """Cases 1–3 at seed 3 (and case 3 at seeds 11, 12): status, simulations, passes, how
    many estimates lie within 3 Cramér–Rao bounds of the simulation values; then selected
    estimates of cases 2 and 3."""
    rows, entries = [], {}
    policies = {1: "fixed (case-2 σ²)", 2: "MAX", 3: "MAX"}
    for case in (1, 2, 3):
        entry = entries[case] = example3(case)
        free = [p for p in entry["parameters"] if p["free"]]
        # |θ̂ − θ_true| ≤ 3 σ_CR
        inside = sum(abs(p["value"] - p["true"]) <= 3 * p["std_cr"] for p in free)
        note = f"{inside}/{len(free)}"
        if case == 1:
            # max_j |θ̂_j − θ_j| / |θ_j| over the non-zero simulation values
            error = max(abs(p["value"] - p["true"]) / abs(p["true"]) for p in free if p["true"])
            note += f", max rel. error {error:.2g}"
        if case == 3:
            others = [example3(3, seed)["equivalent_evaluations"] for seed in (11, 12)]
            note += f" (seeds 11, 12: {others[0]} and {others[1]} evaluations)"
        row = [str(case), policies[case], entry["status"]]
        row += [str(entry["equivalent_evaluations"]), str(entry["iterations"]), note]
        rows.append(row)
    heading = ["case", "R policy", "status", "equivalent evaluations", "iterations"]
    table = cn.table([*heading, "within 3 CR bounds"], rows)
    picks = []
    for name, label in SELECTED:
        two, three = (cn.parameter(entries[c], name) for c in (2, 3))
        picks.append(
            f"{label} {cn.significant(two['true'], 3)} → {cn.significant(two['value'], 4)}, "
            f"{cn.significant(three['value'], 4)}"
        )
    selected = f"Selected estimates (truth → case 2, case 3): {'; '.join(picks)}."
    return f"{table}\n\n{selected}\n\n{wider_start(entries)}"


def wider_start(entries: dict) -> str:
    """Cases 2 and 3 from start values ±20 % (``run_example3(case, start_fraction=0.2)``):
    simulations, passes, and the largest distance from the ±10 % estimates in CR bounds."""
    from flightid.paper.example3 import run_example3

    parts, largest = [], 0.0
    for case in (2, 3):
        result = run_example3(case, start_fraction=0.2)["estimate"]
        near = {p["name"]: p for p in entries[case]["parameters"]}
        for name, value in zip(result.names, result.values, strict=True):
            # |θ̂(±20 %) − θ̂(±10 %)| / σ_CR(±10 %)
            largest = max(largest, abs(value - near[name]["value"]) / near[name]["std_cr"])
        parts.append(
            f"case {case} {result.status} in {result.equivalent_evaluations} evaluations and "
            f"{result.iterations} iterations"
        )
    return (
        f"From ±20 % start values: {'; '.join(parts)}; the estimates within "
        f"{largest:.2g} CR bounds of the ±10 % run's."
    )


def build(data_dir: str | None) -> list[str]:
    return [
        cn.region("aircraft-hfb320-builtin", comparison(data_dir)),
        cn.region("aircraft-example3", example3_table()),
    ]


if __name__ == "__main__":
    raise SystemExit(cn.main("aircraft.md", "aircraft_numbers", build))
