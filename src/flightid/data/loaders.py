"""Loaders: flight-data files and tables into ``FlightData``, with declared channel mapping.

Two steps, each checked:

1. ``read_table(path)`` reads a file into a ``Table`` — a numeric matrix (samples × columns)
   with optional column names and units. Formats: CSV with a header row, whitespace ASCII
   with or without header lines (the names line and an optional units line above the
   numbers, as in the FVSysID ``_withHeader`` files), MATLAB ``.mat`` (SIDPAC's ``fdata``
   matrix with ``varlab`` labels, a single plain matrix, a chosen variable, or a set of
   equal-length vectors), and pandas DataFrames (``table_from_dataframe``). With optional
   extras (``flightid.data.formats``): Parquet, MATLAB v7.3 (HDF5) ``.mat``, PX4 ULog and
   ArduPilot DataFlash logs.
2. ``to_flight_data(table, time=..., inputs=..., outputs=...)`` builds the ``FlightData``
   from channel specifications. A specification is a column (1-based number or name) or an
   expression, with an optional scale, offset and unit conversion::

       {"column": 13, "unit": "deg", "to": "rad"}
       {"expr": "($29 - $28) / 2", "unit": "deg", "to": "rad"}     # δa = (right − left)/2
       {"column": "alpha", "subtract": "first"}                     # Δα about the first sample

   value = (source · scale + offset) · unit factor, then ``subtract`` ("first" or "mean")
   removes a reference value. The unit factor follows the one channel rule of
   ``flightid.data.units.channel_conversion``: with ``unit`` and ``to`` the values are
   converted to ``to``; with ``unit`` alone they are delivered in SI with angles in radians
   (deg → rad, deg/s → rad/s, ft/s → m/s, g → m/s², ...); an unknown unit is refused.
   A unit the file states for a column (``Table.units``: CSV header brackets, ``varlab``,
   DataFlash FMTU, Parquet/HDF5 metadata) is the source unit of a channel that declares
   none, and a declared unit that contradicts it is a ``FileUnitError``
   (``ChannelSpec.with_file_unit``; ``ignore_file_unit`` overrides).

Before reading, ``read_table`` refuses paths that are not regular files and files larger
than the available memory; text files may start with a byte-order mark; numbers are ASCII
(``1_000`` is refused, naming row and column); two columns of one name are refused when a
channel names them.

Expressions are arithmetic (+ − × ÷, parentheses, numbers) over column references ``$N``
(1-based column number) and column names, with the functions sin, cos, tan, asin, acos, atan,
atan2(y, x), sqrt, exp, log (natural), abs, the constant ``pi`` and the time variable ``t``
(the time channel in s, as read); they are parsed here, never passed to ``eval``. A value
outside a function's domain (sqrt of a negative, log of 0, asin of 1.5, ...) is a
``ChannelError`` naming the channel and the first row where it happens.

Names in expressions and ``column`` may also be named constants and intermediate signals
(``[data.constants]``, ``[data.signals]``, ``[[data.steps]]``; ``flightid.data.pipeline``):
``to_flight_data(..., constants=, signals=, steps=)`` computes them per maneuver before the
channels, and they are looked up before the file's columns (``$N`` is always column N).
"""

from __future__ import annotations

import codecs
import csv
import dataclasses
import math
import os
import re
import stat
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from flightid.data.flightdata import FlightData
from flightid.data.preprocess import apply_steps, parse_derivative, parse_smooth
from flightid.data.signals import (
    BUILTIN_SIGNALS,
    builtin_signal,
    quaternion_pitch,
    quaternion_roll,
    quaternion_yaw,
)
from flightid.data.timebase import (
    HALF_INTERVAL,
    TimeBaseError,
    join_recordings,
    largest_move,
    regrid,
)
from flightid.data.units import channel_conversion, parse_unit, same_unit
from flightid.errors import InputError, InputTypeError, describe

__all__ = [
    "DataFileError",
    "ChannelError",
    "FileUnitError",
    "FileTooLargeError",
    "ChannelSpec",
    "Table",
    "TableStream",
    "read_table",
    "table_from_dataframe",
    "to_flight_data",
    "to_flight_segments",
    "load_flight_data",
    "load_flight_segments",
    "TimeBaseError",
    "parse_expression",
]


class DataFileError(InputError):
    """A data file that is missing, unreadable or not a numeric table."""


class ChannelError(InputError):
    """A channel specification naming an unknown column or malformed expression."""


class FileUnitError(ChannelError):
    """A channel's declared unit contradicts the unit its file states for the column, or the
    file states a unit flightid cannot read for a channel that declares none. The message
    names both units and the key that settles it (``ignore_file_unit = true``)."""


class FileTooLargeError(DataFileError):
    """A data file that would not fit in the memory available to read it."""


# =====================================================================================
# Table
# =====================================================================================


@dataclass(frozen=True)
class TableStream:
    """Columns of a ``Table`` sampled together, on their own time base (a flight-log
    message stream): ``rows`` (0-based row numbers where the stream has a sample) and
    ``columns`` (0-based column numbers it fills; NaN on the other rows)."""

    name: str
    rows: np.ndarray
    columns: tuple[int, ...]


@dataclass(frozen=True, eq=False)
class Table:
    """A numeric table read from a file.

    Attributes:
        data: (N, k) float matrix.
        names: column names (``""`` where the file gives none).
        units: column units as written in the file (``""`` where unknown).
        source: where it came from (path or description), for messages.
        constants: scalar values stored beside the table (e.g. ``sarea`` in SIDPAC files).
        streams: for a log whose streams have different time bases: the streams (the rows
            are the union of their time stamps; a column is NaN where its stream has no
            sample). Empty: every column is sampled at every row.
        left_out: names in the file that are not columns, with the reason (a MATLAB struct
            field of another length), for the message when a channel names one.
    """

    data: np.ndarray
    names: tuple[str, ...]
    units: tuple[str, ...]
    source: str = ""
    constants: Mapping[str, float] = field(default_factory=dict)
    streams: tuple[TableStream, ...] = ()
    left_out: Mapping[str, str] = field(default_factory=dict)

    @property
    def n_rows(self) -> int:
        return int(self.data.shape[0])

    @property
    def n_columns(self) -> int:
        return int(self.data.shape[1])

    def column_index(self, key: int | str, where: str = "column") -> int:
        """0-based index of a column given as a 1-based number or a name."""
        if isinstance(key, bool) or not isinstance(key, (int, str)):
            raise ChannelError(
                f"{where}: expected a 1-based column number or a column name, got {describe(key)}"
            )
        if isinstance(key, int):
            if not 1 <= key <= self.n_columns:
                raise ChannelError(
                    f"{where}: column {key} does not exist; {self.source or 'the table'} has "
                    f"columns 1..{self.n_columns}"
                )
            return key - 1
        exact = [i for i, n in enumerate(self.names) if n == key]
        folded = [i for i, n in enumerate(self.names) if n.lower() == key.lower()]
        matches = exact or folded
        if len(matches) == 1:
            return matches[0]
        if len(matches) > 1:
            raise ChannelError(
                f"{where}: {self.source or 'the table'} has {len(matches)} columns named "
                f"{key!r}{'' if exact else ' (case ignored)'}: columns "
                f"{[i + 1 for i in matches]} ({[self.names[i] for i in matches]}); "
                "name one by its number (column = N, or $N in an expression)"
            )
        if key in self.left_out:
            raise ChannelError(
                f"{where}: {key!r} in {self.source or 'the table'} is not a column: "
                f"{self.left_out[key]}"
            )
        known = [n for n in self.names if n]
        raise ChannelError(
            f"{where}: no column named {key!r} in {self.source or 'the table'}; "
            + (f"columns: {known}" if known else "the file has no column names (use numbers)")
        )

    def column(self, key: int | str, where: str = "column") -> np.ndarray:
        return self.data[:, self.column_index(key, where)]


def _finish_table(
    data: np.ndarray, names, units, source: str, constants=None, left_out=None
) -> Table:
    data = np.asarray(data, dtype=float)
    if data.ndim == 1:
        data = data[:, None]
    if data.ndim != 2 or data.shape[0] < 2 or data.shape[1] < 1:
        raise DataFileError(f"{source}: expected a table of at least 2 rows, got {describe(data)}")
    k = data.shape[1]
    names = tuple(str(n).strip() for n in (names or [""] * k))
    units = tuple(str(u).strip() for u in (units or [""] * k))
    if len(names) != k or len(units) != k:
        raise DataFileError(
            f"{source}: {k} data columns but {len(names)} names and {len(units)} units"
        )
    data = np.ascontiguousarray(data)
    data.flags.writeable = False
    return Table(data, names, units, source, dict(constants or {}), left_out=dict(left_out or {}))


# =====================================================================================
# Text formats
# =====================================================================================


def _number(token: str) -> float | None:
    """A number as data files write it (ASCII digits, decimal point, exponent ``e``/``E`` or
    Fortran's ``d``/``D``, ``nan``/``inf``), else None. Python's ``float`` also takes ``1_000``
    and non-ASCII digits; a data file with those has a typing or export error, so they are
    refused."""
    if "_" in token or not token.isascii():
        return None
    try:
        return float(token.replace("D", "E").replace("d", "e"))
    except ValueError:
        return None


def _numbers(tokens: Sequence[str]) -> list[float] | None:
    values = []
    for token in tokens:
        value = _number(token)
        if value is None:
            return None
        values.append(value)
    return values


def _first_non_number(tokens: Sequence[str]) -> int:
    """0-based position of the first token that is not a number (``_number``)."""
    return next(k for k, token in enumerate(tokens) if _number(token) is None)


# byte-order marks at the start of a text file → the encoding they announce
_BOMS = (
    (codecs.BOM_UTF8, "utf-8-sig"),
    (codecs.BOM_UTF16_LE, "utf-16"),
    (codecs.BOM_UTF16_BE, "utf-16"),
)


def _read_text(path: Path, format: str) -> list[str]:
    """The lines of a text file: UTF-8, or the encoding its byte-order mark announces (the
    mark itself is dropped: Excel writes one before the first column name). ``format``
    ("csv" or "ascii") sizes the memory check (``check_data_file``)."""
    check_data_file(path, format)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise DataFileError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
    encoding = next((name for bom, name in _BOMS if raw.startswith(bom)), "utf-8")
    return raw.decode(encoding, errors="replace").splitlines()


# memory needed to read a file, as a multiple of its size: measured peaks for the text
# readers, which hold every line, cell and number as Python objects (15× for a CSV, 7× for
# whitespace ASCII of 8 columns of "%.6f" numbers); a lower bound for the others
_MEMORY_PER_FILE_BYTE = {
    "csv": 16.0,
    "ascii": 8.0,
    "mat": 2.0,
    "parquet": 3.0,
    "ulog": 2.0,
    "dataflash": 1.0,
}


def available_memory_bytes() -> int | None:
    """Memory available to this process now (bytes): Linux ``MemAvailable`` (with the
    cgroup limit where one is set), else the free physical pages; None where unknown."""
    available = None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                available = int(line.split()[1]) * 1024  # kB → bytes
    except (OSError, ValueError, IndexError):
        available = None
    if available is None:
        try:
            available = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (OSError, ValueError, AttributeError):
            return None
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        used = Path("/sys/fs/cgroup/memory.current").read_text().strip()
        if limit.isdigit() and used.isdigit():
            available = min(available, int(limit) - int(used))
    except OSError:
        pass
    return max(int(available), 0)


def check_data_file(path: Path, format: str) -> None:
    """Refuse, before reading, a path that is not a regular file (a directory, a fifo, a
    device such as ``/dev/zero``: reading those hangs or never ends) and a file that would
    not fit in the available memory (``FileTooLargeError``)."""
    try:
        status = path.stat()
    except FileNotFoundError:
        raise DataFileError(f"{path}: no such file") from None
    except OSError as exc:
        raise DataFileError(f"{path}: cannot read the file ({exc.strerror or exc})") from None
    if not stat.S_ISREG(status.st_mode):
        kind = (
            "a directory"
            if stat.S_ISDIR(status.st_mode)
            else "a fifo (named pipe)"
            if stat.S_ISFIFO(status.st_mode)
            else "a device"
            if stat.S_ISCHR(status.st_mode) or stat.S_ISBLK(status.st_mode)
            else "a socket"
            if stat.S_ISSOCK(status.st_mode)
            else "not a regular file"
        )
        raise DataFileError(f"{path}: is {kind}, expected a regular data file")
    available = available_memory_bytes()
    # memory needed ≈ file size × bytes held per file byte (format-dependent)
    needed = status.st_size * _MEMORY_PER_FILE_BYTE.get(format, 1.0)
    if available is not None and needed > available:
        raise FileTooLargeError(
            f"{path}: {_size(status.st_size)} of {format} data needs about {_size(needed)} of "
            f"memory to read, {_size(available)} is available; cut the file to the part you "
            "need, or read it on a machine with more memory"
        )


def _size(n_bytes: float) -> str:
    """A byte count for messages: ``"1.5 GB"``."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n_bytes >= scale:
            return f"{n_bytes / scale:.3g} {unit}"
    return f"{int(n_bytes)} bytes"


def read_ascii(path: str | Path) -> Table:
    """Whitespace-separated numbers, optionally below header lines.

    The data block is the longest run of lines that all parse as numbers with the same count.
    Above it, the last two text lines with that many tokens are read as names and units
    (a single such line: names only), as in the FVSysID ``_withHeader`` files.
    """
    path = Path(path)
    lines = _read_text(path, "ascii")
    rows: list[list[float]] = []
    first = None
    for number, line in enumerate(lines):
        tokens = line.split()
        if not tokens:
            continue
        values = _numbers(tokens)
        if values is None:
            if rows:
                k = _first_non_number(tokens)
                raise DataFileError(
                    f"{path}: line {number + 1} is not numeric inside the data block: "
                    f"column {k + 1}, {tokens[k][:30]!r} is not a number ({line.strip()[:60]!r})"
                )
            continue
        if rows and len(values) != len(rows[0]):
            raise DataFileError(
                f"{path}: line {number + 1} has {len(values)} numbers, the lines above have "
                f"{len(rows[0])}"
            )
        if first is None:
            first = number
        rows.append(values)
    if not rows:
        raise DataFileError(f"{path}: no numeric rows found (whitespace-separated ASCII expected)")
    k = len(rows[0])
    header = [ln.split() for ln in lines[: first or 0] if len(ln.split()) == k]
    names = header[-2] if len(header) >= 2 else (header[-1] if header else None)
    units = header[-1] if len(header) >= 2 else None
    return _finish_table(np.array(rows), names, units, str(path))


# a header "name [unit]" or "name (unit)": group 1 the name, group 2 the unit
_CSV_UNIT = re.compile(r"(.*?)\s*[\[(]([^\])]*)[\])]\s*")


def read_csv(path: str | Path, delimiter: str | None = None) -> Table:
    """CSV with one header row of column names (units in brackets are split off:
    ``alpha [deg]`` or ``alpha (deg)``). The delimiter is sniffed unless given."""
    path = Path(path)
    lines = _read_text(path, "csv")
    lines = [ln for ln in lines if ln.strip() and not ln.lstrip().startswith("#")]
    if len(lines) < 3:
        raise DataFileError(f"{path}: expected a header row and at least 2 data rows")
    if delimiter is None:
        try:
            delimiter = csv.Sniffer().sniff(lines[0] + "\n" + lines[1], ",;\t").delimiter
        except csv.Error:
            delimiter = ","
    reader = list(csv.reader(lines, delimiter=delimiter))
    header = [h.strip() for h in reader[0]]
    if _numbers(header) is not None:
        raise DataFileError(f"{path}: the first row must be the header of column names")
    names, units = [], []
    for h in header:
        m = _CSV_UNIT.fullmatch(h)
        names.append(m.group(1) if m else h)
        units.append(m.group(2) if m else "")
    rows = []
    for number, row in enumerate(reader[1:], start=2):
        if len(row) != len(header):
            raise DataFileError(
                f"{path}: row {number} has {len(row)} fields, the header has {len(header)}"
            )
        cells = [c.strip() or "nan" for c in row]
        values = _numbers(cells)
        if values is None:
            k = _first_non_number(cells)
            raise DataFileError(
                f"{path}: row {number} is not numeric: column {k + 1} "
                f"({names[k] or 'unnamed'!r}), {cells[k][:30]!r} is not a number ({row[:6]})"
            )
        rows.append(values)
    return _finish_table(np.array(rows), names, units, str(path))


# =====================================================================================
# MATLAB
# =====================================================================================

_VARLAB = re.compile(r"^\s*\*?\s*(?P<name>.*?)\s*(?:\((?P<unit>[^)]*)\))?\s*$")


def read_mat(path: str | Path, variable: str | None = None) -> Table:
    """MATLAB .mat (v5 via ``scipy.io.loadmat``; v7.3, an HDF5 file, via
    ``flightid.data.formats.read_mat73``, which needs the ``hdf5`` extra).

    * ``variable`` given: that matrix (or vector); or a struct (``"ail_1"``, a nested one
      ``"flight.ail_1"``), whose numeric fields are the columns by name — nested structs
      flattened with dots (``IMU.GyrX``), an N × k field as ``name_1`` … ``name_k``, scalar
      fields as ``Table.constants`` (``struct_table``).
    * SIDPAC layout: ``fdata`` (N × k) with ``varlab`` labels like ``"* alpha (deg)"``.
    * one 2-D matrix in the file: that matrix (columns unnamed).
    * otherwise: all column vectors of the most common length, as named columns.
    Scalars in the file are kept as ``Table.constants``.
    """
    from scipy.io import loadmat

    path = Path(path)
    check_data_file(path, "mat")
    from flightid.data.formats import is_mat73, read_mat73

    if is_mat73(path):
        return read_mat73(path, variable)
    try:
        contents = loadmat(str(path))
    except Exception as exc:  # scipy raises several types for bad files
        raise DataFileError(f"{path}: not a readable MATLAB file ({exc})") from None
    structs = {
        k: v
        for k, v in contents.items()
        if not k.startswith("__") and isinstance(v, np.ndarray) and v.dtype.names
    }
    if variable is not None and variable.split(".")[0] in structs:
        return struct_table(path, variable, _v5_struct(path, structs, variable))
    arrays = {
        k: v
        for k, v in contents.items()
        if not k.startswith("__") and isinstance(v, np.ndarray) and v.dtype.kind in "fiub"
    }
    return _mat_table(path, arrays, contents.get("varlab"), variable, sorted(structs))


def _v5_struct(path: Path, structs: Mapping[str, np.ndarray], variable: str) -> dict:
    """The fields of the struct ``variable`` ("a" or "a.b.c") of a v5 file, flattened
    (``_v5_fields``); a numeric leaf ("a.x") as the one field ``x``."""
    parts = variable.split(".")
    value = structs[parts[0]]
    for depth, part in enumerate(parts[1:], start=1):
        here = ".".join(parts[:depth])
        if value.size != 1:
            raise DataFileError(f"{path}: {here!r} is a {_shape(value)} struct array; {_ONE}")
        if part not in value.dtype.names:
            raise DataFileError(
                f"{path}: the struct {here!r} has no field {part!r}; fields: "
                f"{list(value.dtype.names)}"
            )
        value = value.ravel()[0][part]
    if isinstance(value, np.ndarray) and value.dtype.names:
        return _v5_fields(path, value, variable)
    if isinstance(value, np.ndarray) and value.dtype.kind in "fiub":
        return {parts[-1]: value}
    raise DataFileError(f"{path}: {variable!r} is neither a struct nor numeric")


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


# =====================================================================================
# pandas
# =====================================================================================


def table_from_dataframe(frame: Any, source: str = "DataFrame") -> Table:
    """A ``Table`` from a pandas DataFrame (numeric columns; names from the column labels)."""
    try:
        import pandas as pd
    except ImportError:  # pragma: no cover - pandas is optional
        raise InputTypeError(
            "frame: pandas is not installed; install it to read DataFrames"
        ) from None
    if not isinstance(frame, pd.DataFrame):
        raise InputTypeError(f"frame: expected a pandas DataFrame, got {describe(frame)}")
    try:
        data = frame.to_numpy(dtype=float)
    except (TypeError, ValueError):
        raise DataFileError(f"{source}: all columns must be numeric") from None
    return _finish_table(data, [str(c) for c in frame.columns], None, source)


# =====================================================================================
# dispatch
# =====================================================================================

FORMATS = ("auto", "csv", "ascii", "mat", "parquet", "ulog", "dataflash")

# file extension → format for format = "auto" (anything else: whitespace ASCII)
_SUFFIX_FORMATS = {
    ".csv": "csv",
    ".mat": "mat",
    ".parquet": "parquet",
    ".pq": "parquet",
    ".ulg": "ulog",
    ".bin": "dataflash",
}


def read_table(
    path: str | Path,
    format: str = "auto",
    *,
    variable: str | None = None,
    delimiter: str | None = None,
) -> Table:
    """Read a data file into a ``Table``; ``format`` "auto" picks by extension
    (.csv → csv, .mat → mat (v5, or v7.3 with the ``hdf5`` extra), .parquet/.pq → parquet
    (the ``parquet`` extra), .ulg → ulog (PX4; the ``px4`` extra), .bin → dataflash
    (ArduPilot; the ``ardupilot`` extra), anything else → whitespace ASCII). ``variable``
    picks a MATLAB variable or struct, or the message streams of a flight log.

    Before reading, a path that is not a regular file (directory, fifo, device) is refused,
    and so is a file that would not fit in the available memory (``FileTooLargeError``)."""
    if format not in FORMATS:
        raise InputError(f"format: expected one of {list(FORMATS)}, got {format!r}")
    path = Path(path)
    if format == "auto":
        suffix = path.suffix.lower()
        format = _SUFFIX_FORMATS.get(suffix, "ascii")
    check_data_file(path, format)
    try:
        return _read_format(path, format, variable, delimiter)
    except MemoryError:
        raise FileTooLargeError(
            f"{path}: ran out of memory while reading it ({_size(path.stat().st_size)} of "
            f"{format} data); cut the file to the part you need"
        ) from None


def _read_format(path: Path, format: str, variable: str | None, delimiter: str | None) -> Table:
    if format == "parquet":
        from flightid.data.formats import read_parquet

        return read_parquet(path)
    if format == "ulog":
        from flightid.data.formats import read_ulog

        return read_ulog(path, variable)
    if format == "dataflash":
        from flightid.data.formats import read_dataflash

        return read_dataflash(path, variable)
    if format == "csv":
        return read_csv(path, delimiter)
    if format == "mat":
        return read_mat(path, variable)
    return read_ascii(path)


# =====================================================================================
# expressions over columns (no eval)
# =====================================================================================

# a name starts with a letter of any script (α_rec, as reconstructed-signal files name their
# columns) or _, and goes on with letters, digits, _ and dots (flight-log stream.field)
_EXPR_TOKEN = re.compile(
    r"\s*(?:(?P<number>\d+\.?\d*(?:[eE][-+]?\d+)?|\.\d+(?:[eE][-+]?\d+)?)"
    r"|(?P<column>\$\d+)|(?P<name>[^\W\d][\w.]*)|(?P<op>[-+*/(),]))"
)


def _tokens(text: str) -> list[tuple[str, str, int]]:
    tokens = []
    position = 0
    text = text.rstrip()
    while position < len(text):
        m = _EXPR_TOKEN.match(text, position)
        if not m or m.end() == position:
            raise ChannelError(
                f"expression {text!r}: unexpected character {text[position:].strip()[:1]!r} at "
                f"position {position}"
            )
        kind = m.lastgroup
        tokens.append((kind, m.group(kind), m.start(kind)))
        position = m.end()
    return tokens


# nesting of parentheses, signs and operations in an expression at most (deeper ones are
# refused: parsing and evaluating recurse once per level)
MAX_EXPRESSION_DEPTH = 100


@dataclass(frozen=True)
class _Function:
    """A whitelisted function: argument count, the numpy function, and its domain (the mask
    of arguments it refuses, with the words for the error), or None where every finite
    argument is allowed (overflow to ±inf is caught after evaluation)."""

    n_args: int
    apply: Any
    refuses: Any = None
    domain: str = ""


_FUNCTIONS = {
    "sin": _Function(1, np.sin),
    "cos": _Function(1, np.cos),
    "tan": _Function(1, np.tan),
    # asin, acos: defined on −1 ≤ x ≤ 1
    "asin": _Function(1, np.arcsin, lambda x: np.abs(x) > 1, "−1 ≤ x ≤ 1"),
    "acos": _Function(1, np.arccos, lambda x: np.abs(x) > 1, "−1 ≤ x ≤ 1"),
    "atan": _Function(1, np.arctan),
    # atan2(y, x): the angle of (x, y) in (−π, π]; atan2(0, 0) = 0 as in numpy
    "atan2": _Function(2, np.arctan2),
    # sqrt: x ≥ 0
    "sqrt": _Function(1, np.sqrt, lambda x: x < 0, "x ≥ 0"),
    "exp": _Function(1, np.exp),
    # log (natural): x > 0
    "log": _Function(1, np.log, lambda x: x <= 0, "x > 0"),
    "abs": _Function(1, np.abs),
    # ZYX Euler angles (rad) of a Hamilton quaternion (w, x, y, z), flightid.data.signals
    "quat_roll": _Function(4, quaternion_roll),
    "quat_pitch": _Function(4, quaternion_pitch),
    "quat_yaw": _Function(4, quaternion_yaw),
}


class _Parser:
    """Recursive-descent parser: expr := term (±term)*, term := unary (×÷ unary)*,
    unary := −unary | atom, atom := NUMBER | $N | NAME | NAME ( expr {, expr} ) | ( expr ).
    Builds a tree of tuples; NAME ( ... ) must be a whitelisted function with its argument
    count, ``pi`` is the constant and ``t`` the time variable."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.tokens = _tokens(text)
        self.i = 0
        self.nesting = 0  # open parentheses and unary signs, limited by MAX_EXPRESSION_DEPTH

    def nest(self, parse):
        self.nesting += 1
        if self.nesting > MAX_EXPRESSION_DEPTH:
            raise ChannelError(
                f"expression {self.text[:40]!r}...: nested deeper than {MAX_EXPRESSION_DEPTH} "
                "levels (parentheses and signs); simplify it"
            )
        tree = parse()
        self.nesting -= 1
        return tree

    def peek(self):
        return self.tokens[self.i] if self.i < len(self.tokens) else (None, None, len(self.text))

    def take(self):
        token = self.peek()
        self.i += 1
        return token

    def fail(self, what: str):
        _, value, position = self.peek()
        got = "the end" if value is None else repr(value)
        raise ChannelError(
            f"expression {self.text!r}: expected {what} at position {position}, got {got}"
        )

    def parse(self):
        if not self.tokens:
            raise ChannelError("expression: empty")
        tree = self.expr()
        if self.i != len(self.tokens):
            self.fail("an operator or the end")
        # chains such as a+a+...+a nest without recursion here, but evaluating them recurses
        if _depth(tree) > MAX_EXPRESSION_DEPTH:
            raise ChannelError(
                f"expression {self.text[:40]!r}...: more than {MAX_EXPRESSION_DEPTH} nested "
                "operations; simplify it"
            )
        return tree

    def expr(self):
        tree = self.term()
        while self.peek()[1] in ("+", "-"):
            op = self.take()[1]
            tree = (op, tree, self.term())
        return tree

    def term(self):
        tree = self.unary()
        while self.peek()[1] in ("*", "/"):
            op = self.take()[1]
            tree = (op, tree, self.unary())
        return tree

    def unary(self):
        if self.peek()[1] in ("-", "+"):
            op = self.take()[1]
            operand = self.nest(self.unary)
            return ("neg", operand) if op == "-" else operand
        return self.atom()

    def atom(self):
        kind, value, _ = self.peek()
        if kind == "number":
            self.take()
            if not np.isfinite(float(value)):
                self.i -= 1
                self.fail("a finite number")
            return ("num", float(value))
        if kind == "column":
            self.take()
            return ("col", int(value[1:]))
        if kind == "name":
            position = self.take()[2]
            if self.peek()[1] == "(":
                return self.call(value, position)
            if value == "pi":
                return ("num", math.pi)
            if value == "t":
                return ("time",)
            return ("col", value)
        if value == "(":
            self.take()
            tree = self.nest(self.expr)
            if self.peek()[1] != ")":
                self.fail("')'")
            self.take()
            return tree
        self.fail("a number, a column ($N or a name) or '('")

    def call(self, name: str, position: int):
        """NAME ( expr {, expr} ): a whitelisted function with its number of arguments."""
        function = _FUNCTIONS.get(name)
        if function is None:
            raise ChannelError(
                f"expression {self.text!r}: unknown function {name!r} at position {position}; "
                f"known: {', '.join(sorted(_FUNCTIONS))}"
            )
        self.take()  # '('
        args = []
        if self.peek()[1] != ")":
            args.append(self.nest(self.expr))
            while self.peek()[1] == ",":
                self.take()
                args.append(self.nest(self.expr))
        if self.peek()[1] != ")":
            self.fail("',' or ')'")
        self.take()
        if len(args) != function.n_args:
            raise ChannelError(
                f"expression {self.text!r}: {name}() takes {function.n_args} argument(s), "
                f"got {len(args)} (at position {position})"
            )
        return ("call", name, *args)


def _depth(tree: tuple) -> int:
    """Depth of an expression tree (iterative: the tree may be deep)."""
    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        if node[0] == "call":
            stack.extend((child, depth + 1) for child in node[2:])
        elif node[0] not in ("num", "col", "time"):
            stack.extend((child, depth + 1) for child in node[1:])
    return deepest


def parse_expression(text: str) -> tuple:
    """Parse an arithmetic expression over columns into a tree (see module docstring)."""
    if not isinstance(text, str):
        raise ChannelError(f"expression: expected a string, got {describe(text)}")
    return _Parser(text).parse()


def _lookup(name: int | str, table: Table, where: str, names: Mapping[str, Any] | None):
    """A name's values: a signal or constant of ``names`` (signals: arrays over all rows),
    else the table's column (``$N`` is always the column), else a built-in log signal
    (``px4.roll``, ... of ``flightid.data.signals``, from the table's columns)."""
    if names and isinstance(name, str) and name in names:
        return names[name]
    try:
        return table.column(name, where)
    except ChannelError as exc:
        if isinstance(name, str) and name in BUILTIN_SIGNALS and name not in table.names:
            return _builtin(name, table, where)
        if not names or not isinstance(name, str):
            raise
        raise ChannelError(f"{exc}; nor a signal or constant (known: {sorted(names)})") from None


def _builtin(name: str, table: Table, where: str) -> np.ndarray:
    """A built-in log signal from the table's columns, or a ``ChannelError`` naming the
    columns (streams) it needs."""
    try:
        values, _ = builtin_signal(name, table.names.__contains__, table.column)
    except KeyError as exc:
        raise ChannelError(
            f"{where}: the built-in signal {name!r} needs the columns {exc.args[0]}; "
            f"read those streams (variable = ...) — {table.source or 'the table'} has "
            f"{[n for n in table.names if n][:12]}"
        ) from None
    return values


def _evaluate(
    tree: tuple,
    table: Table,
    where: str,
    time: np.ndarray | None = None,
    problems: list | None = None,
    names: Mapping[str, Any] | None = None,
) -> np.ndarray | float:
    """Values of an expression tree over the table's rows. ``time``: the values of ``t`` (s)
    (None: ``t`` is the column named t, as inside the time channel itself). ``names``:
    signals (arrays over all rows) and constants (numbers) looked up before the columns.
    Arguments outside a function's domain are recorded in ``problems`` as (words, mask,
    argument) and give NaN there; the caller reports the first such row it keeps."""
    kind = tree[0]
    if kind == "num":
        return tree[1]
    if kind == "col":
        return _lookup(tree[1], table, where, names)
    if kind == "time":
        return table.column("t", where) if time is None else time
    if kind == "neg":
        return -_evaluate(tree[1], table, where, time, problems, names)
    if kind == "call":
        function = _FUNCTIONS[tree[1]]
        args = [_evaluate(sub, table, where, time, problems, names) for sub in tree[2:]]
        if function.refuses is not None:
            refused = function.refuses(np.asarray(args[0], dtype=float))
            if np.any(refused) and problems is not None:
                problems.append((f"{tree[1]}() needs {function.domain}", refused, args[0]))
        with np.errstate(all="ignore"):
            return function.apply(*args)
    left = _evaluate(tree[1], table, where, time, problems, names)
    right = _evaluate(tree[2], table, where, time, problems, names)
    if kind == "+":
        return left + right
    if kind == "-":
        return left - right
    if kind == "*":
        return left * right
    with np.errstate(divide="ignore", invalid="ignore"):
        return left / right


def expression_columns(tree: tuple) -> list:
    """Column references used by an expression tree."""
    if tree[0] == "col":
        return [tree[1]]
    if tree[0] in ("num", "time"):
        return []
    children = tree[2:] if tree[0] == "call" else tree[1:]
    return [c for sub in children for c in expression_columns(sub)]


# =====================================================================================
# channel specifications
# =====================================================================================

_SPEC_KEYS = {
    "column",
    "expr",
    "scale",
    "offset",
    "unit",
    "to",
    "ignore_file_unit",
    "subtract",
    "smooth",
    "derivative",
}

# unit labels with which files say "no unit" (dimensionless counts, unknown): not a unit
_NO_UNIT_LABELS = {"", "-", "--", "none", "n/a", "unknown", "instance", "satellites"}


def stated_unit(label: str) -> str:
    """The unit a file's label states ("" where the label says there is none: ``-``,
    ``UNKNOWN``, ArduPilot's ``instance`` and ``satellites``)."""
    label = label.strip()
    return "" if label.lower() in _NO_UNIT_LABELS else label


def _linear_in_columns(tree: tuple, names: Mapping[str, Any]) -> bool:
    """True when an expression is a sum of column terms, each times or divided by numbers
    or scalar constants (``($29 - $28) / 2``, ``-q``, ``2 * p``): its result then has the
    unit of its columns. Functions, ``t``, signals and products of columns are not."""
    kind = tree[0]
    if kind == "col":
        return not (isinstance(tree[1], str) and tree[1] in names)
    if kind == "neg":
        return _linear_in_columns(tree[1], names)
    if kind in ("+", "-"):
        return _linear_in_columns(tree[1], names) and _linear_in_columns(tree[2], names)
    if kind == "*":
        left, right = tree[1], tree[2]
        return (_is_number(left, names) and _linear_in_columns(right, names)) or (
            _is_number(right, names) and _linear_in_columns(left, names)
        )
    if kind == "/":
        return _linear_in_columns(tree[1], names) and _is_number(tree[2], names)
    return False


def _is_number(tree: tuple, names: Mapping[str, Any]) -> bool:
    """True for a number, a scalar constant or arithmetic over them."""
    kind = tree[0]
    if kind == "num":
        return True
    if kind == "col":
        return isinstance(tree[1], str) and tree[1] in names and np.ndim(names[tree[1]]) == 0
    if kind == "neg":
        return _is_number(tree[1], names)
    if kind in ("+", "-", "*", "/"):
        return _is_number(tree[1], names) and _is_number(tree[2], names)
    return False


@dataclass(frozen=True)
class ChannelSpec:
    """How to compute one channel from a table.

    Attributes:
        column: 1-based column number or column name (or use ``expr``).
        expr: arithmetic expression over ``$N`` / column names, with functions, ``pi`` and
            the time variable ``t`` (see the module docstring).
        scale, offset: value = source · scale + offset (in the source unit), then
            converted by the unit rule.
        unit: the source unit (e.g. ``"deg"``). Without ``to`` the values are delivered in
            SI with angles in rad (``flightid.data.units.channel_conversion``); an unknown
            unit is refused.
        to: the delivered unit (e.g. ``"deg"`` to keep degrees, ``"g"`` to keep g); the
            channel's unit in reports. ``to`` alone is allowed where the file states the
            column's unit.
        ignore_file_unit: use the case's ``unit`` (or none) whatever unit the file states
            for the column(s); by default a unit the file states (CSV header ``q [deg/s]``,
            MATLAB ``varlab``, DataFlash FMTU, Parquet/HDF5 metadata) is the source unit
            when the case declares none, and a declared unit that contradicts it is a
            ``FileUnitError`` (``with_file_unit``).
        subtract: ``"first"`` or ``"mean"``: remove that reference value (perturbations).
        smooth: ``"smoothMulTS"``, ``{"savgol": [window, order]}`` or
            ``{"butter": [order, cutoff_hz]}`` (``flightid.data.preprocess``), stored as a
            tuple; applied per maneuver and segment after ``subtract``.
        derivative: ``"ndiff8"`` or ``{"savgol": [window, order]}``: deliver the rate of
            the (smoothed) channel, unit ``…/s``; applied after ``smooth``.

    Order: source → scale/offset → unit conversion → subtract → smooth → derivative.
    """

    column: int | str | None = None
    expr: str | None = None
    scale: float = 1.0
    offset: float = 0.0
    unit: str = ""
    to: str = ""
    ignore_file_unit: bool = False
    subtract: str | None = None
    smooth: tuple | None = None
    derivative: tuple | None = None

    @classmethod
    def from_value(cls, value: Any, where: str) -> ChannelSpec:
        """From a column number/name, an expression string containing an operator, or a
        mapping with the keys of this class."""
        if isinstance(value, ChannelSpec):
            return value
        if isinstance(value, bool):
            raise ChannelError(f"{where}: expected a column or a mapping, got {value!r}")
        if isinstance(value, int):
            return cls(column=value)
        if isinstance(value, str):
            if re.search(r"[-+*/()$]", value):
                return cls(expr=value)
            return cls(column=value)
        if not isinstance(value, Mapping):
            raise ChannelError(
                f"{where}: expected a column number, a column name, an expression or a table "
                f"with keys {sorted(_SPEC_KEYS)}, got {describe(value)}"
            )
        unknown = sorted(set(value) - _SPEC_KEYS)
        if unknown:
            raise ChannelError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(_SPEC_KEYS)}")
        if ("column" in value) == ("expr" in value):
            raise ChannelError(f"{where}: give exactly one of 'column' and 'expr'")
        for key in ("scale", "offset"):
            if key in value and (
                isinstance(value[key], bool) or not isinstance(value[key], (int, float))
            ):
                raise ChannelError(f"{where}.{key}: expected a number, got {describe(value[key])}")
        for key in ("unit", "to", "expr"):
            if key in value and not isinstance(value[key], str):
                raise ChannelError(f"{where}.{key}: expected a string, got {describe(value[key])}")
        if value.get("subtract") not in (None, "first", "mean"):
            raise ChannelError(
                f"{where}.subtract: expected 'first' or 'mean', got {value['subtract']!r}"
            )
        if not isinstance(value.get("ignore_file_unit", False), bool):
            raise ChannelError(
                f"{where}.ignore_file_unit: expected true or false, got "
                f"{describe(value['ignore_file_unit'])}"
            )
        fields = {k: value[k] for k in value}
        fields["smooth"] = parse_smooth(value.get("smooth"), f"{where}.smooth")
        fields["derivative"] = parse_derivative(value.get("derivative"), f"{where}.derivative")
        spec = cls(**fields)
        if spec.expr is not None:
            parse_expression(spec.expr)  # fail early
        if spec.unit:
            spec.conversion(where)  # unknown units and dimension mismatches fail early
        elif spec.to:
            try:  # the source unit may come from the file; ``to`` must be a unit
                parse_unit(spec.to)
            except InputError as exc:
                raise ChannelError(f"{where}.to: {exc}") from None
        return spec

    def conversion(self, where: str = "channel") -> tuple[float, str]:
        """(factor, delivered unit) by the channel rule of ``channel_conversion``."""
        if self.to and not self.unit:
            raise ChannelError(
                f"{where}: to = {self.to!r} needs the unit the values are recorded in; "
                "neither the channel (unit = ...) nor the file states one"
            )
        try:
            return channel_conversion(self.unit, self.to)
        except InputError as exc:
            raise ChannelError(f"{where}: {exc}") from None

    def with_file_unit(
        self, table: Table, where: str, names: Mapping[str, Any] | None = None
    ) -> ChannelSpec:
        """This channel with the unit its file states for it (``Table.units``).

        A column's stated unit, or for an expression that is a sum of columns times numbers
        (``_linear_in_columns``) the one unit all its columns state, is the source unit when
        the channel declares none; a declared unit must mean the same unit, else
        ``FileUnitError`` naming both. An expression that reads columns with stated units
        and is not such a sum needs a declared unit (of its result). ``ignore_file_unit``
        skips all of this. ``names``: signals and constants (not columns)."""
        if self.ignore_file_unit:
            return self
        names = names or {}
        tree = parse_expression(self.expr) if self.expr is not None else ("col", self.column)
        stated: dict[str, str] = {}
        unstated = False
        for ref in expression_columns(tree):
            if isinstance(ref, str) and ref in names:
                unstated = True
                continue
            try:
                index = table.column_index(ref, where)
            except ChannelError:
                return self  # evaluate names the missing column
            label = stated_unit(table.units[index])
            name = table.names[index] or f"${index + 1}"
            if label:
                stated[name] = label
            else:
                unstated = True
        if not stated:
            return self
        labels = set(stated.values())
        if len(labels) == 1 and not unstated and _linear_in_columns(tree, names):
            return self._apply_stated(labels.pop(), stated, table, where)
        if self.unit:
            return self  # the declared unit of a result the file's units do not determine
        raise FileUnitError(
            f"{where}: the expression {self.expr!r} reads columns whose file states their "
            f"units ({_unit_list(stated)}); declare the unit of its result (unit = ...), or "
            "ignore_file_unit = true to use the recorded numbers as they are"
        )

    def _apply_stated(
        self, label: str, stated: Mapping[str, str], table: Table, where: str
    ) -> ChannelSpec:
        """The spec with the file's unit ``label`` as its source unit (see
        ``with_file_unit``)."""
        source = table.source or "the file"
        try:
            parse_unit(label)
        except InputError:
            if self.unit:
                return self  # a label flightid cannot read: the declared unit applies
            raise FileUnitError(
                f"{where}: {source} states the unit {label!r} for {_unit_list(stated)}, which "
                "flightid cannot read; declare the unit the values are in (unit = ...), or "
                "use them as recorded (ignore_file_unit = true)"
            ) from None
        if not self.unit:
            return dataclasses.replace(self, unit=label)
        if same_unit(self.unit, label):
            return self
        raise FileUnitError(
            f"{where}: the channel declares unit = {self.unit!r}, but {source} states "
            f"{label!r} for {_unit_list(stated)}; remove 'unit' to use the file's, correct it, "
            "or set ignore_file_unit = true if the file's label is wrong"
        )

    @property
    def target_unit(self) -> str:
        """The unit the values are delivered in ("" where no unit is declared; with a
        ``derivative``, that unit per s)."""
        unit = self.to or self.conversion()[1]
        if self.derivative is not None:
            return f"{unit}/s" if unit else "1/s"
        return unit

    def evaluate(
        self,
        table: Table,
        where: str,
        keep: np.ndarray | None = None,
        time: np.ndarray | None = None,
        names: Mapping[str, Any] | None = None,
    ) -> np.ndarray:
        """The channel's values in the target unit, on the rows ``keep`` (default all).
        ``time``: the values of the expression variable ``t`` on all rows (s); None inside the
        time channel itself, where ``t`` is the column named t. ``names``: signals (arrays
        over all rows) and constants (numbers) that names refer to before columns
        (``flightid.data.pipeline``). The file's units apply as ``with_file_unit`` says."""
        spec = self.with_file_unit(table, where, names)
        if spec is not self:
            return spec.evaluate(table, where, keep, time, names)
        if self.expr is not None:
            try:
                tree = parse_expression(self.expr)
            except ChannelError as exc:
                raise ChannelError(f"{where}: {exc}") from None
            problems: list = []
            values = _evaluate(tree, table, where, time, problems, names)
            values = np.broadcast_to(np.asarray(values, dtype=float), (table.n_rows,)).copy()
            rows = np.ones(table.n_rows, dtype=bool) if keep is None else keep
            for words, refused, argument in problems:
                refused = np.broadcast_to(refused, (table.n_rows,)) & rows
                if refused.any():
                    k = int(np.argmax(refused))
                    bad = np.broadcast_to(np.asarray(argument, dtype=float), (table.n_rows,))[k]
                    raise ChannelError(
                        f"{where}: {words}, got {bad:.6g} at row {k + 1} of "
                        f"{table.source or 'the table'} ({int(refused.sum())} row(s) in all)"
                    )
        else:
            values = np.broadcast_to(
                np.asarray(_lookup(self.column, table, where, names), dtype=float),
                (table.n_rows,),
            ).copy()
        factor, _ = self.conversion(where)
        # value = (source · scale + offset) · factor   (scale, offset in the source unit)
        values = (values * self.scale + self.offset) * factor
        if keep is not None:
            values = values[keep]
        if self.subtract == "first":
            values = values - values[0]
        elif self.subtract == "mean":
            values = values - values.mean()
        bad = ~np.isfinite(values)
        if bad.any():
            raise ChannelError(
                f"{where}: {int(bad.sum())} non-finite value(s) in {table.source or 'the table'}, "
                f"the first at row {int(np.argmax(bad)) + 1}"
            )
        return values


def _unit_list(stated: Mapping[str, str]) -> str:
    """``column 'q' [deg/s]`` or ``columns 'p' [deg/s], 'q' [rad/s]`` for messages."""
    words = ", ".join(f"{name!r} [{unit}]" for name, unit in stated.items())
    return f"column{'s' if len(stated) > 1 else ''} {words}"


def _specs(mapping: Mapping[str, Any] | None, where: str) -> dict[str, ChannelSpec]:
    if mapping is None:
        return {}
    if not isinstance(mapping, Mapping):
        raise ChannelError(
            f"{where}: expected a mapping of channel name to column/spec, got {describe(mapping)}"
        )
    specs = {}
    for name, value in mapping.items():
        if not isinstance(name, str) or not name.isidentifier():
            raise ChannelError(f"{where}: channel names must be identifiers, got {name!r}")
        specs[name] = ChannelSpec.from_value(value, f"{where}.{name}")
    return specs


def to_flight_data(
    table: Table,
    *,
    time: Any = 1,
    inputs: Mapping[str, Any] | None = None,
    outputs: Mapping[str, Any] | None = None,
    name: str = "",
    start: float | None = None,
    stop: float | None = None,
    gaps: str = "error",
    uniform_rtol: float = 1e-6,
    constants: Mapping[str, Any] | None = None,
    signals: Mapping[str, Any] | None = None,
    steps: Sequence[Any] | None = None,
    pipeline: Any = None,
    dt: float | None = None,
    resample_hz: float | None = None,
    max_gap_s: float | None = None,
    allow_retime: bool = False,
) -> FlightData:
    """Build ``FlightData`` from a table and channel specifications.

    Time is never warped: the stored stamps are replaced by a uniform grid only where that
    moves no row by more than half an interval (``flightid.data.timebase``), else a
    ``TimeBaseError`` says by how much. What was done is kept in ``FlightData.notes``.

    Args:
        table: the loaded table.
        time: spec of the time column (default column 1), in s after conversion. Stored
            times uniform to within ``1e-3`` relative (rounded stamps) are re-gridded as
            t_0 + k·Δt (Δt the mean interval); other uneven times are refused, with the ways
            to make them uniform (``dt``, ``gaps``, ``resample_hz``, start/stop).
        inputs: ``{channel: spec}`` (see ``ChannelSpec``).
        outputs: ``{channel: spec}`` (see ``ChannelSpec``).
        name: maneuver label.
        start: keep ``start ≤ t ≤ stop`` (s, in the time column's values).
        stop: see ``start``.
        gaps: ``"error"`` (default) refuses non-uniform time; ``"join"`` joins a file holding
            several recordings one after another (the time steps back, or jumps, between
            them) at the recordings' common interval; each recording keeps its own time.
        constants: ``[data.constants]`` (``flightid.data.pipeline``): named numbers the
            signals, steps and channels can use.
        signals: ``[data.signals]``: named intermediate signals.
        steps: ``[[data.steps]]``: built-in pre-processing steps making named signals.
        pipeline: an already checked ``flightid.data.pipeline.Pipeline`` instead of
            ``constants``/``signals``/``steps``.
        dt: the sampling interval (s): replaces the stored times of the kept rows by
            t_k = t_0 + k·dt (t_0 the first kept stored time) — for files whose stamps
            jitter about a uniform grid. Must lie within 10 % of the median stored interval,
            and no row may move by more than dt/2. The time variable of expressions sees
            the regenerated times. Default: the stored times.
        resample_hz: R (Hz): resample every column onto t_k = k/R, anti-aliased where the
            data are faster than R, split at gaps (``flightid.data.resample``). A record that
            splits into several segments is refused here: use ``to_flight_segments``.
        max_gap_s: with ``resample_hz``: the longest interval bridged by interpolation (s).
        allow_retime: accept re-gridding (``dt``, ``gaps = "join"``) that moves rows by more
            than half an interval (to reproduce tools that integrate at a fixed Δt); the
            largest move is named in the notes.
    """
    if resample_hz is not None:
        pieces = to_flight_segments(
            table,
            time=time,
            inputs=inputs,
            outputs=outputs,
            name=name,
            start=start,
            stop=stop,
            gaps=gaps,
            uniform_rtol=uniform_rtol,
            constants=constants,
            signals=signals,
            steps=steps,
            pipeline=pipeline,
            dt=dt,
            resample_hz=resample_hz,
            max_gap_s=max_gap_s,
            allow_retime=allow_retime,
        )
        if len(pieces) > 1:
            raise TimeBaseError(
                f"resample_hz: {table.source or 'the table'} splits into {len(pieces)} "
                f"segments at its gaps ({', '.join(_span(p) for p in pieces)}); use "
                "to_flight_segments (a case makes each a maneuver), start/stop to pick one, "
                "or max_gap_s to bridge the gaps"
            )
        return pieces[0]
    pipeline, time_spec, in_specs, out_specs = _prepare(
        table, time, inputs, outputs, pipeline, constants, signals, steps
    )
    t_all = time_spec.evaluate(table, "time")
    keep = np.ones(t_all.shape[0], dtype=bool)
    if start is not None:
        keep &= t_all >= start - 1e-9
    if stop is not None:
        keep &= t_all <= stop + 1e-9
    if keep.sum() < 2:
        raise InputError(
            f"start/stop: [{start}, {stop}] keeps fewer than 2 samples of "
            f"{table.source} (time runs {t_all[0]:g}..{t_all[-1]:g} s)"
        )
    if max_gap_s is not None:
        raise TimeBaseError("max_gap_s: only used with resample_hz (where gaps split the record)")
    t, t_all, segments, notes = _stored_time_base(table, t_all, keep, gaps, dt, allow_retime)
    return _build(
        table, t, t_all, keep, segments, pipeline, in_specs, out_specs, name, uniform_rtol, notes
    )


def _prepare(table, time, inputs, outputs, pipeline, constants, signals, steps):
    """(pipeline, time spec, input specs, output specs), each checked; the time column takes
    the unit the file states for it where the case gives none."""
    from flightid.data.pipeline import parse_pipeline

    if pipeline is None:
        pipeline = parse_pipeline(constants, signals, steps)
    time_spec = ChannelSpec.from_value(time, "time").with_file_unit(table, "time")
    if time_spec.unit and parse_unit(time_spec.target_unit) != parse_unit("s"):
        raise ChannelError(
            f"time: expected the time in s (leave out 'to', or to = 's'), got to = {time_spec.to!r}"
        )
    return pipeline, time_spec, _specs(inputs, "inputs"), _specs(outputs, "outputs")


def _span(data: FlightData) -> str:
    return f"{data.time[0]:.6g}..{data.time[-1]:.6g} s"


def _streams_refused(table: Table) -> TimeBaseError:
    rates = []
    for stream in table.streams:
        steps = np.diff(table.data[stream.rows, 0]) if stream.rows.size > 1 else np.ones(1)
        rates.append(f"{stream.name} ({1 / np.median(steps):.4g} Hz)")
    return TimeBaseError(
        f"time: the streams of {table.source} have their own time bases: {', '.join(rates)}; "
        "declare resample_hz = R to put them on one grid at R Hz (anti-aliased, split at "
        "gaps), or read one stream"
    )


def _rate_proposal(median_s: float) -> str:
    """A round rate at or below 1/median, 2 significant digits (Hz)."""
    rate = 1.0 / median_s
    scale = 10 ** (math.floor(math.log10(rate)) - 1)
    return f"{math.floor(rate / scale + 1e-9) * scale:.6g}"


def _uneven(table: Table, t: np.ndarray) -> TimeBaseError:
    steps = np.diff(t)
    k = int(np.argmax(np.abs(steps - np.median(steps))))
    median = float(np.median(steps))
    message = (
        f"time: {table.source} has a gap or uneven sampling (interval {steps[k]:.6g} s after "
        f"t = {t[k]:.6g} s, median {median:.6g} s); declare resample_hz = R to resample it "
        f"onto a uniform grid at R Hz (anti-aliased, split at gaps; e.g. resample_hz = "
        f"{_rate_proposal(median)}), or use start/stop to pick one uniform segment"
    )
    if np.all(steps > 0):
        mean = float((t[-1] - t[0]) / (t.shape[0] - 1))
        move, _ = largest_move(t, t[0] + np.arange(t.shape[0]) * mean)
        if move <= HALF_INTERVAL * mean:
            message += (
                f"; the stamps lie within {move:.3g} s of a uniform grid at {mean:.6g} s, so "
                f"dt = {mean:.6g} would re-grid them"
            )
    return TimeBaseError(message + "; gaps = 'join' for a file of several recordings")


def _checked_dt(given: Any, table: Table, t: np.ndarray) -> float:
    if (
        isinstance(given, bool)
        or not isinstance(given, (int, float))
        or not (math.isfinite(given) and given > 0)
    ):
        raise InputError(f"dt: expected a positive number of seconds, got {given!r}")
    median = float(np.median(np.diff(t)))
    if not abs(median - given) <= 0.1 * given:
        raise InputError(
            f"dt: {given:g} s is not within 10 % of the median stored interval of "
            f"{table.source}, {median:.6g} s"
        )
    return float(given)


def _stored_time_base(
    table: Table,
    t_all: np.ndarray,
    keep: np.ndarray,
    gaps: str,
    dt: Any,
    allow_retime: bool,
) -> tuple[np.ndarray, np.ndarray, list[slice], tuple[str, ...]]:
    """The uniform time of the kept rows from their stored stamps: (time, the expression
    variable t on all rows, segments where smoothing restarts, notes)."""
    if gaps not in ("error", "join"):
        raise InputError(f"gaps: expected 'error' or 'join', got {gaps!r}")
    if not isinstance(allow_retime, bool):
        raise InputTypeError(f"allow_retime: expected true or false, got {describe(allow_retime)}")
    if table.streams:
        raise _streams_refused(table)
    t = t_all[keep]
    source = table.source or "the table"
    whole = [slice(0, t.shape[0])]
    if dt is not None:
        step = _checked_dt(dt, table, t)
        grid, note = regrid(t, step, what="dt", source=source, allow_retime=allow_retime)
        # expressions' time variable sees the same regenerated times (row i: t_0 + (i − i_0)·dt)
        i0 = int(np.argmax(keep))
        t_all = grid[0] + (np.arange(t_all.shape[0]) - i0) * step
        return grid, t_all, whole, (note,)
    if gaps == "join":
        joined, recordings, note = join_recordings(t, source=source, allow_retime=allow_retime)
        return joined, t_all, recordings, (note,)
    steps = np.diff(t)
    if np.any(steps <= 0):
        return t, t_all, whole, ()  # FlightData names the first row out of order
    # relative spread of the intervals (max − min)/mean
    spread = (steps.max() - steps.min()) / steps.mean()
    if spread > 1e-3:
        raise _uneven(table, t)
    if spread > 0:
        # t_k = t_0 + k·Δt with Δt the mean interval (rounded stored stamps)
        grid, note = regrid(t, float(np.round(steps.mean(), 12)), what="time", source=source)
        return grid, t_all, whole, (note,)
    return t, t_all, whole, ()


def _build(
    table: Table,
    t: np.ndarray,
    t_all: np.ndarray,
    keep: np.ndarray,
    segments: Sequence[slice],
    pipeline: Any,
    in_specs: Mapping[str, ChannelSpec],
    out_specs: Mapping[str, ChannelSpec],
    name: str,
    uniform_rtol: float,
    notes: Sequence[str],
) -> FlightData:
    """The channels of the kept rows on the uniform time ``t`` (smoothing and
    differentiation restart at every segment and, as each maneuver is built on its own, at
    every maneuver)."""
    step = float((t[-1] - t[0]) / (t.shape[0] - 1))  # s, the uniform interval
    names = None if pipeline.empty else pipeline.evaluate(table, keep, t_all, step, segments)
    # the units the file states for the columns (Table.units) where the case gives none
    in_specs = {k: s.with_file_unit(table, f"inputs.{k}", names) for k, s in in_specs.items()}
    out_specs = {k: s.with_file_unit(table, f"outputs.{k}", names) for k, s in out_specs.items()}
    if not pipeline.empty:
        pipeline = pipeline.with_file_units(table, names)
    units = {k: pipeline.unit_of(s) for k, s in {**in_specs, **out_specs}.items()}
    channels_in = {
        k: s.evaluate(table, f"inputs.{k}", keep, t_all, names) for k, s in in_specs.items()
    }
    channels_out = {
        k: s.evaluate(table, f"outputs.{k}", keep, t_all, names) for k, s in out_specs.items()
    }
    for group, specs, channels in (
        ("inputs", in_specs, channels_in),
        ("outputs", out_specs, channels_out),
    ):
        for k, spec in specs.items():
            if spec.smooth is not None or spec.derivative is not None:
                channels[k] = apply_steps(
                    channels[k], step, segments, spec.smooth, spec.derivative, f"{group}.{k}"
                )
    return FlightData(
        t,
        channels_in,
        channels_out,
        units=units,
        name=name,
        uniform_rtol=uniform_rtol,
        notes=notes,
    )


def _table_streams(table: Table, time_spec: ChannelSpec, t_all: np.ndarray):
    """The table's streams as ``StreamSamples`` (a table without streams: one stream of
    every column but the time column) and the columns no stream fills (set to the grid)."""
    from flightid.data.resample import StreamSamples

    if table.streams:
        listed = [(s.name, s.rows, s.columns) for s in table.streams]
    else:
        own = None
        if time_spec.expr is None:
            own = table.column_index(time_spec.column, "time")
        columns = tuple(c for c in range(table.n_columns) if c != own)
        label = Path(table.source).name if table.source else "table"
        listed = [(f"the rows of {label}", np.arange(table.n_rows), columns)]
    samples = [
        StreamSamples(name, t_all[rows], table.data[np.ix_(rows, list(columns))])
        for name, rows, columns in listed
    ]
    filled = {c for _, _, columns in listed for c in columns}
    return (
        samples,
        [columns for _, _, columns in listed],
        [c for c in range(table.n_columns) if c not in filled],
    )


def to_flight_segments(
    table: Table,
    *,
    time: Any = 1,
    inputs: Mapping[str, Any] | None = None,
    outputs: Mapping[str, Any] | None = None,
    name: str = "",
    start: float | None = None,
    stop: float | None = None,
    gaps: str = "error",
    uniform_rtol: float = 1e-6,
    constants: Mapping[str, Any] | None = None,
    signals: Mapping[str, Any] | None = None,
    steps: Sequence[Any] | None = None,
    pipeline: Any = None,
    dt: float | None = None,
    resample_hz: float | None = None,
    max_gap_s: float | None = None,
    allow_retime: bool = False,
) -> list[FlightData]:
    """``to_flight_data`` for records that gaps split: one ``FlightData`` per segment.

    Without ``resample_hz``: ``[to_flight_data(...)]``. With it, every stream of the table
    (a flight log's message streams, or all the columns of any other table, on the time
    column) is resampled onto t_k = k/R (``flightid.data.resample.resample_streams``:
    anti-alias low-pass where faster than R, linear interpolation where slower, split where
    a stream has a gap longer than ``max_gap_s``), within start/stop; the channels are then
    computed on each segment. Segments are named ``name_1``, ``name_2``, ... when there are
    several; each one's ``notes`` say what was done.
    """
    if resample_hz is None:
        return [
            to_flight_data(
                table,
                time=time,
                inputs=inputs,
                outputs=outputs,
                name=name,
                start=start,
                stop=stop,
                gaps=gaps,
                uniform_rtol=uniform_rtol,
                constants=constants,
                signals=signals,
                steps=steps,
                pipeline=pipeline,
                dt=dt,
                max_gap_s=max_gap_s,
                allow_retime=allow_retime,
            )
        ]
    from flightid.data.resample import check_max_gap, check_rate, resample_streams

    rate = check_rate(resample_hz)
    max_gap = check_max_gap(max_gap_s)
    if dt is not None or gaps != "error":
        raise TimeBaseError(
            "resample_hz: give either resample_hz or dt / gaps = 'join', not both "
            f"(got dt = {dt!r}, gaps = {gaps!r})"
        )
    pipeline, time_spec, in_specs, out_specs = _prepare(
        table, time, inputs, outputs, pipeline, constants, signals, steps
    )
    t_all = time_spec.evaluate(table, "time")
    samples, columns_of, grid_columns = _table_streams(table, time_spec, t_all)
    resampling = resample_streams(samples, rate, max_gap, start=start, stop=stop)
    source = f"{table.source or 'the table'} resampled at {rate:g} Hz"
    pieces = []
    count = len(resampling.segments)
    for number, segment in enumerate(resampling.segments, start=1):
        grid = segment.time_s
        data = np.full((grid.shape[0], table.n_columns), np.nan)
        for columns, values in zip(columns_of, segment.values, strict=True):
            data[:, list(columns)] = values
        data[:, grid_columns] = grid[:, None]
        resampled = _finish_table(data, table.names, table.units, source, table.constants)
        label = f"{name}_{number}" if count > 1 else name
        notes = resampling.notes
        if count > 1:
            notes = (
                *notes,
                f"this maneuver: segment {number} of {count}, {grid[0]:.6g}..{grid[-1]:.6g} s",
            )
        pieces.append(
            _build(
                resampled,
                grid,
                grid,
                np.ones(grid.shape[0], dtype=bool),
                [slice(0, grid.shape[0])],
                pipeline,
                in_specs,
                out_specs,
                label,
                uniform_rtol,
                notes,
            )
        )
    return pieces


def load_flight_data(
    path: str | Path,
    *,
    time: Any = 1,
    inputs: Mapping[str, Any] | None = None,
    outputs: Mapping[str, Any] | None = None,
    format: str = "auto",
    variable: str | None = None,
    name: str | None = None,
    start: float | None = None,
    stop: float | None = None,
    gaps: str = "error",
    constants: Mapping[str, Any] | None = None,
    signals: Mapping[str, Any] | None = None,
    steps: Sequence[Any] | None = None,
    dt: float | None = None,
    resample_hz: float | None = None,
    max_gap_s: float | None = None,
    allow_retime: bool = False,
) -> FlightData:
    """``read_table`` then ``to_flight_data``; the maneuver name defaults to the file stem."""
    table = read_table(path, format, variable=variable)
    return to_flight_data(
        table,
        constants=constants,
        signals=signals,
        steps=steps,
        time=time,
        inputs=inputs,
        outputs=outputs,
        name=Path(path).stem if name is None else name,
        start=start,
        stop=stop,
        gaps=gaps,
        dt=dt,
        resample_hz=resample_hz,
        max_gap_s=max_gap_s,
        allow_retime=allow_retime,
    )


def load_flight_segments(
    path: str | Path,
    *,
    format: str = "auto",
    variable: str | None = None,
    name: str | None = None,
    **settings: Any,
) -> list[FlightData]:
    """``read_table`` then ``to_flight_segments`` (the keyword arguments of
    ``load_flight_data``); the maneuver name defaults to the file stem."""
    table = read_table(path, format, variable=variable)
    return to_flight_segments(table, name=Path(path).stem if name is None else name, **settings)
