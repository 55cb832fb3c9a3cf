"""The example of docs/inspect.md: ``flightid inspect`` on a 40 s PX4 log it writes.

    python docs/inspect_numbers.py [--record] [--write] [--check]

Writes ``flight.ulg`` (seeded; needs pyulog): vehicle_status in Position mode, Stabilized
from 10 to 30 s, Position again; roll, pitch and yaw rate setpoints at about 200 Hz with
stamp jitter (a roll-rate doublet of 0.7 s pulses from 12 s, a pitch-rate sweep from 0.5 to
5 Hz between 18 and 28 s, 0.005 rad/s noise on all three); the attitude quaternion at
100 Hz. Then runs, in the log's folder, ``flightid inspect flight.ulg --out inspect_out``
and ``flightid inspect flight.ulg --case-lines`` and prints both outputs as the guide
quotes them. A few seconds.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import case_numbers as cn
import numpy as np


def _stamps_s(rng: np.random.Generator, stop_s: float, rate_hz: float, jitter_s: float):
    """Stamps at rate_hz from 0 with Gaussian jitter of jitter_s, strictly increasing."""
    nominal = np.arange(0.0, stop_s, 1.0 / rate_hz)
    return np.sort(np.clip(nominal + rng.normal(0.0, jitter_s, nominal.size), 0.0, None))


def write_flight_log(path: Path, seed: int = 11) -> Path:
    from flightid.data.formats import Stream
    from flightid.data.logwrite import write_ulog

    rng = np.random.default_rng(seed)
    t = _stamps_s(rng, 40.0, 200.0, 0.0008)
    # a doublet: +0.5 for 0.7 s, −0.5 for 0.7 s, from 12 s
    roll = 0.5 * (((t >= 12.0) & (t < 12.7)).astype(float) - ((t >= 12.7) & (t < 13.4)))
    # a linear sweep 0.5 → 5 Hz over 18–28 s: phase 2π (f0 τ + (f1 − f0) τ² / (2T))
    tau = t - 18.0
    sweep = np.sin(2 * np.pi * (0.5 * tau + 4.5 * tau**2 / 20.0))
    pitch = np.where((tau >= 0) & (tau < 10.0), 0.4 * sweep, 0.0)
    noise = rng.normal(0.0, 0.005, (3, t.size))
    status_t = np.arange(0.0, 40.0, 0.5)
    attitude_t = np.arange(0.0, 40.0, 0.01)
    streams = [
        Stream(
            "vehicle_status",
            status_t,
            {"nav_state": np.select([status_t < 10, status_t < 30], [2, 15], 2)},
        ),
        Stream(
            "vehicle_rates_setpoint",
            t,
            {"roll": roll + noise[0], "pitch": pitch + noise[1], "yaw": noise[2]},
        ),
        Stream(
            "vehicle_attitude",
            attitude_t,
            {f"q_{i}": np.full(attitude_t.size, 1.0 if i == 0 else 0.0) for i in range(4)},
        ),
    ]
    types = {"vehicle_status": {"nav_state": "uint8_t"}}
    return write_ulog(path, streams, {"MC_ROLLRATE_P": 0.15}, field_types=types)


def _inspect(folder: Path, *arguments: str) -> str:
    environment = dict(os.environ, PYTHONPATH=str(cn.ROOT / "src"))
    command = [sys.executable, "-m", "flightid.cli.main", "inspect", "flight.ulg", *arguments]
    done = subprocess.run(
        command, capture_output=True, text=True, env=environment, cwd=folder, check=True
    )
    # the command prints the folder it wrote as given, here the log's own folder
    return done.stdout.rstrip("\n").replace(f"{folder}/", "")


def example() -> tuple[str, str]:
    """The report and the case lines, each as a code block with its command."""
    with tempfile.TemporaryDirectory() as folder:
        write_flight_log(Path(folder) / "flight.ulg")
        report = _inspect(Path(folder), "--out", "inspect_out")
        lines = _inspect(Path(folder), "--case-lines")
    return (
        f"```\n$ flightid inspect flight.ulg --out inspect_out\n{report}\n```",
        f"```\n$ flightid inspect flight.ulg --case-lines\n{lines}\n```",
    )


def build(data_dir: str | None) -> list[str]:
    report, lines = example()
    return [cn.region("inspect-report", report), cn.region("inspect-case-lines", lines)]


if __name__ == "__main__":
    raise SystemExit(cn.main("inspect.md", "inspect_numbers", build))
