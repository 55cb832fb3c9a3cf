"""A flight log's streams as recorded, and how regularly each was sampled.

``read_log`` reads every stream of a PX4 ULog or an ArduPilot DataFlash log on its own time
base (``flightid.data.formats``), or a table file (CSV, MATLAB, ...) as one stream.
``summarize_stream`` measures each stream's timing from its stamps:

    Δt_k = t_{k+1} − t_k                      sample intervals (s)
    rate = 1 / median(Δt)                      median rate (Hz)
    jitter = std(Δt_k : Δt_k ≤ 2·median(Δt))   spread of the regular intervals (s)
    drop-outs: intervals longer than 2·median(Δt); the largest is reported (s)
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flightid.data.formats import Stream, dataflash_streams, ulog_streams
from flightid.data.loaders import ChannelError, DataFileError, read_table
from flightid.data.signals import BUILTIN_SIGNALS, builtin_signal

__all__ = ["LogContents", "StreamSummary", "read_log", "summarize_stream", "log_kind"]

# an interval longer than this many median intervals is a drop-out
DROPOUT_FACTOR = 2.0
_KIND_WORDS = {"ulog": "PX4 ULog", "dataflash": "ArduPilot DataFlash log", "table": "table"}


@dataclass(frozen=True)
class StreamSummary:
    """Timing and contents of one stream.

    Attributes:
        name: the stream's name (``vehicle_attitude``, ``IMU[1]``).
        samples: number of time stamps.
        start_s, stop_s: first and last stamp (s).
        rate_hz: 1 / median interval (Hz); NaN with fewer than 2 samples or a zero median
            interval (samples logged at one stamp, such as a log's parameters).
        jitter_s: standard deviation of the intervals that are no drop-outs (s).
        max_interval_s: the largest interval (s).
        dropouts: number of intervals longer than ``DROPOUT_FACTOR`` median intervals.
        fields: ``{field: unit}`` ("" where the log states none).
    """

    name: str
    samples: int
    start_s: float
    stop_s: float
    rate_hz: float
    jitter_s: float
    max_interval_s: float
    dropouts: int
    fields: dict[str, str]


def summarize_stream(stream: Stream) -> StreamSummary:
    """Rate, jitter and drop-outs of one stream from its stored stamps (module docstring)."""
    t = np.asarray(stream.time_s, dtype=float)
    fields = {k: stream.units.get(k, "") for k in stream.fields}
    if t.size < 2:
        nan = float("nan")
        start = float(t[0]) if t.size else nan
        return StreamSummary(stream.name, int(t.size), start, start, nan, nan, nan, 0, fields)
    dt = np.diff(t)
    median = float(np.median(dt))
    regular = dt <= DROPOUT_FACTOR * median
    jitter = float(np.std(dt[regular])) if regular.any() else float("nan")
    return StreamSummary(
        stream.name,
        int(t.size),
        float(t[0]),
        float(t[-1]),
        1.0 / median if median > 0 else float("nan"),
        jitter,
        float(dt.max()),
        int((~regular).sum()),
        fields,
    )


def log_kind(path: str | Path, format: str = "auto") -> str:
    """ "ulog", "dataflash" or "table" (any other file ``read_table`` reads), by ``format``
    or, with "auto", by extension (.ulg; .bin and .log)."""
    if format in ("ulog", "dataflash"):
        return format
    if format != "auto":
        return "table"
    suffix = Path(path).suffix.lower()
    return {".ulg": "ulog", ".bin": "dataflash", ".log": "dataflash"}.get(suffix, "table")


def _table_stream(path: Path, time: str | None, format: str) -> Stream:
    """A table file as one stream: time from the column ``time`` (default: a column named
    t or time, else the first column), every other column a field (units from the file)."""
    table = read_table(path, "auto" if format == "auto" else format)
    names = [n or f"${k + 1}" for k, n in enumerate(table.names)]
    if time is None:
        lowered = [n.lower() for n in names]
        index = next((lowered.index(c) for c in ("t", "time") if c in lowered), 0)
    else:
        index = table.column_index(time, "--time")
    fields = {n: table.data[:, k] for k, n in enumerate(names) if k != index}
    units = {n: table.units[k] for k, n in enumerate(names) if k != index and table.units[k]}
    return Stream(path.stem, np.asarray(table.data[:, index], dtype=float), fields, units)


@dataclass(frozen=True)
class LogContents:
    """Every stream of a log on its own time base.

    Attributes:
        path: the file.
        kind: "ulog", "dataflash" or "table".
        streams: the streams, by name order of the log.
        parameters: the log's numeric parameters (ULog), else empty.
    """

    path: Path
    kind: str
    streams: tuple[Stream, ...]
    parameters: dict[str, float]

    @property
    def kind_words(self) -> str:
        return _KIND_WORDS[self.kind]

    def stream(self, name: str) -> Stream | None:
        """The stream of that name (``IMU_1`` also finds ``IMU[1]``, ``topic_1`` ``topic:1``)."""
        for one in self.streams:
            if name in (one.name, _column_stream(one.name)):
                return one
        return None

    def channel(self, name: str) -> tuple[np.ndarray, np.ndarray, str]:
        """(time s, values, unit) of ``stream.field``, of a field of a one-stream log, or of a
        built-in signal (``px4.roll``, ...: ``flightid.data.signals``). Unknown names raise
        ``ChannelError`` listing what the log holds."""
        if name in BUILTIN_SIGNALS:
            return self._builtin(name)
        stream_name, dot, field = name.rpartition(".")
        stream = self.stream(stream_name) if dot else None
        if stream is None and len(self.streams) == 1:
            stream, field = self.streams[0], name
        if stream is None or field not in stream.fields:
            raise ChannelError(
                f"channel {name!r}: not in {self.path}; name it stream.field "
                f"(streams: {[s.name for s in self.streams][:30]}) or a built-in signal "
                f"({', '.join(BUILTIN_SIGNALS)})"
            )
        return stream.time_s, stream.fields[field], stream.units.get(field, "")

    def _builtin(self, name: str) -> tuple[np.ndarray, np.ndarray, str]:
        def has(column: str) -> bool:
            stream_name, _, field = column.rpartition(".")
            stream = self.stream(stream_name)
            return stream is not None and field in stream.fields

        def values(column: str) -> np.ndarray:
            stream_name, _, field = column.rpartition(".")
            return self.stream(stream_name).fields[field]

        try:
            values_out, signal = builtin_signal(name, has, values)
        except KeyError as exc:
            raise ChannelError(
                f"channel {name!r}: {self.path} has none of the streams it is made from "
                f"({exc.args[0]})"
            ) from None
        stream_name = next(s for s, fields, _ in signal.sources if has(f"{s}.{fields[0]}"))
        return self.stream(stream_name).time_s, values_out, signal.unit

    def has_channel(self, name: str) -> bool:
        try:
            self.channel(name)
        except ChannelError:
            return False
        return True

    @property
    def span_s(self) -> tuple[float, float]:
        """First and last stamp over all streams (s)."""
        starts = [float(s.time_s[0]) for s in self.streams if len(s.time_s)]
        stops = [float(s.time_s[-1]) for s in self.streams if len(s.time_s)]
        return min(starts), max(stops)


def _column_stream(name: str) -> str:
    """The stream part of a column name: ``topic:1`` → ``topic_1``, ``IMU[1]`` → ``IMU_1``."""
    return name.replace(":", "_").replace("[", "_").replace("]", "")


def read_log(path: str | Path, format: str = "auto", time: str | None = None) -> LogContents:
    """Every stream of a ULog or DataFlash log, or a table file as one stream (``time``: its
    time column, default t/time or the first). Errors: ``DataFileError`` and, for a missing
    optional package, ``MissingDependencyError``."""
    path = Path(path)
    if not path.is_file():
        raise DataFileError(f"{path}: no such file" if not path.exists() else f"{path}: not a file")
    kind = log_kind(path, format)
    parameters: dict[str, float] = {}
    if kind == "ulog":
        streams, parameters = ulog_streams(path)
    elif kind == "dataflash":
        streams = dataflash_streams(path)
    else:
        streams = [_table_stream(path, time, format)]
    streams = [s for s in streams if len(s.time_s)]
    if not streams:
        raise DataFileError(f"{path}: no stream with time stamps")
    return LogContents(path, kind, tuple(streams), parameters)
