"""The ``[design]`` table of a case file: keys checked (``CaseError`` naming the key), the
design problem built from the case's model, and the design run (``flightid design``).

    [design]
    duration_s = 25.0                 # length T of the input (s); a multisine's period
    dt_s = 0.04                       # sample interval (s)
    signal = "multisine"              # multisine | 3211 | 211 | doublet
    criterion = "d_optimal"           # d_optimal | a_optimal | parameters
    parameters = ["Ma", "Mq"]         # criterion = "parameters": their relative bounds
    band_hz = [0.1, 2.0]              # multisine band (Hz), all inputs (or per input)
    noise_std = { alpha = 0.0018, q = 0.0030 }   # assumed noise σ per model output
    limits = { alpha = 0.05 }         # optional: peak |Δy| about the trim-input response
    trim = true                       # x0 = equilibrium at the trim inputs (false: the
                                      # numbers of [initial_state])
    candidates = 6                    # bands / pulse widths tried
    start_s = 1.0                     # step signals: first pulse; gap_s between inputs
    gap_s = 2.0
    reference = true                  # also predict the first maneuver of [data] (its
                                      # measured inputs) for comparison
    [design.inputs]
    de = { amplitude = 0.0495, trim = 0.0394 }   # peak |Δu| and trim value (input units);
                                      # band_hz = [lo, hi] or pulse_s = Δt per input
    # an input that is not designed: other = { value = 0.3 } (held constant)

The parameter values are the case's (``[parameters]`` over the model's own): the a-priori
values the prediction linearises about.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from flightid.cases.checks import (
    CaseError,
    _bool,
    _integer,
    _known,
    _names,
    _number,
    _string,
    _table,
)
from flightid.cases.spec import Case
from flightid.design.information import CRITERIA
from flightid.design.optimize import SIGNALS, DesignProblem, InputSpec, trim_state
from flightid.errors import InputError

__all__ = ["DESIGN_KEYS", "design_problem", "run_design_case"]

DESIGN_KEYS = {
    "duration_s",
    "dt_s",
    "signal",
    "criterion",
    "parameters",
    "band_hz",
    "inputs",
    "noise_std",
    "limits",
    "trim",
    "candidates",
    "start_s",
    "gap_s",
    "reference",
}
_INPUT_KEYS = {"amplitude", "trim", "band_hz", "pulse_s", "value"}


def _positive(value: Any, key: str) -> float:
    number = _number(value, key)
    if number <= 0:
        raise CaseError(f"{key}: expected a positive number, got {value!r}")
    return number


def _band(value: Any, key: str) -> tuple[float, float]:
    if not isinstance(value, list) or len(value) != 2:
        raise CaseError(f"{key}: expected [low, high] in Hz, got {value!r}")
    low, high = _number(value[0], f"{key}[0]"), _number(value[1], f"{key}[1]")
    if not 0 <= low < high:
        raise CaseError(f"{key}: expected 0 ≤ low < high (Hz), got {value!r}")
    return low, high


def _positive_table(value: Any, key: str) -> dict[str, float]:
    table = _table(value, key)
    return {name: _positive(v, f"{key}.{name}") for name, v in table.items()}


def check_design(section: Mapping[str, Any]) -> dict[str, Any]:
    """The ``[design]`` table with types and keys checked (defaults filled in)."""
    section = _table(section, "design")
    _known(section, DESIGN_KEYS, "design")
    for required in ("duration_s", "dt_s", "inputs", "noise_std"):
        if required not in section:
            raise CaseError(f"design.{required}: missing (see docs/design.md for the keys)")
    checked: dict[str, Any] = {
        "duration_s": _positive(section["duration_s"], "design.duration_s"),
        "dt_s": _positive(section["dt_s"], "design.dt_s"),
        "signal": _string(section.get("signal", "multisine"), "design.signal", SIGNALS),
        "criterion": _string(section.get("criterion", "d_optimal"), "design.criterion", CRITERIA),
        "parameters": tuple(_names(section.get("parameters", []), "design.parameters")),
        "band_hz": _band(section["band_hz"], "design.band_hz") if "band_hz" in section else None,
        "noise_std": _positive_table(section["noise_std"], "design.noise_std"),
        "limits": _positive_table(section.get("limits", {}), "design.limits"),
        "trim": _bool(section.get("trim", True), "design.trim"),
        "candidates": _integer(section.get("candidates", 6), "design.candidates", 1),
        "start_s": _number(section.get("start_s", 1.0), "design.start_s"),
        "gap_s": _number(section.get("gap_s", 2.0), "design.gap_s"),
        "reference": _bool(section.get("reference", False), "design.reference"),
    }
    if checked["criterion"] == "parameters" and not checked["parameters"]:
        raise CaseError('design.parameters: criterion = "parameters" needs parameter names')
    if checked["dt_s"] * 10 > checked["duration_s"]:
        raise CaseError(
            f"design.dt_s: {checked['dt_s']} s gives fewer than 10 samples over duration_s = "
            f"{checked['duration_s']} s"
        )
    designed, held = [], {}
    for name, value in _table(section["inputs"], "design.inputs").items():
        key = f"design.inputs.{name}"
        spec = _table(value, key)
        _known(spec, _INPUT_KEYS, key)
        if "value" in spec:
            extra = sorted(set(spec) - {"value"})
            if extra:
                raise CaseError(f"{key}.{extra[0]}: a held input (value = ...) takes no {extra[0]}")
            held[name] = _number(spec["value"], f"{key}.value")
            continue
        if "amplitude" not in spec:
            raise CaseError(f"{key}.amplitude: missing (peak perturbation, or value = to hold it)")
        designed.append(
            {
                "name": name,
                "amplitude": _positive(spec["amplitude"], f"{key}.amplitude"),
                "trim": _number(spec.get("trim", 0.0), f"{key}.trim"),
                "band_hz": _band(spec["band_hz"], f"{key}.band_hz") if "band_hz" in spec else None,
                "pulse_s": _positive(spec["pulse_s"], f"{key}.pulse_s")
                if "pulse_s" in spec
                else None,
            }
        )
    if not designed:
        raise CaseError("design.inputs: expected at least one input with an amplitude")
    if checked["signal"] == "multisine":
        for spec in designed:
            if spec["band_hz"] is None and checked["band_hz"] is None:
                raise CaseError(
                    f"design.inputs.{spec['name']}.band_hz: a multisine needs a band "
                    "(design.band_hz or per input)"
                )
    checked["inputs"] = designed
    checked["held"] = held
    return checked


def _initial_numbers(case: Case, states: tuple[str, ...]) -> dict[str, float]:
    """[initial_state] as numbers (design.trim = false)."""
    values = {}
    for state in states:
        value = case.initial_state.get(state, case.initial_state.get("default"))
        if isinstance(value, Mapping):
            value = value.get("value")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise CaseError(
                f"initial_state.{state}: design.trim = false needs a number for every state, "
                f"got {value!r}"
            )
        values[state] = float(value)
    return values


def design_problem(case: Case, data_dir: Path | None = None) -> tuple[DesignProblem, dict]:
    """The design problem a case describes, and the checked ``[design]`` table."""
    from flightid.cases.build import base_model, build_model
    from flightid.cases.run import input_interpolation
    from flightid.data.flightdata import FlightData

    settings = check_design(case.design)
    base = base_model(case, data_dir)[0]
    designed_names = [s["name"] for s in settings["inputs"]]
    for name in [*designed_names, *settings["held"]]:
        if name not in base.inputs:
            raise CaseError(
                f"design.inputs.{name}: not an input of the model; inputs: {list(base.inputs)}"
            )
    for table in ("noise_std", "limits"):
        for output in settings[table]:
            if output not in base.outputs:
                raise CaseError(
                    f"design.{table}.{output}: not an output of the model; outputs: "
                    f"{list(base.outputs)}"
                )
    missing = [o for o in base.outputs if o not in settings["noise_std"]]
    if missing:
        raise CaseError(f"design.noise_std: missing σ for the model outputs {missing}")
    # one placeholder maneuver (trim inputs, zero outputs) to build the case's model on
    t = np.arange(2) * settings["dt_s"]
    trims = {**settings["held"], **{s["name"]: s["trim"] for s in settings["inputs"]}}
    missing_inputs = [n for n in base.inputs if n not in trims]
    if missing_inputs:
        raise CaseError(
            f"design.inputs: the model inputs {missing_inputs} are neither designed "
            "(amplitude = ...) nor held (value = ...)"
        )
    placeholder = FlightData(
        t,
        {n: np.full(2, trims[n]) for n in base.inputs},
        {o: np.zeros(2) for o in base.outputs},
        name="design",
    )
    if settings["trim"]:
        start = dict.fromkeys(base.states, 0.0)
        given = _initial_numbers_or_none(case, base.states)
        start.update(given)
    else:
        start = _initial_numbers(case, base.states)
    try:
        model, _ = build_model(case, [placeholder], base=base, initial_state=start)
    except InputError as exc:
        raise CaseError(str(exc)) from None
    if settings["trim"]:
        model = model.with_x0(tuple(float(v) for v in trim_state(model, trims)))
    try:
        problem = DesignProblem(
            model,
            tuple(
                InputSpec(s["name"], s["amplitude"], s["trim"], s["band_hz"], s["pulse_s"])
                for s in settings["inputs"]
            ),
            settings["duration_s"],
            settings["dt_s"],
            settings["noise_std"],
            signal=settings["signal"],
            criterion=settings["criterion"],
            parameters=settings["parameters"],
            held=settings["held"],
            limits=settings["limits"],
            band_hz=settings["band_hz"],
            candidates=settings["candidates"],
            start_s=settings["start_s"],
            gap_s=settings["gap_s"],
            method=case.estimation.get("method", "rk4"),
            input_interpolation=input_interpolation(case),
        )
    except InputError as exc:
        message = str(exc)
        raise CaseError(message if message.startswith("design.") else f"design.{message}") from None
    return problem, settings


def _initial_numbers_or_none(case: Case, states: tuple[str, ...]) -> dict[str, float]:
    """Numeric [initial_state] entries (the trim search starts from them), others skipped."""
    values = {}
    for state in states:
        value = case.initial_state.get(state)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            values[state] = float(value)
    return values


def _reference(case: Case, problem: DesignProblem, data_dir: Path | None, settings: dict):
    """The first maneuver of [data] predicted with the same model and noise: (accuracy, facts)."""
    from flightid.cases.build import load_maneuvers, resolve_data_dir
    from flightid.design.information import predict_accuracy

    maneuver = load_maneuvers(case, resolve_data_dir(case, data_dir))[0]
    first = {n: float(maneuver.channel(n)[0]) for n in problem.model.inputs}
    model = problem.model
    if settings["trim"]:
        model = model.with_x0(tuple(float(v) for v in trim_state(model, first)))
    reference_inputs = {n: maneuver.channel(n) for n in problem.model.inputs}
    from flightid.data.flightdata import FlightData

    data = FlightData(maneuver.time, reference_inputs, name=maneuver.name)
    accuracy = predict_accuracy(
        model,
        data,
        problem.noise_std,
        method=problem.method,
        input_interpolation=problem.input_interpolation,
    )
    from flightid.simulation import simulate

    steady = FlightData(
        maneuver.time, {n: np.full(maneuver.n_samples, first[n]) for n in first}, name="trim"
    )
    flown = accuracy.outputs
    held = simulate(
        model, steady, method=problem.method, input_interpolation=problem.input_interpolation
    )
    facts = {
        "name": maneuver.name,
        # peak |y − y(trim inputs)| per output, as the design's response limits measure it
        "response_peak": {
            o: float(np.max(np.abs(flown[:, i] - held[:, i])))
            for i, o in enumerate(problem.model.outputs)
        },
        "duration_s": float(maneuver.time[-1] - maneuver.time[0]),
        # peak |u − u(t0)| per designed input: the reference's amplitude about its start
        "peak_amplitude": {
            s.name: float(np.max(np.abs(reference_inputs[s.name] - first[s.name])))
            for s in problem.inputs
        },
    }
    return accuracy, facts


def run_design_case(
    case: Case,
    data_dir: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
):
    """Run the design a case's ``[design]`` table describes; returns a ``DesignResult``."""
    import time

    from flightid.design.optimize import design_input
    from flightid.design.result import DesignResult

    if not case.design:
        raise CaseError("design: the case has no [design] table (see docs/design.md)")
    started = time.perf_counter()
    problem, settings = design_problem(case, Path(data_dir) if data_dir else None)
    if progress is not None:
        progress(
            f"designing a {problem.signal} for {list(problem.names)} over {problem.duration_s} s "
            f"({problem.criterion}, {problem.candidates} candidates)"
        )
    best, tried = design_input(problem, progress=progress)
    reference = None
    if settings["reference"]:
        reference = _reference(case, problem, Path(data_dir) if data_dir else None, settings)
    return DesignResult(
        problem=problem,
        best=best,
        tried=tuple(tried),
        reference=reference,
        title=case.title or "",
        case_file=str(case.path) if getattr(case, "path", None) else "",
        wall_time_s=time.perf_counter() - started,
    )
