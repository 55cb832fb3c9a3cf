"""``flightid validate CASE.toml [--data-dir DIR]``: check a case file without estimating.

Reads the case, loads every data file with its channel mapping, builds the model (user module
or built-in airplane), initial states, biases, solver and rules, and prints what it found.
Exit status 0 when the case is valid, 1 with a message naming the key otherwise.
"""

from __future__ import annotations

import argparse

from flightid.cases import load_case, prepare_case
from flightid.cli.run import add_data_dir_argument


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "validate",
        help="check a case file (data, channels, model, parameters) without running it",
        description="Check a TOML case file: every error names the key and the problem.",
    )
    parser.add_argument("case", help="case file (TOML)")
    add_data_dir_argument(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    case = load_case(args.case)
    prepared = prepare_case(case, args.data_dir)
    model = prepared.model
    print(f"case: {case.title}")
    print(f"data directory: {prepared.data_dir}")
    for m in prepared.maneuvers:
        print(f"  maneuver {m.name}: {m.n_samples} samples, dt = {m.dt:g} s")
    for m in prepared.prediction_maneuvers:
        print(f"  prediction maneuver {m.name}: {m.n_samples} samples, dt = {m.dt:g} s")
    print(f"model: {prepared.model_description}")
    print(f"  states {list(model.states)}, inputs {list(model.inputs)}")
    print(f"  outputs {list(model.outputs)}")
    free = model.parameters.free_names
    fixed = [p.name for p in model.parameters if not p.free]
    print(f"  {len(free)} free parameters: {free}")
    if fixed:
        print(f"  {len(fixed)} fixed: {fixed}")
    print("valid")
    return 0
