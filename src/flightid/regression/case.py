"""Stepwise-regression case files (TOML) and running them.

A case names a data file, the signals taken from it and, per coefficient, the candidate terms:

    [data]
    file = "sidpac_twin_otter/totter_lon_020213f1_018.mat"   # relative to the data directory
    data_dir = "../../../shared/data"                           # relative to this case file
    format = "sidpac"                                          # fdata matrix, 1-based columns

    [signals]                      # name = column, or {column = k, unit = "deg", ...}
    alpha = { column = 4, unit = "deg" }                       # deg → rad (the unit rule)
    Cm = 65

    [stepwise]                     # options of flightid.regression.stepwise (all optional)
    f_enter = 4.0
    f_remove = 4.0
    sigma2_max = "response"        # "response", "full" or a number
    select = "pse"                 # "pse" or "final"
    forced = ["1"]

    [coefficients.Cm]
    response = "Cm"                # default: the table's name
    candidates = ["alpha", "qhat", "de", "alpha^2", "alpha*qhat", "alpha*de"]
    # any [stepwise] option may be repeated here to override it for this coefficient

    [ml]                           # optional: regression → output error (flightid regress --ml)
    model = "alpha_q"              # flightid.regression.pipeline.alpha_q_model
    solver = "mnres"               # "mnres", "mnr", "fps"; also solver_settings, convergence
    noise = "max"                  # R policy; method = "rk4" | "euler"
    input_interpolation = "linear" # input between samples: "linear" | "zoh" (held)
    time = "time"                  # the time column (s)
    prediction = ["sidpac_twin_otter/totter_lon_020213f1_017.mat"]   # prediction check
    [ml.inputs]                    # channels of the model, as in `flightid run` case files
    V = "airspeed"
    theta = { column = "theta", unit = "deg", to = "rad" }
    [ml.outputs]
    alpha = { column = "alpha", unit = "deg", to = "rad" }
    [ml.constants]                 # a number, or a column (name or number) whose mean is taken
    mass = "mass"
    g = 32.174

Units follow the one channel rule of ``flightid.data.units.channel_conversion``, in
``[signals]`` as in ``[ml.inputs]``/``[ml.outputs]`` and in ``flightid run`` case files: a
signal with ``unit`` alone is delivered in SI with angles in radians (deg → rad, deg/s →
rad/s, g → m/s²), ``to`` names another delivered unit (``to = "deg"`` keeps degrees), and an
unknown unit is refused. A signal's value is source · scale, then converted.

The data file is read with ``flightid.data.loaders`` (``format = "sidpac"``, the default, is a
MATLAB file with SIDPAC's ``fdata``/``varlab``; "mat", "csv", "ascii" and "auto" work too), so
columns are 1-based numbers or the file's column names. Term signals of the selected model
other than ``alpha`` and ``qhat`` (e.g. ``de``) are taken from ``[signals]`` unless
``[ml.inputs]`` names them. The ML stage fixes x0 at the first measured α and q of each
maneuver.

The data directory is, in order: the ``data_dir`` argument (CLI ``--data-dir``), the
environment variable ``FLIGHTID_DATA``, ``[data].data_dir`` relative to the case file, and
finally ``../../../shared/data`` relative to the case file (the repository's
``../shared/data`` for a case in ``examples/cases``). Errors name the offending key.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from flightid.data.flightdata import FlightData
from flightid.data.loaders import ChannelSpec, Table, read_table, to_flight_data
from flightid.data.location import data_directory
from flightid.data.units import channel_conversion
from flightid.errors import InputError
from flightid.model.terms import TermError, parse_term
from flightid.regression.stepwise import StepwiseResult, stepwise

__all__ = [
    "CaseError",
    "MLRun",
    "MLSpec",
    "StepwiseCase",
    "case_signals",
    "load_case",
    "resolve_data_dir",
    "run_case",
    "run_ml",
]

_STEPWISE_KEYS = {"f_enter", "f_remove", "sigma2_max", "select", "forced", "max_steps"}
_FORMATS = {"sidpac": "mat", "mat": "mat", "csv": "csv", "ascii": "ascii", "auto": "auto"}
_ML_KEYS = {
    "model",
    "solver",
    "solver_settings",
    "convergence",
    "noise",
    "method",
    "input_interpolation",
    "time",
    "prediction",
    "inputs",
    "outputs",
    "constants",
}
_ML_MODELS = ("alpha_q",)
_SOLVERS = ("mnres", "mnr", "fps")
_REQUIRED_CONSTANTS = ("mass", "S", "cbar", "Iy", "g")
_CONSTANTS = (*_REQUIRED_CONSTANTS, "Ix", "Iz", "Ixz")


class CaseError(InputError):
    """A malformed case file; the message names the key."""


@dataclass(frozen=True)
class SignalSpec:
    name: str
    column: int | str
    scale: float


@dataclass(frozen=True)
class CoefficientSpec:
    name: str
    response: str
    candidates: tuple[str, ...]
    options: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class MLSpec:
    """The ``[ml]`` section: the output-error stage seeded by the regression."""

    model: str
    time: ChannelSpec
    inputs: Mapping[str, ChannelSpec]
    outputs: Mapping[str, ChannelSpec]
    constants: Mapping[str, Any]
    prediction: tuple[str, ...] = ()
    solver: str = "mnres"
    solver_settings: Mapping[str, Any] = field(default_factory=dict)
    convergence: Mapping[str, Any] = field(default_factory=dict)
    noise: str = "max"
    method: str = "rk4"
    input_interpolation: str = "linear"


@dataclass(frozen=True)
class StepwiseCase:
    """A parsed case file."""

    path: Path
    data_file: str
    data_dir: str | None
    format: str
    signals: tuple[SignalSpec, ...]
    options: Mapping[str, Any]
    coefficients: tuple[CoefficientSpec, ...]
    ml: MLSpec | None = None


def _table(raw: Mapping, key: str, required: bool = True) -> Mapping:
    if key not in raw:
        if required:
            raise CaseError(f"case file: missing table [{key}]")
        return {}
    value = raw[key]
    if not isinstance(value, Mapping):
        raise CaseError(f"{key}: expected a table, got {type(value).__name__}")
    return value


def _options(table: Mapping, where: str) -> dict[str, Any]:
    options: dict[str, Any] = {}
    for key, value in table.items():
        if key not in _STEPWISE_KEYS:
            continue
        if key in ("f_enter", "f_remove"):
            if not isinstance(value, (int, float)) or isinstance(value, bool) or value < 0:
                raise CaseError(f"{where}.{key}: expected a non-negative number, got {value!r}")
            value = float(value)
        elif key == "sigma2_max":
            if isinstance(value, str):
                if value not in ("response", "full"):
                    raise CaseError(
                        f"{where}.sigma2_max: expected 'response', 'full' or a number, "
                        f"got {value!r}"
                    )
            elif not isinstance(value, (int, float)) or isinstance(value, bool) or value < 0:
                raise CaseError(
                    f"{where}.sigma2_max: expected a non-negative number, got {value!r}"
                )
        elif key == "select":
            if value not in ("pse", "final"):
                raise CaseError(f"{where}.select: expected 'pse' or 'final', got {value!r}")
        elif key == "forced":
            if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                raise CaseError(f"{where}.forced: expected a list of terms, got {value!r}")
            value = tuple(value)
        elif key == "max_steps":
            if not isinstance(value, int) or value < 1:
                raise CaseError(f"{where}.max_steps: expected a positive integer, got {value!r}")
        options[key] = value
    return options


def load_case(path: str | Path) -> StepwiseCase:
    """Parse and check a stepwise case file (see the module docstring)."""
    path = Path(path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CaseError(f"case file: {str(path)!r} does not exist") from None
    except tomllib.TOMLDecodeError as exc:
        raise CaseError(f"case file {str(path)!r}: invalid TOML: {exc}") from None
    data = _table(raw, "data")
    if not isinstance(data.get("file"), str):
        raise CaseError(f"data.file: expected a file name (string), got {data.get('file')!r}")
    fmt = data.get("format", "sidpac")
    if fmt not in _FORMATS:
        raise CaseError(f"data.format: expected one of {sorted(_FORMATS)}, got {fmt!r}")
    data_dir = data.get("data_dir")
    if data_dir is not None and not isinstance(data_dir, str):
        raise CaseError(f"data.data_dir: expected a path (string), got {data_dir!r}")

    signals = []
    for name, spec in _table(raw, "signals").items():
        where = f"signals.{name}"
        if not name.isidentifier():
            raise CaseError(f"{where}: signal names must be identifiers")
        if isinstance(spec, (int, str)) and not isinstance(spec, bool):
            spec = {"column": spec}
        if not isinstance(spec, Mapping):
            raise CaseError(
                f"{where}: expected a column (number or name) or {{column, unit}}, got {spec!r}"
            )
        unknown = sorted(set(spec) - {"column", "unit", "to", "scale"})
        if unknown:
            raise CaseError(f"{where}: unknown keys {unknown}; expected column, unit, to, scale")
        col = spec.get("column")
        if not _is_column(col):
            raise CaseError(
                f"{where}.column: expected a 1-based column number or a column name, got {col!r}"
            )
        unit, to = spec.get("unit", ""), spec.get("to", "")
        try:
            # the one channel rule: unit alone → SI (angles in rad), unit and to → to
            factor, _ = channel_conversion(unit, to)
        except InputError as exc:
            raise CaseError(f"{where}.{'unit' if unit else 'to'}: {exc}") from None
        scale = spec.get("scale", 1.0)
        if not isinstance(scale, (int, float)) or isinstance(scale, bool):
            raise CaseError(f"{where}.scale: expected a number, got {scale!r}")
        # value = (source · scale) · factor
        signals.append(SignalSpec(name, col, float(scale) * factor))

    options = _options(_table(raw, "stepwise", required=False), "stepwise")
    coefficients = []
    known = {s.name for s in signals}
    for name, table in _table(raw, "coefficients").items():
        where = f"coefficients.{name}"
        if not isinstance(table, Mapping):
            raise CaseError(f"{where}: expected a table")
        response = table.get("response", name)
        if response not in known:
            raise CaseError(
                f"{where}.response: {response!r} is not a signal; signals: {sorted(known)}"
            )
        candidates = table.get("candidates")
        if (
            not isinstance(candidates, list)
            or not candidates
            or not all(isinstance(c, str) for c in candidates)
        ):
            raise CaseError(f"{where}.candidates: expected a non-empty list of terms")
        for c in candidates:
            try:
                term = parse_term(c)
            except TermError as exc:
                raise CaseError(f"{where}.candidates: {exc}") from None
            missing = sorted(set(term.signals) - known)
            if missing:
                raise CaseError(
                    f"{where}.candidates: term {c!r} uses unknown signals {missing}; "
                    f"signals: {sorted(known)}"
                )
        unknown = sorted(set(table) - _STEPWISE_KEYS - {"response", "candidates"})
        if unknown:
            raise CaseError(f"{where}: unknown keys {unknown}")
        coefficients.append(
            CoefficientSpec(name, response, tuple(candidates), _options(table, where))
        )
    if not coefficients:
        raise CaseError("coefficients: expected at least one [coefficients.NAME] table")
    ml = _ml_spec(_table(raw, "ml", required=False)) if "ml" in raw else None
    unknown = sorted(set(raw) - {"data", "signals", "stepwise", "coefficients", "ml"})
    if unknown:
        raise CaseError(
            f"{unknown[0]}: unknown table; expected data, signals, stepwise, coefficients, ml"
        )
    return StepwiseCase(
        path, data["file"], data_dir, fmt, tuple(signals), options, tuple(coefficients), ml
    )


def _is_column(value: Any) -> bool:
    if isinstance(value, bool):
        return False
    return (isinstance(value, int) and value >= 1) or (isinstance(value, str) and bool(value))


def _channels(table: Any, where: str) -> dict[str, ChannelSpec]:
    if not isinstance(table, Mapping):
        raise CaseError(f"{where}: expected a table of channel = column or {{column, ...}}")
    specs = {}
    for name, value in table.items():
        if not name.isidentifier():
            raise CaseError(f"{where}.{name}: channel names must be identifiers")
        try:
            specs[name] = ChannelSpec.from_value(value, f"{where}.{name}")
        except InputError as exc:
            message = str(exc)
            raise CaseError(
                message if message.startswith(where) else f"{where}.{name}: {message}"
            ) from None
    return specs


def _choice(table: Mapping, key: str, default: str, choices: tuple[str, ...]) -> str:
    value = table.get(key, default)
    if value not in choices:
        raise CaseError(f"ml.{key}: expected one of {list(choices)}, got {value!r}")
    return value


def _ml_spec(table: Mapping) -> MLSpec:
    """Check the ``[ml]`` section (see the module docstring)."""
    unknown = sorted(set(table) - _ML_KEYS)
    if unknown:
        raise CaseError(f"ml.{unknown[0]}: unknown key; allowed: {sorted(_ML_KEYS)}")
    model = _choice(table, "model", "alpha_q", _ML_MODELS)
    time = _channels({"time": table.get("time", 1)}, "ml")["time"]
    inputs = _channels(table.get("inputs", {}), "ml.inputs")
    if "outputs" not in table:
        raise CaseError("ml.outputs: missing; the alpha_q model needs alpha, q and az")
    outputs = _channels(table["outputs"], "ml.outputs")
    missing = [n for n in ("alpha", "q", "az") if n not in outputs]
    if missing:
        raise CaseError(f"ml.outputs: missing {missing} (the alpha_q model's outputs)")
    from flightid.regression.pipeline import ALPHA_Q_INPUTS
    from flightid.simulate.simulator import INPUT_INTERPOLATIONS

    missing = [n for n in ALPHA_Q_INPUTS if n not in inputs]
    if missing:
        raise CaseError(f"ml.inputs: missing {missing} (measured inputs of the alpha_q model)")
    constants = table.get("constants", {})
    if not isinstance(constants, Mapping):
        raise CaseError("ml.constants: expected a table of name = number or column")
    for name, value in constants.items():
        where = f"ml.constants.{name}"
        if name not in _CONSTANTS:
            raise CaseError(f"{where}: unknown constant; expected {list(_CONSTANTS)}")
        if isinstance(value, Mapping):
            if set(value) != {"column"} or not _is_column(value["column"]):
                raise CaseError(f"{where}: expected {{column = number or name}}, got {value!r}")
        elif isinstance(value, bool) or not isinstance(value, (int, float, str)) or value == "":
            raise CaseError(
                f"{where}: expected a number, a column name or {{column = N}}, got {value!r}"
            )
    missing = [n for n in _REQUIRED_CONSTANTS if n not in constants]
    if missing:
        raise CaseError(
            f"ml.constants: missing {missing}; give them in the data's unit system "
            "(g: 9.80665 m/s² or 32.174 ft/s²)"
        )
    prediction = table.get("prediction", [])
    if isinstance(prediction, str):
        prediction = [prediction]
    if not isinstance(prediction, list) or not all(isinstance(f, str) for f in prediction):
        raise CaseError(
            f"ml.prediction: expected a file name or a list of them, got {prediction!r}"
        )
    for key in ("solver_settings", "convergence"):
        if not isinstance(table.get(key, {}), Mapping):
            raise CaseError(f"ml.{key}: expected a table")
    return MLSpec(
        model=model,
        time=time,
        inputs=inputs,
        outputs=outputs,
        constants=dict(constants),
        prediction=tuple(prediction),
        solver=_choice(table, "solver", "mnres", _SOLVERS),
        solver_settings=dict(table.get("solver_settings", {})),
        convergence=dict(table.get("convergence", {})),
        noise=_choice(table, "noise", "max", ("max", "maxlik")),
        method=_choice(table, "method", "rk4", ("rk4", "euler")),
        input_interpolation=_choice(table, "input_interpolation", "linear", INPUT_INTERPOLATIONS),
    )


def resolve_data_dir(case: StepwiseCase, data_dir: str | Path | None = None) -> Path:
    """The data directory (see the module docstring for the order)."""
    return data_directory(case.path.parent, case.data_dir, data_dir)


def _read(case: StepwiseCase, data_dir: str | Path | None, file: str, key: str) -> Table:
    """The table of one data file of the case (``key`` names the case key for errors)."""
    directory = resolve_data_dir(case, data_dir)
    if not directory.is_dir():
        raise CaseError(
            f"data.data_dir: the data directory {directory} does not exist (set data.data_dir, "
            "FLIGHTID_DATA or --data-dir)"
        )
    path = directory / file
    try:
        return read_table(path, _FORMATS[case.format])
    except InputError as exc:
        raise CaseError(f"{key}: {exc}") from None


def _signals(case: StepwiseCase, table: Table) -> dict[str, np.ndarray]:
    return {
        s.name: s.scale * table.column(s.column, f"signals.{s.name}.column") for s in case.signals
    }


def case_signals(case: StepwiseCase, data_dir: str | Path | None = None) -> dict[str, np.ndarray]:
    """Read the case's data file and return its named signals (converted units)."""
    return _signals(case, _read(case, data_dir, case.data_file, "data.file"))


def run_case(
    case: StepwiseCase | str | Path, data_dir: str | Path | None = None
) -> dict[str, StepwiseResult]:
    """Run stepwise regression for every coefficient of the case."""
    if not isinstance(case, StepwiseCase):
        case = load_case(case)
    signals = case_signals(case, data_dir)
    results = {}
    for coefficient in case.coefficients:
        options = {**case.options, **coefficient.options}
        results[coefficient.name] = stepwise(
            signals[coefficient.response],
            coefficient.candidates,
            signals,
            response=coefficient.name,
            **options,
        )
    return results


# ------------------------------------------------------------------ regression → output error


@dataclass(frozen=True, eq=False)
class MLRun:
    """The output-error stage of a stepwise case: estimate on the case's data file, seeded
    by the regression, and the prediction check on ``[ml].prediction``."""

    pipeline: Any  # flightid.regression.pipeline.PipelineResult
    data: FlightData
    constants: Mapping[str, float]
    predictions: tuple = ()  # flightid.cases.run.Prediction, one per prediction file

    @property
    def estimate(self):
        return self.pipeline.estimate

    def to_dict(self) -> dict:
        """``Estimate.to_dict()`` plus ``model``, ``maneuvers``, ``start`` (the regression
        estimates the ML started from), ``constants`` and ``prediction`` (per maneuver:
        ``maneuver``, ``samples``, ``outputs``, ``rms_error``, ``r2``, as in ``flightid run``)."""
        entry = self.estimate.to_dict()
        entry["model"] = self.pipeline.model.name
        entry["maneuvers"] = [
            {"name": self.data.name, "samples": self.data.n_samples, "dt": self.data.dt}
        ]
        entry["start"] = {p.name: float(p.value) for p in self.pipeline.start}
        entry["constants"] = {k: float(v) for k, v in self.constants.items()}
        entry["prediction"] = [p.to_dict() for p in self.predictions]
        return entry

    def summary(self) -> str:
        lines = [
            f"Regression → output error ({self.pipeline.model.name}, maneuver {self.data.name})",
            self.pipeline.comparison(),
            "",
            self.estimate.summary(),
        ]
        for p in self.predictions:
            lines.append(f"\nprediction on {p.name} (x0 at its first measured alpha, q):")
            lines += [
                f"  {n:<8} RMS error {e:.4g}   R² {r:.4f}"
                for n, e, r in zip(p.output_names, p.rms, p.r2, strict=True)
            ]
        return "\n".join(lines)


def _constants(spec: MLSpec, table: Table) -> dict[str, float]:
    """Numbers as given; columns (by name or ``{column = N}``) as their mean over the file."""
    values = {}
    for name, value in spec.constants.items():
        if isinstance(value, (int, float)):
            values[name] = float(value)
            continue
        column = value["column"] if isinstance(value, Mapping) else value
        try:
            values[name] = float(np.mean(table.column(column, f"ml.constants.{name}")))
        except InputError as exc:
            raise CaseError(str(exc)) from None
    return values


def _ml_data(case: StepwiseCase, table: Table, name: str, extras: list[str]) -> FlightData:
    """FlightData of one maneuver for the ML model: ``[ml.inputs]`` and ``[ml.outputs]``, plus
    the term signals ``extras`` from ``[signals]`` unless ``[ml.inputs]`` names them."""
    spec = case.ml
    signals = {s.name: s for s in case.signals}
    inputs = dict(spec.inputs)
    for signal in extras:
        if signal in inputs:
            continue
        if signal not in signals:
            raise CaseError(
                f"ml.inputs.{signal}: missing; the selected terms use {signal!r} and "
                "[signals] does not define it"
            )
        inputs[signal] = ChannelSpec(column=signals[signal].column, scale=signals[signal].scale)
    try:
        return to_flight_data(
            table,
            time=spec.time,
            inputs=inputs,
            outputs=spec.outputs,
            name=name,
            uniform_rtol=1e-4,
        )
    except InputError as exc:
        raise CaseError(f"ml ({name}): {exc}") from None


def _solver(spec: MLSpec) -> tuple[Any, Any]:
    """(solver, convergence rules) of the ML stage."""
    from flightid.estimation import FPS, MNR, MNRES, Convergence

    solver_class = {"mnres": MNRES, "mnr": MNR, "fps": FPS}[spec.solver]
    try:
        solver = solver_class(**spec.solver_settings)
    except (TypeError, InputError) as exc:
        raise CaseError(f"ml.solver_settings: {exc}") from None
    try:
        convergence = Convergence(**spec.convergence)
    except (TypeError, InputError) as exc:
        raise CaseError(f"ml.convergence: {exc}") from None
    return solver, convergence


def run_ml(
    case: StepwiseCase,
    results: Mapping[str, StepwiseResult],
    data_dir: str | Path | None = None,
    progress=None,
) -> MLRun:
    """Output-error ML on the case's data file, structure and start values from ``results``
    (``regression_to_ml`` with ``alpha_q_model``), then the prediction check.

    Args:
        case: a stepwise case with an ``[ml]`` section.
        results: ``run_case(case)``.
        data_dir: data directory override.
        progress: callable receiving one-line messages (None: silent).
    """
    from flightid.cases.run import Prediction
    from flightid.regression.pipeline import (
        LinearAeroStructure,
        alpha_q_model,
        regression_to_ml,
    )
    from flightid.simulate import simulate

    if case.ml is None:
        raise CaseError("ml: the case has no [ml] section (model, inputs, outputs, constants)")
    say = progress or (lambda message: None)
    spec = case.ml
    table = _read(case, data_dir, case.data_file, "data.file")
    constants = _constants(spec, table)
    extras = [
        s
        for s in LinearAeroStructure.from_stepwise(results).signals()
        if s not in ("alpha", "qhat")
    ]
    data = _ml_data(case, table, Path(case.data_file).stem, extras)

    def x0_of(maneuver: FlightData) -> tuple[float, float]:
        return float(maneuver.output("alpha")[0]), float(maneuver.output("q")[0])

    def build(structure, parameters):
        return alpha_q_model(structure, parameters, x0=x0_of(data), **constants)

    solver, convergence = _solver(spec)
    # the input between samples ("linear" or "zoh"); passed on only when not the default
    interpolation = {} if spec.input_interpolation == "linear" else {"input_interpolation": "zoh"}
    say(
        f"regression → ML: {len(extras) + 2} signals, {data.n_samples} samples of "
        f"{data.name}; solver {spec.solver}, noise {spec.noise}"
    )
    pipeline = regression_to_ml(
        results,
        build,
        data,
        solver=solver,
        method=spec.method,
        noise=spec.noise,
        convergence=convergence,
        **interpolation,
    )
    est = pipeline.estimate
    say(
        f"{est.status}: {est.iterations} iterations, {est.equivalent_evaluations} evaluations, "
        f"cost {est.cost:.6g}, {est.wall_time_s:.1f} s"
    )
    predictions = []
    for k, file in enumerate(spec.prediction):
        other = _read(case, data_dir, file, f"ml.prediction[{k}]")
        maneuver = _ml_data(case, other, Path(file).stem, extras)
        predicted = simulate(
            est.model.with_x0(x0_of(maneuver)),
            maneuver,
            method=spec.method,
            input_interpolation=spec.input_interpolation,
        )
        measured = np.column_stack([maneuver.output(n) for n in est.output_names])
        prediction = Prediction.from_outputs(
            maneuver.name, maneuver.time, measured, predicted, est.output_names
        )
        say(
            f"prediction on {prediction.name}: "
            + ", ".join(
                f"{n} RMS {e:.4g}, R² {r:.3f}"
                for n, e, r in zip(
                    prediction.output_names, prediction.rms, prediction.r2, strict=True
                )
            )
        )
        predictions.append(prediction)
    return MLRun(pipeline, data, constants, tuple(predictions))
