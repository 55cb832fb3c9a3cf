"""RP-1153 example 3: ML/MNRES on a simulated nonlinear lateral model of a light airplane.

The paper [§6.A.3, tables IV–V, figures 10–11] simulates a nonlinear lateral model of a
general-aviation airplane with fourth-order Runge–Kutta at 0.05 s over about 24 s of aileron
and rudder inputs, adds Gaussian measurement noise at three levels, and estimates the 19
derivatives with ML/MNRES (program MAX, algebraic surface [4.15], convergence ΔJ/J < 10⁻³ and
Δθ/θ ≤ 10⁻³). It gives neither the airplane nor the flight condition nor the input shapes, so
this module reproduces the example *in kind*:

* Airplane: the Ryan Navion (mass, inertia, geometry from Nelson, *Flight Stability and
  Automatic Control*, 2nd ed., 1998, Appendix B; ``flightid.aircraft.library``), sea level,
  V = 176 ft/s = 53.64 m/s.
* Lateral aerodynamics: the paper's simulation values (table V). Two nonlinear terms are
  garbled in the scan ("C_l?p" = 2.63, "C_n?r" = 1.7); we read them as C_lαp̂ (``Cl_alpha_phat``)
  and C_nαr̂ (``Cn_alpha_rhat``). The rates are non-dimensional (p̂ = pb/2V, r̂ = rb/2V); the
  table's "C_n?" = 0 entry is read as C_nβ.
* Longitudinal motion: the lateral model is the decoupled one [2.30–2.32], so u, w, q enter
  as measured inputs. They come from a 6-DOF simulation of the same airplane with the Navion's
  linear longitudinal derivatives (Nelson, App. B) started in trim. An elevator doublet
  sequence makes α vary (±0.05 rad): with α constant, α·p̂ and α·r̂ would be collinear with p̂
  and r̂ and the two nonlinear derivatives could not be separated. The longitudinal inputs
  are noise free (the paper adds noise to the five lateral outputs only, table IV).
* Trim: C_Y0 = 0.13 is a steady side force; straight level flight balances it with a steady
  bank Φ0 ≈ −18.7° (β = p = r = 0, δa = δr = 0), which is why a_y sits near 0.3 g as in the
  paper's figure 10.
* Lateral data: by default the lateral outputs are those of the decoupled lateral model itself
  driven by the sampled u, w, q (``source="lateral"``), so the estimation model is exact and
  case 1 can recover the simulation values; ``source="6dof"`` takes them from the 6-DOF run
  (they differ by ≤ 1.2e-3 in p, the RK4 half-step interpolation of the sampled inputs).
* Inputs: aileron doublets (±0.1 rad, 1 s + 1 s) at t = 1 and 13 s, rudder doublets (±0.1 rad)
  at t = 6 and 17 s, elevator doublets (±0.05 rad, 0.5 s + 0.5 s) at t = 3, 10, 15, 20 s; 24 s
  at Δt = 0.05 s (481 samples).
* Noise (table IV): σ = 0 (case 1); β 0.010 rad, p 0.010 rad/s, r 0.010 rad/s, Φ 0.005 rad,
  a_y 0.005 g (case 2); twice those (case 3); ``numpy.random.default_rng(seed)``.
* Estimation: ``estimate(model, data, MNRES(), noise="max")`` for cases 2–3; case 1 has no noise,
  so R cannot come from the residuals: R is fixed at the case-2 variances.
* Start values: every simulation value moved by +10 % / −10 % alternately, and 0.005 for the
  three zero-valued derivatives (the paper's start values are not published; it started
  from stepwise-regression estimates). From ±20 % MNRES under the MAX policy converges too
  (cases 2 and 3, within 0.015 σ of the ±10 % run; docs/aircraft.md).
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from flightid.aircraft import (
    AeroModel,
    body_state,
    lateral_model,
    navion,
    navion_longitudinal_aero,
    six_dof_model,
    trim_level_flight,
)
from flightid.aircraft.library import NAVION_TRIM_SPEED
from flightid.data.flightdata import FlightData
from flightid.errors import InputError
from flightid.estimation import MNRES, Convergence, Estimate, estimate
from flightid.model.parameters import Parameter, Parameters
from flightid.model.statespace import StateSpaceModel
from flightid.simulation import simulate

__all__ = [
    "LATERAL_TERMS",
    "NOISE_STD",
    "OUTPUTS",
    "PAPER_ESTIMATES",
    "SIMULATION_VALUES",
    "cli_main",
    "comparison_table",
    "example3_data",
    "example3_json",
    "example3_model",
    "example3_start_values",
    "example3_inputs",
    "plot_example3",
    "run_example3",
]

OUTPUTS = ("beta", "p", "r", "phi", "ay")
OUTPUT_UNITS = {"beta": "rad", "p": "rad/s", "r": "rad/s", "phi": "rad", "ay": "g"}
CONTROL_UNITS = {"da": "rad", "dr": "rad", "de": "rad"}

# The lateral model of table V: C_Y, C_l, C_n as sums of derivatives × regressors.
LATERAL_TERMS = {
    "CY": ["1", "beta", "phat", "rhat", "da", "dr"],
    "Cl": ["1", "beta", "phat", "rhat", "da", "dr", "alpha*phat"],
    "Cn": ["1", "beta", "phat", "rhat", "dr", "alpha*rhat"],
}

# RP-1153 table V, "Simulation values" column (the two garbled nonlinear terms read as
# C_lαp̂ and C_nαr̂; the zero "C_n?" entry read as C_nβ).
SIMULATION_VALUES = {
    "CY_0": 0.13,
    "CY_beta": -0.411,
    "CY_phat": -0.146,
    "CY_rhat": 0.63,
    "CY_da": -0.053,
    "CY_dr": 0.075,
    "Cl_0": 0.0,
    "Cl_beta": -0.123,
    "Cl_phat": -0.397,
    "Cl_rhat": 0.257,
    "Cl_da": -0.182,
    "Cl_dr": 0.007,
    "Cl_alpha_phat": 2.63,
    "Cn_0": 0.0,
    "Cn_beta": 0.0,
    "Cn_phat": -0.15,
    "Cn_rhat": -0.083,
    "Cn_dr": -0.0431,
    "Cn_alpha_rhat": 1.7,
}

# RP-1153 table V, "Parameter estimates for case 1 / case 2 / case 3" (the paper's airplane,
# flight condition and inputs, not ours: reference points, not targets).
_PAPER_COLUMNS = {
    "CY_0": (0.1299, 0.1298, 0.1295),
    "CY_beta": (-0.4136, -0.4261, -0.4401),
    "CY_phat": (-0.1524, -0.1874, -0.2379),
    "CY_rhat": (0.6686, 0.6070, 0.5412),
    "CY_da": (-0.0618, -0.0733, -0.0872),
    "CY_dr": (0.0794, 0.0775, 0.0751),
    "Cl_0": (0.0001, -0.0003, -0.0005),
    "Cl_beta": (-0.1223, -0.1228, -0.1240),
    "Cl_phat": (-0.3988, -0.4026, -0.4094),
    "Cl_rhat": (0.2573, 0.2409, 0.2239),
    "Cl_da": (-0.1815, -0.1778, -0.1755),
    "Cl_dr": (0.0067, 0.0059, 0.00497),
    "Cl_alpha_phat": (2.6254, 2.519, 2.4359),
    "Cn_0": (-0.00005, -0.00008, -0.0001),
    "Cn_beta": (0.000003, 0.0001, 0.0005),
    "Cn_phat": (-0.1488, -0.1524, -0.1558),
    "Cn_rhat": (-0.0828, -0.0861, -0.0911),
    "Cn_dr": (-0.0425, -0.0434, -0.0445),
    "Cn_alpha_rhat": (1.7343, 1.4419, 1.0118),
}
PAPER_ESTIMATES = {
    case: {name: column[case - 1] for name, column in _PAPER_COLUMNS.items()} for case in (1, 2, 3)
}

# RP-1153 table IV: standard errors of the simulated measurement noise, case 2 (case 3 is
# twice these, case 1 zero). Units: rad, rad/s, rad/s, rad, g.
_NOISE_CASE2 = {"beta": 0.010, "p": 0.010, "r": 0.010, "phi": 0.005, "ay": 0.005}
NOISE_STD = {
    1: dict.fromkeys(OUTPUTS, 0.0),
    2: dict(_NOISE_CASE2),
    3: {k: 2.0 * v for k, v in _NOISE_CASE2.items()},
}

DT = 0.05  # s, RK4 step and sampling interval (paper)
DURATION = 24.0  # s (paper's figures 10–11)
# Parameter scales: floor of the relative convergence test and first perturbation size.
_SCALE_FLOOR = 0.01
# Start values: simulation values moved by ±10 % (see the module docstring).
START_FRACTION = 0.1


def _check_case(case: int) -> int:
    if case not in (1, 2, 3):
        raise InputError(f"case: expected 1, 2 or 3 (RP-1153 table IV), got {case!r}")
    return int(case)


def _doublet(t: np.ndarray, start: float, half_width: float, amplitude: float) -> np.ndarray:
    """+amplitude for start ≤ t < start + w, −amplitude for the next w, 0 elsewhere."""
    first = (t >= start - 1e-9) & (t < start + half_width - 1e-9)
    second = (t >= start + half_width - 1e-9) & (t < start + 2 * half_width - 1e-9)
    return amplitude * (first.astype(float) - second.astype(float))


def example3_inputs(t: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Control perturbations (rad) from trim: aileron, rudder and elevator doublets."""
    t = np.arange(0.0, DURATION + DT / 2, DT) if t is None else np.asarray(t, dtype=float)
    da = _doublet(t, 1.0, 1.0, 0.1) + _doublet(t, 13.0, 1.0, -0.1)
    dr = _doublet(t, 6.0, 1.0, 0.1) + _doublet(t, 17.0, 1.0, -0.1)
    de = sum(
        _doublet(t, start, 0.5, amplitude)
        for start, amplitude in ((3.0, 0.05), (10.0, -0.05), (15.0, 0.05), (20.0, -0.05))
    )
    return {"da": da, "dr": dr, "de": de}


@functools.lru_cache(maxsize=1)
def _truth(compiled: bool = False):
    """Trim, the 6-DOF run and the longitudinal input histories (cached: compiles once)."""
    airplane = navion()
    lon_aero, lon_values = navion_longitudinal_aero()
    lat_aero = AeroModel(LATERAL_TERMS)
    aero = lon_aero + lat_aero
    model6 = six_dof_model(airplane, aero, aero.parameters({**lon_values, **SIMULATION_VALUES}))
    trim = trim_level_flight(model6, NAVION_TRIM_SPEED)
    t = np.arange(0.0, DURATION + DT / 2, DT)
    perturbation = example3_inputs(t)
    inputs = {n: np.full(t.shape, v) for n, v in trim.inputs.items()}
    for name, series in perturbation.items():
        inputs[name] = inputs[name] + series
    data6 = FlightData(t, inputs, name="example 3, 6-DOF")
    # one run: the pure-Python kernel is quicker than compiling the 6-DOF (same numbers)
    y6 = simulate(model6.with_x0(tuple(trim.x)), data6, compiled=compiled)
    full = {name: y6[:, i] for i, name in enumerate(model6.outputs)}
    V, alpha, beta = full["V"], full["alpha"], full["beta"]
    longitudinal = {
        # u = V cos α cos β, w = V sin α cos β (m/s); q (rad/s)
        "u": V * np.cos(alpha) * np.cos(beta),
        "w": V * np.sin(alpha) * np.cos(beta),
        "q": full["q"],
    }
    return trim, t, inputs, longitudinal, full


@functools.lru_cache(maxsize=1)
def _lateral_base() -> StateSpaceModel:
    """The lateral model built once, so every copy shares f/h (and one compiled kernel)."""
    trim = _truth()[0]
    aero = AeroModel(LATERAL_TERMS)
    parameters = Parameters(
        Parameter(n, SIMULATION_VALUES[n], scale=max(abs(SIMULATION_VALUES[n]), _SCALE_FLOOR))
        for n in aero.parameter_names
    )
    x0 = body_state(trim.V, trim.alpha, trim.beta, trim.theta, trim.phi)
    return lateral_model(
        navion(thrust_input=None),
        aero,
        parameters,
        controls=("da", "dr"),
        outputs=OUTPUTS,
        # lateral states (v, p, r, l_xz, l_yz, l_zz) at trim
        x0=tuple(float(x0[i]) for i in (1, 3, 5, 6, 7, 8)),
        name="RP-1153 example 3 (Navion, decoupled lateral)",
    )


def example3_model(values: Mapping[str, float] | None = None) -> StateSpaceModel:
    """The decoupled lateral model of example 3 (inputs da, dr, u, w, q; outputs β, p, r, Φ,
    a_y), started from the trim state, with parameter ``values`` (default: start values)."""
    base = _lateral_base()
    values = example3_start_values() if values is None else dict(values)
    return base.with_parameters(base.parameters.with_values(values))


def example3_start_values(fraction: float = START_FRACTION) -> dict[str, float]:
    """Start values: simulation values × (1 + f, 1 − f, 1 + f, …); 0.005 where the value is 0."""
    start = {}
    for k, (name, value) in enumerate(SIMULATION_VALUES.items()):
        factor = 1.0 + fraction if k % 2 == 0 else 1.0 - fraction
        start[name] = 0.005 if value == 0 else value * factor
    return start


def example3_data(case: int, seed: int = 3, *, source: str = "lateral") -> FlightData:
    """Simulated measurements of example 3 for noise ``case`` (1, 2, 3; RP-1153 table IV).

    Inputs: da, dr (rad, total deflections) and the longitudinal u, w (m/s), q (rad/s);
    outputs: beta (rad), p, r (rad/s), phi (rad), ay (g), with seeded Gaussian noise.
    """
    case = _check_case(case)
    if source not in ("lateral", "6dof"):
        raise InputError(f"source: expected 'lateral' or '6dof', got {source!r}")
    trim, t, inputs, longitudinal, full = _truth()
    data_inputs = {"da": inputs["da"], "dr": inputs["dr"], **longitudinal}
    clean = FlightData(t, data_inputs, name=f"example 3 case {case}")
    if source == "lateral":
        y = simulate(example3_model(SIMULATION_VALUES), clean)
    else:
        y = np.column_stack([full[name] for name in OUTPUTS])
    rng = np.random.default_rng(seed)
    sigma = np.array([NOISE_STD[case][name] for name in OUTPUTS])
    noisy = y + rng.standard_normal(y.shape) * sigma
    units = {**OUTPUT_UNITS, **CONTROL_UNITS, "u": "m/s", "w": "m/s", "q": "rad/s"}
    return FlightData(
        t,
        data_inputs,
        {name: noisy[:, i] for i, name in enumerate(OUTPUTS)},
        units=units,
        name=f"RP-1153 example 3, case {case} (seed {seed})",
    )


def run_example3(
    case: int,
    seed: int = 3,
    *,
    solver: MNRES | None = None,
    source: str = "lateral",
    start_fraction: float = START_FRACTION,
    compiled: bool = True,
) -> dict:
    """Estimate the example-3 derivatives for one noise case.

    Returns a dict: ``case``, ``seed``, ``estimate`` (the ``Estimate``), ``data`` (the
    ``FlightData``), ``truth`` (simulation values), ``paper`` (table V estimates of this case),
    ``within_3sigma`` (fraction of free estimates within 3 Cramér–Rao bounds of the truth),
    ``relative_error`` ({name: |θ̂ − θ|/|θ|, or |θ̂| where θ = 0}), ``wall_time_s``.
    """
    case = _check_case(case)
    started = time.perf_counter()
    data = example3_data(case, seed, source=source)
    model = example3_model(example3_start_values(start_fraction))
    convergence = Convergence(max_iterations=200)
    if case == 1:
        # no noise: R cannot come from the residuals; weight by the case-2 variances
        r_fixed = [NOISE_STD[2][name] ** 2 for name in OUTPUTS]
        result = estimate(
            model,
            data,
            solver=solver or MNRES(),
            noise="fixed",
            R=r_fixed,
            convergence=Convergence(max_iterations=200, cost_atol=1e-10),
            compiled=compiled,
        )
    else:
        result = estimate(
            model,
            data,
            solver=solver or MNRES(),
            noise="max",
            convergence=convergence,
            compiled=compiled,
        )
    within, errors = _accuracy(result)
    return {
        "case": case,
        "seed": seed,
        "estimate": result,
        "data": data,
        "truth": dict(SIMULATION_VALUES),
        "paper": dict(PAPER_ESTIMATES[case]),
        "within_3sigma": within,
        "relative_error": errors,
        "wall_time_s": time.perf_counter() - started,
    }


def _accuracy(result: Estimate) -> tuple[float, dict[str, float]]:
    errors = {}
    inside = []
    for i, name in enumerate(result.names):
        true = SIMULATION_VALUES[name]
        value = float(result.values[i])
        errors[name] = abs(value - true) / abs(true) if true != 0 else abs(value)
        if result.free[i]:
            sigma = float(result.std_cr[i])
            inside.append(math.isfinite(sigma) and abs(value - true) <= 3.0 * sigma)
    return (float(np.mean(inside)) if inside else math.nan), errors


def comparison_table(run: dict) -> str:
    """Text table: parameter, simulation value, estimate, CR bound, paper's estimate."""
    result: Estimate = run["estimate"]
    lines = [
        f"RP-1153 example 3, case {run['case']} (seed {run['seed']}): {result.status}, "
        f"cost {result.cost:.6g}, {result.equivalent_evaluations} equivalent evaluations, "
        f"{result.iterations} iterations, {result.wall_time_s:.2f} s",
        f"{'parameter':<15}{'simulation':>12}{'estimate':>12}{'CR bound':>11}"
        f"{'|err|/σ':>9}{'paper':>11}",
    ]
    for i, name in enumerate(result.names):
        true = SIMULATION_VALUES[name]
        sigma = float(result.std_cr[i])
        ratio = abs(result.values[i] - true) / sigma if sigma > 0 else math.inf
        lines.append(
            f"{name:<15}{true:>12.5g}{result.values[i]:>12.5g}{sigma:>11.3g}"
            f"{ratio:>9.2f}{run['paper'][name]:>11.5g}"
        )
    lines.append(f"within 3 CR bounds of the simulation values: {100 * run['within_3sigma']:.0f} %")
    return "\n".join(lines)


def example3_json(case: int, seed: int = 3, run: dict | None = None, accuracy=None) -> dict:
    """The JSON contract of ``flightid paper example3 --case N --json``.

    ``{"example": 3, "case": N, "seed": s, "results": [estimate.to_dict() with each parameter
    also carrying "true" (simulation value) and "paper" (table V estimate)]}``; with an
    ``AccuracyResult`` from ``flightid.accuracy.assess`` the entry is ``accuracy_json``'s.
    """
    run = run_example3(case, seed) if run is None else run
    if accuracy is None:
        entry = run["estimate"].to_dict()
    else:
        from flightid.accuracy import accuracy_json

        entry = accuracy_json(run["estimate"], accuracy)
    for parameter in entry["parameters"]:
        parameter["true"] = SIMULATION_VALUES[parameter["name"]]
        parameter["paper"] = PAPER_ESTIMATES[run["case"]][parameter["name"]]
    entry["within_3sigma"] = run["within_3sigma"]
    return {"example": 3, "case": run["case"], "seed": run["seed"], "results": [entry]}


def cli_main(args) -> int:
    """``flightid paper example3``: args.case, args.seed (None: 3), args.json, args.plot
    (directory or None), args.accuracy (None, "profile", "search" or "all")."""
    import sys

    seed = 3 if getattr(args, "seed", None) is None else int(args.seed)
    run = run_example3(args.case, seed)
    accuracy = None
    if getattr(args, "accuracy", None):
        from flightid.accuracy import assess

        accuracy = assess(run["estimate"], run["data"], methods=args.accuracy, seed=seed)
    if getattr(args, "plot", None):
        for path in plot_example3(run, args.plot):
            print(f"wrote {path}", file=sys.stderr if args.json else sys.stdout)
    if args.json:
        from flightid.jsonout import dumps  # strict JSON: NaN / inf become null

        sys.stdout.write(dumps(example3_json(args.case, seed, run, accuracy)) + "\n")
    else:
        print(comparison_table(run))
        if accuracy is not None:
            print(accuracy.summary())
    return 0


def plot_example3(run: dict, directory: str | Path) -> list[Path]:
    """Save figures 10 (measured vs predicted) and 11 (control inputs) as PNG in ``directory``.

    Returns the paths written.
    """
    from flightid.report.figures import plot_inputs, plot_measured_vs_predicted

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    result: Estimate = run["estimate"]
    data: FlightData = run["data"]
    labels = {
        "beta": "β, rad",
        "p": "p, rad/s",
        "r": "r, rad/s",
        "phi": "Φ, rad",
        "ay": "a_y, g units",
        "da": "δa, rad",
        "dr": "δr, rad",
        "de": "δe, rad",
    }
    case = run["case"]
    response = plot_measured_vs_predicted(
        result,
        directory / f"example3_case{case}_responses.png",
        labels=labels,
        title=f"Measured and predicted responses, example 3 case {case} (cf. RP-1153 fig. 10)",
    )
    # δe excites the longitudinal motion (u, w, q are inputs of the lateral model)
    elevator = _truth()[2]["de"]
    inputs = plot_inputs(
        data.time,
        {"da": data.input("da"), "dr": data.input("dr"), "de": elevator},
        directory / "example3_inputs.png",
        labels=labels,
        title="Control inputs, example 3 (cf. RP-1153 fig. 11)",
    )
    return [response, inputs]
