"""What ``flightid run CASE --out DIR`` spends on its files: the report's figures, one by one,
and the other files of the result folder (results.json with time_histories.csv,
estimates.csv, report.html).

For each case (``examples/cases/NAME.toml``) the run is made once in this process; then, taking
turns over ``--rounds`` rounds, each of the report's figures is made three ways: as SVG text
written from the arrays (``flightid.report.svg_figures``, the default ``--out``), as PNG bytes
drawn by matplotlib (``flightid.report.drawing.draw_job``: ``--figure-format png``), and, as the
peer, as PNG bytes by the figure module of the commit ``--peer`` (``git show``; the figures
before the figure work); and the other files are written to a temporary folder. CPU time of
this process (``time.process_time``), best over the rounds, in ms.

Prints a table per figure (ms SVG, ms PNG, ms PNG peer, SVG ÷ PNG, PNG ÷ peer) and per other
file, the sums, the share of each item in the default ``--out`` work (SVG figures + files),
and the bare import time of numpy, scipy and matplotlib.pyplot (the start-up yardstick,
``bench/startup.py``) for scale. Fact lines: the SVG figures' CPU against the PNG ones, and
the default ``--out`` work against the bare import. (The command's target, overhead ≤ 2 × the
bare import, is ``bench/startup.py``'s; the PNG figures are matplotlib's cost and only paid
on request.)

Usage:
    OPENBLAS_NUM_THREADS=1 python bench/figures.py [--cases NAME ...] [--rounds N]
    OPENBLAS_NUM_THREADS=1 python bench/figures.py --quick     # hfb320_longitudinal, 2 rounds

Timings scatter with machine load; the turns keep the ratios fair.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
import types
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

CASES = ("hfb320_longitudinal", "attas_lateral", "attas_fpr_biases")
# the commit whose figure module is the peer (the figures before this work)
PEER_COMMIT = "f36db42"


def _peer_module(commit: str) -> types.ModuleType | None:
    """The figure module of ``commit`` as a separate module object (None without git)."""
    try:
        source = subprocess.run(
            ["git", "show", f"{commit}:src/flightid/report/figures.py"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    spec = importlib.util.spec_from_loader("flightid_peer_figures", loader=None)
    module = importlib.util.module_from_spec(spec)
    exec(compile(source, f"{commit}:figures.py", "exec"), module.__dict__)
    return module


def _cpu_ms(action) -> float:
    start = time.process_time()
    action()
    return 1000.0 * (time.process_time() - start)


def _draw(module, job) -> bytes:
    figure = getattr(module, job.function)(*job.args, **job.kwargs)
    return module.png_bytes(figure, job.dpi)


def _draw_here(job) -> bytes:
    """A job drawn as ``flightid.report.drawing.draw`` draws it (the heap frozen)."""
    from flightid.report import drawing, figures

    with drawing._heap_frozen():
        return _draw(figures, job)


def _bare_import_s() -> float:
    best = float("inf")
    for _ in range(2):
        start = time.perf_counter()
        subprocess.run(
            [sys.executable, "-c", "import numpy, scipy, matplotlib.pyplot"],
            check=True,
            env={**os.environ, "MPLBACKEND": "Agg"},
        )
        best = min(best, time.perf_counter() - start)
    return best


def _svg(job) -> bytes:
    """A job's figure as SVG text (the default ``--out`` figures)."""
    from flightid.report.svg_figures import SVG_FUNCTIONS

    options = {key: value for key, value in job.kwargs.items() if key != "dpi"}
    return SVG_FUNCTIONS[job.function](*job.args, **options).encode("utf-8")


def _other_files(run, directory: Path) -> dict[str, callable]:
    from flightid.report import html
    from flightid.report.histories import write_results_and_histories

    def report_page():
        (directory / "report.html").write_text(
            html.render_html(run, None, directory=directory), encoding="utf-8"
        )

    return {
        "results.json + time_histories.csv": lambda: write_results_and_histories(run, directory),
        "estimates.csv": lambda: html.write_csv(run, directory / "estimates.csv"),
        "report.html (page, figures apart)": report_page,
    }


def bench_case(name: str, rounds: int, peer) -> tuple[list[list], list[float], float]:
    """Rows (item, ms SVG, ms PNG here, ms PNG peer) of one case; the figures' ms (SVG, PNG
    here, PNG peer) and the ms of the other files."""
    from flightid.cases import run_case
    from flightid.report.html import figure_jobs

    run = run_case(ROOT / "examples" / "cases" / f"{name}.toml", accuracy="cr")
    files, jobs = figure_jobs(run)
    svg = [float("inf")] * len(jobs)
    here = [float("inf")] * len(jobs)
    there = [float("inf")] * len(jobs)
    with tempfile.TemporaryDirectory() as folder:
        others = _other_files(run, Path(folder))
        other_ms = dict.fromkeys(others, float("inf"))
        for _ in range(rounds):
            for k, job in enumerate(jobs):
                svg[k] = min(svg[k], _cpu_ms(lambda job=job: _svg(job)))
                here[k] = min(here[k], _cpu_ms(lambda job=job: _draw_here(job)))
                if peer is not None:
                    there[k] = min(there[k], _cpu_ms(lambda job=job: _draw(peer, job)))
            for item, action in others.items():
                other_ms[item] = min(other_ms[item], _cpu_ms(action))
    rows = []
    for file, job, v, a, b in zip(files, jobs, svg, here, there, strict=True):
        stem = file.removesuffix(".png")
        panels = f"{job.function}" + (f" ({int(job.weight)} panels)" if "maneuver" in file else "")
        rows.append([f"{stem}: {panels}", v, a, b])
    nan = float("nan")
    rows += [[item, ms, nan, nan] for item, ms in other_ms.items()]
    return rows, [sum(svg), sum(here), sum(there)], sum(other_ms.values())


def _ms(value: float) -> str:
    return f"{value:.0f}" if value == value and value < float("inf") else ""


def _ratio(a: float, b: float) -> str:
    return f"{a / b:.3f}" if a == a and b == b and 0 < b < float("inf") else ""


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=None)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="hfb320_longitudinal, 2 rounds")
    parser.add_argument("--peer", default=PEER_COMMIT, help="commit of the peer figure module")
    args = parser.parse_args(argv)
    cases = args.cases or (["hfb320_longitudinal"] if args.quick else list(CASES))
    rounds = 2 if args.quick else args.rounds
    os.environ.setdefault("MPLBACKEND", "Agg")
    peer = _peer_module(args.peer)
    import_s = _bare_import_s()
    print("<!-- guide: docs/benchmarks.md -->")
    print("<!-- numbers: benchmarks-figures -->")
    print(
        "| case | item | ms SVG (default) | ms PNG | ms PNG peer | SVG ÷ PNG | PNG ÷ peer "
        "| ÷ --out work |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    summary = []
    lines = []
    for name in cases:
        if name == "attas_fpr_biases" and not (ROOT.parent / "shared" / "data").exists():
            lines.append(f"{name}: skipped (no reference data)")
            continue
        rows, (svg, png, peer_png), other = bench_case(name, rounds, peer)
        work = svg + other
        for item, v, a, b in rows:
            print(
                f"| {name} | {item} | {v:.1f} | {_ms(a)} | {_ms(b)} | {_ratio(v, a)} "
                f"| {_ratio(a, b)} | {100 * v / work:.0f} % |"
            )
        print(
            f"| {name} | **all figures** | {svg:.1f} | {png:.0f} | {_ms(peer_png)} "
            f"| {_ratio(svg, png)} | {_ratio(png, peer_png)} | {100 * svg / work:.0f} % |"
        )
        print(f"| {name} | **--out work** (SVG figures + files) | {work:.0f} | | | | | 100 % |")
        summary.append(
            f"{name}: SVG figures {svg:.1f} ms = {svg / png:.3f} × the PNG figures' CPU; the "
            f"default --out work {work / 1000:.3f} s = {work / 1000 / import_s:.2f} × the bare "
            f"import"
        )
    print("<!-- /numbers -->\n")
    print(f"bare import (numpy, scipy, matplotlib.pyplot): {import_s:.3f} s, best of 2")
    print(f"CPU ms, best of {rounds} rounds in turns; peer: the PNG figures of commit {args.peer}")
    for line in lines:
        print(line)
    # the command's target (overhead ≤ 2 × the bare import) is checked by bench/startup.py
    for text in summary:
        print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
