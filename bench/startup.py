"""Start-up cost of the ``flightid`` command: the time outside the estimation, imports, numba
compilation, on-disk kernel cache.

**Overhead table** (the default). For every standard case (``examples/cases/NAME.toml``: the
five of docs/cases.md, "The standard cases", and a flight-path-reconstruction case) runs in
fresh processes, with a warm numba cache (a warm-up run of each command first), taking turns
over ``--rounds`` rounds:

* ``python -c "import numpy, scipy, matplotlib.pyplot"`` — the bare import, the yardstick;
* ``flightid run CASE --json``, ``flightid run CASE --out DIR`` and ``flightid validate CASE``;
* ``flightid run CASE --out DIR --figure-format png`` (the PNG figures drawn by matplotlib,
  on request) with ``FLIGHTID_FIGURE_WORKERS`` = 0 (drawn in the command's own process), 1 and
  2: the second table, whether the figure processes pay for PNG figures, beside the default
  ``--out`` (SVG figures written from the arrays in the command's own process).

Per command it prints the process wall time (s), the estimation time (s: the run's
``wall_time_s``, from stdout with ``--json``, from DIR/results.json with ``--out``; 0 for
``validate``), the overhead = wall − estimation (s), the ratio overhead ÷ bare import, and the
number of numba compilations in one more run (0 when the cache is warm); best over the rounds.
Each command whose ratio is at most 2 prints ``PASS``, else ``FAIL``, and one line per mode
sums it up. The table is printed between the ``<!-- numbers: ... -->`` markers of
docs/benchmarks.md (docs/docs_numbers.py); wall times and ratios are not compared there.

**Compile table** (``--compiles``). For every shipped case and the paper examples, runs
``flightid run CASE`` (``flightid paper EXAMPLE``) twice in fresh processes sharing one fresh
``NUMBA_CACHE_DIR``: the first run compiles and fills the cache, the second should load every
kernel from it. Prints per run the process wall time (s), the time numba spent compiling (s;
numba's ``numba:compile`` events, outermost only, so a kernel compiling its callees is counted
once) and the number of compiled signatures (every dispatcher compile, nested ones included).
Also prints the wall time of ``import flightid`` and ``flightid --help``.

Usage:
    OPENBLAS_NUM_THREADS=1 python bench/startup.py [--cases NAME ...] [--rounds N]
    OPENBLAS_NUM_THREADS=1 python bench/startup.py --quick        # one case, one round
    OPENBLAS_NUM_THREADS=1 python bench/startup.py --compiles [--cases NAME ...]
    OPENBLAS_NUM_THREADS=1 python bench/startup.py --source ...   # no bytecode cache

**As installed.** An installed flightid has its modules' bytecode (``.pyc``) cached; a
source checkout run with ``PYTHONDONTWRITEBYTECODE=1`` (or a read-only tree) compiles every
flightid module from source in every process (about 0.1 s). The children therefore run with
``PYTHONDONTWRITEBYTECODE`` unset and ``PYTHONPYCACHEPREFIX`` pointing at a temporary folder
that the warm-up runs fill; the first line printed says so. ``--source`` measures without
bytecode instead (every module compiled in every run), also said on that line.

Timings scatter with machine load (run it on a quiet machine); the compile counts do not.
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

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
CASES = ROOT / "examples" / "cases"
PAPER_EXAMPLES = ("example1", "example2", "example3")
STANDARD_CASES = (
    "hfb320_longitudinal",
    "attas_lateral",
    "attas_lateral_two_maneuvers",
    "attas_short_period",
    "twin_otter_longitudinal",
    "attas_fpr_biases",
)
MODES = ("--json", "--out", "validate")
# --out --figure-format png with FLIGHTID_FIGURE_WORKERS = 0 (the figures drawn in the
# command's own process), 1 and 2 worker processes: whether the figure processes pay
WORKER_MODES = {"--out-0": "0", "--out-1": "1", "--out-2": "2"}
BARE_IMPORT = "import numpy, scipy, matplotlib.pyplot"
TARGET_RATIO = 2.0

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


def compiles_table(names: list[str] | None, env: dict[str, str]) -> None:
    """The compile table: every shipped case (and the paper examples) twice on a fresh cache."""

    print(f"import flightid        {_wall([sys.executable, '-c', 'import flightid'], env):.3f} s")
    print(
        "flightid --help        "
        f"{_wall([sys.executable, '-m', 'flightid.cli.main', '--help'], env):.3f} s"
    )

    jobs: list[tuple[str, list[str]]] = []
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


# ------------------------------------------------------------------------------ overhead


def _flightid(argv: list[str]) -> list[str]:
    return [sys.executable, "-m", "flightid.cli.main", *argv]


def _command(case: Path, mode: str, out: Path, data_dir: str | None) -> list[str]:
    extra = ["--data-dir", data_dir] if data_dir else []
    if mode == "validate":
        return _flightid(["validate", str(case), *extra])
    if mode == "--json":
        return _flightid(["run", str(case), "--json", "--quiet", *extra])
    png = ["--figure-format", "png"] if mode in WORKER_MODES else []
    return _flightid(["run", str(case), "--out", str(out), "--overwrite", "--quiet", *png, *extra])


def _mode_env(mode: str, env: dict[str, str]) -> dict[str, str]:
    workers = WORKER_MODES.get(mode)
    return env if workers is None else dict(env, FLIGHTID_FIGURE_WORKERS=workers)


def _estimation_s(mode: str, stdout: str, out: Path) -> float:
    """The run's estimation time (s): ``wall_time_s`` of its results (0 for validate)."""
    if mode == "validate":
        return 0.0
    text = stdout if mode == "--json" else (out / "results.json").read_text(encoding="utf-8")
    results = json.loads(text)["results"]
    return float(sum(entry.get("wall_time_s") or 0.0 for entry in results))


def _timed(command: list[str], env: dict[str, str]) -> tuple[float, subprocess.CompletedProcess]:
    start = time.perf_counter()
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["?"])[-1]
        raise SystemExit(f"{' '.join(command[3:5])}: exit {done.returncode}: {last}")
    return wall, done


def _compiles(command: list[str], env: dict[str, str]) -> int:
    """numba compilations of one more run of ``command`` (a flightid command line)."""
    return int(_run_child(command[3:], env)["compiles"])


def overhead_table(
    names: list[str], rounds: int, env: dict[str, str], data_dir: str | None, setting: str = ""
):
    """Measure and print the overhead table (see the module docstring; ``setting``: the
    line saying how bytecode is cached, printed before the table); returns the rows."""
    cases = [CASES / f"{name}.toml" for name in names]
    for case in cases:
        if not case.is_file():
            raise SystemExit(f"--cases: no case file {case}")
    bare_command = [sys.executable, "-c", BARE_IMPORT]
    best: dict[tuple[str, str], tuple[float, float]] = {}
    bare = float("inf")
    with tempfile.TemporaryDirectory(prefix="flightid-overhead-") as scratch:
        run_env = dict(env, NUMBA_CACHE_DIR=str(Path(scratch) / "numba-cache"))
        outs = {case.stem: Path(scratch) / "out" / case.stem for case in cases}
        # warm-up: fills the numba cache and the file cache; not counted
        _timed(bare_command, run_env)
        for case in cases:
            for mode in MODES:
                _timed(_command(case, mode, outs[case.stem], data_dir), run_env)
        # per case: {mode: walls over the rounds} of run --out (default and fixed workers)
        outs_wall: dict[str, dict[str, list[float]]] = {case.stem: {} for case in cases}
        for _ in range(rounds):
            # taking turns: the bare import, then every command of every case
            bare = min(bare, _timed(bare_command, run_env)[0])
            for case in cases:
                for mode in (*MODES, *WORKER_MODES):
                    command = _command(case, mode, outs[case.stem], data_dir)
                    wall, done = _timed(command, _mode_env(mode, run_env))
                    estimation = _estimation_s(mode, done.stdout, outs[case.stem])
                    if mode.startswith("--out"):
                        outs_wall[case.stem].setdefault(mode, []).append(wall)
                    if mode in WORKER_MODES:
                        continue
                    previous = best.get((case.stem, mode))
                    if previous is None or wall - estimation < previous[0] - previous[1]:
                        best[(case.stem, mode)] = (wall, estimation)
        compiles = {
            (case.stem, mode): _compiles(_command(case, mode, outs[case.stem], data_dir), run_env)
            for case in cases
            for mode in MODES
        }
    rows = []
    for case in cases:
        for mode in MODES:
            wall, estimation = best[(case.stem, mode)]
            overhead = wall - estimation
            ratio = overhead / bare
            rows.append(
                (case.stem, mode, wall, estimation, overhead, ratio, compiles[(case.stem, mode)])
            )
    _print_overhead(rows, bare, rounds, setting)
    worker_ratio = _print_workers(outs_wall)
    print("<!-- /numbers -->")
    print()
    _print_verdicts(rows, worker_ratio)
    return rows


def _print_workers(outs_wall: dict[str, dict[str, list[float]]]) -> float:
    """``run --out --figure-format png`` with the figures drawn in the command's own process
    (0 workers), in 1 and 2 worker processes, and the default ``run --out`` (SVG): median
    wall time over the rounds per case, and the ratio of 2 workers to none for PNG; returns
    the median of that ratio over the cases."""
    print()
    print(
        "| case | PNG drawn here, wall (s) | PNG, 1 process, wall (s) "
        "| PNG, 2 processes, wall (s) | default (SVG), wall (s) | PNG 2 ÷ here |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    ratios = []
    for name, walls in outs_wall.items():
        median = {mode: float(np.median(values)) for mode, values in walls.items()}
        ratios.append(median["--out-2"] / median["--out-0"])
        print(
            f"| {name} | {median['--out-0']:.2f} | {median['--out-1']:.2f} "
            f"| {median['--out-2']:.2f} | {median['--out']:.2f} | {ratios[-1]:.2f} |"
        )
    return float(np.median(ratios))


def _print_overhead(rows, bare: float, rounds: int, setting: str = "") -> None:
    print("<!-- guide: docs/benchmarks.md -->")
    if setting:
        print(setting)
    print("<!-- numbers: benchmarks-startup-overhead -->")
    print(f'bare import (`python -c "{BARE_IMPORT}"`): {bare:.3f} s, best of {rounds}')
    print()
    print(
        "| case | command | wall (s) | estimation (s) | overhead (s) | ÷ import "
        "| compilations | overhead ≤ 2 × import |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---|")
    for name, mode, wall, estimation, overhead, ratio, compiles in rows:
        command = "validate" if mode == "validate" else f"run {mode}"
        verdict = "PASS" if ratio <= TARGET_RATIO else "FAIL"
        print(
            f"| {name} | {command} | {wall:.2f} | {estimation:.2f} | {overhead:.2f} "
            f"| {ratio:.2f} | {compiles} | {verdict} |"
        )


def _print_verdicts(rows, worker_ratio: float) -> None:
    for mode in MODES:
        ratios = [row[5] for row in rows if row[1] == mode]
        verdict = "PASS" if max(ratios) <= TARGET_RATIO else "FAIL"
        print(
            f"{verdict}: {mode.lstrip('-')}: overhead at most {TARGET_RATIO:g} × the bare import "
            f"on every case (largest ratio {max(ratios):.2f})"
        )
    compiled = sum(row[6] for row in rows)
    print(
        f"{'PASS' if compiled == 0 else 'FAIL'}: no numba compilation on a warm cache ({compiled})"
    )
    print(
        f"{'PASS' if worker_ratio < 1.0 else 'FAIL'}: the figure processes pay for PNG figures "
        f"(median wall-time ratio of run --out --figure-format png, 2 processes ÷ here, "
        f"{worker_ratio:.2f} < 1)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", help="case file stems (default: the standard cases)")
    parser.add_argument("--rounds", type=int, default=3, help="rounds taken in turns (default 3)")
    parser.add_argument("--quick", action="store_true", help="one case, one round")
    parser.add_argument("--data-dir", default=None, help="the cases' data directory")
    parser.add_argument(
        "--compiles", action="store_true", help="the compile table of every shipped case instead"
    )
    parser.add_argument(
        "--source",
        action="store_true",
        help="no bytecode cache: every module compiled from source in every run",
    )
    args = parser.parse_args()
    env = dict(os.environ)
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(SRC), env.get("PYTHONPATH")]))
    with tempfile.TemporaryDirectory(prefix="flightid-pycache-") as pycache:
        setting = bytecode_setting(env, None if args.source else Path(pycache))
        if args.compiles:
            print(setting, flush=True)
            compiles_table(args.cases, env)
            return
        names = list(args.cases or STANDARD_CASES)
        rounds = args.rounds
        if args.quick:
            names, rounds = names[:1], 1
        overhead_table(names, rounds, env, args.data_dir, setting)


def bytecode_setting(env: dict[str, str], pycache: Path | None) -> str:
    """Set the children's bytecode environment in ``env``; returns the line that says it.

    With ``pycache`` (as installed): ``PYTHONDONTWRITEBYTECODE`` unset, ``PYTHONPYCACHEPREFIX``
    = ``pycache``, filled by the warm-up runs. Without: ``PYTHONDONTWRITEBYTECODE=1``, no
    prefix (every module compiled from source in every run)."""
    if pycache is None:
        env["PYTHONDONTWRITEBYTECODE"] = "1"
        env.pop("PYTHONPYCACHEPREFIX", None)
        return "bytecode: none (--source): every module compiled from source in every run"
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env["PYTHONPYCACHEPREFIX"] = str(pycache)
    return (
        "bytecode: cached, as installed (PYTHONPYCACHEPREFIX = a temporary folder the "
        "warm-up runs fill; --source measures without)"
    )


if __name__ == "__main__":
    main()
