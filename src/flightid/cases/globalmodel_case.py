"""``[[stages]] kind = "global_model"``: one model of each chosen aerodynamic coefficient over
the flight envelope, fitted to every maneuver of the case at once
(``flightid.globalmodel.fit_global_model``: multivariate orthogonal functions, prediction
intervals, data support).

    [[stages]]
    kind = "global_model"
    name = "envelope"
    variables = ["alpha", "Mach", "de", "qhat"]     # channels after the pre-processing
    orders = { alpha = 4, Mach = 2, de = 2, qhat = 1 }
    max_order = 3                                   # any key of GlobalModelSettings
    decimate = 5
    [stages.conditions]                             # optional: constant channels per maneuver
    m1 = { Mach = 0.6 }
    m2 = { Mach = 0.8 }
    [stages.coefficients.CL]                        # one table per coefficient
    response = "CL"                                 # a channel (default: the table's name)
    orders = { alpha = 5 }                          # any option, for this coefficient alone

The stage's options are the fields of ``flightid.globalmodel.GlobalModelSettings``; a
coefficient's table may repeat any of them for itself. ``conditions`` gives a channel whose
value is constant over a maneuver (its Mach number, altitude, configuration), one table per
maneuver by name; a condition named in ``variables`` must be given for every maneuver.

``batch = "out/envelope"`` (relative to the case file's folder, or absolute) takes the
stage's maneuvers from a ``flightid batch`` results folder instead of the case's own data:
the estimation maneuvers of every case that did not fail, each loaded with that case's own
``[data]`` and carrying its record's numeric ``conditions`` as constant channels
(``flightid.cases.batch_source``). The stage's ``conditions`` then name a batch case (all
its maneuvers) or one maneuver as ``case/maneuver``, and add to or override the batch's
values. Variables and responses are checked against the batch cases' channels when the stage
runs (or is validated). A case whose stages all take their maneuvers from batches has no
``[data]`` section.

This module checks the stage when the case is read and runs it; the package
``flightid.globalmodel`` is imported only for a case with such a stage.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from flightid.cases.checks import CaseError, _known, _names, _number, _string, _table
from flightid.data.flightdata import FlightData
from flightid.errors import InputError

__all__ = [
    "GLOBAL_MODEL_FILE",
    "GLOBAL_MODEL_KIND",
    "StageData",
    "check_stage_channels",
    "global_model_entry",
    "global_model_options",
    "global_model_signals",
    "global_model_stage_data",
    "is_batch_stage",
    "maneuver_signals",
    "parse_global_model_stage",
    "run_global_model_stage",
    "validate_global_model_stage",
]

GLOBAL_MODEL_KIND = "global_model"
# the whole model (reloadable: flightid.globalmodel.load_global_model) beside results.json
GLOBAL_MODEL_FILE = "global_model.json"
# what results.json leaves to GLOBAL_MODEL_FILE: the matrices and reference sets
_HEAVY = (
    "covariance",
    "covariance_cr",
    "xtx_inv",
    "local_reference",
    "local_squared_residuals",
    "local_noise_variances",
)
# keys of the stage besides the settings' fields
_STAGE_KEYS = {"variables", "conditions", "coefficients", "batch"}


def global_model_options() -> tuple[str, ...]:
    """The option keys of a global-model stage: the fields of ``GlobalModelSettings``."""
    from flightid.globalmodel.settings import GlobalModelSettings

    return tuple(f.name for f in dataclasses.fields(GlobalModelSettings))


def _settings(options: Mapping[str, Any], where: str):
    """``GlobalModelSettings(**options)``, its errors as ``CaseError`` naming the stage."""
    from flightid.globalmodel.settings import GlobalModelSettings

    try:
        return GlobalModelSettings(**options)
    except (InputError, TypeError, ValueError) as exc:
        raise CaseError(f"{where}: {exc}") from None


def _conditions(value: Any, where: str) -> dict[str, dict[str, float]]:
    """``{maneuver: {channel: number}}``."""
    table = _table(value, where)
    conditions = {}
    for maneuver, entry in table.items():
        key = f"{where}.{maneuver}"
        entry = _table(entry, key)
        conditions[maneuver] = {
            name: _number(number, f"{key}.{name}") for name, number in entry.items()
        }
    return conditions


def parse_global_model_stage(
    stage: Mapping[str, Any], where: str, channels: set[str]
) -> tuple[dict[str, Any], tuple]:
    """Check a global-model stage: (its settings: ``variables``, ``conditions``, ``batch``
    (the folder as written, or None) and the stage-wide ``options``; its coefficients:
    (name, response, (), options) each). A batch stage's variables and responses are
    checked against the batch cases' channels when it runs. Every
    option set is tried on ``GlobalModelSettings`` here, so a bad value stops the case
    before any data is read."""
    options_keys = set(global_model_options())
    settings = {k: v for k, v in stage.items() if k not in {"kind", "name", "from"}}
    _known(settings, _STAGE_KEYS | options_keys, where)
    if "variables" not in settings:
        raise CaseError(f"{where}.variables: missing (the explanatory variables, channels)")
    variables = _names(settings["variables"], f"{where}.variables")
    if not variables or len(set(variables)) != len(variables):
        raise CaseError(f"{where}.variables: expected distinct channel names, got {variables!r}")
    conditions = _conditions(settings.get("conditions", {}), f"{where}.conditions")
    batch = _string(settings["batch"], f"{where}.batch") if "batch" in settings else None
    if batch == "":
        raise CaseError(f"{where}.batch: expected the folder of a `flightid batch` run, got ''")
    known = channels | {name for entry in conditions.values() for name in entry}
    missing = [v for v in variables if v not in known]
    if missing and batch is None:
        raise CaseError(
            f"{where}.variables: {missing} are neither channels of [data.inputs] / "
            f"[data.outputs] nor [{where}.conditions]; channels: {sorted(channels)}"
        )
    options = {k: v for k, v in settings.items() if k in options_keys}
    _settings(options, where)
    coefficients = _coefficients(stage, where, None if batch else channels, options)
    stage_settings = {
        "variables": tuple(variables),
        "conditions": conditions,
        "options": options,
        "batch": batch,
    }
    return stage_settings, coefficients


def _coefficients(
    stage: Mapping[str, Any],
    where: str,
    channels: set[str] | None,
    options: Mapping[str, Any],
) -> tuple:
    """``[stages.coefficients.NAME]``: (name, response, (), own options) each; responses are
    checked against ``channels`` (None: a batch stage, checked when it runs)."""
    options_keys = set(global_model_options())
    table = _table(stage.get("coefficients", {}), f"{where}.coefficients")
    if not table:
        raise CaseError(f"{where}.coefficients: expected at least one [{where}.coefficients.NAME]")
    coefficients = []
    for name, entry in table.items():
        key = f"{where}.coefficients.{name}"
        entry = _table(entry, key)
        _known(entry, {"response"} | options_keys, key)
        response = _string(entry.get("response", name), f"{key}.response")
        if channels is not None and response not in channels:
            raise CaseError(
                f"{key}.response: {response!r} is not a channel of [data.inputs] / "
                f"[data.outputs]; channels: {sorted(channels)}"
            )
        own = {k: v for k, v in entry.items() if k != "response"}
        _settings({**options, **own}, key)
        coefficients.append((name, response, (), own))
    return tuple(coefficients)


def is_batch_stage(stage: Mapping[str, Any]) -> bool:
    """True for a raw ``[[stages]]`` table of kind global_model that names a ``batch``."""
    return (
        isinstance(stage, Mapping)
        and stage.get("kind") == GLOBAL_MODEL_KIND
        and stage.get("batch") is not None
    )


def global_model_signals(
    stage, maneuvers: Sequence[FlightData]
) -> tuple[dict[str, np.ndarray], np.ndarray, float]:
    """The stage's signals over all maneuvers (every channel, concatenated in order, and
    each condition as a constant channel), the maneuver index of each sample and the
    sample interval (s) of the first maneuver."""
    where = f"stages[{stage.index}].conditions"
    conditions = stage.settings["conditions"]
    unknown = sorted(set(conditions) - {m.name for m in maneuvers})
    if unknown:
        raise CaseError(
            f"{where}: {unknown} are not maneuvers of the case; maneuvers: "
            f"{[m.name for m in maneuvers]}"
        )
    labelled = [(m, m.name, conditions.get(m.name, {})) for m in maneuvers]
    return maneuver_signals(labelled, where)


def maneuver_signals(
    labelled: Sequence[tuple[FlightData, str, Mapping[str, float]]], where: str
) -> tuple[dict[str, np.ndarray], np.ndarray, float]:
    """``global_model_signals`` for (maneuver, its label, its conditions) triples: every
    channel concatenated, each condition a constant channel (given for every maneuver),
    the maneuver index of each sample and the first maneuver's sample interval (s)."""
    maneuvers = [m for m, _, _ in labelled]
    names = list(maneuvers[0].input_names) + list(maneuvers[0].output_names)
    for maneuver, label, _ in labelled[1:]:
        lacking = sorted(set(names) - set(maneuver.input_names) - set(maneuver.output_names))
        if lacking:
            raise CaseError(f"maneuver {label!r}: lacks the channels {lacking}")
    signals = {name: np.concatenate([m.channel(name) for m in maneuvers]) for name in names}
    condition_names = sorted({name for _, _, entry in labelled for name in entry})
    for name in condition_names:
        if name in signals:
            raise CaseError(f"{where}: {name!r} is a channel of the data, not a condition")
        lacking = [label for _, label, entry in labelled if name not in entry]
        if lacking:
            raise CaseError(f"{where}: {name!r} is not given for the maneuvers {lacking}")
        signals[name] = np.concatenate(
            [np.full(m.n_samples, entry[name]) for m, _, entry in labelled]
        )
    index = np.concatenate([np.full(m.n_samples, k) for k, m in enumerate(maneuvers)])
    return signals, index, float(maneuvers[0].dt)


@dataclass(frozen=True, eq=False)
class StageData:
    """What a global-model stage is fitted to.

    Attributes:
        signals: every channel and condition, concatenated over the maneuvers.
        maneuver_index: (N,) the maneuver of each sample.
        dt: s, the sample interval of the first maneuver.
        units: {channel: unit} of the first maneuver's channels.
        sources: per maneuver, ``flightid.globalmodel.SourceInfo`` (its name, its batch
            case, its conditions, its samples).
        skipped: batch cases left out, ``{"case", "reason"}`` each.
    """

    signals: Mapping[str, np.ndarray]
    maneuver_index: np.ndarray
    dt: float
    units: Mapping[str, str]
    sources: tuple = ()
    skipped: tuple[Mapping[str, str], ...] = ()


def check_stage_channels(stage, signals: Mapping[str, np.ndarray]) -> None:
    """Every variable and response is a channel or condition of the stage's maneuvers."""
    where = f"stages[{stage.index}]"
    missing = [v for v in stage.settings["variables"] if v not in signals]
    if missing:
        raise CaseError(
            f"{where}.variables: {missing} are neither channels of the maneuvers nor "
            f"conditions; channels and conditions: {sorted(signals)}"
        )
    for name, response, _, _ in stage.coefficients:
        if response not in signals:
            raise CaseError(
                f"{where}.coefficients.{name}.response: {response!r} is not a channel of the "
                f"maneuvers; channels: {sorted(signals)}"
            )


def global_model_stage_data(stage, maneuvers: Sequence[FlightData]) -> StageData:
    """The data a global-model stage without ``batch`` is fitted to: the case's maneuvers
    with the stage's conditions (a batch stage's: ``flightid.cases.batch_source``)."""
    from flightid.globalmodel.model import SourceInfo

    signals, index, dt = global_model_signals(stage, maneuvers)
    units = {k: v for k, v in maneuvers[0].units.items() if k in signals and v}
    conditions = stage.settings["conditions"]
    sources = tuple(
        SourceInfo(m.name, "", dict(conditions.get(m.name, {})), int(m.n_samples))
        for m in maneuvers
    )
    return StageData(signals, index, dt, units, sources)


def _coefficient_settings(stage) -> dict[str, Any]:
    options = stage.settings["options"]
    return {
        name: _settings({**options, **own}, f"stages[{stage.index}].coefficients.{name}")
        for name, _, _, own in stage.coefficients
    }


def run_global_model_stage(
    stage,
    maneuvers: Sequence[FlightData],
    progress: Callable[[str], None] | None = None,
    *,
    data: StageData | None = None,
):
    """Fit the stage's global model to the maneuvers (``flightid.globalmodel``), or to
    ``data`` (``global_model_stage_data``) when given; returns the ``GlobalModel``. Errors
    of the fit are ``CaseError`` naming the stage."""
    from flightid.globalmodel import fit_global_model

    say = progress or (lambda message: None)
    data = data if data is not None else global_model_stage_data(stage, maneuvers)
    responses = {name: response for name, response, _, _ in stage.coefficients}
    try:
        model = fit_global_model(
            data.signals,
            responses,
            list(stage.settings["variables"]),
            settings=_coefficient_settings(stage),
            maneuver_index=data.maneuver_index,
            dt=data.dt,
            units=data.units,
            sources=data.sources,
        )
    except InputError as exc:
        raise CaseError(f"stages[{stage.index}]: {exc}") from None
    for name, coefficient in model.coefficients.items():
        say(
            f"global model {name}: {len(coefficient.terms)} terms of "
            f"{coefficient.n_candidates} candidates (PSE {coefficient.pse:.4g})"
        )
    return model


def global_model_entry(model, skipped: Sequence[Mapping[str, str]] = ()) -> dict[str, Any]:
    """The stage's entry in results.json, ``{"global_model": {...}}``: the variables (name,
    unit, range), the maneuvers and, per coefficient, the selected terms with value, σ and
    σ_cr, the selection path and the fit statistics; the matrices and the support's
    reference set are in ``GLOBAL_MODEL_FILE`` (``model_file``). A batch stage adds
    ``skipped``: the batch cases left out, ``{"case", "reason"}`` each."""
    document = model.to_dict()
    coefficients = {
        name: {key: value for key, value in entry.items() if key not in _HEAVY}
        for name, entry in document["coefficients"].items()
    }
    for entry in coefficients.values():
        entry["support"] = {
            key: value for key, value in entry["support"].items() if not isinstance(value, list)
        }
    entry = {
        "global_model": {
            "model_file": GLOBAL_MODEL_FILE,
            "variables": document["variables"],
            "sources": document["sources"],
            "coefficients": coefficients,
        }
    }
    if skipped:
        entry["skipped"] = [dict(s) for s in skipped]
    return entry


def validate_global_model_stage(
    stage, maneuvers: Sequence[FlightData], data: StageData | None = None
) -> str:
    """Check the stage on the data without fitting: the signals build, every variable and
    response is a finite channel; one line for ``flightid validate``."""
    data = data if data is not None else global_model_stage_data(stage, maneuvers)
    signals = data.signals
    check_stage_channels(stage, signals)
    for name in (*stage.settings["variables"], *(c[1] for c in stage.coefficients)):
        if not np.isfinite(signals[name]).all():
            raise CaseError(f"stages[{stage.index}]: non-finite values in {name!r} on the data")
    tail = ""
    if stage.settings.get("batch") is not None:
        cases = len({s.case for s in data.sources})
        tail = f" from {cases} batch case(s), {len(data.skipped)} skipped" + "".join(
            f"\n      skipped {s['case']}: {s['reason']}" for s in data.skipped
        )
    return (
        f"global_model '{stage.name}': {len(stage.coefficients)} coefficient(s) over "
        f"{', '.join(stage.settings['variables'])}, {len(signals[stage.coefficients[0][1]])} "
        f"samples{tail}"
    )
