"""Maneuvers from a ``flightid batch`` results folder, each with its flight condition.

``flightid batch`` writes one folder per case, ``<batch>/cases/<name>/``, holding the
expanded case text (``case.toml``) and the case's record (``batch.json``: its name, its
flight-condition columns ``conditions``, the path the case had when the batch ran it
``case_path`` and its ``status``). ``read_batch_maneuvers`` re-reads every case that did not
fail from its text, with the record's ``case_path`` as its path (so its relative data paths
resolve as when the batch ran it), loads its estimation maneuvers with its own ``[data]``
(files, channels, pre-processing) and pairs each maneuver with the case's conditions;
``batch_stage_data`` turns them into what a global-model stage with ``batch = ...`` is
fitted to (``flightid.cases.globalmodel_case.StageData``).

The records are read here as JSON: this package comes before ``flightid.batch`` in the layer
order and does not import it; ``RECORD_FILE`` and ``RECORD_VERSION`` are the record's file
name and format version that ``flightid.batch.task`` writes.
"""

from __future__ import annotations

import json
import math
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from flightid.cases.checks import CaseError
from flightid.cases.globalmodel_case import StageData, check_stage_channels, maneuver_signals
from flightid.data.flightdata import FlightData
from flightid.errors import FlightIdError

__all__ = [
    "CASE_TEXT_FILE",
    "RECORD_FILE",
    "RECORD_VERSION",
    "BatchManeuver",
    "batch_stage_data",
    "read_batch_maneuvers",
    "resolve_batch_folder",
]

# the record of one case (written by flightid.batch.task: RECORD_FILE, RECORD_VERSION)
RECORD_FILE = "batch.json"
RECORD_VERSION = 2
# the expanded case text beside the record
CASE_TEXT_FILE = "case.toml"


@dataclass(frozen=True, eq=False)
class BatchManeuver:
    """One estimation maneuver of a batch case.

    Attributes:
        data: the maneuver, loaded and pre-processed by its case's ``[data]``.
        case: the batch case's name.
        conditions: the case's numeric flight-condition columns (constant over the maneuver).
        text_conditions: the case's non-numeric columns (a configuration label, ...).
    """

    data: FlightData
    case: str
    conditions: Mapping[str, float] = field(default_factory=dict)
    text_conditions: Mapping[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        """``case/maneuver``: unique over the batch."""
        return f"{self.case}/{self.data.name}"


def resolve_batch_folder(value: str, case_directory: Path) -> Path:
    """The batch folder: ``value`` relative to the case file's folder, or absolute."""
    path = Path(value).expanduser()
    return path if path.is_absolute() else case_directory / path


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _split_conditions(conditions: Any) -> tuple[dict[str, float], dict[str, Any]]:
    """(numeric columns, other columns) of a record's ``conditions``."""
    numbers, texts = {}, {}
    for name, value in (conditions if isinstance(conditions, Mapping) else {}).items():
        if _is_number(value) and math.isfinite(value):
            numbers[str(name)] = float(value)
        else:
            texts[str(name)] = value
    return numbers, texts


def _read_record(folder: Path) -> tuple[dict[str, Any] | None, str]:
    """(the record, "") or (None, why it cannot be used)."""
    try:
        record = json.loads((folder / RECORD_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        return None, f"record {RECORD_FILE} unreadable ({type(exc).__name__})"
    if not isinstance(record, dict) or record.get("version") != RECORD_VERSION:
        found = record.get("version") if isinstance(record, dict) else type(record).__name__
        return None, f"record {RECORD_FILE}: expected version {RECORD_VERSION}, got {found!r}"
    if record.get("status") == "failed":
        return None, f"failed in the batch: {record.get('error', 'no message')}"
    return record, ""


def _case_maneuvers(folder: Path, record: Mapping[str, Any], data_dir) -> list[FlightData]:
    """The case's estimation maneuvers, read from its text with ``case_path`` as its path."""
    from flightid.cases.build import load_maneuvers, resolve_data_dir
    from flightid.cases.spec import parse_case

    text = (folder / CASE_TEXT_FILE).read_text(encoding="utf-8")
    case_path = Path(str(record.get("case_path") or folder / CASE_TEXT_FILE))
    case = parse_case(tomllib.loads(text), case_path)
    if not case.maneuvers:
        raise CaseError("the case has no data files of its own")
    return load_maneuvers(case, resolve_data_dir(case, data_dir))


def read_batch_maneuvers(
    folder: Path,
    data_dir: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
) -> tuple[list[BatchManeuver], list[dict[str, str]]]:
    """The maneuvers of every usable case of a batch folder, and the skipped cases.

    Args:
        folder: the batch's output folder (``flightid batch ... --out FOLDER``).
        data_dir: the ``--data-dir`` override, applied to every case as when it ran.
        progress: receives one line per skipped case.

    Returns:
        (maneuvers in case-name order, ``[{"case", "reason"}]`` of the cases skipped: failed
        in the batch, record unreadable, case text or data missing or unreadable).

    Raises:
        CaseError: the folder has no ``cases/`` folder, or no case is usable.
    """
    say = progress or (lambda message: None)
    cases = folder / "cases"
    if not cases.is_dir():
        raise CaseError(
            f"batch folder {folder}: no cases/ folder (expected the --out folder of "
            "`flightid batch`)"
        )
    maneuvers: list[BatchManeuver] = []
    skipped: list[dict[str, str]] = []
    for case_folder in sorted(p for p in cases.iterdir() if p.is_dir()):
        record, reason = _read_record(case_folder)
        name = str(record.get("case", case_folder.name)) if record else case_folder.name
        if record is not None:
            try:
                loaded = _case_maneuvers(case_folder, record, data_dir)
            except (FlightIdError, OSError, tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
                loaded, reason = [], f"{type(exc).__name__}: {exc}"
        if reason:
            skipped.append({"case": name, "reason": reason})
            say(f"batch case {name} skipped: {reason}")
            continue
        numbers, texts = _split_conditions(record.get("conditions"))
        maneuvers += [BatchManeuver(m, name, numbers, texts) for m in loaded]
    if not maneuvers:
        raise CaseError(
            f"batch folder {folder}: no usable case ({len(skipped)} skipped: "
            f"{[s['case'] for s in skipped]})"
        )
    return maneuvers, skipped


def _batch_conditions(stage, found: Sequence[BatchManeuver]) -> list[dict[str, float]]:
    """Per batch maneuver: the record's numeric conditions, then the stage's table (by case
    name, then by ``case/maneuver``)."""
    where = f"stages[{stage.index}].conditions"
    table = stage.settings["conditions"]
    keys = {b.case for b in found} | {b.name for b in found}
    unknown = sorted(set(table) - keys)
    if unknown:
        raise CaseError(
            f"{where}: {unknown} are neither batch cases nor their maneuvers (case/maneuver); "
            f"maneuvers: {[b.name for b in found]}"
        )
    variables = set(stage.settings["variables"])
    merged = []
    for b in found:
        entry = {**b.conditions, **table.get(b.case, {}), **table.get(b.name, {})}
        text = sorted((set(b.text_conditions) & variables) - set(entry))
        if text:
            raise CaseError(
                f"stages[{stage.index}].variables: the batch condition(s) {text} of case "
                f"{b.case!r} are not numbers ({[b.text_conditions[t] for t in text]!r})"
            )
        merged.append(entry)
    return merged


def batch_stage_data(
    stage,
    case_directory: Path,
    data_dir: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
) -> StageData:
    """The data of a global-model stage with ``batch``: the maneuvers of the batch folder
    (relative to ``case_directory``) with their conditions (the records', then the stage's)
    and their sources; the skipped cases. ``data_dir`` is the ``--data-dir`` override,
    applied to every batch case."""
    from flightid.globalmodel import SourceInfo

    say = progress or (lambda message: None)

    folder = resolve_batch_folder(stage.settings["batch"], case_directory)
    if not folder.is_dir():
        raise CaseError(f"stages[{stage.index}].batch: the batch folder {folder} does not exist")
    found, skipped = read_batch_maneuvers(folder, data_dir, say)
    conditions = _batch_conditions(stage, found)
    labelled = [(b.data, b.name, c) for b, c in zip(found, conditions, strict=True)]
    signals, index, dt = maneuver_signals(labelled, f"stages[{stage.index}].conditions")
    check_stage_channels(stage, signals)
    sources = tuple(
        SourceInfo(b.data.name, b.case, c, b.data.n_samples)
        for b, c in zip(found, conditions, strict=True)
    )
    cases = len({b.case for b in found})
    say(f"global model: {len(found)} maneuvers of {cases} batch cases ({len(skipped)} skipped)")
    units = {k: v for k, v in found[0].data.units.items() if k in signals and v}
    return StageData(signals, index, dt, units, sources, tuple(skipped))
