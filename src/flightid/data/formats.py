"""Readers for file formats that need an optional package (an extra of flightid).

Each reader returns the same ``Table`` as the CSV/ASCII/MATLAB readers of
``flightid.data.loaders``, so channel specifications, units and expressions work unchanged.
A missing package raises ``MissingDependencyError`` (a ``FlightIdError`` and an
``ImportError``) naming the extra to install:

=====================  ================  =========================================
format                 package           install
=====================  ================  =========================================
Parquet                pyarrow           ``pip install 'flightid[parquet]'``
MATLAB v7.3 ``.mat``   h5py              ``pip install 'flightid[hdf5]'``
=====================  ================  =========================================
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from flightid.data.loaders import (
    _CSV_UNIT,
    DataFileError,
    Table,
    _finish_table,
    _mat_table,
)
from flightid.results import MissingDependencyError

__all__ = ["read_parquet", "read_mat73", "is_mat73"]


def _require(module: str, extra: str, what: str) -> Any:
    """Import ``module`` or raise ``MissingDependencyError`` naming the extra."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        package = module.split(".")[0]
        raise MissingDependencyError(
            f"reading {what} needs {package}, which is not installed; install it with "
            f"pip install 'flightid[{extra}]' (or pip install {package})"
        ) from None


# =====================================================================================
# Parquet (pyarrow)
# =====================================================================================


def read_parquet(path: str | Path) -> Table:
    """Parquet file → ``Table`` (needs pyarrow: the ``parquet`` extra).

    Numeric and boolean columns are read (other columns — strings, timestamps — are left
    out and listed in no column). Units come from a field's metadata key ``unit`` when
    present, else from the column name as in CSV headers (``alpha [deg]``, ``alpha (deg)``).
    """
    path = Path(path)
    pq = _require("pyarrow.parquet", "parquet", f"the Parquet file {path}")
    try:
        arrow = pq.read_table(str(path))
    except Exception as exc:  # pyarrow raises ArrowInvalid, OSError, ...
        raise DataFileError(f"{path}: not a readable Parquet file ({exc})") from None
    import pyarrow.types as pat

    columns, names, units = [], [], []
    for field, column in zip(arrow.schema, arrow.columns, strict=True):
        if not (pat.is_integer(field.type) or pat.is_floating(field.type)) and not (
            pat.is_boolean(field.type)
        ):
            continue
        # nulls → NaN (the same rule as empty CSV fields)
        values = column.to_numpy(zero_copy_only=False)
        columns.append(np.asarray(values, dtype=float))
        meta = field.metadata or {}
        unit = meta.get(b"unit", b"").decode("utf-8", "replace")
        m = _CSV_UNIT.fullmatch(field.name)
        names.append(m.group(1) if m else field.name)
        units.append(unit or (m.group(2) if m else ""))
    if not columns:
        raise DataFileError(
            f"{path}: no numeric columns; columns and types: "
            f"{[f'{f.name}: {f.type}' for f in arrow.schema]}"
        )
    return _finish_table(np.column_stack(columns), names, units, str(path))


# =====================================================================================
# MATLAB v7.3 (HDF5; h5py)
# =====================================================================================

_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def is_mat73(path: str | Path) -> bool:
    """True when ``path`` is an HDF5 file (MATLAB v7.3 ``.mat``): the HDF5 signature at
    byte 0 or at 512 (after MATLAB's 512-byte user block)."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(520)
    except OSError:
        return False
    return head[:8] == _HDF5_SIGNATURE or head[512:520] == _HDF5_SIGNATURE


def _mat73_value(h5py: Any, handle: Any, item: Any) -> Any:
    """A MATLAB v7.3 dataset as MATLAB sees it: numeric → 2-D array (transposed back from
    HDF5's row-major order); char → list of row strings; cell of char → list of strings;
    anything else (structs, empty, complex, objects) → None."""
    if not isinstance(item, h5py.Dataset):
        return None
    kind = item.attrs.get("MATLAB_class", b"")
    kind = kind.decode() if isinstance(kind, bytes) else str(kind)
    if item.attrs.get("MATLAB_empty", 0):
        return None
    if kind == "char":
        # a MATLAB k × L char matrix is stored as uint16 codes with shape (L, k)
        codes = np.atleast_2d(np.asarray(item[()])).T
        return ["".join(chr(int(c)) for c in row) for row in codes]
    if kind == "cell":
        out = []
        for ref in np.asarray(item[()]).T.ravel():
            value = _mat73_value(h5py, handle, handle[ref])
            if not (isinstance(value, list) and len(value) == 1):
                return None
            out.append(value[0])
        return out
    data = np.asarray(item[()])
    if data.dtype.kind not in "fiub" or data.ndim > 2:
        return None
    # MATLAB stores column-major: an N × k matrix appears in HDF5 as k × N
    return np.atleast_2d(data).T


def read_mat73(path: str | Path, variable: str | None = None) -> Table:
    """MATLAB v7.3 ``.mat`` (HDF5; needs h5py: the ``hdf5`` extra), read by the same rules
    as v5 files in ``read_mat``: a chosen ``variable``; SIDPAC ``fdata`` with ``varlab``
    (char matrix or cell array of labels); a single matrix; or equal-length named vectors.
    Scalars are kept as ``Table.constants``."""
    path = Path(path)
    h5py = _require("h5py", "hdf5", f"the MATLAB v7.3 file {path}")
    try:
        handle = h5py.File(str(path), "r")
    except OSError as exc:
        raise DataFileError(f"{path}: not a readable HDF5/MATLAB v7.3 file ({exc})") from None
    with handle:
        values = {
            name: _mat73_value(h5py, handle, handle[name])
            for name in handle
            if not name.startswith("#")
        }
    arrays = {k: v for k, v in values.items() if isinstance(v, np.ndarray)}
    varlab = values.get("varlab")
    labels = np.array(varlab, dtype=object) if isinstance(varlab, list) else None
    return _mat_table(path, arrays, labels, variable)
