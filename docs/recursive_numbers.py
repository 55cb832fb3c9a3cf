"""The measured numbers of docs/recursive.md: every shipped recursive case, and the throughput.

    python docs/recursive_numbers.py [--data-dir DIR] [--record] [--write] [--check]

Runs every ``examples/cases/*_recursive_*.toml`` through ``run_recursive_case`` in this
process (once to compile and cache, then once timed) and prints, per model, the reported
value ± σ of each parameter for each method (σ: the square root of the parameter's diagonal
element of P at the last sample; the forgetting-factor RLS reports none), the wall time of
the timed run and whether the case warned about its innovations; then the per-sample cost
table of ``bench/recursive_realtime.py --repeat 3``. About 2 minutes on one core. Wall times
are not compared by the tests.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time

import case_numbers as cn

MODELS = (
    ("attas_lateral_pr", ("ekf", "ukf", "ukf_aug", "efrls", "ftr")),
    ("attas_short_period", ("ekf", "ukf", "ukf_aug", "efrls", "ftr")),
    ("hfb320_longitudinal", ("ekf", "ukf", "ukf_aug")),
    ("unstab_sp", ("ekf", "ukf", "ukf_aug")),
)


def _cell(value: float, sigma: float) -> str:
    if math.isnan(sigma):
        return f"{value:.5g} (no σ)"
    return f"{value:.5g} ± {sigma:.2g}"


def case_tables(data_dir: str | None) -> str:
    from flightid.cases import load_case
    from flightid.cases.recursive_case import run_recursive_case

    blocks = []
    for model, methods in MODELS:
        columns, walls, warned, n_samples = {}, [], [], None
        for method in methods:
            case = load_case(cn.CASES / f"{model}_recursive_{method}.toml")
            run_recursive_case(case, data_dir)  # compiles and caches the kernels
            start = time.perf_counter()
            result = run_recursive_case(case, data_dir)
            walls.append(f"{time.perf_counter() - start:.2f}")
            warned.append("yes" if result.warnings else "no")
            n_samples = result.n_samples
            columns[method] = {
                name: _cell(float(value), float(sigma))
                for name, value, sigma in zip(
                    result.parameter_names, result.values, result.std, strict=True
                )
            }
        names = list(columns[methods[0]])
        rows = [[name] + [columns[m].get(name, "—") for m in methods] for name in names]
        rows += [["wall (s)", *walls], ["innovation warning", *warned]]
        table = cn.table(["parameter", *methods], rows)
        blocks.append(f"**{model}** (N = {n_samples})\n\n{table}")
    return "\n\n".join(blocks)


def throughput(data_dir: str | None) -> str:
    command = [sys.executable, str(cn.ROOT / "bench" / "recursive_realtime.py"), "--repeat", "3"]
    if data_dir:
        command += ["--data-dir", data_dir]
    environment = dict(os.environ, PYTHONPATH=str(cn.ROOT / "src"))
    done = subprocess.run(command, capture_output=True, text=True, env=environment, check=True)
    return done.stdout


def build(data_dir: str | None) -> list[str]:
    return [
        cn.region("recursive-cases", case_tables(data_dir)),
        cn.region("recursive-throughput", throughput(data_dir)),
    ]


if __name__ == "__main__":
    raise SystemExit(cn.main("recursive.md", "recursive_numbers", build))
