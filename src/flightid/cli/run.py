"""``flightid run CASE.toml [--out DIR] [--json] [--accuracy M] [--data-dir DIR] [--quiet]``.

Runs the output-error estimation a case file describes. Progress goes to stderr. Standard
output gets the estimate summary (text), or with ``--json`` the JSON contract of the core::

    {"results": [ENTRY]}

with exactly one ENTRY: ``Estimate.to_dict()`` (method, converged, status, message, cost,
iterations, equivalent_evaluations, R, outputs, fit_rms, cost_history, parameters with
name/value/initial/std/free, ...) plus ``case`` (title, file, model), ``maneuvers`` and
``prediction`` (per predicted maneuver: outputs, rms_error, r2).

``--accuracy profile|search|all|cr|none`` (or the case's ``accuracy.methods``) adds the
accuracy assessment of ``flightid.accuracy.assess``: ENTRY is then ``accuracy_json(...)``, each
parameter with ``ci_cr``, ``ci_profile`` and, when run, ``ci_search`` ([lower, upper], null
for an open side), and the top level with ``confidence_level`` and ``nonlinearity``
({"N_phi": ...}). The text output adds the interval table and N_φ. Exit status 0 when the
estimation ran (read ``converged``/``status``), 1 on a bad case. ``--out DIR`` writes
results.json (the same document), estimates.csv, figures/*.png and report.html.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from flightid.cases import load_case, run_case
from flightid.cases.run import stderr_progress


def add_data_dir_argument(parser: argparse.ArgumentParser) -> None:
    """The ``--data-dir`` option of the commands that read a case's data files."""
    parser.add_argument(
        "--data-dir",
        default=None,
        help="directory holding the data files (default: $FLIGHTID_DATA, then the case's "
        "data.data_dir, then ../../../shared/data relative to the case file)",
    )


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "run",
        help="run the estimation of a case file and write its report",
        description=(
            "Output-error estimation from a TOML case file: data files and channel mapping, "
            "model, parameters, solver. Prints the estimates with Cramér–Rao bounds."
        ),
    )
    parser.add_argument("case", help="case file (TOML)")
    parser.add_argument("--out", default=None, help="write results, figures and report.html here")
    parser.add_argument(
        "--json", action="store_true", help='print {"results": [entry]} as JSON on stdout'
    )
    add_data_dir_argument(parser)
    parser.add_argument(
        "--accuracy",
        choices=("cr", "profile", "search", "all", "none"),
        default=None,
        help="confidence limits after the estimation: Cramér–Rao intervals and N_phi (cr), "
        "plus profile-likelihood (profile) and random-search (search; seeded, within "
        "accuracy.budget) limits; all = every method; none = no assessment (default: the "
        "case's accuracy.methods)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress messages on stderr")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    case = load_case(args.case)
    result = run_case(
        case,
        args.data_dir,
        progress=None if args.quiet else stderr_progress,
        accuracy=args.accuracy,
    )
    payload = {"results": [result.to_dict()]}
    if args.out:
        from flightid.report.html import write_report

        path = write_report(result, Path(args.out))
        if not args.quiet:
            stderr_progress(f"report written to {path}")
    if args.json:
        print(json.dumps(payload, indent=2))
    else:
        print(result.estimate.summary())
        if result.accuracy is not None:
            print("\naccuracy of the estimates:")
            print(result.accuracy.summary())
        for p in result.predictions:
            print(f"\nprediction on {p.name}:")
            for n, e, r in zip(p.output_names, p.rms, p.r2, strict=True):
                print(f"  {n:<10} RMS error {e:.4g}   R² {r:.4f}")
    return 0
