"""The measured numbers of docs/design.md: predicted against realised σ of designed inputs,
and the peak factors of the multisines, as ``bench/design_montecarlo.py`` prints them.

    python docs/design_numbers.py [--record] [--write] [--check]

Runs ``bench/design_montecarlo.py --runs 300`` (seed 17: the ATTAS short period and RP-1153
example 3, each with the reference maneuver and two designs flown 300 times in simulation;
tens of minutes on one core) and prints each of its tables in the region the guide quotes
(its headings one level lower, the closing wall-time line left out). The tests compare the
page with the record of the last run; the peak factors and predicted σ are deterministic,
the realised σ are seeded. ``DESIGN_RUNS=N`` in the environment flies N runs instead of 300
(a quick look; the page quotes 300).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys

import case_numbers as cn


def montecarlo(runs: int) -> str:
    environment = dict(os.environ, PYTHONPATH=str(cn.ROOT / "src"))
    command = [sys.executable, str(cn.ROOT / "bench" / "design_montecarlo.py")]
    done = subprocess.run(
        [*command, "--runs", str(runs)], capture_output=True, text=True, env=environment
    )
    if done.returncode not in (0, 1):  # 1: a table outside its tolerance, still printed
        raise SystemExit(f"bench/design_montecarlo.py failed: {done.stderr.strip()}")
    return done.stdout


def regions_of(output: str) -> list[str]:
    """One region per ``###`` block: the Monte Carlo tables, then the peak factors."""
    blocks = re.split(r"^### ", output, flags=re.MULTILINE)[1:]
    regions = []
    for index, block in enumerate(blocks):
        lines = [line for line in block.splitlines() if not line.startswith("runs ")]
        if lines[0].startswith("Relative peak factors"):
            regions.append(cn.region("design-peak-factors", "\n".join(lines[1:])))
        else:
            regions.append(cn.region(f"design-monte-carlo-{index + 1}", "#### " + "\n".join(lines)))
    return regions


def build(data_dir: str | None) -> list[str]:
    return regions_of(montecarlo(int(os.environ.get("DESIGN_RUNS", "300"))))


if __name__ == "__main__":
    raise SystemExit(cn.main("design.md", "design_numbers", build))
