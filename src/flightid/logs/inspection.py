"""One look at a log, as ``flightid inspect`` prints it: the streams with their timing and
units, the flight modes and system-identification runs, and the excitation segments of the
input channels.

Input channels searched by default (those the log has): PX4 ``px4.aileron``,
``px4.elevator``, ``px4.rudder``, ``px4.throttle`` (``actuator_controls_0`` or the torque
and thrust setpoints) and ``vehicle_rates_setpoint.roll/pitch/yaw``; ArduPilot
``RATE.RDes/PDes/YDes`` and the RC sticks ``ardupilot.aileron`` ... ; a table file: its
columns (the first eight). The overview adds the body rates and the roll and pitch angles.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flightid.logs.excitation import Segment, detect_excitation
from flightid.logs.modes import ModeInterval, SysIdRun, mode_intervals, sysid_runs
from flightid.logs.streams import LogContents, StreamSummary, read_log, summarize_stream

__all__ = ["Inspection", "inspect_log", "inspection_text", "DEFAULT_INPUTS"]

DEFAULT_INPUTS = (
    "px4.aileron",
    "px4.elevator",
    "px4.rudder",
    "px4.throttle",
    "vehicle_rates_setpoint.roll",
    "vehicle_rates_setpoint.pitch",
    "vehicle_rates_setpoint.yaw",
    "RATE.RDes",
    "RATE.PDes",
    "RATE.YDes",
    "ardupilot.aileron",
    "ardupilot.elevator",
    "ardupilot.rudder",
    "ardupilot.throttle",
)
DEFAULT_RESPONSES = (
    "px4.p",
    "px4.q",
    "px4.r",
    "px4.roll",
    "px4.pitch",
    "ardupilot.p",
    "ardupilot.q",
    "ardupilot.r",
    "ardupilot.roll",
    "ardupilot.pitch",
)
MAX_TABLE_CHANNELS = 8


@dataclass(frozen=True)
class Inspection:
    """What ``inspect_log`` found.

    Attributes:
        contents: the log's streams.
        summaries: per stream its timing and fields.
        modes: flight-mode intervals (time order); runs: system-identification runs.
        inputs: the channels searched for excitation; plotted: the channels of the figure
            (inputs first).
        segments: the excitation segments of all inputs, in time order.
    """

    contents: LogContents
    summaries: tuple[StreamSummary, ...]
    modes: tuple[ModeInterval, ...]
    runs: tuple[SysIdRun, ...]
    inputs: tuple[str, ...]
    plotted: tuple[str, ...]
    segments: tuple[Segment, ...]

    def channel_data(self, name: str) -> tuple[np.ndarray, np.ndarray, str]:
        return self.contents.channel(name)


def _default_channels(contents: LogContents) -> tuple[list[str], list[str]]:
    if contents.kind == "table":
        fields = list(contents.streams[0].fields)[:MAX_TABLE_CHANNELS]
        return fields, fields
    inputs = [c for c in DEFAULT_INPUTS if contents.has_channel(c)]
    responses = [c for c in DEFAULT_RESPONSES if contents.has_channel(c)]
    return inputs, inputs + responses


def inspect_log(
    path: str | Path,
    channels: Sequence[str] | None = None,
    *,
    format: str = "auto",
    time: str | None = None,
    vehicle: str | None = None,
) -> Inspection:
    """Read a log and find its streams' timing, modes and excitation segments.
    ``channels``: the channels to search and plot (``stream.field`` or built-in names;
    default: the module docstring's); an unknown one is a ``ChannelError``."""
    contents = read_log(path, format, time)
    if channels:
        inputs = list(dict.fromkeys(channels))
        for name in inputs:
            contents.channel(name)  # unknown names fail here, listing the streams
        plotted = inputs
    else:
        inputs, plotted = _default_channels(contents)
    _, end = contents.span_s
    segments = []
    for name in inputs:
        t, values, unit = contents.channel(name)
        segments += detect_excitation(t, values, name, unit)
    segments.sort(key=lambda s: (s.start_s, s.channel))
    return Inspection(
        contents,
        tuple(summarize_stream(s) for s in contents.streams),
        tuple(mode_intervals(contents.streams, end, vehicle)),
        tuple(sysid_runs(contents.streams)),
        tuple(inputs),
        tuple(plotted),
        tuple(segments),
    )


def _fields_words(fields: dict[str, str], limit: int = 6) -> str:
    shown = [f"{k} [{u}]" if u else k for k, u in list(fields.items())[:limit]]
    more = len(fields) - limit
    return ", ".join(shown) + (f", … (+{more})" if more > 0 else "")


def _ms(seconds: float) -> str:
    return "–" if not math.isfinite(seconds) else f"{seconds * 1000:.2f}"


def _hz(rate: float) -> str:
    """A stream's rate; "–" where it has none (one sample, or every sample at one stamp)."""
    return "–" if not math.isfinite(rate) else f"{rate:.2f}"


def inspection_text(inspection: Inspection) -> str:
    """The printed report: header, streams, modes, SysID runs and excitation segments."""
    c = inspection.contents
    start, stop = c.span_s
    lines = [
        f"{c.path} ({c.kind_words}): {len(c.streams)} stream(s), "
        f"{start:.3f} .. {stop:.3f} s ({stop - start:.1f} s)",
        "",
        "streams (rate = 1/median interval; jitter = std of the regular intervals; "
        "drop-outs: intervals > 2 × median)",
        f"  {'stream':<30} {'samples':>8} {'rate Hz':>9} {'jitter ms':>10} "
        f"{'max gap ms':>11} {'drop-outs':>9}  fields [unit]",
    ]
    for s in inspection.summaries:
        lines.append(
            f"  {s.name:<30} {s.samples:>8d} {_hz(s.rate_hz):>9} {_ms(s.jitter_s):>10} "
            f"{_ms(s.max_interval_s):>11} {s.dropouts:>9d}  {_fields_words(s.fields)}"
        )
    lines.append("")
    if inspection.modes:
        lines.append(f"flight modes ({inspection.modes[0].source})")
        lines.append(f"  {'mode':<22} {'number':>6} {'start s':>10} {'stop s':>10} {'length s':>9}")
        for m in inspection.modes:
            stop_m = min(m.stop_s, stop)
            lines.append(
                f"  {m.name:<22} {m.number:>6d} {m.start_s:>10.3f} {stop_m:>10.3f} "
                f"{stop_m - m.start_s:>9.2f}"
            )
    else:
        lines.append("flight modes: none recorded")
    if inspection.runs:
        lines += ["", "system-identification runs (SIDD, settings from SIDS)"]
        for r in inspection.runs:
            band = r.band_hz
            band_words = f", {band[0]:g}–{band[1]:g} Hz" if band else ""
            magnitude = r.settings.get("Mag")
            mag_words = f", magnitude {magnitude:g}" if magnitude is not None else ""
            lines.append(f"  {r.start_s:.3f} .. {r.stop_s:.3f} s: {r.axis}{mag_words}{band_words}")
    lines += ["", "excitation segments (ratio = 20·log10(RMS(x − x₀) / quiet noise σ))"]
    if not inspection.inputs:
        lines.append("  no usual input channel in this log; name the inputs with --channels")
    elif not inspection.segments:
        lines.append(f"  none in {', '.join(inspection.inputs)}")
    else:
        lines.append(
            f"  {'channel':<30} {'kind':<10} {'start s':>10} {'stop s':>10} "
            f"{'band Hz':>14} {'amplitude':>11} {'ratio dB':>9}"
        )
        for g in inspection.segments:
            band = f"{g.band_hz[0]:.3g}–{g.band_hz[1]:.3g}"
            amplitude = f"{g.amplitude:.4g}" + (f" {g.unit}" if g.unit else "")
            lines.append(
                f"  {g.channel:<30} {g.kind:<10} {g.start_s:>10.3f} {g.stop_s:>10.3f} "
                f"{band:>14} {amplitude:>11} {g.ratio_db:>9.1f}"
            )
    return "\n".join(lines) + "\n"
