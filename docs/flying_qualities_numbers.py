"""Regenerate the measured examples of docs/flying_qualities.md.

Runs the standard cases HFB-320 longitudinal, ATTAS short period and ATTAS lateral (output
error, no accuracy assessment), linearizes each estimate at the initial state and mean inputs
of its first maneuver, and prints the block the page quotes between its
``<!-- flying-qualities:begin -->`` and ``<!-- flying-qualities:end -->`` markers: the modes
with σ, the MIL-F-8785C levels for the class and category named below, and the short-period
LOES of the HFB-320.

    python docs/flying_qualities_numbers.py --data-dir DIR            # print the block
    python docs/flying_qualities_numbers.py --data-dir DIR --check    # compare with the page

``--check`` compares every number of the page's block with the fresh one to a relative
tolerance of 1e-3 (absolute 1e-9) and exits 1 naming each difference.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs" / "flying_qualities.md"
BEGIN = "<!-- flying-qualities:begin -->"
END = "<!-- flying-qualities:end -->"
NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?")
RELATIVE_TOLERANCE = 1e-3
# case, airplane class, flight-phase category, airspeed for n/α where the model has no V [m/s]
CASES = (
    ("hfb320_longitudinal", "II-L", "B", None),
    ("attas_short_period", "II-L", "B", None),
    ("attas_lateral", "II-L", "B", None),
)


def block(data_dir: Path | None) -> str:
    from flightid.cases.run import run_case
    from flightid.export.loes import short_period_loes
    from flightid.export.modal import modal_analysis

    lines = []
    for name, airplane_class, category, speed in CASES:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            run = run_case(
                ROOT / "examples" / "cases" / f"{name}.toml", data_dir=data_dir, accuracy="none"
            )
        settings = {"class": airplane_class, "category": category}
        if speed is not None:
            settings["speed"] = speed
        analysis = modal_analysis(run.estimate, at=run.maneuvers[0], settings=settings)
        lines += [f"== {name}", analysis.summary()]
        if name == "hfb320_longitudinal":
            for band in ((0.1, 10.0), (0.5, 10.0)):
                fit = short_period_loes(analysis.linear, "de", "q", band_rad_s=band)
                lines.append(fit.summary())
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def _numbers(text: str) -> list[float]:
    return [float(n) for n in NUMBER.findall(text)]


def check(fresh: str) -> list[str]:
    """Differences between the page's block and ``fresh``."""
    page = PAGE.read_text(encoding="utf-8")
    if BEGIN not in page or END not in page:
        return [f"{PAGE.name}: the markers {BEGIN} ... {END} are missing"]
    quoted = page.split(BEGIN, 1)[1].split(END, 1)[0]
    quoted = quoted.replace("```text", "").replace("```", "")
    old_lines = [line for line in quoted.strip().splitlines()]
    new_lines = fresh.strip().splitlines()
    if len(old_lines) != len(new_lines):
        return [f"the block has {len(old_lines)} lines, the script prints {len(new_lines)}"]
    problems = []
    for number, (old, new) in enumerate(zip(old_lines, new_lines, strict=True), start=1):
        a, b = _numbers(old), _numbers(new)
        close = len(a) == len(b) and all(
            math.isclose(x, y, rel_tol=RELATIVE_TOLERANCE, abs_tol=1e-9)
            for x, y in zip(a, b, strict=True)
        )
        if not close or NUMBER.sub("#", old) != NUMBER.sub("#", new):
            problems.append(f"line {number}: page {old!r}\n          script {new!r}")
    return problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-dir", type=Path, default=None)
    parser.add_argument("--check", action="store_true")
    args = parser.parse_args(argv)
    data_dir = args.data_dir
    if data_dir is None and os.environ.get("FLIGHTID_DATA"):
        data_dir = Path(os.environ["FLIGHTID_DATA"])
    fresh = block(data_dir)
    if not args.check:
        print(fresh, end="")
        return 0
    problems = check(fresh)
    for problem in problems:
        print(problem)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
