"""flightid's MNR against a plain batched forward-difference Gauss–Newton.

The plain Gauss–Newton is written here in numpy and uses nothing of flightid's estimation
code, only its simulator. Per iteration: one ``Simulator.run`` of the batch
θ + δ_j e_j, j = 1 … n_f (δ_j = 10⁻⁶·max(|θ_j|, typical_j), the steps of ``MNR()``), the
forward-difference Jacobian G_j = (y(θ + δ_j e_j) − y(θ))/δ_j, the normal equations

    M = Σ_i G_iᵀ R⁻¹ G_i,   Δθ = M⁻¹ Σ_i G_iᵀ R⁻¹ ν_i,   ν = z − y(θ)

and one integration at θ + λΔθ, λ = 1 (then ½, ¼, … while the cost does not drop: the step
halving of MNR, without which the iterates part on this benchmark's seed 0). It runs to the
stop that ``estimate`` applies, in three stages, each timed (checkpoints of one run):

1. "MNR's stop": the tests of ``Convergence()`` as MNR applies them — after an accepted step
   |ΔJ| ≤ 10⁻³·J and |Δθ_j| ≤ 10⁻³·max(|θ_j|, typ_j); before a step, the same parameter
   test on the next step and its predicted drop ΔθᵀMΔθ ≤ 10⁻³·J. The integrations MNR
   spends (n_f + 1 per pass, plus one per halving). No Cramér–Rao matrix.
2. "≤ 0.02 σ, forward CR": ``estimate``'s rule — go on with full Gauss–Newton steps until
   the forward-difference step is ≤ 0.02 Cramér–Rao σ, √(ΔθᵀM̂Δθ) with M̂ weighted by the
   residuals' own R̂ = mean(ν²) [3.45] (the relative tests stop up to √(10⁻³·J) σ short,
   ≈ 28 σ at N = 10⁵; on this benchmark 0.1 σ at N = 10⁵); the Cramér–Rao matrix M⁻¹ from
   those forward differences.
3. "≤ 0.02 σ, central CR": and the Cramér–Rao matrix from central differences at the end
   point (the backward half, n_f integrations: (G⁺ + G⁻)/2), as ``estimate`` reports them.

Compared, on ``bench/peers.py``'s 6-DOF Navion benchmark (seed 0, R fixed at the true noise
variances):

* "MNR solver": ``MNR().minimize`` on flightid's ``Objective`` (the iterations only: no
  confirmation, no Cramér–Rao matrix) — against stage 1, the same iterates and stop;
* "estimate(MNR)": ``flightid.estimate(model, data, MNR(), noise="fixed", R=σ²)`` end to end:
  the model check, the same iterations, the confirmation (steps on forward differences while
  they are > 0.02 σ, then central differences at the end point, which must confirm ≤ 0.02 σ
  and give the Cramér–Rao bounds; ``flightid.estimation.confirm``), the information matrix,
  the covariance and the ``Estimate`` (``wall_time_s``, ``cost_history``,
  ``evaluation_history``) — against stage 3, the same iterates, the same stop and a
  Cramér–Rao matrix from the same differences. The issue-14 target: ≤ 1.3×.

Columns: "steps" (accepted Gauss–Newton steps), "same iterates" (largest
|θ_k(flightid) − θ_k(plain)| / max(|θ_k|, typ) over the common iterates; flightid's from
``Objective.record``: they agree to the rounding of normal equations against flightid's QR,
≈ cond²·ε), sims (``Simulator.run`` trajectories), wall s (best of ``--repeat``), "÷ plain
GN, same stop" (wall ÷ the plain stage it is compared with), wall per sim ÷ plain's (the
overhead per integration), sim share (time inside ``Simulator.run`` ÷ wall). The comment
under each case gives estimate's wall ÷ each plain stage, how far (σ) each stopped, and
the Cramér–Rao σ of both. Peak memory: ``tracemalloc`` peak (numpy's allocations included;
not RSS) during one more run of each, beside the size of the sensitivity array G
(N × n_o × n_f float64); the plain loop holds G, a weighted copy and the perturbed outputs
(its peak is on its last row). Wall times on a shared 2-core machine scatter; simulation
counts do not. One BLAS thread (``OPENBLAS_NUM_THREADS=1``).

Usage: ``python -P bench/gauss_newton_overhead.py [--cases 1000:22 10000:22 100000:20]
[--repeat 3] [--no-memory]`` (about 20 s for N = 10⁴ and 10⁵ with --no-memory on two quiet
cores at ba04428).
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
from flightid.simulation import Simulator, simulate  # noqa: E402
from peers import benchmark  # noqa: E402

RELATIVE_STEP = 1e-6  # MNR().relative_step
COST_RTOL = PARAM_RTOL = 1e-3  # Convergence() defaults
CONFIRM_SIGMA = 0.02  # Convergence().confirm_sigma


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


def plain_gauss_newton(simulator, measured, r_diag, theta_full, free_index, typical, clock):
    """The plain forward-difference Gauss–Newton with step halving (module docstring).

    Returns (iterates (K, n_f), Cramér–Rao matrix M⁻¹ from central differences at the last
    one, costs per iterate, halvings taken, σ of the last forward step, σ of the central
    step at the end, checkpoints {name: (wall s, trajectories, seconds integrating)}).
    """
    start = time.perf_counter()
    checkpoints = {}

    def checkpoint(name):
        checkpoints[name] = (time.perf_counter() - start, clock.trajectories, clock.seconds)

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

    def forward_jacobian(theta, y):
        # G_j = (y(θ + δ_j e_j) − y(θ)) / δ_j, as (n_f, N, n_o)
        steps = RELATIVE_STEP * np.maximum(np.abs(theta), typical)
        perturbed = simulate_free(theta + np.diag(steps))
        perturbed -= y
        perturbed /= steps[:, None, None]
        return perturbed, steps

    def normal_equations(g, y):
        a = (g * root_weight).reshape(n_f, -1)  # R^(-1/2) G, rows j
        m = a @ a.T  # M = Σ GᵀR⁻¹G
        gradient = a @ ((measured - y) * root_weight).ravel()  # Σ GᵀR⁻¹ν
        step = np.linalg.solve(m, gradient)  # Δθ = M⁻¹ Σ GᵀR⁻¹ν
        return m, step, float(step @ gradient)  # …, ΔθᵀMΔθ

    def sigma_of(g, step, y):
        # √(ΔθᵀM̂Δθ), M̂ weighted by the residuals' own R̂ = mean(ν²) [3.45] (as estimate's)
        r_hat = np.mean((measured - y) ** 2, axis=0)
        change = np.tensordot(step, g, axes=1)  # G_i Δθ, (N, n_o)
        return float(np.sqrt(np.sum(change**2 / r_hat)))

    def settle(theta, y, cost, step):
        # θ + λΔθ, λ = 1, ½, …, 2⁻¹⁰, until J drops
        for halving in range(11):
            trial = theta + 0.5**halving * step
            y_trial = simulate_free(trial[None, :])[0]
            trial_cost = cost_of(y_trial)
            if trial_cost < cost:
                return trial, y_trial, trial_cost, halving
        raise RuntimeError("plain Gauss–Newton: no step length lowered the cost")

    y = simulate_free(theta[None, :])[0]
    cost = cost_of(y)
    iterates, costs, halvings = [theta.copy()], [cost], 0
    g = None
    # 1. MNR's stop: the relative tests of 10⁻³
    for _ in range(500):
        g, steps = forward_jacobian(theta, y)
        m, step, predicted = normal_equations(g, y)
        if predicted <= COST_RTOL * abs(cost) and np.all(
            np.abs(step) <= PARAM_RTOL * np.maximum(np.abs(theta), typical)
        ):
            break
        g = None
        trial, y_trial, trial_cost, halving = settle(theta, y, cost, step)
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
    checkpoint("mnr stop")
    # 2. the confirmation's stop: a forward-difference step ≤ 0.02 σ (R̂), full steps
    for _ in range(50):
        if g is None:
            g, steps = forward_jacobian(theta, y)
            m, step, predicted = normal_equations(g, y)
        if sigma_of(g, step, y) <= CONFIRM_SIGMA:
            break
        g = None
        theta, y, cost, halving = settle(theta, y, cost, step)
        halvings += halving
        iterates.append(theta.copy())
        costs.append(cost)
    forward_sigma = sigma_of(g, step, y)
    np.linalg.inv(m)  # the Cramér–Rao matrix from these forward differences
    checkpoint("same stop, forward CR")
    # 3. central differences at the end point: the backward half, (G⁺ + G⁻)/2
    minus = simulate_free(theta - np.diag(steps))
    np.subtract(y, minus, out=minus)
    minus /= steps[:, None, None]
    g += minus
    g *= 0.5
    del minus
    m, step, _ = normal_equations(g, y)
    central_sigma = sigma_of(g, step, y)
    cramer_rao = np.linalg.inv(m)
    checkpoint("same stop, central CR")
    result = (np.array(iterates), cramer_rao, np.array(costs), halvings)
    return result + (forward_sigma, central_sigma, checkpoints)


def run_plain(model, data, r_diag, clock):
    problem = OutputErrorProblem(model, data)  # only for the data matrix and θ layout
    simulator = problem.simulator
    return lambda: plain_gauss_newton(
        simulator,
        problem.measured,
        r_diag,
        problem.theta_start_full,
        problem.free_index,
        problem.typical,
        clock,
    )


def run_solver(model, data, r_diag):
    def run():
        problem = OutputErrorProblem(model, data)
        objective = Objective(problem, r_diag, "fixed", Convergence())
        outcome = MNR().minimize(objective, problem.theta_start)
        return np.array(objective.theta_history), outcome

    return run


class IterateLog:
    """Wraps ``Objective.record``: the iterates of every objective (estimate's included)."""

    def __init__(self) -> None:
        self.thetas: list[np.ndarray] = []
        original = Objective.record
        log = self

        def record(objective, theta, cost):
            log.thetas.append(np.array(theta, dtype=float))
            return original(objective, theta, cost)

        Objective.record = record


def run_estimate(model, data, r_diag, log):
    def run():
        log.thetas = []
        est = estimate(model, data, MNR(), noise="fixed", R=r_diag)
        return est, np.array(log.thetas)

    return run


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


def _deviation(a: np.ndarray, b: np.ndarray, typical: np.ndarray) -> tuple[float, int]:
    """Largest |θ_k(a) − θ_k(b)| / max(|θ_k|, typ) over the common iterates, and their count."""
    n = min(len(a), len(b))
    return float(np.max(np.abs(a[:n] - b[:n]) / np.maximum(np.abs(a[:n]), typical))), n


def case(n_steps: int, n_free: int, repeat: int, memory: bool) -> list[str]:
    model, data, r_diag, _ = benchmark(0, n_steps, n_free)
    simulate(model, data)  # compile outside the timings: single runs and batches
    warm = OutputErrorProblem(model, data)
    for size in (1, 2, 3):
        warm.run(np.repeat(warm.theta_start[None, :], size, axis=0))
    clock = SimulationClock()
    log = IterateLog()
    runners = {
        "plain GN": run_plain(model, data, r_diag, clock),
        "MNR solver": run_solver(model, data, r_diag),
        "estimate(MNR)": run_estimate(model, data, r_diag, log),
    }
    results = {name: timed(clock, runner, repeat) for name, runner in runners.items()}
    plain_iterates, plain_cr, _, halvings, forward_sigma, central_sigma, checkpoints = results[
        "plain GN"
    ][3]
    mnr_iterates, _ = results["MNR solver"][3]
    est, est_iterates = results["estimate(MNR)"][3]
    problem = OutputErrorProblem(model, data)
    g_bytes = problem.n_samples * problem.n_outputs * problem.n_free * 8
    peaks = {}
    if memory:
        peaks = {name: peak_memory(runner) for name, runner in runners.items()}
    # Cramér–Rao σ: plain's (central differences at its end point) against estimate's
    sigma_plain = np.sqrt(np.diag(plain_cr))
    sigma_est = est.std[problem.free_index]
    n_mnr = len(mnr_iterates)
    # rows: (name, steps, iterates compared with, wall, sims, seconds integrating, reference)
    plain_at = {name: (wall, sims, sim_s) for name, (wall, sims, sim_s) in checkpoints.items()}
    rows_data = [
        ("plain GN, MNR's stop", n_mnr - 1, None, *plain_at["mnr stop"], None),
        (
            "plain GN, ≤ 0.02 σ, forward CR",
            len(plain_iterates) - 1,
            None,
            *plain_at["same stop, forward CR"],
            None,
        ),
        (
            "plain GN, ≤ 0.02 σ, central CR",
            len(plain_iterates) - 1,
            None,
            *plain_at["same stop, central CR"],
            None,
        ),
        (
            "MNR solver",
            n_mnr - 1,
            mnr_iterates,
            results["MNR solver"][0],
            results["MNR solver"][2],
            results["MNR solver"][1],
            "mnr stop",
        ),
        (
            "estimate(MNR)",
            len(est.cost_history) - 1,
            est_iterates,
            results["estimate(MNR)"][0],
            results["estimate(MNR)"][2],
            results["estimate(MNR)"][1],
            "same stop, central CR",
        ),
    ]
    rows = []
    for name, steps, iterates, wall, sims, sim_s, reference in rows_data:
        key = {"MNR solver": "MNR solver", "estimate(MNR)": "estimate(MNR)"}.get(name)
        peak = f"{peaks[key] / 2**20:.0f}" if key in peaks else "-"
        peak_ratio = f"{peaks[key] / g_bytes:.2f}" if key in peaks else "-"
        if name == "plain GN, ≤ 0.02 σ, central CR" and "plain GN" in peaks:
            peak = f"{peaks['plain GN'] / 2**20:.0f}"
            peak_ratio = f"{peaks['plain GN'] / g_bytes:.2f}"
        same, ratio, per_sim = "-", "-", "-"
        if reference is not None:
            ref_wall, ref_sims, _ = plain_at[reference]
            deviation, _ = _deviation(plain_iterates, iterates, problem.typical)
            same = f"{deviation:.1e}"
            ratio = f"{wall / ref_wall:.2f}"
            per_sim = f"{(wall / sims) / (ref_wall / ref_sims):.2f}"
        rows.append(
            f"| {problem.n_samples} | {problem.n_free} | {name} | {steps} | {same} | {sims} | "
            f"{wall:.3f} | {ratio} | {per_sim} | {sim_s / wall:.2f} | {peak} | {peak_ratio} |"
        )
    est_wall = results["estimate(MNR)"][0]
    # the requirement: within 1.3 × the plain loop with the same iterates and stop
    for name, wall, reference in (
        ("MNR solver", results["MNR solver"][0], "mnr stop"),
        ("estimate(MNR)", est_wall, "same stop, central CR"),
    ):
        ratio = wall / plain_at[reference][0]
        rows.append(
            f"<!-- {'PASS' if ratio <= 1.3 else 'FAIL'}: {name} wall ≤ 1.3 × plain GN "
            f"({reference}) at N = {problem.n_samples}: {ratio:.2f} × -->"
        )
    others = ", ".join(
        f"{name} {est_wall / plain_at[name][0]:.2f}"
        for name in ("mnr stop", "same stop, forward CR", "same stop, central CR")
    )
    final_deviation = float(
        np.max(
            np.abs(plain_iterates[-1] - est.values[problem.free_index])
            / np.maximum(np.abs(plain_iterates[-1]), problem.typical)
        )
    )
    rows.append(
        f"<!-- N = {problem.n_samples}: G = {g_bytes / 2**20:.0f} MiB; estimate(MNR) wall ÷ "
        f"plain GN's at: {others}. Plain GN: halvings {halvings}, iterates {len(plain_iterates)}"
        f" (MNR solver {n_mnr}, estimate {len(est_iterates)}), last forward step "
        f"{forward_sigma:.3g} σ, central step at its end {central_sigma:.3g} σ (R̂); "
        f"estimate: {est.status}, {est.optimality_sigma:.3g} σ, "
        f"{est.equivalent_evaluations} + {est.accuracy_evaluations} evaluations, wall_time_s "
        f"{est.wall_time_s:.3f}, end point vs plain's {final_deviation:.1e}; CR σ "
        f"plain/estimate − 1: max {np.max(np.abs(sigma_plain / sigma_est - 1)):.1e} -->"
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
        "| N | free p. | method | steps | same iterates | sims | wall, s | ÷ plain GN, same stop | "
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
