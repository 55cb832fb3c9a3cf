"""Build the objects a case describes: maneuvers (FlightData), the model, solver and rules.

Initial states and biases become parameters appended after the model's own, so the model
functions index θ exactly as they were written:

    x0 of state s in maneuver k:  fixed number, first measured sample, or parameter x0_s[_k]
    state bias   b_x  (per state s):   ẋ_s = f_s(t, x, u, θ) + b_x,s[k]
    output bias  b_y  (per output o):  y_o = h_o(t, x, u, θ) + b_y,o[k]

Per-maneuver biases ([_k] suffix, k = 1, 2, ...) see the maneuver through an extra constant
input channel ``maneuver_number`` (0, 1, ...) added to each maneuver's data.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from flightid.cases.spec import Case, CaseError, ManeuverSpec
from flightid.cases.usermodel import load_user_model
from flightid.data.flightdata import FlightData
from flightid.data.loaders import read_table, to_flight_segments
from flightid.data.location import data_directory
from flightid.errors import InputError
from flightid.estimation import FPS, MNR, MNRES, Convergence
from flightid.model.parameters import Parameter, Parameters
from flightid.model.statespace import StateSpaceModel, per_maneuver_name

__all__ = [
    "resolve_data_dir",
    "load_maneuvers",
    "maneuver_entry",
    "base_model",
    "build_model",
    "build_solver",
    "build_convergence",
    "prediction_initial_state",
    "MANEUVER_CHANNEL",
]

MANEUVER_CHANNEL = "maneuver_number"


def resolve_data_dir(case: Case, override: str | Path | None = None) -> Path:
    """The data directory: ``override`` (CLI --data-dir), ``[data].data_dir`` relative to the
    case file, env FLIGHTID_DATA, else a folder ``shared/data`` three levels above the case
    file's folder (``flightid.data.location.DEFAULT_DATA_DIR``). A case without ``data_dir``
    passes None, so that FLIGHTID_DATA applies to it."""
    given = case.data.get("data_dir")
    if given is not None and not isinstance(given, str):
        raise CaseError(f"data.data_dir: expected a path string, got {given!r}")
    return data_directory(case.directory, given, override)


def load_maneuvers(
    case: Case, data_dir: Path, specs: Sequence[ManeuverSpec] | None = None, key: str = "data"
) -> list[FlightData]:
    """Read the case's data files into ``FlightData`` (one per maneuver; a resampled file
    that gaps split gives one per segment, named ``name_1``, ``name_2``, ...)."""
    specs = case.maneuvers if specs is None else specs
    maneuvers = []
    for i, spec in enumerate(specs):
        path = Path(spec.file)
        path = path if path.is_absolute() else data_dir / path
        where = f"{key} (maneuver {i + 1} '{spec.name}', {path})"
        try:
            start, stop = _maneuver_span(spec, path)
            table = read_table(path, spec.format, variable=spec.variable)
            pieces = to_flight_segments(
                table,
                time=case.data.get("time", 1),
                inputs=case.data.get("inputs"),
                outputs=case.data.get("outputs"),
                name=spec.name,
                start=start,
                stop=stop,
                gaps=spec.gaps,
                dt=spec.dt,
                resample_hz=spec.resample_hz,
                max_gap_s=spec.max_gap_s,
                allow_retime=spec.allow_retime,
                constants=case.data.get("constants"),
                signals=case.data.get("signals"),
                steps=case.data.get("steps"),
            )
        except InputError as exc:
            raise CaseError(f"{where}: {exc}") from None
        maneuvers.extend(pieces)
    names = [m.name for m in maneuvers]
    clash = sorted({n for n in names if names.count(n) > 1})
    if clash:
        raise CaseError(
            f"{key}: maneuver names must be unique; the segments of resampled files made "
            f"{clash} twice (rename the maneuvers)"
        )
    return maneuvers


def _maneuver_span(spec: ManeuverSpec, path: Path) -> tuple[float | None, float | None]:
    """(start, stop) in s: the spec's, or the interval of its flight ``mode`` in the log
    (``flightid.logs.modes``; the last mode runs to the end of the data)."""
    if spec.mode is None:
        return spec.start, spec.stop
    from flightid.logs.modes import log_mode_intervals, select_mode

    interval = select_mode(
        log_mode_intervals(path), spec.mode, spec.mode_index, "mode", str(path.name)
    )
    return interval.start_s, None if math.isinf(interval.stop_s) else interval.stop_s


def maneuver_entry(maneuver: FlightData) -> dict:
    """A maneuver in the results: name, samples, dt (s) and, where its stored time base was
    changed (re-gridded, joined, resampled), ``time_base``: what was done, in words
    (``FlightData.notes``)."""
    entry: dict[str, Any] = {
        "name": maneuver.name,
        "samples": int(maneuver.n_samples),
        "dt": float(maneuver.dt),
    }
    if maneuver.notes:
        entry["time_base"] = list(maneuver.notes)
    return entry


def time_base_lines(maneuvers) -> list[str]:
    """What was done to the maneuvers' stored time bases (``FlightData.notes``), each line
    once, in order: the lines ``flightid run`` and ``validate`` print."""
    lines: list[str] = []
    for maneuver in maneuvers:
        lines.extend(n for n in maneuver.notes if n not in lines)
    return lines


# ------------------------------------------------------------------------------ base model


def base_model(case: Case, data_dir: Path | None = None) -> tuple[StateSpaceModel, str]:
    """The model before case parameters, x0 and biases: (model, description).

    ``data_dir`` is needed by an α–q model whose constants name data columns.
    """
    spec = case.model
    if spec.get("type") == "alpha_q":
        from flightid.cases.alpha_q import structure_from_terms, zero_parameters

        structure = structure_from_terms(spec["aero"])
        return alpha_q_base(case, data_dir, structure, zero_parameters(structure))
    if spec.get("type") == "kinematic":
        from flightid.cases.compat_case import kinematic_from_case

        return kinematic_from_case(case), "built-in kinematic model (flight-path reconstruction)"
    if spec.get("type") == "linear":
        from flightid.model.linear import linear_model

        try:
            model = linear_model(
                spec["states"],
                spec["inputs"],
                spec["outputs"],
                spec["parameters"],
                spec["derivatives"],
                spec["output_equations"],
                constants=spec.get("constants", {}),
                name=spec.get("name", "linear"),
            )
        except InputError as exc:
            raise CaseError(f"model: {exc}") from None
        return model, "linear model declared by terms"
    if "module" in spec:
        path = Path(spec["module"])
        path = path if path.is_absolute() else case.directory / path
        user = load_user_model(path)
        parameters = Parameters(user.parameters)
        model = StateSpaceModel(
            user.states,
            user.inputs,
            user.outputs,
            user.f,
            user.h,
            parameters,
            x0=(0.0,) * len(user.states),
            name=spec.get("name", path.stem),
        )
        return model, f"user module {path.name}"
    return _builtin_model(case), f"built-in {spec['type']} airplane model"


def alpha_q_base(
    case: Case, data_dir: Path | None, structure, parameters: Parameters
) -> tuple[StateSpaceModel, str]:
    """The α–q model of ``[model] type = "alpha_q"`` with ``structure`` (a
    ``LinearAeroStructure``) and start ``parameters``: (model, description)."""
    from flightid.cases.alpha_q import alpha_q_constants, alpha_q_model

    first = case.maneuvers[0]
    path = Path(first.file)
    if not path.is_absolute():
        path = (data_dir if data_dir is not None else resolve_data_dir(case)) / path
    constants = alpha_q_constants(
        case.model.get("constants", {}), path, first.format, variable=first.variable
    )
    try:
        model = alpha_q_model(
            structure, parameters, name=case.model.get("name", "alpha_q_longitudinal"), **constants
        )
    except InputError as exc:
        raise CaseError(f"model: {exc}") from None
    return model, "built-in alpha_q model (α, q integrated; other variables measured)"


def _builtin_model(case: Case) -> StateSpaceModel:
    """A ``flightid.aircraft`` model from ``[model]`` (see docs/aircraft.md, "Case files"):

    type = "lateral" | "longitudinal" | "six_dof" | "wind_axis_longitudinal"
    airplane = {mass, Ix, Iy, Iz, Ixz, S, b, cbar, ...} (SI) or {library = "navion", ...}
    aero = {coefficient = [terms]}; optional controls, outputs, name, accelerometer
    (sign/unit convention of ax, ay, az) and measured (the lateral model's longitudinal
    inputs: ["u", "w", "q"] or ["V", "alpha", "q"]). Parameters start at 0; [parameters]
    sets start values.
    """
    from flightid import aircraft

    spec = case.model
    try:
        airplane = aircraft.airplane_from_table(spec["airplane"])
    except InputError as exc:
        raise CaseError(f"model.{exc}" if str(exc).startswith("airplane") else
                        f"model.airplane: {exc}") from None  # fmt: skip
    aero_spec = {}
    for coefficient, terms in spec["aero"].items():
        # a list of terms, or a table {parameter name = term} naming the parameters
        listed = list(terms.values()) if isinstance(terms, Mapping) else terms
        if not isinstance(listed, list) or not all(isinstance(t, str) for t in listed):
            raise CaseError(
                f"model.aero.{coefficient}: expected a list of terms like ['1', 'beta', "
                f"'alpha*phat', 'spline1(alpha,0.15)'] or a table {{name = term}}, got {terms!r}"
            )
        aero_spec[coefficient] = dict(terms) if isinstance(terms, Mapping) else terms
    try:
        aero = aircraft.AeroModel(aero_spec)
    except InputError as exc:
        raise CaseError(f"model.aero: {exc}") from None
    builder = {
        "wind_axis_longitudinal": aircraft.wind_axis_longitudinal_model,
        "longitudinal": aircraft.longitudinal_model,
        "lateral": aircraft.lateral_model,
        "six_dof": aircraft.six_dof_model,
    }[spec["type"]]
    kwargs: dict[str, Any] = {}
    for key in ("controls", "outputs", "measured"):
        if key in spec:
            if not isinstance(spec[key], list) or not all(isinstance(n, str) for n in spec[key]):
                raise CaseError(f"model.{key}: expected a list of names, got {spec[key]!r}")
            kwargs[key] = spec[key]
    if "measured" in kwargs and spec["type"] != "lateral":
        raise CaseError("model.measured: only the lateral model takes a choice of measured inputs")
    if "accelerometer" in spec:
        try:
            kwargs["accelerometer"] = aircraft.Accelerometer.from_value(spec["accelerometer"])
        except InputError as exc:
            raise CaseError(f"model.{exc}") from None
    # reference speed V0 (m/s) of Vrel, dVrel and rate_speed = "V0" (docs/aircraft.md)
    for key in ("reference_speed", "rate_speed"):
        if key in spec:
            kwargs[key] = spec[key]
    try:
        return builder(airplane, aero, aero.parameters(), name=spec.get("name"), **kwargs)
    except InputError as exc:
        raise CaseError(f"model: {exc}") from None


# ------------------------------------------------------------------------------ parameters


def _apply_parameters(parameters: Parameters, section: Mapping[str, Any]) -> list[Parameter]:
    items = {p.name: p for p in parameters}
    for name, value in section.items():
        if name not in items:
            raise CaseError(
                f"parameters.{name}: not a parameter of the model; its parameters: "
                f"{parameters.names}"
            )
        settings = dict(value) if isinstance(value, Mapping) else {"value": value}
        # per_maneuver is read by _per_maneuver_names, not a field of Parameter
        settings.pop("per_maneuver", None)
        try:
            items[name] = replace(items[name], **{k: v for k, v in settings.items()})
        except InputError as exc:
            raise CaseError(f"parameters.{name}: {exc}") from None
    return list(items.values())


def _per_maneuver_names(
    section: Mapping[str, Any], parameters: Parameters, not_allowed: Sequence[str]
) -> list[str]:
    """Names of the model parameters with ``per_maneuver = true`` in ``[parameters]``, in
    the model's parameter order (``not_allowed``: delay parameters the case adds)."""
    chosen = set()
    for name, value in section.items():
        if not isinstance(value, Mapping) or "per_maneuver" not in value:
            continue
        flag = value["per_maneuver"]
        where = f"parameters.{name}.per_maneuver"
        if not isinstance(flag, bool):
            raise CaseError(f"{where}: expected true or false, got {flag!r}")
        if not flag:
            continue
        if name in not_allowed:
            raise CaseError(
                f"{where}: {name!r} is a time delay the case adds; only parameters of the "
                "model's f and h can be per maneuver"
            )
        if name not in parameters:
            raise CaseError(
                f"{where}: {name!r} is not a parameter of the model; its parameters: "
                f"{parameters.names}"
            )
        chosen.add(name)
    return [n for n in parameters.names if n in chosen]


def _expand_per_maneuver(
    params: Sequence[Parameter], names: Sequence[str], n_m: int
) -> tuple[list[Parameter], dict[str, tuple[str, ...]]]:
    """The model parameters with each of ``names`` replaced by one copy per maneuver
    (``NAME_1`` … ``NAME_n``, same settings): the others in order, then the copies in
    maneuver-major order; and the {NAME: copies} map of ``StateSpaceModel``."""
    chosen = [p for p in params if p.name in names]
    expanded = [p for p in params if p.name not in names]
    for k in range(1, n_m + 1):
        expanded += [replace(p, name=per_maneuver_name(p.name, k)) for p in chosen]
    copies = {
        p.name: tuple(per_maneuver_name(p.name, k) for k in range(1, n_m + 1)) for p in chosen
    }
    return expanded, copies


# Body-axis states the built-in airplane models carry that data sets rarely record: their
# first value follows from measured flight variables [RP-1153 2.19–2.24]
#   u = V cos α cos β,  v = V sin β,  w = V sin α cos β,
#   l_xz = −sin Θ,  l_yz = sin Φ cos Θ,  l_zz = cos Φ cos Θ
_DERIVED_STATES = {
    "u": (("V", "alpha", "beta"), lambda V, a, b: V * math.cos(a) * math.cos(b)),
    "v": (("V", "beta"), lambda V, b: V * math.sin(b)),
    "w": (("V", "alpha", "beta"), lambda V, a, b: V * math.sin(a) * math.cos(b)),
    "l_xz": (("theta",), lambda th: -math.sin(th)),
    "l_yz": (("theta", "phi"), lambda th, ph: math.sin(ph) * math.cos(th)),
    "l_zz": (("theta", "phi"), lambda th, ph: math.cos(ph) * math.cos(th)),
}
# channels a derivation may do without (then 0: symmetric flight, wings level)
_OPTIONAL_ZERO = {"beta", "phi"}

# Initial states of the built-in airplane models are estimated (start: the first measured
# or derived sample) unless [initial_state] names them or sets a `default`; only the direction
# cosine that enters the decoupled models solely multiplied by a measured rate (l_yz of the
# longitudinal, l_xz of the lateral model: nearly unidentifiable) stays at the first sample.
# A state fixed at one noisy sample offsets the whole simulated record (airspeed: the
# phugoid; attitude: gravity) and makes the Cramér–Rao σ 1.5–4× too small; measured in
# docs/cases.md, "Initial states from measurements".
BUILTIN_AIRPLANE_TYPES = ("longitudinal", "lateral", "six_dof", "wind_axis_longitudinal")
FIXED_BY_DEFAULT = {"longitudinal": ("l_yz",), "lateral": ("l_xz",)}


def estimated_by_default(model_type: str | None, states: Sequence[str]) -> tuple[str, ...]:
    """The states of a ``model_type`` model estimated when ``[initial_state]`` is silent."""
    if model_type not in BUILTIN_AIRPLANE_TYPES:
        return ()
    fixed = FIXED_BY_DEFAULT.get(model_type, ())
    return tuple(s for s in states if s not in fixed)


def _has(maneuver: FlightData, channel: str) -> bool:
    return channel in maneuver.input_names or channel in maneuver.output_names


def _first_measured(maneuver: FlightData, channel: str, where: str) -> float:
    """First sample of ``channel``; for u, v, w and the direction cosines of the built-in
    airplane models, derived from the first V, α, β, Θ, Φ when the channel is not recorded."""
    if _has(maneuver, channel):
        return float(maneuver.channel(channel)[0])
    if channel in _DERIVED_STATES:
        needed, formula = _DERIVED_STATES[channel]
        missing = [c for c in needed if not _has(maneuver, c) and c not in _OPTIONAL_ZERO]
        if not missing:
            return float(
                formula(
                    *(float(maneuver.channel(c)[0]) if _has(maneuver, c) else 0.0 for c in needed)
                )
            )
        raise CaseError(
            f"{where}: 'measured' needs a data channel {channel!r}, or the channels "
            f"{list(needed)} to derive it from (missing {missing}) in maneuver "
            f"'{maneuver.name}'"
        )
    raise CaseError(
        f"{where}: 'measured' needs a data channel named {channel!r} in maneuver "
        f"'{maneuver.name}' (set channel = '...' to use another)"
    )


def _initial_states(
    model: StateSpaceModel,
    section: Mapping[str, Any],
    maneuvers: Sequence[FlightData],
    key: str,
    allow_estimate: bool = True,
    default_estimated: Sequence[str] = (),
) -> tuple[list[list], list[Parameter]]:
    """Per-maneuver x0 specifications and the x0 parameters they need, in maneuver-major
    order (maneuver 1's free states in state order, then maneuver 2's …, the order in which
    FVSysID's flight-path reconstruction test case TC33 lists them). A state without an entry
    takes the section's ``default``, else "estimate" if it is one of ``default_estimated``
    (and estimation is allowed), else "measured"."""
    unknown = sorted(set(section) - set(model.states) - {"default"})
    if unknown:
        raise CaseError(
            f"{key}.{unknown[0]}: not a state of the model; states: {list(model.states)}"
        )
    n_m = len(maneuvers)
    x0 = [[None] * len(model.states) for _ in range(n_m)]
    extra: list[tuple[int, int, Parameter]] = []  # (maneuver, state, parameter)
    for j, state in enumerate(model.states):
        where = f"{key}.{state}"
        implicit = "estimate" if allow_estimate and state in default_estimated else "measured"
        value = section.get(state, section.get("default", implicit))
        spec = dict(value) if isinstance(value, Mapping) else {"value": value}
        allowed = {"value", "free", "channel", "scale"}
        if set(spec) - allowed:
            raise CaseError(
                f"{where}: unknown key(s) {sorted(set(spec) - allowed)}; allowed: {sorted(allowed)}"
            )
        start = spec.get("value", "measured")
        free = spec.get("free", False)
        if start == "estimate":
            start, free = "measured", True
        if not isinstance(free, bool):
            raise CaseError(f"{where}.free: expected true or false")
        if free and not allow_estimate:
            raise CaseError(f"{where}: initial states of predicted maneuvers cannot be estimated")
        channel = spec.get("channel", state)
        if isinstance(start, list):
            if len(start) != n_m:
                raise CaseError(
                    f"{where}: a list needs one value per maneuver ({n_m}), got {len(start)}"
                )
            values = [float(_num(v, f"{where}[{k}]")) for k, v in enumerate(start)]
        elif start == "measured":
            values = [_first_measured(m, channel, where) for m in maneuvers]
        elif isinstance(start, str):
            raise CaseError(
                f"{where}: expected a number, a list, 'measured' or 'estimate', got {start!r}"
            )
        else:
            values = [_num(start, where)] * n_m
        for k, v in enumerate(values):
            if free:
                name = f"x0_{state}" if n_m == 1 else f"x0_{state}_{k + 1}"
                extra.append((k, j, Parameter(name, v, free=True, scale=spec.get("scale"))))
                x0[k][j] = name
            else:
                x0[k][j] = v
    return x0, [p for _, _, p in sorted(extra, key=lambda e: (e[0], e[1]))]


def _predicted_entry(value: Any) -> Any:
    """One ``[initial_state]`` entry as it applies to a predicted maneuver, or None where it
    does not apply: numbers and ``channel`` are kept; an estimated start ("estimate" or
    ``free = true``) becomes the maneuver's first measured value of the same channel (a
    predicted maneuver has nothing to estimate it from); a list (one value per estimation
    maneuver) does not apply, nor does a plain "measured" (the prediction's own default
    decides)."""
    spec = dict(value) if isinstance(value, Mapping) else {"value": value}
    start = spec.get("value", "measured")
    if isinstance(start, list):
        return None
    if start == "estimate" or spec.get("free") is True:
        start = "measured"
    if start == "measured" and "channel" not in spec:
        return None
    entry = {"value": start}
    if "channel" in spec:
        entry["channel"] = spec["channel"]
    return entry


def prediction_initial_state(case: Case) -> dict[str, Any]:
    """The initial-state settings of the predicted maneuvers, per state: the entry of
    ``[prediction.initial_state]`` (or a prediction stage's ``initial_state``), else the
    case's ``[initial_state]`` entry as it applies to a predicted maneuver
    (``_predicted_entry``), else the ``default`` of the prediction's table, else that of
    ``[initial_state]``, else the first measured value."""
    section: dict[str, Any] = {}
    for state, value in case.initial_state.items():
        entry = _predicted_entry(value)
        if entry is not None:
            section[state] = entry
    section.update(case.prediction_initial_state)
    return section


def _num(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CaseError(f"{where}: expected a number, got {value!r}")
    return float(value)


def _biases(
    model: StateSpaceModel, biases: Mapping[str, Mapping[str, Any]], n_m: int
) -> tuple[np.ndarray, np.ndarray, list[Parameter], bool]:
    """Index maps (n_m, n_x), (n_m, n_o) into the full θ (−1: no bias) and new parameters."""
    n_base = len(model.parameters)
    bx = -np.ones((n_m, len(model.states)), dtype=np.int64)
    by = -np.ones((n_m, len(model.outputs)), dtype=np.int64)
    extra: list[Parameter] = []
    per_maneuver_any = False
    for kind, names, table, prefix in (
        ("states", model.states, bx, "bx"),
        ("outputs", model.outputs, by, "by"),
    ):
        for name, value in biases.get(kind, {}).items():
            where = f"biases.{kind}.{name}"
            if name not in names:
                raise CaseError(f"{where}: not one of the model's {kind} {list(names)}")
            spec = dict(value) if isinstance(value, Mapping) else {"value": value}
            per = bool(spec.get("per_maneuver", False)) and n_m > 1
            per_maneuver_any |= per
            j = names.index(name)
            for k in range(n_m if per else 1):
                pname = f"{prefix}_{name}" + (f"_{k + 1}" if per else "")
                extra.append(
                    Parameter(
                        pname,
                        float(spec.get("value", 0.0)),
                        free=bool(spec.get("free", True)),
                        scale=spec.get("scale"),
                    )
                )
                index = n_base + len(extra) - 1
                if per:
                    table[k, j] = index
                else:
                    table[:, j] = index
    return bx, by, extra, per_maneuver_any


def _dispatcher(fn):
    """The numba dispatcher of the model function ``fn`` (``compiled_function``: one per
    process for the same function, kept in the on-disk kernel cache), or numba's error where
    it refuses the function outright. Nothing is compiled or loaded here: the kernel that
    calls it compiles it (or loads it from the cache) when the estimation builds it, and a
    function numba cannot compile then runs in Python with the simulator's ``CompileWarning``
    (``flightid.simulation.Simulator``)."""
    from flightid.model.kernel_cache import compiled_function

    try:
        return compiled_function(fn)
    except Exception as exc:  # numba's errors have many classes
        return exc


def _biased_functions(f, h, n_x, n_y, n_u, bx, by, per_maneuver, compiled):
    """f, h with the state and output biases added, in return form carrying their out forms
    (``flightid.model.forms``; built on the base model's out forms, so that a base without
    allocation stays without).

    The return forms call the Python f and h (``check_model`` and the other Python callers:
    nothing is compiled before the estimation). With ``compiled`` = (f_jit, h_jit), the
    numba dispatchers of f and h (or f and h themselves where they carry their own out form),
    the out forms are numba-compilable closures around the compiled out forms, each carrying
    the Python one as ``python_form``: the interpreted kernel of the fall-back runs that."""
    from flightid.model.forms import as_out_form, kernel_function, with_out_form

    def out_form(fn, jit):
        return kernel_function(getattr(fn, "out_form", None) or as_out_form(fn), jit)

    # ẋ_j = f_j + b_x,j ;  y_j = h_j + b_y,j
    f_py = _with_biases(f, out_form(f, False), n_x, n_u, bx, per_maneuver)
    h_py = _with_biases(h, out_form(h, False), n_y, n_u, by, per_maneuver)
    if not compiled:
        return f_py, h_py
    f_jit, h_jit = compiled
    f_out = _with_biases(f_jit, out_form(f_jit, True), n_x, n_u, bx, per_maneuver).out_form
    h_out = _with_biases(h_jit, out_form(h_jit, True), n_y, n_u, by, per_maneuver).out_form
    f_out.python_form = f_py.out_form
    h_out.python_form = h_py.out_form
    return with_out_form(f_py, f_out), with_out_form(h_py, h_out)


def _with_biases(fn, fn_out, n, n_u, b, per_maneuver):
    """``fn`` (return form, out form ``fn_out``) with the biases θ[b[m, j]] added to its n
    values (none where b[m, j] < 0; m the maneuver number from the extra input channel when
    ``per_maneuver``), in return form carrying its out form (numba-compilable closures)."""
    from flightid.model.forms import with_out_form

    def biased(t, x, u, theta):
        m = int(u[n_u] + 0.5) if per_maneuver else 0
        v = fn(t, x, u[:n_u], theta)
        out = np.empty(n)
        for j in range(n):
            # v_j + b_j
            out[j] = v[j] + (theta[b[m, j]] if b[m, j] >= 0 else 0.0)
        return out

    def biased_out(t, x, u, theta, out):
        m = int(u[n_u] + 0.5) if per_maneuver else 0
        fn_out(t, x, u[:n_u], theta, out)
        for j in range(n):
            # v_j + b_j
            out[j] = out[j] + (theta[b[m, j]] if b[m, j] >= 0 else 0.0)

    return with_out_form(biased, biased_out)


def _model_and_delay_parameters(
    case: Case,
    base: StateSpaceModel,
    delays: Mapping[str, str],
    input_delays: Mapping[str, str],
) -> tuple[list[Parameter], list[Parameter], list[str]]:
    """The model's parameters with ``[parameters]`` applied, the delay parameters the model
    does not have, and those new delay names.

    Delay parameters the model does not have are new parameters τ (s), start 0, free, put
    after the biases and initial states (output delays', then input delays' new names);
    ``[parameters]`` sets them like any other."""
    new_delays = [
        n
        for n in dict.fromkeys([*delays.values(), *input_delays.values()])
        if n not in base.parameters
    ]
    section = {k: v for k, v in case.parameters.items() if k not in new_delays}
    params = _apply_parameters(base.parameters, section)
    delay_params = (
        _apply_parameters(
            Parameters([Parameter(n, 0.0) for n in new_delays]),
            {k: v for k, v in case.parameters.items() if k in new_delays},
        )
        if new_delays
        else []
    )
    return params, delay_params, new_delays


def _biased_model_functions(case: Case, base: StateSpaceModel, bx, by, per_maneuver: bool):
    """The base model's f and h with the biases added (``_biased_functions``): out forms
    around the compiled f and h (their own out forms where they carry one) when the case
    compiles, else around the Python functions (then carrying numba's error, where numba
    refused a function outright, for the simulator's fall-back message)."""
    jitted = (
        [
            fn if getattr(fn, "out_form", None) is not None else _dispatcher(fn)
            for fn in (base.f, base.h)
        ]
        if case.estimation.get("compiled", True)
        else []
    )
    failure = next((fn for fn in jitted if isinstance(fn, BaseException)), None)
    compiled = tuple(jitted) if jitted and failure is None else None
    f, h = _biased_functions(
        base.f,
        base.h,
        len(base.states),
        len(base.outputs),
        len(base.inputs),
        bx,
        by,
        per_maneuver,
        compiled,
    )
    if failure is not None:
        # the simulator's fall-back to Python names the user's line from this error (its
        # own error would name the wrappers)
        for fn in (f, h):
            fn.out_form.compile_failure = failure
    return f, h


def build_model(
    case: Case,
    maneuvers: Sequence[FlightData],
    *,
    base: StateSpaceModel | None = None,
    initial_state: Mapping[str, Any] | None = None,
    values: Mapping[str, float] | None = None,
    key: str = "initial_state",
) -> tuple[StateSpaceModel, list[FlightData]]:
    """The case's model for these maneuvers, and the maneuvers (with the maneuver-number
    channel added when per-maneuver biases need it).

    ``values`` (name → value) replaces parameter values afterwards (prediction with estimates).
    """
    base = base_model(case)[0] if base is None else base
    _check_channels(base, maneuvers)
    delays = dict(case.model.get("output_delays", {}))
    input_delays = dict(case.model.get("input_delays", {}))
    params, delay_params, new_delays = _model_and_delay_parameters(case, base, delays, input_delays)
    n_m = len(maneuvers)
    per_names = _per_maneuver_names(case.parameters, base.parameters, new_delays)
    bx, by, bias_params, per_maneuver = _biases(base, case.biases, n_m)
    section = case.initial_state if initial_state is None else initial_state
    x0, x0_params = _initial_states(
        base,
        section,
        maneuvers,
        key,
        allow_estimate=values is None,
        default_estimated=estimated_by_default(case.model.get("type"), base.states),
    )
    # f and h index θ as (model, biases, x0, delays); with per-maneuver parameters θ holds
    # (other model parameters, copies per maneuver, biases, x0, delays) and the simulator
    # substitutes each maneuver's copies (StateSpaceModel.maneuver_parameters)
    layout = [p.name for p in params + bias_params + x0_params + delay_params]
    copies: dict[str, tuple[str, ...]] = {}
    if per_names and n_m > 1:
        params, copies = _expand_per_maneuver(params, per_names, n_m)
    try:
        parameters = Parameters(params + bias_params + x0_params + delay_params)
    except InputError as exc:
        raise CaseError(f"parameters: {exc}") from None
    f, h, inputs = base.f, base.h, base.inputs
    if bias_params:
        f, h = _biased_model_functions(case, base, bx, by, per_maneuver)
        if per_maneuver:
            inputs = (*base.inputs, MANEUVER_CHANNEL)
            maneuvers = [_with_maneuver_channel(m, k) for k, m in enumerate(maneuvers)]
    if values is not None:
        parameters = parameters.with_values({k: v for k, v in values.items() if k in parameters})
    try:
        model = StateSpaceModel(
            base.states,
            inputs,
            base.outputs,
            f,
            h,
            parameters,
            x0=x0,
            name=base.name,
            output_delays=delays or None,
            input_delays=input_delays or None,
            delay_convention=case.model.get("delay_convention", "fractional"),
            function_parameters=layout if copies else None,
            maneuver_parameters=copies or None,
        )
    except InputError as exc:
        raise CaseError(f"model: {exc}") from None
    _check_channels(model, maneuvers)
    return model, list(maneuvers)


def _with_maneuver_channel(maneuver: FlightData, k: int) -> FlightData:
    inputs = {n: maneuver.input(n) for n in maneuver.input_names}
    inputs[MANEUVER_CHANNEL] = np.full(maneuver.n_samples, float(k))
    outputs = {n: maneuver.output(n) for n in maneuver.output_names}
    return FlightData(
        maneuver.time,
        inputs,
        outputs,
        units=maneuver.units,
        name=maneuver.name,
        notes=maneuver.notes,
    )


def _check_channels(model: StateSpaceModel, maneuvers: Sequence[FlightData]) -> None:
    for maneuver in maneuvers:
        channels = set(maneuver.input_names) | set(maneuver.output_names)
        missing_in = [n for n in model.inputs if n not in channels]
        if missing_in:
            raise CaseError(
                f"data.inputs: the model needs input channel(s) {missing_in}; the case defines "
                f"{sorted(channels)}"
            )
        missing_out = [n for n in model.outputs if n not in maneuver.output_names]
        if missing_out:
            raise CaseError(
                f"data.outputs: the model's outputs {missing_out} are not measured output "
                f"channels; data.outputs has {list(maneuver.output_names)}"
            )


# ------------------------------------------------------------------------------ estimation


def build_solver(case: Case) -> MNRES | MNR | FPS:
    name = case.estimation.get("solver", "mnres")
    cls = {"mnres": MNRES, "mnr": MNR, "fps": FPS}[name]
    settings = dict(case.estimation.get("solver_settings", {}))
    try:
        return cls(**settings)
    except TypeError as exc:
        raise CaseError(f"estimation.solver_settings: {exc} (solver {name})") from None
    except InputError as exc:
        raise CaseError(f"estimation.solver_settings: {exc}") from None


def build_convergence(case: Case) -> Convergence:
    settings = dict(case.estimation.get("convergence", {}))
    try:
        return Convergence(**settings)
    except TypeError as exc:
        raise CaseError(f"estimation.convergence: {exc}") from None
    except InputError as exc:
        raise CaseError(f"estimation.convergence: {exc}") from None


def unbiased_model(
    model: StateSpaceModel, base: StateSpaceModel, n_maneuvers: int
) -> StateSpaceModel | None:
    """The case's model *before* biases were wrapped around f and h, at the case's start
    values and initial states — or None when f and h are not wrapped.

    The bias wrappers call the user's f and h compiled (where numba can), and compiled code
    does not check indices, so the user's own functions are checked on their own as well.
    """
    if model.f is base.f and model.h is base.h:
        return None
    theta = model.parameters.values
    # the base model's parameters (or, per maneuver, the others and the copies): the
    # leading entries of θ
    copies = {k: v for k, v in model.maneuver_parameters.items() if k in base.parameters}
    n_lead = len(base.parameters) + len(copies) * (max(model.n_parameter_maneuvers, 1) - 1)
    parameters = Parameters(list(model.parameters)[:n_lead])
    x0 = [model.initial_state(theta, i).tolist() for i in range(n_maneuvers)]
    return StateSpaceModel(
        base.states,
        base.inputs,
        base.outputs,
        base.f,
        base.h,
        parameters,
        x0=x0 if model.per_maneuver_x0 else x0[0],
        name=base.name,
        function_parameters=base.parameters.names if copies else None,
        maneuver_parameters=copies or None,
    )


def with_process_noise(
    case: Case, model: StateSpaceModel
) -> tuple[StateSpaceModel, dict[str, str]]:
    """The model with the ``[process_noise]`` elements appended as parameters (after all
    others, so f and h index θ as before), and {state: parameter name} of the diagonal F.

    Each entry ``state = value`` or ``{value, free, name, scale}`` adds the parameter F_ii
    (default name ``F11``, ``F22``, … by the state's position; free by default).
    """
    from flightid.estimation.filter_error import process_noise_name

    added: list[Parameter] = []
    mapping: dict[str, str] = {}
    for state, value in case.process_noise.items():
        where = f"process_noise.{state}"
        if state not in model.states:
            raise CaseError(f"{where}: not a state of the model; states {list(model.states)}")
        spec = value if isinstance(value, Mapping) else {"value": value}
        name = spec.get("name", process_noise_name(model.states.index(state)))
        if name in model.parameters or name in mapping.values():
            raise CaseError(f"{where}.name: {name!r} is already a parameter of the model")
        added.append(
            Parameter(
                name,
                float(spec["value"]),
                free=bool(spec.get("free", True)),
                scale=None if spec.get("scale") is None else float(spec["scale"]),
            )
        )
        mapping[state] = name
    try:
        parameters = Parameters(list(model.parameters) + added)
    except InputError as exc:
        raise CaseError(f"process_noise: {exc}") from None
    try:
        # f and h keep indexing θ as before (the F elements come last)
        noisy = replace(model, parameters=parameters)
    except InputError as exc:
        raise CaseError(f"process_noise: {exc}") from None
    return noisy, mapping
