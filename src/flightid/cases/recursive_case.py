"""Case files with a ``[recursive]`` table: recursive (online) estimation
(Jategaonkar, *Flight Vehicle System Identification*, 2nd ed., ch. 7).

    [recursive]
    method = "ekf"            # ekf | ukf | ukf_aug | efrls | ftr
    p0 = 10.0                 # number (× I) or a list (diagonal), augmented states
    q_states = [1e-7, 1e-7]   # per-step covariance (EKF, UKF); ẋ-noise variance (ukf_aug)
    r0 = [4.1e-7, 8.0e-7]     # measurement noise covariance (number × I or diagonal)
    jacobian_step = 1e-4      # EKF: absolute central-difference step (number or list)
    report = "last_10"        # mean over the last 10 samples ("final": the last one)

    # efrls: forgetting = 0.998, p0 = 1e3, jacobian_step = 1e-7 (relative)
    # ftr:   states = ["alpha", "q"], inputs = ["de"] (channel names),
    #        frequencies_hz = {start = 0.2, stop = 1.5, step = 0.04}, update_every_s = 1.0,
    #        parameter_names = [[...], [...]] (per state equation: A row, then B row),
    #        offsets = {zq = 1.0} (reported = coefficient − offset), n_mean = 10,
    #        report = "last_5" (updates), input_delays_s = {de = 0.05} (fixed delays, s)

The filters (EKF, UKF, UKF_aug, EFRLS) estimate the free parameters of ``[model]`` (built
with ``[parameters]``, ``[initial_state]`` and ``[biases]`` as for output error; x0 is that of
the first maneuver). The FTR needs no model: it regresses the measured ``states`` channels on
themselves and the ``inputs`` channels in the frequency domain.

Several ``[data]`` files are ONE continuous record here: the samples are joined without
re-initialising the state at a junction, and the time is regenerated over the joined record,
t_k = (k − 1)·dt, k = 1..N (the files' own time columns are not used).
Every key is checked; a wrong one is a ``CaseError`` naming ``recursive.<key>``.
"""

from __future__ import annotations

import hashlib
import time as _time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from flightid.cases.build import (
    base_model,
    build_model,
    load_maneuvers,
    maneuver_entry,
    resolve_data_dir,
)
from flightid.cases.checks import CaseError, _bool, _integer, _known, _names, _number, _string
from flightid.cases.spec import Case
from flightid.errors import InputError

__all__ = [
    "RECURSIVE_METHODS",
    "RecursivePreparation",
    "prepare_recursive_case",
    "recursive_settings",
    "run_recursive_case",
]

RECURSIVE_METHODS = ("ekf", "ukf", "ukf_aug", "efrls", "ftr")
_COMMON = {"method", "report", "compiled"}
_KEYS = {
    "ekf": _COMMON | {"p0", "q_states", "r0", "jacobian_step"},
    "ukf": _COMMON | {"p0", "q_states", "r0"},
    "ukf_aug": _COMMON | {"p0", "q_states", "r0"},
    "efrls": _COMMON | {"p0", "forgetting", "jacobian_step"},
    "ftr": _COMMON
    | {
        "states",
        "inputs",
        "frequencies_hz",
        "update_every_s",
        "parameter_names",
        "offsets",
        "n_mean",
        "input_delays_s",
    },
}
_REQUIRED = {
    "ekf": ("p0", "q_states", "r0"),
    "ukf": ("p0", "q_states", "r0"),
    "ukf_aug": ("p0", "q_states", "r0"),
    "efrls": (),
    "ftr": ("states", "inputs", "frequencies_hz", "update_every_s"),
}


def _numbers(value: Any, key: str, *, positive: bool = False) -> float | list[float]:
    """A number or a non-empty list of numbers (all ≥ 0, or > 0 with ``positive``)."""
    values = value if isinstance(value, list) else [value]
    if not values:
        raise CaseError(f"{key}: expected a number or a non-empty list of numbers, got []")
    checked = [_number(v, f"{key}" if not isinstance(value, list) else f"{key}[{i}]")
               for i, v in enumerate(values)]  # fmt: skip
    for i, v in enumerate(checked):
        if v < 0 or (positive and v == 0):
            where = key if not isinstance(value, list) else f"{key}[{i}]"
            raise CaseError(f"{where}: expected a number {'>' if positive else '>='} 0, got {v}")
    return checked if isinstance(value, list) else checked[0]


def _method(table: Any) -> str:
    """The checked method of ``[recursive]``; every key known to it, every key it needs."""
    if not isinstance(table, Mapping) or not table:
        raise CaseError("recursive: expected a table with at least 'method'")
    if "method" not in table:
        raise CaseError(f"recursive.method: missing; one of {list(RECURSIVE_METHODS)}")
    method = _string(table["method"], "recursive.method", RECURSIVE_METHODS)
    _known(table, _KEYS[method], "recursive")
    for key in _REQUIRED[method]:
        if key not in table:
            raise CaseError(f"recursive.{key}: missing; method {method!r} needs it")
    return method


def _report(table: Mapping[str, Any], method: str) -> str:
    """``report``: "final" or "last_<n>" (default last_5 updates for the FTR, else last_10)."""
    report = _string(
        table.get("report", "last_5" if method == "ftr" else "last_10"), "recursive.report"
    )
    from flightid.recursive.result import report_rows

    try:
        report_rows(report, 1)
    except InputError as exc:
        raise CaseError(f"recursive.{exc}") from None
    return report


def _filter_settings(table: Mapping[str, Any], method: str) -> dict[str, Any]:
    """p0, q_states, r0 (and the EKF's jacobian_step) of the EKF, UKF and UKF_aug."""
    settings = {
        "p0": _numbers(table["p0"], "recursive.p0"),
        "q_states": _numbers(table["q_states"], "recursive.q_states"),
        "r0": _numbers(table["r0"], "recursive.r0", positive=True),
    }
    if method == "ekf":
        settings["jacobian_step"] = _numbers(
            table.get("jacobian_step", 1e-4), "recursive.jacobian_step", positive=True
        )
    return settings


def _efrls_settings(table: Mapping[str, Any]) -> dict[str, Any]:
    """p0, forgetting in (0, 1] and the relative jacobian_step (one number) of the EFRLS."""
    p0 = _numbers(table.get("p0", 1e3), "recursive.p0", positive=True)
    forgetting = _number(table.get("forgetting", 0.998), "recursive.forgetting")
    if not 0.0 < forgetting <= 1.0:
        raise CaseError(f"recursive.forgetting: expected a number in (0, 1], got {forgetting}")
    step = table.get("jacobian_step", 1e-7)
    if isinstance(step, list):
        raise CaseError(
            f"recursive.jacobian_step: the EFRLS step is relative, one number; got {step!r}"
        )
    return {
        "p0": p0,
        "forgetting": forgetting,
        "jacobian_step": _numbers(step, "recursive.jacobian_step", positive=True),
    }


def _ftr_channels(table: Mapping[str, Any]) -> tuple[list[str], list[str]]:
    """(states, inputs): at least one state, no name twice, none both a state and an input."""
    channels = {
        "states": _names(table["states"], "recursive.states"),
        "inputs": _names(table["inputs"], "recursive.inputs"),
    }
    if not channels["states"]:
        raise CaseError("recursive.states: expected at least one state channel, got []")
    for key, names in channels.items():
        repeated = sorted({n for n in names if names.count(n) > 1})
        if repeated:
            raise CaseError(f"recursive.{key}: {repeated} named more than once")
    both = sorted(set(channels["states"]) & set(channels["inputs"]))
    if both:
        raise CaseError(
            f"recursive.inputs: {both} also named in recursive.states (a channel is a "
            "state or an input)"
        )
    return channels["states"], channels["inputs"]


def _frequency_grid(grid: Any) -> dict[str, float]:
    """``frequencies_hz = {start, stop, step}`` (Hz), each a number."""
    if not isinstance(grid, Mapping):
        raise CaseError(
            f"recursive.frequencies_hz: expected a table {{start, stop, step}} (Hz), got {grid!r}"
        )
    _known(grid, {"start", "stop", "step"}, "recursive.frequencies_hz")
    for key in ("start", "stop", "step"):
        if key not in grid:
            raise CaseError(f"recursive.frequencies_hz.{key}: missing (Hz)")
    return {
        key: _number(grid[key], f"recursive.frequencies_hz.{key}")
        for key in ("start", "stop", "step")
    }


def _update_every_s(value: Any) -> float:
    """``update_every_s``: the time between least-squares updates, > 0 s."""
    update = _number(value, "recursive.update_every_s")
    if update <= 0:
        raise CaseError(f"recursive.update_every_s: expected a time > 0 (s), got {update}")
    return update


def _ftr_parameter_names(rows: Any) -> list[list[str]]:
    """``parameter_names``: a list of lists of names (one per state equation)."""
    if not isinstance(rows, list):
        raise CaseError(
            f"recursive.parameter_names: expected a list of lists of names, got {rows!r}"
        )
    return [_names(row, f"recursive.parameter_names[{i}]") for i, row in enumerate(rows)]


def _ftr_offsets(offsets: Any) -> dict[str, float]:
    """``offsets = {name = number}``: the known parts removed before reporting."""
    if not isinstance(offsets, Mapping):
        raise CaseError(f"recursive.offsets: expected a table name = number, got {offsets!r}")
    return {k: _number(v, f"recursive.offsets.{k}") for k, v in offsets.items()}


def _ftr_settings(table: Mapping[str, Any]) -> dict[str, Any]:
    """The FTR's channels, frequency grid, update interval, n_mean, names, offsets, delays."""
    states, inputs = _ftr_channels(table)
    settings: dict[str, Any] = {
        "states": states,
        "inputs": inputs,
        "frequencies_hz": _frequency_grid(table["frequencies_hz"]),
        "update_every_s": _update_every_s(table["update_every_s"]),
        "n_mean": _integer(table.get("n_mean", 10), "recursive.n_mean", 1),
    }
    if "parameter_names" in table:
        settings["parameter_names"] = _ftr_parameter_names(table["parameter_names"])
    settings["offsets"] = _ftr_offsets(table.get("offsets", {}))
    settings["input_delays_s"] = _ftr_delays(table.get("input_delays_s", {}), inputs)
    return settings


def recursive_settings(table: Mapping[str, Any]) -> dict[str, Any]:
    """The checked ``[recursive]`` table, with defaults filled in (CaseError naming the key)."""
    method = _method(table)
    settings: dict[str, Any] = {"method": method}
    settings["report"] = _report(table, method)
    settings["compiled"] = _bool(table.get("compiled", True), "recursive.compiled")
    if method in ("ekf", "ukf", "ukf_aug"):
        settings.update(_filter_settings(table, method))
    if method == "efrls":
        settings.update(_efrls_settings(table))
    if method == "ftr":
        settings.update(_ftr_settings(table))
    return settings


def _ftr_delays(table: Any, inputs: Sequence[str]) -> dict[str, float]:
    """``input_delays_s = {channel = τ}``: a fixed delay ≥ 0 (s) per named input channel."""
    if not isinstance(table, Mapping):
        raise CaseError(
            f"recursive.input_delays_s: expected a table input channel = delay (s), got {table!r}"
        )
    delays = {}
    for channel, value in table.items():
        if channel not in inputs:
            raise CaseError(
                f"recursive.input_delays_s.{channel}: not one of recursive.inputs {list(inputs)}"
            )
        tau = _number(value, f"recursive.input_delays_s.{channel}")
        if tau < 0:
            raise CaseError(
                f"recursive.input_delays_s.{channel}: expected a delay >= 0 s (the FTR cannot "
                f"read inputs not yet fed), got {tau}"
            )
        delays[channel] = tau
    return delays


def _record(case: Case, data_dir: Path) -> tuple[list, np.ndarray, float]:
    """(maneuvers, t as one continuous record, dt)."""
    maneuvers = load_maneuvers(case, data_dir)
    dts = [m.dt for m in maneuvers]
    dt = float(dts[0])
    if not (np.isfinite(dt) and dt > 0):
        raise CaseError(f"data: expected a positive sample interval, got {dt} s")
    for m, value in zip(maneuvers, dts, strict=True):
        if abs(value - dt) > 1e-6 * dt:
            raise CaseError(
                f"data: the files form one record and need one sample interval; "
                f"'{maneuvers[0].name}' has dt = {dt} s, '{m.name}' has {value} s"
            )
    n = sum(m.n_samples for m in maneuvers)
    # t_k = (k − 1)·dt, k = 1..N, over the joined record (no restart at a junction)
    return maneuvers, dt * np.arange(n), dt


def _columns(maneuvers, names: Sequence[str], key: str) -> np.ndarray:
    """The channels ``names`` of all maneuvers joined into one (N × len(names)) array."""
    blocks = []
    for m in maneuvers:
        try:
            blocks.append(np.column_stack([m.channel(n) for n in names]))
        except KeyError:
            channels = [*m.input_names, *m.output_names]
            missing = [n for n in names if n not in channels]
            raise CaseError(
                f"{key}: channel(s) {missing} not in the data; the case defines {channels}"
            ) from None
    values = np.vstack(blocks) if names else np.empty((sum(m.n_samples for m in maneuvers), 0))
    if not np.all(np.isfinite(values)):
        raise CaseError(f"{key}: the channels {list(names)} hold non-finite samples")
    return values


def _parameter_correlation(estimator) -> np.ndarray | None:
    """Correlation of the parameters in the filter's last covariance P (its parameter
    block, after the n_x model states); None for an estimator without one, or for the
    EFRLS, whose P is an RLS matrix, not a covariance."""
    P = getattr(estimator, "P", None)
    augmented = getattr(estimator, "augmented", None)
    if P is None or augmented is None or getattr(estimator, "method", "") == "efrls":
        return None
    block = np.asarray(P, dtype=float)[augmented.n_x :, augmented.n_x :]
    # ρ_ij = P_ij / √(P_ii P_jj)
    scale = np.sqrt(np.where(np.diag(block) > 0, np.diag(block), np.nan))
    return block / np.outer(scale, scale)


def _meta(case: Case, maneuvers, description: str, outputs, r0) -> dict[str, Any]:
    units = maneuvers[0].units
    path = Path(case.path) if case.path is not None else None
    return {
        "title": case.title,
        "file": str(case.path),
        # SHA-256 of the case file's bytes as run (the report's provenance)
        "sha256": hashlib.sha256(path.read_bytes()).hexdigest()
        if path is not None and path.is_file()
        else "",
        "model": description,
        "outputs": list(outputs),
        "output_units": [units.get(n, "") for n in outputs],
        "R0": list(r0),
        "maneuvers": [maneuver_entry(m) for m in maneuvers],
    }


def _filter(settings: Mapping[str, Any], augmented):
    from flightid.recursive import (
        AugmentedUnscentedKalmanFilter,
        ExtendedForgettingRLS,
        ExtendedKalmanFilter,
        UnscentedKalmanFilter,
    )

    method = settings["method"]
    try:
        if method == "ekf":
            return ExtendedKalmanFilter(
                augmented,
                settings["p0"],
                settings["q_states"],
                settings["r0"],
                settings["jacobian_step"],
            )
        if method == "ukf":
            return UnscentedKalmanFilter(
                augmented, settings["p0"], settings["q_states"], settings["r0"]
            )
        if method == "ukf_aug":
            return AugmentedUnscentedKalmanFilter(
                augmented, settings["p0"], settings["q_states"], settings["r0"]
            )
        return ExtendedForgettingRLS(
            augmented, settings["p0"], settings["forgetting"], settings["jacobian_step"]
        )
    except InputError as exc:
        # p0 / q_states / r0 / jacobian_step of the wrong length: name the case key
        raise CaseError(f"recursive.{exc}") from None


@dataclass(frozen=True)
class RecursivePreparation:
    """Everything a recursive run checks before it feeds the first sample (``validate``
    stops here): the settings, the joined record, the estimator, the input and measured
    channels."""

    settings: dict[str, Any]
    maneuvers: list
    time: np.ndarray
    dt: float
    estimator: Any
    inputs: np.ndarray
    measured: np.ndarray
    units: list[str] | None
    initial: list[float] | None
    description: str
    outputs: list[str]
    r0: list[float]


def prepare_recursive_case(
    case: Case, data_dir: str | Path | None = None, *, compile_model: bool | None = None
) -> RecursivePreparation:
    """Read and check everything a recursive run needs before feeding samples: the
    ``[recursive]`` table, the record (one sample interval), the channels, the model and the
    filter's settings against it, or for the FTR the frequencies against the Nyquist
    frequency and the update interval against the record. ``compile_model`` False builds
    the filter's model loops in plain Python (same checks, no numba compilation; None: the
    table's ``compiled``). Every failure is a ``CaseError`` naming the key."""
    settings = recursive_settings(case.recursive)
    directory = resolve_data_dir(case, data_dir)
    if not directory.is_dir():
        raise CaseError(
            f"data.data_dir: the data directory {directory} does not exist (set data.data_dir, "
            "FLIGHTID_DATA or --data-dir)"
        )
    maneuvers, t, dt = _record(case, directory)
    if settings["method"] == "ftr":
        return _prepare_ftr(settings, maneuvers, t, dt)
    compiled = settings["compiled"] if compile_model is None else bool(compile_model)
    return _prepare_filter(case, directory, settings, maneuvers, t, dt, compiled)


def _prepare_ftr(settings, maneuvers, t: np.ndarray, dt: float) -> RecursivePreparation:
    from flightid.recursive import FourierTransformRegression
    from flightid.recursive.ftr import frequency_grid_hz

    states, inputs = settings["states"], settings["inputs"]
    z = _columns(maneuvers, states, "recursive.states")
    u = _columns(maneuvers, inputs, "recursive.inputs")
    update_every = int(round(settings["update_every_s"] / dt))
    if update_every < 1 or abs(update_every * dt - settings["update_every_s"]) > 1e-6:
        raise CaseError(
            f"recursive.update_every_s: expected a whole number of samples of "
            f"{dt} s, got {settings['update_every_s']} s"
        )
    grid = settings["frequencies_hz"]
    nyquist = 0.5 / dt
    try:
        freq = frequency_grid_hz(grid["start"], grid["stop"], grid["step"])
    except InputError as exc:
        raise CaseError(f"recursive.{exc}") from None
    if freq.max() >= nyquist:
        raise CaseError(
            f"recursive.frequencies_hz.stop: the highest frequency {freq.max():.4g} Hz is at or "
            f"above the Nyquist frequency {nyquist:.4g} Hz of the record (dt = {dt} s)"
        )
    try:
        estimator = FourierTransformRegression(
            len(states),
            len(inputs),
            freq,
            update_every,
            settings.get("parameter_names"),
            settings["offsets"],
            settings["n_mean"],
            [settings["input_delays_s"].get(name, 0.0) for name in inputs],
        )
    except InputError as exc:
        raise CaseError(f"recursive.{exc}") from None
    if t.size < max(update_every, settings["n_mean"]):
        raise CaseError(
            f"recursive.update_every_s: the record has {t.size} samples, fewer than one "
            f"update interval ({update_every} samples) or n_mean ({settings['n_mean']})"
        )
    return RecursivePreparation(
        settings=settings,
        maneuvers=maneuvers,
        time=t,
        dt=dt,
        estimator=estimator,
        inputs=u,
        measured=z,
        units=None,
        initial=None,
        description=f"FTR: states {states}, inputs {inputs} (measured)",
        outputs=list(states),
        r0=[],
    )


def _prepare_filter(
    case: Case, directory: Path, settings, maneuvers, t: np.ndarray, dt: float, compiled: bool
) -> RecursivePreparation:
    from flightid.recursive import AugmentedModel

    method = settings["method"]
    if not case.model:
        raise CaseError(f"model: missing; method {method!r} estimates a model's parameters")
    base, description = base_model(case, directory)
    model, maneuvers = build_model(case, maneuvers, base=base)
    if any(isinstance(e, str) for e in model.x0_spec(0)):
        raise CaseError(
            "initial_state: estimated initial states are not available in recursive "
            "estimation (give numbers or 'measured')"
        )
    x0 = model.initial_state(maneuver=0)
    try:
        augmented = AugmentedModel(model, x0, compiled=compiled)
    except InputError as exc:
        raise CaseError(f"model: {exc}") from None
    if augmented.n_free == 0:
        raise CaseError("parameters: no free parameter to estimate")
    estimator = _filter(settings, augmented)
    return RecursivePreparation(
        settings=settings,
        maneuvers=maneuvers,
        time=t,
        dt=dt,
        estimator=estimator,
        inputs=_columns(maneuvers, model.inputs, "data.inputs"),
        measured=_columns(maneuvers, model.outputs, "data.outputs"),
        units=augmented.free_units,
        initial=augmented.x_a0[augmented.n_x :].tolist(),
        description=description,
        outputs=list(model.outputs),
        r0=np.diag(estimator.R0).tolist() if hasattr(estimator, "R0") else [],
    )


def run_recursive_case(
    case: Case,
    data_dir: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
):
    """Run the case's recursive estimation; returns a ``RecursiveResult``.

    Raises ``CaseError`` for a wrong ``[recursive]`` key or data
    (``prepare_recursive_case``), ``RecursiveDivergenceError`` when the filter diverges.
    """
    from flightid.recursive import RecursiveEstimator

    prepared = prepare_recursive_case(case, data_dir)
    settings, estimator = prepared.settings, prepared.estimator
    method, t, dt = settings["method"], prepared.time, prepared.dt
    say = progress or (lambda message: None)
    say(f"{method}: {t.size} samples (dt = {dt} s), {len(estimator.parameter_names)} parameters")
    online = RecursiveEstimator(estimator)
    start = _time.perf_counter()
    online.feed_block(t, prepared.inputs, prepared.measured)
    wall = _time.perf_counter() - start
    meta = _meta(case, prepared.maneuvers, prepared.description, prepared.outputs, prepared.r0)
    innovations = np.asarray(estimator.innovations)
    if innovations.size:
        # rms of the innovations ν_k = z_k − ỹ_k per output
        meta["innovation_rms"] = np.sqrt(np.mean(innovations**2, axis=0)).tolist()
        # the innovations themselves, one per corrected sample (the last ones of the run),
        # for the report's innovation analysis
        meta["innovations"] = innovations
        meta["innovation_time_s"] = np.asarray(t, dtype=float)[-innovations.shape[0] :]
    correlation = _parameter_correlation(estimator)
    if correlation is not None:
        meta["parameter_correlation"] = correlation
    result = online.result(
        settings["report"],
        units=prepared.units,
        initial=prepared.initial,
        settings={k: v for k, v in settings.items() if k != "compiled"},
        meta=meta,
    )
    say(f"{method}: done in {wall:.2f} s")
    return result
