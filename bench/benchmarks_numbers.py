"""The tables of docs/benchmarks.md that the optimizer and start-value benchmarks print.

    python -P bench/benchmarks_numbers.py [--data-dir DIR] [--record] [--write] [--check]

Runs ``bench/solvers.py --repeat 3`` and ``bench/start_robustness.py`` and prints their
tables in the regions docs/benchmarks.md quotes (the start-value study without its closing
wall-time line). About 2 minutes on two idle cores. The tests compare the counts, costs,
distances and verdicts with the page; the wall-time columns depend on the machine and are
not compared.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))

import case_numbers as cn  # noqa: E402  (docs/: the regions' shared command line)


def bench(script: str, *arguments: str, data_dir: str | None = None) -> str:
    """What ``python -P bench/SCRIPT ARGUMENTS`` prints."""
    environment = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    if data_dir:
        environment["FLIGHTID_DATA"] = data_dir
    done = subprocess.run(
        [sys.executable, "-P", str(ROOT / "bench" / script), *arguments],
        capture_output=True,
        text=True,
        env=environment,
        check=False,
    )
    if done.returncode != 0:
        raise SystemExit(f"bench/{script} failed: {done.stderr.strip()}")
    return done.stdout


def build(data_dir: str | None) -> list[str]:
    solvers = bench("solvers.py", "--repeat", "3", data_dir=data_dir)
    table = "\n".join(line for line in solvers.splitlines() if line.startswith("|"))
    robustness = bench("start_robustness.py", data_dir=data_dir)
    study = robustness[robustness.index("### Part 1") :]
    study = "\n".join(line for line in study.splitlines() if not line.startswith("total wall time"))
    return [
        cn.region("benchmarks-solvers", table),
        cn.region("benchmarks-start-robustness", study),
    ]


if __name__ == "__main__":
    raise SystemExit(cn.main("benchmarks.md", "benchmarks_numbers", build))
