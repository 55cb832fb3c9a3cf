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

This module checks the stage when the case is read and runs it; the package
``flightid.globalmodel`` is imported only for a case with such a stage.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from flightid.cases.checks import CaseError, _known, _names, _number, _string, _table
from flightid.data.flightdata import FlightData
from flightid.errors import InputError

__all__ = [
    "GLOBAL_MODEL_FILE",
    "GLOBAL_MODEL_KIND",
    "global_model_entry",
    "global_model_options",
    "global_model_signals",
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
_STAGE_KEYS = {"variables", "conditions", "coefficients"}


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
    """Check a global-model stage: (its settings: ``variables``, ``conditions`` and the
    stage-wide ``options``; its coefficients: (name, response, (), options) each). Every
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
    known = channels | {name for entry in conditions.values() for name in entry}
    missing = [v for v in variables if v not in known]
    if missing:
        raise CaseError(
            f"{where}.variables: {missing} are neither channels of [data.inputs] / "
            f"[data.outputs] nor [{where}.conditions]; channels: {sorted(channels)}"
        )
    options = {k: v for k, v in settings.items() if k in options_keys}
    _settings(options, where)
    table = _table(stage.get("coefficients", {}), f"{where}.coefficients")
    if not table:
        raise CaseError(f"{where}.coefficients: expected at least one [{where}.coefficients.NAME]")
    coefficients = []
    for name, entry in table.items():
        key = f"{where}.coefficients.{name}"
        entry = _table(entry, key)
        _known(entry, {"response"} | options_keys, key)
        response = _string(entry.get("response", name), f"{key}.response")
        if response not in channels:
            raise CaseError(
                f"{key}.response: {response!r} is not a channel of [data.inputs] / "
                f"[data.outputs]; channels: {sorted(channels)}"
            )
        own = {k: v for k, v in entry.items() if k != "response"}
        _settings({**options, **own}, key)
        coefficients.append((name, response, (), own))
    return {"variables": tuple(variables), "conditions": conditions, "options": options}, tuple(
        coefficients
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
    names = list(maneuvers[0].input_names) + list(maneuvers[0].output_names)
    for maneuver in maneuvers[1:]:
        lacking = sorted(set(names) - set(maneuver.input_names) - set(maneuver.output_names))
        if lacking:
            raise CaseError(f"maneuver {maneuver.name!r}: lacks the channels {lacking}")
    signals = {name: np.concatenate([m.channel(name) for m in maneuvers]) for name in names}
    condition_names = sorted({name for entry in conditions.values() for name in entry})
    for name in condition_names:
        if name in signals:
            raise CaseError(f"{where}: {name!r} is a channel of the data, not a condition")
        lacking = [m.name for m in maneuvers if name not in conditions.get(m.name, {})]
        if lacking:
            raise CaseError(f"{where}: {name!r} is not given for the maneuvers {lacking}")
        signals[name] = np.concatenate(
            [np.full(m.n_samples, conditions[m.name][name]) for m in maneuvers]
        )
    index = np.concatenate([np.full(m.n_samples, k) for k, m in enumerate(maneuvers)])
    return signals, index, float(maneuvers[0].dt)


def _coefficient_settings(stage) -> dict[str, Any]:
    options = stage.settings["options"]
    return {
        name: _settings({**options, **own}, f"stages[{stage.index}].coefficients.{name}")
        for name, _, _, own in stage.coefficients
    }


def run_global_model_stage(
    stage, maneuvers: Sequence[FlightData], progress: Callable[[str], None] | None = None
):
    """Fit the stage's global model to the maneuvers (``flightid.globalmodel``); returns the
    ``GlobalModel``. Errors of the fit are ``CaseError`` naming the stage."""
    from flightid.globalmodel import fit_global_model

    say = progress or (lambda message: None)
    signals, index, dt = global_model_signals(stage, maneuvers)
    responses = {name: response for name, response, _, _ in stage.coefficients}
    try:
        model = fit_global_model(
            signals,
            responses,
            list(stage.settings["variables"]),
            settings=_coefficient_settings(stage),
            maneuver_index=index,
            dt=dt,
            units={k: v for k, v in maneuvers[0].units.items() if k in signals and v},
        )
    except InputError as exc:
        raise CaseError(f"stages[{stage.index}]: {exc}") from None
    for name, coefficient in model.coefficients.items():
        say(
            f"global model {name}: {len(coefficient.terms)} terms of "
            f"{coefficient.n_candidates} candidates (PSE {coefficient.pse:.4g})"
        )
    return model


def global_model_entry(model) -> dict[str, Any]:
    """The stage's entry in results.json, ``{"global_model": {...}}``: the variables (name,
    unit, range), the maneuvers and, per coefficient, the selected terms with value, σ and
    σ_cr, the selection path and the fit statistics; the matrices and the support's
    reference set are in ``GLOBAL_MODEL_FILE`` (``model_file``)."""
    document = model.to_dict()
    coefficients = {
        name: {key: value for key, value in entry.items() if key not in _HEAVY}
        for name, entry in document["coefficients"].items()
    }
    for entry in coefficients.values():
        entry["support"] = {
            key: value for key, value in entry["support"].items() if not isinstance(value, list)
        }
    return {
        "global_model": {
            "model_file": GLOBAL_MODEL_FILE,
            "variables": document["variables"],
            "sources": document["sources"],
            "coefficients": coefficients,
        }
    }


def validate_global_model_stage(stage, maneuvers: Sequence[FlightData]) -> str:
    """Check the stage on the data without fitting: the signals build, every variable and
    response is finite; one line for ``flightid validate``."""
    signals, _, _ = global_model_signals(stage, maneuvers)
    for name in (*stage.settings["variables"], *(c[1] for c in stage.coefficients)):
        if not np.isfinite(signals[name]).all():
            raise CaseError(f"stages[{stage.index}]: non-finite values in {name!r} on the data")
    return (
        f"global_model '{stage.name}': {len(stage.coefficients)} coefficient(s) over "
        f"{', '.join(stage.settings['variables'])}, {len(signals[stage.coefficients[0][1]])} "
        "samples"
    )
