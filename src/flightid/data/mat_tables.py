"""MATLAB arrays and structs into a ``Table``: shared by the v5 reader
(``flightid.data.loaders.read_mat``) and the v7.3 (HDF5) reader
(``flightid.data.formats.read_mat73``), so that both files of one flight give the same
table."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from flightid.data.table import (
    DataFileError,
    Table,
    _finish_table,
)

# the rule for struct arrays, in messages
_ONE = "flightid reads one struct (1 × 1) at a time: save each maneuver as its own struct"


def _shape(value: np.ndarray) -> str:
    return " × ".join(str(n) for n in value.shape)


def _v5_fields(path: Path, value: np.ndarray, where: str) -> dict[str, np.ndarray | str]:
    """The fields of a v5 struct (scipy's record array): numeric arrays by name, nested
    structs flattened with dots; a field that cannot be a column maps to the reason."""
    if value.size != 1:
        raise DataFileError(f"{path}: {where!r} is a {_shape(value)} struct array; {_ONE}")
    record = value.ravel()[0]
    fields: dict[str, np.ndarray | str] = {}
    for name in value.dtype.names:
        item = record[name]
        if isinstance(item, np.ndarray) and item.dtype.names:
            if item.size != 1:
                fields[name] = f"a {_shape(item)} struct array; {_ONE}"
                continue
            for key, sub in _v5_fields(path, item, f"{where}.{name}").items():
                fields[f"{name}.{key}"] = sub
        elif isinstance(item, np.ndarray) and item.dtype.kind in "fiub" and item.size:
            fields[name] = item
        else:
            fields[name] = "not numeric (text, cell or empty)"
    return fields


def struct_table(
    path: Path,
    variable: str,
    fields: Mapping[str, np.ndarray | str],
    units: Mapping[str, str] | None = None,
) -> Table:
    """The ``Table`` of a MATLAB struct's flattened ``fields`` (name → array in MATLAB's
    shape, or the reason it is no column).

    The rows are the most common sample count N of the non-scalar fields (a vector's
    length, a matrix's rows); a vector of N values is a column by its name, an N × k matrix
    the columns ``name_1`` … ``name_k``; scalars are constants; fields of another length
    are left out, and a channel naming one is told why (``Table.left_out``)."""
    units = units or {}
    left_out = {k: v for k, v in fields.items() if isinstance(v, str)}
    arrays = {k: np.atleast_2d(v) for k, v in fields.items() if not isinstance(v, str)}
    constants = {k: float(v.ravel()[0]) for k, v in arrays.items() if v.size == 1}
    lengths = [v.size if min(v.shape) == 1 else v.shape[0] for v in arrays.values() if v.size > 1]
    if not lengths:
        raise DataFileError(
            f"{path}: the struct {variable!r} has no numeric vector fields; fields: "
            f"{sorted(fields)}"
        )
    n = max(set(lengths), key=lambda length: (lengths.count(length), length))
    columns, names, column_units = [], [], []
    for name, value in arrays.items():
        if value.size == 1:
            continue
        if min(value.shape) == 1 and value.size == n:
            columns.append(value.ravel())
            names.append(name)
            column_units.append(units.get(name, ""))
            continue
        matrix = value if value.shape[0] == n else value.T if value.shape[1] == n else None
        if min(value.shape) == 1 or matrix is None:
            left_out[name] = f"a {_shape(value)} field; the struct's columns have {n} rows"
            continue
        for j in range(matrix.shape[1]):
            columns.append(matrix[:, j])
            names.append(f"{name}_{j + 1}")
            column_units.append(units.get(name, ""))
    return _finish_table(
        np.column_stack(columns),
        names,
        column_units,
        f"{path}:{variable}",
        constants,
        left_out,
    )


def _fdata_table(
    matrix: np.ndarray, varlab: Any, source: str, constants: Mapping[str, float]
) -> Table:
    """SIDPAC's ``fdata`` matrix, its columns named by ``varlab`` where the file has it."""
    names, units = (None, None)
    if varlab is not None:
        names, units = _varlab(varlab, matrix.shape[1])
    return _finish_table(matrix, names, units, source, constants)


def _only_matrix(
    path: Path, arrays: Mapping[str, np.ndarray], constants: Mapping[str, float]
) -> Table | None:
    """The table of the file's one 2-D matrix; None when it has none, an error when several."""
    matrices = {k: v for k, v in arrays.items() if v.ndim == 2 and min(v.shape) > 1}
    if len(matrices) > 1:
        raise DataFileError(
            f"{path}: several matrices {sorted(matrices)}; name the one to read (variable)"
        )
    if not matrices:
        return None
    ((name, matrix),) = matrices.items()
    return _finish_table(matrix, None, None, f"{path}:{name}", constants)


def _vectors_table(
    path: Path,
    arrays: Mapping[str, np.ndarray],
    structs: Sequence[str],
    constants: Mapping[str, float],
) -> Table:
    """The column vectors of the most common length, as named columns."""
    vectors = {k: v.ravel() for k, v in arrays.items() if v.ndim == 2 and min(v.shape) == 1}
    vectors = {k: v for k, v in vectors.items() if v.size > 1}
    if not vectors and structs:
        raise DataFileError(
            f"{path}: no numeric matrix or vectors at the top level; the file holds the "
            f"structs {list(structs)}: name the one to read, variable = {structs[0]!r} (its "
            "fields are the columns)"
        )
    if not vectors:
        raise DataFileError(f"{path}: no numeric matrix or vectors found")
    lengths = [v.size for v in vectors.values()]
    n = max(set(lengths), key=lengths.count)
    chosen = {k: v for k, v in vectors.items() if v.size == n}
    return _finish_table(
        np.column_stack(list(chosen.values())), list(chosen), None, str(path), constants
    )


def _mat_table(
    path: Path,
    arrays: Mapping[str, np.ndarray],
    varlab: Any,
    variable: str | None,
    structs: Sequence[str] = (),
) -> Table:
    """The ``Table`` of ``read_mat`` from the file's numeric arrays (MATLAB shapes, at least
    2-D), its ``varlab`` labels (array of strings, or None) and the names of its structs
    (for messages)."""
    constants = {k: float(v.ravel()[0]) for k, v in arrays.items() if v.size == 1}
    source = str(path)
    if variable is not None:
        if variable not in arrays:
            structs_words = f"; structs: {list(structs)}" if structs else ""
            raise DataFileError(
                f"{path}: no numeric variable or struct {variable!r}; variables: "
                f"{sorted(arrays)}{structs_words}"
            )
        if variable == "fdata":
            return _fdata_table(arrays[variable], varlab, source, constants)
        return _finish_table(arrays[variable], None, None, source, constants)
    if "fdata" in arrays:
        return _fdata_table(arrays["fdata"], varlab, source, constants)
    table = _only_matrix(path, arrays, constants)
    if table is not None:
        return table
    return _vectors_table(path, arrays, structs, constants)


_VARLAB = re.compile(r"^\s*\*?\s*(?P<name>.*?)\s*(?:\((?P<unit>[^)]*)\))?\s*$")


def _varlab(varlab: np.ndarray, k: int) -> tuple[list[str], list[str]]:
    labels = [str(v if not isinstance(v, np.ndarray) else v.ravel()[0]) for v in varlab.ravel()]
    labels = (labels + [""] * k)[:k]
    names, units = [], []
    seen: set[str] = set()
    for label in labels:
        m = _VARLAB.match(label)
        name = (m.group("name") if m else label).strip()
        name = re.sub(r"\s+", "_", name)
        if name in seen:
            name = ""
        seen.add(name)
        names.append(name)
        units.append((m.group("unit") or "").strip() if m else "")
    return names, units
