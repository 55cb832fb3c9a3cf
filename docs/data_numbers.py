"""The measured numbers of docs/data.md: resampling a jittery log with a gap.

    python docs/data_numbers.py [--record] [--write] [--check]

Writes ``roll.csv`` (seeded): a roll-rate channel stamped at intervals drawn uniformly in
4.0–5.6 ms (about 208 Hz) for 19.2 s, without samples from 12.0 to 12.4 s, holding a 3 Hz
motion sin(2π·3t) rad/s and 0.3 rad/s of 80 Hz vibration. Then prints what flightid says
about it: the refusal without a resampling method, the refusal of ``dt`` at the median
interval, the segments and notes with ``resample_hz = 100``, and how well the resampled
channel follows the 3 Hz motion against plain linear interpolation onto the same grid
(more than 0.5 s from the segment ends: the largest difference, and the gain and delay of
the 3 Hz component fitted by least squares). A second.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import case_numbers as cn
import numpy as np

F_HZ = 3.0  # the motion
VIBRATION_HZ, VIBRATION = 80.0, 0.3  # rad/s


def roll_csv(folder: Path, seed: int = 7) -> tuple[Path, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.004, 0.0056, 5000))])
    t = t[(t <= 19.2) & ~((t > 12.0) & (t < 12.4))]
    p = np.sin(2 * np.pi * F_HZ * t) + VIBRATION * np.sin(2 * np.pi * VIBRATION_HZ * t)
    path = folder / "roll.csv"
    np.savetxt(path, np.column_stack([t, p]), delimiter=",", header="t,p", comments="")
    return path, t, p


def _refusal(load, **options) -> str:
    from flightid.errors import InputError

    try:
        load(**options)
    except InputError as error:
        return str(error)
    raise SystemExit(f"not refused: {options}")


def _fit(values: np.ndarray, times: np.ndarray) -> tuple[float, float]:
    """Gain and delay (s) of the 3 Hz component: y = a·sin(ω(t − τ)) by least squares."""
    omega = 2 * np.pi * F_HZ
    basis = np.column_stack([np.sin(omega * times), np.cos(omega * times)])
    s, c = np.linalg.lstsq(basis, values, rcond=None)[0]
    # a sin(ωt − ωτ) = a cos(ωτ) sin ωt − a sin(ωτ) cos ωt
    return float(np.hypot(s, c)), float(-np.arctan2(c, s) / omega)


def resampling() -> str:
    from flightid.data.loaders import load_flight_data, load_flight_segments

    with tempfile.TemporaryDirectory() as folder:
        path, stamps, values = roll_csv(Path(folder))
        spec = {"path": path, "time": "t", "outputs": {"p": "p"}}
        uneven = _refusal(load_flight_data, **spec)
        median = float(np.median(np.diff(stamps)))
        regrid = _refusal(load_flight_data, dt=round(median, 8), **spec)
        segments = load_flight_segments(resample_hz=100, **spec)
        # the messages name the file as given; here as the user's own roll.csv
        uneven, regrid = (m.replace(f"{folder}/", "") for m in (uneven, regrid))
    pieces = ", ".join(
        f"`{s.name}` ({s.time[0]:.4g}–{s.time[-1]:.4g} s, {s.time.size} samples)" for s in segments
    )
    lines = ["Refused as stored:", "", "```text", uneven, "```", ""]
    lines += [f"Refused with dt = {median:.8g} s (the median interval):", "", "```text"]
    lines += [regrid, "```", ""]
    lines += [f"With resample_hz = 100: {len(segments)} maneuvers, {pieces}; the notes of the"]
    lines += ["first:", "", "```text", *segments[0].notes, "```", ""]
    found = {"resampled (flightid)": [], "linear interpolation": []}
    for segment in segments:
        grid = segment.time
        inner = (grid > grid[0] + 0.5) & (grid < grid[-1] - 0.5)
        found["resampled (flightid)"].append((grid[inner], segment.output("p")[inner]))
        found["linear interpolation"].append((grid[inner], np.interp(grid[inner], stamps, values)))
    rows = []
    for label, parts in found.items():
        times = np.concatenate([t for t, _ in parts])
        channel = np.concatenate([y for _, y in parts])
        gain, delay = _fit(channel, times)
        # the largest |p − sin(2π·3t)| more than 0.5 s from the segment ends
        error = np.max(np.abs(channel - np.sin(2 * np.pi * F_HZ * times)))
        delay_ms = f"{delay * 1e3:.2f} ms".replace("-", "−")
        rows.append([label, f"{error:.2g}", f"{gain:.4f}", delay_ms])
    heading = ["onto the 100 Hz grid", "largest abs(p − sin 2π·3t), rad/s", "gain at 3 Hz"]
    heading.append("delay at 3 Hz")
    return "\n".join(lines) + "\n" + cn.table(heading, rows)


def build(data_dir: str | None) -> list[str]:
    return [cn.region("data-resampling", resampling())]


if __name__ == "__main__":
    raise SystemExit(cn.main("data.md", "data_numbers", build))
