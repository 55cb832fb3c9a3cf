"""``flightid regress CASE.toml [...]``: an alias of ``flightid run`` (the same options).

There is one case language: a stepwise regression is a ``[[stages]]`` entry with
``kind = "stepwise"`` (docs/cases.md, "One case language"), and ``flightid run`` runs every
stage of the file. ``flightid regress`` prints a one-line notice on stderr (unless
``--quiet``) and does exactly what ``flightid run`` does. ``--ml`` is gone: an output-error
stage (``kind = "output_error"``, ``from = "previous"``) in the file says it.
"""

from __future__ import annotations

import argparse

NOTICE = "`flightid regress` is an alias of `flightid run`: it runs every stage of the case file"


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "regress",
        help="alias of `flightid run` (stepwise regression is a [[stages]] entry of the case)",
        description=(
            "Alias of `flightid run`: runs every stage of the case file (stepwise regression, "
            "output error, accuracy, prediction). " + NOTICE + "."
        ),
    )
    from flightid.cli.run import add_run_arguments

    add_run_arguments(parser)
    parser.add_argument(
        "--ml",
        action="store_true",
        help="removed: put a [[stages]] entry with kind = 'output_error' and "
        "from = 'previous' in the case file",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from flightid.cases.checks import CaseError
    from flightid.cli import run as run_command

    if args.ml:
        raise CaseError(
            "--ml: removed; the output-error stage is part of the case file now: "
            '[[stages]] kind = "output_error", from = "previous" after the stepwise stage '
            "(docs/cases.md, 'One case language'); `flightid run` runs every stage"
        )
    if not args.quiet:
        from flightid.cases.run import stderr_progress

        stderr_progress(NOTICE)
    return run_command.run(args)
