"""``flightid validate CASE.toml [--data-dir DIR]``: check a case file without estimating.

Reads the case, loads every data file with its channel mapping, checks every stage of
``[[stages]]`` (regression terms evaluated on the data; the output-error model after a
regression stage built with every candidate term), builds the model (user module
or built-in airplane), initial states, biases, solver and rules, then evaluates the model's
``f`` and ``h`` on the data at the start values (``flightid.model.check_model``: indices into
x, u and θ, number and type of returned values, finite at the start), for the estimation
maneuvers and for every prediction maneuver (with the prediction's initial states), makes the
estimator's own checks of its arguments (``flightid.cases.run.check_estimator``: free
parameters, more measurements than free parameters, what the filter error method refuses) and
the accuracy methods against the estimator, checks a ``[design]`` table as ``flightid design``
does, and prints what it found.
Exit status 0 when the case is valid, 1 with a message naming the key or function otherwise.

``model.module`` names a Python file; validating (like running) the case **executes** it.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import TYPE_CHECKING

from flightid.cli.run import add_data_dir_argument

if TYPE_CHECKING:
    from flightid.data.flightdata import FlightData
    from flightid.model import StateSpaceModel

_MODULE_WARNING = (
    "A case whose model.module names a Python file EXECUTES that file (it is imported as "
    "Python code, with your rights) when it is validated or run: validate only case files "
    "and model modules you trust."
)


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "validate",
        help="check a case file (data, channels, model functions, parameters) without "
        "estimating; model.module executes the Python file it names",
        description=(
            "Check a TOML case file without estimating: data files and channels, the model, "
            "parameters, initial states, biases and solver settings, and the model functions "
            "f and h, evaluated on the data at the start values (indices into x, u and theta, "
            "number and type of returned values, finite at the start), the estimator's own checks "
            "and a [design] table; every check `flightid run` / `flightid design` makes before "
            "estimating. Every error names the "
            "key or function and the problem. " + _MODULE_WARNING
        ),
    )
    parser.add_argument("case", help="case file (TOML)")
    add_data_dir_argument(parser)
    parser.set_defaults(func=run)


def _check(model: StateSpaceModel, maneuvers: Sequence[FlightData], method: str, label: str):
    from flightid.model import check_model

    report = check_model(model, list(maneuvers), method=method)
    print(f"  {label}{report.summary()}")


def _stages(case, data_dir):
    """Check every ``[[stages]]`` entry (``flightid.cases.stages.validate_stages``); print one
    line per stage; the prepared output-error stage (or None) for the checks below."""
    from flightid.cases.stages import validate_stages

    lines, prepared = validate_stages(case, data_dir)
    print(f"stages of {case.title}:")
    for k, line in enumerate(lines):
        print(f"  [{k}] {line}")
    return prepared


def _design(case, data_dir) -> None:
    """The ``[design]`` table checked as ``flightid design`` checks it before designing
    (``flightid.cases.design_case.design_problem``: keys, ranges, bands below the Nyquist
    frequency, inputs and outputs of the model, the trim search)."""
    from pathlib import Path

    from flightid.cases.design_case import design_problem

    problem, _ = design_problem(case, Path(data_dir) if data_dir else None)
    print(
        f"[design]: {problem.signal} for {list(problem.names)} over {problem.duration_s:g} s "
        f"at dt {problem.dt_s:g} s, settings valid"
    )


def run(args: argparse.Namespace) -> int:
    # imported here, not at the top: `flightid --help` must not load numpy/scipy/numba
    from flightid.cases import load_case, prepare_case
    from flightid.cases.build import time_base_lines, unbiased_model
    from flightid.cases.run import accuracy_methods, check_accuracy_methods, prediction_model

    case = load_case(args.case)
    # the accuracy methods `flightid run` would run after this estimator
    check_accuracy_methods(case, accuracy_methods(case))
    # an estimator's table, and every check its run makes before estimating, by its module
    # (a bad key or a band the data cannot give: CaseError naming it)
    if case.recursive:
        from flightid.cases.recursive_case import prepare_recursive_case

        settings = prepare_recursive_case(case, args.data_dir, compile_model=False).settings
        print(f"[recursive]: method {settings['method']}, settings valid for the data")
    if case.frequency_domain:
        from flightid.cases.frequency_case import prepare_frequency_case

        prepared_fd = prepare_frequency_case(case, args.data_dir)
        print(
            f"[frequency_domain]: settings valid for the data ({prepared_fd.frequencies.size} "
            f"frequencies × {len(prepared_fd.spectra)} maneuver(s))"
        )
    if case.design:
        _design(case, args.data_dir)
    if case.staged:
        prepared = _stages(case, args.data_dir)
        if prepared is None:
            print("valid")
            return 0
    else:
        prepared = prepare_case(case, args.data_dir)
    model = prepared.model
    method = case.estimation.get("method", "rk4")
    print(f"case: {case.title}")
    print(f"data directory: {prepared.data_dir}")
    for m in prepared.maneuvers:
        print(f"  maneuver {m.name}: {m.n_samples} samples, dt = {m.dt:g} s")
    for m in prepared.prediction_maneuvers:
        print(f"  prediction maneuver {m.name}: {m.n_samples} samples, dt = {m.dt:g} s")
    for line in time_base_lines([*prepared.maneuvers, *prepared.prediction_maneuvers]):
        print(f"  time base: {line}")
    print(f"model: {prepared.model_description}")
    if "module" in case.model:
        print("  (model.module is Python code: it was executed to read the model)")
    print(f"  states {list(model.states)}, inputs {list(model.inputs)}")
    print(f"  outputs {list(model.outputs)}")
    free = model.parameters.free_names
    fixed = [p.name for p in model.parameters if not p.free]
    print(f"  {len(free)} free parameters: {free}")
    if fixed:
        print(f"  {len(fixed)} fixed: {fixed}")
    _check(model, prepared.maneuvers, method, "")
    base = unbiased_model(model, prepared.base, len(prepared.maneuvers))
    if base is not None:
        _check(base, prepared.maneuvers, method, "without biases: ")
    for maneuver in prepared.prediction_maneuvers:
        predicted, data = prediction_model(case, maneuver, prepared.base)
        _check(predicted, data, method, f"prediction maneuver {maneuver.name}: ")
    print("valid")
    return 0
