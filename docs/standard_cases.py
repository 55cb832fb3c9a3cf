"""Regenerate the tables of docs/cases.md, "Measured results of the standard cases".

Runs each standard case of ``examples/cases/`` through the command line a user types,
``flightid run CASE --json --quiet``, and prints the block that docs/cases.md quotes between
its ``<!-- standard-cases:begin -->`` and ``<!-- standard-cases:end -->`` markers: per case
the status, the Gauss–Newton passes (``iterations``), the simulations (``equivalent
evaluations``, + those for the bounds) and the cost J, then each parameter's estimate, its
σ (coloured-residual correction) and its raw Cramér–Rao bound.

    python docs/standard_cases.py --data-dir DIR            # print the block
    python docs/standard_cases.py --data-dir DIR --check    # compare it with docs/cases.md

``--check`` compares every number of the page's block with the fresh one to a relative
tolerance of 1e-3 (counts exactly) and exits 1 naming each difference. The data directory is
``--data-dir``, else ``$FLIGHTID_DATA``, else the shipped cases' own default.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CASES = (
    "hfb320_longitudinal",
    "attas_lateral",
    "attas_lateral_two_maneuvers",
    "attas_short_period",
    "twin_otter_longitudinal",
)
BEGIN = "<!-- standard-cases:begin -->"
END = "<!-- standard-cases:end -->"
NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?")
RELATIVE_TOLERANCE = 1e-3


def run_case(name: str, data_dir: str | None) -> dict:
    """The ``results[0]`` entry of ``flightid run examples/cases/NAME.toml --json``."""
    command = [sys.executable, "-m", "flightid.cli.main", "run"]
    command += [str(ROOT / "examples" / "cases" / f"{name}.toml"), "--json", "--quiet"]
    if data_dir:
        command += ["--data-dir", data_dir]
    environment = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    done = subprocess.run(command, capture_output=True, text=True, env=environment, check=False)
    if done.returncode != 0:
        raise SystemExit(f"{name}: flightid run failed: {done.stderr.strip()}")
    return json.loads(done.stdout)["results"][0]


def block(data_dir: str | None) -> str:
    """The markdown block of all standard cases, as docs/cases.md quotes it."""
    lines = []
    for name in CASES:
        entry = run_case(name, data_dir)
        lines.append(
            f"### `{name}` — {entry['status']}, {entry['iterations']} passes, "
            f"{entry['equivalent_evaluations']} simulations "
            f"(+{entry['accuracy_evaluations']} for the bounds), J = {entry['cost']:.6g}"
        )
        lines += ["", "| parameter | estimate | σ (coloured) | CR bound |", "|---|---:|---:|---:|"]
        for parameter in entry["parameters"]:
            if parameter["free"]:
                lines.append(
                    f"| {parameter['name']} | {parameter['value']:.6g} | "
                    f"{parameter['std']:.3g} | {parameter['std_cr']:.3g} |"
                )
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def page_block() -> str:
    """The block docs/cases.md quotes now."""
    text = (ROOT / "docs" / "cases.md").read_text(encoding="utf-8")
    return text.split(BEGIN, 1)[1].split(END, 1)[0].strip() + "\n"


def differences(page: str, fresh: str) -> list[str]:
    """Lines whose numbers differ by more than the tolerance, or whose words differ."""
    found = []
    page_lines, fresh_lines = page.splitlines(), fresh.splitlines()
    if len(page_lines) != len(fresh_lines):
        return [f"{len(page_lines)} lines on the page, {len(fresh_lines)} now"]
    for quoted, now in zip(page_lines, fresh_lines, strict=True):
        if NUMBER.sub("#", quoted) != NUMBER.sub("#", now):
            found.append(f"page: {quoted!r}\n now: {now!r}")
            continue
        for a, b in zip(NUMBER.findall(quoted), NUMBER.findall(now), strict=True):
            # |a − b| ≤ tol·max(|a|, |b|), whole numbers (counts) exactly
            x, y = float(a), float(b)
            exact = "." not in a and "e" not in a
            if (exact and x != y) or not math.isclose(x, y, rel_tol=RELATIVE_TOLERANCE):
                found.append(f"page: {quoted!r}\n now: {now!r}")
                break
    return found


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-dir", default=os.environ.get("FLIGHTID_DATA"))
    parser.add_argument("--check", action="store_true", help="compare with docs/cases.md")
    arguments = parser.parse_args()
    fresh = block(arguments.data_dir)
    if not arguments.check:
        print(fresh, end="")
        return 0
    found = differences(page_block(), fresh)
    for line in found:
        print(line)
    return 1 if found else 0


if __name__ == "__main__":
    raise SystemExit(main())
