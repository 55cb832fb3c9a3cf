"""The case-file sections a single run and its ``[[stages]]`` share: the maneuvers, the
estimation, accuracy and prediction settings, checked with every error naming the key.

``flightid.cases.spec`` reads a whole case file with them, ``flightid.cases.stagespec`` each
stage of a staged one; ``StageSpec`` is the checked stage they produce.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from flightid.cases.checks import (
    CaseError,
    _bool,
    _integer,
    _known,
    _number,
    _optional_string,
    _settings,
    _string,
    _table,
)
from flightid.estimation import FPS, MNR, MNRES, Convergence

# the time-base keys: a maneuver's own, else its section's ([prediction]), else [data]'s
_TIME_BASE = ("gaps", "dt", "resample_hz", "max_gap_s", "allow_retime")


_MANEUVER = {
    "file",
    "name",
    "start",
    "stop",
    "variable",
    "format",
    "mode",
    "mode_index",
    *_TIME_BASE,
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
    "stabilizing_gain",
    "eigenvalue_shift",
    "shooting_intervals",
    "shooting_weight",
    "estimator",
    "relaxation",
    "linearisation",
    "max_cycles",
    "filter_gradients",
    "outliers",
    "outlier_threshold",
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


_PREDICTION = {"file", "files", "maneuvers", "initial_state", *_TIME_BASE[2:]}


SOLVERS = ("mnres", "mnr", "fps")


METHODS = ("rk4", "euler")


NOISE = ("max", "maxlik", "fixed")


# inputs between samples: "linear" (mean of neighbouring samples at the half step) or "zoh"
# (each sample held over its interval)
INPUT_INTERPOLATIONS = ("linear", "zoh")


SOLVER_CLASSES = {"mnres": MNRES, "mnr": MNR, "fps": FPS}


# "output_error" (no process noise) or "filter_error" (flightid.estimation.filter_error)
ESTIMATORS = ("output_error", "filter_error")


FILTER_RELAXATIONS = ("reference", "fixed_point")


FILTER_LINEARISATIONS = ("start",)


# H of the filter error method: "differences" of filter passes, or "analytic" (linear models)
FILTER_GRADIENTS = ("differences", "analytic")


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
    dt: float | None = None  # s: regenerate time as t_0 + k·dt (None: the stored times)
    # the flight mode whose interval is the maneuver (start/stop from the log), and which
    # of its occurrences (1-based; None: the mode must occur once)
    mode: str | None = None
    mode_index: int | None = None
    # Hz: resample every channel onto t_k = k/R (anti-aliased; gaps split the maneuver)
    resample_hz: float | None = None
    max_gap_s: float | None = None  # s: the longest interval resampling bridges
    allow_retime: bool = False  # accept dt / join moving rows by more than half an interval


@dataclass(frozen=True)
class StageSpec:
    """One checked ``[[stages]]`` entry (see ``flightid.cases.stagespec``).

    Attributes:
        kind: "stepwise", "regression", "global_model", "output_error", "accuracy" or
            "prediction".
        name: a label (default the kind).
        index: position in ``[[stages]]`` (0-based), for messages (``stages[index]``).
        source: "previous" when the stage takes its structure and start values from the
            stage before (``from = "previous"``), else None.
        settings: the stage's own keys (options of its kind).
        coefficients: per coefficient of a regression or global-model stage: (name,
            response channel, terms (candidates of a stepwise stage; none for a global
            model), per-coefficient options).
    """

    kind: str
    name: str
    index: int
    source: str | None = None
    settings: Mapping[str, Any] = field(default_factory=dict)
    coefficients: tuple[tuple[str, str, tuple[str, ...], Mapping[str, Any]], ...] = ()


def _positive(value: Any, key: str) -> float:
    """A finite number > 0 (a scale: the typical magnitude of a parameter)."""
    number = _number(value, key)
    if number <= 0:
        raise CaseError(f"{key}: expected a positive number, got {value!r}")
    return number


def _initial_state_types(section: Mapping[str, Any], key: str) -> None:
    """Types of ``[initial_state]`` entries (the state names are checked with the model)."""
    for state, value in section.items():
        where = f"{key}.{state}"
        if isinstance(value, Mapping):
            _known(value, {"value", "free", "channel", "scale"}, where)
        spec = value if isinstance(value, Mapping) else {"value": value}
        for name in ("free",):
            if name in spec:
                _bool(spec[name], f"{where}.{name}")
        if "channel" in spec:
            _string(spec["channel"], f"{where}.channel")
        if "scale" in spec:
            _positive(spec["scale"], f"{where}.scale")
        start = spec.get("value", "measured")
        if isinstance(start, list):
            for k, v in enumerate(start):
                _number(v, f"{where}[{k}]")
        elif isinstance(start, str):
            _string(start, where, ("measured", "estimate"))
        else:
            _number(start, where)


def _maneuver_mode(
    item: Mapping[str, Any], where: str, start: Any, stop: Any
) -> tuple[str | None, int | None]:
    """``mode`` (a flight-mode name: the maneuver is that mode's interval in the log) and
    ``mode_index`` (1-based occurrence); a mode excludes start/stop, an index needs a mode."""
    if "mode" not in item:
        if "mode_index" in item:
            raise CaseError(f'{where}.mode_index: give the mode too (mode = "...")')
        return None, None
    mode = _string(item["mode"], f"{where}.mode")
    if not mode.strip():
        raise CaseError(f"{where}.mode: expected a flight-mode name, got an empty string")
    if start is not None or stop is not None:
        raise CaseError(
            f"{where}: give either mode (the mode's interval) or start/stop, not both "
            f"(got mode = {mode!r}, start = {start!r}, stop = {stop!r})"
        )
    index = item.get("mode_index")
    return mode, None if index is None else _integer(index, f"{where}.mode_index", 1)


def _resampling(item: Mapping[str, Any], defaults: Mapping[str, Any], where: str) -> dict:
    """``resample_hz``, ``max_gap_s``, ``allow_retime`` of one maneuver (its own, else the
    defaults), checked: positive numbers; ``max_gap_s`` only with ``resample_hz``, which
    excludes ``dt`` and ``gaps = "join"``."""
    given = {k: item.get(k, defaults.get(k)) for k in _TIME_BASE}
    rate, gap = given["resample_hz"], given["max_gap_s"]
    for name, value, unit in (("resample_hz", rate, "Hz"), ("max_gap_s", gap, "s")):
        if value is not None and _number(value, f"{where}.{name}") <= 0:
            raise CaseError(f"{where}.{name}: expected a positive number ({unit}), got {value!r}")
    if gap is not None and rate is None:
        raise CaseError(f"{where}.max_gap_s: only used with resample_hz (gaps split the record)")
    if rate is not None and (given["dt"] is not None or given["gaps"] == "join"):
        raise CaseError(
            f"{where}.resample_hz: give either resample_hz or dt / gaps = 'join', not both "
            f"(dt = {given['dt']!r}, gaps = {given['gaps']!r})"
        )
    retime = given["allow_retime"]
    return {
        "resample_hz": None if rate is None else float(rate),
        "max_gap_s": None if gap is None else float(gap),
        "allow_retime": False if retime is None else _bool(retime, f"{where}.allow_retime"),
    }


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
        dt = item.get("dt", defaults.get("dt"))
        if dt is not None and _number(dt, f"{where}.dt") <= 0:
            raise CaseError(f"{where}.dt: expected a positive sampling interval (s), got {dt!r}")
        if start is not None and stop is not None:
            if _number(start, f"{where}.start") >= _number(stop, f"{where}.stop"):
                raise CaseError(
                    f"{where}.stop: expected stop > start (s), got start {start!r}, stop {stop!r}"
                )
        mode, mode_index = _maneuver_mode(item, where, start, stop)
        resampling = _resampling(item, defaults, where)
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
                dt=None if dt is None else float(dt),
                mode=mode,
                mode_index=mode_index,
                **resampling,
            )
        )
    names = [m.name for m in result]
    if len(set(names)) != len(names):
        raise CaseError(f"{key}: maneuver names must be unique, got {names} (set 'name')")
    return result


def _noise_variances(estimation: Mapping[str, Any], noise: str, key: str) -> None:
    if "R" in estimation:
        r = estimation["R"]
        if not isinstance(r, list) or not r:
            raise CaseError(f"{key}.R: expected a list of variances, one per output")
        for i, v in enumerate(r):
            if _number(v, f"{key}.R[{i}]") <= 0:
                raise CaseError(f"{key}.R[{i}]: variances must be positive, got {v}")
    elif noise == "fixed":
        raise CaseError(f"{key}.R: needed with noise = 'fixed' (one variance per output)")


def estimation_settings(estimation: Mapping[str, Any], key: str = "estimation") -> None:
    """The settings of an output-error estimation ([estimation] or an output_error stage)."""
    _known(estimation, _ESTIMATION, key)
    solver = _string(estimation.get("solver", "mnres"), f"{key}.solver", SOLVERS)
    _string(estimation.get("method", "rk4"), f"{key}.method", METHODS)
    noise = _string(estimation.get("noise", "max"), f"{key}.noise", NOISE)
    _noise_variances(estimation, noise, key)
    _settings(
        _table(estimation.get("solver_settings", {}), f"{key}.solver_settings"),
        SOLVER_CLASSES[solver],
        f"{key}.solver_settings",
    )
    _settings(
        _table(estimation.get("convergence", {}), f"{key}.convergence"),
        Convergence,
        f"{key}.convergence",
    )
    _bool(estimation.get("compiled", True), f"{key}.compiled")
    _string(
        estimation.get("input_interpolation", "linear"),
        f"{key}.input_interpolation",
        INPUT_INTERPOLATIONS,
    )
    _unstable_settings(estimation, key)
    _filter_error_settings(estimation, key)
    _outlier_settings(estimation, key)


def _outlier_settings(estimation: Mapping[str, Any], key: str) -> None:
    """``outliers`` ("warn", "exclude" or "huber": flightid.accuracy.outliers) and
    ``outlier_threshold`` (robust σ, > 0); only in [estimation] and with output error."""
    from flightid.accuracy.outliers import OUTLIER_MODES

    present = [k for k in ("outliers", "outlier_threshold") if k in estimation]
    if not present:
        return
    if key != "estimation":
        raise CaseError(f"{key}.{present[0]}: an [estimation] setting; stages do not take it")
    mode = _string(estimation.get("outliers", "warn"), f"{key}.outliers", OUTLIER_MODES)
    if "outlier_threshold" in estimation:
        if _number(estimation["outlier_threshold"], f"{key}.outlier_threshold") <= 0:
            raise CaseError(
                f"{key}.outlier_threshold: expected a positive number of robust σ, got "
                f"{estimation['outlier_threshold']!r}"
            )
    if mode != "warn" and estimation.get("estimator", "output_error") == "filter_error":
        raise CaseError(
            f'{key}.outliers: "{mode}" re-weights the output-error cost; with the filter error '
            'method only "warn" is available'
        )


def _unstable_settings(estimation: Mapping[str, Any], key: str) -> None:
    """The unstable-aircraft options (docs/unstable.md): ``stabilizing_gain`` ({state =
    {output = gain}}), ``eigenvalue_shift`` (σ, 1/s), ``shooting_intervals`` (whole number
    ≥ 2) and ``shooting_weight`` (> 0, or an increasing list: a continuation); names are
    checked with the model (cases.run)."""
    if "stabilizing_gain" in estimation:
        gain = _table(estimation["stabilizing_gain"], f"{key}.stabilizing_gain")
        for state, row in gain.items():
            for output, value in _table(row, f"{key}.stabilizing_gain.{state}").items():
                _number(value, f"{key}.stabilizing_gain.{state}.{output}")
    if "eigenvalue_shift" in estimation:
        shift = _number(estimation["eigenvalue_shift"], f"{key}.eigenvalue_shift")
        # σ ≤ 0 weights the data by e^(+|σ|t) and moves the eigenvalues to the right: the
        # transformation then destabilizes instead of stabilizing
        if shift <= 0:
            raise CaseError(
                f"{key}.eigenvalue_shift: expected σ > 0 (1/s; larger than the unstable "
                f"eigenvalue's real part, e.g. 0.7), got {shift!r}"
            )
    if "shooting_intervals" in estimation:
        _integer(estimation["shooting_intervals"], f"{key}.shooting_intervals", 2)
    if "shooting_weight" in estimation:
        if "shooting_intervals" not in estimation:
            raise CaseError(f"{key}.shooting_weight: only used with shooting_intervals")
        weights = estimation["shooting_weight"]
        weights = weights if isinstance(weights, list) else [weights]
        values = [_number(w, f"{key}.shooting_weight") for w in weights]
        increasing = all(b > a for a, b in zip(values, values[1:], strict=False))
        if not values or min(values) <= 0 or not increasing:
            raise CaseError(
                f"{key}.shooting_weight: expected a positive number or an increasing list of "
                f"them, got {estimation['shooting_weight']!r}"
            )


def _filter_error_settings(estimation: Mapping[str, Any], key: str) -> None:
    """``estimator`` and the filter error method's settings (``relaxation``,
    ``linearisation``, ``max_cycles``); R and the noise policy are not its to set."""
    solver = estimation.get("solver", "mnres")
    estimator = _string(estimation.get("estimator", "output_error"), f"{key}.estimator", ESTIMATORS)
    filter_keys = [
        k
        for k in ("relaxation", "linearisation", "max_cycles", "filter_gradients")
        if k in estimation
    ]
    if estimator != "filter_error" and filter_keys:
        raise CaseError(
            f"{key}.{filter_keys[0]}: a setting of the filter error method; "
            'set estimator = "filter_error" (and [process_noise])'
        )
    if estimator == "filter_error":
        if solver == "fps":
            raise CaseError(f"{key}.solver: the filter error method runs with 'mnr' or 'mnres'")
        if "noise" in estimation or "R" in estimation:
            raise CaseError(
                f"{key}.noise: the filter error method estimates R from the innovations; "
                "leave out noise and R"
            )
        _string(
            estimation.get("relaxation", "fixed_point"), f"{key}.relaxation", FILTER_RELAXATIONS
        )
        _string(
            estimation.get("linearisation", "start"), f"{key}.linearisation", FILTER_LINEARISATIONS
        )
        _integer(estimation.get("max_cycles", 30), f"{key}.max_cycles", 1)
        _string(
            estimation.get("filter_gradients", "differences"),
            f"{key}.filter_gradients",
            FILTER_GRADIENTS,
        )


def _accuracy_methods(accuracy: Mapping[str, Any], key: str) -> None:
    methods = accuracy.get("methods", [])
    if isinstance(methods, str):
        methods = [methods]
    if not isinstance(methods, list):
        raise CaseError(
            f"{key}.methods: expected a list of names from {list(ACCURACY_METHODS)}, "
            f"got {methods!r}"
        )
    for i, method in enumerate(methods):
        _string(method, f"{key}.methods[{i}]", ACCURACY_METHODS)


def accuracy_settings(accuracy: Mapping[str, Any], key: str = "accuracy") -> None:
    """The settings of an accuracy assessment ([accuracy] or an accuracy stage)."""
    _known(accuracy, _ACCURACY, key)
    confidence = _number(accuracy.get("confidence", 0.95), f"{key}.confidence")
    if not 0 < confidence < 1:
        raise CaseError(f"{key}.confidence: expected a level between 0 and 1, got {confidence}")
    if _number(accuracy.get("bound_factor", 1.0), f"{key}.bound_factor") <= 0:
        raise CaseError(f"{key}.bound_factor: expected a positive number")
    correlation = _number(accuracy.get("correlation_warning", 0.9), f"{key}.correlation_warning")
    if not 0 < correlation <= 1:
        raise CaseError(
            f"{key}.correlation_warning: expected a correlation in (0, 1], got {correlation}"
        )
    _accuracy_methods(accuracy, key)
    for name, smallest in (("budget", 1), ("seed", 0)):
        _integer(accuracy.get(name, smallest), f"{key}.{name}", smallest)
    _string(accuracy.get("kind", "individual"), f"{key}.kind", INTERVAL_KINDS)
    _string(accuracy.get("distribution", "t"), f"{key}.distribution", DISTRIBUTIONS)


def prediction_settings(
    section: Mapping[str, Any], data: Mapping[str, Any], key: str = "prediction"
) -> tuple[list[ManeuverSpec], Mapping[str, Any]]:
    """The maneuvers to predict and their initial states ([prediction] or a prediction
    stage): (maneuvers, initial_state)."""
    _known(section, _PREDICTION, key)
    # the section's own resampling keys before [data]'s
    defaults = {**data, **{k: section[k] for k in _TIME_BASE[2:] if k in section}}
    maneuvers = (
        _maneuvers(section, key, defaults)
        if any(k in section for k in ("file", "files", "maneuvers"))
        else []
    )
    x0 = _table(section.get("initial_state", {}), f"{key}.initial_state")
    _initial_state_types(x0, f"{key}.initial_state")
    return maneuvers, x0


_FLYING_QUALITIES = {"class", "category", "speed", "n_alpha", "include_unverified"}


def flying_qualities_settings(table: Mapping[str, Any], key: str = "flying_qualities") -> dict:
    """``[flying_qualities]``: the airplane class and flight-phase category whose
    MIL-F-8785C limits the report judges the modes against (``flightid.export``); optional
    ``speed`` [m/s] and ``n_alpha`` [g/rad] for the control anticipation parameter and
    ``include_unverified`` (judge with the limits marked unverified too). {} when absent."""
    if not table:
        return {}
    # imported only for a case that has the table (it loads flightid.export)
    from flightid.export.flying_qualities import AIRPLANE_CLASSES, CATEGORIES

    _known(table, _FLYING_QUALITIES, key)
    for required in ("class", "category"):
        if required not in table:
            raise CaseError(
                f"{key}.{required}: missing; give the airplane class (one of "
                f"{list(AIRPLANE_CLASSES)}) and the flight-phase category (one of "
                f"{list(CATEGORIES)})"
            )
    settings: dict[str, Any] = {
        "class": _string(table["class"], f"{key}.class", AIRPLANE_CLASSES),
        "category": _string(table["category"], f"{key}.category", CATEGORIES),
    }
    if settings["class"] == "II" and settings["category"] == "C":
        raise CaseError(
            f"{key}.class: Category C limits differ for Class II carrier-based and land-based "
            "airplanes; expected 'II-C' or 'II-L', got 'II'"
        )
    for name in ("speed", "n_alpha"):
        if name in table:
            settings[name] = _positive(table[name], f"{key}.{name}")
    if "include_unverified" in table:
        settings["include_unverified"] = _bool(
            table["include_unverified"], f"{key}.include_unverified"
        )
    return settings
