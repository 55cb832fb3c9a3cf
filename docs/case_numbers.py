"""Running shipped case files for the guides' numbers: the command a user types, read back.

Each guide's script (``docs/<guide>_numbers.py``) runs the case files of ``examples/cases/``
through ``flightid run CASE --json --quiet`` — what a user types — and formats what the
JSON holds. The helpers here are the parts every such script shares: running a case
(optionally with some of its TOML settings replaced), reading a parameter, the ln det R of
the result, and the printed form of an estimate ± σ.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CASES = ROOT / "examples" / "cases"
sys.path.insert(0, str(Path(__file__).resolve().parent))

import docs_numbers  # noqa: E402  (beside this file)


def run(
    case: str | Path,
    data_dir: str | None = None,
    replace: dict | None = None,
    allow_failure: bool = False,
) -> dict:
    """The JSON ``flightid run CASE --json --quiet`` prints, with ``wall_s`` (the process's
    wall time) added. ``replace`` maps TOML text of the case file to the text it is replaced
    with (a changed solver or setting), run from a copy beside the original. A run that
    fails stops the script, or with ``allow_failure`` gives ``{"error": its message}``."""
    path = Path(case) if Path(case).suffix == ".toml" else CASES / f"{case}.toml"
    text = path.read_text(encoding="utf-8")
    for old, new in (replace or {}).items():
        if old not in text:
            raise ValueError(f"{path.name}: {old!r} not in the case file")
        text = text.replace(old, new)
    copy = None
    if replace:
        with tempfile.NamedTemporaryFile(
            "w", suffix=".toml", dir=path.parent, prefix=".numbers-", delete=False
        ) as file:
            file.write(text)
        copy = Path(file.name)
    command = [sys.executable, "-m", "flightid.cli.main", "run", str(copy or path)]
    command += ["--json", "--quiet"]
    if data_dir:
        command += ["--data-dir", data_dir]
    environment = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    try:
        start = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True, env=environment, check=False)
        wall_s = time.perf_counter() - start
    finally:
        if copy is not None:
            copy.unlink()
    if done.returncode != 0 and allow_failure:
        return {"error": done.stderr.strip().splitlines()[-1], "wall_s": wall_s}
    if done.returncode != 0:
        raise SystemExit(f"{path.name}: flightid run failed: {done.stderr.strip()}")
    output = json.loads(done.stdout)
    output["wall_s"] = wall_s
    return output


def parameter(entry: dict, name: str) -> dict:
    """The parameter ``name`` of a results entry (or a regression coefficient's list)."""
    for item in entry["parameters"]:
        if item["name"] == name:
            return item
    raise KeyError(f"no parameter {name!r}: {[p['name'] for p in entry['parameters']]}")


def ln_det_r(entry: dict) -> float:
    """ln det R of a results entry (R stored as its diagonal or as the full matrix)."""
    r = np.asarray(entry["R"], dtype=float)
    # ln det R = Σ ln R_ii for a diagonal R, ln det of the matrix otherwise
    return float(np.sum(np.log(r))) if r.ndim == 1 else float(np.linalg.slogdet(r)[1])


def significant(value: float, digits: int) -> str:
    """``value`` to ``digits`` significant digits (``%g``), with a minus sign ``−``."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    text = f"{value:.{digits}g}"
    return "−" + text[1:] if text.startswith("-") else text


def estimate(item: dict, sigma: str = "std_cr", digits: int = 5) -> str:
    """``value ± σ`` (σ to 2 significant digits), or ``value (fixed)``."""
    if not item.get("free", True):
        return f"{significant(item['value'], digits)} (fixed)"
    return f"{significant(item['value'], digits)} ± {significant(item[sigma], 2)}"


def table(heading: list[str], rows: list[list[str]]) -> str:
    """A markdown table."""
    lines = ["| " + " | ".join(heading) + " |", "|" + "---|" * len(heading)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def region(name: str, body: str, options: str = "") -> str:
    """A region in the form the guides quote it."""
    marker = f"<!-- numbers: {name}{' ' + options if options else ''} -->"
    return f"{marker}\n{body.strip()}\n<!-- /numbers -->\n"


def main(guide: str, script: str, build: Callable[[str | None], list[str]]) -> int:
    """The command line every guide's script shares: print the regions; ``--record`` keeps
    them in ``docs/numbers/SCRIPT.txt``; ``--write`` puts them into the guide; ``--check``
    compares them with the guide (exit 1 naming each difference)."""
    parser = argparse.ArgumentParser(description=f"the measured numbers of docs/{guide}")
    parser.add_argument("--data-dir", default=os.environ.get("FLIGHTID_DATA"))
    parser.add_argument("--record", action="store_true", help=f"keep in docs/numbers/{script}")
    parser.add_argument("--write", action="store_true", help=f"put into docs/{guide}")
    parser.add_argument("--check", action="store_true", help=f"compare with docs/{guide}")
    arguments = parser.parse_args()
    output = f"<!-- guide: docs/{guide} -->\n" + "\n".join(build(arguments.data_dir))
    print(output, end="")
    if arguments.record:
        docs_numbers.record(script, output)
    page = ROOT / "docs" / guide
    if arguments.write:
        page.write_text(docs_numbers.write(page.read_text("utf-8"), output), encoding="utf-8")
    if arguments.check:
        problems = docs_numbers.compare(page.read_text("utf-8"), output)
        print("\n".join(problems) or f"docs/{guide} agrees", file=sys.stderr)
        return 1 if problems else 0
    return 0
