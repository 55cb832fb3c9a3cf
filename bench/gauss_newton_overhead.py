"""flightid's MNR against a plain batched forward-difference Gauss–Newton (issue 14 part 4).

The plain Gauss–Newton is written here in numpy and uses nothing of flightid's estimation
code, only its simulator. Per iteration: one ``Simulator.run`` of the batch
θ + δ_j e_j, j = 1 … n_f (δ_j = 10⁻⁶·max(|θ_j|, typical_j), the steps of ``MNR()``), the
forward-difference Jacobian G_j = (y(θ + δ_j e_j) − y(θ))/δ_j, the normal equations

    M = Σ_i G_iᵀ R⁻¹ G_i,   Δθ = M⁻¹ Σ_i G_iᵀ R⁻¹ ν_i,   ν = z − y(θ)

and one integration at θ + λΔθ, λ = 1 (then ½, ¼, … while the cost does not drop: the step
halving of MNR, without which the iterates part on this benchmark's seed 0). Stop rules of
``Convergence()`` as MNR applies them: after an accepted step |ΔJ| ≤ 10⁻³·J and
|Δθ_j| ≤ 10⁻³·max(|θ_j|, typ_j); before a step, the same parameter test on the next step and
its predicted drop ΔθᵀMΔθ ≤ 10⁻³·J. So it spends the integrations MNR spends (n_f + 1 per
pass, plus one per halving). At the end the Cramér–Rao matrix M⁻¹ from the Jacobian at the
final θ (one more batch of n_f if the last pass stopped after a step, else the last one).

Compared, on ``bench/peers.py``'s 6-DOF Navion benchmark (seed 0, R fixed at the true noise
variances):

* "plain GN": the loop above, Cramér–Rao matrix included;
* "MNR solver": ``MNR().minimize`` on flightid's ``Objective`` (the iterations only: no
  confirmation, no Cramér–Rao matrix);
* "estimate(MNR)": ``flightid.estimate(model, data, MNR(), noise="fixed", R=σ²)`` end to end:
  the model check, the same iterations, the central-difference confirmation of convergence
  (which gives the sensitivities of the Cramér–Rao bounds), the information matrix, the
  covariance and the ``Estimate`` (``wall_time_s``, ``cost_history``, ``evaluation_history``).

Columns: "steps" (accepted Gauss–Newton steps), "same iterates" (largest
|θ_k(MNR) − θ_k(plain)| / max(|θ_k|, typ) over the iterates; MNR's from
``Objective.theta_history``: they agree to the rounding of normal equations against MNR's QR,
≈ cond²·ε), sims (``Simulator.run`` trajectories), wall s (best of ``--repeat``), ratio
(wall ÷ plain GN's), wall per sim ÷ plain's (the overhead per integration, whatever the
number of passes), sim share (time inside ``Simulator.run`` ÷ wall). ``estimate`` may take
more passes than the plain loop: its confirmation continues until the central-difference
Gauss–Newton step is ≤ 0.02 Cramér–Rao σ, where the relative tests of 10⁻³ stop up to
√(10⁻³·J) σ short (≈ 28 σ at N = 10⁵); the comment under each case says how far each
stopped. Peak memory:
``tracemalloc`` peak (numpy's allocations included; not RSS) during one more run of each,
beside the size of the sensitivity array G (N × n_o × n_f float64). Wall times on a shared
2-core machine scatter; simulation counts do not. One BLAS thread
(``OPENBLAS_NUM_THREADS=1``).

Usage: ``python -P bench/gauss_newton_overhead.py [--cases 1000:22 10000:22 100000:20]
[--repeat 3] [--no-memory]`` (about 10 minutes with N = 10⁵).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

from flightid.estimation import MNR, Convergence, OutputErrorProblem, estimate  # noqa: E402
from flightid.estimation.objective import Objective  # noqa: E402
from flightid.simulate import Simulator, simulate  # noqa: E402
from peers import benchmark  # noqa: E402

RELATIVE_STEP = 1e-6  # MNR().relative_step
COST_RTOL = PARAM_RTOL = 1e-3  # Convergence() defaults


class SimulationClock:
    """Wraps ``Simulator.run``: counts trajectories and the seconds spent integrating."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self.trajectories = 0
        original = Simulator.run
        clock = self

        def run(simulator, thetas):
            start = time.perf_counter()
            batch = original(simulator, thetas)
            clock.seconds += time.perf_counter() - start
            clock.trajectories += len(batch.outputs)
            return batch

        Simulator.run = run

    def reset(self) -> None:
        self.seconds = 0.0
        self.trajectories = 0


def plain_gauss_newton(simulator, measured, r_diag, theta_full, free_index, typical):
    """The plain forward-difference Gauss–Newton with step halving (module docstring).

    Returns (iterates (K, n_f), Cramér–Rao matrix M⁻¹ at the last one, costs per iterate,
    halvings taken).
    """
    weight = 1.0 / r_diag  # R⁻¹ (diagonal)
    root_weight = np.sqrt(weight)
    theta = theta_full[free_index].copy()
    n_f = theta.size

    def simulate_free(thetas_free):
        full = np.repeat(theta_full[None, :], len(thetas_free), axis=0)
        full[:, free_index] = thetas_free
        return simulator.run(full).outputs

    def cost_of(y):
        # J = Σ_i ν_iᵀ R⁻¹ ν_i
        return float(np.sum((measured - y) ** 2 * weight))

    y = simulate_free(theta[None, :])[0]
    cost = cost_of(y)
    iterates, costs, halvings = [theta.copy()], [cost], 0
    for _ in range(500):
        steps = RELATIVE_STEP * np.maximum(np.abs(theta), typical)
        perturbed = simulate_free(theta + np.diag(steps))  # (n_f, N, n_o)
        # G_j = (y(θ + δ_j e_j) − y(θ)) / δ_j, weighted by R^(-1/2), as (n_f, N·n_o)
        a = ((perturbed - y) * (root_weight / steps[:, None, None])).reshape(n_f, -1)
        del perturbed
        m = a @ a.T  # M = Σ GᵀR⁻¹G
        gradient = a @ ((measured - y) * root_weight).ravel()  # Σ GᵀR⁻¹ν
        del a
        step = np.linalg.solve(m, gradient)  # Δθ = M⁻¹ Σ GᵀR⁻¹ν
        predicted = float(step @ gradient)  # ΔθᵀMΔθ
        if predicted <= COST_RTOL * abs(cost) and np.all(
            np.abs(step) <= PARAM_RTOL * np.maximum(np.abs(theta), typical)
        ):
            # √(ΔθᵀMΔθ): how far (in Cramér–Rao σ under R) the next step would still go
            sigma = np.sqrt(max(predicted, 0.0))
            return np.array(iterates), np.linalg.inv(m), np.array(costs), halvings, sigma
        for halving in range(11):  # θ + λΔθ, λ = 1, ½, …, 2⁻¹⁰, until J drops
            trial = theta + 0.5**halving * step
            y_trial = simulate_free(trial[None, :])[0]
            trial_cost = cost_of(y_trial)
            if trial_cost < cost:
                break
        else:
            raise RuntimeError("plain Gauss–Newton: no step length lowered the cost")
        halvings += halving
        # after an accepted step: |ΔJ| ≤ rtol·J and |Δθ_j| ≤ rtol·max(|θ_j|, typ_j)
        settled = abs(cost - trial_cost) <= COST_RTOL * abs(trial_cost) and np.all(
            np.abs(trial - theta) <= PARAM_RTOL * np.maximum(np.abs(trial), typical)
        )
        theta, y, cost = trial, y_trial, trial_cost
        iterates.append(theta.copy())
        costs.append(cost)
        if settled:
            break
    # the Cramér–Rao matrix needs the Jacobian at the final θ: one more batch
    steps = RELATIVE_STEP * np.maximum(np.abs(theta), typical)
    perturbed = simulate_free(theta + np.diag(steps))
    a = ((perturbed - y) * (root_weight / steps[:, None, None])).reshape(n_f, -1)
    m = a @ a.T
    gradient = a @ ((measured - y) * root_weight).ravel()
    sigma = np.sqrt(max(float(np.linalg.solve(m, gradient) @ gradient), 0.0))
    return np.array(iterates), np.linalg.inv(m), np.array(costs), halvings, sigma


def run_plain(model, data, r_diag):
    problem = OutputErrorProblem(model, data)  # only for the data matrix and θ layout
    simulator = problem.simulator
    return lambda: plain_gauss_newton(
        simulator,
        problem.measured,
        r_diag,
        problem.theta_start_full,
        problem.free_index,
        problem.typical,
    )


def run_solver(model, data, r_diag):
    def run():
        problem = OutputErrorProblem(model, data)
        objective = Objective(problem, r_diag, "fixed", Convergence())
        outcome = MNR().minimize(objective, problem.theta_start)
        return np.array(objective.theta_history), outcome

    return run


def run_estimate(model, data, r_diag):
    return lambda: estimate(model, data, MNR(), noise="fixed", R=r_diag)


def timed(clock, runner, repeat):
    best = None
    for _ in range(repeat):
        clock.reset()
        start = time.perf_counter()
        result = runner()
        wall = time.perf_counter() - start
        if best is None or wall < best[0]:
            best = (wall, clock.seconds, clock.trajectories, result)
    return best


def peak_memory(runner):
    """tracemalloc peak (bytes) of one call."""
    tracemalloc.start()
    tracemalloc.reset_peak()
    runner()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak


def case(n_steps: int, n_free: int, repeat: int, memory: bool) -> list[str]:
    model, data, r_diag, _ = benchmark(0, n_steps, n_free)
    simulate(model, data)  # compile outside the timings: single runs and batches
    warm = OutputErrorProblem(model, data)
    for size in (1, 2, 3):
        warm.run(np.repeat(warm.theta_start[None, :], size, axis=0))
    clock = SimulationClock()
    runners = {
        "plain GN": run_plain(model, data, r_diag),
        "MNR solver": run_solver(model, data, r_diag),
        "estimate(MNR)": run_estimate(model, data, r_diag),
    }
    results = {name: timed(clock, runner, repeat) for name, runner in runners.items()}
    plain_iterates, plain_cr, _, halvings, plain_sigma = results["plain GN"][3]
    mnr_iterates, _ = results["MNR solver"][3]
    est = results["estimate(MNR)"][3]
    problem = OutputErrorProblem(model, data)
    n_common = min(len(plain_iterates), len(mnr_iterates))
    deviation = np.max(
        np.abs(plain_iterates[:n_common] - mnr_iterates[:n_common])
        / np.maximum(np.abs(plain_iterates[:n_common]), problem.typical)
    )
    g_bytes = problem.n_samples * problem.n_outputs * problem.n_free * 8
    peaks = {}
    if memory:
        peaks = {name: peak_memory(runner) for name, runner in runners.items()}
    # Cramér–Rao σ: plain (forward differences) against estimate's (central differences)
    sigma_plain = np.sqrt(np.diag(plain_cr))
    sigma_est = est.std[problem.free_index]
    rows = []
    plain_wall, plain_sims = results["plain GN"][0], results["plain GN"][2]
    steps_taken = {
        "plain GN": len(plain_iterates) - 1,
        "MNR solver": len(mnr_iterates) - 1,
        "estimate(MNR)": len(est.cost_history) - 1,
    }
    for name, (wall, sim_s, sims, _) in results.items():
        peak = f"{peaks[name] / 2**20:.0f}" if name in peaks else "-"
        ratio = f"{peaks[name] / g_bytes:.2f}" if name in peaks else "-"
        same = "-" if name == "plain GN" else f"{deviation:.1e}"
        rows.append(
            f"| {problem.n_samples} | {problem.n_free} | {name} | {steps_taken[name]} | {same} | "
            f"{sims} | {wall:.3f} | {wall / plain_wall:.2f} | "
            f"{(wall / sims) / (plain_wall / plain_sims):.2f} | {sim_s / wall:.2f} | {peak} | "
            f"{ratio} |"
        )
    rows.append(
        f"<!-- N = {problem.n_samples}: G = {g_bytes / 2**20:.0f} MiB; plain GN "
        f"halvings: {halvings}, stopped {plain_sigma:.3g} σ (under R) short of the optimum "
        f"its last step predicts, estimate {est.optimality_sigma:.3g} σ (under R̂); "
        f"iterates compared: {n_common} (plain {len(plain_iterates)}, "
        f"MNR {len(mnr_iterates)}); estimate: {est.status}, {est.equivalent_evaluations} + "
        f"{est.accuracy_evaluations} evaluations, wall_time_s {est.wall_time_s:.3f}; "
        f"CR σ plain/estimate − 1: max {np.max(np.abs(sigma_plain / sigma_est - 1)):.1e} -->"
    )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--cases",
        nargs="+",
        default=["1000:22", "10000:22", "100000:20"],
        help="RK4 steps:free parameters of each row",
    )
    parser.add_argument("--repeat", type=int, default=3, help="best of this many runs (N ≤ 1e4)")
    parser.add_argument("--no-memory", action="store_true", help="skip the tracemalloc runs")
    args = parser.parse_args()
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=False
        ).stdout.strip()
    except OSError:
        commit = "?"
    print(f"commit {commit or '?'}; OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']}")
    print(
        "| N | free p. | method | steps | same iterates | sims | wall, s | ÷ plain GN | "
        "wall per sim ÷ plain's | sim share | peak MiB (tracemalloc) | peak ÷ G |"
    )
    print("|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for spec in args.cases:
        n_steps, n_free = (int(v) for v in spec.split(":"))
        repeat = args.repeat if n_steps <= 10000 else 1
        for row in case(n_steps, n_free, repeat, not args.no_memory):
            print(row, flush=True)


if __name__ == "__main__":
    main()
