"""``flightid paper exampleN``: the RP-1153 examples, printed beside the paper's tables."""

from __future__ import annotations

import argparse
import sys

__all__ = ["register"]


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "paper", help="run the examples of NASA RP-1153 and compare with the paper's tables"
    )
    examples = parser.add_subparsers(dest="example", metavar="EXAMPLE")

    one = examples.add_parser("example1", help="linear system, no noise: FPS, MNR, MNRES")
    one.add_argument("--json", action="store_true", help="print one JSON document on stdout")
    one.add_argument(
        "--methods", default="fps,mnr,mnres", help="comma-separated solvers (default fps,mnr,mnres)"
    )
    one.set_defaults(func=_example1)

    two = examples.add_parser("example2", help="linear system, pulse input, noise: MNR, MNRES")
    two.add_argument(
        "--case",
        type=int,
        choices=(1, 2),
        required=True,
        help="1: sigma 1e-4, 5 s of data; 2: sigma 1e-3, 3 s",
    )
    two.add_argument("--seed", type=int, default=1, help="noise seed (default 1)")
    two.add_argument(
        "--methods", default="mnr,mnres", help="comma-separated solvers (default mnr,mnres)"
    )
    two.add_argument("--json", action="store_true", help="print one JSON document on stdout")
    two.set_defaults(func=_example2)

    three = examples.add_parser(
        "example3", help="nonlinear lateral model of a light airplane, three noise cases"
    )
    three.add_argument(
        "--case",
        type=int,
        choices=(1, 2, 3),
        required=True,
        help="1: no noise; 2: table IV noise; 3: twice that",
    )
    three.add_argument("--seed", type=int, default=None, help="noise seed")
    three.add_argument("--json", action="store_true", help="print one JSON document on stdout")
    three.add_argument(
        "--plot",
        metavar="DIR",
        default=None,
        help="write measured-vs-predicted and input figures (PNG) to DIR",
    )
    three.add_argument(
        "--accuracy",
        choices=("profile", "search", "all"),
        default=None,
        help="add confidence limits from the likelihood region",
    )
    three.set_defaults(func=_example3)
    parser.set_defaults(func=lambda args: parser.print_help() or 2)


def _methods(text: str, allowed: tuple[str, ...]) -> tuple[str, ...]:
    from flightid.errors import InputError

    methods = tuple(m.strip().lower() for m in text.split(",") if m.strip())
    unknown = [m for m in methods if m not in allowed]
    if unknown or not methods:
        raise InputError(f"--methods: expected a comma-separated subset of {allowed}, got {text!r}")
    return methods


def _emit(run, as_json: bool) -> int:
    from flightid.paper.examples12 import comparison_table

    if as_json:
        from flightid.jsonout import dumps

        sys.stdout.write(dumps(run.to_dict()) + "\n")
    else:
        print(comparison_table(run))
    return 0


def _example1(args: argparse.Namespace) -> int:
    from flightid.paper.examples12 import run_example1

    return _emit(run_example1(_methods(args.methods, ("fps", "mnr", "mnres"))), args.json)


def _example2(args: argparse.Namespace) -> int:
    from flightid.paper.examples12 import run_example2

    methods = _methods(args.methods, ("fps", "mnr", "mnres"))
    return _emit(run_example2(args.case, methods, seed=args.seed), args.json)


def _example3(args: argparse.Namespace) -> int:
    if args.plot is not None:
        from pathlib import Path

        from flightid.errors import InputError

        # checked before the estimation, not after it
        plot = Path(args.plot)
        if plot.exists() and not plot.is_dir():
            raise InputError(f"--plot {plot}: exists and is a file, not a folder")
        if not plot.exists() and not plot.absolute().parent.is_dir():
            raise InputError(f"--plot {plot}: the parent folder does not exist; create it first")
    try:
        from flightid.paper import example3
    except ImportError as exc:  # pragma: no cover - present once the aircraft package lands
        print(f"flightid: example 3 is not available: {exc}", file=sys.stderr)
        return 1
    return example3.cli_main(args)
