"""Stepwise-regression case files (TOML) and running them.

A case names a data file, the signals taken from it and, per coefficient, the candidate terms:

    [data]
    file = "sidpac_twin_otter/totter_lon_020213f1_018.mat"   # relative to the data directory
    data_dir = "../../../shared/data"                           # relative to this case file
    format = "sidpac"                                          # fdata matrix, 1-based columns

    [signals]                      # name = column, or {column = k, unit = "deg"}
    alpha = { column = 4, unit = "deg" }                       # deg → rad
    Cm = 65

    [stepwise]                     # options of flightid.regression.stepwise (all optional)
    f_enter = 4.0
    f_remove = 4.0
    sigma2_max = "response"        # "response", "full" or a number
    select = "pse"                 # "pse" or "final"
    forced = ["1"]

    [coefficients.Cm]
    response = "Cm"                # default: the table's name
    candidates = ["alpha", "qhat", "de", "alpha^2", "alpha*qhat", "alpha*de"]
    # any [stepwise] option may be repeated here to override it for this coefficient

The data directory is, in order: the ``data_dir`` argument (CLI ``--data-dir``), the
environment variable ``FLIGHTID_DATA``, ``[data].data_dir`` relative to the case file, and
finally ``../../../shared/data`` relative to the case file (the repository's
``../shared/data`` for a case in ``examples/cases``). Errors name the offending key.
"""

from __future__ import annotations

import math
import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from flightid.errors import InputError
from flightid.model.terms import TermError, parse_term
from flightid.regression import _sidpac
from flightid.regression.stepwise import StepwiseResult, stepwise

__all__ = ["StepwiseCase", "CaseError", "load_case", "run_case", "resolve_data_dir"]

_UNITS = {"rad": 1.0, "deg": math.pi / 180.0, "": 1.0}
_STEPWISE_KEYS = {"f_enter", "f_remove", "sigma2_max", "select", "forced", "max_steps"}


class CaseError(InputError):
    """A malformed case file; the message names the key."""


@dataclass(frozen=True)
class SignalSpec:
    name: str
    column: int
    scale: float


@dataclass(frozen=True)
class CoefficientSpec:
    name: str
    response: str
    candidates: tuple[str, ...]
    options: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class StepwiseCase:
    """A parsed case file."""

    path: Path
    data_file: str
    data_dir: str | None
    format: str
    signals: tuple[SignalSpec, ...]
    options: Mapping[str, Any]
    coefficients: tuple[CoefficientSpec, ...]


def _table(raw: Mapping, key: str, required: bool = True) -> Mapping:
    if key not in raw:
        if required:
            raise CaseError(f"case file: missing table [{key}]")
        return {}
    value = raw[key]
    if not isinstance(value, Mapping):
        raise CaseError(f"{key}: expected a table, got {type(value).__name__}")
    return value


def _options(table: Mapping, where: str) -> dict[str, Any]:
    options: dict[str, Any] = {}
    for key, value in table.items():
        if key not in _STEPWISE_KEYS:
            continue
        if key in ("f_enter", "f_remove"):
            if not isinstance(value, (int, float)) or isinstance(value, bool) or value < 0:
                raise CaseError(f"{where}.{key}: expected a non-negative number, got {value!r}")
            value = float(value)
        elif key == "sigma2_max":
            if isinstance(value, str):
                if value not in ("response", "full"):
                    raise CaseError(
                        f"{where}.sigma2_max: expected 'response', 'full' or a number, "
                        f"got {value!r}"
                    )
            elif not isinstance(value, (int, float)) or isinstance(value, bool) or value < 0:
                raise CaseError(
                    f"{where}.sigma2_max: expected a non-negative number, got {value!r}"
                )
        elif key == "select":
            if value not in ("pse", "final"):
                raise CaseError(f"{where}.select: expected 'pse' or 'final', got {value!r}")
        elif key == "forced":
            if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                raise CaseError(f"{where}.forced: expected a list of terms, got {value!r}")
            value = tuple(value)
        elif key == "max_steps":
            if not isinstance(value, int) or value < 1:
                raise CaseError(f"{where}.max_steps: expected a positive integer, got {value!r}")
        options[key] = value
    return options


def load_case(path: str | Path) -> StepwiseCase:
    """Parse and check a stepwise case file (see the module docstring)."""
    path = Path(path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CaseError(f"case file: {str(path)!r} does not exist") from None
    except tomllib.TOMLDecodeError as exc:
        raise CaseError(f"case file {str(path)!r}: invalid TOML: {exc}") from None
    data = _table(raw, "data")
    if not isinstance(data.get("file"), str):
        raise CaseError(f"data.file: expected a file name (string), got {data.get('file')!r}")
    fmt = data.get("format", "sidpac")
    if fmt != "sidpac":
        raise CaseError(f"data.format: expected 'sidpac', got {fmt!r}")
    data_dir = data.get("data_dir")
    if data_dir is not None and not isinstance(data_dir, str):
        raise CaseError(f"data.data_dir: expected a path (string), got {data_dir!r}")

    signals = []
    for name, spec in _table(raw, "signals").items():
        where = f"signals.{name}"
        if not name.isidentifier():
            raise CaseError(f"{where}: signal names must be identifiers")
        if isinstance(spec, int) and not isinstance(spec, bool):
            spec = {"column": spec}
        if not isinstance(spec, Mapping):
            raise CaseError(f"{where}: expected a column number or {{column, unit}}, got {spec!r}")
        unknown = sorted(set(spec) - {"column", "unit", "scale"})
        if unknown:
            raise CaseError(f"{where}: unknown keys {unknown}; expected column, unit, scale")
        col = spec.get("column")
        if not isinstance(col, int) or isinstance(col, bool) or col < 1:
            raise CaseError(f"{where}.column: expected a 1-based column number, got {col!r}")
        unit = spec.get("unit", "")
        if unit not in _UNITS:
            raise CaseError(f"{where}.unit: expected one of {sorted(_UNITS)}, got {unit!r}")
        scale = spec.get("scale", 1.0)
        if not isinstance(scale, (int, float)) or isinstance(scale, bool):
            raise CaseError(f"{where}.scale: expected a number, got {scale!r}")
        signals.append(SignalSpec(name, col, float(scale) * _UNITS[unit]))

    options = _options(_table(raw, "stepwise", required=False), "stepwise")
    coefficients = []
    known = {s.name for s in signals}
    for name, table in _table(raw, "coefficients").items():
        where = f"coefficients.{name}"
        if not isinstance(table, Mapping):
            raise CaseError(f"{where}: expected a table")
        response = table.get("response", name)
        if response not in known:
            raise CaseError(
                f"{where}.response: {response!r} is not a signal; signals: {sorted(known)}"
            )
        candidates = table.get("candidates")
        if (
            not isinstance(candidates, list)
            or not candidates
            or not all(isinstance(c, str) for c in candidates)
        ):
            raise CaseError(f"{where}.candidates: expected a non-empty list of terms")
        for c in candidates:
            try:
                term = parse_term(c)
            except TermError as exc:
                raise CaseError(f"{where}.candidates: {exc}") from None
            missing = sorted(set(term.signals) - known)
            if missing:
                raise CaseError(
                    f"{where}.candidates: term {c!r} uses unknown signals {missing}; "
                    f"signals: {sorted(known)}"
                )
        unknown = sorted(set(table) - _STEPWISE_KEYS - {"response", "candidates"})
        if unknown:
            raise CaseError(f"{where}: unknown keys {unknown}")
        coefficients.append(
            CoefficientSpec(name, response, tuple(candidates), _options(table, where))
        )
    if not coefficients:
        raise CaseError("coefficients: expected at least one [coefficients.NAME] table")
    return StepwiseCase(
        path, data["file"], data_dir, fmt, tuple(signals), options, tuple(coefficients)
    )


def resolve_data_dir(case: StepwiseCase, data_dir: str | Path | None = None) -> Path:
    """The data directory (see the module docstring for the order)."""
    if data_dir is not None:
        return Path(data_dir)
    env = os.environ.get("FLIGHTID_DATA")
    if env:
        return Path(env)
    relative = case.data_dir if case.data_dir is not None else "../../../shared/data"
    return (case.path.parent / relative).resolve()


def case_signals(case: StepwiseCase, data_dir: str | Path | None = None) -> dict[str, np.ndarray]:
    """Read the case's data file and return its named signals (converted units)."""
    path = resolve_data_dir(case, data_dir) / case.data_file
    fdata, _ = _sidpac.read_fdata(path)
    return {
        s.name: s.scale * _sidpac.column(fdata, s.column, f"signals.{s.name}.column")
        for s in case.signals
    }


def run_case(
    case: StepwiseCase | str | Path, data_dir: str | Path | None = None
) -> dict[str, StepwiseResult]:
    """Run stepwise regression for every coefficient of the case."""
    if not isinstance(case, StepwiseCase):
        case = load_case(case)
    signals = case_signals(case, data_dir)
    results = {}
    for coefficient in case.coefficients:
        options = {**case.options, **coefficient.options}
        results[coefficient.name] = stepwise(
            signals[coefficient.response],
            coefficient.candidates,
            signals,
            response=coefficient.name,
            **options,
        )
    return results
