"""Peers on a 6-DOF benchmark: flightid MNR and MNRES against scipy, lmfit and DFO-LS.

    python -P bench/peers.py --all          # everything below, about 15 min on 2 quiet cores
    python -P bench/peers.py [--seeds 8] [--quick] [--variant base|hard40|user] [--scaling]
                             [--memory] [--cases [CASE ...]] [--load N]

The benchmark: the Navion 6-DOF model built by ``flightid.aircraft.six_dof_model``
(9 states u, v, w, p, q, r, l_xz, l_yz, l_zz; Nelson's longitudinal and lateral derivatives,
22 free aerodynamic parameters), trimmed at 53.6 m/s, excited by elevator, aileron and rudder
doublets; 1000 RK4 steps of 0.02 s; 8 outputs (V, α, β, Θ, Φ, p, q, r) with seeded Gaussian
noise. Seed s draws the noise and a start θ₀ = θ_true·(1 + a u) + 0.01 u', u, u' ~ U(−1, 1).

Every method minimises the same weighted cost J = Σ νᵀR⁻¹ν (R = diag σ², fixed) through the
same simulator: ``flightid.simulation.Simulator.run`` is wrapped here, so every integration of
the system, by any method, is timed and its cost recorded in order. "sims to J*+1" is the
number of simulations until the first one whose cost is ≤ J* + 1 (J* = the lowest cost any
method reached on that seed), likewise for J*+0.01; "-" means never. "sim share" is the time
spent in ``Simulator.run`` over the method's wall time (cost recording excluded).

Peers: scipy ``least_squares`` (lm, trf; 2-point Jacobian, ftol = xtol = 1e-8), lmfit
(``leastsq``), DFO-LS (``dfols.solve``, variables scaled by the parameters' typical values).
A peer whose package is missing is skipped with a printed reason (``pip install -e '.[bench]'``).

``--variant hard40``: the hard 40-parameter variant (``benchmark(seed, variant="hard40")``):
the 22 derivatives + CY_da (true 0) + output biases b_y of the 8 outputs (true values
``HARD40_BIAS_TRUTH``, start 0) + the initial values of the 9 states (true: the trim; start:
trim + U(−1, 1)·``HARD40_STATE_TYPICAL``/2) = 40 free parameters.

``--variant user``: the base benchmark with the model written as a user model module
(``bench/navion_user_model.py``), MNR and MNRES against scipy lm and a plain Gauss–Newton on
the hand-written simulator of ``bench/kernel.py`` (``bench/user_module_peers.py``); prints
MNR wall / plain GN wall (target ≤ 1.3) and MNRES against scipy lm. ``--load N`` runs N
busy-loop processes beside the measurement (any variant; ``--variant user`` takes several
counts, ``--load 0 5``, one table each).

``--scaling`` adds the table over N (1e3, 1e4, 1e5 samples, same 20 s manoeuvre; ``--sizes``)
and the number of free parameters (5, 10, 20: the first n of the 22, the rest fixed at the
truth; 40: the hard40 variant) for MNR, MNRES and scipy lm on seed 0; it is slow. At sizes of
``LARGE_N`` steps and more only the ``--large-free`` counts run (default 20).

Each seeds table ends with a per-seed table (sims to J*+0.01 / wall per method) and the
issue-14 checks as PASS/FAIL lines; the scaling table with MNRES ≤ MNR (sims to J*+0.01).

``--memory``: peak memory at N = 1e5, 20 free parameters, of MNR, MNRES and scipy lm, each in
its own subprocess: the increase of the peak resident set over a run of at most 3 passes, after
data, compilation and one simulation (Linux: VmHWM reset just before the run; elsewhere
ru_maxrss); against the sensitivity array N·n_o·n_f·8 bytes.

``--cases``: the standard cases (``STANDARD_CASES``), MNR and MNRES: process time of
``flightid run`` (cold: empty NUMBA_CACHE_DIR; warm: second run) and the warm in-process
estimate time (``Estimate.wall_time_s``).
"""

from __future__ import annotations

import os

# one BLAS thread for every method: several threads on 2 shared cores distort timings
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

from flightid.aircraft import (  # noqa: E402
    AeroModel,
    navion,
    navion_longitudinal_aero,
    six_dof_model,
    trim_level_flight,
)
from flightid.aircraft.library import NAVION_TRIM_SPEED  # noqa: E402
from flightid.data import FlightData  # noqa: E402
from flightid.estimation import MNR, MNRES, Convergence, OutputErrorProblem, estimate  # noqa: E402
from flightid.model import Parameter, Parameters  # noqa: E402
from flightid.simulation import Simulator, simulate  # noqa: E402

# Nelson (1998) App. B, Navion lateral derivatives (per rad), as in tests/test_aircraft_equations.py
NAVION_LATERAL = {
    "CY_beta": -0.564, "CY_dr": 0.157, "Cl_beta": -0.074, "Cl_phat": -0.410, "Cl_rhat": 0.107,
    "Cl_da": -0.134, "Cl_dr": 0.107, "Cn_beta": 0.071, "Cn_phat": -0.0575, "Cn_rhat": -0.125,
    "Cn_da": -0.0035, "Cn_dr": -0.072,
}  # fmt: skip
LATERAL = {
    "CY": ["beta", "dr"],
    "Cl": ["beta", "phat", "rhat", "da", "dr"],
    "Cn": ["beta", "phat", "rhat", "da", "dr"],
}
# 18 further terms (true value 0) for the 40-parameter variant
EXTRA = {
    "CY": ["1", "phat", "rhat", "da", "alpha*beta"],
    "Cl": ["1", "alpha*beta", "alpha*da"],
    "Cn": ["1", "alpha*beta", "alpha*da"],
    "CD": ["de", "qhat", "beta^2", "alpha^2"],
    "CL": ["beta^2", "alpha^2"],
    "Cm": ["beta^2"],
}
OUTPUTS8 = ("V", "alpha", "beta", "theta", "phi", "p", "q", "r")
# noise standard deviations of the 8 outputs: m/s, rad (α β Θ Φ), rad/s (p q r)
SIGMA8 = np.array([0.1, 0.002, 0.002, 0.002, 0.002, 0.005, 0.005, 0.005])
DURATION_S = 20.0


def _doublet(t, start, width, amplitude):
    return amplitude * (
        ((t >= start) & (t < start + width)).astype(float)
        - ((t >= start + width) & (t < start + 2 * width)).astype(float)
    )


def benchmark(
    seed: int,
    n_steps: int = 1000,
    n_free: int = 22,
    spread: float = 0.5,
    variant: str = "base",
):
    """(model at the seeded start, data, R diagonal, truth) of the 6-DOF benchmark.

    ``variant="base"``: the first ``n_free`` aerodynamic parameters free (22: all of Nelson's;
    > 22 adds the 18 ``EXTRA`` terms). ``variant="hard40"``: 40 free parameters, see
    ``HARD40``; ``n_free`` is ignored.
    """
    if variant == "hard40":
        return _hard40(seed, n_steps, spread)
    if variant != "base":
        raise ValueError(f"variant: expected one of {VARIANTS}, got {variant!r}")
    lon, lon_values = navion_longitudinal_aero()
    spec = {k: list(v) for k, v in {**lon.spec, **LATERAL}.items()}
    if n_free > 22:
        for coefficient, terms in EXTRA.items():
            spec[coefficient].extend(terms)
    aero = AeroModel(spec)
    values = {**lon_values, **NAVION_LATERAL}
    names = aero.parameter_names
    truth = np.array([values.get(n, 0.0) for n in names])
    full = six_dof_model(navion(), aero, aero.parameters(dict(zip(names, truth, strict=True))))
    trim = trim_level_flight(full, NAVION_TRIM_SPEED)
    t, inputs = _manoeuvre(full, trim, n_steps)
    truth_model = six_dof_model(
        navion(),
        aero,
        aero.parameters(dict(zip(names, truth, strict=True))),
        outputs=OUTPUTS8,
        x0=tuple(trim.x),
    )
    clean = simulate(truth_model, FlightData(t, inputs))
    rng = np.random.default_rng(seed)
    noisy = clean + rng.normal(size=clean.shape) * SIGMA8
    data = FlightData(t, inputs, {n: noisy[:, k] for k, n in enumerate(OUTPUTS8)})
    free = np.arange(len(names)) < min(n_free, len(names))
    start = truth * (1 + spread * rng.uniform(-1, 1, truth.size)) + 0.01 * rng.uniform(
        -1, 1, truth.size
    )
    start = np.where(free, start, truth)
    parameters = Parameters(
        Parameter(n, float(v), free=bool(f), scale=max(abs(tv), 0.05))
        for n, v, f, tv in zip(names, start, free, truth, strict=True)
    )
    model = six_dof_model(navion(), aero, parameters, outputs=OUTPUTS8, x0=tuple(trim.x))
    return model, data, SIGMA8**2, truth


def _manoeuvre(full, trim, n_steps):
    """Time (s) and inputs of the 20 s doublet manoeuvre about the trim, ``n_steps`` RK4 steps."""
    dt = DURATION_S / n_steps
    t = np.arange(n_steps + 1) * dt
    inputs = {n: np.full(t.shape, trim.inputs[n]) for n in full.inputs}
    inputs["de"] = inputs["de"] + _doublet(t, 1.0, 0.5, 0.03) + _doublet(t, 11.0, 1.0, -0.02)
    inputs["da"] = inputs["da"] + _doublet(t, 3.0, 1.0, 0.06) + _doublet(t, 14.0, 0.5, -0.05)
    inputs["dr"] = inputs["dr"] + _doublet(t, 6.5, 1.0, 0.06) + _doublet(t, 16.5, 0.7, 0.04)
    return t, inputs


def _hard40(seed: int, n_steps: int, spread: float):
    """The 40-parameter variant (``HARD40``): derivatives, output biases, initial states."""
    import numba

    from flightid.model import StateSpaceModel

    lon, lon_values = navion_longitudinal_aero()
    spec = {k: list(v) for k, v in {**lon.spec, **LATERAL}.items()}
    for coefficient, terms in HARD40_EXTRA_TERMS.items():
        spec[coefficient].extend(terms)
    aero = AeroModel(spec)
    values = {**lon_values, **NAVION_LATERAL}
    aero_names = aero.parameter_names
    aero_truth = np.array([values.get(n, 0.0) for n in aero_names])
    base = six_dof_model(
        navion(),
        aero,
        aero.parameters(dict(zip(aero_names, aero_truth, strict=True))),
        outputs=OUTPUTS8,
    )
    trim = trim_level_flight(base, NAVION_TRIM_SPEED)
    t, inputs = _manoeuvre(base, trim, n_steps)
    n_x, n_y, n_a = len(base.states), len(base.outputs), len(aero_names)
    # θ = (aerodynamic parameters, output biases b_y, initial states x0)
    bias_names = [f"by_{o}" for o in base.outputs]
    x0_names = [f"x0_{s}" for s in base.states]
    names = [*aero_names, *bias_names, *x0_names]
    truth = np.concatenate([aero_truth, HARD40_BIAS_TRUTH, np.asarray(trim.x, float)])
    h_base = base.h_out if hasattr(base.h_out, "py_func") else numba.njit(base.h_out)

    def h_biased(t, x, u, theta, out):
        h_base(t, x, u, theta, out)
        for j in range(n_y):
            # y_j = h_j + b_y,j
            out[j] = out[j] + theta[n_a + j]

    def model_at(theta):
        # typical values: |truth| with floors (aero 0.05; biases σ of the output; states below)
        typical = np.concatenate(
            [np.maximum(np.abs(aero_truth), 0.05), SIGMA8, HARD40_STATE_TYPICAL]
        )
        parameters = Parameters(
            Parameter(n, float(v), free=True, scale=float(s))
            for n, v, s in zip(names, theta, typical, strict=True)
        )
        return StateSpaceModel(
            base.states, base.inputs, base.outputs, base.f, h_biased, parameters,
            x0=tuple(x0_names),
            name="navion 6-DOF hard40",
        )  # fmt: skip

    clean = simulate(model_at(truth), FlightData(t, inputs))
    rng = np.random.default_rng(seed)
    noisy = clean + rng.normal(size=clean.shape) * SIGMA8
    data = FlightData(t, inputs, {n: noisy[:, k] for k, n in enumerate(OUTPUTS8)})
    # start: derivatives as in the base variant; biases 0; states trim + U(−1, 1)·typical/2
    start_aero = aero_truth * (1 + spread * rng.uniform(-1, 1, n_a)) + 0.01 * rng.uniform(
        -1, 1, n_a
    )
    start_x0 = np.asarray(trim.x, float) + 0.5 * HARD40_STATE_TYPICAL * rng.uniform(-1, 1, n_x)
    start = np.concatenate([start_aero, np.zeros(n_y), start_x0])
    return model_at(start), data, SIGMA8**2, truth


VARIANTS = ("base", "hard40")
# a simulation of 1e5 RK4 steps takes ~0.5 s: the scaling table runs few free counts there
LARGE_N = 50_000
# hard40 = 22 Nelson derivatives + CY_da (true 0: Nelson gives none) + 8 output biases + the
# initial values of the 9 states = 40 free parameters
HARD40_EXTRA_TERMS = {"CY": ["da"]}
# true output biases of V (m/s), α, β, Θ, Φ (rad), p, q, r (rad/s)
HARD40_BIAS_TRUTH = np.array([0.3, 0.01, -0.005, 0.008, -0.006, 0.003, -0.002, 0.002])
# typical size of the initial states u, v, w (m/s), p, q, r (rad/s), l_xz, l_yz, l_zz (-):
# parameter scale and the width of the start's offset from the trim
HARD40_STATE_TYPICAL = np.array([1.0, 0.5, 0.5, 0.02, 0.02, 0.02, 0.02, 0.02, 0.02])


class Recorder:
    """Wraps ``Simulator.run``: times every call and records each trajectory's cost J."""

    def __init__(self) -> None:
        self.measured = None
        self.weight = None
        self.costs: list[float] = []
        self.sim_s = 0.0
        self.record_s = 0.0
        self._original = Simulator.run
        recorder = self

        def run(simulator, thetas):
            start = time.perf_counter()
            batch = recorder._original(simulator, thetas)
            middle = time.perf_counter()
            recorder.sim_s += middle - start
            if recorder.measured is not None:
                # J = Σ_k Σ_i (z_i(k) − y_i(k))² / σ_i² per trajectory of the batch
                resid = (recorder.measured[None] - batch.outputs) * recorder.weight
                costs = np.sum(resid.reshape(resid.shape[0], -1) ** 2, axis=1)
                recorder.costs.extend(np.where(np.isfinite(costs), costs, np.inf).tolist())
            recorder.record_s += time.perf_counter() - middle
            return batch

        Simulator.run = run

    def reset(self, measured, r_diag) -> None:
        self.measured = measured
        self.weight = 1.0 / np.sqrt(r_diag)
        self.costs = []
        self.sim_s = 0.0
        self.record_s = 0.0


def _flightid(solver, budget):
    def run(model, data, r_diag, problem):
        result = estimate(
            model,
            data,
            solver,
            noise="fixed",
            R=r_diag,
            convergence=Convergence(max_iterations=500, max_evaluations=budget),
        )
        return result.cost

    return run


def _residual_function(problem, r_diag):
    weight = 1.0 / np.sqrt(r_diag)

    def residuals(theta):
        return ((problem.measured - problem.outputs(theta[None, :])[0]) * weight).ravel()

    return residuals


def _scipy(lsq_method, budget):
    def run(model, data, r_diag, problem):
        solution = least_squares(
            _residual_function(problem, r_diag),
            problem.theta_start,
            method=lsq_method,
            ftol=1e-8,
            xtol=1e-8,
            x_scale=problem.typical,
            max_nfev=budget,
        )
        return float(np.sum(solution.fun**2))

    return run


def _lmfit(budget):
    import lmfit

    def run(model, data, r_diag, problem):
        residuals = _residual_function(problem, r_diag)
        params = lmfit.Parameters()
        for i, value in enumerate(problem.theta_start):
            params.add(f"p{i}", value=float(value))

        def objective(p):
            return residuals(np.array([p[f"p{i}"].value for i in range(len(p))]))

        out = lmfit.minimize(
            objective, params, method="leastsq", max_nfev=budget, ftol=1e-8, xtol=1e-8
        )
        return float(np.sum(np.asarray(out.residual) ** 2))

    return run


def _dfols(budget):
    import dfols

    def run(model, data, r_diag, problem):
        residuals = _residual_function(problem, r_diag)
        typical = problem.typical
        # variables in units of their typical size; DFO-LS's default first radius,
        # 0.1·max|x0|, is 5.4 typical sizes on hard40 (the initial airspeed u0 ≈ 54 m/s with a
        # typical size of 1 m/s), whose interpolation points make its model singular after 41
        # simulations (exit -3 on every seed): start at 0.1 typical sizes instead, as on the
        # base variant (where 0.1·max|x0| ≈ 0.1–0.2)
        solution = dfols.solve(
            lambda z: residuals(z * typical),
            problem.theta_start / typical,
            maxfun=budget,
            rhobeg=0.1,
            rhoend=1e-8,
        )
        if solution.flag not in (0, 1):  # 0 success, 1 budget reached
            print(f"<!-- DFO-LS exit {solution.flag}: {solution.msg} -->")
        return float(np.sum(np.asarray(solution.resid) ** 2))

    return run


def methods(budget: int):
    """(name, runner or None, reason skipped)."""
    rows = [
        ("MNR", _flightid(MNR(), budget), ""),
        ("MNRES", _flightid(MNRES(), budget), ""),
        ("scipy lm", _scipy("lm", budget), ""),
        ("scipy trf", _scipy("trf", budget), ""),
    ]
    for name, module, factory in (("lmfit", "lmfit", _lmfit), ("DFO-LS", "dfols", _dfols)):
        try:
            __import__(module)
        except ImportError as error:
            rows.append((name, None, f"{module} not installed ({error})"))
        else:
            rows.append((name, factory(budget), ""))
    return rows


def run_one(recorder, runner, model, data, r_diag):
    problem = OutputErrorProblem(model, data)
    recorder.reset(problem.measured, r_diag)
    start = time.perf_counter()
    try:
        cost = runner(model, data, r_diag, problem)
    except Exception as error:  # a peer that gives up (lmfit on a NaN residual) is a result
        print(
            f"<!-- {getattr(runner, '__name__', 'method')} stopped: {type(error).__name__}: "
            f"{str(error)[:120]} -->"
        )
        finite = [c for c in recorder.costs if np.isfinite(c)]
        cost = min(finite) if finite else float("inf")
    wall = time.perf_counter() - start - recorder.record_s
    recorder.measured = None  # simulations outside a method's run are not recorded
    return {
        "cost": cost,
        "history": np.array(recorder.costs),
        "wall": wall,
        "share": recorder.sim_s / wall if wall > 0 else float("nan"),
        "sims": len(recorder.costs),
    }


def _first_below(history, level):
    hits = np.flatnonzero(history <= level)
    return int(hits[0]) + 1 if hits.size else None


def _fmt(value):
    return "-" if value is None else str(value)


def seeds_table(recorder, seeds, budget, n_steps, variant="base"):
    runs = methods(budget)
    for name, runner, reason in runs:
        if runner is None:
            print(f"skipped {name}: {reason}")
    active = [(n, r) for n, r, _ in runs if r is not None]
    per_method = {n: [] for n, _ in active}
    print(
        "| seed | method | sims to J*+1 | sims to J*+0.01 | sims total | final J − J* | "
        "wall, s | sim share |"
    )
    print("|---:|---|---:|---:|---:|---:|---:|---:|")
    for seed in seeds:
        model, data, r_diag, _ = benchmark(seed, n_steps, variant=variant)
        simulate(model, data)  # compile outside the timings
        results = {name: run_one(recorder, runner, model, data, r_diag) for name, runner in active}
        j_star = min(float(np.min(r["history"])) for r in results.values())
        for name, r in results.items():
            to1 = _first_below(r["history"], j_star + 1)
            to001 = _first_below(r["history"], j_star + 0.01)
            per_method[name].append(
                (to1, to001, r["sims"], r["cost"] - j_star, r["wall"], r["share"])
            )
            print(
                f"| {seed} | {name} | {_fmt(to1)} | {_fmt(to001)} | {r['sims']} | "
                f"{r['cost'] - j_star:.3g} | {r['wall']:.3f} | {r['share']:.2f} |"
            )
        print(f"<!-- seed {seed}: J* = {j_star:.6g}, N = {n_steps + 1} samples -->")
    print()
    print(
        "| method | median sims to J*+1 | median sims to J*+0.01 (reached) | median sims total | "
        "median final J − J* | median wall, s | median sim share |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")

    def median(values):
        # seeds that never reached the level count as +∞ in the median
        values = [np.inf if v is None else v for v in values]
        m = statistics.median(values)
        return "-" if not np.isfinite(m) else f"{m:g}"

    for name, rows in per_method.items():
        reached = sum(r[1] is not None for r in rows)
        print(
            f"| {name} | {median([r[0] for r in rows])} | "
            f"{median([r[1] for r in rows])} ({reached}/{len(rows)}) | "
            f"{median([r[2] for r in rows])} | {statistics.median(r[3] for r in rows):.3g} | "
            f"{statistics.median(r[4] for r in rows):.3f} | "
            f"{statistics.median(r[5] for r in rows):.2f} |"
        )
    per_seed_table(per_method, seeds)
    return per_method


def per_seed_table(per_method, seeds) -> None:
    """Sims to J*+0.01 / wall (s) per seed and method, and the issue-14 checks as PASS/FAIL."""
    names = list(per_method)
    print()
    print("| seed | " + " | ".join(f"{n}: sims to J*+0.01 / wall, s" for n in names) + " |")
    print("|---:|" + "---:|" * len(names))
    for i, seed in enumerate(seeds):
        cells = [f"{_fmt(per_method[n][i][1])} / {per_method[n][i][4]:.3f}" for n in names]
        print(f"| {seed} | " + " | ".join(cells) + " |")
    print()
    for line in seed_checks(per_method):
        print(line)


def _inf(value):
    return np.inf if value is None else value


def seed_checks(per_method) -> list[str]:
    """The issue-14 part-3 checks on a seeds table, as 'PASS|FAIL: …' lines."""
    lines = []

    def verdict(ok, text):
        lines.append(f"{'PASS' if ok else 'FAIL'}: {text}")

    mnres, mnr, lm = (per_method.get(n) for n in ("MNRES", "MNR", "scipy lm"))
    if mnres is None:
        return lines
    sims = [_inf(r[1]) for r in mnres]
    verdict(
        all(np.isfinite(sims)),
        f"MNRES reaches J*+0.01 on every seed ({sum(np.isfinite(sims))}/{len(sims)})",
    )
    if lm is not None:
        lm_sims = [_inf(r[1]) for r in lm]
        median_mnres, median_lm = statistics.median(sims), statistics.median(lm_sims)
        verdict(
            median_mnres <= 0.7 * median_lm,
            f"median MNRES sims to J*+0.01 ≤ 0.7 × median scipy lm's "
            f"({median_mnres:g} vs 0.7 × {median_lm:g} = {0.7 * median_lm:g})",
        )
        worse = [i for i, (a, b) in enumerate(zip(sims, lm_sims, strict=True)) if a > b]
        verdict(
            not worse,
            "MNRES sims to J*+0.01 ≤ scipy lm's on every seed"
            + (f" (more on seed index {worse})" if worse else ""),
        )
    if mnr is not None:
        slower = [i for i, (a, b) in enumerate(zip(mnres, mnr, strict=True)) if a[4] > b[4]]
        verdict(
            not slower,
            "MNRES wall ≤ MNR wall on every seed"
            + (f" (slower on seed index {slower})" if slower else ""),
        )
    return lines


def scaling_table(recorder, budget, sizes, free_counts, large_free=(20,)):
    """Sizes of ``LARGE_N`` samples and more run only the free counts ``large_free``."""
    chosen = [
        ("MNR", _flightid(MNR(), budget)),
        ("MNRES", _flightid(MNRES(), budget)),
        ("scipy lm", _scipy("lm", budget)),
    ]
    print()
    print("| N | free parameters | method | sims to J*+0.01 | sims total | wall, s | sim share |")
    print("|---:|---:|---|---:|---:|---:|---:|")
    checks = []
    for n_steps in sizes:
        counts = [n for n in free_counts if n in large_free] if n_steps >= LARGE_N else free_counts
        for n_free in counts:
            # 40 free: the hard40 variant (derivatives, output biases, initial states)
            variant = "hard40" if n_free == 40 else "base"
            model, data, r_diag, _ = benchmark(0, n_steps, n_free, variant=variant)
            simulate(model, data)
            results = {n: run_one(recorder, r, model, data, r_diag) for n, r in chosen}
            j_star = min(float(np.min(r["history"])) for r in results.values())
            reached = {}
            for name, r in results.items():
                to001 = _first_below(r["history"], j_star + 0.01)
                reached[name] = to001
                print(
                    f"| {n_steps} | {n_free} | {name} | {_fmt(to001)} | {r['sims']} | "
                    f"{r['wall']:.3f} | {r['share']:.2f} |"
                )
            a, b = _inf(reached["MNRES"]), _inf(reached["MNR"])
            checks.append(
                f"{'PASS' if a <= b else 'FAIL'}: N = {n_steps + 1}, {n_free} free: MNRES sims "
                f"to J*+0.01 ≤ MNR's ({_fmt(reached['MNRES'])} vs {_fmt(reached['MNR'])})"
            )
    print()
    for line in checks:
        print(line)


MEMORY_METHODS = ("MNR", "MNRES", "scipy lm")
MEMORY_FREE = 20
MEMORY_BUDGET = 3 * (MEMORY_FREE + 1) + 6  # simulations: ~3 Jacobians (the peak is in each)


def _memory_runner(name: str, budget: int):
    if name == "scipy lm":
        return _scipy("lm", budget)
    solver = {"MNR": MNR, "MNRES": MNRES}[name]()

    def run(model, data, r_diag, problem):
        result = estimate(
            model,
            data,
            solver,
            noise="fixed",
            R=r_diag,
            convergence=Convergence(max_iterations=3, max_evaluations=budget),
        )
        return result.cost

    return run


def _status_kib(field: str) -> int | None:
    """A ``VmRSS`` / ``VmHWM`` entry of /proc/self/status, KiB (None off Linux)."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith(field + ":"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def _reset_peak_rss() -> bool:
    """Reset the process's peak resident set (VmHWM) to its current size: Linux ≥ 4.0,
    ``echo 5 > /proc/self/clear_refs``. False where that is not possible."""
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as refs:
            refs.write("5")
    except OSError:
        return False
    return _status_kib("VmHWM") is not None


def memory_one(name: str, n_steps: int) -> dict:
    """Peak resident-memory increase of one short run of ``name``.

    Everything compiled and the data built before the baseline: a warm-up run on a record of
    min(N, 5000) steps of the same model (long enough for the parallel kernels), then the
    benchmark at ``n_steps`` and one simulation. The peak is the kernel's high-water mark
    VmHWM, reset to the current resident set just before the run (so a higher peak of the
    set-up — a compilation, the data — cannot hide the run's); where that reset is not
    available, the increase of ``ru_maxrss``, which such an earlier peak hides (a zero
    increase is then reported as unmeasured, not as a pass).
    """
    import resource

    runner = _memory_runner(name, MEMORY_BUDGET)
    small = benchmark(0, min(n_steps, 5000), MEMORY_FREE)
    runner(small[0], small[1], small[2], OutputErrorProblem(small[0], small[1]))
    model, data, r_diag, _ = benchmark(0, n_steps, MEMORY_FREE)
    simulate(model, data)
    problem = OutputErrorProblem(model, data)
    if _reset_peak_rss():
        method = "VmHWM after a reset"
        before = _status_kib("VmRSS")
        runner(model, data, r_diag, problem)
        after = _status_kib("VmHWM")
    else:
        method = "ru_maxrss"
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux
        runner(model, data, r_diag, problem)
        after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    n_samples = data.n_samples
    return {
        "method": name,
        "n_samples": n_samples,
        "peak_increase_bytes": (after - before) * 1024,
        "baseline_bytes": before * 1024,
        "sensitivity_bytes": n_samples * len(OUTPUTS8) * MEMORY_FREE * 8,
        "measured_by": method,
    }


def memory_table(n_steps: int) -> list[str]:
    """One subprocess per method (peaks do not mix); the table and the part-4 check."""
    import json
    import subprocess
    import sys

    rows = []
    for name in MEMORY_METHODS:
        done = subprocess.run(
            [sys.executable, "-P", __file__, "--memory-one", name, "--memory-steps", str(n_steps)],
            capture_output=True,
            text=True,
            check=False,
        )
        lines = [ln for ln in done.stdout.splitlines() if ln.startswith("{")]
        if done.returncode != 0 or not lines:
            print(f"memory {name}: failed (exit {done.returncode}): {done.stderr.strip()[-400:]}")
            continue
        rows.append(json.loads(lines[-1]))
    print()
    print(
        f"Peak memory, {MEMORY_FREE} free parameters, one subprocess per method: increase of "
        "the process's peak resident set (VmHWM reset just before the run; elsewhere "
        "ru_maxrss) over its value after data, compilation and one simulation; "
        f"{MEMORY_BUDGET} simulations at most (3 passes)."
    )
    print()
    print("| N | method | peak increase, MB | sensitivity array N·n_o·n_f·8, MB | ratio |")
    print("|---:|---|---:|---:|---:|")
    lines = []
    for row in rows:
        ratio = row["peak_increase_bytes"] / row["sensitivity_bytes"]
        print(
            f"| {row['n_samples']} | {row['method']} | {row['peak_increase_bytes'] / 1e6:.1f} | "
            f"{row['sensitivity_bytes'] / 1e6:.1f} | {ratio:.2f} |"
        )
        if row["method"] in ("MNR", "MNRES"):
            if row["peak_increase_bytes"] <= 0:
                # ru_maxrss cannot fall: an earlier peak of the set-up hid the run's
                lines.append(
                    f"FAIL: {row['method']} peak memory unmeasured at N = {row['n_samples']} "
                    f"(no increase seen by {row.get('measured_by', 'ru_maxrss')})"
                )
                continue
            lines.append(
                f"{'PASS' if ratio <= 2 else 'FAIL'}: {row['method']} peak memory ≤ 2 × the "
                f"sensitivity array at N = {row['n_samples']} ({ratio:.2f} ×)"
            )
    print()
    for line in lines:
        print(line)
    return lines


# the standard cases (docs/cases.md "The standard cases", plus the built-in-model HFB-320 and
# the Y-13 AUS output-error case): output error with a solver, each under ~60 s
STANDARD_CASES = (
    "hfb320_longitudinal",
    "hfb320_longitudinal_builtin",
    "attas_lateral",
    "attas_lateral_two_maneuvers",
    "attas_short_period",
    "twin_otter_longitudinal",
    "y13aus_lateral_output_error",
)
CASE_TIMEOUT_S = 120.0
# in-process warm estimates per solver and case (the best is reported)
CASE_ESTIMATE_REPEATS = 5


def _case_copy(path, solver: str, folder) -> object:
    """A copy of the case file in ``folder`` with every ``solver = …`` set to ``solver``
    (inserted under [estimation] where the case relies on the default) and relative model
    modules made absolute."""
    import re
    from pathlib import Path

    text = Path(path).read_text()
    if re.search(r"^\s*solver\s*=", text, flags=re.M):
        text = re.sub(r'^(\s*)solver\s*=\s*"[a-z]+"', rf'\1solver = "{solver}"', text, flags=re.M)
    else:
        text = re.sub(
            r"^\[estimation\]\s*$", f'[estimation]\nsolver = "{solver}"', text, flags=re.M
        )

    def absolute(match):
        return f'{match.group(1)}"{(Path(path).parent / match.group(2)).resolve()}"'

    text = re.sub(r'^(\s*module\s*=\s*)"([^"]+)"', absolute, text, flags=re.M)
    copy = Path(folder) / f"{Path(path).stem}_{solver}.toml"
    copy.write_text(text)
    return copy


def _process_time(case_file, data_dir, cache_dir, out_dir) -> float | None:
    """Wall time (s) of ``flightid run CASE --out … --json`` in a fresh process (None: failed
    or over ``CASE_TIMEOUT_S``)."""
    import shutil
    import subprocess

    shutil.rmtree(out_dir, ignore_errors=True)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache_dir)}
    command = ["flightid", "run", str(case_file), "--out", str(out_dir), "--json", "--quiet"]
    command += ["--accuracy", "cr", "--data-dir", str(data_dir)]
    start = time.perf_counter()
    try:
        done = subprocess.run(
            command, env=env, capture_output=True, text=True, timeout=CASE_TIMEOUT_S, check=False
        )
    except subprocess.TimeoutExpired:
        return None
    wall = time.perf_counter() - start
    if done.returncode != 0:
        print(f"<!-- {case_file}: exit {done.returncode}: {done.stderr.strip()[-300:]} -->")
        return None
    return wall


def cases_table(names=STANDARD_CASES) -> None:
    """Process time (cold, warm) and warm in-process estimate time of the standard cases,
    MNR and MNRES."""
    import dataclasses
    import tempfile
    from pathlib import Path

    from flightid.cases import load_case, run_case
    from flightid.data.location import data_directory

    cases_dir = Path(__file__).resolve().parents[1] / "examples" / "cases"
    data_dir = data_directory(cases_dir).resolve()  # --data-dir, $FLIGHTID_DATA, the default
    print()
    print(
        "Standard cases. Process: `flightid run CASE --out DIR --json --accuracy cr` in a new "
        "process, cold = empty NUMBA_CACHE_DIR (every kernel compiled), warm = the second run on "
        f"that cache (runs over {CASE_TIMEOUT_S:.0f} s: '>'). Estimate: "
        "the best Estimate.wall_time_s of in-process run_case (accuracy none) after a first "
        f"that compiled everything, MNR and MNRES in turns, {CASE_ESTIMATE_REPEATS} runs each."
    )
    print()
    print(
        "| case | solver | process cold, s | process warm, s | warm estimate, s | "
        "simulations | cost |"
    )
    print("|---|---|---:|---:|---:|---:|---:|")
    checks = []
    with tempfile.TemporaryDirectory(prefix="flightid_cases_") as tmp:
        for name in names:
            path = cases_dir / f"{name}.toml"
            processes, specs = {}, {}
            for solver in ("mnr", "mnres"):
                copy = _case_copy(path, solver, tmp)
                cache = Path(tmp) / f"cache_{name}_{solver}"
                out = Path(tmp) / "out"
                cold = _process_time(copy, data_dir, cache, out)
                warm = _process_time(copy, data_dir, cache, out)
                processes[solver] = (cold, warm)
                spec = load_case(path)
                specs[solver] = dataclasses.replace(
                    spec, estimation={**spec.estimation, "solver": solver}
                )
                run_case(specs[solver], data_dir=data_dir, accuracy="none")  # compiles
            # warm estimates: the two solvers take turns, the best of CASE_ESTIMATE_REPEATS
            # each (one run of 0.02–0.3 s scattered by up to 1.5× between runs)
            walls = {"mnr": float("inf"), "mnres": float("inf")}
            results = {}
            for _ in range(CASE_ESTIMATE_REPEATS):
                for solver in ("mnr", "mnres"):
                    result = run_case(specs[solver], data_dir=data_dir, accuracy="none").estimate
                    walls[solver] = min(walls[solver], result.wall_time_s)
                    results[solver] = result

            def fmt(v):
                return f"> {CASE_TIMEOUT_S:.0f}" if v is None else f"{v:.2f}"

            for solver in ("mnr", "mnres"):
                cold, warm = processes[solver]
                result = results[solver]
                print(
                    f"| {name} | {solver.upper()} | {fmt(cold)} | {fmt(warm)} | "
                    f"{walls[solver]:.3f} | {result.equivalent_evaluations} | "
                    f"{result.cost:.6g} |",
                    flush=True,
                )
            ok = walls["mnres"] <= walls["mnr"]
            checks.append(
                f"{'PASS' if ok else 'FAIL'}: {name}: MNRES warm estimate ≤ MNR's "
                f"({walls['mnres']:.3f} vs {walls['mnr']:.3f} s)"
            )
    print()
    for line in checks:
        print(line)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--seeds",
        type=int,
        default=8,
        help="number of seeded starts (0, 1, …; 0: scaling table only)",
    )
    parser.add_argument(
        "--quick", action="store_true", help="3 seeds, 300 RK4 steps, budget 1500 simulations"
    )
    parser.add_argument("--scaling", action="store_true", help="also the N × parameters table")
    parser.add_argument(
        "--load",
        type=int,
        nargs="+",
        default=[0],
        metavar="N",
        help="run N busy-loop processes beside the measurement (behaviour under load); "
        "--variant user takes several counts (one table each, e.g. --load 0 5)",
    )
    parser.add_argument(
        "--variant",
        choices=(*VARIANTS, "user"),
        default="base",
        help="seeds table: base (22 derivatives), hard40 (40: derivatives, output biases, "
        "initial states) or user (base, the model as a user module, against a plain "
        "Gauss–Newton on a hand-written simulator)",
    )
    parser.add_argument("--budget", type=int, default=5000, help="simulations per method and run")
    parser.add_argument(
        "--sizes",
        type=int,
        nargs="+",
        default=None,
        help="RK4 steps of the scaling table (default 1000 10000 100000; --quick: 300 1000)",
    )
    parser.add_argument(
        "--free",
        type=int,
        nargs="+",
        default=[5, 10, 20, 40],
        help="free-parameter counts of the scaling table (5 … 40)",
    )
    parser.add_argument(
        "--large-free",
        type=int,
        nargs="+",
        default=[20],
        help=f"free-parameter counts run at sizes ≥ {LARGE_N} steps (default 20)",
    )
    parser.add_argument(
        "--memory",
        action="store_true",
        help=f"peak memory of {', '.join(MEMORY_METHODS)} at --memory-steps RK4 steps",
    )
    parser.add_argument(
        "--cases",
        nargs="*",
        default=None,
        metavar="CASE",
        help="standard cases table: process and warm estimate times, MNR and MNRES "
        f"(names from examples/cases; default {' '.join(STANDARD_CASES)})",
    )
    parser.add_argument(
        "--all",
        action="store_true",
        help="everything: seeds tables of both variants, --scaling, --memory, --cases",
    )
    parser.add_argument("--memory-steps", type=int, default=100_000, help=argparse.SUPPRESS)
    parser.add_argument("--memory-one", choices=MEMORY_METHODS, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.memory_one:
        import json

        print(json.dumps(memory_one(args.memory_one, args.memory_steps)))
        return
    if args.all:
        args.scaling, args.memory = True, True
        args.cases = [] if args.cases is None else args.cases
        print(
            "--all: seeds tables (base and hard40), scaling, memory, standard cases; "
            "about 15 min on 2 quiet cores (--quick: about 5 min)"
        )
    recorder = Recorder()
    n_seeds, n_steps, budget = args.seeds, 1000, args.budget
    if args.quick:
        n_seeds, n_steps, budget = min(n_seeds, 3), 300, min(budget, 1500)
    started = time.perf_counter()
    sys.path.insert(0, str(Path(__file__).resolve().parent))  # bench/ (python -P)
    if args.variant == "user":
        from user_module_peers import user_module_table

        print("<!-- guide: docs/benchmarks.md -->")
        print(
            f"6-DOF Navion benchmark as a user module: {n_steps} RK4 steps, 8 outputs, 22 free "
            f"parameters, {n_seeds} seeds, budget {budget} simulations"
        )
        for load in args.load:
            print()
            user_module_table(recorder, range(n_seeds), budget, n_steps, load)
        _elapsed(started)
        return
    from user_module_peers import busy_load

    with busy_load(max(args.load)):
        _tables(args, recorder, n_seeds, n_steps, budget, started)


def _tables(args, recorder, n_seeds: int, n_steps: int, budget: int, started: float) -> None:
    """The seeds, scaling, memory and cases tables ``args`` ask for."""
    variants = VARIANTS if args.all else (args.variant,)
    for variant in variants if n_seeds > 0 else ():
        n_free = 40 if variant == "hard40" else 22
        print()
        print(
            f"6-DOF Navion benchmark ({variant}): {n_steps} RK4 steps, 8 outputs, "
            f"{n_free} free parameters, {n_seeds} seeds, budget {budget} simulations"
        )
        print()
        seeds_table(recorder, range(n_seeds), budget, n_steps, variant)
        _elapsed(started)
    if args.scaling:
        sizes = args.sizes or ((300, 1000) if args.quick else (1000, 10000, 100000))
        scaling_table(recorder, budget, sizes, args.free, args.large_free)
        _elapsed(started)
    if args.memory:
        memory_table(10_000 if args.quick else args.memory_steps)
        _elapsed(started)
    if args.cases is not None:
        cases_table(args.cases or (STANDARD_CASES[:2] if args.quick else STANDARD_CASES))
        _elapsed(started)


def _elapsed(started: float) -> None:
    print(f"\n(elapsed {time.perf_counter() - started:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
