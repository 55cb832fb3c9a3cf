"""Run a case: load data, build the model, estimate, assess accuracy, predict other maneuvers.

Accuracy (``[accuracy] methods`` or ``run_case(..., accuracy=...)``): after the estimation
``flightid.accuracy.assess`` computes, at ``accuracy.confidence``, the Cramér–Rao intervals and
Beale's N_φ (always) and the profile-likelihood and random-search limits when asked; the
search is seeded (``accuracy.seed``, default 0) and bounded by ``accuracy.budget``
(equivalent evaluations, default ``DEFAULT_BUDGET``).

Input interpolation (``[estimation] input_interpolation``): how the inputs vary between
samples in the integration — ``"linear"`` (default; the input at the RK4 half step is the
mean of the neighbouring samples) or ``"zoh"`` (each sample held over its interval, as a
sample-and-hold recorder or a generator holding its input does). The same setting is used
by the estimation, the accuracy assessment and the prediction check.

Prediction check (verification on data not used for estimation): the estimated model is
simulated on each prediction maneuver (initial states at the first measured values unless
``[prediction.initial_state]`` says otherwise) and compared per output:

    RMS error   e_o = √( (1/N) Σ_i (z_io − y_io)² )
    R²_o        = 1 − Σ_i (z_io − y_io)² / Σ_i (z_io − z̄_o)²
"""

from __future__ import annotations

import contextlib
import hashlib
import sys
import threading
import time as _time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from flightid.accuracy import AccuracyResult, accuracy_json, assess
from flightid.accuracy.identifiability import IdentifiabilityReport, check_identifiability
from flightid.accuracy.outliers import DEFAULT_THRESHOLD, OutlierScreen, estimate_robust
from flightid.cases.build import (
    base_model,
    build_convergence,
    build_model,
    build_solver,
    load_maneuvers,
    maneuver_entry,
    prediction_initial_state,
    resolve_data_dir,
    time_base_lines,
    unbiased_model,
    with_process_noise,
)
from flightid.cases.spec import ACCURACY_METHODS, Case, CaseError
from flightid.cases.unstable import apply_unstable_options
from flightid.data.flightdata import FlightData
from flightid.errors import InputError, SimulationError
from flightid.estimation import Estimate, estimate
from flightid.estimation.problem import OutputErrorProblem
from flightid.estimation.shooting import estimate_multiple_shooting
from flightid.model.check import check_model
from flightid.model.statespace import StateSpaceModel
from flightid.simulation import simulate
from flightid.simulation.prediction import Prediction

if TYPE_CHECKING:
    from flightid.compat.kinematic import KinematicSpec

__all__ = [
    "DEFAULT_BUDGET",
    "CaseRun",
    "Prediction",
    "accuracy_methods",
    "check_accuracy_methods",
    "check_estimator",
    "input_interpolation",
    "prediction_model",
    "prepare_case",
    "run_case",
]

Progress = Callable[[str], None]
DEFAULT_BUDGET = 50_000  # random-search budget, equivalent evaluations


def stderr_progress(message: str) -> None:
    print(f"flightid: {message}", file=sys.stderr, flush=True)


def _whiteness_entry(result) -> dict | None:
    """``estimate_whiteness(result).to_dict()``; None for a record too short for any lag."""
    from flightid.accuracy.whiteness import WhitenessError, estimate_whiteness

    try:
        return estimate_whiteness(result).to_dict()
    except WhitenessError:
        return None


def covariance_entry(estimate: Estimate) -> dict:
    """The covariance of the free estimates in results.json: ``parameters`` (the free names,
    the rows' order), ``default`` (the covariance behind ``std``) and ``cramer_rao`` (M⁻¹),
    each n_f × n_f — what ``flightid export`` needs to carry the uncertainty into a model."""
    return {
        "parameters": list(estimate.free_names),
        "default": np.asarray(estimate.covariance_default, dtype=float).tolist(),
        "cramer_rao": np.asarray(estimate.covariance, dtype=float).tolist(),
    }


@dataclass(frozen=True)
class CaseRun:
    """Everything a run produced."""

    case: Case
    data_dir: Path
    model: StateSpaceModel
    maneuvers: tuple[FlightData, ...]
    estimate: Estimate
    predictions: tuple[Prediction, ...] = field(default_factory=tuple)
    model_description: str = ""
    accuracy: AccuracyResult | None = None
    case_sha256: str = ""  # SHA-256 of the case file's bytes when the run started
    # the residual outliers and what was done (``[estimation] outliers``), and the parameter
    # combinations the data barely determine (flightid.accuracy.outliers / .identifiability)
    outliers: OutlierScreen | None = None
    identifiability: IdentifiabilityReport | None = None

    def to_dict(self) -> dict:
        """The core's JSON entry, plus ``case``, ``maneuvers`` and ``prediction``.

        With an accuracy assessment the entry is ``accuracy_json(estimate, accuracy)``: each
        parameter gains ``ci_cr``, ``ci_profile``, ``ci_search`` (when run), ...; the top
        level ``confidence_level``, ``nonlinearity`` ({"N_phi", ...}) and ``accuracy``.
        """
        if self.accuracy is None:
            entry = self.estimate.to_dict()
        else:
            entry = accuracy_json(self.estimate, self.accuracy)
        entry["case"] = {
            "title": self.case.title,
            "file": str(self.case.path),
            "sha256": self.case_sha256,
            "model": self.model_description,
            "data_dir": str(self.data_dir),
        }
        entry["covariance"] = covariance_entry(self.estimate)
        entry["maneuvers"] = [maneuver_entry(m) for m in self.maneuvers]
        entry["prediction"] = [p.to_dict() for p in self.predictions]
        # residual autocorrelation and Ljung–Box test per output (flightid.accuracy.whiteness)
        entry["whiteness"] = _whiteness_entry(self.estimate)
        entry["outliers"] = None if self.outliers is None else self.outliers.to_dict()
        entry["identifiability"] = (
            None if self.identifiability is None else self.identifiability.to_dict()
        )
        entry["modes"] = self.modes_entry()
        return entry

    def modal_analysis(self):
        """The modes of the estimated model at the initial state and mean inputs of the first
        estimation maneuver, with the flying qualities when the case has a
        ``[flying_qualities]`` table (``flightid.export.modal``); None for a model without
        states. Raises ``InputError`` where the linearization or the check cannot be made."""
        from flightid.export.modal import modal_analysis

        if not self.estimate.model.states:
            return None
        return modal_analysis(
            self.estimate, at=self.maneuvers[0], settings=self.case.flying_qualities
        )

    def modes_entry(self) -> dict | None:
        """results.json's ``modes``: ``ModalAnalysis.to_dict()``, None without states, or
        ``{"error": message}`` where they could not be computed."""
        try:
            analysis = self.modal_analysis()
        except (ValueError, TypeError, ArithmeticError) as error:
            # the results are written whatever the modes: the entry says why they are missing
            return {"error": f"{type(error).__name__}: {error}"}
        return None if analysis is None else analysis.to_dict()

    @property
    def kinematic_spec(self) -> KinematicSpec | None:
        """The ``KinematicSpec`` of a case whose ``[model]`` has ``type = "kinematic"`` (what
        ``flightid.compat.reconstruct.write_reconstruction`` inverts the sensors with);
        None for other models."""
        if self.case.model.get("type") != "kinematic":
            return None
        from flightid.cases.compat_case import spec_from_case

        return spec_from_case(self.case)

    @property
    def input_interpolation(self) -> str:
        """The case's ``estimation.input_interpolation`` (``input_interpolation``)."""
        return input_interpolation(self.case)


@dataclass(frozen=True)
class Prepared:
    """A case ready to estimate (``flightid validate`` stops here)."""

    case: Case
    data_dir: Path
    model: StateSpaceModel
    maneuvers: tuple[FlightData, ...]
    prediction_maneuvers: tuple[FlightData, ...]
    base: StateSpaceModel
    model_description: str
    # {state: F parameter} of the filter error method ({} for output error)
    process_noise: dict = field(default_factory=dict)


def filter_error(case: Case) -> bool:
    """True when the case runs the filter error method (``[estimation] estimator``)."""
    return case.estimation.get("estimator", "output_error") == "filter_error"


def prepare_case(
    case: Case,
    data_dir: str | Path | None = None,
    base: tuple[StateSpaceModel, str] | None = None,
) -> Prepared:
    """Load all data and build the model, solver and rules (raises ``CaseError``).

    ``base`` (model, description) replaces the case's ``[model]`` (an output-error stage
    whose structure and start values come from the stage before, ``flightid.cases.stages``).
    """
    directory = resolve_data_dir(case, data_dir)
    if not directory.is_dir():
        raise CaseError(
            f"data.data_dir: the data directory {directory} does not exist (set data.data_dir, "
            "FLIGHTID_DATA or --data-dir)"
        )
    maneuvers = load_maneuvers(case, directory)
    base, description = base_model(case, directory) if base is None else base
    model, maneuvers = build_model(case, maneuvers, base=base)
    process_noise: dict[str, str] = {}
    if filter_error(case):
        model, process_noise = with_process_noise(case, model)
    build_solver(case)
    build_convergence(case)
    input_interpolation(case)
    # the model contract, also for the user's own f and h inside the bias wrappers (compiled
    # code does not check indices): named ModelError before any estimation
    unbiased = unbiased_model(model, base, len(maneuvers))
    if unbiased is not None:
        check_model(unbiased, list(maneuvers), method=case.estimation.get("method", "rk4"))
    r = case.estimation.get("R")
    if r is not None and len(r) != len(model.outputs):
        raise CaseError(
            f"estimation.R: {len(r)} variances for {len(model.outputs)} outputs "
            f"{list(model.outputs)}"
        )
    prediction = (
        load_maneuvers(case, directory, case.prediction, key="prediction")
        if case.prediction
        else []
    )
    per_maneuver = [
        v
        for kind in ("states", "outputs")
        for v in case.biases.get(kind, {}).values()
        if isinstance(v, dict) and v.get("per_maneuver")
    ]
    if prediction and per_maneuver:
        raise CaseError("prediction: not available with per-maneuver biases")
    if prediction and model.maneuver_parameters:
        raise CaseError(
            f"prediction: not available with parameters per maneuver "
            f"{list(model.maneuver_parameters)} (a predicted maneuver has no copy of its own)"
        )
    # the predicted maneuvers' models are built now, so that a bad initial state is named
    # before the estimation and not after it
    for maneuver in prediction:
        prediction_model(case, maneuver, base)
    # stabilizing gain, eigenvalue shift, multiple shooting (docs/unstable.md)
    model, maneuvers = apply_unstable_options(case, model, maneuvers)
    check_estimator(case, model, maneuvers, process_noise)
    return Prepared(
        case,
        directory,
        model,
        tuple(maneuvers),
        tuple(prediction),
        base,
        description,
        process_noise,
    )


def _estimation_key(case: Case) -> str:
    """The table that holds the estimation settings: ``estimation`` or ``stages[i]``."""
    stage = next((s for s in case.stages if s.kind == "output_error"), None)
    return "estimation" if stage is None else f"stages[{stage.index}]"


def check_estimator(
    case: Case,
    model: StateSpaceModel,
    maneuvers: Sequence[FlightData],
    process_noise: dict[str, str],
) -> None:
    """The checks the estimator makes on its arguments before its first iteration, made
    without estimating and without compiling (the problem is set up with the pure-Python
    kernel and dropped): free parameters, the data against the model (channels, initial
    states and parameters per maneuver, stabilizing gain, shooting intervals) and, for the
    filter error method, its solver, states, delays, uniform sampling and, for analytic
    gradients, a linear model; more scalar measurements than free parameters. A refusal is
    a ``CaseError`` before any work is done, in ``flightid validate`` as in ``flightid run``.
    """
    settings = case.estimation
    common = {
        "method": settings.get("method", "rk4"),
        "compiled": False,
        "input_interpolation": input_interpolation(case),
    }
    try:
        if filter_error(case):
            # the filter error method's own checks of its solver and problem
            from flightid.estimation.filter_error import _check_solver, _new_problem

            _check_solver(build_solver(case))
            problem = _new_problem(
                model,
                list(maneuvers),
                process_noise,
                {
                    **common,
                    "linearisation": settings.get("linearisation", "start"),
                    "gradients": settings.get("filter_gradients", "differences"),
                },
            )
        else:
            problem = OutputErrorProblem(model, list(maneuvers), **common)
        problem.check_enough_data()
    except InputError as exc:
        raise CaseError(f"{_estimation_key(case)}: {exc}") from None


def check_accuracy_methods(case: Case, methods: Sequence[str]) -> None:
    """The accuracy methods ``methods`` can follow the case's estimator: with the filter
    error method only the Cramér–Rao bounds are given (``CaseError`` otherwise)."""
    if filter_error(case) and methods:
        raise CaseError(
            f"accuracy.methods: {list(methods)} re-simulate the model without the filter; with "
            "the filter error method only the Cramér–Rao bounds are given (leave methods out)"
        )


def _has_schedule(model: StateSpaceModel) -> bool:
    """True for a multiple-shooting model with a defect-weight continuation (one estimation
    per weight, ``flightid.estimation.shooting``; docs/unstable.md)."""
    return bool(getattr(model, "shooting_schedule", ()))


def input_interpolation(case: Case) -> str:
    """The case's ``estimation.input_interpolation``: ``"linear"`` (default) or ``"zoh"``."""
    return case.estimation.get("input_interpolation", "linear")


def prediction_model(
    case: Case,
    maneuver: FlightData,
    base: StateSpaceModel,
    values: dict[str, float] | None = None,
) -> tuple[StateSpaceModel, list[FlightData]]:
    """The case's model for one predicted maneuver, at ``values`` (name → value; None: the
    start values), with the prediction's initial states (``prediction_initial_state``: its
    own table over the case's ``[initial_state]``); raises ``CaseError`` naming the key."""
    return build_model(
        case,
        [maneuver],
        base=base,
        initial_state=prediction_initial_state(case),
        values={} if values is None else values,
        key="prediction.initial_state",
    )


def _predict(prepared: Prepared, result: Estimate) -> list[Prediction]:
    case = prepared.case
    values = dict(zip(result.names, result.values, strict=True))
    predictions = []
    for maneuver in prepared.prediction_maneuvers:
        model, (data,) = prediction_model(case, maneuver, prepared.base, values)
        try:
            y = simulate(
                model,
                data,
                method=case.estimation.get("method", "rk4"),
                input_interpolation=input_interpolation(case),
            )
        except SimulationError as exc:
            raise CaseError(f"prediction ({maneuver.name}): {exc}") from None
        prediction = Prediction.of_maneuver(data, y, model.outputs)
        # the case's name for the maneuver (its data may carry the file's)
        predictions.append(replace(prediction, name=maneuver.name))
    return predictions


def accuracy_methods(case: Case, override: str | Sequence[str] | None = None) -> tuple[str, ...]:
    """The accuracy methods to run: ``override`` (e.g. the CLI's ``--accuracy``) if given,
    else the case's ``accuracy.methods``; ``()`` (or ``"none"``) runs no assessment."""
    methods = case.accuracy.get("methods", ()) if override is None else override
    if isinstance(methods, str):
        methods = (methods,)
    methods = tuple(methods)
    if methods in ((), ("none",)):
        return ()
    unknown = [m for m in methods if m not in ACCURACY_METHODS]
    if unknown:
        raise CaseError(
            f"accuracy.methods: expected names from {list(ACCURACY_METHODS)}, got {unknown}"
        )
    return methods


@contextlib.contextmanager
def _heartbeat(say: Progress | None, label: str, interval_s: float) -> Iterator[None]:
    """Call ``say`` every ``interval_s`` seconds (0.1 s at least) with the elapsed time while
    the body runs."""
    if say is None:
        yield
        return
    interval_s = max(interval_s, 0.1)
    started = _time.perf_counter()
    done = threading.Event()

    def beat() -> None:
        while not done.wait(interval_s):
            say(f"{label} ... {_time.perf_counter() - started:.0f} s")

    thread = threading.Thread(target=beat, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()


def _assess(
    case: Case,
    result: Estimate,
    maneuvers: Sequence[FlightData],
    methods: tuple[str, ...],
    say: Progress,
    progress: Progress | None,
    heartbeat_s: float,
    engine: object = None,
) -> AccuracyResult:
    settings = case.accuracy
    level = float(settings.get("confidence", 0.95))
    budget = int(settings.get("budget", DEFAULT_BUDGET))
    seed = int(settings.get("seed", 0))
    searching = "search" in methods or "all" in methods
    say(
        f"accuracy: {', '.join(methods)} at level {level:g}"
        + (f" (search: seed {seed}, budget {budget} evaluations)" if searching else "")
    )
    # the search draws its own progress bar on a terminal; elsewhere the heartbeat speaks
    bar = progress is not None and sys.stderr.isatty()
    compiled = bool(case.estimation.get("compiled", True))
    data = _likelihood_data(case, result, maneuvers)
    with _heartbeat(None if bar else progress, "assessing accuracy", heartbeat_s):
        accuracy = assess(
            result,
            data,
            level=level,
            methods=methods,
            kind=settings.get("kind", "individual"),
            distribution=settings.get("distribution", "t"),
            seed=seed,
            budget=budget,
            progress=bar,
            compiled=compiled,
            warn=False,
            engine=engine,
        )
    spent = ", ".join(f"{k} {v}" for k, v in accuracy.evaluations.items())
    say(f"accuracy: N_phi = {accuracy.nonlinearity.n_phi:.3g}; evaluations {spent}")
    for message in accuracy.warnings:
        say(f"accuracy warning: {message}")
    return accuracy


def _likelihood_data(
    case: Case, result: Estimate, maneuvers: Sequence[FlightData]
) -> list[FlightData] | OutputErrorProblem:
    """The data of the likelihood region: the maneuvers, or with an input interpolation other
    than linear the output-error problem on them with that interpolation."""
    if input_interpolation(case) == "linear":
        return list(maneuvers)
    return OutputErrorProblem(
        result.model,
        list(maneuvers),
        method=result.method,
        compiled=bool(case.estimation.get("compiled", True)),
        input_interpolation=input_interpolation(case),
    )


def _estimate_filter_error(
    case: Case, prepared: Prepared, progress: Callable[[int, int, float], None]
) -> Estimate:
    """The filter error method on a prepared case (``[estimation] estimator``)."""
    from flightid.estimation.filter_error import estimate_filter_error

    settings = case.estimation
    return estimate_filter_error(
        prepared.model,
        list(prepared.maneuvers),
        prepared.process_noise,
        solver=build_solver(case),
        relaxation=settings.get("relaxation", "fixed_point"),
        method=settings.get("method", "rk4"),
        input_interpolation=input_interpolation(case),
        linearisation=settings.get("linearisation", "start"),
        convergence=build_convergence(case),
        max_cycles=int(settings.get("max_cycles", 30)),
        compiled=bool(settings.get("compiled", True)),
        progress=progress,
        gradients=settings.get("filter_gradients", "differences"),
    )


def run_case(
    case: Case | str | Path,
    data_dir: str | Path | None = None,
    progress: Progress | None = None,
    heartbeat_s: float = 5.0,
    accuracy: str | Sequence[str] | None = None,
    base: tuple[StateSpaceModel, str] | None = None,
    engine: object = None,
) -> CaseRun:
    """Prepare, estimate, assess accuracy and predict; ``progress`` receives one-line messages.

    Args:
        case: a checked case (``load_case``), or the path of a case file (read with
            ``load_case``).
        data_dir: the data directory (overrides the case's).
        progress: receives progress messages (None: silent).
        heartbeat_s: seconds between "still running" messages.
        accuracy: accuracy methods (``"cr"``, ``"profile"``, ``"search"``, ``"all"`` or a
            list; ``"none"`` for no assessment); None: the case's ``accuracy.methods``.
        base: (model, description) in place of the case's ``[model]`` (see ``prepare_case``).
        engine: a ``flightid.batch`` engine for the profile and search tasks of the accuracy
            assessment (``flightid.batch.make_engine``; the caller closes it); None: this
            process. The numbers do not depend on it.
    """
    if isinstance(case, (str, Path)):
        from flightid.cases.spec import load_case

        case = load_case(case)
    elif not isinstance(case, Case):
        from flightid.errors import InputTypeError

        raise InputTypeError(
            f"case: expected a Case (load_case) or a case file path, got {type(case).__name__}"
        )
    say = progress or (lambda message: None)
    methods = accuracy_methods(case, accuracy)
    check_accuracy_methods(case, methods)
    case_file = Path(case.path)
    # the report names the exact case text that ran: SHA-256 of the file's bytes
    case_sha256 = hashlib.sha256(case_file.read_bytes()).hexdigest() if case_file.is_file() else ""
    say(f"case {case.title!r}: loading data and building the model")
    prepared = prepare_case(case, data_dir, base)
    model = prepared.model
    say(
        f"{len(prepared.maneuvers)} maneuver(s), {sum(m.n_samples for m in prepared.maneuvers)} "
        f"samples; {len(model.parameters.free_names)} free parameters; "
        f"solver {case.estimation.get('solver', 'mnres')}, noise "
        f"{case.estimation.get('noise', 'max')}"
    )
    for line in time_base_lines(prepared.maneuvers):
        say(f"time base: {line}")
    last_report = [_time.monotonic()]

    def report_pass(passes: int, evaluations: int, cost: float) -> None:
        # one line per heartbeat interval at most
        now = _time.monotonic()
        if progress is not None and now - last_report[0] >= heartbeat_s:
            last_report[0] = now
            progress(f"estimating: pass {passes}, {evaluations} simulations, cost {cost:.6g}")

    with _heartbeat(progress, "estimating", heartbeat_s):
        if filter_error(case):
            result = _estimate_filter_error(case, prepared, report_pass)
        else:
            options = dict(
                solver=build_solver(case),
                method=case.estimation.get("method", "rk4"),
                noise=case.estimation.get("noise", "max"),
                R=case.estimation.get("R"),
                convergence=build_convergence(case),
                compiled=bool(case.estimation.get("compiled", True)),
                progress=report_pass,
                input_interpolation=input_interpolation(case),
            )
            estimator = estimate_multiple_shooting if _has_schedule(model) else estimate
            result = estimator(model, list(prepared.maneuvers), **options)
        result, screen = estimate_robust(
            model,
            list(prepared.maneuvers),
            case.estimation.get("outliers", "warn"),
            threshold=float(case.estimation.get("outlier_threshold", DEFAULT_THRESHOLD)),
            first=result,
            estimator=None if filter_error(case) else estimator,
            **({} if filter_error(case) else options),
        )
    say(
        f"{result.status}: {result.iterations} iterations, {result.equivalent_evaluations} "
        f"evaluations, cost {result.cost:.6g}, {result.wall_time_s:.1f} s"
    )
    assessed = (
        _assess(case, result, prepared.maneuvers, methods, say, progress, heartbeat_s, engine)
        if methods
        else None
    )
    # both issue their findings as FlightIdWarning (``flightid: warning: ...`` on the terminal)
    identifiability = check_identifiability(
        result,
        # the profile re-simulates the plain output-error problem: not with the filter or with
        # multiple shooting (whose defect rows it does not have)
        None
        if filter_error(case) or getattr(result.model, "shooting", None) is not None
        else _likelihood_data(case, result, prepared.maneuvers),
        accuracy=assessed,
        level=float(case.accuracy.get("confidence", 0.95)),
        compiled=bool(case.estimation.get("compiled", True)),
    )
    predictions = _predict(prepared, result) if prepared.prediction_maneuvers else []
    for p in predictions:
        numbers = ", ".join(
            f"{n}: RMS {e:.4g}, R² {r:.3f}"
            for n, e, r in zip(p.output_names, p.rms, p.r2, strict=True)
        )
        say(f"prediction on {p.name}: {numbers}")
    return CaseRun(
        case,
        prepared.data_dir,
        model,
        prepared.maneuvers,
        result,
        tuple(predictions),
        prepared.model_description,
        assessed,
        case_sha256,
        screen,
        identifiability,
    )
