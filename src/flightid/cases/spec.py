"""Case files (TOML): reading and checking, with every error naming the key.

A case file describes one output-error estimation from flight data (see ``docs/cases.md`` for
the walk-through and every key)::

    title = "HFB-320 longitudinal"

    [data]                                  # files relative to the data directory
    files = ["fvsysid/hfb320_1_10.asc"]     # one maneuver per file ([[data.maneuvers]] too)
    time = 1                                # column of time, s
    [data.inputs]                           # channel = column | "expression" | {column, ...}
    de = 2
    [data.outputs]
    alpha = { column = 6, unit = "rad" }

    [model]
    module = "../models/hfb320.py"          # a Python file with STATES, INPUTS, OUTPUTS,
                                            # PARAMETERS, f and h   (or type = "lateral" ...)
    [parameters]                            # start values; {value, free, scale, lower, upper}
    CD0 = 5.67516e-3

    [initial_state]                         # per state: number, list (per maneuver),
    V = 106.023                             # "measured", "estimate", or {value, free, channel}

    [biases.states] / [biases.outputs]      # name = start | {value, free, per_maneuver}
    [estimation]                            # solver, method, noise (R policy), R, settings
    [accuracy]                              # confidence, bound_factor, correlation_warning,
                                            # methods (["cr", "profile", "search"]), budget,
                                            # seed, kind, distribution
    [prediction]                            # maneuvers to predict with the estimated model
    [output]                                # figures, figure_format, report, dir
    [flying_qualities]                      # class ("I" … "IV"), category ("A", "B", "C"):
                                            # the report judges the modes (MIL-F-8785C)

    [[stages]]                              # optional: an ordered list of stages, e.g.
    kind = "stepwise"                       # stepwise → output error → prediction
    [stages.coefficients.Cm]                # (see flightid.cases.stagespec, docs/cases.md)
    candidates = ["alpha", "qhat", "de"]

A file without ``[[stages]]`` is one output-error estimation ([estimation]) followed by the
accuracy assessment ([accuracy]) and the prediction check ([prediction]).

This module only parses and checks types and keys; ``flightid.cases.build`` makes the
objects. Nothing is evaluated: expressions and terms go to their own safe parsers.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

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
from flightid.cases.settings import (  # noqa: F401 (the shared sections, read from here too)
    ACCURACY_METHODS,
    DISTRIBUTIONS,
    ESTIMATORS,
    FILTER_GRADIENTS,
    FILTER_LINEARISATIONS,
    FILTER_RELAXATIONS,
    INPUT_INTERPOLATIONS,
    INTERVAL_KINDS,
    METHODS,
    NOISE,
    SOLVER_CLASSES,
    SOLVERS,
    ManeuverSpec,
    StageSpec,
    _initial_state_types,
    _maneuvers,
    _positive,
    accuracy_settings,
    estimation_settings,
    flying_qualities_settings,
    prediction_settings,
)
from flightid.data.loaders import ChannelSpec
from flightid.errors import InputError
from flightid.model.statespace import DELAY_CONVENTIONS

__all__ = ["CaseError", "Case", "ManeuverSpec", "StageSpec", "load_case", "parse_case"]


_TOP = {
    "title",
    "description",
    "data",
    "model",
    "parameters",
    "initial_state",
    "biases",
    "estimation",
    "accuracy",
    "prediction",
    "output",
    "stages",
    "process_noise",
    # estimators and tools with their own table, checked by their own module
    "recursive",  # flightid.cases.recursive_case (EKF, UKF, EFRLS, FTR)
    "frequency_domain",  # flightid.cases.frequency_case
    "design",  # flightid.cases.design_case (flightid design CASE.toml)
    "flying_qualities",  # class and category of the modes' flying-quality check
}
# keys of the old `flightid regress` dialect, and where they went in the one language
_MIGRATED = {
    "signals": "channels go in [data.inputs] / [data.outputs] (the same channel grammar: "
    "column, unit, to, scale, expr)",
    "stepwise": 'stepwise options go in a [[stages]] table with kind = "stepwise" '
    "(f_enter, f_remove, sigma2_max, select, forced, max_steps)",
    "coefficients": "[coefficients.NAME] becomes [stages.coefficients.NAME] of a "
    'kind = "stepwise" stage (response, candidates)',
    "ml": 'the output-error stage is a [[stages]] table with kind = "output_error" and '
    'from = "previous" (solver, noise, method, ...); [ml.inputs]/[ml.outputs] go in '
    "[data.inputs]/[data.outputs], [ml.constants] in [model.constants] with "
    '[model] type = "alpha_q", ml.prediction in a kind = "prediction" stage (files)',
}
_DATA = {
    "data_dir",
    "format",
    "variable",
    "time",
    "gaps",
    "dt",
    "resample_hz",
    "max_gap_s",
    "allow_retime",
    "file",
    "files",
    "maneuvers",
    "inputs",
    "outputs",
    "start",
    "stop",
    "constants",
    "signals",
    "steps",
}
_MODEL = {
    "module",
    "type",
    "airplane",
    "aero",
    "controls",
    "outputs",
    "name",
    "accelerometer",
    "measured",
    "reference_speed",
    "rate_speed",
    "output_delays",
    "input_delays",
    "delay_convention",
}
_OUTPUT = {"figures", "report", "dir", "figure_format"}
# [output] figure_format: the report figures' files (SVG written from the arrays, or PNG
# drawn by matplotlib)
FIGURE_FORMATS = ("svg", "png")
AIRCRAFT_TYPES = ("wind_axis_longitudinal", "longitudinal", "lateral", "six_dof")
# "alpha_q": α and q integrated, the other flight variables measured (flightid.cases.alpha_q);
# "kinematic": flight-path reconstruction (flightid.compat)
MODEL_TYPES = (*AIRCRAFT_TYPES, "alpha_q", "kinematic")
_ALPHA_Q_MODEL = {"type", "name", "constants", "aero"}
# [model] type = "linear": a linear model declared by term tables (flightid.model.linear)
_LINEAR_MODEL = {
    "type",
    "name",
    "states",
    "inputs",
    "outputs",
    "constants",
    "parameters",
    "derivatives",
    "output_equations",
    "output_delays",
    "input_delays",
    "delay_convention",
}


@dataclass(frozen=True)
class Case:
    """A checked case file (plain data; ``flightid.cases.build`` makes the objects)."""

    path: Path
    title: str
    description: str
    data: Mapping[str, Any]
    maneuvers: tuple[ManeuverSpec, ...]
    model: Mapping[str, Any]
    parameters: Mapping[str, Any]
    initial_state: Mapping[str, Any]
    biases: Mapping[str, Mapping[str, Any]]
    estimation: Mapping[str, Any]
    accuracy: Mapping[str, Any]
    prediction: tuple[ManeuverSpec, ...]
    prediction_initial_state: Mapping[str, Any]
    output: Mapping[str, Any]
    raw: Mapping[str, Any] = field(repr=False, default_factory=dict)
    stages: tuple[StageSpec, ...] = ()
    # [process_noise]: state → {value, free, name, scale} (filter error method)
    process_noise: Mapping[str, Any] = field(default_factory=dict)
    # [recursive], [frequency_domain], [design]: the raw tables; their own modules check them
    recursive: Mapping[str, Any] = field(default_factory=dict)
    frequency_domain: Mapping[str, Any] = field(default_factory=dict)
    design: Mapping[str, Any] = field(default_factory=dict)
    # [flying_qualities]: {class, category, speed?, n_alpha?, include_unverified?} or {}
    flying_qualities: Mapping[str, Any] = field(default_factory=dict)

    @property
    def staged(self) -> bool:
        """True when the file lists ``[[stages]]`` (else: one output-error estimation)."""
        return bool(self.stages)

    @property
    def directory(self) -> Path:
        return self.path.parent


# ------------------------------------------------------------------------------ sections


def _top_level(raw: Mapping[str, Any]) -> None:
    """Known top-level keys; the old `flightid regress` keys get a migration message."""
    for old, new in _MIGRATED.items():
        if old in raw:
            raise CaseError(
                f"{old}: a key of the old `flightid regress` case files; in the one case "
                f"language (docs/cases.md, 'One case language') {new}"
            )
    _known(raw, _TOP, "")
    if _batch_only(raw):
        if "data" in raw:
            raise CaseError(
                "data: the case's stages all take their maneuvers from batch folders "
                "(global_model stages with batch = ...), so [data] would not be read; remove it"
            )
        return
    # a file of regression stages alone needs no model
    for required in ("data",) if "stages" in raw else ("data", "model"):
        if required not in raw:
            raise CaseError(f"{required}: missing section [{required}]")


def _batch_only(raw: Mapping[str, Any]) -> bool:
    """True when every ``[[stages]]`` entry is a global_model stage with ``batch``: such a
    case has no data of its own and no ``[data]`` section."""
    from flightid.cases.globalmodel_case import is_batch_stage

    stages = raw.get("stages")
    return isinstance(stages, list) and bool(stages) and all(map(is_batch_stage, stages))


def _channels(data: Mapping[str, Any]) -> None:
    """``[data.inputs]`` / ``[data.outputs]``: the channel grammar of ``ChannelSpec``."""
    for key in ("inputs", "outputs"):
        for name, value in _table(data.get(key, {}), f"data.{key}").items():
            column = value.get("column") if isinstance(value, Mapping) else None
            if column is not None and (
                isinstance(column, bool)
                or not isinstance(column, (int, str))
                or (isinstance(column, int) and column < 1)
                or column == ""
            ):
                raise CaseError(
                    f"data.{key}.{name}.column: expected a column number (1, 2, ...) or a "
                    f"column name, got {column!r}"
                )
            try:
                ChannelSpec.from_value(value, f"data.{key}.{name}")
            except InputError as exc:
                message = str(exc)
                if not message.startswith("data."):
                    message = f"data.{key}.{name}: {message}"
                raise CaseError(message) from None


def _pipeline(data: Mapping[str, Any]) -> None:
    """``[data.constants]``, ``[data.signals]``, ``[[data.steps]]``: checked without data
    (settings, constants named by steps, cycles, declared units; ``flightid.data.pipeline``)."""
    from flightid.data.pipeline import parse_pipeline

    try:
        parse_pipeline(data.get("constants"), data.get("signals"), data.get("steps"))
    except InputError as exc:
        raise CaseError(f"data.{exc}") from None


def _data_section(raw: Mapping[str, Any], staged: bool) -> tuple[Mapping[str, Any], list]:
    """``[data]``: (the table, its maneuvers)."""
    data = _table(raw["data"], "data")
    _known(data, _DATA, "data")
    if data.get("format") == "sidpac":
        raise CaseError(
            'data.format: "sidpac" was a `flightid regress` name; SIDPAC fdata files are '
            'MATLAB files: format = "mat" (or leave it out)'
        )
    _channels(data)
    _pipeline(data)
    if not staged and not data.get("outputs"):
        raise CaseError("data.outputs: missing; name the measured output channels")
    if "data_dir" in data:
        _string(data["data_dir"], "data.data_dir")
    time = data.get("time", 1)
    if not isinstance(time, str):
        _integer(time, "data.time", 1)
    return data, _maneuvers(data, "data", data)


def _model_section(raw: Mapping[str, Any]) -> Mapping[str, Any]:
    """``[model]``: a user module, a built-in airplane model or the α–q model."""
    if "model" not in raw:
        return {}
    model = _table(raw["model"], "model")
    if model.get("type") == "alpha_q":
        return _alpha_q_section(model)
    if model.get("type") == "linear":
        return _linear_section(model)
    if model.get("type") == "kinematic":
        from flightid.cases.compat_case import kinematic_section

        return kinematic_section(model)
    _known(model, _MODEL, "model")
    if ("module" in model) == ("type" in model):
        raise CaseError(
            "model: give exactly one of 'module' (a Python file with f and h) and 'type' "
            f"(a built-in airplane model: {list(MODEL_TYPES)})"
        )
    if "name" in model:
        _string(model["name"], "model.name")
    for key in ("controls", "outputs", "measured"):
        if key in model:
            _names(model[key], f"model.{key}")
    # output_delays = { output = "parameter" }: the output is delayed by that parameter (s);
    # the output and parameter names are checked with the model (cases.build)
    for output, parameter in _table(model.get("output_delays", {}), "model.output_delays").items():
        if not isinstance(parameter, str) or not parameter.isidentifier():
            raise CaseError(
                f"model.output_delays.{output}: expected a parameter name (the delay in s), "
                f"got {parameter!r}"
            )
    # input_delays = { input = "parameter" }: the model reads that input at t − τ (s)
    for channel, parameter in _table(model.get("input_delays", {}), "model.input_delays").items():
        if not isinstance(parameter, str) or not parameter.isidentifier():
            raise CaseError(
                f"model.input_delays.{channel}: expected a parameter name (the delay in s), "
                f"got {parameter!r}"
            )
    if "delay_convention" in model:
        _string(model["delay_convention"], "model.delay_convention", DELAY_CONVENTIONS)
    if "module" in model:
        _string(model["module"], "model.module")
        for key in ("airplane", "aero", "controls"):
            if key in model:
                raise CaseError(f"model.{key}: only used with a built-in 'type', not a module")
    else:
        _string(model["type"], "model.type", MODEL_TYPES)
        for key in ("airplane", "aero"):
            if key not in model:
                raise CaseError(f"model.{key}: missing; a built-in airplane model needs it")
            _table(model[key], f"model.{key}")
    return model


def _linear_section(model: Mapping[str, Any]) -> Mapping[str, Any]:
    """``[model] type = "linear"``: states, inputs, outputs (lists of names), parameters
    ({name = start value}), constants ({name = number}), derivatives ({state = [terms]}),
    output_equations ({output = [terms]}); the terms are read by ``flightid.model.linear``."""
    _known(model, _LINEAR_MODEL, "model")
    for key in ("states", "inputs", "outputs", "parameters", "derivatives", "output_equations"):
        if key not in model:
            raise CaseError(f"model.{key}: missing; a linear model declared by terms needs it")
    for key in ("states", "inputs", "outputs"):
        _names(model[key], f"model.{key}")
    for key in ("parameters", "constants"):
        for name, value in _table(model.get(key, {}), f"model.{key}").items():
            _number(value, f"model.{key}.{name}")
    for key in ("derivatives", "output_equations"):
        for name, terms in _table(model[key], f"model.{key}").items():
            if isinstance(terms, str):
                continue
            if not isinstance(terms, list) or not all(isinstance(t, str) for t in terms):
                raise CaseError(
                    f"model.{key}.{name}: expected a list of terms such as ['Zw*w', 'u0*q'], "
                    f"got {terms!r}"
                )
    if "name" in model:
        _string(model["name"], "model.name")
    if "delay_convention" in model:
        _string(model["delay_convention"], "model.delay_convention", DELAY_CONVENTIONS)
    return model


ALPHA_Q_CONSTANTS = ("mass", "S", "cbar", "Iy", "g")
ALPHA_Q_OPTIONAL = ("Ix", "Iz", "Ixz")


def _alpha_q_section(model: Mapping[str, Any]) -> Mapping[str, Any]:
    """``[model] type = "alpha_q"``: ``constants`` (numbers, column names or {column = N}:
    the column's mean over the first maneuver) and ``aero`` ({CZ = [terms], Cm = [terms]})."""
    _known(model, _ALPHA_Q_MODEL, "model")
    if "name" in model:
        _string(model["name"], "model.name")
    constants = _table(model.get("constants", {}), "model.constants")
    for name, value in constants.items():
        where = f"model.constants.{name}"
        if name not in ALPHA_Q_CONSTANTS + ALPHA_Q_OPTIONAL:
            raise CaseError(
                f"{where}: unknown constant; expected {list(ALPHA_Q_CONSTANTS + ALPHA_Q_OPTIONAL)}"
            )
        if isinstance(value, Mapping):
            _known(value, {"column"}, where)
            if "column" not in value:
                raise CaseError(f"{where}: expected {{column = number or name}}, got {value!r}")
            column = value["column"]
            if isinstance(column, bool) or not isinstance(column, (int, str)) or column in ("", 0):
                raise CaseError(f"{where}.column: expected a column number or name, got {column!r}")
        elif isinstance(value, str):
            _string(value, where)
        else:
            _number(value, where)
    missing = [n for n in ALPHA_Q_CONSTANTS if n not in constants]
    if missing:
        raise CaseError(
            f"model.constants: missing {missing}; give them in the data's unit system "
            "(g: 9.80665 m/s² or 32.174 ft/s²)"
        )
    if "aero" in model:
        aero = _table(model["aero"], "model.aero")
        _known(aero, {"CZ", "Cm"}, "model.aero")
        for coefficient in ("CZ", "Cm"):
            if coefficient not in aero:
                raise CaseError(f"model.aero.{coefficient}: missing; the α–q model needs CZ and Cm")
            _names(aero[coefficient], f"model.aero.{coefficient}")
    return model


def _parameters_section(raw: Mapping[str, Any]) -> Mapping[str, Any]:
    """``[parameters]``: name = start value, or {value, free, scale, lower, upper, unit,
    per_maneuver} (per_maneuver = true: one copy NAME_1, NAME_2, ... per maneuver)."""
    parameters = _table(raw.get("parameters", {}), "parameters")
    for name, value in parameters.items():
        where = f"parameters.{name}"
        if not isinstance(value, Mapping):
            _number(value, where)
            continue
        _known(value, {"value", "free", "scale", "lower", "upper", "unit", "per_maneuver"}, where)
        for key, check in (
            ("value", _number),
            ("free", _bool),
            ("scale", _positive),
            ("per_maneuver", _bool),
        ):
            if key in value:
                check(value[key], f"{where}.{key}")
        for bound in ("lower", "upper"):
            if bound in value:
                _number(value[bound], f"{where}.{bound}", infinite=True)
        lower, upper = value.get("lower", -math.inf), value.get("upper", math.inf)
        if not lower < upper:
            raise CaseError(f"{where}.lower: expected lower < upper, got [{lower}, {upper}]")
        if "unit" in value:
            _string(value["unit"], f"{where}.unit")
    return parameters


def _bias_entry(value: Any, where: str) -> None:
    if not isinstance(value, Mapping):
        _number(value, where)
        return
    _known(value, {"value", "free", "per_maneuver", "scale"}, where)
    for key, check in (
        ("value", _number),
        ("free", _bool),
        ("per_maneuver", _bool),
        ("scale", _positive),
    ):
        if key in value:
            check(value[key], f"{where}.{key}")


def _biases_section(raw: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """``[biases.states]`` / ``[biases.outputs]``: name = start | {value, free, per_maneuver}."""
    biases = _table(raw.get("biases", {}), "biases")
    _known(biases, {"states", "outputs"}, "biases")
    for kind in ("states", "outputs"):
        for name, value in _table(biases.get(kind, {}), f"biases.{kind}").items():
            _bias_entry(value, f"biases.{kind}.{name}")
    return {k: dict(biases.get(k, {})) for k in ("states", "outputs")}


def _process_noise_section(raw: Mapping[str, Any], estimation: Mapping[str, Any]) -> dict:
    """``[process_noise]``: state = start value of its F element, or {value, free, name,
    scale}; only with ``[estimation] estimator = "filter_error"``, which needs it."""
    section = _table(raw.get("process_noise", {}), "process_noise")
    filter_error = estimation.get("estimator", "output_error") == "filter_error"
    if section and not filter_error:
        raise CaseError(
            "process_noise: only used by the filter error method; set [estimation] estimator = "
            '"filter_error"'
        )
    if filter_error and not section:
        raise CaseError(
            "process_noise: missing; the filter error method needs the process-noise elements "
            "F_ii (state = start value, or {value, free, name})"
        )
    for state, value in section.items():
        where = f"process_noise.{state}"
        if not isinstance(value, Mapping):
            _number(value, where)
            continue
        _known(value, {"value", "free", "name", "scale"}, where)
        if "value" not in value:
            raise CaseError(f"{where}.value: missing (the start value of the F element)")
        _number(value["value"], f"{where}.value")
        if "free" in value:
            _bool(value["free"], f"{where}.free")
        if "scale" in value:
            _positive(value["scale"], f"{where}.scale")
        if "name" in value:
            name = _string(value["name"], f"{where}.name")
            if not name.isidentifier():
                raise CaseError(f"{where}.name: expected an identifier, got {name!r}")
    return dict(section)


def _output_section(raw: Mapping[str, Any]) -> Mapping[str, Any]:
    output = _table(raw.get("output", {}), "output")
    _known(output, _OUTPUT, "output")
    for key in ("figures", "report"):
        if key in output:
            _bool(output[key], f"output.{key}")
    if "dir" in output:
        _string(output["dir"], "output.dir")
    if "figure_format" in output and output["figure_format"] not in FIGURE_FORMATS:
        raise CaseError(
            f"output.figure_format: expected one of {', '.join(map(repr, FIGURE_FORMATS))} "
            f"(the report figures' files: SVG written from the arrays, or PNG drawn by "
            f"matplotlib), got {output['figure_format']!r}"
        )
    return output


def _single_run(raw: Mapping[str, Any], data: Mapping[str, Any]) -> dict[str, Any]:
    """A file without ``[[stages]]``: [estimation], [accuracy] and [prediction]."""
    estimation = _table(raw.get("estimation", {}), "estimation")
    estimation_settings(estimation)
    accuracy = _table(raw.get("accuracy", {}), "accuracy")
    accuracy_settings(accuracy)
    prediction, x0 = prediction_settings(_table(raw.get("prediction", {}), "prediction"), data)
    return {
        "estimation": estimation,
        "accuracy": accuracy,
        "prediction": tuple(prediction),
        "prediction_initial_state": x0,
    }


# ------------------------------------------------------------------------------ parsing


def parse_case(raw: Mapping[str, Any], path: Path) -> Case:
    """Check the structure of a parsed TOML document and return a ``Case``."""
    from flightid.cases.stagespec import parse_stages

    _top_level(raw)
    staged = "stages" in raw
    data, maneuvers = _data_section(raw, staged) if "data" in raw else ({}, [])
    model = _model_section(raw)
    initial_state = _table(raw.get("initial_state", {}), "initial_state")
    _initial_state_types(initial_state, "initial_state")
    if staged:
        stages, run = parse_stages(raw, data, model)
    else:
        stages, run = (), _single_run(raw, data)
    if model.get("type") == "alpha_q" and "aero" not in model and not staged:
        raise CaseError("model.aero: missing; give the CZ and Cm terms of the α–q model")
    return Case(
        path=path,
        title=_string(raw.get("title", path.stem), "title"),
        description=_string(raw.get("description", ""), "description"),
        data=data,
        maneuvers=tuple(maneuvers),
        model=model,
        parameters=_parameters_section(raw),
        initial_state=initial_state,
        biases=_biases_section(raw),
        output=_output_section(raw),
        raw=raw,
        stages=stages,
        process_noise=_process_noise_section(raw, run.get("estimation", {})),
        recursive=_table(raw.get("recursive", {}), "recursive"),
        frequency_domain=_table(raw.get("frequency_domain", {}), "frequency_domain"),
        design=_table(raw.get("design", {}), "design"),
        flying_qualities=flying_qualities_settings(
            _table(raw.get("flying_qualities", {}), "flying_qualities")
        ),
        **run,
    )


def load_case(path: str | Path) -> Case:
    """Read and check a TOML case file."""
    path = Path(path)
    if not path.is_file():
        what = "is not a file" if path.exists() else "does not exist"
        raise CaseError(f"case file: {path} {what}")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise CaseError(f"case file {path}: cannot be read ({exc.strerror or exc})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CaseError(
            f"case file {path}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset "
            f"{exc.start}); TOML files are UTF-8 — save it as UTF-8"
        ) from None
    try:
        raw = tomllib.loads(text.removeprefix("\ufeff"))
    except tomllib.TOMLDecodeError as exc:
        raise CaseError(f"case file {path}: not valid TOML ({exc})") from None
    return parse_case(raw, path.resolve())
