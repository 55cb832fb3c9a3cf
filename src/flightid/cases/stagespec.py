"""``[[stages]]``: the ordered list of stages of a case file, checked (see docs/cases.md).

    [[stages]]
    kind = "stepwise"               # or "regression", "global_model", "output_error",
                                    # "accuracy", "prediction"
    name = "structure"              # optional label (default: the kind)
    f_enter = 4.0                   # options of the kind (below)
    [stages.coefficients.Cm]        # stepwise / regression: one table per coefficient
    response = "Cm"                 # a data channel (default: the table's name)
    candidates = ["alpha", "qhat", "de", "alpha^2"]     # stepwise; regression: terms = [...]

    [[stages]]
    kind = "output_error"
    from = "previous"               # structure and start values from the stage before
    solver = "mnres"                # the keys of [estimation]

Kinds and their keys:

- ``stepwise``: f_enter, f_remove, sigma2_max ("response", "full" or a number), select
  ("pse", "final"), forced (terms), max_steps, and ``[stages.coefficients.NAME]`` with
  response, candidates and any of those options for that coefficient alone.
- ``regression``: ``[stages.coefficients.NAME]`` with response and terms (least squares
  with statistics on exactly those terms; the constant "1" is a term like any other);
  method ("ols" ordinary, "tls" total least squares) and covariance ("ols": s²(XᵀX)⁻¹,
  "eiv": errors-in-variables sandwich; TLS only) for the stage or per coefficient, and per
  coefficient ``parameters`` (one name per term, for the reports).
- ``global_model``: variables, conditions and the options of
  ``flightid.globalmodel.GlobalModelSettings``, and ``[stages.coefficients.NAME]`` with
  response and any of those options for that coefficient alone; ``batch`` takes the
  maneuvers from a ``flightid batch`` results folder (``flightid.cases.globalmodel_case``,
  ``flightid.cases.batch_source``).
- ``output_error``: the keys of ``[estimation]``; ``from = "previous"`` after a stepwise or
  regression stage takes the selected terms and their least-squares estimates as the
  structure and start values of ``[model] type = "alpha_q"`` (coefficients CZ and Cm).
- ``accuracy``: the keys of ``[accuracy]`` (methods default ["cr"]); after output_error.
- ``prediction``: the keys of ``[prediction]`` (file / files / maneuvers, initial_state);
  after output_error.
- ``compatibility``, ``filter_error``: names of the language, not available yet (an error).

For now each kind appears at most once, regression stages come before the output-error
stage, accuracy and prediction after it; a global-model stage stands apart (anywhere). With
``[[stages]]`` the settings live in the stages: top-level [estimation], [accuracy] and
[prediction] are refused (one place for each setting).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from flightid.cases.checks import CaseError, _known, _names, _number, _string, _table
from flightid.cases.settings import (
    StageSpec,
    accuracy_settings,
    estimation_settings,
    prediction_settings,
)
from flightid.model.terms import TermError, parse_term

__all__ = ["STAGE_KINDS", "LATER_KINDS", "STEPWISE_OPTIONS", "parse_stages"]

STAGE_KINDS = (
    "stepwise",
    "regression",
    "global_model",
    "output_error",
    "accuracy",
    "prediction",
)
# names of the language whose stages come in later work
LATER_KINDS = ("compatibility", "filter_error")
REGRESSION_KINDS = ("stepwise", "regression")
STEPWISE_OPTIONS = ("f_enter", "f_remove", "sigma2_max", "select", "forced", "max_steps")
REGRESSION_OPTIONS = ("method", "covariance")
_COMMON = {"kind", "name", "from"}
_MOVED = ("estimation", "accuracy", "prediction")


# ------------------------------------------------------------------------------ options


def _threshold(value: Any, where: str) -> float:
    if _number(value, where) < 0:
        raise CaseError(f"{where}: expected a non-negative number, got {value!r}")
    return float(value)


def _sigma2_max(value: Any, where: str) -> float | str:
    if isinstance(value, str):
        return _string(value, where, ("response", "full"))
    return _threshold(value, where)


def _forced(value: Any, where: str) -> tuple[str, ...]:
    return tuple(_names(value, where))


def _max_steps(value: Any, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise CaseError(f"{where}: expected a positive integer, got {value!r}")
    return value


_OPTION_CHECKS: dict[str, Callable[[Any, str], Any]] = {
    "f_enter": _threshold,
    "f_remove": _threshold,
    "sigma2_max": _sigma2_max,
    "select": lambda value, where: _string(value, where, ("pse", "final")),
    "forced": _forced,
    "max_steps": _max_steps,
}


def _regression_options(table: Mapping[str, Any], where: str) -> dict[str, Any]:
    """``method`` ("ols" | "tls") and ``covariance`` ("ols" | "eiv") of a regression stage."""
    options = {}
    if "method" in table:
        options["method"] = _string(table["method"], f"{where}.method", ("ols", "tls"))
    if "covariance" in table:
        options["covariance"] = _string(table["covariance"], f"{where}.covariance", ("ols", "eiv"))
    return options


def _parameter_names(value: Any, where: str, terms: tuple[str, ...]) -> tuple[str, ...]:
    """One distinct, non-empty name per term."""
    if (
        not isinstance(value, list)
        or len(value) != len(terms)
        or not all(isinstance(n, str) and n.strip() for n in value)
    ):
        raise CaseError(
            f"{where}: expected a list of {len(terms)} names (one per term {list(terms)}), "
            f"got {value!r}"
        )
    if len(set(value)) != len(value):
        raise CaseError(f"{where}: expected distinct names, got {value!r}")
    return tuple(value)


def _stepwise_options(table: Mapping[str, Any], where: str) -> dict[str, Any]:
    """The options of ``flightid.regression.stepwise`` present in ``table``, checked."""
    return {
        key: _OPTION_CHECKS[key](value, f"{where}.{key}")
        for key, value in table.items()
        if key in _OPTION_CHECKS
    }


# ------------------------------------------------------------------------------ coefficients


def _terms(value: Any, where: str, channels: set[str]) -> tuple[str, ...]:
    """A non-empty list of terms whose signals are data channels."""
    if not isinstance(value, list) or not value or not all(isinstance(c, str) for c in value):
        raise CaseError(f"{where}: expected a non-empty list of terms, got {value!r}")
    for text in value:
        try:
            term = parse_term(text)
        except TermError as exc:
            raise CaseError(f"{where}: {exc}") from None
        missing = sorted(set(term.signals) - channels)
        if missing:
            raise CaseError(
                f"{where}: term {text!r} uses {missing}, not channels of [data.inputs] / "
                f"[data.outputs]; channels: {sorted(channels)}"
            )
    return tuple(value)


def _coefficients(stage: Mapping[str, Any], where: str, kind: str, channels: set[str]) -> tuple:
    """``[stages.coefficients.NAME]`` tables: (name, response, terms, options) each."""
    terms_key = "candidates" if kind == "stepwise" else "terms"
    allowed = {"response", terms_key} | (
        set(STEPWISE_OPTIONS) if kind == "stepwise" else {*REGRESSION_OPTIONS, "parameters"}
    )
    table = _table(stage.get("coefficients", {}), f"{where}.coefficients")
    if not table:
        raise CaseError(f"{where}.coefficients: expected at least one [{where}.coefficients.NAME]")
    result = []
    for name, entry in table.items():
        key = f"{where}.coefficients.{name}"
        entry = _table(entry, key)
        _known(entry, allowed, key)
        response = _string(entry.get("response", name), f"{key}.response")
        if response not in channels:
            raise CaseError(
                f"{key}.response: {response!r} is not a channel of [data.inputs] / "
                f"[data.outputs]; channels: {sorted(channels)}"
            )
        if terms_key not in entry:
            raise CaseError(f"{key}.{terms_key}: missing (the terms of {name})")
        terms = _terms(entry[terms_key], f"{key}.{terms_key}", channels)
        if kind == "stepwise":
            options = _stepwise_options(entry, key)
        else:
            options = _regression_options(entry, key)
            if "parameters" in entry:
                options["parameters"] = _parameter_names(
                    entry["parameters"], f"{key}.parameters", terms
                )
        result.append((name, response, terms, options))
    return tuple(result)


# ------------------------------------------------------------------------------ one stage


def _kind(stage: Mapping[str, Any], where: str) -> str:
    if "kind" not in stage:
        raise CaseError(f"{where}.kind: missing; one of {list(STAGE_KINDS)}")
    kind = stage["kind"]
    if kind in LATER_KINDS:
        raise CaseError(
            f"{where}.kind: {kind!r} stages are part of the case language but not available "
            f"yet; available: {list(STAGE_KINDS)}"
        )
    return _string(kind, f"{where}.kind", STAGE_KINDS)


def _stage_settings(stage: Mapping[str, Any], kind: str, where: str, data: Mapping) -> dict:
    """The stage's own keys, checked by the rules of its kind."""
    settings = {k: v for k, v in stage.items() if k not in _COMMON}
    if kind in REGRESSION_KINDS:
        options = STEPWISE_OPTIONS if kind == "stepwise" else REGRESSION_OPTIONS
        _known(settings, {"coefficients", *options}, where)
        if kind == "regression":
            return _regression_options(settings, where)
        return _stepwise_options(settings, where)
    if kind == "output_error":
        estimation_settings(settings, where)
    elif kind == "accuracy":
        accuracy_settings(settings, where)
    else:
        prediction_settings(settings, data, where)
    return settings


def _stage(stage: Any, index: int, data: Mapping[str, Any], channels: set[str]) -> StageSpec:
    where = f"stages[{index}]"
    stage = _table(stage, where)
    kind = _kind(stage, where)
    source = stage.get("from")
    if source is not None:
        _string(source, f"{where}.from", ("previous",))
        if kind != "output_error":
            raise CaseError(f"{where}.from: only an output_error stage takes 'from', not {kind}")
    name = _string(stage.get("name", kind), f"{where}.name")
    if kind == "global_model":
        from flightid.cases.globalmodel_case import parse_global_model_stage

        settings, coefficients = parse_global_model_stage(stage, where, channels)
        return StageSpec(kind, name, index, source, settings, coefficients)
    coefficients = _coefficients(stage, where, kind, channels) if kind in REGRESSION_KINDS else ()
    return StageSpec(
        kind=kind,
        name=name,
        index=index,
        source=source,
        settings=_stage_settings(stage, kind, where, data),
        coefficients=coefficients,
    )


# ------------------------------------------------------------------------------ the list


def _order(stages: list[StageSpec]) -> None:
    """One stage per kind; regression before output error; accuracy, prediction after it."""
    seen: set[str] = set()
    for stage in stages:
        if stage.kind in seen:
            raise CaseError(
                f"stages[{stage.index}].kind: a second {stage.kind!r} stage; one stage of each "
                "kind is available so far"
            )
        seen.add(stage.kind)
    position = {s.kind: s.index for s in stages}
    estimation = position.get("output_error")
    for stage in stages:
        where = f"stages[{stage.index}]"
        if stage.kind in ("accuracy", "prediction") and (
            estimation is None or stage.index < estimation
        ):
            raise CaseError(f"{where}: a {stage.kind} stage follows an output_error stage")
        if stage.kind in REGRESSION_KINDS and estimation is not None and stage.index > estimation:
            raise CaseError(f"{where}: a {stage.kind} stage comes before the output_error stage")


def _structure_source(stages: list[StageSpec], model: Mapping[str, Any]) -> None:
    """``from = "previous"``: a regression stage right before, feeding the α–q model."""
    for stage in stages:
        where = f"stages[{stage.index}]"
        if stage.kind != "output_error":
            continue
        if not model:
            raise CaseError("model: missing section [model]; the output_error stage needs it")
        if stage.source is None:
            if model.get("type") == "alpha_q" and "aero" not in model:
                raise CaseError(
                    f"{where}.from: the alpha_q model has no model.aero; set from = "
                    '"previous" after a stepwise or regression stage, or give model.aero'
                )
            continue
        before = stages[stage.index - 1] if stage.index > 0 else None
        if before is None or before.kind not in REGRESSION_KINDS:
            raise CaseError(
                f'{where}.from: "previous" needs a stepwise or regression stage right before'
            )
        if model.get("type") != "alpha_q":
            raise CaseError(
                f'{where}.from: "previous" builds the model from the regression, which is '
                'available for [model] type = "alpha_q" only so far'
            )
        if "aero" in model:
            raise CaseError(
                'model.aero: the structure comes from the stage before (from = "previous"); '
                "leave model.aero out"
            )
        names = sorted(c[0] for c in before.coefficients)
        if names != ["CZ", "Cm"]:
            raise CaseError(
                f"stages[{before.index}].coefficients: the alpha_q model takes CZ and Cm, got "
                f"{names}"
            )


def _run_settings(stages: list[StageSpec], data: Mapping[str, Any]) -> dict[str, Any]:
    """The Case fields the output-error run reads, taken from its stages."""
    by_kind = {s.kind: s for s in stages}
    estimation = dict(by_kind["output_error"].settings) if "output_error" in by_kind else {}
    accuracy: dict[str, Any] = {}
    if "accuracy" in by_kind:
        accuracy = {"methods": ["cr"], **by_kind["accuracy"].settings}
    prediction, x0 = [], {}
    if "prediction" in by_kind:
        stage = by_kind["prediction"]
        prediction, x0 = prediction_settings(stage.settings, data, f"stages[{stage.index}]")
    return {
        "estimation": estimation,
        "accuracy": accuracy,
        "prediction": tuple(prediction),
        "prediction_initial_state": x0,
    }


def parse_stages(
    raw: Mapping[str, Any], data: Mapping[str, Any], model: Mapping[str, Any]
) -> tuple[tuple[StageSpec, ...], dict[str, Any]]:
    """Check ``[[stages]]``: (the stages, the estimation / accuracy / prediction settings of
    the Case taken from them)."""
    for key in _MOVED:
        if key in raw:
            raise CaseError(
                f"{key}: with [[stages]] the {key} settings go in the stage (kind = "
                f'"{"output_error" if key == "estimation" else key}"), not in [{key}]'
            )
    listed = raw["stages"]
    if not isinstance(listed, list) or not listed:
        raise CaseError("stages: expected a non-empty array of tables ([[stages]])")
    channels = set(_table(data.get("inputs", {}), "data.inputs")) | set(
        _table(data.get("outputs", {}), "data.outputs")
    )
    stages = [_stage(stage, i, data, channels) for i, stage in enumerate(listed)]
    _order(stages)
    _structure_source(stages, model)
    if "output_error" in {s.kind for s in stages} and not data.get("outputs"):
        raise CaseError("data.outputs: missing; the output_error stage needs measured outputs")
    return tuple(stages), _run_settings(stages, data)
