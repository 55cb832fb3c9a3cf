"""Flight-mode intervals and system-identification runs recorded in a log, and the choice
of one mode interval as a maneuver (``mode = "..."`` in a case).

- PX4: ``vehicle_status.nav_state``, numbers named as PX4's ``vehicle_status`` message
  defines them (``NAVIGATION_STATE_STAB`` = 15 is "Stabilized"; both the constant's name
  and the ground-station label match).
- ArduPilot: ``MODE`` messages (``ModeNum``, else ``Mode``), named for the vehicle of the
  log's ``VER.BU`` build type (Copter/Heli, Plane, Rover; without ``VER`` the vehicle can be
  given). Copter's mode 25 "SYSTEMID" also answers to "SYSID".
- ArduPilot system identification: each run of ``SIDD`` samples (a gap of more than 1 s
  starts a new run) with the settings of the ``SIDS`` message before it (axis, magnitude,
  start/stop frequency).

A mode interval runs from the first stamp that records the mode to the first stamp that
records another; the last one runs to the end of the log (``math.inf`` where the end is not
known).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flightid.data.formats import Stream, dataflash_streams, ulog_streams
from flightid.data.loaders import DataFileError
from flightid.errors import InputError

__all__ = [
    "ModeInterval",
    "ModeSelectionError",
    "SysIdRun",
    "PX4_NAV_STATES",
    "ARDUPILOT_MODES",
    "mode_intervals",
    "sysid_runs",
    "select_mode",
    "log_mode_intervals",
]


class ModeSelectionError(InputError):
    """A maneuver chosen by flight mode: the log records no modes, not that mode, or that
    mode several times without an index saying which."""


# PX4 vehicle_status NAVIGATION_STATE_* : (constant name, ground-station label)
PX4_NAV_STATES: dict[int, tuple[str, str]] = {
    0: ("MANUAL", "Manual"),
    1: ("ALTCTL", "Altitude"),
    2: ("POSCTL", "Position"),
    3: ("AUTO_MISSION", "Mission"),
    4: ("AUTO_LOITER", "Hold"),
    5: ("AUTO_RTL", "Return"),
    6: ("POSITION_SLOW", "Position Slow"),
    10: ("ACRO", "Acro"),
    12: ("DESCEND", "Descend"),
    13: ("TERMINATION", "Termination"),
    14: ("OFFBOARD", "Offboard"),
    15: ("STAB", "Stabilized"),
    16: ("RATTITUDE", "Rattitude"),
    17: ("AUTO_TAKEOFF", "Takeoff"),
    18: ("AUTO_LAND", "Land"),
    19: ("AUTO_FOLLOW_TARGET", "Follow Me"),
    20: ("AUTO_PRECLAND", "Precision Land"),
    21: ("ORBIT", "Orbit"),
    22: ("AUTO_VTOL_TAKEOFF", "VTOL Takeoff"),
}

_COPTER = (
    "STABILIZE ACRO ALT_HOLD AUTO GUIDED LOITER RTL CIRCLE POSITION LAND OF_LOITER DRIFT - "
    "SPORT FLIP AUTOTUNE POSHOLD BRAKE THROW AVOID_ADSB GUIDED_NOGPS SMART_RTL FLOWHOLD "
    "FOLLOW ZIGZAG SYSTEMID AUTOROTATE AUTO_RTL TURTLE"
).split()
_PLANE = (
    "MANUAL CIRCLE STABILIZE TRAINING ACRO FBWA FBWB CRUISE AUTOTUNE - AUTO RTL LOITER "
    "TAKEOFF AVOID_ADSB GUIDED INITIALISING QSTABILIZE QHOVER QLOITER QLAND QRTL QAUTOTUNE "
    "QACRO THERMAL LOITER_ALT_QLAND AUTOLAND"
).split()
_ROVER = (
    "MANUAL ACRO - STEERING HOLD LOITER FOLLOW SIMPLE DOCK CIRCLE AUTO RTL SMART_RTL - - "
    "GUIDED INITIALISING"
).split()
# ArduPilot mode numbers per vehicle (the firmware's mode enumerations)
ARDUPILOT_MODES: dict[str, dict[int, str]] = {
    vehicle: {k: name for k, name in enumerate(names) if name != "-"}
    for vehicle, names in (("copter", _COPTER), ("plane", _PLANE), ("rover", _ROVER))
}
# VER.BU build types → vehicle (ArduPilot AP_Vehicle_Type; 13 = Heli uses Copter's modes)
_BUILD_TYPES = {1: "rover", 2: "copter", 3: "plane", 13: "copter"}
_ALIASES = {"SYSTEMID": ("SYSID", "SYSTEM_ID")}

# SIDS.Ax: the axis the system-identification mode excites (ArduCopter SID_AXIS)
SYSID_AXES = {
    1: "input roll angle",
    2: "input pitch angle",
    3: "input yaw angle",
    4: "recovery roll angle",
    5: "recovery pitch angle",
    6: "recovery yaw angle",
    7: "rate roll",
    8: "rate pitch",
    9: "rate yaw",
    10: "mixer roll",
    11: "mixer pitch",
    12: "mixer yaw",
    13: "mixer thrust",
}
SYSID_GAP_S = 1.0  # s: SIDD samples further apart start a new run


@dataclass(frozen=True)
class ModeInterval:
    """One stretch of one flight mode.

    Attributes:
        name: the mode's label ("Stabilized", "SYSTEMID", or "mode 7" where unnamed).
        number: the number the log stores.
        start_s, stop_s: the interval (s, log time); ``stop_s`` is ``math.inf`` where the
            mode lasts to an end of the log that is not known.
        source: where it was read (``vehicle_status.nav_state``, ``MODE.ModeNum``).
        aliases: other names that select it (PX4 constant names, ``SYSID``).
    """

    name: str
    number: int
    start_s: float
    stop_s: float
    source: str
    aliases: tuple[str, ...] = ()

    def matches(self, wanted: str) -> bool:
        wanted = wanted.strip().lower()
        return any(wanted == n.lower() for n in (self.name, *self.aliases))


@dataclass(frozen=True)
class SysIdRun:
    """One run of ArduPilot's system-identification mode: the span of its ``SIDD`` samples
    and the ``SIDS`` settings before it (``Ax`` axis, ``Mag`` magnitude, ``FSt``/``FSp``
    start/stop frequency in Hz, ``TFin``/``TC``/``TR``/``TFout`` fade-in, constant,
    record and fade-out times in s), empty where the log holds no ``SIDS``."""

    start_s: float
    stop_s: float
    settings: dict[str, float] = field(default_factory=dict)

    @property
    def axis(self) -> str:
        number = self.settings.get("Ax")
        if number is None:
            return "axis unknown"
        return SYSID_AXES.get(int(number), f"axis {int(number)}")

    @property
    def band_hz(self) -> tuple[float, float] | None:
        if "FSt" in self.settings and "FSp" in self.settings:
            return float(self.settings["FSt"]), float(self.settings["FSp"])
        return None


def _changes(time: np.ndarray, values: np.ndarray) -> list[tuple[int, float, float]]:
    """(value, start, stop) per run of equal values; the last stop is NaN (open)."""
    keep = np.isfinite(values)
    time, values = time[keep], values[keep].astype(int)
    if values.size == 0:
        return []
    starts = np.flatnonzero(np.r_[True, values[1:] != values[:-1]])
    stops = list(time[starts[1:]]) + [math.nan]
    return [(int(values[i]), float(time[i]), float(s)) for i, s in zip(starts, stops, strict=True)]


def _px4_interval(number: int, start: float, stop: float) -> ModeInterval:
    constant, label = PX4_NAV_STATES.get(number, (f"NAV_STATE_{number}", f"mode {number}"))
    return ModeInterval(label, number, start, stop, "vehicle_status.nav_state", (constant,))


def _ardupilot_interval(number: int, start: float, stop: float, vehicle: str | None, source):
    name = ARDUPILOT_MODES.get(vehicle or "", {}).get(number, f"mode {number}")
    return ModeInterval(name, number, start, stop, source, _ALIASES.get(name, ()))


def _vehicle(streams: Sequence[Stream], vehicle: str | None) -> str | None:
    if vehicle is not None:
        if vehicle not in ARDUPILOT_MODES:
            raise InputError(f"vehicle: expected one of {sorted(ARDUPILOT_MODES)}, got {vehicle!r}")
        return vehicle
    for stream in streams:
        if (
            stream.name.split("[")[0] == "VER"
            and "BU" in stream.fields
            and stream.fields["BU"].size
        ):
            return _BUILD_TYPES.get(int(stream.fields["BU"][0]))
    return None


def mode_intervals(
    streams: Sequence[Stream],
    end_s: float | None = None,
    vehicle: str | None = None,
) -> list[ModeInterval]:
    """The flight-mode intervals of a log's streams, in time order (empty where the log
    records no modes). ``end_s``: the end of the log (s), where the last mode ends (else
    ``math.inf``); ``vehicle``: "copter", "plane" or "rover" for an ArduPilot log without
    ``VER`` (default: from ``VER.BU``)."""
    end = math.inf if end_s is None else float(end_s)
    by_name = {s.name: s for s in streams}
    status = by_name.get("vehicle_status")
    if status is not None and "nav_state" in status.fields:
        runs = _changes(status.time_s, status.fields["nav_state"])
        return [_px4_interval(n, a, end if math.isnan(b) else b) for n, a, b in runs]
    mode = next((s for s in streams if s.name.split("[")[0] == "MODE"), None)
    if mode is None:
        return []
    column = "ModeNum" if "ModeNum" in mode.fields else "Mode"
    if column not in mode.fields:
        return []
    named = _vehicle(streams, vehicle)
    runs = _changes(mode.time_s, mode.fields[column])
    return [
        _ardupilot_interval(n, a, end if math.isnan(b) else b, named, f"MODE.{column}")
        for n, a, b in runs
    ]


def sysid_runs(streams: Sequence[Stream]) -> list[SysIdRun]:
    """ArduPilot system-identification runs (``SIDD`` spans with the ``SIDS`` settings
    logged before each), in time order; empty where the log has no ``SIDD``."""
    by_name = {s.name.split("[")[0]: s for s in streams}
    data = by_name.get("SIDD")
    if data is None or data.time_s.size == 0:
        return []
    settings = by_name.get("SIDS")
    t = data.time_s
    breaks = np.flatnonzero(np.diff(t) > SYSID_GAP_S)
    starts = np.r_[0, breaks + 1]
    stops = np.r_[breaks, t.size - 1]
    runs = []
    for a, b in zip(starts, stops, strict=True):
        chosen: dict[str, float] = {}
        if settings is not None and settings.time_s.size:
            before = np.flatnonzero(settings.time_s <= t[a] + 1e-9)
            k = int(before[-1]) if before.size else 0
            chosen = {name: float(v[k]) for name, v in settings.fields.items()}
        runs.append(SysIdRun(float(t[a]), float(t[b]), chosen))
    return runs


def _interval_words(interval: ModeInterval) -> str:
    stop = "end" if math.isinf(interval.stop_s) else f"{interval.stop_s:.3f} s"
    return f"{interval.start_s:.3f} s .. {stop}"


def select_mode(
    intervals: Sequence[ModeInterval],
    mode: str,
    index: int | None = None,
    where: str = "mode",
    source: str = "the log",
) -> ModeInterval:
    """The interval of ``mode`` (matched without regard to case against each interval's
    name and aliases). ``index`` (1-based) picks one occurrence where the mode occurs
    several times; without it, several occurrences are a ``ModeSelectionError`` listing
    them, as are a mode the log does not record and an index out of range."""
    if not intervals:
        raise ModeSelectionError(
            f"{where}: {source} records no flight modes (no vehicle_status.nav_state of a "
            "PX4 ULog, no MODE messages of an ArduPilot log); give start/stop instead"
        )
    found = [i for i in intervals if i.matches(mode)]
    present = sorted({i.name for i in intervals})
    if not found:
        raise ModeSelectionError(
            f"{where}: {source} never records mode {mode!r}; modes in it: {present}"
        )
    if index is None:
        if len(found) > 1:
            spans = "; ".join(f"{k + 1}: {_interval_words(i)}" for k, i in enumerate(found))
            raise ModeSelectionError(
                f"{where}: mode {mode!r} occurs {len(found)} times in {source} ({spans}); "
                "say which with mode_index = 1, 2, ..."
            )
        return found[0]
    if isinstance(index, bool) or not isinstance(index, int) or not 1 <= index <= len(found):
        raise ModeSelectionError(
            f"{where}: mode_index: expected 1..{len(found)} (mode {mode!r} occurs "
            f"{len(found)} time(s) in {source}), got {index!r}"
        )
    return found[index - 1]


def log_mode_intervals(path: str | Path, vehicle: str | None = None) -> list[ModeInterval]:
    """The flight-mode intervals of a ULog (``.ulg``) or DataFlash log (``.bin``/``.log``),
    read from its mode streams only; the last one open (``math.inf``). A file of another
    kind is a ``ModeSelectionError``."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".ulg":
        try:
            streams, _ = ulog_streams(path, "vehicle_status")
        except DataFileError as exc:
            if "no stream" in str(exc):
                return []
            raise
        return mode_intervals(streams, None, vehicle)
    if suffix in (".bin", ".log"):
        try:
            streams = dataflash_streams(path, "MODE")
        except DataFileError as exc:
            if "no stream" in str(exc):
                return []
            raise
        try:
            streams += dataflash_streams(path, "VER")
        except DataFileError:
            pass
        return mode_intervals(streams, None, vehicle)
    raise ModeSelectionError(
        f"mode: {path} is not a flight log that records modes (a PX4 .ulg or an ArduPilot "
        ".bin/.log); give start/stop instead"
    )
