"""``flightid`` console entry point.

Each sub-command lives in its own module ``flightid.cli.<name>`` exposing
``register(subparsers)``, which adds its parser and sets ``func(args) -> int``.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from flightid import __version__
from flightid.errors import FlightIdError

# Sub-command modules, in the order they appear in --help.
SUBCOMMAND_MODULES = ("paper", "regress", "run", "validate")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="flightid",
        description="Airplane parameter estimation from flight data (NASA RP-1153 methodology).",
    )
    parser.add_argument("--version", action="version", version=f"flightid {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMAND_MODULES:
        try:
            module = importlib.import_module(f"flightid.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"flightid.cli.{name}":
                continue  # sub-command not built yet
            raise
        module.register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except FlightIdError as exc:
        print(f"flightid: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
