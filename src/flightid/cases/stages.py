"""Run (and dry-check) the ``[[stages]]`` of a case: regression → output error → accuracy,
prediction — the SIDPAC workflow in one file and one ``flightid run``.

A stepwise stage runs ``flightid.regression.stepwise`` per coefficient on the channels of
the case's maneuvers (all estimation maneuvers, concatenated); a regression stage fits
least squares with statistics on the given terms. An output-error stage with
``from = "previous"`` takes the selected terms and their least-squares estimates as the
structure and start values of the α–q model (``flightid.cases.alpha_q``; each parameter's
scale max(|θ̂|, σ̂), ``flightid.regression.pipeline.starting_parameters``) and runs the
ordinary case run (``flightid.cases.run.run_case``: estimation, then the accuracy and
prediction stages, whose settings ``parse_case`` placed in the Case).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from flightid.accuracy.whiteness import Whiteness, WhitenessError, residual_whiteness
from flightid.cases.build import alpha_q_base, load_maneuvers, resolve_data_dir
from flightid.cases.checks import CaseError
from flightid.cases.run import CaseRun, Prepared, prepare_case, run_case
from flightid.cases.spec import Case, StageSpec
from flightid.data.flightdata import FlightData
from flightid.errors import InputError
from flightid.model.parameters import Parameters
from flightid.model.terms import Term, evaluate_terms, parse_term
from flightid.regression.least_squares import LeastSquaresResult, least_squares
from flightid.regression.pipeline import (
    LinearAeroStructure,
    PipelineResult,
    starting_parameters,
)
from flightid.regression.stepwise import StepwiseResult, selected_fit_dict, stepwise
from flightid.regression.total_least_squares import (
    TotalLeastSquaresResult,
    total_least_squares,
)

__all__ = [
    "StagesRun",
    "TermsFit",
    "case_signals",
    "has_regression_stages",
    "run_regression_stage",
    "run_stages",
    "stage_signals",
    "validate_stages",
]

Progress = Callable[[str], None]


@dataclass(frozen=True, eq=False)
class TermsFit:
    """A regression stage's fit of one coefficient on given terms (least squares with
    statistics); like ``StepwiseResult`` it has ``selected_terms`` and ``fit``."""

    response: str
    selected: tuple[str, ...]
    fit: LeastSquaresResult
    parameter_names: tuple[str, ...] = ()  # the case's names of the terms' parameters

    @property
    def selected_terms(self) -> list[Term]:
        return [parse_term(label) for label in self.selected]

    @property
    def method(self) -> str:
        """The fit's method: "tls" (total least squares) or "ols"."""
        return "tls" if isinstance(self.fit, TotalLeastSquaresResult) else "ols"

    def summary(self) -> str:
        title = "Total least squares" if self.method == "tls" else "Least squares"
        text = f"{title} for {self.response}\n\n" + self.fit.summary()
        if self.parameter_names:
            pairs = ", ".join(
                f"{n} = {t}" for n, t in zip(self.parameter_names, self.selected, strict=True)
            )
            text += f"\nparameters: {pairs}"
        return text

    def to_dict(self) -> dict:
        """``selected``, ``parameters`` (name, value, std; with ``parameters`` names in the
        case each row also names its ``term``), ``r2``, ``pse``, ``s2``, ``method`` and, for
        TLS, ``covariance`` and each parameter's ``std_ols`` and ``std_eiv``."""
        entry = selected_fit_dict(self.selected, self.fit)
        entry["method"] = self.method
        if self.method == "tls":
            full = self.fit.to_dict()
            entry["covariance"] = full["covariance"]
            entry["parameters"] = full["parameters"]
        if self.parameter_names:
            for row, name, term in zip(
                entry["parameters"], self.parameter_names, self.selected, strict=True
            ):
                row["term"] = term
                row["name"] = name
        return entry


RegressionResult = StepwiseResult | TermsFit


@dataclass(frozen=True, eq=False)
class StagesRun:
    """What the stages of a case produced.

    Attributes:
        case: the case.
        data_dir: the data directory used.
        regressions: per regression stage (in order): (stage, {coefficient: result}).
        global_models: per global-model stage (in order): (stage, ``GlobalModel``).
        output_error: the output-error run (estimate, accuracy, predictions), or None.
        pipeline: regression → output error (comparison table), when ``from = "previous"``.
    """

    case: Case
    data_dir: Path
    regressions: tuple[tuple[StageSpec, Mapping[str, RegressionResult]], ...]
    output_error: CaseRun | None = None
    pipeline: PipelineResult | None = None
    maneuver_index: np.ndarray | None = None  # (N,) maneuver of each regression sample
    dt: float | None = None  # s, sample interval of the first maneuver
    # per global-model stage (in order): (stage, flightid.globalmodel.GlobalModel)
    global_models: tuple[tuple[StageSpec, Any], ...] = ()
    # per global-model stage index: the batch cases it skipped, {"case", "reason"} each
    global_model_skipped: Mapping[int, tuple[Mapping[str, str], ...]] = field(default_factory=dict)

    def whiteness(self, result: RegressionResult) -> Whiteness | None:
        """Residual whiteness of one regression fit (``flightid.accuracy.whiteness``; lags
        never pair samples of different maneuvers); None for a record too short."""
        try:
            return residual_whiteness(
                result.fit.residuals,
                (result.response,),
                maneuver_index=self.maneuver_index,
                dt=self.dt,
            )
        except WhitenessError:
            return None

    @property
    def estimate(self):
        return None if self.output_error is None else self.output_error.estimate

    def stages_dict(self) -> list[dict]:
        """One entry per stage: ``kind``, ``name`` and, for regression stages,
        ``coefficients`` ({name: result.to_dict() with ``whiteness``, the residual
        autocorrelation and Ljung–Box test}); a global-model stage adds its model
        (``flightid.cases.globalmodel_case.global_model_entry``); the output-error stage
        adds ``start`` (the values it started from) when it took them from the stage
        before."""
        from flightid.cases.globalmodel_case import global_model_entry

        entries = []
        regressions = {stage.index: results for stage, results in self.regressions}
        global_models = {stage.index: model for stage, model in self.global_models}
        for stage in self.case.stages:
            entry: dict[str, Any] = {"kind": stage.kind, "name": stage.name}
            if stage.index in global_models:
                skipped = self.global_model_skipped.get(stage.index, ())
                entry.update(global_model_entry(global_models[stage.index], skipped))
            if stage.index in regressions:
                coefficients = {}
                for n, r in regressions[stage.index].items():
                    whiteness = self.whiteness(r)
                    coefficients[n] = {
                        **r.to_dict(),
                        "whiteness": None if whiteness is None else whiteness.to_dict(),
                    }
                entry["coefficients"] = coefficients
            if stage.kind == "output_error" and self.pipeline is not None:
                entry["start"] = {p.name: float(p.value) for p in self.pipeline.start}
            entries.append(entry)
        return entries

    def to_dict(self) -> dict:
        """``{"results": [ENTRY] (the output-error entry of ``flightid run``; [] without an
        output-error stage), "stages": [...]}`` (``stages_dict``)."""
        results = [] if self.output_error is None else [self.output_error.to_dict()]
        return {"results": results, "stages": self.stages_dict()}

    def summary(self) -> str:
        """Regression results (each with its residual whiteness), the regression-vs-ML table
        and the estimate summary."""
        parts = []
        for _, results in self.regressions:
            for result in results.values():
                whiteness = self.whiteness(result)
                tail = "" if whiteness is None else "\n" + whiteness.summary()
                parts.append(result.summary() + tail)
        for _, model in self.global_models:
            parts.append(model.summary())
        if self.pipeline is not None:
            parts.append("Regression → output error\n" + self.pipeline.comparison())
        return "\n\n".join(parts)


def has_regression_stages(case: Case) -> bool:
    """True when the case has stages other than output error, accuracy and prediction."""
    return any(stage.kind in ("stepwise", "regression", "global_model") for stage in case.stages)


# ------------------------------------------------------------------------------ regression


def stage_signals(maneuvers: Sequence[FlightData]) -> dict[str, np.ndarray]:
    """Every channel (inputs and outputs) of the maneuvers, concatenated in order."""
    names = list(maneuvers[0].input_names) + list(maneuvers[0].output_names)
    return {name: np.concatenate([m.channel(name) for m in maneuvers]) for name in names}


def case_signals(case: Case, data_dir: str | Path | None = None) -> dict[str, np.ndarray]:
    """The channels a regression stage of ``case`` sees (``stage_signals`` of its maneuvers,
    in the units the channel rule delivers)."""
    return stage_signals(load_maneuvers(case, _data_directory(case, data_dir)))


def _stepwise_stage(stage: StageSpec, signals: Mapping[str, np.ndarray]) -> dict:
    results = {}
    for name, response, candidates, options in stage.coefficients:
        try:
            results[name] = stepwise(
                signals[response],
                candidates,
                signals,
                response=name,
                **{**stage.settings, **options},
            )
        except InputError as exc:
            raise CaseError(f"stages[{stage.index}].coefficients.{name}: {exc}") from None
    return results


def _regression_stage(stage: StageSpec, signals: Mapping[str, np.ndarray]) -> dict:
    """Least squares (``method = "ols"``) or total least squares (``"tls"``) per
    coefficient, on exactly its terms."""
    results = {}
    for name, response, terms, options in stage.coefficients:
        where = f"stages[{stage.index}].coefficients.{name}"
        method = options.get("method", stage.settings.get("method", "ols"))
        covariance = options.get("covariance", stage.settings.get("covariance"))
        if method == "ols" and covariance not in (None, "ols"):
            raise CaseError(
                f'{where}: covariance = {covariance!r} is for method = "tls"; ordinary '
                "least squares has the covariance s²(XᵀX)⁻¹"
            )
        parsed = [parse_term(t) for t in terms]
        labels = tuple(t.label for t in parsed)
        try:
            X = evaluate_terms(parsed, signals)
            if method == "tls":
                fit = total_least_squares(
                    X, signals[response], labels, covariance=covariance or "ols"
                )
            else:
                fit = least_squares(X, signals[response], labels)
        except InputError as exc:
            raise CaseError(f"{where}: {exc}") from None
        results[name] = TermsFit(name, labels, fit, tuple(options.get("parameters", ())))
    return results


def run_regression_stage(
    stage: StageSpec, signals: Mapping[str, np.ndarray], progress: Progress | None = None
) -> dict[str, RegressionResult]:
    """Run one stepwise or regression stage on ``signals`` (``case_signals``):
    {coefficient: ``StepwiseResult`` or ``TermsFit``}."""
    say = progress or (lambda message: None)
    run = _stepwise_stage if stage.kind == "stepwise" else _regression_stage
    results = run(stage, signals)
    for name, result in results.items():
        say(f"{stage.kind} {name}: {', '.join(result.selected)} (R² {result.fit.r2:.4f})")
    return results


# ------------------------------------------------------------------------------ all stages


def _output_error_stage(case: Case) -> StageSpec | None:
    return next((s for s in case.stages if s.kind == "output_error"), None)


def run_stages(
    case: Case,
    data_dir: str | Path | None = None,
    progress: Progress | None = None,
    accuracy: str | Sequence[str] | None = None,
    heartbeat_s: float = 5.0,
) -> StagesRun:
    """Run every stage of ``case`` in order (see the module docstring).

    Args:
        case: a checked case with ``[[stages]]``.
        data_dir: the data directory (overrides the case's).
        progress: receives one-line progress messages (None: silent).
        accuracy: accuracy methods overriding the accuracy stage (as ``run_case``).
        heartbeat_s: seconds between "still running" messages of the estimation.
    """
    say = progress or (lambda message: None)
    directory, maneuvers = _own_maneuvers(case, data_dir)
    signals = stage_signals(maneuvers) if maneuvers else {}
    samples: dict[str, Any] = {"maneuver_index": None, "dt": None}
    if maneuvers:
        counts = [np.full(m.n_samples, k) for k, m in enumerate(maneuvers)]
        samples.update(maneuver_index=np.concatenate(counts), dt=float(maneuvers[0].dt))
    regressions: list[tuple[StageSpec, Mapping[str, RegressionResult]]] = []
    global_models, skipped = [], {}
    for stage in case.stages:
        if stage.kind in ("stepwise", "regression"):
            regressions.append((stage, run_regression_stage(stage, signals, say)))
        elif stage.kind == "global_model":
            from flightid.cases.globalmodel_case import run_global_model_stage

            data = _global_model_data(stage, case, maneuvers, data_dir, say)
            global_models.append((stage, run_global_model_stage(stage, maneuvers, say, data=data)))
            if data.skipped:
                skipped[stage.index] = data.skipped
    samples["global_models"] = tuple(global_models)
    samples["global_model_skipped"] = skipped
    oe_stage = _output_error_stage(case)
    if oe_stage is None:
        return StagesRun(case, directory, tuple(regressions), **samples)
    base, structure, start = None, None, None
    if oe_stage.source == "previous":
        results = regressions[-1][1]
        structure = LinearAeroStructure.from_stepwise(results)
        start = starting_parameters(results)
        base = alpha_q_base(case, directory, structure, start)
        say(f"output error from the {regressions[-1][0].kind} stage: {structure.parameter_names}")
    run = run_case(case, directory, progress, heartbeat_s, accuracy, base=base)
    pipeline = None
    if structure is not None:
        pipeline = PipelineResult(regressions[-1][1], structure, start, base[0], run.estimate)
    return StagesRun(case, directory, tuple(regressions), run, pipeline, **samples)


def _global_model_data(
    stage: StageSpec,
    case: Case,
    maneuvers: Sequence[FlightData],
    data_dir: str | Path | None,
    progress: Progress | None = None,
):
    """What a global-model stage is fitted to: the maneuvers of its batch folder
    (``batch = ...``, relative to the case file) or the case's own."""
    if stage.settings.get("batch") is not None:
        from flightid.cases.batch_source import batch_stage_data

        return batch_stage_data(stage, case.directory, data_dir, progress)
    from flightid.cases.globalmodel_case import global_model_stage_data

    return global_model_stage_data(stage, maneuvers)


def _own_maneuvers(case: Case, data_dir: str | Path | None) -> tuple[Path, list[FlightData]]:
    """(the data directory, the case's own maneuvers); a case without ``[data]`` (its
    global-model stages take their maneuvers from batch folders) has none and its
    directory need not exist."""
    if not case.data:
        return resolve_data_dir(case, data_dir), []
    directory = _data_directory(case, data_dir)
    return directory, load_maneuvers(case, directory)


def _data_directory(case: Case, data_dir: str | Path | None) -> Path:
    directory = resolve_data_dir(case, data_dir)
    if not directory.is_dir():
        raise CaseError(
            f"data.data_dir: the data directory {directory} does not exist (set data.data_dir, "
            "FLIGHTID_DATA or --data-dir)"
        )
    return directory


# ------------------------------------------------------------------------------ validation


def _check_terms(stage: StageSpec, signals: Mapping[str, np.ndarray]) -> str:
    """Evaluate every term of a regression stage on the data: finite values."""
    for name, response, terms, _ in stage.coefficients:
        values = evaluate_terms([parse_term(t) for t in terms], signals)
        bad = [t for t, ok in zip(terms, np.isfinite(values).all(axis=0), strict=True) if not ok]
        if bad or not np.isfinite(signals[response]).all():
            raise CaseError(
                f"stages[{stage.index}].coefficients.{name}: non-finite values in "
                f"{bad or [response]} on the data"
            )
    count = sum(len(c[2]) for c in stage.coefficients)
    return f"{stage.kind} '{stage.name}': {len(stage.coefficients)} coefficient(s), {count} terms"


def _dry_structure(stage: StageSpec) -> tuple[LinearAeroStructure, Parameters]:
    """Every candidate term of a regression stage, at start value 0: the largest structure
    the output-error stage can receive from it."""
    from flightid.cases.alpha_q import structure_from_terms, zero_parameters

    aero = {}
    for name, _, terms, options in stage.coefficients:
        # a stepwise stage always keeps its forced terms (default the constant "1")
        forced = options.get("forced", stage.settings.get("forced", ("1",)))
        every = [*forced, *terms] if stage.kind == "stepwise" else list(terms)
        labels = {}
        for text in every:
            labels.setdefault(parse_term(text).label, text)
        aero[name] = list(labels.values())
    structure = structure_from_terms(aero)
    return structure, zero_parameters(structure)


def validate_stages(
    case: Case, data_dir: str | Path | None = None
) -> tuple[list[str], Prepared | None]:
    """Check every stage without estimating: (one line per stage, the ``Prepared`` output-
    error stage or None). The output-error stage after a regression is built with all the
    candidate terms (start 0), so ``check_model`` sees every term it may get."""
    directory, maneuvers = _own_maneuvers(case, data_dir)
    signals = stage_signals(maneuvers) if maneuvers else {}
    lines, prepared = [], None
    last_regression = None
    for stage in case.stages:
        if stage.kind in ("stepwise", "regression"):
            lines.append(_check_terms(stage, signals))
            last_regression = stage
        elif stage.kind == "global_model":
            from flightid.cases.globalmodel_case import validate_global_model_stage

            data = _global_model_data(stage, case, maneuvers, data_dir)
            lines.append(validate_global_model_stage(stage, maneuvers, data))
        elif stage.kind == "output_error":
            base = None
            if stage.source == "previous":
                structure, parameters = _dry_structure(last_regression)
                base = alpha_q_base(case, directory, structure, parameters)
            prepared = prepare_case(case, directory, base)
            lines.append(
                f"output_error '{stage.name}': {prepared.model_description}"
                + (" with every candidate term" if base is not None else "")
            )
        else:
            lines.append(f"{stage.kind} '{stage.name}'")
    return lines, prepared
