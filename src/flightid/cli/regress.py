"""``flightid regress CASE.toml [--ml] [--json] [--data-dir DIR] [--quiet]``: stepwise
regression of a case, and optionally the output-error ML stage it seeds.

Text output: the step history and the least-squares table of each coefficient; with ``--ml``
also the regression-vs-ML table, the estimate summary and the prediction check.
JSON output (``--json``), the contract read by the acceptance checks:

    {"coefficients": {"Cm": {"selected": [...], "parameters": [{"name", "value", "std"}],
                             "r2": float, "pse": float, "steps": [...], ...}, ...},
     "ml": ENTRY}                                           # only with --ml

ENTRY is the estimation entry of ``flightid run`` (``Estimate.to_dict()``: converged, status,
cost, parameters with name/value/initial/std/free, ...) plus ``model``, ``maneuvers``,
``start`` (the regression estimates ML started from), ``constants`` and ``prediction`` (per
``[ml].prediction`` maneuver: outputs, rms_error, r2). The JSON is strict: NaN / ±inf become
null, listed under ``"nonfinite"`` (``flightid.report.jsonout``). ``--ml`` needs the case's ``[ml]``
section (see ``flightid.regression.case``). Progress of the ML stage goes to stderr unless
``--quiet``.
"""

from __future__ import annotations

import argparse

from flightid.cli.run import add_data_dir_argument


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "regress",
        help="model structure determination by modified stepwise regression",
        description=(
            "Run modified stepwise regression for every coefficient of a case file and print "
            "the selected terms with their least-squares estimates and statistics; with --ml "
            "refine them by output-error maximum likelihood."
        ),
    )
    parser.add_argument("case", help="stepwise case file (TOML)")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument(
        "--ml",
        action="store_true",
        help="then run output-error ML seeded by the regression (the case's [ml] section), "
        "with its prediction check",
    )
    add_data_dir_argument(parser)
    parser.add_argument("--quiet", action="store_true", help="no progress messages on stderr")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # imported here, not at the top: `flightid --help` must not load numpy/scipy/numba
    from flightid.regression.case import load_case, run_case, run_ml
    from flightid.report.jsonout import dumps

    case = load_case(args.case)
    results = run_case(case, args.data_dir)
    ml = None
    if args.ml:
        from flightid.cases.run import stderr_progress

        ml = run_ml(case, results, args.data_dir, None if args.quiet else stderr_progress)
    if args.json:
        payload = {"coefficients": {name: r.to_dict() for name, r in results.items()}}
        if ml is not None:
            payload["ml"] = ml.to_dict()
        print(dumps(payload))
    else:
        for result in results.values():
            print(result.summary())
            print()
        if ml is not None:
            print(ml.summary())
    return 0
