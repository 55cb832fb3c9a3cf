"""Regenerate the outputs quoted in docs/logs.md ("From a flight log to a model").

Runs the walk-through of that page end to end in a temporary folder, through the same
command line a user types: ``flightid example-logs``, ``flightid inspect --case-lines
--out`` on both logs, ``flightid run`` of both example cases; then prints each block the
page quotes, under the key of its ``<!-- walkthrough: KEY -->`` marker.

    python docs/logs_walkthrough.py                  # print the blocks
    python docs/logs_walkthrough.py --check          # compare them with docs/logs.md
    python docs/logs_walkthrough.py --figure docs/figures/inspect_multirotor.png

``--check`` compares every number of a quoted block with the fresh one to the digits the
page prints (one unit of the last printed digit; whole numbers such as sample counts
exactly); words must agree exactly; wall times are not compared. Needs the ``px4`` and
``ardupilot`` extras (pyulog, pymavlink).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import re
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "logs"
DOC = ROOT / "docs" / "logs.md"
MULTIROTOR_CASE = "multirotor_roll_rate.toml"
FIXEDWING_CASE = "fixedwing_roll.toml"
# the channel searched for excitation on the DataFlash log (the servo output of the aileron)
FIXEDWING_CHANNELS = ["RCOU.C1"]
# case parameter name → (truth key of the example writer, label on the page)
MULTIROTOR_PARAMETERS = {
    "wn": ("omega_n", "ω_n (rad/s)"),
    "zeta": ("zeta", "ζ"),
    "tau": ("tau", "τ (s)"),
}
FIXEDWING_PARAMETERS = {"Lp": ("Lp", "L_p (1/s)"), "Lda": ("Lda", "L_δa (1/s²)")}
# blocks whose table rows end in a wall time: the last cell is not compared
WALL_TIME_LAST = {"runs"}
_MARKER = re.compile(r"<!--\s*walkthrough:\s*([\w-]+)\s*-->")
_NUMBER = re.compile(r"^[−+-]?(\d+\.?\d*|\.\d+)(e[−+-]?\d+)?$", re.IGNORECASE)


def _cli(*argv: str) -> str:
    """Run ``flightid ARGV`` in this process; its standard output (a failure raises)."""
    from flightid.cli.main import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(list(argv))
    if code != 0:
        raise RuntimeError(f"flightid {' '.join(argv)} exited with {code}:\n{out.getvalue()}")
    return out.getvalue()


def _significant(value: float, digits: int) -> str:
    return f"{value:.{digits}g}"


def _estimate_rows(example: str, results: dict, parameters: dict, truth: dict) -> list[str]:
    by_name = {p["name"]: p for p in results["parameters"]}
    rows = []
    for name, (truth_key, label) in parameters.items():
        estimate, bound = by_name[name]["value"], by_name[name]["std"]
        # (estimate − truth) / σ: the error in standard deviations (σ: the default σ)
        z = (estimate - truth[truth_key]) / bound
        rows.append(
            f"| {example} | {label} | {truth[truth_key]:g} | {_significant(estimate, 6)} "
            f"| {_significant(bound, 2)} | {z:+.2f} |"
        )
    return rows


def _time_base(results: dict) -> str:
    """The resampling summary of a run: the notes of its first maneuver (shared by its
    segments) without the per-segment line."""
    notes = results["maneuvers"][0].get("time_base", [])
    return "\n".join(n for n in notes if not n.startswith("this maneuver"))


def run_walkthrough(folder: Path) -> dict:
    """The walk-through in ``folder`` (emptied of nothing; it should be new). Returns
    ``{"blocks": {key: text}, "results": {case: results.json}, "folder": folder}``."""
    from flightid.examples.logs import FIXEDWING_FILE, FW_TRUTH, MR_TRUTH, MULTIROTOR_FILE

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for item in [*EXAMPLES.glob("*.toml"), *EXAMPLES.glob("*.py")]:
        shutil.copy(item, folder / item.name)
    blocks: dict[str, str] = {}
    results: dict[str, dict] = {}
    with contextlib.chdir(folder):
        _cli("example-logs", "--out", ".")
        blocks["case_lines_multirotor"] = _cli(
            "inspect", MULTIROTOR_FILE, "--case-lines", "--out", "inspect_multirotor"
        )
        blocks["inspect_multirotor"] = Path("inspect_multirotor/inspect.txt").read_text()
        blocks["case_lines_fixedwing"] = _cli(
            "inspect",
            FIXEDWING_FILE,
            "--channels",
            *FIXEDWING_CHANNELS,
            "--case-lines",
            "--out",
            "inspect_fixedwing",
        )
        blocks["inspect_fixedwing"] = Path("inspect_fixedwing/inspect.txt").read_text()
        rows, runs = [], []
        for example, case, parameters, truth in (
            ("multirotor", MULTIROTOR_CASE, MULTIROTOR_PARAMETERS, MR_TRUTH),
            ("fixed wing", FIXEDWING_CASE, FIXEDWING_PARAMETERS, FW_TRUTH),
        ):
            out = f"out_{Path(case).stem}"
            _cli("run", case, "--out", out)
            (result,) = json.loads(Path(out, "results.json").read_text())["results"]
            results[case] = result
            rows += _estimate_rows(example, result, parameters, truth)
            samples = sum(m["samples"] for m in result["maneuvers"])
            runs.append(
                f"| {example} | `flightid run {case} --out {out}` | {result['status']} "
                f"| {len(result['maneuvers'])} | {samples} | {result['iterations']} "
                f"| {result['wall_time_s']:.2f} s |"
            )
            key = "time_base_" + ("multirotor" if example == "multirotor" else "fixedwing")
            blocks[key] = _time_base(result)
    head = "| example | parameter | truth | estimate | σ | (estimate − truth)/σ |"
    blocks["estimates"] = "\n".join([head, "|---|---|---|---|---|---|", *rows])
    head = "| example | command | status | segments | samples | iterations | wall time |"
    blocks["runs"] = "\n".join([head, "|---|---|---|---|---|---|---|", *runs])
    return {"blocks": blocks, "results": results, "folder": folder}


def write_figure(log_path: Path, target: Path, dpi: int = 80, colors: int = 32) -> Path:
    """The overview figure of ``flightid inspect`` for ``log_path`` at ``dpi``, stored with
    a palette of ``colors`` colours (a small file for the page)."""
    from PIL import Image

    from flightid.logs.inspection import inspect_log
    from flightid.report.log_figures import log_overview_figure, save_log_overview

    inspection = inspect_log(log_path)
    channels = [(name, *inspection.channel_data(name)) for name in inspection.plotted]
    figure = log_overview_figure(
        channels, inspection.segments, inspection.modes, inspection.runs, title=log_path.name
    )
    save_log_overview(figure, target, dpi=dpi)
    with Image.open(target) as image:
        palette = image.convert("RGB").quantize(colors=colors, method=Image.Quantize.MEDIANCUT)
    palette.save(target, optimize=True)
    return Path(target)


# ------------------------------------------------------------------ comparing with the page


def doc_blocks(text: str) -> dict[str, str]:
    """The quoted blocks of the page: after each ``<!-- walkthrough: KEY -->`` marker, the
    fenced code block or the table that follows it."""
    blocks: dict[str, str] = {}
    lines = text.splitlines()
    for i, line in enumerate(lines):
        match = _MARKER.search(line)
        if not match:
            continue
        j = i + 1
        while j < len(lines) and not lines[j].strip():
            j += 1
        if j < len(lines) and lines[j].startswith("```"):
            end = next(k for k in range(j + 1, len(lines)) if lines[k].startswith("```"))
            body = lines[j + 1 : end]
        else:
            end = j
            while end < len(lines) and lines[end].startswith("|"):
                end += 1
            body = lines[j:end]
        blocks[match.group(1)] = "\n".join(body)
    return blocks


def _tokens(line: str) -> list[str]:
    return [t for t in re.split(r"[\s|,=`()\[\]]+|–|\.\.", line) if t]


def _unit_of_last_digit(token: str) -> float:
    mantissa, _, exponent = token.lower().replace("−", "-").partition("e")
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return 10.0 ** (-decimals + (int(exponent) if exponent else 0))


def _same_token(quoted: str, fresh: str) -> bool:
    integer = re.compile(r"^[−+-]?\d+$")
    if integer.match(quoted) or integer.match(fresh):
        return quoted == fresh  # counts (samples, iterations, mode numbers) exactly
    if _NUMBER.match(quoted) and _NUMBER.match(fresh):
        a = float(quoted.replace("−", "-"))
        b = float(fresh.replace("−", "-"))
        # equal to the digits printed: one unit of the last digit either way
        return abs(a - b) <= _unit_of_last_digit(quoted) * (1 + 1e-9) or math.isclose(a, b)
    return quoted == fresh


def compare(doc_text: str, blocks: dict[str, str]) -> list[str]:
    """What differs between the page's quoted blocks and fresh ones (empty: they agree)."""
    quoted = doc_blocks(doc_text)
    problems = [f"{key}: not quoted on the page" for key in blocks if key not in quoted]
    problems += [f"{key}: quoted on the page, not produced" for key in quoted if key not in blocks]
    for key in sorted(set(quoted) & set(blocks)):
        old = [line for line in quoted[key].splitlines() if line.strip()]
        new = [line for line in blocks[key].splitlines() if line.strip()]
        if len(old) != len(new):
            problems.append(f"{key}: {len(old)} lines on the page, {len(new)} now")
            continue
        for line_old, line_new in zip(old, new, strict=True):
            if key in WALL_TIME_LAST:
                line_old, line_new = line_old.rsplit("|", 2)[0], line_new.rsplit("|", 2)[0]
            a, b = _tokens(line_old), _tokens(line_new)
            if len(a) != len(b) or not all(map(_same_token, a, b)):
                problems.append(f"{key}:\n  page: {line_old}\n  now:  {line_new}")
    return problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare with docs/logs.md")
    parser.add_argument("--figure", type=Path, help="write the multirotor overview figure here")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="flightid-logs-") as tmp:
        walk = run_walkthrough(Path(tmp))
        for key, text in walk["blocks"].items():
            print(f"<!-- walkthrough: {key} -->\n{text.rstrip()}\n")
        if args.figure:
            from flightid.examples.logs import MULTIROTOR_FILE

            print(f"wrote {write_figure(Path(tmp) / MULTIROTOR_FILE, args.figure)}")
    if args.check:
        problems = compare(DOC.read_text(encoding="utf-8"), walk["blocks"])
        print("\n".join(problems) or "docs/logs.md agrees with this run")
        return 1 if problems else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
