"""``flightid run CASE.toml [--out DIR [--overwrite]] [--json] [--accuracy M] [--data-dir DIR]
[--quiet]``.

Runs the output-error estimation a case file describes. Progress goes to stderr. Standard
output gets the estimate summary (text), or with ``--json`` the JSON contract of the core::

    {"schema_version": "1", "results": [ENTRY]}

(layout version 1, described by docs/schema/results.schema.json) with exactly one ENTRY:
``Estimate.to_dict()`` (method, converged, status, message, cost, iterations,
equivalent_evaluations, R, outputs, fit_rms, cost_history, parameters with
name/value/initial/std/free/unit, ...) plus ``case`` (title, file, model), ``maneuvers`` and
``prediction`` (per predicted maneuver: outputs, rms_error, r2).

``--accuracy profile|search|all|cr|none`` (or the case's ``accuracy.methods``) adds the
accuracy assessment of ``flightid.accuracy.assess``: ENTRY is then ``accuracy_json(...)``, each
parameter with ``ci_cr``, ``ci_profile`` and, when run, ``ci_search`` ([lower, upper], null
for an open side), and the top level with ``confidence_level`` and ``nonlinearity``
({"N_phi": ...}). The text output adds the interval table and N_φ. Exit status 0 when the
estimation ran (read ``converged``/``status``), 1 on any failure (one line
``flightid: error: ...``), 130 when interrupted.

``--out DIR`` (or the case's ``output.dir``) writes results.json (the same document),
estimates.csv, figures/*.svg (or *.png) and report.html. The folder is checked and locked before the
estimation, the files are written to a temporary folder beside it and moved into place at
once (``flightid.report.folder``), after the summary has been printed; a folder that already
holds a run is replaced (whole) only with ``--overwrite``, and only when flightid wrote every
file in it (its manifest ``.flightid-run``). The current folder, the home folder and a folder
holding the case file, its data or its model module are refused. All JSON is strict: NaN and
±inf become null and are listed under ``"nonfinite"`` (``flightid.jsonout``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_data_dir_argument(parser: argparse.ArgumentParser) -> None:
    """The ``--data-dir`` option of the commands that read a case's data files."""
    parser.add_argument(
        "--data-dir",
        default=None,
        help="directory holding the data files (default: the case's data.data_dir, then "
        "$FLIGHTID_DATA, then a folder shared/data three levels above the case file's folder)",
    )


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "run",
        help="run the estimation of a case file and write its report",
        description=(
            "Output-error estimation from a TOML case file: data files and channel mapping, "
            "model, parameters, solver. Prints the estimates with Cramér–Rao bounds. "
            "WARNING: a case with model.module imports and runs that Python file with your "
            "permissions; run only case files and model modules you trust."
        ),
    )
    add_run_arguments(parser)
    parser.set_defaults(func=run)


def add_run_arguments(parser: argparse.ArgumentParser) -> None:
    """The arguments of ``flightid run`` (also those of its alias ``flightid regress``)."""
    parser.add_argument(
        "case", help="case file (TOML); its model.module, if any, is executed as Python code"
    )
    parser.add_argument(
        "--out",
        default=None,
        help="write results.json, estimates.csv, figures and report.html to this folder "
        "(default: the case's output.dir, else none); checked before estimating, written all "
        "at once; a folder that already holds a run is refused unless --overwrite",
    )
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the run already in --out (the whole folder is replaced; refused, naming "
        "them, when it holds files flightid did not write or that changed since)",
    )
    parser.add_argument(
        "--json",
        action="store_true",
        help='print {"schema_version": "1", "results": [entry]} as JSON on stdout',
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
    parser.add_argument(
        "--workers",
        type=int,
        default=None,
        help="run the profile limits (one task per parameter) and the random search of "
        "--accuracy on a Dask LocalCluster of N worker processes (1: this process, the "
        "default); the limits are the same for any N",
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        help="run them on the running Dask scheduler at this address (tcp://host:8786) instead",
    )
    parser.add_argument(
        "--figure-format",
        choices=("svg", "png"),
        default=None,
        help="the report figures' files in --out: svg (written from the arrays, no "
        "matplotlib) or png (drawn by matplotlib); default: the case's output.figure_format, "
        "else svg",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress messages on stderr")


def output_folder(case, given: str | None) -> Path | None:
    """The result folder: ``--out``, else the case's ``output.dir`` (relative to the case
    file), else None. An empty name is refused (it would be the current or the case's
    folder)."""
    from flightid.report.folder import OutputError

    if given is not None:
        if not given.strip():
            raise OutputError("--out: expected a folder name, got an empty string")
        return Path(given)
    configured = case.output.get("dir")
    if configured is None:
        return None
    if not str(configured).strip():
        raise OutputError("output.dir: expected a folder name, got an empty string")
    path = Path(configured).expanduser()
    return path if path.is_absolute() else case.directory / path


def case_inputs(case, data_dir: str | None) -> list[Path]:
    """The files a run reads — the case file, its model module, its data files — which its
    result folder may neither be nor hold."""
    from flightid.cases.build import resolve_data_dir

    inputs = [Path(case.path)]
    module = case.model.get("module")
    if isinstance(module, str):
        inputs.append(case.directory / module)
    try:
        directory: Path | None = resolve_data_dir(case, data_dir)
    except Exception:  # a bad data_dir is reported by the run itself
        directory = None
    for spec in (*case.maneuvers, *case.prediction):
        path = Path(spec.file)
        if path.is_absolute():
            inputs.append(path)
        elif directory is not None:
            inputs.append(directory / path)
    return inputs


def open_result_folder(case, args: argparse.Namespace, given: str | None):
    """The checked and locked result folder of a run (``flightid.report.folder``), or None
    without ``--out`` / ``output.dir``; notes about an earlier interrupted run go to stderr."""
    from flightid.report.folder import ResultFolder

    out = output_folder(case, given)
    if out is None:
        return None
    return ResultFolder.open(
        out,
        overwrite=args.overwrite,
        keep=case_inputs(case, getattr(args, "data_dir", None)),
        notify=print_note,
    )


def print_note(text: str) -> None:
    """A result folder's notice (not an error) as one ``flightid: note:`` line on stderr,
    shown with ``--quiet`` too: it concerns the user's files."""
    print(f"flightid: note: {text}", file=sys.stderr)


def print_sigma_note(estimate) -> None:
    """When the default σ is the coloured-residual σ: one ``flightid: note:`` line on stderr
    saying so and by how much the Cramér–Rao bounds understate it (``--quiet`` too: it
    concerns every number shown)."""
    from flightid.report.text import sigma_note

    text = sigma_note(estimate)
    if text is not None:
        print_note(text)


def _print_modes(result) -> None:
    """The run's modes at its first maneuver (and the flying qualities when the case asks),
    where the estimate's own summary could not show them: a nonlinear model, or a
    ``[flying_qualities]`` table."""
    from flightid.export.modal import linear_in_states_and_inputs

    if not hasattr(result, "modal_analysis"):
        return
    try:
        analysis = result.modal_analysis()
        shown = linear_in_states_and_inputs(result.estimate) if analysis else True
    except (ValueError, TypeError, ArithmeticError) as error:
        print(f"\nmodes: not computed ({error})")
        return
    if analysis is not None and (not shown or result.case.flying_qualities):
        print("\n" + analysis.summary())


def print_summary(result) -> None:
    """The estimates (and accuracy, predictions) as text on stdout."""
    print(result.estimate.summary())
    _print_modes(result)
    if result.accuracy is not None:
        print("\naccuracy of the estimates:")
        print(result.accuracy.summary())
    for p in result.predictions:
        print(f"\nprediction on {p.name}:")
        for n, e, r in zip(p.output_names, p.rms, p.r2, strict=True):
            print(f"  {n:<10} RMS error {e:.4g}   R² {r:.4f}")


def answer_then_files(
    args: argparse.Namespace, document, show, folder, write, written: str = "results"
) -> None:
    """The answer to stdout first — ``document()`` as JSON with ``--json`` (built only then),
    else ``show()`` prints the text — so that a failure to write files cannot lose it; then,
    with a result folder, ``write(directory) -> Path`` fills it and a progress line
    ("``written`` written to …") names the main file. Also used by ``flightid design``."""
    from flightid.cases.run import stderr_progress
    from flightid.jsonout import dumps

    if args.json:
        print(dumps(document()))
    else:
        show()
    sys.stdout.flush()
    if folder is not None:
        path = folder.write(write)
        if not args.quiet:
            stderr_progress(f"{written} written to {folder.target} ({path.name} there)")


def run(args: argparse.Namespace) -> int:
    # imported here, not at the top: `flightid --help` must not load numpy/scipy/numba
    from flightid.cases import load_case, run_case
    from flightid.cases.run import stderr_progress
    from flightid.results import results_document

    case = with_figure_format(load_case(args.case), getattr(args, "figure_format", None))
    # the result folder is checked (and locked) before any work, so that a bad --out costs
    # nothing and a second run into the same folder stops here
    folder = open_result_folder(case, args, args.out)
    pool = None
    try:
        if case.staged and _has_regression_stages(case):
            return _run_stages(case, args, folder)
        if case.recursive or case.frequency_domain:
            return _run_own_estimator(case, args, folder)
        # the figures' worker processes start now and import matplotlib during the estimation
        pool = figure_pool(case, folder)
        engine = None
        if getattr(args, "workers", None) not in (None, 1) or getattr(args, "scheduler", None):
            from flightid.batch.engine import make_engine

            engine = make_engine(args.workers, args.scheduler)
        try:
            result = run_case(
                case,
                args.data_dir,
                progress=None if args.quiet else stderr_progress,
                accuracy=args.accuracy,
                engine=engine,
            )
        finally:
            if engine is not None:
                engine.close()
        print_sigma_note(result.estimate)
        answer_then_files(
            args,
            lambda: results_document([result.to_dict()]),
            lambda: print_summary(result),
            folder,
            lambda directory: _write_report(result, directory),
        )
    finally:
        if pool is not None:
            pool.close()
        if folder is not None:
            folder.release()
    return 0


def _write_report(result, directory):
    """The result folder's files (``flightid.report.html.write_files``): imported only
    when a folder is written, so that ``--json`` alone does not load the report."""
    from flightid.report.html import write_files

    return write_files(result, directory)


def with_figure_format(case, figure_format: str | None):
    """The case with ``--figure-format`` in its ``[output] figure_format`` (the case's own
    setting where the option is not given)."""
    if figure_format is None:
        return case
    import dataclasses

    return dataclasses.replace(case, output={**case.output, "figure_format": figure_format})


def figure_pool(case, folder):
    """Worker processes for the report's figures (``flightid.report.drawing.FigurePool``)
    when the run writes PNG figures (``[output] figure_format = "png"``); else None (PNG
    figures are then drawn in this process; SVG figures are always written here).

    Two workers when this process may use two cores and one of them is idle (the 1-minute
    load average leaves at least 1.5 cores free): the figures are drawn two at a time. Else
    one: it loads matplotlib while the estimation runs and draws the figures while this
    process writes the other files, for no more work in all than drawing them here. One
    core only: none. ``FLIGHTID_FIGURE_WORKERS`` sets the number (0: none)."""
    import os

    if folder is None or not case.output.get("figures", True):
        return None
    # SVG figures are written in this process from the arrays: no matplotlib, no workers
    if case.output.get("figure_format", "svg") != "png":
        return None
    given = os.environ.get("FLIGHTID_FIGURE_WORKERS", "").strip()
    if given and not given.isdigit():
        from flightid.errors import InputError

        raise InputError(
            f"FLIGHTID_FIGURE_WORKERS: expected a whole number of processes (0: draw the "
            f"figures in this process), got {given!r}"
        )
    workers = int(given) if given else _default_figure_workers()
    if workers < 1:
        return None
    from flightid.report.drawing import FigurePool

    pool = FigurePool.start(workers=workers)
    if pool is not None:
        pool.activate()  # the report's writer draws its figures there
    return pool


def _default_figure_workers() -> int:
    """2 with an idle core besides this process's, 1 on a busy machine, 0 on one core."""
    import os

    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    if cores < 2:
        return 0
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):
        return 1
    return 2 if cores - load >= 1.5 else 1


def _has_regression_stages(case) -> bool:
    """Whether a staged case has regression stages (the regression package is imported only
    for a case that has stages)."""
    from flightid.cases.stages import has_regression_stages

    return has_regression_stages(case)


def _run_own_estimator(case, args: argparse.Namespace, folder) -> int:
    """A case with a ``[recursive]`` or ``[frequency_domain]`` table: its own module runs it
    and returns a result with the common surface (``summary()``, ``to_dict()``); its folder
    is written by ``flightid.report.estimator_reports`` (the same layout as the output-error
    run's)."""
    from flightid.cases.run import stderr_progress
    from flightid.results import results_document

    if case.recursive and case.frequency_domain:
        from flightid.cases.checks import CaseError

        raise CaseError(
            "recursive, frequency_domain: a case runs one estimator; give one of the two tables"
        )
    if case.recursive:
        from flightid.cases.recursive_case import run_recursive_case as run_own
        from flightid.report.estimator_reports import write_recursive_files as write_own
    else:
        from flightid.cases.frequency_case import run_frequency_case as run_own
        from flightid.report.estimator_reports import write_frequency_files as write_own
    result = run_own(case, args.data_dir, progress=None if args.quiet else stderr_progress)
    answer_then_files(
        args,
        lambda: results_document([result.to_dict()]),
        lambda: print(result.summary()),
        folder,
        lambda directory: write_own(result, directory),
    )
    return 0


def _run_stages(case, args: argparse.Namespace, folder) -> int:
    """A case with regression stages (``flightid.cases.stages``): print the stages' results,
    and write the output-error stage's files plus ``stages.json`` and ``stages.html`` (the
    fits with their residual whiteness, ``flightid.report.estimator_reports``) into the
    result folder; without an output-error stage the stages' page is report.html, with
    results.json and estimates.csv beside it."""
    import json

    from flightid.cases.run import stderr_progress
    from flightid.cases.stages import run_stages
    from flightid.jsonout import dumps
    from flightid.results import results_document

    run = run_stages(
        case,
        args.data_dir,
        progress=None if args.quiet else stderr_progress,
        accuracy=args.accuracy,
    )
    document = results_document(run.to_dict()["results"])
    document["stages"] = run.stages_dict()
    output_error = getattr(run, "output_error", None)
    if output_error is not None:
        print_sigma_note(output_error.estimate)

    def show() -> None:
        print(run.summary())
        if run.output_error is not None:
            print()
            print_summary(run.output_error)

    def write(directory: Path) -> Path:
        (directory / "stages.json").write_text(
            json.dumps(json.loads(dumps({"stages": run.stages_dict()})), indent=2) + "\n",
            encoding="utf-8",
        )
        from flightid.report.estimator_reports import write_stages_files

        if run.output_error is None:
            # regression stages only: results.json, estimates.csv, report.html of the stages
            (directory / "results.json").write_text(dumps(document) + "\n", encoding="utf-8")
            return write_stages_files(run, directory, case.output.get("figures", True))
        from flightid.report.html import write_files

        # the output-error stage's report.html, then stages.html (its file list is complete)
        page = write_files(run.output_error, directory)
        write_stages_files(run, directory, case.output.get("figures", True))
        return page

    answer_then_files(args, lambda: document, show, folder, write)
    return 0
