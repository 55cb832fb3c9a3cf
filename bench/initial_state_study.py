"""Initial states from a noisy first sample: does the stated σ still describe the spread?

Seeded Monte Carlo over measurement-noise realisations of one elevator 3-2-1-1 record of an
airplane, estimated with flightid's built-in body-axis longitudinal model (states u, w, q,
l_xz, l_yz, l_zz; outputs V, α, q, Θ, a_x, a_z; output error, R estimated) under four rules
for the initial states:

* ``first_sample``  every initial state fixed from the first noisy sample (``"measured"``;
  u, w from V, α; l_xz, l_zz from Θ; l_yz = 0 without Φ): the rule of the reference tools;
* ``attitude_estimated``  l_xz, l_zz estimated (start: the first sample), u, w, q fixed;
* ``averaged``      as ``first_sample``, but the attitude from the mean Θ of the first ``--k``
  samples (the record starts in trim), with the noise of that mean propagated into the
  covariance: Cov = M_θθ⁻¹ + K σ²_Θ̄ Kᵀ, K = −M_θθ⁻¹ M_θΘ0 (the linearised shift of θ̂ per
  unit Θ0 error, M_θΘ0 from central differences of the outputs in Θ0), σ²_Θ̄ = R_Θ / k;
* ``estimated``     u, w, q, l_xz, l_zz estimated, l_yz fixed (it enters only through the
  measured rates p, r): the default of the built-in airplane models.

Simulator, written independently of flightid's simulator: the rigid-body longitudinal
equations in body axes (u̇ = −q w − g sin Θ + X/m, ẇ = q u + g cos Θ + Z/m, q̇ = M/I_y,
Θ̇ = q) with linear aerodynamics of known derivatives, integrated here by RK4 at 1/10 of the
sample interval; trimmed level flight at 50 m/s, then an elevator 3-2-1-1. The truth is the
coded derivatives.

For each parameter it prints the 2σ coverage (fraction of seeds with |θ̂ − θ_true| ≤ 2σ)
and the ratio of the empirical standard deviation of θ̂ to the mean stated σ. Honest σ:
coverage ≈ 95 %, ratio 0.8–1.25.

Usage (about 15 s on a loaded 2-core machine for 40 seeds and the four rules)::

    PYTHONPATH=src python bench/initial_state_study.py [--seeds 40] [--k 10]
        [--rules first_sample attitude_estimated averaged estimated] [--jsbsim]

``--jsbsim`` flies JSBSim's Cessna 172 (c172x; the optional ``jsbsim`` package) instead of the
closed-form airplane: no coded truth, so coverage is around the noise-free estimate and the
spread / σ ratio is the measure.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

RULES = ("first_sample", "attitude_estimated", "averaged", "estimated")
OUTPUTS = ("V", "alpha", "q", "theta", "ax", "az")
G = 9.80665
# measurement noise 1σ per output (m/s, rad, rad/s, rad, m/s², m/s²)
NOISE = {"V": 0.2, "alpha": 0.003, "q": 0.003, "theta": 0.003, "ax": 0.05, "az": 0.1}
AERO = {
    "CX": {"CX0": "1", "CXa": "alpha"},
    "CZ": {"CZ0": "1", "CZa": "alpha", "CZq": "qhat", "CZde": "de"},
    "Cm": {"Cm0": "1", "Cma": "alpha", "Cmq": "qhat", "Cmde": "de"},
}


@dataclass(frozen=True)
class Record:
    """One noise-free record: time (s), elevator (rad), outputs (N, 6), airplane constants."""

    time: np.ndarray
    de: np.ndarray
    clean: np.ndarray
    airplane: dict
    truth: dict
    measured: dict | None = None  # noise-free v (m/s), p, r (rad/s) fed as inputs; None: zero


def elevator_3211(time_s: np.ndarray, start_s: float, unit_s: float, amp: float) -> np.ndarray:
    """3-2-1-1 (+, −, +, −) of amplitude ``amp`` starting at ``start_s``; piecewise linear
    between the samples, so linear interpolation between samples is exact."""
    edges = start_s + unit_s * np.cumsum([0, 3, 2, 1, 1])
    signs = (1.0, -1.0, 1.0, -1.0)
    de = np.zeros_like(time_s)
    for lo, hi, s in zip(edges[:-1], edges[1:], signs, strict=True):
        de[(time_s >= lo) & (time_s < hi)] = s * amp
    return de


# --------------------------------------------------------------------- closed-form airplane
CLOSED_AIRPLANE = {"mass": 1247.4, "Iy": 4067.5, "S": 17.094, "cbar": 1.737, "density": 1.225}
CLOSED_DERIVATIVES = {"CXa": 0.35, "CZa": -4.6, "CZq": -9.0, "CZde": -0.45,
                      "Cma": -0.75, "Cmq": -11.0, "Cmde": -1.1, "Cm0": 0.03}  # fmt: skip


def closed_form_record(dt_s: float = 0.05, duration_s: float = 16.0) -> Record:
    """Trimmed level flight at 50 m/s, then an elevator 3-2-1-1 (unit 0.6 s, 0.04 rad)."""
    a = CLOSED_AIRPLANE
    d = dict(CLOSED_DERIVATIVES)
    V0, alpha0 = 50.0, 0.05
    qbar_S = 0.5 * a["density"] * V0**2 * a["S"]
    # trim: Ẋ = 0 with Θ0 = α0 (level), q = 0: CX = m g sin Θ / (q̄S), CZ = −m g cos Θ / (q̄S)
    d["CX0"] = a["mass"] * G * math.sin(alpha0) / qbar_S - d["CXa"] * alpha0
    de0 = 0.0
    # Cm = 0 at trim with δe = 0: Cm0 + Cma α0 = 0 sets α0's Cm0 (replaces the coded value)
    d["Cm0"] = -d["Cma"] * alpha0
    d["CZ0"] = -a["mass"] * G * math.cos(alpha0) / qbar_S - d["CZa"] * alpha0
    time_s = np.arange(0.0, duration_s + dt_s / 2, dt_s)
    de = de0 + elevator_3211(time_s, 1.0, 0.6, 0.04)

    def derivatives(x, elevator):
        u, w, q, theta = x
        V = math.hypot(u, w)
        alpha = math.atan2(w, u)
        qhat = q * a["cbar"] / (2.0 * V)
        qs = 0.5 * a["density"] * V * V * a["S"]
        cx = d["CX0"] + d["CXa"] * alpha
        cz = d["CZ0"] + d["CZa"] * alpha + d["CZq"] * qhat + d["CZde"] * elevator
        cm = d["Cm0"] + d["Cma"] * alpha + d["Cmq"] * qhat + d["Cmde"] * elevator
        return np.array([
            -q * w - G * math.sin(theta) + qs * cx / a["mass"],
            q * u + G * math.cos(theta) + qs * cz / a["mass"],
            qs * a["cbar"] * cm / a["Iy"],
            q,
        ]), qs * cx / a["mass"], qs * cz / a["mass"]  # fmt: skip

    x = np.array([V0 * math.cos(alpha0), V0 * math.sin(alpha0), 0.0, alpha0])
    rows = []
    substeps = 10
    h = dt_s / substeps
    for i, t in enumerate(time_s):
        _, ax, az = derivatives(x, de[i])
        rows.append((math.hypot(x[0], x[1]), math.atan2(x[1], x[0]), x[2], x[3], ax, az))
        if i + 1 == len(time_s):
            break
        for s in range(substeps):
            # elevator linear between samples; RK4 [x_{n+1} = x_n + h/6 (k1 + 2k2 + 2k3 + k4)]
            tau = s * h
            e0 = np.interp(t + tau, time_s, de)
            em = np.interp(t + tau + h / 2, time_s, de)
            e1 = np.interp(t + tau + h, time_s, de)
            k1 = derivatives(x, e0)[0]
            k2 = derivatives(x + h / 2 * k1, em)[0]
            k3 = derivatives(x + h / 2 * k2, em)[0]
            k4 = derivatives(x + h * k3, e1)[0]
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    truth = {k: d[k] for k in ("CX0", "CXa", "CZ0", "CZa", "CZq", "CZde", "Cm0", "Cma", "Cmq",
                               "Cmde")}  # fmt: skip
    return Record(time_s, de, np.array(rows), dict(a), truth)


# ------------------------------------------------------------------- JSBSim's Cessna 172
FT, SLUG, SLUG_FT2, SLUG_FT3 = 0.3048, 14.59390294, 1.3558179619, 515.3788184


def jsbsim_available() -> bool:
    """True when the optional ``jsbsim`` package imports."""
    try:
        import jsbsim  # noqa: F401
    except ImportError:
        return False
    return True


def _jsbsim_trimmed_c172x(dt_s: float):
    """JSBSim's c172x trimmed (JSBSim's own full trim) in level flight, 100 kt, 4000 ft,
    engine running, throttle then held; the autopilot's wing leveller (ailerons only) keeps
    the wings level during the pitch maneuver."""
    import os

    os.environ.setdefault("JSBSIM_DEBUG", "0")  # no start-up banner
    import jsbsim

    fdm = jsbsim.FGFDMExec(os.path.dirname(jsbsim.__file__))
    fdm.set_debug_level(0)
    fdm.load_model("c172x")
    for name, value in (("ic/h-sl-ft", 4000.0), ("ic/vt-kts", 100.0), ("ic/gamma-deg", 0.0),
                        ("ic/psi-true-deg", 0.0), ("ic/phi-deg", 0.0)):  # fmt: skip
        fdm[name] = value
    fdm.set_dt(dt_s)
    fdm["fcs/throttle-cmd-norm"] = 0.8
    fdm["fcs/mixture-cmd-norm"] = 1.0
    fdm.run_ic()
    fdm["propulsion/set-running"] = -1
    fdm["propulsion/magneto_cmd"] = 3
    for _ in range(10):
        fdm.run()
    fdm["simulation/do_simple_trim"] = 1  # full trim: throttle, elevator, ailerons, rudder
    fdm["ap/attitude_hold"] = 1
    return fdm


def jsbsim_record(dt_s: float = 0.02, duration_s: float = 15.0) -> Record:
    """JSBSim c172x from trim, elevator 3-2-1-1 (unit 0.6 s) around the trim command, recorded
    every ``dt_s`` (JSBSim at dt_s / 4). The elevator actuator has a 0.05 rad hysteresis: the
    command pulses are ±0.12 (about 0.05 rad), and the command ends 0.025 rad above trim so the
    surface comes back to its trim position (recorded: fcs/elevator-pos-rad, about ±0.023
    rad). Outputs: V = vt, α, q, Θ, a_x, a_z = total non-gravitational body force / mass
    (m/s², at the centre of gravity). No truth: the derivatives are JSBSim's tables."""
    substeps = 4
    fdm = _jsbsim_trimmed_c172x(dt_s / substeps)
    time_s = np.arange(0.0, duration_s + dt_s / 2, dt_s)
    command = elevator_3211(time_s, 1.0, 0.6, 0.12)
    # back from below through the hysteresis: command = trim + half the width (0.025 rad)
    command[time_s >= 1.0 + 0.6 * 7] = 0.025 / (23.0 * 0.01745)
    rows = []
    for c in command:
        mass = fdm["inertia/mass-slugs"]
        rows.append((fdm["velocities/vt-fps"] * FT, fdm["aero/alpha-rad"],
                     fdm["velocities/q-rad_sec"], fdm["attitude/theta-rad"],
                     fdm["forces/fbx-total-lbs"] / mass * FT,
                     fdm["forces/fbz-total-lbs"] / mass * FT, fdm["fcs/elevator-pos-rad"],
                     fdm["velocities/v-fps"] * FT, fdm["velocities/p-rad_sec"],
                     fdm["velocities/r-rad_sec"]))  # fmt: skip
        fdm["fcs/elevator-cmd-norm"] = c
        for _ in range(substeps):
            fdm.run()
    rows = np.array(rows)
    airplane = {
        "mass": fdm["inertia/mass-slugs"] * SLUG,
        "Ix": fdm["inertia/ixx-slugs_ft2"] * SLUG_FT2,
        "Iy": fdm["inertia/iyy-slugs_ft2"] * SLUG_FT2,
        "Iz": fdm["inertia/izz-slugs_ft2"] * SLUG_FT2,
        "Ixz": fdm["inertia/ixz-slugs_ft2"] * SLUG_FT2,
        "S": fdm["metrics/Sw-sqft"] * FT**2,
        "b": fdm["metrics/bw-ft"] * FT,
        "cbar": fdm["metrics/cbarw-ft"] * FT,
        "density": fdm["atmosphere/rho-slugs_ft3"] * SLUG_FT3,
    }
    measured = dict(zip(("v", "p", "r"), rows[:, 7:].T, strict=True))
    return Record(time_s, rows[:, 6], rows[:, :6], airplane, {}, measured)


# ------------------------------------------------------------------------- the estimation
def _case(record: Record, rule: str, k: int):
    from flightid.cases.spec import parse_case

    raw = {
        "title": f"initial-state study, {rule}",
        "data": {"file": "memory.csv", "inputs": {"de": {"column": 2}},
                 "outputs": {o: {"column": 3 + j} for j, o in enumerate(OUTPUTS)}},
        "model": {"type": "longitudinal", "outputs": list(OUTPUTS), "controls": ["de"],
                  "accelerometer": {"unit": "m/s^2"}, "airplane": dict(record.airplane),
                  "aero": AERO},
        "estimation": {"solver": "mnres", "noise": "max"},
    }  # fmt: skip
    if rule in ("first_sample", "averaged"):
        raw["initial_state"] = {"default": "measured"}  # the explicit old rule
    elif rule == "attitude_estimated":
        raw["initial_state"] = {s: "measured" for s in ("u", "w", "q", "l_yz")}
    return parse_case(raw, Path("memory.toml"))


def _maneuver(record: Record, outputs: np.ndarray):
    from flightid.data import FlightData

    zeros = np.zeros_like(record.time)
    lateral = record.measured or {"v": zeros, "p": zeros, "r": zeros}
    return FlightData(
        record.time,
        {"de": record.de, **lateral},
        dict(zip(OUTPUTS, outputs.T, strict=True)),
        name="3-2-1-1",
    )


def _attitude_x0(theta0: float) -> dict:
    # wings level: l_xz = −sin Θ0, l_yz = 0, l_zz = cos Θ0   [2.21–2.24]
    return {"l_xz": -math.sin(theta0), "l_yz": 0.0, "l_zz": math.cos(theta0)}


def _propagated_covariance(model, maneuver, result, theta0: float, var_theta0: float):
    """M_θθ⁻¹ + K var Kᵀ with K = −M_θθ⁻¹ M_θΘ0 (one column of Θ0 sensitivities)."""
    from flightid.simulation import simulate

    step = 1e-4

    def outputs_at(theta_pitch):
        x0 = [_attitude_x0(theta_pitch).get(s) for s in model.states]
        spec = [v if v is not None else e for v, e in zip(x0, model.x0_spec(), strict=True)]
        return simulate(model.with_x0(spec), maneuver, result.values)

    # ∂y/∂Θ0 by central differences
    column = (outputs_at(theta0 + step) - outputs_at(theta0 - step)) / (2 * step)
    weights = 1.0 / result.r_diag
    # M_θΘ0 = Σ_i G_iᵀ R⁻¹ ∂y_i/∂Θ0
    cross = np.einsum("iof,o,io->f", result.sensitivities, weights, column)
    gain = -result.covariance @ cross
    return result.covariance + var_theta0 * np.outer(gain, gain)


def estimate_rule(record: Record, outputs: np.ndarray, rule: str, k: int, start: dict):
    """(names, values, σ) of the aerodynamic parameters under ``rule``."""
    from flightid.cases.build import base_model, build_model
    from flightid.estimation import MNRES, estimate

    case = _case(record, rule, k)
    maneuver = _maneuver(record, outputs)
    base = base_model(case)[0]
    base = base.with_parameters(base.parameters.with_values(start))
    model, maneuvers = build_model(case, [maneuver], base=base)
    theta_bar = float(np.mean(outputs[:k, OUTPUTS.index("theta")]))
    if rule == "averaged":
        fixed = _attitude_x0(theta_bar)
        model = model.with_x0([fixed.get(s, e) for s, e in zip(model.states, model.x0_spec(),
                                                               strict=True)])  # fmt: skip
    result = estimate(model, maneuvers, MNRES(), noise="max")
    free = [n for n, f in zip(result.names, result.free, strict=True) if f]
    covariance = result.covariance
    if rule == "averaged":
        var = result.r_diag[OUTPUTS.index("theta")] / k
        covariance = _propagated_covariance(model, maneuvers[0], result, theta_bar, var)
    sigma = np.sqrt(np.diag(covariance))
    chosen = [free.index(n) for n in free if not n.startswith("x0_")]
    values = result.values[result.free][chosen]
    return [free[i] for i in chosen], values, sigma[chosen], result.converged


def noise_free_fit(record: Record, rule: str, k: int) -> dict:
    """The estimate from the noise-free record (the centre of the noise seeds' estimates when
    the simulator has no coded truth), started from generic light-airplane values."""
    start = {"CX0": 0.0, "CXa": 0.3, "CZ0": -0.4, "CZa": -4.5, "CZq": -5.0, "CZde": -0.4,
             "Cm0": 0.0, "Cma": -0.8, "Cmq": -10.0, "Cmde": -1.0}  # fmt: skip
    names, values, _, converged = estimate_rule(record, record.clean, rule, k, start)
    if not converged:
        raise RuntimeError(f"the noise-free fit under rule {rule!r} did not converge")
    return dict(zip(names, values, strict=True))


def study(simulator: str, seeds: int, k: int, rules, seed0: int = 0) -> dict:
    """{rule: (names, values (seeds, p), σ (seeds, p), truth (p,))}."""
    record = closed_form_record() if simulator == "closed_form" else jsbsim_record()
    rng_scale = np.array([NOISE[o] for o in OUTPUTS])
    table = {}
    for rule in rules:
        start = record.truth or noise_free_fit(record, rule, k)
        values, sigmas, names = [], [], None
        for s in range(seed0, seed0 + seeds):
            noise = np.random.default_rng(s).standard_normal(record.clean.shape) * rng_scale
            names, v, sd, _ = estimate_rule(record, record.clean + noise, rule, k, start)
            values.append(v)
            sigmas.append(sd)
        truth = np.array([start[n] for n in names])
        table[rule] = (names, np.array(values), np.array(sigmas), truth)
    return table


def coverage_and_ratio(values: np.ndarray, sigmas: np.ndarray, truth: np.ndarray):
    """2σ coverage and empirical-spread / mean-σ ratio per parameter."""
    inside = np.abs(values - truth) <= 2.0 * sigmas
    # ratio = std_seeds(θ̂) / mean_seeds(σ)
    ratio = values.std(axis=0, ddof=1) / sigmas.mean(axis=0)
    return inside.mean(axis=0), ratio


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--simulator", choices=("closed_form",), default="closed_form")
    parser.add_argument("--seeds", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--k", type=int, default=10, help="samples averaged by 'averaged'")
    parser.add_argument("--rules", nargs="+", choices=RULES, default=list(RULES))
    parser.add_argument(
        "--jsbsim",
        action="store_true",
        help="fly JSBSim's Cessna 172 (c172x) instead; needs the jsbsim package",
    )
    args = parser.parse_args(argv)
    if args.jsbsim:
        if not jsbsim_available():
            print(
                "skipped: --jsbsim needs the jsbsim package (pip install jsbsim), "
                "which is not importable here"
            )
            return 0
        args.simulator = "jsbsim"
    start = time.perf_counter()
    table = study(args.simulator, args.seeds, args.k, args.rules, args.seed)
    print(f"simulator {args.simulator}, {args.seeds} seeds, k = {args.k}")
    if args.simulator == "jsbsim":
        print("no coded truth: coverage is around the estimate from the noise-free record")
    names = table[args.rules[0]][0]
    header = "".join(f" | {r:>14s} cov  ratio" for r in args.rules)
    print(f"{'parameter':10s}{header}")
    stats = {r: coverage_and_ratio(*table[r][1:]) for r in args.rules}
    for j, name in enumerate(names):
        cells = "".join(
            f" | {100 * stats[r][0][j]:17.0f}% {stats[r][1][j]:5.2f}" for r in args.rules
        )
        print(f"{name:10s}{cells}")
    print(f"{time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
