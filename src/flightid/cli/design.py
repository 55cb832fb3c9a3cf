"""``flightid design CASE.toml [--out DIR [--overwrite]] [--json] [--data-dir DIR] [--quiet]``.

Designs the input a case's ``[design]`` table asks for (``flightid.design``, docs/design.md):
the candidate inputs are simulated with the case's model at its parameter values, their
Cramér–Rao bounds predicted with the assumed noise, and the best one under the amplitude,
duration and response limits is kept. Standard output gets the summary (text) or, with
``--json``, the document

    {"schema_version": "1", "results": [ENTRY], "inputs": {...}, "predicted": {...}}

with ``inputs`` = {"time": [...], "<input>": [Δu ...]} (perturbations about the trim values
given in ENTRY["trim"]) and ``predicted`` = {parameter: predicted σ}; ENTRY has both too and
``parameters`` in the results.json layout (std = predicted σ). ``--out DIR`` writes
results.json, estimates.csv, designed_input.csv, predicted_accuracy.csv, figures/ and
report.html (``flightid.report.estimator_reports.write_design_files``). Progress goes to
stderr. Exit status 0 after a design, 1 on any failure (one line ``flightid: error: ...``).
"""

from __future__ import annotations

import argparse


def register(subparsers) -> None:
    from flightid.cli.run import add_data_dir_argument

    parser = subparsers.add_parser(
        "design",
        help="design a flight-test input from a case file's [design] table",
        description=(
            "Model-based input design: multisines or 3-2-1-1 / 2-1-1 / doublet inputs chosen "
            "for the smallest predicted Cramér–Rao bounds (D-, A-optimal or named parameters) "
            "under amplitude, duration and response limits. WARNING: a case with model.module "
            "imports and runs that Python file with your permissions."
        ),
    )
    parser.add_argument("case", help="case file (TOML) with a [design] table")
    parser.add_argument(
        "--out",
        default=None,
        help="write results.json, estimates.csv, designed_input.csv, predicted_accuracy.csv, "
        "figures and "
        "report.html to this folder (a folder that already holds a run is refused unless "
        "--overwrite)",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace the run in --out")
    parser.add_argument(
        "--json",
        action="store_true",
        help="print the design as JSON (inputs, predicted σ, results.json entry) on stdout",
    )
    add_data_dir_argument(parser)
    parser.add_argument("--quiet", action="store_true", help="no progress messages on stderr")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # imported here: `flightid --help` must not load numpy/scipy/numba
    from flightid.cases import load_case
    from flightid.cases.design_case import run_design_case
    from flightid.cases.run import stderr_progress
    from flightid.cli.run import answer_then_files, open_result_folder
    from flightid.results import results_document

    case = load_case(args.case)
    # only --out: a design case's output.dir is not its result folder
    folder = open_result_folder(case, args, args.out) if args.out is not None else None
    try:
        result = run_design_case(
            case, args.data_dir, progress=None if args.quiet else stderr_progress
        )

        def document() -> dict:
            # results.json's layout, with the design's inputs and predicted σ at the top
            entry = result.to_dict()
            return {
                **results_document([entry]),
                "inputs": entry["inputs"],
                "predicted": entry["predicted"],
            }

        from flightid.report.estimator_reports import write_design_files

        units = declared_units(case)
        answer_then_files(
            args, document, lambda: print(result.summary()), folder,
            lambda directory: write_design_files(result, directory, units), written="design",
        )  # fmt: skip
    finally:
        if folder is not None:
            folder.release()
    return 0


# the unit a channel declared in ``unit`` without ``to`` is converted to (the loaders'
# unit rule: angles in rad)
_CONVERTED = {"deg": "rad", "deg/s": "rad/s", "deg/s^2": "rad/s^2"}


def declared_units(case) -> dict[str, str]:
    """{channel: unit} of the case's ``[data.inputs]`` and ``[data.outputs]`` after
    loading: ``to`` where given, else ``unit`` (deg → rad), for the design's axis labels."""
    units: dict[str, str] = {}
    for section in ("inputs", "outputs"):
        table = case.data.get(section, {})
        if not isinstance(table, dict):
            continue
        for name, spec in table.items():
            if isinstance(spec, dict):
                unit = spec.get("to") or spec.get("unit") or ""
                units[name] = _CONVERTED.get(unit, unit) if "to" not in spec else unit
    return units
