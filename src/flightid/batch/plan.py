"""Planning a batch: the list of cases from case files and from case templates with a table.

A batch source is a TOML file. A plain case file (``flightid run`` reads it) is one case,
named by its file's stem. A file with a ``[batch]`` table is a *template with a table*::

    [batch]
    template = "case.toml"          # a case file with {{placeholders}} (relative to this file)
    table = "conditions.csv"        # one row per case: a CSV file with a header ...

    [[batch.cases]]                 # ... or the rows inline (instead of table)
    name = "fl100_m05"
    file = "fvsysid/fAttasElv1.mat"
    mach = 0.5

Each row fills the template's placeholders ``{{column}}`` (letters, digits, underscore) by
plain text substitution — no expression is evaluated — and names the case (column ``name``,
which becomes the case's stem and the folder ``cases/<name>/``). The row's other columns are
the case's *flight-condition columns*: they are copied into the results table (numbers where
the text is a number). The expanded text is read as a case file lying beside the template
(relative ``model.module`` and ``data.data_dir`` paths resolve as for the template itself).

Checks, each a ``BatchError`` naming the source and the row (1-based, as in the table):
a placeholder without a column, a row without a value for a placeholder the template uses,
a value with a quote, backslash or line break (it would change the TOML around it), a
missing or repeated name, and an expanded text that is not a valid case.
"""

from __future__ import annotations

import csv
import math
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from flightid.errors import InputError

__all__ = ["BatchCase", "BatchError", "PLACEHOLDER", "expand_template", "plan_cases"]

# {{ column }}: a placeholder of a template
PLACEHOLDER = re.compile(r"\{\{\s*([A-Za-z_][A-Za-z0-9_]*)\s*\}\}")
# a case name becomes a folder name and the `case` column
_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-]*$")
# characters that would change the TOML around a substituted value
_UNSAFE = ('"', "'", "\\", "\n", "\r")


class BatchError(InputError):
    """A batch source (case list, template, table) is wrong; the message names the file,
    the row and the column."""


@dataclass(frozen=True)
class BatchCase:
    """One case of a batch.

    Attributes:
        name: the case's stem (``case`` column, folder ``cases/<name>/``).
        text: the case file's text (after substitution for a template row).
        path: where the case is read as lying (the case file, or ``<template dir>/<name>.toml``
            for a template row: relative paths resolve from there).
        conditions: flight-condition columns of a template row (name → number or text).
        source: the file the case came from (a case file or a batch file), for messages.
    """

    name: str
    text: str
    path: Path
    conditions: Mapping[str, Any] = field(default_factory=dict)
    source: Path | None = None


def _read_text(path: Path, what: str) -> str:
    if not path.is_file():
        raise BatchError(f"{what}: {path} {'is not a file' if path.exists() else 'does not exist'}")
    try:
        return path.read_bytes().decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError:
        raise BatchError(f"{what}: {path} is not UTF-8 text") from None
    except OSError as exc:
        raise BatchError(f"{what}: {path} cannot be read ({exc.strerror or exc})") from None


# a decimal number as a table cell writes it: sign, digits, point, exponent (Python's int()
# and float() also take "1_000", "nan", "inf" and surrounding blanks)
_DECIMAL = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


def _number_or_text(text: str) -> Any:
    """A table cell as a number (int or float) where it is a finite decimal number, else the
    text as written ("1_000", "nan", "inf" stay text: the record must be valid JSON and
    nothing may be read as a number it does not say)."""
    if not _DECIMAL.fullmatch(text):
        return text
    try:
        return int(text)
    except ValueError:
        pass
    number = float(text)
    return number if math.isfinite(number) else text


def _read_table(path: Path, where: str) -> list[dict[str, str]]:
    text = _read_text(path, f"{where}: batch.table")
    reader = csv.DictReader(text.splitlines())
    if not reader.fieldnames:
        raise BatchError(f"{where}: batch.table {path} has no header row")
    header = [name.strip() for name in reader.fieldnames]
    if len(set(header)) != len(header):
        raise BatchError(f"{where}: batch.table {path}: repeated column in the header {header}")
    rows = []
    for i, raw in enumerate(reader, start=1):
        if None in raw:
            raise BatchError(
                f"{where}: batch.table {path}, row {i}: more cells than header columns {header}"
            )
        rows.append({k.strip(): ("" if v is None else v.strip()) for k, v in raw.items()})
    return rows


def _inline_rows(rows: Any, where: str) -> list[dict[str, str]]:
    if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
        raise BatchError(f"{where}: batch.cases: expected [[batch.cases]] tables")
    out = []
    for i, row in enumerate(rows, start=1):
        cells = {}
        for key, value in row.items():
            if isinstance(value, bool) or not isinstance(value, (str, int, float)):
                raise BatchError(
                    f"{where}: batch.cases row {i}, column {key!r}: expected a string or a "
                    f"number, got {value!r}"
                )
            cells[key] = value if isinstance(value, str) else repr(value)
        out.append(cells)
    return out


def expand_template(path: str | Path) -> list[BatchCase]:
    """The cases of a batch file (``[batch] template`` + ``table`` or ``[[batch.cases]]``).

    Args:
        path: the batch file (TOML).

    Raises:
        BatchError: a bad batch file, template, table or row (named in the message).
    """
    path = Path(path).resolve()
    where = f"batch file {path}"
    try:
        raw = tomllib.loads(_read_text(path, "batch file"))
    except tomllib.TOMLDecodeError as exc:
        raise BatchError(f"{where}: not valid TOML ({exc})") from None
    section = raw.get("batch")
    if not isinstance(section, dict):
        raise BatchError(f"{where}: expected a [batch] table")
    unknown = sorted(set(section) - {"template", "table", "cases"})
    if unknown:
        raise BatchError(f"{where}: unknown key(s) in [batch]: {unknown}")
    if not isinstance(section.get("template"), str):
        raise BatchError(f'{where}: batch.template: expected a file name, e.g. "case.toml"')
    template_path = (path.parent / section["template"]).resolve()
    template = _read_text(template_path, f"{where}: batch.template")
    if ("table" in section) == ("cases" in section):
        raise BatchError(f"{where}: give either batch.table (a CSV file) or [[batch.cases]]")
    if "table" in section:
        if not isinstance(section["table"], str):
            raise BatchError(f"{where}: batch.table: expected a CSV file name")
        rows = _read_table((path.parent / section["table"]).resolve(), where)
        label = "batch.table row"
    else:
        rows = _inline_rows(section["cases"], where)
        label = "batch.cases row"
    if not rows:
        raise BatchError(f"{where}: the table has no rows")
    used = list(dict.fromkeys(PLACEHOLDER.findall(template)))
    cases: list[BatchCase] = []
    seen: dict[str, int] = {}
    for i, row in enumerate(rows, start=1):
        at = f"{where}, {label} {i}"
        name = row.get("name", "")
        if not name:
            raise BatchError(f"{at}: no value in column 'name' (the case's name)")
        if not _NAME.match(name):
            raise BatchError(
                f"{at}: name {name!r}: expected letters, digits, '_', '-', '.' (a folder name)"
            )
        if name in seen:
            raise BatchError(f"{at}: name {name!r} repeats row {seen[name]}")
        seen[name] = i
        for column in used:
            if column not in row:
                raise BatchError(
                    f"{at}: the template {template_path.name} uses {{{{{column}}}}}, but the "
                    f"table has no column {column!r} (columns: {sorted(row)})"
                )
            if row[column] == "":
                raise BatchError(f"{at}: no value in column {column!r} (the template uses it)")
            if any(c in row[column] for c in _UNSAFE):
                raise BatchError(
                    f"{at}, column {column!r}: the value {row[column]!r} holds a quote, "
                    "backslash or line break; these are not substituted"
                )
        text = PLACEHOLDER.sub(lambda m, row=row: row[m.group(1)], template)
        case_path = template_path.parent / f"{name}.toml"
        try:
            tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise BatchError(f"{at}: the expanded template is not valid TOML ({exc})") from None
        conditions = {k: _number_or_text(v) for k, v in row.items() if k != "name"}
        cases.append(BatchCase(name, text, case_path, conditions, path))
    return cases


def is_batch_file(path: Path) -> bool:
    """True when ``path`` is a TOML file with a ``[batch]`` table (a template with a table)."""
    try:
        raw = tomllib.loads(_read_text(path, "case file"))
    except tomllib.TOMLDecodeError:
        return False  # a broken case file: its own run reports it
    return "batch" in raw


def plan_cases(sources: Sequence[str | Path]) -> list[BatchCase]:
    """The cases of a batch: each source a case file (one case, named by its stem) or a batch
    file (``expand_template``), in the order given.

    Raises:
        BatchError: a source cannot be read, or two cases have the same name.
    """
    if not sources:
        raise BatchError("batch: expected at least one case file")
    cases: list[BatchCase] = []
    for source in sources:
        path = Path(source).resolve()
        if is_batch_file(path):
            cases.extend(expand_template(path))
        else:
            text = _read_text(path, "case file")
            cases.append(BatchCase(path.stem, text, path, {}, path))
    seen: dict[str, Path | None] = {}
    for case in cases:
        if case.name in seen:
            raise BatchError(
                f"batch: two cases are named {case.name!r} ({seen[case.name]} and "
                f"{case.source}); each case's name (file stem) must be unique"
            )
        seen[case.name] = case.source
    return cases
