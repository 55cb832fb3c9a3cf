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
PX4 ULog ``.ulg``      pyulog            ``pip install 'flightid[px4]'``
ArduPilot DataFlash    pymavlink         ``pip install 'flightid[ardupilot]'``
=====================  ================  =========================================
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from flightid.data.mat_tables import _mat_table, struct_table
from flightid.data.table import (
    _CSV_UNIT,
    DataFileError,
    Table,
    TableStream,
    _finish_table,
    _require,
)

__all__ = [
    "Stream",
    "read_parquet",
    "read_mat73",
    "is_mat73",
    "read_ulog",
    "read_dataflash",
    "ulog_streams",
    "dataflash_streams",
]


@dataclass(frozen=True)
class Stream:
    """One message stream of a flight log, on its own time base, as the log stored it.

    Attributes:
        name: the stream's name as a case names it (ULog topic, ``topic:1`` for
            multi-instance 1; DataFlash message type, ``IMU[1]`` for instance 1); column names
            write it ``topic_1`` / ``IMU_1``.
        time_s: the stream's time stamps (s since boot), as stored (jitter, drop-outs kept).
        fields: ``{field: values}``, one value per time stamp (array fields ``q[0]`` → ``q_0``).
        units: ``{field: unit}`` where the log states one (DataFlash FMTU); else absent.
    """

    name: str
    time_s: np.ndarray
    fields: dict[str, np.ndarray]
    units: dict[str, str] = dataclasses.field(default_factory=dict)


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
        structs = sorted(
            name for name in handle if not name.startswith("#") and _is_struct(h5py, handle[name])
        )
        if variable is not None and variable.split(".")[0] in structs:
            fields, units = _mat73_struct(h5py, handle, path, variable)
            return struct_table(path, variable, fields, units)
        values = {
            name: _mat73_value(h5py, handle, handle[name])
            for name in handle
            if not name.startswith("#")
        }
    arrays = {k: v for k, v in values.items() if isinstance(v, np.ndarray)}
    varlab = values.get("varlab")
    labels = np.array(varlab, dtype=object) if isinstance(varlab, list) else None
    return _mat_table(path, arrays, labels, variable, structs)


def _is_struct(h5py: Any, item: Any) -> bool:
    """True for a MATLAB v7.3 struct: an HDF5 group (MATLAB_class ``struct``, or none)."""
    if not isinstance(item, h5py.Group):
        return False
    kind = item.attrs.get("MATLAB_class", b"struct")
    return (kind.decode() if isinstance(kind, bytes) else str(kind)) == "struct"


def _hdf5_unit(item: Any) -> str:
    """The unit an HDF5 dataset states in an attribute ``unit`` or ``units`` ("" if none)."""
    for key in ("unit", "units"):
        value = item.attrs.get(key)
        if value is not None:
            value = value.decode("utf-8", "replace") if isinstance(value, bytes) else value
            value = np.asarray(value).ravel()
            if value.size == 1 and isinstance(value[0], (str, bytes)):
                text = value[0]
                return text.decode("utf-8", "replace") if isinstance(text, bytes) else text
    return ""


def _mat73_struct(
    h5py: Any, handle: Any, path: Path, variable: str
) -> tuple[dict[str, np.ndarray | str], dict[str, str]]:
    """The fields of the v7.3 struct ``variable`` ("a" or "a.b"), nested structs flattened
    with dots (field → array in MATLAB's shape, or the reason it is no column), and the
    units the datasets state (``_hdf5_unit``)."""
    node = handle
    for depth, part in enumerate(variable.split(".")):
        if part not in node:
            here = ".".join(variable.split(".")[:depth]) or "the file"
            raise DataFileError(f"{path}: {here!r} has no field {part!r}; fields: {sorted(node)}")
        node = node[part]
    fields: dict[str, np.ndarray | str] = {}
    units: dict[str, str] = {}

    def collect(group: Any, prefix: str) -> None:
        for name in group:
            item = group[name]
            key = f"{prefix}{name}"
            if _is_struct(h5py, item):
                collect(item, f"{key}.")
                continue
            value = _mat73_value(h5py, handle, item)
            if isinstance(value, np.ndarray) and value.size:
                fields[key] = value
                units[key] = _hdf5_unit(item)
            else:
                fields[key] = "not numeric (text, cell, struct array or empty)"

    if not _is_struct(h5py, node):
        value = _mat73_value(h5py, handle, node)
        if not isinstance(value, np.ndarray):
            raise DataFileError(f"{path}: {variable!r} is neither a struct nor numeric")
        return {variable.split(".")[-1]: value}, {variable.split(".")[-1]: _hdf5_unit(node)}
    collect(node, "")
    return fields, units


# =====================================================================================
# Flight logs: several message streams, each on its own time base
# =====================================================================================


def _topics(variable: str | None, available: list[str], path: Path, kind: str) -> list[str]:
    """The streams named in ``variable`` ("A" or "A,B,..."), checked against the file's."""
    if variable is None:
        if len(available) == 1:
            return available
        raise DataFileError(
            f"{path}: a {kind} holds several message streams, each with its own time base; "
            f'name the ones to read with variable = "first,second" (streams at different '
            f"rates need resample_hz); streams in the file: {sorted(available)}"
        )
    wanted = [v.strip() for v in variable.split(",") if v.strip()]
    missing = [v for v in wanted if v not in available]
    if not wanted or missing:
        raise DataFileError(
            f"{path}: variable {variable!r}: no stream {missing or [variable]} in the {kind}; "
            f"streams in the file: {sorted(available)}"
        )
    return wanted


def _column_name(stream: str, field: str, prefix: bool) -> str:
    """``stream.field`` (or ``field`` for a single stream), array indices ``x[0]`` → ``x_0``
    so that the name can be used in channel expressions."""
    field = field.replace("[", "_").replace("]", "")
    return f"{stream}.{field}" if prefix else field


def _streams_table(
    path: Path,
    streams: list[Stream],
    constants: dict[str, float] | None = None,
) -> Table:
    """One ``Table`` from message streams, nothing interpolated.

    Streams that share their time stamps (one stream, or several logged together) give a
    plain table on those stamps (column ``t``, s). Streams on different time bases give a
    table whose rows are the union of their stamps, each column NaN where its stream has no
    sample, and ``Table.streams`` naming each stream's rows and columns: ``to_flight_data``
    refuses it unless a resampling rate is declared (``resample_hz``), which puts every
    stream on one grid, anti-aliased (``flightid.data.resample``). With one stream, columns
    are named by field; with several, ``stream.field``.
    """
    for one in streams:
        if one.time_s.shape[0] < 1 or np.any(np.diff(one.time_s) <= 0):
            k = int(np.argmax(np.diff(one.time_s) <= 0)) if one.time_s.shape[0] > 1 else 0
            raise DataFileError(
                f"{path}: stream {one.name!r}: time stamps must increase"
                + (
                    f" (t = {one.time_s[k]:.6g} s at sample {k + 1} is followed by "
                    f"{one.time_s[k + 1]:.6g} s)"
                    if one.time_s.shape[0] > 1
                    else " (the stream is empty)"
                )
            )
    shared = all(np.array_equal(s.time_s, streams[0].time_s) for s in streams)
    t = streams[0].time_s if shared else np.unique(np.concatenate([s.time_s for s in streams]))
    prefix = len(streams) > 1
    columns, names, units = [t], ["t"], ["s"]
    listed = []
    for one in streams:
        stream = one.name.replace(":", "_").replace("[", "_").replace("]", "")
        rows = np.searchsorted(t, one.time_s)
        first = len(columns)
        for field, values in one.fields.items():
            column = np.full(t.shape[0], np.nan)
            column[rows] = np.asarray(values, dtype=float)
            columns.append(column)
            names.append(_column_name(stream, field, prefix))
            units.append(one.units.get(field, ""))
        listed.append(TableStream(one.name, rows, tuple(range(first, len(columns)))))
    table = _finish_table(np.column_stack(columns), names, units, str(path), constants)
    return table if shared else dataclasses.replace(table, streams=tuple(listed))


def _open_ulog(path: Path) -> Any:
    pyulog = _require("pyulog", "px4", f"the PX4 ULog file {path}")
    try:
        return pyulog.ULog(str(path))
    except Exception as exc:  # pyulog raises ULogException, struct.error, ...
        raise DataFileError(f"{path}: not a readable PX4 ULog file ({exc})") from None


def ulog_streams(
    path: str | Path, variable: str | None = None
) -> tuple[list[Stream], dict[str, float]]:
    """The topics of a PX4 ULog as ``Stream`` objects (each on its own time base) and the
    log's numeric parameters.

    ``variable`` names the topics, ``"vehicle_attitude,sensor_combined"`` (``"topic:1"``:
    multi-instance 1); ``None`` reads every topic. Time: ``timestamp`` (µs since boot) × 10⁻⁶.
    """
    path = Path(path)
    ulog = _open_ulog(path)
    datasets = {}
    for d in ulog.data_list:
        datasets[f"{d.name}:{d.multi_id}"] = d
        if d.multi_id == 0:
            datasets[d.name] = d
    available = sorted(
        {d.name if d.multi_id == 0 else f"{d.name}:{d.multi_id}" for d in ulog.data_list}
    )
    names = available if variable is None else _topics(variable, available, path, "ULog file")
    streams = []
    for name in names:
        d = datasets[name]
        fields = {
            _column_name("", k, False): np.asarray(v, dtype=float)
            for k, v in d.data.items()
            if k != "timestamp" and np.asarray(v).dtype.kind in "biuf"
        }
        time = np.asarray(d.data["timestamp"], dtype=float) * 1e-6  # µs → s
        streams.append(Stream(name, time, fields, {}))
    constants = {
        k: float(v) for k, v in ulog.initial_parameters.items() if isinstance(v, (int, float))
    }
    return streams, constants


def read_ulog(path: str | Path, variable: str | None = None) -> Table:
    """PX4 ULog (``.ulg``; needs pyulog: the ``px4`` extra) → ``Table``.

    ``variable`` names the uORB topics to read, ``"vehicle_attitude,sensor_combined"``;
    ``"topic:1"`` picks multi-instance 1 (default 0). Time ``t`` (s) is ``timestamp``
    (µs since boot) × 10⁻⁶; topics on different time bases keep their own stamps (see
    ``_streams_table``) and need a declared ``resample_hz`` to become flight data.
    Columns: ``topic.field`` (one topic: ``field``), array fields ``q[0]`` → ``q_0``.
    ULog stores no units (PX4 topics are in SI, angles in rad); declare them in the mapping.
    Numeric parameters of the log are kept as ``Table.constants``.
    """
    path = Path(path)
    streams, constants = ulog_streams(path, variable)
    if variable is None and len(streams) > 1:
        _topics(None, [s.name for s in streams], path, "ULog file")
    return _streams_table(path, streams, constants)


def dataflash_streams(path: str | Path, variable: str | None = None) -> list[Stream]:
    """The message types of an ArduPilot DataFlash log as ``Stream`` objects (each on its own
    time base, ``TimeUS`` × 10⁻⁶ s), with the units of the log's FMTU/UNIT messages.

    ``variable`` names the types, ``"ATT,IMU"`` (``"IMU[1]"``: instance 1); ``None`` reads
    every type that has a ``TimeUS`` field. Values carry the scale of their format character.
    """
    path = Path(path)
    dfreader = _require("pymavlink.DFReader", "ardupilot", f"the ArduPilot DataFlash log {path}")
    try:
        with open(path, "rb") as handle:
            head = handle.read(4)
    except OSError as exc:
        raise DataFileError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
    # binary logs start with the message header bytes 0xA3 0x95; text logs with "FMT,"
    if head[:2] == b"\xa3\x95":
        reader = dfreader.DFReader_binary
    elif head == b"FMT,":
        reader = dfreader.DFReader_text
    else:
        raise DataFileError(
            f"{path}: not an ArduPilot DataFlash log (expected the bytes A3 95 of a binary "
            f"log or 'FMT,' of a text log at the start, got {head!r})"
        )
    # read only the named types (pymavlink's index skips the others); all of them when
    # none is named, or to list what the file holds when a named one is missing
    types = None
    if variable is not None:
        types = {v.strip().split("[")[0] for v in variable.split(",") if v.strip()}
    records, formats = _dataflash_records(reader, path, types)
    if types is not None and not types <= {n.split("[")[0] for n in records}:
        records, formats = _dataflash_records(reader, path, None)
    # a type logged for a single instance may also be named without it: "IMU" for "IMU[0]"
    aliases = {}
    for name in records:
        base = name.split("[")[0]
        if base != name and sum(n.split("[")[0] == base for n in records) == 1:
            aliases[base] = name
    wanted_names = (
        sorted(records)
        if variable is None
        else _topics(variable, sorted(set(records) | set(aliases)), path, "DataFlash log")
    )
    streams = []
    for wanted in wanted_names:
        name = aliases.get(wanted, wanted)
        count = len(records[name]["TimeUS"])
        fields = {
            k: np.asarray(v, dtype=float) for k, v in records[name].items() if len(v) == count
        }
        time = fields.pop("TimeUS") * 1e-6  # µs → s
        units = {k: formats[name].get_unit(k) for k in fields}
        streams.append(Stream(name, time, fields, units))
    return streams


def read_dataflash(path: str | Path, variable: str | None = None) -> Table:
    """ArduPilot DataFlash log (binary ``.bin``, or the text ``.log`` form; needs pymavlink:
    the ``ardupilot`` extra) → ``Table``.

    ``variable`` names the message types to read, ``"ATT,IMU"``; a type logged for several
    instances (an instance field such as ``IMU.I``) is named with the instance, ``"IMU[1]"``.
    Time ``t`` (s) is ``TimeUS`` (µs since boot) × 10⁻⁶; types on different time bases keep
    their own stamps (see ``_streams_table``) and need a declared ``resample_hz``. Columns:
    ``TYPE.Field`` (one type: ``Field``); text fields are left out. Values carry the scale
    of their format character (``c``: int16 × 0.01, ``L``: int32 × 10⁻⁷, ...), and units
    come from the log's FMTU/UNIT messages where it has them (informational; declare them
    in the mapping as for CSV).
    """
    path = Path(path)
    streams = dataflash_streams(path, variable)
    if variable is None and len(streams) > 1:
        _topics(None, [s.name for s in streams], path, "DataFlash log")
    return _streams_table(path, streams)


def _dataflash_records(
    reader: Any, path: Path, types: set[str] | None
) -> tuple[dict[str, dict[str, list]], dict[str, Any]]:
    """Numeric fields per message type (``"IMU[1]"`` for an instance) and the types'
    formats, from one pass over the log; only ``types`` when given."""
    try:
        log = reader(str(path), zero_time_base=True)
    except Exception as exc:  # pymavlink raises several types for bad files
        raise DataFileError(f"{path}: not a readable DataFlash log ({exc})") from None
    records: dict[str, dict[str, list]] = {}
    formats: dict[str, Any] = {}
    try:
        while True:
            if types is None:
                message = log.recv_msg()
            else:
                message = log.recv_match(type=types, strict=True)
            if message is None:
                break
            fmt = message.fmt
            if fmt.name in ("FMT", "FMTU", "UNIT", "MULT") or "TimeUS" not in fmt.colhash:
                continue
            name = fmt.name
            if fmt.instance_field is not None:
                name = f"{name}[{getattr(message, fmt.instance_field)}]"
            formats[name] = fmt
            row = records.setdefault(name, {})
            for column in fmt.columns:
                value = getattr(message, column)
                if isinstance(value, (int, float)) and column != fmt.instance_field:
                    row.setdefault(column, []).append(value)
    finally:
        handle = getattr(log, "filehandle", None)
        if handle is not None:
            handle.close()
    return records, formats
