"""``flightid export RUN_DIR --format FORMAT --out PATH [--at POINT] [--std default|cr]
[--overwrite] [--data-dir DIR]``.

Reads a result folder of ``flightid run`` back (``flightid.cases.load_run``: the case file
checked against the SHA-256 the run recorded, the model rebuilt with the recorded estimates
and covariance; nothing is estimated again) and writes the identified model in one of the
formats of ``EXPORT_FORMATS``:

    statespace  PATH.json and PATH.npz: A, B, C, D, names, units, operating point, the
                covariance of the entries, the modes with σ (flightid.export.statespace)
    mat         PATH.mat: the same for MATLAB (scipy.io.savemat)
    python      PATH.py: a stand-alone module with f, h, the estimated values and simulate()
                (flightid.export.python_module)
    jsbsim      folder PATH: a JSBSim aircraft of a built-in airplane model
                (flightid.export.jsbsim), or of the global model of a run folder holding
                global_model.json (a [[stages]] kind = "global_model" run;
                flightid.export.globalmodel_jsbsim) with the airplane of --airplane FILE.toml

The linear formats linearize at the initial state of the first estimation maneuver and the
mean of each input over it, unless ``--at`` names another maneuver (its number, from 1, or
its name) or gives every state and input (``--at "alpha=0.1,q=0,de=-0.02"``).

An existing file is replaced only with ``--overwrite``, and only when flightid exported it
(a record ``.NAME.flightid-export`` beside it vouches for its bytes): ``flightid.export.files``.

A format is one entry of ``EXPORT_FORMATS``: its help line and ``write(run, out, args) ->
[paths]``.
"""

from __future__ import annotations

import argparse
import textwrap
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

# the model file a global-model stage writes into the run folder (cases.globalmodel_case)
GLOBAL_MODEL_FILE = "global_model.json"


@dataclass(frozen=True)
class ExportFormat:
    """One ``--format``: what it writes (help) and the writer ``write(run, out, args)``
    taking the loaded run (``LoadedRun``), the ``--out`` path and the parsed arguments,
    returning the paths written."""

    help: str
    write: Callable[..., list[Path]]


def _linear_model(run, args: argparse.Namespace):
    return run.linearize(operating_point(run, args.at), std=args.std)


def _write_statespace(run, out: Path, args: argparse.Namespace) -> list[Path]:
    from flightid.export import write_statespace

    return write_statespace(_linear_model(run, args), out, overwrite=args.overwrite)


def _write_mat(run, out: Path, args: argparse.Namespace) -> list[Path]:
    from flightid.export import write_mat

    return [write_mat(_linear_model(run, args), out, overwrite=args.overwrite)]


def _write_python(run, out: Path, args: argparse.Namespace) -> list[Path]:
    import numpy as np

    from flightid.export import write_python
    from flightid.simulation.prediction import initial_states

    point = operating_point(run, args.at)
    if point is not None and not hasattr(point, "channel"):
        # (x, u) of --at NAME=VALUE: x by state name
        x0 = np.array([point[0][n] for n in run.model.states], dtype=float)
    else:
        (x0,) = initial_states(run.model, [point or run.maneuvers[0]], None)
    sigma = run.std if args.std == "default" else run.std_cr
    std = [sigma.get(n, float("nan")) for n in run.model.parameters.names]
    description = (
        f"Estimated by flightid run of the case {run.case.path} ({run.case.title}); result "
        f"folder {run.directory}. X0: the initial state of "
        + ("the first estimation maneuver." if args.at is None else f"--at {args.at}.")
    )
    path = write_python(
        run.model,
        out,
        x0,
        std=std,
        method=run.method,
        input_interpolation=run.input_interpolation,
        description=description,
        overwrite=args.overwrite,
    )
    return [path]


def _estimated_parameters(run):
    """The recorded estimates with their covariance, in the form ``write_jsbsim`` takes from
    an ``Estimate``: names, values, free flags and the covariance over the free ones."""
    from types import SimpleNamespace

    import numpy as np

    parameters = run.model.parameters
    free = [name in run.free_names for name in parameters.names]
    order = [name for name, is_free in zip(parameters.names, free, strict=True) if is_free]
    index = [run.free_names.index(name) for name in order]
    # the covariance in the model's order of the free parameters
    covariance = run.covariance
    if covariance is not None:
        covariance = covariance[np.ix_(index, index)]
    return SimpleNamespace(
        names=tuple(parameters.names),
        values=np.asarray(parameters.values, dtype=float),
        free=tuple(free),
        covariance=covariance,
    )


def _check_jsbsim_out(out: Path, args: argparse.Namespace) -> None:
    """A non-empty ``--out`` folder is replaced only with --overwrite, and only when it is a
    JSBSim aircraft flightid exported (it holds export.json)."""
    from flightid.export import ExportError

    if out.exists() and any(out.iterdir()):
        if not args.overwrite:
            raise ExportError(f"--out {out}: the folder exists and is not empty; give a new one")
        if not (out / "export.json").is_file():
            raise ExportError(
                f"--out {out}: --overwrite replaces only a JSBSim aircraft flightid exported "
                "(a folder holding its export.json); this folder has none"
            )


def _controls(args: argparse.Namespace) -> dict[str, str]:
    """``--control NAME=PROPERTY`` options as {name: property}."""
    from flightid.export import ExportError

    controls = {}
    for text in args.control or ():
        name, _, prop = text.partition("=")
        if not name.strip() or not prop.strip():
            raise ExportError(
                f"--control: expected NAME=PROPERTY (de=fcs/elevator-pos-rad), got {text!r}"
            )
        controls[name.strip()] = prop.strip()
    return controls


def _write_jsbsim(run, out: Path, args: argparse.Namespace) -> list[Path]:
    from flightid.aircraft.aero import AeroModel
    from flightid.aircraft.library import airplane_from_table
    from flightid.export import ExportError
    from flightid.export.jsbsim import write_jsbsim

    spec = run.case.model
    if "aero" not in spec or "airplane" not in spec:
        raise ExportError(
            "--format jsbsim: expected a run of a built-in airplane model ([model] type "
            "longitudinal, lateral, six_dof or wind_axis_longitudinal, with [model.airplane] and "
            f"[model.aero]); the case {run.case.path} has neither table"
        )
    if args.airplane is not None:
        raise ExportError(
            "--airplane: only for a global-model run folder; the airplane of an output-error "
            f"run is its case's [model.airplane] ({run.case.path}), which the model was "
            "estimated with"
        )
    _check_jsbsim_out(out, args)
    aircraft = write_jsbsim(
        _estimated_parameters(run),
        airplane_from_table(spec["airplane"]),
        out,
        aero=AeroModel(spec["aero"]),
        reference_speed=spec.get("reference_speed"),
        rate_speed=spec.get("rate_speed", "V"),
        draws=args.draws,
        seed=args.seed,
        controls=_controls(args),
        dynamic_pressure=args.dynamic_pressure or "airplane",
        overwrite=args.overwrite,
    )
    return [Path(aircraft.folder)]


def _airplane_file(path: str):
    """The ``Airplane`` of ``--airplane FILE``: its ``[airplane]`` table, or a case file's
    ``[model.airplane]`` (``flightid.aircraft.airplane_from_table``)."""
    import tomllib

    from flightid.aircraft.library import airplane_from_table
    from flightid.export import ExportError

    file = Path(path).expanduser()
    try:
        document = tomllib.loads(file.read_text(encoding="utf-8").removeprefix("\ufeff"))
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ExportError(
            f"--airplane {file}: expected a TOML file, cannot read it ({exc})"
        ) from None
    model = document.get("model")
    if isinstance(model, dict) and isinstance(model.get("airplane"), dict):
        return airplane_from_table(model["airplane"])
    if isinstance(document.get("airplane"), dict):
        return airplane_from_table(document["airplane"])
    raise ExportError(
        f"--airplane {file}: expected an [airplane] table (Airplane fields, SI units, or "
        'library = "navion") or a case file\'s [model.airplane]; the file has neither'
    )


def _write_jsbsim_global(run_dir: Path, out: Path, args: argparse.Namespace) -> list[Path]:
    """``--format jsbsim`` of a run folder holding a global model (``global_model.json``)."""
    from flightid.export import ExportError
    from flightid.export.globalmodel_jsbsim import write_jsbsim_global
    from flightid.globalmodel import load_global_model

    if args.airplane is None:
        raise ExportError(
            f"--format jsbsim: {run_dir / GLOBAL_MODEL_FILE} holds a global model, whose case "
            "has no airplane; expected --airplane FILE.toml with an [airplane] table (S, b, "
            "cbar, mass, inertia; SI units) or a case file with [model.airplane]"
        )
    airplane = _airplane_file(args.airplane)
    _check_jsbsim_out(out, args)
    aircraft = write_jsbsim_global(
        load_global_model(run_dir / GLOBAL_MODEL_FILE),
        airplane,
        out,
        controls=_controls(args),
        dynamic_pressure=args.dynamic_pressure or "atmosphere",
        draws=args.draws,
        seed=args.seed,
        overwrite=args.overwrite,
    )
    return [Path(aircraft.folder)]


# --format → its writer; one entry adds a format
EXPORT_FORMATS: dict[str, ExportFormat] = {
    "statespace": ExportFormat(
        "PATH.json and PATH.npz: A, B, C, D, names, units, operating point, covariance, modes",
        _write_statespace,
    ),
    "mat": ExportFormat("PATH.mat: the same for MATLAB", _write_mat),
    "python": ExportFormat(
        "PATH.py: a stand-alone module with f, h, the estimated values and simulate()",
        _write_python,
    ),
    "jsbsim": ExportFormat(
        "folder PATH: a JSBSim aircraft (NAME.xml, aerodynamics/nominal.xml, --draws "
        "alternative aerodynamics from the covariance); built-in airplane models, and global "
        "models (a run folder with global_model.json; needs --airplane)",
        _write_jsbsim,
    ),
}


def _option_error(message: str) -> Exception:
    """A bad ``--at`` value: ``ExportError`` (an ``InputError``)."""
    from flightid.export import ExportError

    return ExportError(message)


def _parse_values(text: str, names: tuple[str, ...]) -> dict[str, float]:
    values: dict[str, float] = {}
    for part in text.split(","):
        name, _, value = part.partition("=")
        try:
            values[name.strip()] = float(value)
        except ValueError:
            raise _option_error(
                f"--at: expected NAME=VALUE pairs separated by commas, got {part!r}"
            ) from None
    unknown = sorted(set(values) - set(names))
    missing = [n for n in names if n not in values]
    if unknown or missing:
        raise _option_error(
            f"--at: expected a value for every state and input {list(names)}; unknown "
            f"{unknown}, missing {missing}"
        )
    return values


def operating_point(run, at: str | None):
    """``--at`` as ``LoadedRun.linearize`` takes it: None (the first estimation maneuver), a
    maneuver (by number from 1 or by name) or (x, u) as mappings."""
    if at is None:
        return None
    if "=" in at:
        states, inputs = run.model.states, run.model.inputs
        values = _parse_values(at, (*states, *inputs))
        return ({n: values[n] for n in states}, {n: values[n] for n in inputs})
    names = [m.name for m in run.maneuvers]
    if at.strip().isdigit() and 1 <= int(at) <= len(run.maneuvers):
        return run.maneuvers[int(at) - 1]
    if at in names:
        return run.maneuvers[names.index(at)]
    raise _option_error(
        f"--at: expected a maneuver number 1..{len(names)}, a maneuver name {names} or "
        f"NAME=VALUE for every state and input, got {at!r}"
    )


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "export",
        help="write an estimated model for other tools (state space, MATLAB, Python)",
        description=textwrap.fill(
            "Export the model of a result folder of 'flightid run' without estimating again: "
            "the case file is read again (refused when it changed since the run: its SHA-256 "
            "is checked) and the model rebuilt with the recorded estimates and covariance. "
            "The linear formats linearize at the initial state of the first estimation "
            "maneuver and the mean of each input over it (change with --at). WARNING: a case "
            "with model.module imports and runs that Python file.",
            width=88,
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="formats:\n"
        + "\n".join(f"  {name:<11} {fmt.help}" for name, fmt in EXPORT_FORMATS.items()),
    )
    parser.add_argument("run_dir", metavar="RUN_DIR", help="result folder of flightid run --out")
    parser.add_argument(
        "--format", required=True, choices=tuple(EXPORT_FORMATS), help="what to write"
    )
    parser.add_argument(
        "--out",
        required=True,
        help="file to write (the format's suffix is added when missing); an existing file is "
        "refused unless --overwrite",
    )
    parser.add_argument(
        "--at",
        default=None,
        help="operating point of the linear model (and X0 of the python module): a maneuver "
        "number (from 1) or name of the run — its initial state and mean inputs — or "
        "NAME=VALUE,... for every state and input (default: the first estimation maneuver's "
        "initial state and mean inputs)",
    )
    parser.add_argument(
        "--std",
        choices=("default", "cr"),
        default="default",
        help="covariance carried into the export: the one behind the reported σ (default) or "
        "the Cramér–Rao bounds (cr)",
    )
    parser.add_argument(
        "--draws",
        type=int,
        default=0,
        help="jsbsim: write this many parameter draws from the covariance as alternative "
        "aerodynamics files (aerodynamics/draw_0001.xml, ...) for dispersion studies",
    )
    parser.add_argument("--seed", type=int, default=0, help="jsbsim: seed of the draws")
    parser.add_argument(
        "--dynamic-pressure",
        choices=("airplane", "atmosphere"),
        default=None,
        help="jsbsim: q̄ = ½ρV² with the case's constant air density, as in the identified "
        "model (airplane, the default of an output-error run), or JSBSim's atmosphere at the "
        "flown altitude (atmosphere, the default of a global model)",
    )
    parser.add_argument(
        "--airplane",
        default=None,
        metavar="FILE.toml",
        help="jsbsim, global model: the airplane (S, b, cbar, mass, inertia): a TOML file "
        'with an [airplane] table of Airplane fields in SI units (library = "navion" '
        "starts from a published one), or a case file with [model.airplane]",
    )
    parser.add_argument(
        "--control",
        action="append",
        default=None,
        metavar="NAME=PROPERTY",
        help="jsbsim: the JSBSim property (rad) of a control variable, added to de, da, dr → "
        "fcs/elevator-pos-rad, fcs/left-aileron-pos-rad, fcs/rudder-pos-rad (repeat the "
        "option for several)",
    )
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an existing file, only when flightid exported it and it is unchanged",
    )
    parser.add_argument(
        "--data-dir",
        default=None,
        help="directory holding the data files (default: the one the run used)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # imported here: `flightid --help` must not load numpy/scipy/numba
    from flightid.cases.load_run import load_run

    run_dir = Path(args.run_dir).expanduser()
    out = Path(args.out).expanduser()
    if (run_dir / GLOBAL_MODEL_FILE).is_file():
        if args.format != "jsbsim":
            from flightid.export import ExportError

            raise ExportError(
                f"--format {args.format}: {run_dir / GLOBAL_MODEL_FILE} holds a global model, "
                "which exports as --format jsbsim only"
            )
        written = _write_jsbsim_global(run_dir, out, args)
    else:
        written = EXPORT_FORMATS[args.format].write(load_run(run_dir, args.data_dir), out, args)
    for path in written:
        print(f"written: {path}")
    return 0
