"""Modes, flying-quality levels and JSBSim round-trip errors of the shipped airplane cases.

Runs the HFB-320 (built-in wind-axis model), ATTAS short-period and ATTAS lateral cases
(real data, skipped with a line when absent) and the simulated RP-1153 example-3 Navion, and
prints, as markdown tables, each case's modes with σ, the MIL-F-8785C level each criterion
meets at 95 % for the stated class and category, and the RMS difference between the
exported aircraft flown in JSBSim and flightid's simulation of the estimate, in units of the
estimated measurement-noise σ.

    python docs/fly_cases_numbers.py

The Navion's estimate is of a decoupled lateral model (u, w, q measured inputs); it is flown
and judged as a 6-DOF airplane completed with the Navion's longitudinal derivatives (Nelson,
App. B), which are taken as exact (σ = 0).
"""

from __future__ import annotations

import math
import tempfile
import warnings
from pathlib import Path

import numpy as np

from flightid.export.flying_qualities import flying_qualities
from flightid.numbers import format_with_sigma

ROOT = Path(__file__).resolve().parents[1]
CASES = ROOT / "examples" / "cases"
# (label, case file, airplane class, flight-phase category)
REAL_CASES = (
    ("HFB-320 (built-in model)", "hfb320_longitudinal_builtin.toml", "II-L", "B"),
    ("ATTAS short period", "attas_short_period.toml", "II-L", "B"),
    ("ATTAS lateral", "attas_lateral.toml", "II-L", "B"),
)
QUANTITIES = (
    ("natural_frequency", "ω_n (rad/s)"),
    ("damping_ratio", "ζ"),
    ("time_constant", "τ (s)"),
    ("time_to_double", "t_2 (s)"),
)


def _cell(value: float, sigma: float) -> str:
    if not np.isfinite(value):
        return ""
    text, sigma_text = format_with_sigma(value, sigma, missing="-")
    return f"{text} ± {sigma_text}"


def modes_table(linear) -> list[str]:
    """Markdown rows: mode, eigenvalue, ω_n, ζ, τ, t_2 each ± σ."""
    lines = ["| mode | eigenvalue (1/s) | " + " | ".join(h for _, h in QUANTITIES) + " |"]
    lines.append("|---" * (2 + len(QUANTITIES)) + "|")
    for mode in linear.modes():
        if mode.name == "neutral":  # heading: λ = 0
            continue
        lam = mode.eigenvalue
        eigen = f"{lam.real:.4g}" + (f" ± {abs(lam.imag):.4g}i" if lam.imag else "")
        cells = [_cell(getattr(mode, q), getattr(mode, f"{q}_std")) for q, _ in QUANTITIES]
        lines.append(f"| {mode.name} | {eigen} | " + " | ".join(cells) + " |")
    return lines


def levels_table(linear, airplane_class: str, category: str) -> list[str]:
    """Markdown rows: criterion, value ± σ, level met at 95 % (MIL-F-8785C)."""
    quality = flying_qualities(linear, airplane_class, category)
    lines = ["| criterion | value ± σ | level at 95 % |", "|---|---|---|"]
    for row in quality.rows():
        lines.append(f"| {row[0]} | {row[1]} | {row[-2]} |")
    lines.extend(f"\n*{note}*" for note in quality.notes)
    for criterion in quality.criteria:
        if criterion.note:
            lines.append(f"\n*{criterion.label}: {criterion.note}*")
    return lines


def _ratio_line(label: str, names, flown, simulated, sigma) -> str:
    # RMS(JSBSim − flightid) / σ per output
    ratios = [
        math.sqrt(float(np.mean((flown[n] - simulated[:, i]) ** 2))) / sigma[i]
        for i, n in enumerate(names)
    ]
    return f"| {label} | " + " | ".join(f"{r:.1e}" for r in ratios) + " |"


def hfb320_round_trip(case, run, folder: Path) -> list[str]:
    """The HFB-320 estimate exported and flown in JSBSim with the recorded elevator and
    thrust over the estimation maneuver."""
    from flightid.aircraft import AeroModel, airplane_from_table
    from flightid.export._jsbsim_fly import fly_jsbsim
    from flightid.export.jsbsim import write_jsbsim
    from flightid.simulation import simulate

    estimate, data = run.estimate, run.maneuvers[0]
    spec = case.model
    airplane = airplane_from_table(spec["airplane"])
    aircraft = write_jsbsim(estimate, airplane, folder / "HFB320", aero=AeroModel(spec["aero"]),
                            reference_speed=spec["reference_speed"], rate_speed=spec["rate_speed"],
                            dynamic_pressure="airplane")  # fmt: skip
    y = simulate(estimate.model, data)
    V, alpha, theta, q = estimate.model.initial_state()
    # u = V cos α, w = V sin α
    initial = {"u": V * math.cos(alpha), "w": V * math.sin(alpha), "theta": theta, "q": q}
    inputs = {n: data.input(n) for n in ("de", "F")}
    flown = fly_jsbsim(aircraft, data.time, inputs, initial, substeps=10)
    flown["ax"], flown["az"] = flown["ax"] * airplane.g, flown["az"] * airplane.g
    names = estimate.output_names
    return [
        "| maneuver | " + " | ".join(names) + " |",
        "|---" * (1 + len(names)) + "|",
        _ratio_line("estimation (60 s)", names, flown, y, np.sqrt(estimate.r_diag)),
    ]


def real_case(label: str, case_file: str, airplane_class: str, category: str) -> list[str]:
    from flightid.cases import load_case, resolve_data_dir, run_case

    case = load_case(CASES / case_file)
    data_dir = resolve_data_dir(case)
    files = [case.data.get("file")] if case.data.get("file") else list(case.data["files"])
    missing = [f for f in files if not (data_dir / f).exists()]
    if missing:
        return [f"## {label}", "", f"data {missing} not found in {data_dir}: skipped", ""]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = run_case(case, accuracy="none")
    linear = run.estimate.linearize(at=run.maneuvers[0])
    lines = [f"## {label} — class {airplane_class}, category {category}", ""]
    lines += modes_table(linear) + [""]
    lines += levels_table(linear, airplane_class, category) + [""]
    if "airplane" in case.model:
        with tempfile.TemporaryDirectory() as folder:
            lines += ["JSBSim round trip, RMS(JSBSim − flightid) / σ:", ""]
            lines += hfb320_round_trip(case, run, Path(folder)) + [""]
    return lines


def navion_six_dof(estimate):
    """The lateral estimate completed with the Navion's longitudinal derivatives (Nelson,
    App. B, as the example's 6-DOF truth): airplane, aero, values, trimmed 6-DOF model, trim."""
    from flightid.aircraft import (
        AeroModel,
        navion,
        navion_longitudinal_aero,
        six_dof_model,
        trim_level_flight,
    )
    from flightid.aircraft.library import NAVION_TRIM_SPEED
    from flightid.paper.example3 import LATERAL_TERMS

    lon_aero, lon_values = navion_longitudinal_aero()
    aero = lon_aero + AeroModel(LATERAL_TERMS)
    values = {**lon_values, **dict(zip(estimate.names, estimate.values, strict=True))}
    airplane = navion()
    model = six_dof_model(airplane, aero, aero.parameters(values))
    trim = trim_level_flight(model, NAVION_TRIM_SPEED)
    model = six_dof_model(airplane, aero, aero.parameters(values), x0=trim.x)
    return airplane, aero, values, model, trim


def navion_maneuvers(t):
    """{name: control perturbations}: the estimation maneuver's doublets and a held-out
    maneuver (other times, widths, amplitudes and signs)."""
    from flightid.paper.example3 import _doublet, example3_inputs

    held_out = {
        "da": _doublet(t, 2.0, 0.75, -0.08),
        "dr": _doublet(t, 8.0, 1.5, 0.06),
        "de": _doublet(t, 14.0, 0.5, -0.04),
    }
    return {"estimation": example3_inputs(t), "held-out": held_out}


def navion() -> list[str]:
    """Example 3, noise case 2: the lateral model's modes, the completed 6-DOF airplane's
    modes and levels (class I, category B), and the JSBSim round trip on the estimation and
    a held-out maneuver."""
    from flightid.data.flightdata import FlightData
    from flightid.export._jsbsim_fly import fly_jsbsim, initial_from_body_state
    from flightid.export.jsbsim import write_jsbsim
    from flightid.model.linearization import linearize
    from flightid.paper.example3 import DT, DURATION, OUTPUTS, run_example3
    from flightid.simulation import simulate

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        estimate = run_example3(2)["estimate"]
        data = run_example3(2)["data"]
    lines = ["## RP-1153 example 3 Navion (noise case 2) — class I, category B", ""]
    lines += ["Decoupled lateral model (u, w, q held as measured inputs):", ""]
    lines += modes_table(estimate.linearize(at=data)) + [""]
    airplane, aero, values, model, trim = navion_six_dof(estimate)
    # Cov θ of the 6-DOF parameters: the lateral estimate's, longitudinal values exact
    names = model.parameters.free_names
    index = [names.index(n) for n in np.asarray(estimate.names)[np.asarray(estimate.free)]]
    covariance = np.zeros((len(names), len(names)))
    covariance[np.ix_(index, index)] = estimate.covariance_default
    six_dof = linearize(model, trim.x, [trim.inputs[n] for n in model.inputs],
                        covariance=covariance)  # fmt: skip
    lines += ["6-DOF airplane at trim (lateral estimate + Nelson's longitudinal values):", ""]
    lines += modes_table(six_dof) + [""]
    lines += levels_table(six_dof, "I", "B") + [""]
    t = np.arange(0.0, DURATION + DT / 2, DT)
    sigma = np.sqrt(estimate.r_diag)
    rows = ["| maneuver | " + " | ".join(OUTPUTS) + " |", "|---" * (1 + len(OUTPUTS)) + "|"]
    with tempfile.TemporaryDirectory() as folder:
        aircraft = write_jsbsim(values, airplane, Path(folder) / "Navion", aero=aero,
                                dynamic_pressure="airplane")  # fmt: skip
        for label, perturbation in navion_maneuvers(t).items():
            inputs = {n: np.full(t.shape, v) for n, v in trim.inputs.items()}
            for name, series in perturbation.items():
                inputs[name] = inputs[name] + series
            y = simulate(model, FlightData(t, {n: inputs[n] for n in model.inputs}))
            y_out = np.column_stack([y[:, model.outputs.index(n)] for n in OUTPUTS])
            flown = fly_jsbsim(aircraft, t, inputs, initial_from_body_state(trim.x), substeps=10)
            rows.append(_ratio_line(f"{label} (24 s)", OUTPUTS, flown, y_out, sigma))
    lines += ["JSBSim round trip, RMS(JSBSim − flightid 6-DOF) / σ:", ""] + rows + [""]
    return lines


def main() -> None:
    lines: list[str] = []
    for spec in REAL_CASES:
        lines += real_case(*spec)
    lines += navion()
    print("\n".join(lines))


if __name__ == "__main__":
    main()
