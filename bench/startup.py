"""Start-up cost of the ``flightid`` command: imports, numba compilation, on-disk kernel cache.

For every shipped case (``examples/cases/*.toml``) and the paper examples, runs
``flightid run CASE`` (``flightid paper EXAMPLE``) twice in fresh processes sharing one
fresh ``NUMBA_CACHE_DIR``: the first run compiles and fills the cache, the second should
load every kernel from it. Prints per run the process wall time (s), the time numba spent
compiling (s; numba's ``numba:compile`` events, outermost only, so a kernel compiling its
callees is counted once) and the number of compiled signatures (every dispatcher compile,
nested ones included). Also prints the wall time of ``import flightid`` and ``flightid --help``.

Usage:  OPENBLAS_NUM_THREADS=1 python bench/startup.py [--cases NAME ...]

Timings scatter with machine load; the compile counts do not.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CASES = ROOT / "examples" / "cases"
PAPER_EXAMPLES = ("example1", "example2", "example3")

# Runs the flightid command in this process with a numba compile listener; prints one
# JSON line {"compile_s", "compiles", "rc"} on the last line of stdout.
_CHILD = r"""
import json, sys, time
start = time.perf_counter()
from numba.core import event

class Compiles(event.Listener):
    def __init__(self):
        self.depth = 0
        self.seconds = 0.0
        self.count = 0
    def on_start(self, ev):
        self.count += 1
        if self.depth == 0:
            self.t0 = time.perf_counter()
        self.depth += 1
    def on_end(self, ev):
        self.depth -= 1
        if self.depth == 0:
            self.seconds += time.perf_counter() - self.t0

listener = Compiles()
event.register("numba:compile", listener)
from flightid.cli.main import main
try:
    rc = main(sys.argv[1:])
except SystemExit as exc:
    rc = exc.code
sys.stdout.flush()
print("\n" + json.dumps({"compile_s": listener.seconds, "compiles": listener.count, "rc": rc}))
"""


def _run_child(argv: list[str], env: dict[str, str]) -> dict:
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", _CHILD, *argv], env=env, capture_output=True, text=True
    )
    wall = time.perf_counter() - start
    try:
        result = json.loads(done.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        result = {"compile_s": float("nan"), "compiles": -1, "rc": done.returncode}
    result["wall_s"] = wall
    if result["rc"] not in (0, None):
        result["error"] = (done.stderr.strip().splitlines() or ["?"])[-1]
    return result


def _wall(command: list[str], env: dict[str, str], repeats: int = 3) -> float:
    """Best of ``repeats`` process wall times (s)."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(command, env=env, capture_output=True, check=True)
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", help="case file stems (default: all, and paper)")
    args = parser.parse_args()
    env = dict(os.environ)
    env.setdefault("OPENBLAS_NUM_THREADS", "1")

    print(f"import flightid        {_wall([sys.executable, '-c', 'import flightid'], env):.3f} s")
    print(
        "flightid --help        "
        f"{_wall([sys.executable, '-m', 'flightid.cli.main', '--help'], env):.3f} s"
    )

    jobs: list[tuple[str, list[str]]] = []
    names = args.cases
    for path in sorted(CASES.glob("*.toml")):
        if names is None or path.stem in names:
            jobs.append((path.stem, ["run", str(path)]))
    for example in PAPER_EXAMPLES:
        if names is None or example in names:
            # examples 2 and 3 need their case (example 2: 1, the paper's table III(a);
            # example 3: 1, no noise)
            extra = ["--case", "1"] if example in ("example2", "example3") else []
            jobs.append((f"paper {example}", ["paper", example, *extra]))

    header = (
        f"{'case':40s} {'wall 1st':>8s} {'comp 1st':>8s} {'n 1st':>5s}"
        f" {'wall 2nd':>8s} {'comp 2nd':>8s} {'n 2nd':>5s}"
    )
    print(header)
    print("-" * len(header))
    worst = 0.0
    with tempfile.TemporaryDirectory(prefix="flightid-startup-") as scratch:
        for name, argv in jobs:
            # a fresh numba cache per case: the first run compiles everything it needs
            run_env = dict(env, NUMBA_CACHE_DIR=str(Path(scratch) / name.replace(" ", "_")))
            out = Path(scratch) / "out" / name.replace(" ", "_")
            extra = ["--out", str(out), "--overwrite", "--quiet"] if argv[0] == "run" else []
            runs = [_run_child([*argv, *extra], run_env) for _ in range(2)]
            first, second = runs
            worst = max(worst, second["compile_s"])
            note = (
                "  " + first.get("error", second.get("error", ""))
                if "error" in (first | second)
                else ""
            )
            print(
                f"{name:40s} {first['wall_s']:8.2f} {first['compile_s']:8.2f} "
                f"{first['compiles']:5d} {second['wall_s']:8.2f} {second['compile_s']:8.2f} "
                f"{second['compiles']:5d}{note}",
                flush=True,
            )
    print(f"largest second-run compile time: {worst:.3f} s")


if __name__ == "__main__":
    main()
