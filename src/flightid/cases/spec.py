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
    [output]                                # figures, report

This module only parses and checks types and keys; ``flightid.cases.build`` makes the
objects. Nothing is evaluated: expressions and terms go to their own safe parsers.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from flightid.data.loaders import ChannelSpec
from flightid.errors import InputError
from flightid.estimation import FPS, MNR, MNRES, Convergence

__all__ = ["CaseError", "Case", "ManeuverSpec", "load_case", "parse_case"]


class CaseError(InputError):
    """A malformed case file; the message starts with the offending key."""


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
}
_DATA = {
    "data_dir",
    "format",
    "variable",
    "time",
    "gaps",
    "file",
    "files",
    "maneuvers",
    "inputs",
    "outputs",
    "start",
    "stop",
}
_MANEUVER = {"file", "name", "start", "stop", "variable", "format", "gaps"}
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
}
_ESTIMATION = {
    "solver",
    "method",
    "noise",
    "R",
    "solver_settings",
    "convergence",
    "compiled",
    "input_interpolation",
}
_ACCURACY = {
    "confidence",
    "bound_factor",
    "correlation_warning",
    "methods",
    "budget",
    "seed",
    "kind",
    "distribution",
}
ACCURACY_METHODS = ("cr", "profile", "search", "all")
INTERVAL_KINDS = ("individual", "simultaneous")
DISTRIBUTIONS = ("t", "normal")
_PREDICTION = {"file", "files", "maneuvers", "initial_state"}
_OUTPUT = {"figures", "report", "dir"}
SOLVERS = ("mnres", "mnr", "fps")
METHODS = ("rk4", "euler")
NOISE = ("max", "maxlik", "fixed")
# inputs between samples: "linear" (mean of neighbouring samples at the half step) or "zoh"
# (each sample held over its interval)
INPUT_INTERPOLATIONS = ("linear", "zoh")
SOLVER_CLASSES = {"mnres": MNRES, "mnr": MNR, "fps": FPS}
MODEL_TYPES = ("wind_axis_longitudinal", "longitudinal", "lateral", "six_dof")


@dataclass(frozen=True)
class ManeuverSpec:
    """One data file (maneuver) of a case."""

    file: str
    name: str
    start: float | None = None
    stop: float | None = None
    variable: str | None = None
    format: str = "auto"
    gaps: str = "error"


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

    @property
    def directory(self) -> Path:
        return self.path.parent


# ------------------------------------------------------------------------------ helpers


def _table(value: Any, key: str) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise CaseError(f"{key}: expected a table ([{key}] or {{...}}), got {type(value).__name__}")
    return value


def _known(table: Mapping[str, Any], allowed: set[str], key: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        where = f"[{key}]" if key else "the top level"
        raise CaseError(
            f"{key + '.' if key else ''}{unknown[0]}: unknown key in {where}; "
            f"allowed keys: {sorted(allowed)}"
        )


def _number(value: Any, key: str, *, infinite: bool = False) -> float:
    """A TOML integer or float; NaN never, ±inf only where ``infinite`` (bounds, limits)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CaseError(f"{key}: expected a number, got {value!r}")
    number = float(value)
    if math.isnan(number) or (math.isinf(number) and not infinite):
        what = "a number (not NaN)" if infinite else "a finite number"
        raise CaseError(f"{key}: expected {what}, got {value!r}")
    return number


def _integer(value: Any, key: str, smallest: int | None = None) -> int:
    """A TOML integer (not 2.5, 3.0 or "3"), at least ``smallest``."""
    what = {None: "an integer", 0: "a non-negative integer", 1: "a positive integer"}.get(
        smallest, f"an integer ≥ {smallest}"
    )
    if isinstance(value, bool) or not isinstance(value, int):
        raise CaseError(f"{key}: expected {what}, got {value!r}")
    if smallest is not None and value < smallest:
        raise CaseError(f"{key}: expected {what}, got {value!r}")
    return value


def _bool(value: Any, key: str) -> bool:
    """TOML true / false only ("no", 0 and "false" are errors, not truthy values)."""
    if not isinstance(value, bool):
        raise CaseError(f"{key}: expected true or false, got {value!r}")
    return value


def _string(value: Any, key: str, choices: tuple[str, ...] | None = None) -> str:
    if not isinstance(value, str):
        raise CaseError(f"{key}: expected a string, got {value!r}")
    if choices is not None and value not in choices:
        raise CaseError(f"{key}: expected one of {list(choices)}, got {value!r}")
    return value


def _optional_string(value: Any, key: str) -> str | None:
    return None if value is None else _string(value, key)


def _names(value: Any, key: str) -> list[str]:
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise CaseError(f"{key}: expected a list of names (strings), got {value!r}")
    return value


def _typed(value: Any, hint: Any, key: str) -> None:
    """Check ``value`` against a dataclass field's type (bool, int, float, str, X | None)."""
    arguments = [a for a in typing.get_args(hint) if a is not type(None)]
    if typing.get_origin(hint) in (typing.Union, types.UnionType) and len(arguments) == 1:
        hint = arguments[0]  # TOML has no null: X | None means X here
    if hint is bool:
        _bool(value, key)
    elif hint is int:
        _integer(value, key)
    elif hint is float:
        _number(value, key, infinite=True)
    elif hint is str:
        _string(value, key)


def _settings(table: Mapping[str, Any], cls: type, key: str) -> None:
    """The keys of ``table`` are fields of the dataclass ``cls``, each of its type."""
    try:
        hints = typing.get_type_hints(cls)
    except Exception:  # an annotation that cannot be resolved: leave the check to cls
        hints = {}
    fields = {f.name: hints.get(f.name) for f in dataclasses.fields(cls) if f.init}
    for name, value in table.items():
        if name not in fields:
            raise CaseError(
                f"{key}.{name}: not a setting of {cls.__name__}; its settings: {sorted(fields)}"
            )
        _typed(value, fields[name], f"{key}.{name}")


def _initial_state_types(section: Mapping[str, Any], key: str) -> None:
    """Types of ``[initial_state]`` entries (the state names are checked with the model)."""
    for state, value in section.items():
        where = f"{key}.{state}"
        spec = value if isinstance(value, Mapping) else {"value": value}
        for name in ("free",):
            if name in spec:
                _bool(spec[name], f"{where}.{name}")
        if "channel" in spec:
            _string(spec["channel"], f"{where}.channel")
        if "scale" in spec:
            _number(spec["scale"], f"{where}.scale")
        start = spec.get("value", "measured")
        if isinstance(start, list):
            for k, v in enumerate(start):
                _number(v, f"{where}[{k}]")
        elif isinstance(start, str):
            _string(start, where, ("measured", "estimate"))
        else:
            _number(start, where)


def _maneuvers(section: Mapping[str, Any], key: str, defaults: Mapping[str, Any]) -> list:
    given = [k for k in ("file", "files", "maneuvers") if k in section]
    if len(given) != 1:
        raise CaseError(
            f"{key}: give exactly one of 'file', 'files' or [[{key}.maneuvers]], got "
            f"{given or 'none'}"
        )
    items: list[Mapping[str, Any]]
    if "file" in section:
        items = [{"file": section["file"]}]
    elif "files" in section:
        files = section["files"]
        if not isinstance(files, list) or not files:
            raise CaseError(f"{key}.files: expected a non-empty list of file names, got {files!r}")
        items = [{"file": f} for f in files]
    else:
        listed = section["maneuvers"]
        if not isinstance(listed, list) or not listed:
            raise CaseError(f"{key}.maneuvers: expected a non-empty array of tables")
        items = listed
    result = []
    for i, item in enumerate(items):
        where = f"{key}.maneuvers[{i}]" if "maneuvers" in section else f"{key}.file"
        item = _table(item, where)
        _known(item, _MANEUVER, where)
        if "file" not in item:
            raise CaseError(f"{where}.file: missing (the data file of this maneuver)")
        file = _string(item["file"], f"{where}.file")
        start = item.get("start", defaults.get("start"))
        stop = item.get("stop", defaults.get("stop"))
        result.append(
            ManeuverSpec(
                file=file,
                name=_string(item.get("name", Path(file).stem), f"{where}.name"),
                start=None if start is None else _number(start, f"{where}.start"),
                stop=None if stop is None else _number(stop, f"{where}.stop"),
                variable=_optional_string(
                    item.get("variable", defaults.get("variable")), f"{where}.variable"
                ),
                format=_string(
                    item.get("format", defaults.get("format", "auto")),
                    f"{where}.format",
                    ("auto", "csv", "ascii", "mat"),
                ),
                gaps=_string(
                    item.get("gaps", defaults.get("gaps", "error")),
                    f"{where}.gaps",
                    ("error", "join"),
                ),
            )
        )
    names = [m.name for m in result]
    if len(set(names)) != len(names):
        raise CaseError(f"{key}: maneuver names must be unique, got {names} (set 'name')")
    return result


# ------------------------------------------------------------------------------ parsing


def parse_case(raw: Mapping[str, Any], path: Path) -> Case:
    """Check the structure of a parsed TOML document and return a ``Case``."""
    _known(raw, _TOP, "")
    for required in ("data", "model"):
        if required not in raw:
            raise CaseError(f"{required}: missing section [{required}]")
    data = _table(raw["data"], "data")
    _known(data, _DATA, "data")
    for key in ("inputs", "outputs"):
        for name, value in _table(data.get(key, {}), f"data.{key}").items():
            try:
                ChannelSpec.from_value(value, f"data.{key}.{name}")
            except InputError as exc:
                message = str(exc)
                if not message.startswith("data."):
                    message = f"data.{key}.{name}: {message}"
                raise CaseError(message) from None
    if "outputs" not in data or not data["outputs"]:
        raise CaseError("data.outputs: missing; name the measured output channels")
    if "data_dir" in data:
        _string(data["data_dir"], "data.data_dir")
    time = data.get("time", 1)
    if not isinstance(time, str):
        _integer(time, "data.time", 1)
    maneuvers = _maneuvers(data, "data", data)

    model = _table(raw["model"], "model")
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

    parameters = _table(raw.get("parameters", {}), "parameters")
    for name, value in parameters.items():
        if isinstance(value, Mapping):
            _known(
                value, {"value", "free", "scale", "lower", "upper", "unit"}, f"parameters.{name}"
            )
            if "value" in value:
                _number(value["value"], f"parameters.{name}.value")
            if "free" in value:
                _bool(value["free"], f"parameters.{name}.free")
            if "scale" in value:
                _number(value["scale"], f"parameters.{name}.scale")
            for bound in ("lower", "upper"):
                if bound in value:
                    _number(value[bound], f"parameters.{name}.{bound}", infinite=True)
            if "unit" in value:
                _string(value["unit"], f"parameters.{name}.unit")
        else:
            _number(value, f"parameters.{name}")

    initial_state = _table(raw.get("initial_state", {}), "initial_state")
    _initial_state_types(initial_state, "initial_state")
    biases = _table(raw.get("biases", {}), "biases")
    _known(biases, {"states", "outputs"}, "biases")
    for kind in ("states", "outputs"):
        for name, value in _table(biases.get(kind, {}), f"biases.{kind}").items():
            where = f"biases.{kind}.{name}"
            if isinstance(value, Mapping):
                _known(value, {"value", "free", "per_maneuver", "scale"}, where)
                if "value" in value:
                    _number(value["value"], f"{where}.value")
                for flag in ("free", "per_maneuver"):
                    if flag in value:
                        _bool(value[flag], f"{where}.{flag}")
                if "scale" in value:
                    _number(value["scale"], f"{where}.scale")
            else:
                _number(value, where)

    estimation = _table(raw.get("estimation", {}), "estimation")
    _known(estimation, _ESTIMATION, "estimation")
    solver = _string(estimation.get("solver", "mnres"), "estimation.solver", SOLVERS)
    _string(estimation.get("method", "rk4"), "estimation.method", METHODS)
    noise = _string(estimation.get("noise", "max"), "estimation.noise", NOISE)
    if "R" in estimation:
        r = estimation["R"]
        if not isinstance(r, list) or not r:
            raise CaseError("estimation.R: expected a list of variances, one per output")
        for i, v in enumerate(r):
            if _number(v, f"estimation.R[{i}]") <= 0:
                raise CaseError(f"estimation.R[{i}]: variances must be positive, got {v}")
    elif noise == "fixed":
        raise CaseError("estimation.R: needed with noise = 'fixed' (one variance per output)")
    _settings(
        _table(estimation.get("solver_settings", {}), "estimation.solver_settings"),
        SOLVER_CLASSES[solver],
        "estimation.solver_settings",
    )
    _settings(
        _table(estimation.get("convergence", {}), "estimation.convergence"),
        Convergence,
        "estimation.convergence",
    )
    _bool(estimation.get("compiled", True), "estimation.compiled")
    _string(
        estimation.get("input_interpolation", "linear"),
        "estimation.input_interpolation",
        INPUT_INTERPOLATIONS,
    )

    accuracy = _table(raw.get("accuracy", {}), "accuracy")
    _known(accuracy, _ACCURACY, "accuracy")
    confidence = _number(accuracy.get("confidence", 0.95), "accuracy.confidence")
    if not 0 < confidence < 1:
        raise CaseError(f"accuracy.confidence: expected a level between 0 and 1, got {confidence}")
    if _number(accuracy.get("bound_factor", 1.0), "accuracy.bound_factor") <= 0:
        raise CaseError("accuracy.bound_factor: expected a positive number")
    _number(accuracy.get("correlation_warning", 0.9), "accuracy.correlation_warning")
    methods = accuracy.get("methods", [])
    if isinstance(methods, str):
        methods = [methods]
    if not isinstance(methods, list):
        raise CaseError(
            f"accuracy.methods: expected a list of names from {list(ACCURACY_METHODS)}, "
            f"got {methods!r}"
        )
    for i, method in enumerate(methods):
        _string(method, f"accuracy.methods[{i}]", ACCURACY_METHODS)
    for key, smallest in (("budget", 1), ("seed", 0)):
        _integer(accuracy.get(key, smallest), f"accuracy.{key}", smallest)
    _string(accuracy.get("kind", "individual"), "accuracy.kind", INTERVAL_KINDS)
    _string(accuracy.get("distribution", "t"), "accuracy.distribution", DISTRIBUTIONS)

    prediction_raw = _table(raw.get("prediction", {}), "prediction")
    _known(prediction_raw, _PREDICTION, "prediction")
    prediction = (
        _maneuvers(prediction_raw, "prediction", data)
        if any(k in prediction_raw for k in ("file", "files", "maneuvers"))
        else []
    )
    prediction_x0 = _table(prediction_raw.get("initial_state", {}), "prediction.initial_state")
    _initial_state_types(prediction_x0, "prediction.initial_state")

    output = _table(raw.get("output", {}), "output")
    _known(output, _OUTPUT, "output")
    for key in ("figures", "report"):
        if key in output:
            _bool(output[key], f"output.{key}")
    if "dir" in output:
        _string(output["dir"], "output.dir")

    return Case(
        path=path,
        title=_string(raw.get("title", path.stem), "title"),
        description=_string(raw.get("description", ""), "description"),
        data=data,
        maneuvers=tuple(maneuvers),
        model=model,
        parameters=parameters,
        initial_state=initial_state,
        biases={k: dict(biases.get(k, {})) for k in ("states", "outputs")},
        estimation=estimation,
        accuracy=accuracy,
        prediction=tuple(prediction),
        prediction_initial_state=prediction_x0,
        output=output,
        raw=raw,
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
