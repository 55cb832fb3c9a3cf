"""The time base of a record: stored stamps put on a uniform grid t_k = t_0 + k·Δt only
where that moves no sample by more than half an interval.

Three ways a record's rows become uniform samples, each checked here:

* ``regrid``: stored stamps that are uniform up to rounding or jitter (a declared ``dt``,
  or stamps rounded in the file) are replaced by t_0 + k·Δt. The largest move
  |t_stored,k − (t_0 + k·Δt)| must stay within Δt/2; beyond that the grid would stretch or
  compress time, and ``TimeBaseError`` says by how much.
* ``join_recordings``: a file holding several recordings one after the other (the time
  steps back, or jumps forward by more than 1.5 typical intervals, between them) becomes one
  record at the recordings' common interval; each recording keeps its own time to within
  half an interval. Joining closes the breaks between recordings; it never changes the rate.
* anything else (jitter, drop-outs, several rates) is resampled on purpose
  (``flightid.data.resample``).

Every function returns a line saying what it did, kept with the data (``FlightData.notes``).
"""

from __future__ import annotations

import numpy as np

from flightid.errors import InputError

__all__ = [
    "TimeBaseError",
    "HALF_INTERVAL",
    "MIN_RECORDING_SAMPLES",
    "JOIN_BREAK_INTERVALS",
    "largest_move",
    "regrid",
    "join_recordings",
]


class TimeBaseError(InputError):
    """A time base that cannot be made uniform without moving samples (re-timing), or a
    resampling setting that cannot be applied."""


# the largest move of a stored sample that re-gridding may make, in intervals
HALF_INTERVAL = 0.5
# a recording of fewer samples is taken for jittery stamps, not for a recording (join)
MIN_RECORDING_SAMPLES = 5
# between recordings the time steps back or jumps forward by more than this many intervals
JOIN_BREAK_INTERVALS = 1.5

_PROPOSAL = (
    "declare resample_hz = R to resample every channel onto a uniform grid at R Hz "
    "(anti-aliased, split at gaps), or use start/stop to pick a uniform part"
)


def largest_move(stored: np.ndarray, grid: np.ndarray) -> tuple[float, int]:
    """(max_k |stored_k − grid_k| in s, the 0-based row k where it happens)."""
    moves = np.abs(np.asarray(stored, dtype=float) - np.asarray(grid, dtype=float))
    k = int(np.argmax(moves))
    return float(moves[k]), k


def _moved_too_far(what: str, source: str, stored, grid, step: float, k: int, move: float):
    return TimeBaseError(
        f"{what}: re-gridding {source} at {step:.6g} s would move row {k + 1} from its stored "
        f"t = {stored[k]:.6g} s to {grid[k]:.6g} s, by {move:.4g} s ({move / step:.3g} "
        f"intervals; at most half an interval is allowed): the stored rows span "
        f"{stored[-1] - stored[0]:.6g} s, the grid {grid[-1] - grid[0]:.6g} s; {_PROPOSAL}; "
        "allow_retime = true re-times the rows anyway"
    )


def regrid(
    stored: np.ndarray,
    step_s: float,
    *,
    what: str,
    source: str,
    allow_retime: bool = False,
) -> tuple[np.ndarray, str]:
    """The grid t_k = t_0 + k·Δt over the stored stamps (t_0 the first), and a note.

    Args:
        stored: the stored stamps of the rows, s (strictly increasing not required).
        step_s: Δt, s.
        what: the setting that asks for it, for messages (``"dt"``, ``"time"``).
        source: the file, for messages.
        allow_retime: accept moves beyond half an interval (named in the note).

    Raises:
        TimeBaseError: a row would move by more than Δt/2, unless ``allow_retime``.
    """
    stored = np.asarray(stored, dtype=float)
    # t_k = t_0 + k·Δt
    grid = stored[0] + np.arange(stored.shape[0]) * float(step_s)
    move, k = largest_move(stored, grid)
    if move > HALF_INTERVAL * step_s and not allow_retime:
        raise _moved_too_far(what, source, stored, grid, step_s, k, move)
    note = (
        f"time ({what}): stored stamps replaced by t_0 + k·{step_s:.6g} s; rows moved by at "
        f"most {move:.3g} s ({move / step_s:.3g} interval)"
    )
    if move > HALF_INTERVAL * step_s:
        note += " — more than half an interval, accepted by allow_retime = true"
    return grid, note


def _recordings(stored: np.ndarray) -> tuple[list[slice], float]:
    """The recordings of joined rows (split where the time steps back or jumps by more than
    ``JOIN_BREAK_INTERVALS`` typical intervals) and that typical interval (the median of the
    positive intervals), s."""
    steps = np.diff(stored)
    positive = steps[steps > 0]
    if positive.size == 0:
        raise TimeBaseError(
            "gaps = 'join': the stored time never increases; expected recordings of "
            "increasing stamps"
        )
    typical = float(np.median(positive))
    cuts = np.flatnonzero((steps <= 0) | (steps > JOIN_BREAK_INTERVALS * typical)) + 1
    edges = [0, *cuts.tolist(), stored.shape[0]]
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True)], typical


def join_recordings(
    stored: np.ndarray, *, source: str, allow_retime: bool = False
) -> tuple[np.ndarray, list[slice], str]:
    """Rows holding several recordings one after another → one uniform record.

    The common interval is the pooled mean interval of the recordings,
        Δt = Σ_r (t_r,last − t_r,first) / Σ_r (n_r − 1),
    and the joined time is t_k = t_0 + k·Δt. Each recording must keep its own time:
    |t_r,j − (t_r,0 + j·Δt)| ≤ Δt/2 for every row j of recording r (so recordings at
    different rates, or jittery stamps read as many tiny recordings, are refused).

    Returns:
        (joined time, the recordings as row slices, a note naming the closed breaks).

    Raises:
        TimeBaseError: a recording shorter than ``MIN_RECORDING_SAMPLES`` rows, or a row
        that would move by more than half an interval within its recording.
    """
    stored = np.asarray(stored, dtype=float)
    recordings, typical = _recordings(stored)
    short = [r for r in recordings if r.stop - r.start < MIN_RECORDING_SAMPLES]
    if short:
        r = short[0]
        raise TimeBaseError(
            f"gaps = 'join': {source} splits into {len(recordings)} recordings where the time "
            f"steps back or jumps by more than {JOIN_BREAK_INTERVALS:g} × {typical:.6g} s, and "
            f"{len(short)} of them hold fewer than {MIN_RECORDING_SAMPLES} rows (the first: "
            f"rows {r.start + 1}..{r.stop}, t = {stored[r.start]:.6g}..{stored[r.stop - 1]:.6g}"
            f" s); these are uneven stamps, not recordings: {_PROPOSAL}"
        )
    spans = sum(float(stored[r.stop - 1] - stored[r.start]) for r in recordings)
    # Δt = Σ_r (t_r,last − t_r,first) / Σ_r (n_r − 1)
    step = spans / sum(r.stop - r.start - 1 for r in recordings)
    worst = (0.0, 0)
    for r in recordings:
        own = stored[r]
        move, k = largest_move(own, own[0] + np.arange(own.shape[0]) * step)
        worst = max(worst, (move, r.start + k))
    move, k = worst
    if move > HALF_INTERVAL * step and not allow_retime:
        raise TimeBaseError(
            f"gaps = 'join': joined at their common interval {step:.6g} s, row {k + 1} of "
            f"{source} (stored t = {stored[k]:.6g} s) would move by {move:.4g} s "
            f"({move / step:.3g} intervals) within its recording; at most half an interval "
            f"is allowed (the recordings are uneven or at different rates); {_PROPOSAL}"
        )
    # t_k = t_0 + k·Δt
    joined = stored[0] + np.arange(stored.shape[0]) * step
    breaks = [
        f"{stored[r.start - 1]:.6g} → {stored[r.start]:.6g} s" for r in recordings[1:] if r.start
    ]
    note = (
        f"time (gaps = 'join'): {len(recordings)} recording(s) joined at their common "
        f"interval {step:.6g} s; rows moved within their recording by at most {move:.3g} s "
        f"({move / step:.3g} interval)"
    )
    if breaks:
        shown = ", ".join(breaks[:5]) + (f", … ({len(breaks)} in all)" if len(breaks) > 5 else "")
        note += f"; breaks closed: {shown}"
    return joined, recordings, note
