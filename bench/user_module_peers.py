"""The user-module variant of ``bench/peers.py`` (``--variant user``), and busy-loop load.

The 6-DOF benchmark of ``bench/peers.py`` (base variant: its data, noise, seeded starts and
R) with the model written as a user model module, ``bench/navion_user_model.py`` (``f`` and
``h`` return new arrays, as documented; 22 parameters, all free). Methods, in turns on every
seed:

* flightid ``MNR`` and ``MNRES`` on the user-module model;
* scipy ``least_squares(method="lm")`` on the same model's residuals (``Simulator``);
* a plain Gauss–Newton on the hand-written numba simulator of ``bench/kernel.py``
  (``hand_simulate``, serial): forward differences of relative step 1e-6 · max(|θ|, typical),
  the step solved by least squares, halved (at most 10 times) while the cost rises, stopped
  when the cost changes by less than 1e-8 relative or after the budget. It is the code a user
  would write by hand; its simulations are counted like the others'.

Printed: per seed, each method's simulations, final J − J* and wall time; then the medians
and the ratios MNR wall / plain GN wall (target ≤ 1.3, a PASS/FAIL line) and MNRES against
scipy lm (wall and simulations).

``--load N`` starts N busy-loop processes (``python -c "while True: pass"``) before the
measurement and stops them after it, to show how the times grow when the cores are shared.
"""

from __future__ import annotations

import contextlib
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

# MNR's wall time within this factor of the plain Gauss–Newton's
GN_TARGET = 1.3


@contextlib.contextmanager
def busy_load(n_processes: int):
    """N busy-loop processes running for the duration of the block (stopped after it)."""
    processes = [
        subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n_processes)
    ]
    try:
        if processes:
            time.sleep(0.5)  # let them start spinning
        yield
    finally:
        for process in processes:
            process.terminate()
        for process in processes:
            process.wait()


def user_model_at(base_model):
    """The user-module model at the base benchmark model's start values, free flags,
    typical values and initial state (parameters matched by name)."""
    from flightid.cases.usermodel import load_user_model
    from flightid.model import Parameter, Parameters, StateSpaceModel
    from kernel import USER_MODULE

    user = load_user_model(USER_MODULE)
    by_name = {p.name: p for p in base_model.parameters}
    parameters = Parameters(
        Parameter(n, by_name[n].value, free=by_name[n].free, scale=by_name[n].scale)
        for n in user.parameters
    )
    return StateSpaceModel(user.states, user.inputs, user.outputs, user.f, user.h, parameters,
                           x0=base_model.x0, name="navion user module")  # fmt: skip


def _plain_gauss_newton(budget: int):
    """The plain Gauss–Newton on the hand-written kernel (module docstring)."""
    from kernel import HAND_INPUTS, airplane_constants, hand_simulate

    def run(model, data, r_diag, problem, recorder):
        t = np.ascontiguousarray(data.time, dtype=float)
        u = np.ascontiguousarray(np.column_stack([data.channel(n) for n in HAND_INPUTS]))
        x0, c = np.asarray(model.initial_state(), dtype=float), airplane_constants()
        z, w = problem.measured, 1.0 / np.sqrt(r_diag)
        typical = np.array([p.typical for p in model.parameters])
        y = np.empty((t.size, z.shape[1]))

        def residuals(theta):
            start = time.perf_counter()
            hand_simulate(theta, x0, t, u, c, y)
            recorder.sim_s += time.perf_counter() - start
            r = ((z - y) * w).ravel()
            cost = float(r @ r)
            recorder.costs.append(cost if np.isfinite(cost) else np.inf)
            return r

        theta = model.parameters.values.copy()
        r0 = residuals(theta)
        cost = float(r0 @ r0)
        while len(recorder.costs) + theta.size + 1 <= budget:
            steps = 1e-6 * np.maximum(np.abs(theta), typical)
            # J_ij = ∂r_i/∂θ_j by forward differences
            jac = np.column_stack(
                [(residuals(theta + steps[j] * np.eye(theta.size)[j]) - r0) / steps[j]
                 for j in range(theta.size)]
            )  # fmt: skip
            delta = np.linalg.lstsq(jac, -r0, rcond=None)[0]
            for _ in range(10):
                r_new = residuals(theta + delta)
                new = float(r_new @ r_new)
                if new <= cost:
                    break
                delta = 0.5 * delta
            if not new <= cost:
                break
            theta, r0, converged = theta + delta, r_new, abs(cost - new) <= 1e-8 * new
            cost = new
            if converged:
                break
        return cost

    run.records_itself = True
    return run


def _warm_hand_kernel(model, data) -> None:
    """Compile the hand-written kernel outside the timings."""
    from kernel import HAND_INPUTS, airplane_constants, hand_simulate

    t = np.ascontiguousarray(data.time[:3], dtype=float)
    u = np.ascontiguousarray(np.column_stack([data.channel(n)[:3] for n in HAND_INPUTS]))
    x0 = np.asarray(model.initial_state(), dtype=float)
    hand_simulate(model.parameters.values, x0, t, u, airplane_constants(), np.empty((3, 8)))


def _methods(budget: int):
    from peers import MNR, MNRES, _flightid, _scipy

    return [
        ("MNR", _flightid(MNR(), budget)),
        ("MNRES", _flightid(MNRES(), budget)),
        ("scipy lm", _scipy("lm", budget)),
        ("plain GN, hand kernel", _plain_gauss_newton(budget)),
    ]


def _run(recorder, runner, model, data, r_diag):
    from peers import run_one

    if not getattr(runner, "records_itself", False):
        return run_one(recorder, runner, model, data, r_diag)
    from flightid.estimation import OutputErrorProblem

    problem = OutputErrorProblem(model, data)
    recorder.reset(problem.measured, r_diag)
    recorder.measured = None  # the runner records its own simulations
    start = time.perf_counter()
    cost = runner(model, data, r_diag, problem, recorder)
    wall = time.perf_counter() - start
    return {
        "cost": cost,
        "history": np.array(recorder.costs),
        "wall": wall,
        "share": recorder.sim_s / wall,
        "sims": len(recorder.costs),
    }


def user_module_table(recorder, seeds, budget: int, n_steps: int, load: int = 0) -> list[str]:
    """The seeds table of the user-module variant (module docstring); returns the PASS/FAIL
    lines (printed too)."""
    from flightid.simulation import Simulator, simulate
    from peers import benchmark

    runs = _methods(budget)
    per_method: dict[str, list[dict]] = {name: [] for name, _ in runs}
    print(f"busy-loop processes beside the measurement: {load}; {os.cpu_count()} CPUs")
    print()
    print("| seed | method | sims | final J − J* | wall, s | sim share |")
    print("|---:|---|---:|---:|---:|---:|")
    with busy_load(load):
        for seed in seeds:
            base, data, r_diag, _ = benchmark(seed, n_steps)
            model = user_model_at(base)
            # compile outside the timings: the serial and parallel kernels, the hand kernel
            simulate(model, data)
            Simulator(model, data).run(np.tile(model.parameters.values, (23, 1)))
            _warm_hand_kernel(model, data)
            results = {name: _run(recorder, runner, model, data, r_diag) for name, runner in runs}
            j_star = min(float(np.min(r["history"])) for r in results.values())
            for name, r in results.items():
                per_method[name].append(r)
                print(f"| {seed} | {name} | {r['sims']} | {r['cost'] - j_star:.3g} | "
                      f"{r['wall']:.3f} | {r['share']:.2f} |")  # fmt: skip
    print()
    print(f"<!-- numbers: peers-user-module-load-{load} -->")
    print(f"| method ({len(per_method['MNR'])} seeds, {load} busy processes) | median sims | "
          "median wall, s | ÷ plain GN |")  # fmt: skip
    print("|---|---:|---:|---:|")
    gn_wall = statistics.median(r["wall"] for r in per_method["plain GN, hand kernel"])
    for name, rows in per_method.items():
        wall = statistics.median(r["wall"] for r in rows)
        print(f"| {name} | {statistics.median(r['sims'] for r in rows):g} | {wall:.3f} | "
              f"{wall / gn_wall:.2f} |")  # fmt: skip
    print("<!-- /numbers -->")

    def ratios(a, b, key):
        return [x[key] / y[key] for x, y in zip(per_method[a], per_method[b], strict=True)]

    gn = ratios("MNR", "plain GN, hand kernel", "wall")
    sims_gn = ratios("MNR", "plain GN, hand kernel", "sims")
    es_wall = ratios("MNRES", "scipy lm", "wall")
    es_sims = ratios("MNRES", "scipy lm", "sims")
    print()
    print(f"MNR / plain GN: wall median {statistics.median(gn):.2f} (worst {max(gn):.2f}), "
          f"simulations median {statistics.median(sims_gn):.2f}")  # fmt: skip
    print(f"MNRES / scipy lm: wall median {statistics.median(es_wall):.2f} (worst "
          f"{max(es_wall):.2f}), simulations median {statistics.median(es_sims):.2f}")  # fmt: skip
    verdict = "PASS" if statistics.median(gn) <= GN_TARGET else "FAIL"
    line = (
        f"{verdict}: user module, MNR wall / plain Gauss–Newton wall = "
        f"{statistics.median(gn):.2f} (median over seeds; target ≤ {GN_TARGET}; load {load})"
    )
    print(line)
    return [line]
