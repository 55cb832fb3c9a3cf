"""Per-sample cost of the recursive estimators on one core.

For each shipped ATTAS case (short period: N = 1252, n_x = 2, 8 free → 10 augmented states;
lateral p, r: N = 3004, n_x = 2, 12 free → 14 augmented states) and each method, the case's
estimator is built by ``flightid.cases.recursive_case`` machinery, warmed up once (numba
compilation of the batch kernels), then fed the whole record ``--repeat`` times; the best
time of a pass ÷ N is the cost per sample (µs). "× real time at 100 Hz" is the sample
budget at 100 Hz (10 000 µs) ÷ that cost: how many times faster than a 100 Hz data stream
the estimator keeps up. One thread: ``NUMBA_NUM_THREADS=1`` and ``OMP/OPENBLAS/MKL`` thread
counts set to 1 before numpy is imported, and threadpoolctl's BLAS limit 1 in the loop.
Wall times on a shared machine scatter; the best of the repeats is the least disturbed.

    python bench/recursive_realtime.py [--repeat 3] [--data-dir DIR]
    python bench/recursive_realtime.py --cases      # the 16 case files: estimates ± σ, wall

``--cases`` runs every ``examples/cases/*_recursive_*.toml`` through ``run_recursive_case``
(in this process, after one warm-up run of the same case, so the wall time excludes numba
compilation and imports) and prints the reported values ± σ and the wall time per case.
"""

from __future__ import annotations

import os

for _variable in (
    "NUMBA_NUM_THREADS",
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
):
    os.environ[_variable] = "1"

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CASES = [
    ("attas_short_period", ("ekf", "ukf", "ukf_aug", "efrls", "ftr")),
    ("attas_lateral_pr", ("ekf", "ukf", "ukf_aug", "efrls", "ftr")),
]
BUDGET_US = 1e6 / 100.0  # one sample at 100 Hz


def _estimator_and_record(name: str, data_dir: Path | None):
    """(fresh-estimator factory, t, u, z, n augmented states) of a case file."""
    import numpy as np

    from flightid.cases import load_case
    from flightid.cases.build import base_model, build_model, resolve_data_dir
    from flightid.cases.recursive_case import _columns, _filter, _record, recursive_settings
    from flightid.recursive import AugmentedModel, FourierTransformRegression
    from flightid.recursive.ftr import frequency_grid_hz

    case = load_case(ROOT / "examples/cases" / f"{name}.toml")
    settings = recursive_settings(case.recursive)
    directory = resolve_data_dir(case, data_dir)
    maneuvers, t, dt = _record(case, directory)
    if settings["method"] == "ftr":
        z = _columns(maneuvers, settings["states"], "states")
        u = _columns(maneuvers, settings["inputs"], "inputs")
        grid = settings["frequencies_hz"]
        freq = frequency_grid_hz(grid["start"], grid["stop"], grid["step"])
        every = int(round(settings["update_every_s"] / dt))

        def make():
            return FourierTransformRegression(
                z.shape[1], u.shape[1], freq, every, settings.get("parameter_names"),
                settings["offsets"], settings["n_mean"],
            )  # fmt: skip

        return make, t, u, z, len(settings["states"]) * (z.shape[1] + u.shape[1])
    base, _ = base_model(case, directory)
    model, maneuvers = build_model(case, maneuvers, base=base)
    augmented = AugmentedModel(model, model.initial_state(maneuver=0))
    u = _columns(maneuvers, model.inputs, "inputs")
    z = _columns(maneuvers, model.outputs, "outputs")
    return (lambda: _filter(settings, augmented)), t, np.asarray(u), np.asarray(z), augmented.n


def case_table(data_dir: str | None) -> None:
    """Reported value ± σ and wall time of every recursive case file (warm)."""
    from flightid.cases import load_case
    from flightid.cases.recursive_case import run_recursive_case

    print("| case | N | wall (s) | estimates ± σ (reported value) |")
    print("|---|---|---|---|")
    for path in sorted((ROOT / "examples/cases").glob("*_recursive_*.toml")):
        case = load_case(path)
        run_recursive_case(case, data_dir)  # warm-up: compilation, file cache
        start = time.perf_counter()
        result = run_recursive_case(case, data_dir)
        wall = time.perf_counter() - start
        values = ", ".join(
            f"{n} {v:.5g} ± {s:.2g}"
            for n, v, s in zip(result.parameter_names, result.values, result.std, strict=True)
        )
        flag = ""
        if result.warnings:
            flag = " (warning: " + "; ".join(w[:60] for w in result.warnings) + " …)"
        print(f"| {path.stem} | {result.n_samples} | {wall:.2f} | {values}{flag} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--data-dir", default=None)
    parser.add_argument("--cases", action="store_true", help="the per-case estimate table")
    args = parser.parse_args()
    if args.cases:
        case_table(args.data_dir)
        return
    from threadpoolctl import threadpool_limits

    from flightid.recursive import RecursiveEstimator

    print(
        "| case | method | N | states (aug.) | best pass (s) | µs/sample | × real time at 100 Hz |"
    )
    print("|---|---|---|---|---|---|---|")
    with threadpool_limits(1):
        for model_name, methods in CASES:
            for method in methods:
                name = f"{model_name}_recursive_{method}"
                make, t, u, z, n_aug = _estimator_and_record(name, args.data_dir)
                # warm-up: compiles the kernels of this model
                RecursiveEstimator(make(), record=False).feed_block(t[:30], u[:30], z[:30])
                best = float("inf")
                for _ in range(args.repeat):
                    online = RecursiveEstimator(make(), record=False)
                    start = time.perf_counter()
                    online.feed_block(t, u, z)
                    best = min(best, time.perf_counter() - start)
                per_sample_us = best / t.size * 1e6
                label = f"{n_aug}" if method != "ftr" else f"— ({n_aug} coefficients)"
                print(
                    f"| {model_name} | {method} | {t.size} | {label} | {best:.3f} | "
                    f"{per_sample_us:.0f} | {BUDGET_US / per_sample_us:.0f} |"
                )


if __name__ == "__main__":
    main()
