"""MNRES study: the secant MNRES against the surface MNRES, MNR and scipy lm.

    python -P bench/mnres_study.py [--seeds 8] [--steps 1000] [--free 22]
                                   [--variant base|hard40] [--cases]

Same 6-DOF Navion benchmark and accounting as ``bench/peers.py`` (imported from it): every
integration through ``Simulator.run`` is recorded; "sims to J*+0.01" counts simulations until
the first whose cost is within 0.01 of the lowest any method reached on that seed. Methods:
MNRES (default: secant form), MNRES surface (``form="algebraic"``, the earlier form),
MNR, scipy lm. ``--cases`` runs the standard example cases (examples/cases/*.toml that name
solver mnres) with MNRES and MNR and prints simulations (split into those to the optimum and
those confirming it, with the bounds' beside them) and wall time. The paper's examples 1 and
2: ``bench/mnres_paper.py``. ``--variant hard40``:
the 40-parameter variant of bench/peers.py (derivatives, output biases, initial states;
``--free`` ignored).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import pathlib  # noqa: E402
import statistics  # noqa: E402

import numpy as np  # noqa: E402

from flightid.estimation import MNR, MNRES  # noqa: E402
from flightid.simulation import simulate  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("peers", HERE / "peers.py")
peers = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(peers)

CASES = (
    "attas_lateral",
    "attas_lateral_two_maneuvers",
    "attas_short_period",
    "hfb320_longitudinal",
    "hfb320_longitudinal_builtin",
    "twin_otter_longitudinal",
    "y13aus_lateral_output_error",
)


def methods(budget: int):
    return [
        ("MNRES", peers._flightid(MNRES(), budget)),
        ("MNRES surface", peers._flightid(MNRES(form="algebraic"), budget)),
        ("MNR", peers._flightid(MNR(), budget)),
        ("scipy lm", peers._scipy("lm", budget)),
    ]


def seeds_table(recorder, seeds, n_steps, n_free, budget, names, variant="base"):
    chosen = [(n, r) for n, r in methods(budget) if names is None or n in names]
    rows = {n: [] for n, _ in chosen}
    free = "40 (hard40)" if variant == "hard40" else str(n_free)
    print(f"N = {n_steps + 1} samples, {free} free parameters, budget {budget}")
    print("| seed | method | sims to J*+0.01 | sims total | final J − J* | wall, s |")
    print("|---:|---|---:|---:|---:|---:|")
    for seed in seeds:
        model, data, r_diag, _ = peers.benchmark(seed, n_steps, n_free, variant=variant)
        simulate(model, data)
        results = {n: peers.run_one(recorder, r, model, data, r_diag) for n, r in chosen}
        j_star = min(float(np.min(r["history"])) for r in results.values())
        for name, r in results.items():
            hit = peers._first_below(r["history"], j_star + 0.01)
            rows[name].append((hit, r["sims"], r["wall"]))
            print(
                f"| {seed} | {name} | {peers._fmt(hit)} | {r['sims']} | "
                f"{r['cost'] - j_star:.3g} | {r['wall']:.3f} |",
                flush=True,
            )
    print()
    print("| method | median sims to J*+0.01 | max | median wall, s |")
    print("|---|---:|---:|---:|")
    for name, values in rows.items():
        hits = [np.inf if h is None else h for h, _, _ in values]
        print(
            f"| {name} | {statistics.median(hits):g} | {max(hits):g} | "
            f"{statistics.median(w for _, _, w in values):.3f} |"
        )


def cases_table():
    import dataclasses  # noqa: PLC0415

    from flightid.cases import load_case, run_case  # noqa: PLC0415

    print(
        "| case | method | converged | simulations | to optimum | confirming | bounds | "
        "estimation wall, s | cost |"
    )
    print("|---|---|---|---:|---:|---:|---:|---:|---:|")
    for case in CASES:
        path = HERE.parent / "examples" / "cases" / f"{case}.toml"
        spec = load_case(path)
        runs = {}
        # a first, untimed run compiles the model's kernels; then each method, timed
        for name, solver in (("warm-up", "mnr"), ("MNRES", "mnres"), ("MNR", "mnr")):
            spec = dataclasses.replace(spec, estimation={**spec.estimation, "solver": solver})
            runs[name] = run_case(spec, accuracy="none").estimate
        for name in ("MNRES", "MNR"):
            result = runs[name]
            print(
                f"| {case} | {name} | {result.converged} | {result.equivalent_evaluations} | "
                f"{result.evaluations_to_optimum} | {result.confirmation_evaluations} | "
                f"{result.accuracy_evaluations} | {result.wall_time_s:.3f} | {result.cost:.6g} |",
                flush=True,
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--free", type=int, default=22)
    parser.add_argument("--budget", type=int, default=5000)
    parser.add_argument("--methods", nargs="+", default=None)
    parser.add_argument("--variant", choices=peers.VARIANTS, default="base")
    parser.add_argument("--cases", action="store_true")
    args = parser.parse_args()
    if args.cases:
        cases_table()
        return
    recorder = peers.Recorder()
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    seeds_table(recorder, seeds, args.steps, args.free, args.budget, args.methods, args.variant)


if __name__ == "__main__":
    main()
