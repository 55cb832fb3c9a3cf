"""Case-file lines for the excitation segments of a log: one ``[[data.maneuvers]]`` table per
segment with ``file``, ``name``, ``start`` and ``stop`` (s, log time), ready to paste into a
case (``flightid inspect LOG --case-lines``).

Each segment is widened by ``pad_s`` on both sides (default 1 s: the trim before the input
and the response after it), clipped to the log's span, and rounded outwards to the
millisecond so that the padded segment is always inside [start, stop].
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path

from flightid.errors import InputError
from flightid.logs.excitation import Segment

__all__ = ["case_lines", "maneuver_names"]


def maneuver_names(segments: Sequence[Segment]) -> list[str]:
    """``doublet_1``, ``3211_1``, ``sweep_2``, ...: the kind and its running number."""
    counts: dict[str, int] = {}
    names = []
    for segment in segments:
        slug = re.sub(r"\W+", "", segment.kind.replace("-", "")) or "segment"
        counts[slug] = counts.get(slug, 0) + 1
        names.append(f"{slug}_{counts[slug]}")
    return names


def _toml_string(text: str) -> str:
    escaped = text.replace("\\", "\\\\").replace('"', '\\"')
    return f'"{escaped}"'


def case_lines(
    segments: Sequence[Segment],
    file: str | Path,
    span_s: tuple[float, float],
    pad_s: float = 1.0,
    variable: str | None = None,
) -> str:
    """TOML text: a comment header, then one ``[[data.maneuvers]]`` per segment (in time
    order) with its padded ``start``/``stop`` (s) and a comment naming the channel, kind,
    band and excitation ratio. ``span_s``: the log's first and last time stamp (s);
    ``variable``: the streams to read, written into each table where given."""
    if isinstance(pad_s, bool) or not isinstance(pad_s, (int, float)) or not pad_s >= 0:
        raise InputError(f"pad: expected a number of seconds ≥ 0, got {pad_s!r}")
    lo, hi = float(span_s[0]), float(span_s[1])
    ordered = sorted(segments, key=lambda s: (s.start_s, s.channel))
    lines = [
        f"# {len(ordered)} excitation segment(s) found by flightid inspect in {Path(file).name}",
        f"# (each widened by {pad_s:g} s on both sides, within the log's {lo:.3f} .. {hi:.3f} s)",
    ]
    for segment, name in zip(ordered, maneuver_names(ordered), strict=True):
        # rounded outwards to the ms: floor(start·1000)/1000, ceil(stop·1000)/1000
        start = math.floor(max(lo, segment.start_s - pad_s) * 1000.0) / 1000.0
        stop = math.ceil(min(hi, segment.stop_s + pad_s) * 1000.0) / 1000.0
        band = f"{segment.band_hz[0]:.3g}–{segment.band_hz[1]:.3g} Hz"
        lines += [
            "",
            f"# {segment.channel}: {segment.kind} {segment.start_s:.3f} .. "
            f"{segment.stop_s:.3f} s, {band}, {segment.ratio_db:.1f} dB above quiet",
            "[[data.maneuvers]]",
            f"file = {_toml_string(str(file))}",
            f"name = {_toml_string(name)}",
        ]
        if variable:
            lines.append(f"variable = {_toml_string(variable)}")
        lines += [f"start = {start:.3f}", f"stop = {stop:.3f}"]
    return "\n".join(lines) + "\n"
