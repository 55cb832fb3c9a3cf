"""Writers for flight logs: PX4 ULog (through pyulog) and ArduPilot DataFlash (through
pymavlink's message packer).

Both take the ``Stream`` objects that ``flightid.data.formats.ulog_streams`` and
``dataflash_streams`` return, so that writing and reading back give the same streams: the
same names, time stamps (stored as integer microseconds) and field values (stored in the
field's log type: ``float`` is float32, integer types must hold integers in range, and
DataFlash's scaled types such as ``c`` = int16 × 0.01 must hold exact multiples of their
scale). A value that the log type cannot store exactly (other than float rounding) is a
``LogWriteError``, never a silently changed number.

They serve the shipped example logs (``flightid.examples.logs``) and the tests; they write
what a logger writes, not everything a logger can write (no nested ULog types, no logged
strings, no DataFlash text messages).
"""

from __future__ import annotations

import math
import re
import types
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from flightid.data.formats import Stream, _require
from flightid.errors import InputError, InputTypeError

__all__ = ["LogWriteError", "write_ulog", "write_dataflash", "DATAFLASH_UNIT_IDS"]


class LogWriteError(InputError):
    """A stream cannot be written to the log as given: bad time stamps, a name or value the
    log format cannot hold exactly. The message names the stream, field and what came."""


# ---------------------------------------------------------------------------------------
# checks shared by both writers
# ---------------------------------------------------------------------------------------

_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_US_PER_S = 1_000_000


def _stamps_us(stream: Stream) -> np.ndarray:
    """The stream's time stamps in integer µs (t_us = round(t_s · 10⁶)); refused unless
    finite, ≥ 0 and strictly increasing after rounding (a log stores one sample per stamp)."""
    if not isinstance(stream, Stream):
        raise InputTypeError(
            f"expected flightid.data.formats.Stream objects, got {type(stream).__name__}"
        )
    time_s = np.asarray(stream.time_s, dtype=float)
    if time_s.ndim != 1 or time_s.size == 0:
        raise LogWriteError(
            f"stream {stream.name!r}: time_s must be a non-empty 1-D array, "
            f"got shape {time_s.shape}"
        )
    if not np.all(np.isfinite(time_s)) or time_s.min() < 0:
        raise LogWriteError(
            f"stream {stream.name!r}: time stamps must be finite and ≥ 0 s "
            f"(µs since boot), got min {np.nanmin(time_s)!r}"
        )
    stamps = np.rint(time_s * _US_PER_S).astype(np.int64)
    steps = np.diff(stamps)
    if np.any(steps <= 0):
        k = int(np.argmax(steps <= 0))
        raise LogWriteError(
            f"stream {stream.name!r}: time stamps must increase by at least 1 µs; sample "
            f"{k + 1} at {time_s[k + 1]!r} s follows {time_s[k]!r} s"
        )
    for field, values in stream.fields.items():
        values = np.asarray(values)
        if values.shape != time_s.shape:
            raise LogWriteError(
                f"stream {stream.name!r}: field {field!r} has shape {values.shape}, "
                f"expected one value per time stamp {time_s.shape}"
            )
    return stamps


def _target(path: str | Path, overwrite: bool) -> Path:
    """The file to write: an existing one (or a link) only with ``overwrite``; a link is
    removed first, so that the log is never written through it into another file."""
    path = Path(path)
    if path.exists() or path.is_symlink():
        if not overwrite:
            raise LogWriteError(f"{path}: already exists; pass overwrite=True to replace it")
        if path.is_dir() and not path.is_symlink():
            raise LogWriteError(f"{path}: is a folder, not a log file")
        if path.is_symlink():
            path.unlink()
    return path


def _exact_integers(
    values: np.ndarray, low: float, high: float, where: str, scale: float = 1.0
) -> np.ndarray:
    """values / scale as integers, refused unless every one is an integer in [low, high]
    (to 10⁻⁶ of a count: the scaled types store counts)."""
    counts = np.asarray(values, dtype=float) / scale
    rounded = np.rint(counts)
    bad = ~np.isfinite(counts) | (np.abs(counts - rounded) > 1e-6) | (rounded < low)
    bad |= rounded > high
    if np.any(bad):
        k = int(np.argmax(bad))
        what = "integers" if scale == 1.0 else f"multiples of {scale:g}"
        raise LogWriteError(
            f"{where}: the log type stores {what} in [{low * scale:g}, {high * scale:g}]; "
            f"sample {k} is {float(np.asarray(values)[k])!r}"
        )
    return rounded


# ---------------------------------------------------------------------------------------
# PX4 ULog (pyulog)
# ---------------------------------------------------------------------------------------

# ULog basic type → numpy dtype (little-endian), as the ULog file format defines them
_ULOG_DTYPES = {
    "int8_t": "<i1",
    "uint8_t": "<u1",
    "int16_t": "<i2",
    "uint16_t": "<u2",
    "int32_t": "<i4",
    "uint32_t": "<u4",
    "int64_t": "<i8",
    "uint64_t": "<u8",
    "float": "<f4",
    "double": "<f8",
    "bool": "<u1",
}
_ARRAY_FIELD = re.compile(r"(.+)_(\d+)")


def _ulog_fields(
    stream: Stream, field_types: Mapping[str, str]
) -> list[tuple[str, int, str, list[str]]]:
    """The stream's fields as ULog format entries ``(type, array size, name, [Stream field
    names])``: fields ``x_0, x_1, …, x_{n−1}`` of one type, in this order, are one array
    ``type[n] x`` (the reader names array elements ``x_k``); others are scalars."""
    names = list(stream.fields)
    entries: list[tuple[str, int, str, list[str]]] = []
    k = 0
    while k < len(names):
        name = names[k]
        if not _IDENTIFIER.fullmatch(name) or name == "timestamp":
            raise LogWriteError(
                f"stream {stream.name!r}: field {name!r} is not a ULog field name "
                "(letters, digits, '_'; not 'timestamp', which the writer adds)"
            )
        kind = field_types.get(name, "float")
        if kind not in _ULOG_DTYPES:
            raise LogWriteError(
                f"stream {stream.name!r}: field {name!r}: ULog type {kind!r} unknown; "
                f"known: {sorted(_ULOG_DTYPES)}"
            )
        match = _ARRAY_FIELD.fullmatch(name)
        if match and match.group(2) == "0":
            base, run = match.group(1), [name]
            while k + len(run) < len(names) and names[k + len(run)] == f"{base}_{len(run)}":
                if field_types.get(names[k + len(run)], "float") != kind:
                    break
                run.append(names[k + len(run)])
            if len(run) > 1:
                entries.append((kind, len(run), base, run))
                k += len(run)
                continue
        entries.append((kind, 0, name, [name]))
        k += 1
    return entries


def _ulog_values(values: Any, kind: str, where: str) -> np.ndarray:
    """The values as stored in ULog type ``kind``; integer types must hold exact integers."""
    dtype = np.dtype(_ULOG_DTYPES[kind])
    if dtype.kind == "f":
        return np.asarray(values, dtype=float).astype(dtype)
    info = np.iinfo(dtype)
    low, high = (0, 1) if kind == "bool" else (info.min, info.max)
    return _exact_integers(values, low, high, where).astype(dtype)


def _ulog_topic(stream: Stream) -> tuple[str, int]:
    """``"topic:k"`` → (topic, multi-instance k)."""
    topic, _, instance = stream.name.partition(":")
    if not _IDENTIFIER.fullmatch(topic) or (instance and not instance.isdigit()):
        raise LogWriteError(
            f"stream name {stream.name!r}: expected a ULog topic name, 'topic' or "
            "'topic:k' for multi-instance k"
        )
    multi_id = int(instance or 0)
    if multi_id > 255:
        raise LogWriteError(f"stream {stream.name!r}: multi-instance {multi_id} > 255")
    return topic, multi_id


def _ulog_parameter(name: str, value: object) -> int | float:
    """A ULog parameter: ``int`` → int32_t, ``float`` → float (float32)."""
    if not isinstance(name, str) or not name or " " in name:
        raise LogWriteError(f"parameter name {name!r}: expected a name without spaces")
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputTypeError(
            f"parameter {name!r}: expected an int (int32_t) or a float, got {value!r}"
        )
    if isinstance(value, (int, np.integer)):
        if not -(2**31) <= int(value) < 2**31:
            raise LogWriteError(f"parameter {name!r}: {value} does not fit an int32_t")
        return int(value)
    return float(value)


def write_ulog(
    path: str | Path,
    streams: Sequence[Stream],
    parameters: Mapping[str, int | float] | None = None,
    *,
    field_types: Mapping[str, Mapping[str, str]] | None = None,
    dropouts: Sequence[tuple[float, float]] = (),
    info: Mapping[str, str] | None = None,
    overwrite: bool = False,
) -> Path:
    """Write ``streams`` as a PX4 ULog file (needs pyulog: the ``px4`` extra).

    Each stream is one topic (``"topic:k"``: multi-instance k), its fields after the
    ``uint64_t timestamp`` (µs, from ``time_s``); fields ``x_0 … x_{n−1}`` are written as
    an array ``x[n]``, which the reader names ``x_0 …`` again. ``field_types`` gives a
    field's ULog type per stream name (``{"vehicle_status": {"nav_state": "uint8_t"}}``);
    the default is ``float`` (float32, as PX4 logs most values). ``parameters``: int →
    ``int32_t``, float → ``float``. ``dropouts``: (time s, duration s) of logger drop-outs,
    written as ULog dropout messages (a dropout message holds only its duration, in ms; it
    is placed among the data by its time, and readers date it by the message before it).
    ``info``: string info messages such
    as ``{"sys_name": "PX4"}``. An existing file is replaced only with ``overwrite``.
    Returns the path.
    """
    pyulog = _require("pyulog", "px4", f"writing the PX4 ULog file {path}")
    if not hasattr(pyulog.ULog, "write_ulog"):
        raise LogWriteError(
            "writing a ULog needs a pyulog with ULog.write_ulog (pyulog ≥ 1.3 has it); "
            "upgrade with pip install -U pyulog"
        )
    field_types = field_types or {}
    log = pyulog.ULog(None)
    log._file_version = 1
    formats: dict[str, Any] = {}
    first_us = []
    for msg_id, stream in enumerate(streams):
        stamps = _stamps_us(stream)
        first_us.append(int(stamps[0]))
        topic, multi_id = _ulog_topic(stream)
        entries = _ulog_fields(stream, field_types.get(stream.name, {}))
        text = f"{topic}:uint64_t timestamp;" + "".join(
            f"{kind}[{size}] {name};" if size else f"{kind} {name};"
            for kind, size, name, _ in entries
        )
        if topic in formats and formats[topic][0] != text:
            raise LogWriteError(
                f"stream {stream.name!r}: every instance of topic {topic!r} must have the "
                f"same fields and types; {formats[topic][0]!r} and {text!r}"
            )
        formats[topic] = (text, pyulog.ULog.MessageFormat(text.encode(), None))
        log._data_list.append(_ulog_data(pyulog, stream, msg_id, topic, multi_id, entries))
    log._message_formats = {topic: fmt for topic, (_, fmt) in formats.items()}
    log._start_timestamp = min(first_us, default=0)
    log._initial_parameters = {
        name: _ulog_parameter(name, value) for name, value in (parameters or {}).items()
    }
    for key, value in (info or {}).items():
        log._msg_info_dict[key] = str(value)
        log._msg_info_dict_types[key] = f"char[{len(str(value).encode())}]"
    log._dropouts = [_ulog_dropout(time_s, duration_s) for time_s, duration_s in dropouts]
    path = _target(path, overwrite)
    log.write_ulog(str(path))
    return path


def _ulog_data(
    pyulog: Any,
    stream: Stream,
    msg_id: int,
    topic: str,
    multi_id: int,
    entries: list[tuple[str, int, str, list[str]]],
) -> Any:
    """A ``pyulog.ULog.Data`` holding the stream (the object ``ULog.write_ulog`` writes)."""
    columns = [("timestamp", "uint64_t", _stamps_us(stream).astype(np.uint64))]
    for kind, size, name, sources in entries:
        for k, source in enumerate(sources):
            column = f"{name}[{k}]" if size else name
            where = f"stream {stream.name!r}, field {source!r} ({kind})"
            columns.append((column, kind, _ulog_values(stream.fields[source], kind, where)))
    dtype = np.dtype([(name, _ULOG_DTYPES[kind]) for name, kind, _ in columns])
    table = np.empty(len(columns[0][2]), dtype=dtype)
    for name, _, values in columns:
        table[name] = values
    subscription = types.SimpleNamespace(
        multi_id=multi_id,
        msg_id=msg_id,
        message_name=topic,
        field_data=[
            types.SimpleNamespace(field_name=name, type_str=kind) for name, kind, _ in columns
        ],
        timestamp_idx=0,
        buffer=table.tobytes(),
        dtype=dtype,
    )
    return pyulog.ULog.Data(subscription)


def _ulog_dropout(time_s: float, duration_s: float) -> Any:
    """A ULog dropout message: at ``time_s``, ``duration_s`` lost (stored in whole ms)."""
    duration_ms = duration_s * 1000.0
    if not (math.isfinite(time_s) and time_s >= 0 and 0 < duration_ms < 65535.5):
        raise LogWriteError(
            f"dropout ({time_s!r} s, {duration_s!r} s): expected a time ≥ 0 s and a duration "
            "in (0, 65.535] s"
        )
    return types.SimpleNamespace(
        timestamp=round(time_s * _US_PER_S), duration=max(1, round(duration_ms))
    )


# ---------------------------------------------------------------------------------------
# ArduPilot DataFlash (pymavlink)
# ---------------------------------------------------------------------------------------

# ArduPilot's unit identifiers (libraries/AP_Logger/LogStructure.h, log_Units): the label a
# unit id stands for. Labels outside the table get an unused id.
DATAFLASH_UNIT_IDS = {
    "": "-",
    "A": "A",
    "Ah": "a",
    "deg": "d",
    "B": "b",
    "B/s": "B",
    "deg/s": "k",
    "deglatitude": "D",
    "deg/s/s": "e",
    "rad/s": "E",
    "Gauss": "G",
    "degheading": "h",
    "A.s": "i",
    "W.s": "J",
    "l": "l",
    "rad/s/s": "L",
    "m": "m",
    "m/s": "n",
    "m/s/s": "o",
    "degC": "O",
    "%": "%",
    "satellites": "S",
    "s": "s",
    "rpm": "q",
    "rad": "r",
    "deglongitude": "U",
    "ppm": "u",
    "V": "v",
    "Pa": "P",
    "Ohm": "w",
    "Watt": "W",
    "W.h": "X",
    "l/s": "y",
    "us": "Y",
    "Hz": "z",
    "instance": "#",
}
# multiplier ids: '-' none (text, instance), '0' × 1, 'F' × 10⁻⁶ (TimeUS)
_DF_MULTS = {"-": 0.0, "0": 1.0, "F": 1e-6}
# format character → (integer range or None for floats, scale), pymavlink's FORMAT_TO_STRUCT
_DF_NUMERIC = {
    "b": ((-(2**7), 2**7 - 1), 1.0),
    "B": ((0, 2**8 - 1), 1.0),
    "M": ((0, 2**7 - 1), 1.0),
    "h": ((-(2**15), 2**15 - 1), 1.0),
    "H": ((0, 2**16 - 1), 1.0),
    "i": ((-(2**31), 2**31 - 1), 1.0),
    "I": ((0, 2**32 - 1), 1.0),
    "q": ((-(2**63), 2**63 - 1), 1.0),
    "Q": ((0, 2**64 - 1), 1.0),
    "c": ((-(2**15), 2**15 - 1), 0.01),
    "C": ((0, 2**16 - 1), 0.01),
    "e": ((-(2**31), 2**31 - 1), 0.01),
    "E": ((0, 2**32 - 1), 0.01),
    "L": ((-(2**31), 2**31 - 1), 1e-7),
    "f": (None, 1.0),
    "d": (None, 1.0),
    "g": (None, 1.0),
}
_DF_SIZES = {"b": 1, "B": 1, "M": 1, "h": 2, "H": 2, "i": 4, "I": 4, "q": 8, "Q": 8}
_DF_SIZES.update({"c": 2, "C": 2, "e": 4, "E": 4, "L": 4, "f": 4, "d": 8, "g": 2})
_DF_SIZES.update({"n": 4, "N": 16, "Z": 64})
_DF_HEADER = 3  # 0xA3 0x95 and the type byte
_DF_META = (  # type id, name, format, columns of the messages that describe the others
    (128, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns"),
    (129, "UNIT", "QbZ", "TimeUS,Id,Label"),
    (130, "MULT", "Qbd", "TimeUS,Id,Mult"),
    (131, "FMTU", "QBNN", "TimeUS,FmtType,UnitIds,MultIds"),
    (132, "PARM", "QNf", "TimeUS,Name,Value"),
)


def _df_split(name: str) -> tuple[str, int | None]:
    """``"IMU[1]"`` → ("IMU", 1); ``"ATT"`` → ("ATT", None)."""
    match = re.fullmatch(r"([A-Z0-9]{1,4})(?:\[(\d+)\])?", name)
    if not match:
        raise LogWriteError(
            f"stream name {name!r}: expected a DataFlash message name of 1–4 capital "
            "letters or digits, with [k] for instance k"
        )
    return match.group(1), None if match.group(2) is None else int(match.group(2))


class _DataFlashType:
    """One message type: its fields, format characters, units and instances."""

    def __init__(self, type_id: int, name: str, fields: list[str], formats: str, units):
        self.type_id, self.name, self.fields, self.formats = type_id, name, fields, formats
        self.units = units  # {field: label}
        self.length = _DF_HEADER + sum(_DF_SIZES[c] for c in formats)


def _df_types(
    streams: Sequence[Stream],
    formats: Mapping[str, Mapping[str, str]],
    instance_field: str,
) -> dict[str, _DataFlashType]:
    """The message types of the streams (one per base name), checked for what a DataFlash
    FMT message can hold: ≤ 16 fields, columns ≤ 64 characters, format characters known."""
    kinds: dict[str, _DataFlashType] = {}
    for stream in streams:
        base, instance = _df_split(stream.name)
        fields = list(stream.fields)
        for field in fields:
            if not _IDENTIFIER.fullmatch(field) or field in ("TimeUS", instance_field):
                raise LogWriteError(
                    f"stream {stream.name!r}: field {field!r} is not a DataFlash column name "
                    f"(letters, digits, '_'; not TimeUS or {instance_field!r}, which the "
                    "writer adds)"
                )
        chars = "".join(formats.get(base, {}).get(f, "f") for f in fields)
        unknown = sorted(set(chars) - set(_DF_NUMERIC))
        if unknown:
            raise LogWriteError(
                f"stream {stream.name!r}: format characters {unknown} unknown or not "
                f"numeric; known: {''.join(sorted(_DF_NUMERIC))}"
            )
        columns = ["TimeUS", *([instance_field] if instance is not None else []), *fields]
        chars = "Q" + ("B" if instance is not None else "") + chars
        if len(chars) > 16 or len(",".join(columns)) > 64:
            raise LogWriteError(
                f"stream {stream.name!r}: a DataFlash message holds at most 16 fields "
                f"and 64 characters of column names; got {columns}"
            )
        if "Mode" in fields and "ModeNum" in fields:
            # pymavlink packs ModeNum into the Mode column: they must agree
            if not np.array_equal(stream.fields["Mode"], stream.fields["ModeNum"]):
                raise LogWriteError(f"stream {stream.name!r}: Mode and ModeNum must be equal")
        units = {f: str(stream.units.get(f, "")) for f in fields}
        kind = _DataFlashType(len(kinds) + 1, base, columns, chars, units)
        known = kinds.get(base)
        if known is not None and (known.fields, known.formats, known.units) != (
            kind.fields,
            kind.formats,
            kind.units,
        ):
            raise LogWriteError(
                f"stream {stream.name!r}: every instance of {base!r} must have the same "
                "fields, formats and units"
            )
        if known is None and len(kinds) >= 127:
            raise LogWriteError("a DataFlash log written here holds at most 127 message types")
        kinds.setdefault(base, kind)
    return kinds


def _df_unit_ids(kinds: Mapping[str, _DataFlashType]) -> dict[str, str]:
    """label → unit id: ArduPilot's ids where the label is theirs, else an unused one."""
    labels = {"s", "instance"}
    for kind in kinds.values():
        labels.update(kind.units.values())
    ids = {label: DATAFLASH_UNIT_IDS[label] for label in labels if label in DATAFLASH_UNIT_IDS}
    spare = [
        chr(c)
        for c in range(33, 127)
        if chr(c) not in DATAFLASH_UNIT_IDS.values() and chr(c) not in ",\\"
    ]
    for label in sorted(labels - set(ids)):
        if not spare or len(label.encode()) > 64 or not label.isascii():
            raise LogWriteError(f"unit {label!r}: cannot be written as a DataFlash UNIT label")
        ids[label] = spare.pop(0)
    return ids


def _df_column(stream: Stream, field: str, char: str) -> list:
    """The field's values as pymavlink packs them (the scaled value for 'c', 'L', …)."""
    values = np.asarray(stream.fields[field], dtype=float)
    limits, scale = _DF_NUMERIC[char]
    if limits is None:
        return values.tolist()
    where = f"stream {stream.name!r}, field {field!r} (format {char!r})"
    counts = _exact_integers(values, limits[0], limits[1], where, scale)
    if scale == 1.0:
        return counts.astype(np.int64).tolist()
    return (counts * scale).tolist()


def write_dataflash(
    path: str | Path,
    streams: Sequence[Stream],
    *,
    formats: Mapping[str, Mapping[str, str]] | None = None,
    parameters: Mapping[str, float] | None = None,
    instance_field: str = "I",
    overwrite: bool = False,
) -> Path:
    """Write ``streams`` as a binary ArduPilot DataFlash log (``.bin``; needs pymavlink:
    the ``ardupilot`` extra, whose message packer writes every message).

    Each stream is one message type (``"IMU[1]"``: instance 1 of ``IMU``, with the
    instance in column ``instance_field``), with ``TimeUS`` (µs, from ``time_s``) first.
    ``formats`` gives a field's DataFlash format character per type name
    (``{"RCOU": {"C1": "H"}, "ATT": {"Roll": "c"}}``; default ``f``, float32); integer and
    scaled characters must hold exact values (``c``: multiples of 0.01). The log
    describes itself as ArduPilot's does: FMT for every type, UNIT and MULT tables and an
    FMTU per type giving each field's unit (``Stream.units``; ArduPilot's unit ids for
    its labels, e.g. ``d`` deg, ``E`` rad/s, ``Y`` us). ``parameters`` are written as PARM
    messages at time 0. Messages are written in time order. An existing file is replaced
    only with ``overwrite``. Returns the path.
    """
    dfreader = _require("pymavlink.DFReader", "ardupilot", f"writing the DataFlash log {path}")
    kinds = _df_types(streams, formats or {}, instance_field)
    unit_ids = _df_unit_ids(kinds)
    meta = {name: dfreader.DFFormat(t, name, 0, f, c) for t, name, f, c in _DF_META}

    def pack(fmt: Any, elements: list) -> bytes:
        buffer = dfreader.DFMessage(fmt, elements, False, None).get_msgbuf()
        if buffer is None:  # pymavlink answers None when struct.pack fails
            raise LogWriteError(f"{fmt.name}: values {elements!r} do not fit {fmt.format!r}")
        return buffer

    out = bytearray()
    described = [(t, n, f, c) for t, n, f, c in _DF_META]
    described += [(k.type_id, k.name, k.formats, ",".join(k.fields)) for k in kinds.values()]
    for type_id, name, chars, columns in described:
        length = _DF_HEADER + sum(_DF_SIZES[c] for c in chars)
        out += pack(meta["FMT"], [type_id, length, name, chars, columns])
    for label, ident in sorted(unit_ids.items(), key=lambda item: item[1]):
        out += pack(meta["UNIT"], [0, ord(ident), label])
    for ident, mult in _DF_MULTS.items():
        out += pack(meta["MULT"], [0, ord(ident), mult])
    for kind in kinds.values():
        instance = kind.fields[1] == instance_field
        unit_text = "s" + ("#" if instance else "")
        unit_text += "".join(unit_ids[kind.units[f]] for f in kind.fields[1 + instance :])
        mult_text = "F" + ("-" if instance else "")
        mult_text += "".join("0" if kind.units[f] else "-" for f in kind.fields[1 + instance :])
        out += pack(meta["FMTU"], [0, kind.type_id, unit_text, mult_text])
    for name, value in (parameters or {}).items():
        if not (isinstance(name, str) and 0 < len(name) <= 16 and name.isascii()):
            raise LogWriteError(f"parameter name {name!r}: expected 1–16 ASCII characters")
        out += pack(meta["PARM"], [0, name, float(value)])
    out += _df_data(dfreader, streams, kinds, pack)
    path = _target(path, overwrite)
    path.write_bytes(bytes(out))
    return path


def _df_data(dfreader: Any, streams: Sequence[Stream], kinds, pack) -> bytes:
    """The data messages of every stream, in time order (stable: the streams' order at
    equal stamps)."""
    rows: list[tuple[int, int, int, list]] = []
    for order, stream in enumerate(streams):
        stamps = _stamps_us(stream)
        base, instance = _df_split(stream.name)
        kind = kinds[base]
        fmt = dfreader.DFFormat(
            kind.type_id, kind.name, kind.length, kind.formats, ",".join(kind.fields)
        )
        offset = 1 + (instance is not None)
        columns = [
            _df_column(stream, field, char)
            for field, char in zip(kind.fields[offset:], kind.formats[offset:], strict=True)
        ]
        prefix = [] if instance is None else [instance]
        for k, stamp in enumerate(stamps.tolist()):
            elements = [stamp, *prefix, *(column[k] for column in columns)]
            rows.append((stamp, order, k, [fmt, elements]))
    rows.sort(key=lambda row: row[:3])
    return b"".join(pack(*row[3]) for row in rows)
