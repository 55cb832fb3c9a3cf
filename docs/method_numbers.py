"""The measured numbers of docs/method.md: the paper's examples 1 and 2 with FPS, MNR, MNRES.

    python docs/method_numbers.py [--record] [--write] [--check]

Runs ``flightid paper example1 --json`` and ``flightid paper example2 --case 1|2 --json``
(noise seed 1) and prints the table of the guide: equivalent evaluations, the largest error
of the estimates (example 1: |θ̂ − θ_true|), final cost and status, with the paper's counts
(tables II and III of RP-1153) in brackets. A few seconds.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import case_numbers as cn

PAPER_EXAMPLE1 = {"fps": 715, "mnr": 28, "mnres": 12}
PAPER_EXAMPLE2 = {1: {"mnr": "42", "mnres": "12"}, 2: {"mnr": "70", "mnres": "27, not converged"}}


def paper(*arguments: str) -> dict:
    environment = dict(os.environ, PYTHONPATH=str(cn.ROOT / "src"))
    command = [sys.executable, "-m", "flightid.cli.main", "paper", *arguments, "--json"]
    done = subprocess.run(command, capture_output=True, text=True, env=environment, check=True)
    return {entry["method"]: entry for entry in json.loads(done.stdout)["results"]}


def table() -> str:
    from flightid.paper.linear_system import TRUE_VALUES

    one = paper("example1")
    rows = [["1: equivalent evaluations"], ["1: max error of the estimates"]]
    for method in ("fps", "mnr", "mnres"):
        entry = one[method]
        rows[0].append(f"{entry['equivalent_evaluations']} [{PAPER_EXAMPLE1[method]}]")
        # max_j |θ̂_j − θ_true,j|
        error = max(
            abs(p["value"] - true) for p, true in zip(entry["parameters"], TRUE_VALUES, strict=True)
        )
        rows[1].append(f"{error:.2g}")
    for case, what in ((1, "cost"), (2, "status")):
        two = paper("example2", "--case", str(case))
        row = [f"2, case {case}: evaluations, {what}", "—"]
        for method in ("mnr", "mnres"):
            entry = two[method]
            last = f"{entry['cost']:.4g}" if what == "cost" else entry["status"]
            row.append(
                f"{entry['equivalent_evaluations']}, {last} [{PAPER_EXAMPLE2[case][method]}]"
            )
        rows.append(row)
    return cn.table(["example", "FPS", "MNR", "MNRES"], rows)


def build(data_dir: str | None) -> list[str]:
    return [cn.region("method-paper-examples", table())]


if __name__ == "__main__":
    raise SystemExit(cn.main("method.md", "method_numbers", build))
