"""The measured numbers of docs/recursive.md: every shipped recursive case, and the throughput.

    python docs/recursive_numbers.py [--data-dir DIR] [--record] [--write] [--check]

Runs the EKF and UKF on the delayed rate loop of docs/frequency.md and the FTR on a delayed
roll mode (with and without the delay); then every ``examples/cases/*_recursive_*.toml``
through ``run_recursive_case`` in this process (once to compile and cache, then once timed)
and prints, per model, the reported value ± σ of each parameter for each method (σ: the
square root of the parameter's diagonal element of P at the last sample; the
forgetting-factor RLS reports none), the wall time of the timed run and whether the case
warned about its innovations; then the per-sample cost table of
``bench/recursive_realtime.py --repeat 3``. About 2 minutes on one core. Wall times
are not compared by the tests.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time

import case_numbers as cn
import frequency_numbers as loop
import numpy as np

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


def delay_table() -> str:
    """EKF and UKF on the rate loop of docs/frequency.md, with τ held at 0.025 s and without
    a delay (ω_n, ζ ± σ at the last sample)."""
    from flightid.recursive import (
        AugmentedModel,
        ExtendedKalmanFilter,
        RecursiveEstimator,
        UnscentedKalmanFilter,
    )

    t, u, y = loop.rate_loop_record(1)
    settings = {"p0": [1e-4, 1e-2, 100.0, 0.1], "q_states": [1e-8, 1e-4], "r0": [0.02**2]}
    rows = []
    for label, kind in (("EKF", ExtendedKalmanFilter), ("UKF", UnscentedKalmanFilter)):
        row = [label]
        for delay in ("fixed", "none"):
            estimator = kind(AugmentedModel(loop.loop_model(delay), [0.0, 0.0]), **settings)
            RecursiveEstimator(estimator).feed_block(t, u[:, None], y[:, None])
            (wn, zeta), (s_wn, s_zeta) = estimator.theta, estimator.theta_std
            row.append(f"ω_n {wn:.5g} ± {s_wn:.2g}, ζ {zeta:.4g} ± {s_zeta:.2g}")
        rows.append(row)
    return cn.table(["filter", "τ held at 0.025 s", "no delay"], rows)


def ftr_delay() -> str:
    """The FTR on a noise-free roll mode ṗ = L_p p + L_δ δ(t − 0.05 s), L_p = −8, L_δ = 30
    (scipy on a 2 kHz grid, 200 Hz, the multisine of the rate loop), with and without the
    delay."""
    from scipy import signal

    from flightid.recursive import FourierTransformRegression, RecursiveEstimator

    fine = np.arange(40001) * loop.DT / 10
    _, p, _ = signal.lsim(signal.lti([30.0], [1.0, 8.0]), loop.multisine(fine - 0.05), fine)
    t, u, p = fine[::10], loop.multisine(fine[::10]), p[::10]
    found = []
    for delay in (0.05, 0.0):
        ftr = FourierTransformRegression(
            1, 1, np.arange(0.2, 8.01, 0.1), 200, [["Lp", "Lda"]], input_delays_s=[delay]
        )
        RecursiveEstimator(ftr).feed_block(t, u[:, None], p[:, None])
        (lp, lda), (s_lp, s_lda) = ftr.theta, ftr.theta_std
        found.append(f"L_p = {lp:.4g} ± {s_lp:.2g}, L_δ = {lda:.5g} ± {s_lda:.2g}")
    return f"FTR: {found[0]} with `input_delays_s = 0.05`, {found[1]} without."


def build(data_dir: str | None) -> list[str]:
    return [
        cn.region("recursive-delay", f"{delay_table()}\n\n{ftr_delay()}"),
        cn.region("recursive-cases", case_tables(data_dir)),
        cn.region("recursive-throughput", throughput(data_dir)),
    ]


if __name__ == "__main__":
    raise SystemExit(cn.main("recursive.md", "recursive_numbers", build))
