"""RP-1153 examples 1 and 2: the linear second-order system, three optimizers compared.

Example 1 [table II]: input u = sin t for 0 ≤ t ≤ 2π, 0 afterwards; samples every 0.25 s;
Euler integration; no noise; only the first 5 s are used. With no noise R cannot be estimated
from the residuals, so R = I (fixed). Noise-free data let J fall without bound, so the cost
test gets an absolute floor ``cost_atol = 1e-8`` (the paper's final costs are 1e-8 … 1e-10).

Example 2 [table III]: the same system with a pulse input and Gaussian measurement noise,
σ = 1e-4 (case 1, 5 s of data) and σ = 1e-3 (case 2, 3 s of data). The paper does not give
the pulse; ours is u = 1 for 0 ≤ t < 1 s, 0 afterwards, sampled every 0.1 s, Euler
integration, noise from ``numpy.random.default_rng(seed)`` (seed 1 by default). R is fixed at
the identity, as the paper's weighted-least-squares costs suggest (both outputs carry equal
noise, so the estimates are the ML estimates); ``noise="max"`` gives the same estimates.

Parameter scales (the floor of the relative convergence test, which θ1 = 0 needs): 1 for the
entries of A and 0.1 for those of B, their typical magnitudes.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from flightid.data.flightdata import FlightData
from flightid.errors import InputError
from flightid.estimation import FPS, MNR, MNRES, Convergence, Estimate, estimate
from flightid.model import Parameter, Parameters
from flightid.paper.linear_system import NAMES, START_VALUES, TRUE_VALUES, linear_model
from flightid.simulation import simulate

__all__ = [
    "PAPER_TABLE_II",
    "PAPER_TABLE_III",
    "ExampleRun",
    "comparison_table",
    "example1_data",
    "example2_data",
    "example_model",
    "run_example1",
    "run_example2",
]

# RP-1153 table II (example 1): final estimates are the true values for all three methods.
PAPER_TABLE_II = {
    "fps": {"cost": 0.14e-8, "equivalent_evaluations": 715, "cpu_s": 2948},
    "mnr": {"cost": 0.61e-10, "equivalent_evaluations": 28, "cpu_s": 106},
    "mnres": {"cost": 0.11e-7, "equivalent_evaluations": 12, "cpu_s": 47},
}
# RP-1153 table III (example 2); MNR used analytic sensitivities there. Case 2: MNRES did not
# converge (no step-size control).
PAPER_TABLE_III = {
    1: {
        "mnr": {
            "values": (-0.0675, -1.471, 1.009, -0.449, 0.202, 0.098),
            "cost": 0.105e-6,
            "equivalent_evaluations": 42,
        },
        "mnres": {
            "values": (-0.0684, -1.471, 1.010, -0.448, 0.202, 0.098),
            "cost": 0.105e-6,
            "equivalent_evaluations": 12,
        },
    },
    2: {
        "mnr": {
            "values": (-0.705, -1.228, 1.757, 0.159, 0.210, 0.087),
            "cost": 0.104e-4,
            "equivalent_evaluations": 70,
        },
        "mnres": {
            "values": (-0.410, -1.549, 0.799, -0.238, 0.251, 0.037),
            "cost": 0.122e-4,
            "equivalent_evaluations": 27,
            "converged": False,
        },
    },
}

EXAMPLE1_CONVERGENCE = Convergence(cost_atol=1e-8, max_iterations=5000)
EXAMPLE2_CONVERGENCE = Convergence(max_iterations=200)
SCALES = (1.0, 1.0, 1.0, 1.0, 0.1, 0.1)


def example_model(values=START_VALUES):
    """The linear system with the examples' parameter scales."""
    model = linear_model(values)
    parameters = Parameters(
        Parameter(name, value, scale=scale)
        for name, value, scale in zip(NAMES, values, SCALES, strict=True)
    )
    return model.with_parameters(parameters)


def _measured(time_s: np.ndarray, u: np.ndarray, sigma: float, seed: int) -> FlightData:
    inputs = FlightData(time_s, {"u": u})
    clean = simulate(linear_model(TRUE_VALUES), inputs, method="euler")
    noise = np.random.default_rng(seed).normal(0.0, sigma, clean.shape) if sigma > 0 else 0.0
    z = clean + noise
    return FlightData(
        time_s, {"u": u}, {"x1": z[:, 0], "x2": z[:, 1]}, name=f"linear system, sigma={sigma:g}"
    )


def example1_data() -> FlightData:
    """Example 1: u = sin t (0 ≤ t ≤ 2π), every 0.25 s, first 5 s, no noise."""
    t = np.arange(0.0, 5.0 + 1e-9, 0.25)
    u = np.where(t <= 2 * np.pi, np.sin(t), 0.0)
    return _measured(t, u, 0.0, 0)


def example2_data(case: int, seed: int = 1) -> FlightData:
    """Example 2: unit pulse for 1 s, every 0.1 s; case 1 σ = 1e-4 over 5 s, case 2 σ = 1e-3
    over 3 s."""
    if case not in (1, 2):
        raise InputError(f"case: expected 1 or 2, got {case!r}")
    duration, sigma = (5.0, 1e-4) if case == 1 else (3.0, 1e-3)
    t = np.arange(0.0, duration + 1e-9, 0.1)
    u = np.where(t < 1.0 - 1e-9, 1.0, 0.0)
    return _measured(t, u, sigma, seed)


@dataclass(frozen=True)
class ExampleRun:
    """Results of one paper example, one entry per method."""

    example: int
    case: int | None
    results: tuple[Estimate, ...]

    def to_dict(self) -> dict:
        document = {"example": self.example}
        if self.case is not None:
            document["case"] = self.case
        document["results"] = []
        for result in self.results:
            entry = result.to_dict()
            for parameter, true in zip(entry["parameters"], TRUE_VALUES, strict=True):
                parameter["true"] = true
            document["results"].append(entry)
        return document


SOLVERS = {"fps": FPS(), "mnr": MNR(), "mnres": MNRES()}


def _run(data: FlightData, methods, convergence: Convergence, compiled: bool) -> tuple:
    """Every requested solver on the linear system (Euler, R = I fixed)."""
    return tuple(
        estimate(
            example_model(),
            data,
            SOLVERS[name],
            method="euler",
            noise="fixed",
            convergence=convergence,
            compiled=compiled,
        )
        for name in methods
    )


def run_example1(methods=("fps", "mnr", "mnres"), compiled: bool = True) -> ExampleRun:
    """Example 1 with the requested solvers."""
    return ExampleRun(1, None, _run(example1_data(), methods, EXAMPLE1_CONVERGENCE, compiled))


def run_example2(
    case: int, methods=("mnr", "mnres"), seed: int = 1, compiled: bool = True
) -> ExampleRun:
    """Example 2, case 1 or 2, with the requested solvers."""
    data = example2_data(case, seed)
    return ExampleRun(2, case, _run(data, methods, EXAMPLE2_CONVERGENCE, compiled))


def comparison_table(run: ExampleRun) -> str:
    """The paper's table beside ours: estimates, cost, equivalent evaluations (ours split
    into those to the optimum and those confirming it, and the bounds' beside them; the
    paper's are each solver's count to its own "converged")."""
    from flightid.report.text import format_table

    paper = PAPER_TABLE_II if run.example == 1 else PAPER_TABLE_III[run.case]
    headers = ["", "true", "start"]
    for result in run.results:
        headers += [result.solver, f"{result.solver} (paper)"]
    rows = []
    for j, name in enumerate(NAMES):
        row = [name, f"{TRUE_VALUES[j]:g}", f"{START_VALUES[j]:g}"]
        for result in run.results:
            reference = paper.get(result.solver, {})
            values = reference.get("values", TRUE_VALUES if run.example == 1 else None)
            row += [f"{result.values[j]:.5g}", "-" if values is None else f"{values[j]:.4g}"]
        rows.append(row)
    for label, key, fmt in (
        ("cost", "cost", "{:.3g}"),
        ("equivalent evaluations", "equivalent_evaluations", "{:d}"),
        ("  to the optimum", "evaluations_to_optimum", "{:d}"),
        ("  confirming it", "confirmation_evaluations", "{:d}"),
        ("+ for the bounds", "accuracy_evaluations", "{:d}"),
    ):
        row = [label, "", ""]
        for result in run.results:
            reference = paper.get(result.solver, {})
            ours = getattr(result, key)
            row += [
                "-" if ours is None else fmt.format(ours),
                fmt.format(reference[key]) if key in reference else "-",
            ]
        rows.append(row)
    row = ["status", "", ""]
    for result in run.results:
        reference = paper.get(result.solver, {})
        row += [
            result.status,
            "not converged"
            if reference.get("converged") is False
            else ("converged" if reference else "-"),
        ]
    rows.append(row)
    row = ["wall time, s", "", ""]
    for result in run.results:
        row += [f"{result.wall_time_s:.3f}", "-"]
    rows.append(row)
    title = (
        f"RP-1153 example {run.example}"
        + (f", case {run.case}" if run.case else "")
        + " — ours beside the paper's table "
        + ("II" if run.example == 1 else "III")
    )
    return title + "\n" + format_table(headers, rows)


def timed(function, *args, **kwargs):
    """(result, seconds) of a call."""
    start = time.perf_counter()
    value = function(*args, **kwargs)
    return value, time.perf_counter() - start
