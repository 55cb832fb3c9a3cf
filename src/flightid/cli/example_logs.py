"""``flightid example-logs --out DIR [--overwrite]``: write the two example flight logs.

Writes ``multirotor_roll_rate.ulg`` (PX4 ULog, a multirotor roll-rate loop) and
``fixedwing_roll.bin`` (ArduPilot DataFlash, a fixed-wing roll mode) into DIR, simulated
with fixed seeds (the same bytes every time; ``flightid.examples.logs``), and prints what
each holds and the truth it was simulated from. DIR is created if missing; an existing file
of either name is refused unless ``--overwrite`` (which replaces those two files only).
Needs pyulog and pymavlink (the ``px4`` and ``ardupilot`` extras).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from flightid.errors import InputError


class ExampleLogsError(InputError):
    """The output folder cannot take the example logs (a file there would be replaced)."""


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "example-logs",
        help="write the example flight logs (a PX4 ULog and an ArduPilot DataFlash log, "
        "simulated with a known truth) into a folder",
        description=(
            "Write multirotor_roll_rate.ulg (PX4 ULog: a multirotor roll-rate loop, "
            "second order with an input delay) and fixedwing_roll.bin (ArduPilot DataFlash: "
            "a fixed-wing roll mode) into DIR, and print the truth they were simulated from. "
            "Seeded: the same files every time."
        ),
    )
    parser.add_argument("--out", required=True, metavar="DIR", help="folder for the two logs")
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace multirotor_roll_rate.ulg and fixedwing_roll.bin in DIR if present",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from flightid.examples.logs import (
        FIXEDWING_FILE,
        MULTIROTOR_FILE,
        write_fixedwing_dataflash,
        write_multirotor_ulog,
    )

    if not str(args.out).strip():
        raise ExampleLogsError("--out: expected a folder name, got an empty string")
    folder = Path(args.out)
    if folder.exists() and not folder.is_dir():
        raise ExampleLogsError(f"--out {folder}: exists and is not a folder")
    targets = [folder / MULTIROTOR_FILE, folder / FIXEDWING_FILE]
    present = [str(t) for t in targets if t.exists() or t.is_symlink()]
    if present and not args.overwrite:
        raise ExampleLogsError(
            f"--out {folder}: {', '.join(present)} already exist; pass --overwrite to "
            "replace them (nothing else in the folder is touched)"
        )
    folder.mkdir(parents=True, exist_ok=True)
    logs = [
        write_multirotor_ulog(targets[0], overwrite=args.overwrite),
        write_fixedwing_dataflash(targets[1], overwrite=args.overwrite),
    ]
    for log in logs:
        _describe(log)
    return 0


def _describe(log) -> None:
    """What a written log holds and its truth, a few lines on stdout."""
    size_kb = log.path.stat().st_size / 1024
    print(f"{log.path}  ({size_kb:.0f} KiB, seed {log.seed})")
    print("  truth: " + ", ".join(f"{k} = {v:g}" for k, v in log.parameters.items()))
    rates = ", ".join(f"{name} {hz:g} Hz" for name, hz in log.rates_hz.items())
    print(f"  streams: {rates}")
    modes = ", ".join(f"{m} {a:.1f}–{b:.1f} s" for m, a, b in log.modes)
    print(f"  modes: {modes}")
    maneuvers = ", ".join(f"{k} {a:.2f}–{b:.2f} s" for k, a, b in log.maneuvers)
    print(f"  maneuvers: {maneuvers}")
    dropouts = ", ".join(f"{a:.3f} s ({d * 1000:.0f} ms)" for a, d in log.dropouts)
    print(f"  drop-outs: {dropouts}")
