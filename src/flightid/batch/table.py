"""The results table of a batch: one row per case and parameter.

Columns (the contract other tools read; ``docs/batch.md``):

==============  ===========================================================================
case            the case's name (the case file's stem, or the template row's ``name``)
<conditions>    the flight-condition columns of a template row (numbers where they read as
                numbers), in the order of the table; empty for other cases
parameter       parameter name (empty in the one row of a failed case)
unit            parameter unit (as declared by the model; may be empty)
value           estimate, parameter units (empty: failed case, or not finite)
std             Cramér–Rao standard error σ, parameter units (free parameters; empty for a
                fixed one)
coloured_std    σ corrected for coloured residuals (free parameters), parameter units
free            true when the parameter was estimated
converged       true when the estimation converged
status          the estimation's status (converged, max_iterations, ...) or ``failed``
error           the named error's message of a failed case (else empty)
==============  ===========================================================================

``write_table`` writes ``estimates.csv`` (always) and ``estimates.parquet`` (with pyarrow:
``pip install flightid[parquet]``; without it a one-line notice says it was not written).
Each file is written to a temporary name and renamed into place. The table is rebuilt from
the per-case records (``cases/<name>/batch.json``) every time, so an interrupted batch leaves
a consistent table of what had finished.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

__all__ = ["FIXED_COLUMNS", "table_rows", "write_table"]

FIXED_COLUMNS = (
    "parameter",
    "unit",
    "value",
    "std",
    "std_cr",
    "coloured_std",
    "free",
    "converged",
    "status",
    "error",
)


def condition_columns(records: Sequence[dict[str, Any]]) -> list[str]:
    """Flight-condition column names in first-seen order."""
    names: dict[str, None] = {}
    for record in records:
        for name in record.get("conditions", {}):
            if name not in FIXED_COLUMNS and name != "case":
                names[name] = None
    return list(names)


def table_rows(records: Sequence[dict[str, Any]]) -> tuple[list[str], list[dict[str, Any]]]:
    """(column names, rows) of the results table for the case records (in the given order)."""
    conditions = condition_columns(records)
    columns = ["case", *conditions, *FIXED_COLUMNS]
    rows: list[dict[str, Any]] = []
    for record in records:
        base = {"case": record["case"]}
        base.update({c: record.get("conditions", {}).get(c) for c in conditions})
        common = {
            "converged": bool(record.get("converged", False)),
            "status": record.get("status", "failed"),
            "error": record.get("error"),
        }
        parameters = record.get("rows") or [
            {
                "parameter": None,
                "unit": None,
                "value": None,
                "std": None,
                "std_cr": None,
                "coloured_std": None,
            }
        ]
        for p in parameters:
            row = dict(base)
            row.update(
                parameter=p.get("parameter"),
                unit=p.get("unit"),
                value=p.get("value"),
                std=p.get("std"),
                std_cr=p.get("std_cr"),
                coloured_std=p.get("coloured_std"),
                free=p.get("free"),
            )
            row.update(common)
            rows.append(row)
    return columns, rows


def _replace(path: Path, write: Callable[[Path], None]) -> None:
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _csv_text(columns: list[str], rows: list[dict[str, Any]]) -> str:
    stream = io.StringIO()
    writer = csv.DictWriter(stream, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        # repr of a float is its shortest exact text: the CSV reads back to the same numbers
        writer.writerow({k: ("" if v is None else v) for k, v in row.items()})
    return stream.getvalue()


def _parquet(columns: list[str], rows: list[dict[str, Any]], path: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    types = {
        "value": pa.float64(),
        "std": pa.float64(),
        "coloured_std": pa.float64(),
        "free": pa.bool_(),
        "converged": pa.bool_(),
    }
    arrays = {}
    for column in columns:
        values = [row.get(column) for row in rows]
        kind = types.get(column)
        if kind is None:
            present = [v for v in values if v is not None]
            if present and all(isinstance(v, (int, float)) for v in present):
                kind = pa.float64()
                values = [None if v is None else float(v) for v in values]
            else:
                kind = pa.string()
                values = [None if v is None else str(v) for v in values]
        arrays[column] = pa.array(values, type=kind)
    pq.write_table(pa.table(arrays), path)


def write_table(
    records: Sequence[dict[str, Any]], out: Path, notice: Callable[[str], None] | None = None
) -> list[Path]:
    """Write ``out/estimates.csv`` and, with pyarrow, ``out/estimates.parquet``.

    Args:
        records: the case records (``flightid.batch.task.run_task``), in table order.
        out: the batch folder (exists).
        notice: receives the one-line notice when the Parquet file cannot be written.

    Returns:
        The files written.
    """
    columns, rows = table_rows(records)
    written = []
    text = _csv_text(columns, rows)
    csv_path = out / "estimates.csv"
    _replace(csv_path, lambda p: p.write_text(text, encoding="utf-8"))
    written.append(csv_path)
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        if notice is not None:
            notice(
                "estimates.parquet not written: pyarrow is not installed "
                "(pip install 'flightid[parquet]'); estimates.csv has the same table"
            )
        return written
    parquet_path = out / "estimates.parquet"
    _replace(parquet_path, lambda p: _parquet(columns, rows, p))
    written.append(parquet_path)
    return written
