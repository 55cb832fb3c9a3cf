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
import math
import os
import stat
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from flightid.data.channels import ChannelSpec, _specs
from flightid.data.expressions import (  # noqa: F401 (MAX_EXPRESSION_DEPTH: read by callers)
    MAX_EXPRESSION_DEPTH,
    expression_columns,
    parse_expression,
)
from flightid.data.flightdata import FlightData
from flightid.data.mat_tables import _ONE, _mat_table, _shape, _v5_fields, struct_table
from flightid.data.preprocess import apply_steps
from flightid.data.table import (  # noqa: F401 (the Table and its errors, read from here too)
    _CSV_UNIT,
    ChannelError,
    DataFileError,
    FileTooLargeError,
    FileUnitError,
    Table,
    TableStream,
    _finish_table,
)
from flightid.data.timebase import (
    HALF_INTERVAL,
    TimeBaseError,
    join_recordings,
    largest_move,
    regrid,
)
from flightid.data.units import parse_unit
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


# =====================================================================================
# Table
# =====================================================================================


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


# =====================================================================================
# channel specifications
# =====================================================================================


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
