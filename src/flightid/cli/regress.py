"""``flightid regress CASE.toml [--json] [--data-dir DIR]``: stepwise regression of a case.

Text output: the step history and the least-squares table of each coefficient.
JSON output (``--json``), the contract read by the acceptance checks:

    {"coefficients": {"Cm": {"selected": [...], "parameters": [{"name", "value", "std"}],
                             "r2": float, "pse": float, "steps": [...], ...}, ...}}
"""

from __future__ import annotations

import argparse
import json

from flightid.regression.case import load_case, run_case


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "regress",
        help="model structure determination by modified stepwise regression",
        description=(
            "Run modified stepwise regression for every coefficient of a case file and print "
            "the selected terms with their least-squares estimates and statistics."
        ),
    )
    parser.add_argument("case", help="stepwise case file (TOML)")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument(
        "--data-dir",
        default=None,
        help="directory holding the data files (default: $FLIGHTID_DATA, then the case's "
        "data.data_dir, then ../../../shared/data relative to the case file)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    case = load_case(args.case)
    results = run_case(case, args.data_dir)
    if args.json:
        payload = {"coefficients": {name: r.to_dict() for name, r in results.items()}}
        print(json.dumps(payload, indent=2))
    else:
        for result in results.values():
            print(result.summary())
            print()
    return 0
