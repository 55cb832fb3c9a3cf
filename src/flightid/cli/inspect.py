"""``flightid inspect LOG [--out DIR [--overwrite]] [--channels ...] [--case-lines]``.

Shows a flight log as an engineer first wants to see it (``flightid.logs``, docs/inspect.md):
its streams with their rates, jitter, drop-outs and units; the flight-mode intervals and
system-identification runs it records; the excitation segments found in its input channels
(kind, time span, band, excitation ratio). ``--out DIR`` writes overview.png (the chosen
channels with the segments and modes), inspect.txt (the printed report) and segments.toml
(the case lines). ``--case-lines`` prints only the ``[[data.maneuvers]]`` tables of the
segments (valid TOML) instead of the report, to paste into a case.
"""

from __future__ import annotations

import argparse

FORMATS = ("auto", "ulog", "dataflash", "csv", "mat", "parquet", "ascii")


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "inspect",
        help="show a flight log's streams, modes and excitation segments",
        description=(
            "Show what a flight log (PX4 ULog, ArduPilot DataFlash, or a CSV/MATLAB table) "
            "holds: streams with rates and units, flight-mode and SysID intervals, and the "
            "excitation segments (steps, doublets, 3-2-1-1, sweeps, multisines) in its inputs; "
            "optionally the overview figure and the case-file lines for the segments."
        ),
    )
    parser.add_argument("log", help="the log file (.ulg, .bin/.log, .csv, .mat, ...)")
    parser.add_argument(
        "--out",
        default=None,
        help="write overview.png, inspect.txt and segments.toml to this folder (a folder "
        "that already holds flightid output is refused unless --overwrite)",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace the output in --out")
    parser.add_argument(
        "--channels",
        nargs="+",
        default=None,
        metavar="CHANNEL",
        help="channels to search for excitation and plot: stream.field (e.g. "
        "vehicle_rates_setpoint.roll, RATE.RDes), a column of a table, or a built-in signal "
        "(px4.roll, ardupilot.p, ...); several by spaces or commas (default: the log's usual "
        "input channels)",
    )
    parser.add_argument(
        "--case-lines",
        action="store_true",
        help="print only the case-file lines ([[data.maneuvers]] with start/stop) of the "
        "segments found, as TOML",
    )
    parser.add_argument(
        "--pad",
        type=float,
        default=1.0,
        metavar="SECONDS",
        help="widen each segment by this much on both sides in the case lines (default 1 s)",
    )
    parser.add_argument(
        "--format", default="auto", choices=FORMATS, help="file format (default: by extension)"
    )
    parser.add_argument(
        "--time", default=None, help="time column of a table file (default: t, time or the first)"
    )
    parser.add_argument(
        "--vehicle",
        default=None,
        choices=("copter", "plane", "rover"),
        help="name ArduPilot modes for this vehicle where the log has no VER message",
    )
    parser.set_defaults(func=run)


def _channel_list(values: list[str] | None) -> list[str] | None:
    if not values:
        return None
    names = [n.strip() for value in values for n in value.split(",") if n.strip()]
    return names or None


def run(args: argparse.Namespace) -> int:
    # imported here: `flightid --help` must not load numpy/scipy
    from pathlib import Path

    from flightid.logs.caselines import case_lines
    from flightid.logs.inspection import inspect_log, inspection_text

    folder = None
    if args.out:
        from flightid.report.folder import ResultFolder

        folder = ResultFolder.open(Path(args.out), overwrite=args.overwrite)
    try:
        inspection = inspect_log(
            args.log,
            _channel_list(args.channels),
            format=args.format,
            time=args.time,
            vehicle=args.vehicle,
        )
        text = inspection_text(inspection)
        lines = case_lines(
            inspection.segments, args.log, inspection.contents.span_s, pad_s=args.pad
        )
        print(lines if args.case_lines else text, end="", flush=True)
        if folder is not None:
            folder.write(lambda tmp: _write(tmp, inspection, text, lines))
            if not args.case_lines:
                print(f"wrote {folder.target}/overview.png, inspect.txt, segments.toml")
    finally:
        if folder is not None:
            folder.release()
    return 0


def _write(tmp, inspection, text: str, lines: str) -> None:
    from flightid.report.log_figures import log_overview_figure, save_log_overview

    channels = [(name, *inspection.channel_data(name)) for name in inspection.plotted]
    figure = log_overview_figure(
        channels,
        inspection.segments,
        inspection.modes,
        inspection.runs,
        title=str(inspection.contents.path.name),
    )
    save_log_overview(figure, tmp / "overview.png")
    (tmp / "inspect.txt").write_text(text, encoding="utf-8")
    (tmp / "segments.toml").write_text(lines, encoding="utf-8")
