"""The measured numbers of docs/frequency.md: the comparison with the time domain and the
Monte Carlo coverage, printed by the benchmark scripts that measure them.

    python docs/frequency_numbers.py [--record] [--write] [--check]

Runs ``bench/frequency_comparison.py`` (the case files' band 0.1–1.5 Hz, and 0.04–3 Hz) and
``bench/frequency_monte_carlo.py --n 200`` at the steps 0.04 Hz and 0.02 Hz, and prints
their tables as the guide quotes them (the lines that state a wall time without it). About
5 minutes on one core, most of it the Monte Carlo runs.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys

import case_numbers as cn

BENCH = cn.ROOT / "bench"


def bench(script: str, *arguments: str, data_dir: str | None = None) -> str:
    """What ``python bench/SCRIPT ARGUMENTS`` prints."""
    environment = dict(os.environ, PYTHONPATH=str(cn.ROOT / "src"))
    if data_dir:
        environment["FLIGHTID_DATA"] = data_dir
    done = subprocess.run(
        [sys.executable, str(BENCH / script), *arguments],
        capture_output=True,
        text=True,
        env=environment,
        check=False,
    )
    if done.returncode != 0:
        raise SystemExit(f"bench/{script} failed: {done.stderr.strip()}")
    return done.stdout


def comparison_tables(output: str) -> list[str]:
    """The tables and summary lines of ``bench/frequency_comparison.py``, one per case, each
    without the heading line that states the wall times."""
    blocks = re.split(r"\n(?=\S+\.toml \(time domain)", "\n" + output.strip())
    return [block.split("\n", 1)[1].strip() for block in blocks if block.strip()]


def without_wall_time(output: str) -> str:
    """``…, 16.1 s`` at the end of the Monte Carlo heading line removed."""
    return re.sub(r", [\d.]+ s$", "", output.strip(), count=1, flags=re.MULTILINE)


def build(data_dir: str | None) -> list[str]:
    regions = []
    for band, label in ((None, "case-band"), (("0.04", "3.0"), "wide-band")):
        output = bench("frequency_comparison.py", *(("--band", *band) if band else ()))
        tables = comparison_tables(output)
        for case, table in zip(("short-period", "lateral"), tables, strict=True):
            regions.append(cn.region(f"frequency-{label}-{case}", table))
    for step in ("0.04", "0.02"):
        output = bench("frequency_monte_carlo.py", "--n", "200", "--step", step)
        block = f"```\n{without_wall_time(output)}\n```"
        regions.append(cn.region(f"frequency-monte-carlo-{step}", block))
    return regions


if __name__ == "__main__":
    raise SystemExit(cn.main("frequency.md", "frequency_numbers", build))
