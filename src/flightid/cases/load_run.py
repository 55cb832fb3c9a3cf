"""A result folder read back: the model with the estimated values and their covariance, and
the maneuvers, without estimating again.

``flightid run CASE --out DIR`` writes DIR/results.json, which names the case file and the
SHA-256 of its bytes when the run started, the estimated values and the covariance of the
free estimates. ``load_run(DIR)`` reads the case file again, checks that its bytes are those
that ran, builds the model and loads the data as the run did (``prepare_case``), and sets the
parameters to the recorded estimates. A missing case file, a case file that changed since,
or a folder that is not a flightid run is refused with a named error: a model rebuilt from a
different case would not be the model that was estimated.

Read back: output-error and filter-error runs of a case (``flightid run`` without regression
stages, ``[recursive]`` or ``[frequency_domain]``); the others are refused by name.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flightid.cases.spec import Case, CaseError
from flightid.data.flightdata import FlightData
from flightid.errors import InputError
from flightid.model.statespace import StateSpaceModel

__all__ = ["CaseChangedError", "LoadedRun", "RunFolderError", "load_run"]

RESULTS_FILE = "results.json"


class RunFolderError(InputError):
    """A folder that is not a flightid run folder this version can read back."""


class CaseChangedError(RunFolderError):
    """The case file of a run is missing, or its bytes differ from those that ran."""


@dataclass(frozen=True, eq=False)
class LoadedRun:
    """A run read back from its result folder (``load_run``).

    Attributes:
        directory: the result folder.
        case: the case file, read again (its SHA-256 checked).
        model: the model as estimated, its parameters at the recorded estimates.
        maneuvers: the estimation maneuvers, loaded as the run loaded them.
        free_names: the free parameters, the order of the covariance's rows.
        covariance: the covariance behind the default σ (n_f × n_f).
        covariance_cr: the Cramér–Rao covariance M⁻¹ (n_f × n_f).
        method, input_interpolation: the integration the run used.
        output_units: ``{output: unit}`` ("" where unknown).
        entry: the results.json entry as read.
    """

    directory: Path
    case: Case
    model: StateSpaceModel
    maneuvers: tuple[FlightData, ...]
    free_names: tuple[str, ...]
    covariance: np.ndarray
    covariance_cr: np.ndarray
    method: str
    input_interpolation: str
    output_units: dict
    entry: dict

    @property
    def values(self) -> dict[str, float]:
        """The estimated value of every parameter, by name."""
        return {p.name: float(p.value) for p in self.model.parameters}

    @property
    def std(self) -> dict[str, float]:
        """The default σ of every free parameter, by name (√ of the covariance's diagonal)."""
        sigma = np.sqrt(np.maximum(np.diag(self.covariance), 0.0))
        return dict(zip(self.free_names, (float(s) for s in sigma), strict=True))

    @property
    def std_cr(self) -> dict[str, float]:
        """The Cramér–Rao σ of every free parameter, by name."""
        sigma = np.sqrt(np.maximum(np.diag(self.covariance_cr), 0.0))
        return dict(zip(self.free_names, (float(s) for s in sigma), strict=True))

    def _covariance_for(self, std: str) -> np.ndarray:
        if std not in ("default", "cr"):
            raise InputError(f"std: expected 'default' or 'cr', got {std!r}")
        return self.covariance if std == "default" else self.covariance_cr

    def predict(self, data, x0=None, *, bands: bool = False, std: str = "default"):
        """The model on other data, as ``Estimate.predict``: one ``Prediction`` for a
        ``FlightData``, a tuple for a list."""
        from flightid.simulation.prediction import predict_maneuvers

        predictions = predict_maneuvers(
            self.model,
            data,
            x0,
            method=self.method,
            input_interpolation=self.input_interpolation,
            covariance=self._covariance_for(std) if bands else None,
        )
        return predictions[0] if isinstance(data, FlightData) else tuple(predictions)

    def simulate(self, inputs, x0=None) -> np.ndarray:
        """Outputs (N_total, n_o) driven by the inputs of ``inputs``, as ``Estimate.simulate``."""
        from flightid.model.binding import as_data_list
        from flightid.simulation import simulate
        from flightid.simulation.prediction import prediction_model

        maneuvers = as_data_list(inputs)
        model = prediction_model(self.model, maneuvers, x0)
        return simulate(
            model, maneuvers, method=self.method, input_interpolation=self.input_interpolation
        )

    def linearize(self, at=None, *, std: str = "default"):
        """The model linearized with the covariance of A, B, C, D (``LinearModel``).

        Args:
            at: None — the initial state of the first estimation maneuver (as ``predict``
                starts it) and the mean of each input over it; a ``FlightData`` — the same
                for that maneuver; or ``(x, u)`` — values per state and per input.
            std: which covariance: ``"default"`` or ``"cr"``.
        """
        from flightid.model.linearization import LinearizationError, linearize
        from flightid.simulation.prediction import initial_states

        maneuver = self.maneuvers[0] if at is None else at
        units = dict(self.output_units)
        if isinstance(maneuver, FlightData):
            (x,) = initial_states(self.model, [maneuver], None)
            u = np.array([float(np.mean(maneuver.channel(n))) for n in self.model.inputs])
            units = {**units, **dict(maneuver.units)}
            which = "first estimation maneuver" if at is None else "maneuver"
            point = f"initial state and mean inputs of the {which} {maneuver.name or '(unnamed)'}"
        elif isinstance(at, (tuple, list)) and len(at) == 2:
            x, u = at
            point = "given"
        else:
            raise LinearizationError(
                f"at: expected None, a FlightData or (x, u), got {type(at).__name__}"
            )
        covariance, notes = self._covariance_for(std), ()
        if not np.all(np.isfinite(covariance)):
            covariance = None
            notes = ("no σ of the entries: the run's covariance has undetermined entries",)
        return linearize(
            self.model,
            x,
            u,
            covariance=covariance,
            units=units,
            operating_point=point,
            name=self.model.name,
            notes=notes,
        )


def _read_entry(directory: Path) -> dict:
    """The one results.json entry of an output-error run in ``directory``."""
    path = directory / RESULTS_FILE
    if not directory.is_dir():
        raise RunFolderError(f"run folder {directory}: expected a folder, found none")
    if not path.is_file():
        raise RunFolderError(
            f"run folder {directory}: expected a flightid run folder with {RESULTS_FILE} "
            "(written by flightid run --out), found none"
        )
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise RunFolderError(
            f"{path}: expected flightid results JSON, cannot read it ({exc})"
        ) from None
    results = document.get("results") if isinstance(document, dict) else None
    if not isinstance(results, list) or len(results) != 1 or not isinstance(results[0], dict):
        raise RunFolderError(
            f"{path}: expected a results document with one entry (flightid run), got "
            f"{type(results).__name__ if not isinstance(results, list) else len(results)}"
        )
    if "stages" in document:
        raise RunFolderError(
            f"{path}: a run with regression stages cannot be read back yet; run its "
            "output-error case on its own"
        )
    entry = results[0]
    estimator = entry.get("estimator")
    if estimator not in ("output_error", "filter_error"):
        raise RunFolderError(
            f"{path}: expected an output-error or filter-error run, got the estimator "
            f"{estimator!r} (recursive and frequency-domain runs cannot be read back yet)"
        )
    for key in ("case", "parameters", "covariance"):
        if key not in entry:
            raise RunFolderError(
                f"{path}: has no {key!r} (written by an older flightid); run the case again "
                "to write a folder that can be read back"
            )
    return entry


def _checked_case_file(entry: Mapping, path: Path) -> Path:
    """The case file that ran, its bytes checked against the recorded SHA-256."""
    recorded = entry["case"]
    case_file = Path(str(recorded.get("file", "")))
    digest = str(recorded.get("sha256", ""))
    if not digest:
        raise CaseChangedError(
            f"{path}: records no SHA-256 of the case file {case_file}; the case that ran "
            "cannot be told from another"
        )
    if not case_file.is_file():
        raise CaseChangedError(
            f"{path}: the case file {case_file} that ran is missing; expected it there with "
            f"SHA-256 {digest}"
        )
    found = hashlib.sha256(case_file.read_bytes()).hexdigest()
    if found != digest:
        raise CaseChangedError(
            f"{path}: the case file {case_file} changed since the run: SHA-256 {found} now, "
            f"{digest} when it ran; run the case again"
        )
    return case_file


def _matrix(value, names: Sequence[str], where: str) -> np.ndarray:
    n = len(names)
    try:
        matrix = np.array(
            [[np.nan if v is None else float(v) for v in row] for row in value], dtype=float
        )
    except (TypeError, ValueError):
        raise RunFolderError(f"{where}: expected an {n} x {n} matrix of numbers") from None
    if matrix.shape != (n, n):
        raise RunFolderError(f"{where}: expected an {n} x {n} matrix, got shape {matrix.shape}")
    return matrix


def _estimated_model(model: StateSpaceModel, entry: Mapping, path: Path) -> StateSpaceModel:
    """``model`` with the recorded estimates (the same parameter names, in the same order)."""
    recorded = [p.get("name") for p in entry["parameters"]]
    if recorded != list(model.parameters.names):
        raise RunFolderError(
            f"{path}: the recorded parameters {recorded} are not those of the model the case "
            f"builds {list(model.parameters.names)}"
        )
    values = np.array([float(p["value"]) for p in entry["parameters"]])
    return model.with_parameters(model.parameters.with_values(values))


def load_run(run_dir: str | Path, data_dir: str | Path | None = None) -> LoadedRun:
    """Read the result folder ``run_dir`` of ``flightid run`` back (module docstring).

    Args:
        run_dir: the result folder.
        data_dir: the data directory (default: the one the run recorded, else the case's).

    Raises:
        RunFolderError: not a flightid run folder, or one this version cannot read back.
        CaseChangedError: the case file is missing or changed since the run.
    """
    from flightid.cases.run import input_interpolation, prepare_case
    from flightid.cases.spec import load_case

    directory = Path(run_dir).expanduser()
    entry = _read_entry(directory)
    path = directory / RESULTS_FILE
    case_file = _checked_case_file(entry, path)
    case = load_case(case_file)
    if data_dir is None:
        recorded = entry["case"].get("data_dir")
        data_dir = recorded if recorded and Path(recorded).is_dir() else None
    try:
        prepared = prepare_case(case, data_dir)
    except CaseError as exc:
        raise RunFolderError(f"{path}: the case cannot be rebuilt: {exc}") from None
    model = _estimated_model(prepared.model, entry, path)
    covariance = entry["covariance"]
    free = tuple(covariance.get("parameters", ()))
    if list(free) != list(model.parameters.free_names):
        raise RunFolderError(
            f"{path}: covariance.parameters {list(free)} are not the free parameters "
            f"{model.parameters.free_names}"
        )
    units = entry.get("output_units") or [""] * len(entry.get("outputs", ()))
    return LoadedRun(
        directory=directory,
        case=case,
        model=model,
        maneuvers=prepared.maneuvers,
        free_names=free,
        covariance=_matrix(covariance["default"], free, f"{path}: covariance.default"),
        covariance_cr=_matrix(covariance["cramer_rao"], free, f"{path}: covariance.cramer_rao"),
        method=str(entry.get("integration", case.estimation.get("method", "rk4"))),
        input_interpolation=str(entry.get("input_interpolation", input_interpolation(case))),
        output_units=dict(zip(entry.get("outputs", ()), units, strict=False)),
        entry=entry,
    )
