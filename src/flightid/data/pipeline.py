"""Declared pre-processing pipelines: named constants, intermediate signals and built-in steps.

A case's ``[data]`` may hold, beside ``inputs`` and ``outputs``::

    [data.constants]                  # named numbers (SI, or {value, unit}) and positions
    m = 17631                         # kg
    Ix = { value = 1.33367e5, unit = "kg*m^2" }
    NB = [13.080, -0.010, -0.027]     # m from the CG (x, y, z body axes)

    [data.signals]                    # named intermediate channels (the channel grammar)
    p = { column = 7, unit = "deg/s" }                     # rad/s
    q_c = "q - 3.40891e-3"                                 # expr over signals/constants/columns
    alpha_s = { column = "alpha_cg", smooth = "smoothMulTS" }
    qbar = "0.5 * rho * V_s * V_s"

    [[data.steps]]                    # built-in steps, each producing named signals
    kind = "transfer_air_data"
    signals = { V = "V", alpha = "alpha", beta = "beta", p = "p_c", q = "q_c", r = "r_c" }
    sensor = "NB"                     # a constant, or [x, y, z] in m
    names = { V = "V_cg", alpha = "alpha_cg", beta = "beta_cg" }   # the defaults

Names. Inside a signal's ``column`` or ``expr`` and in a step's ``signals``, a name is, in this
order: a signal (of ``[data.signals]`` or made by a step), a constant (scalar constants only
in expressions), or a column of the file. Inside signal X the name X itself is the file's
column X, so ``p = { column = "p", unit = "deg/s" }`` is allowed. ``[data.inputs]`` and
``[data.outputs]`` use the same names (a channel that is one signal, ``alpha = "alpha_s"``,
inherits the signal's unit).

Order. Signals and steps are computed in dependency order (each once everything it names
is computed; among those ready, in the order written: signals before steps), so a file can
be read top to bottom or not; a cycle is a ``PreprocessError`` naming it.

Every smoothing and differentiation restarts at maneuver and segment boundaries (the loader
calls the pipeline per maneuver, with that maneuver's segments); the steps are algebraic,
sample by sample. The steps' physics is in ``flightid.data.transfer`` and
``flightid.data.coefficients``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from flightid.data.channels import ChannelSpec
from flightid.data.coefficients import COEFFICIENTS, Engine, MassGeometry, aero_coefficients
from flightid.data.expressions import expression_columns, parse_expression
from flightid.data.preprocess import PreprocessError, apply_steps
from flightid.data.table import ChannelError, Table
from flightid.data.transfer import transfer_accelerations, transfer_air_data
from flightid.data.units import channel_conversion, parse_unit
from flightid.errors import InputError, describe

__all__ = [
    "STEP_KINDS",
    "Pipeline",
    "StepSpec",
    "parse_constants",
    "parse_pipeline",
]

_RATE = {"p": "rad/s", "q": "rad/s", "r": "rad/s"}
_RATE_DOT = {"pdot": "rad/s^2", "qdot": "rad/s^2", "rdot": "rad/s^2"}
_ACCEL = {"ax": "m/s^2", "ay": "m/s^2", "az": "m/s^2"}


@dataclass(frozen=True)
class _Kind:
    """A built-in step: its input roles with their units (None: any), output roles with
    default names and units, and its setting keys (required and optional)."""

    roles: Mapping[str, str | None]
    outputs: Mapping[str, tuple[str, str]]
    required: tuple[str, ...] = ()
    optional: tuple[str, ...] = ()
    what: str = ""


STEP_KINDS: dict[str, _Kind] = {
    "remove_bias": _Kind(
        roles={},
        outputs={},
        required=("biases",),
        what="x_c = x − b for each signal x of 'biases' (b in x's unit); names default x_c",
    ),
    "transfer_air_data": _Kind(
        roles={"V": "m/s", "alpha": "rad", "beta": "rad", **_RATE},
        outputs={"V": ("V_cg", "m/s"), "alpha": ("alpha_cg", "rad"), "beta": ("beta_cg", "rad")},
        required=("sensor",),
        optional=("target",),
        what="V, α, β measured at 'sensor' moved to 'target' (default the CG)",
    ),
    "transfer_accelerations": _Kind(
        roles={**_ACCEL, **_RATE, **_RATE_DOT},
        outputs={"ax": ("ax_cg", "m/s^2"), "ay": ("ay_cg", "m/s^2"), "az": ("az_cg", "m/s^2")},
        required=("sensor",),
        optional=("target",),
        what="accelerations measured at 'sensor' moved to 'target' (default the CG)",
    ),
    "aero_coefficients": _Kind(
        roles={**_ACCEL, **_RATE, **_RATE_DOT, "qbar": "Pa", "alpha": "rad"},
        outputs={name: (name, "") for name in COEFFICIENTS},
        required=("mass", "Ix", "Iy", "Iz", "S", "cbar", "b"),
        optional=("Ixz", "Ixy", "Iyz", "reference_point", "engines"),
        what="C_X, C_Y, C_Z, C_l, C_m, C_n, C_L, C_D from accelerations at the CG, rates, "
        "angular accelerations, q̄, α, thrust, mass, inertia and geometry",
    ),
}
# SI units of the scalar settings of aero_coefficients (a {value, unit} is converted to them)
_SETTING_UNITS = {
    "mass": "kg",
    "Ix": "kg*m^2",
    "Iy": "kg*m^2",
    "Iz": "kg*m^2",
    "Ixz": "kg*m^2",
    "Ixy": "kg*m^2",
    "Iyz": "kg*m^2",
    "S": "m^2",
    "cbar": "m",
    "b": "m",
}
_ENGINE_KEYS = {"thrust", "position", "incidence"}


# ------------------------------------------------------------------------------ constants


def _quantity(value: Any, where: str) -> float | tuple[float, ...]:
    """A number, a list of numbers, or {value = number | [numbers], unit = "..."} (converted
    to SI by the channel rule)."""
    unit = ""
    if isinstance(value, Mapping):
        unknown = sorted(set(value) - {"value", "unit"})
        if unknown or "value" not in value:
            raise PreprocessError(
                f"{where}: expected a number, a list of numbers or {{value = ..., unit = ...}}, "
                f"got keys {sorted(value)}"
            )
        unit = value.get("unit", "")
        if not isinstance(unit, str):
            raise PreprocessError(f"{where}.unit: expected a unit string, got {describe(unit)}")
        value = value["value"]
    try:
        factor = channel_conversion(unit)[0] if unit else 1.0
    except InputError as exc:
        raise PreprocessError(f"{where}: {exc}") from None
    if isinstance(value, (list, tuple)):
        numbers = [_number(v, f"{where}[{k}]") for k, v in enumerate(value)]
        if not numbers:
            raise PreprocessError(f"{where}: expected a non-empty list of numbers")
        # value_SI = factor · value
        return tuple(factor * v for v in numbers)
    return factor * _number(value, where)


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise PreprocessError(f"{where}: expected a finite number, got {describe(value)}")
    return float(value)


def parse_constants(section: Mapping[str, Any] | None, where: str = "constants") -> dict:
    """``[data.constants]`` → {name: number or tuple of numbers} in SI."""
    if section is None:
        return {}
    if not isinstance(section, Mapping):
        raise PreprocessError(f"{where}: expected a table of name = value, got {describe(section)}")
    constants = {}
    for name, value in section.items():
        if not isinstance(name, str) or not name.isidentifier() or name in ("t", "pi"):
            raise PreprocessError(
                f"{where}: constant names must be identifiers other than 't' and 'pi', got {name!r}"
            )
        constants[name] = _quantity(value, f"{where}.{name}")
    return constants


# ------------------------------------------------------------------------------ steps


@dataclass(frozen=True)
class StepSpec:
    """One checked ``[[data.steps]]`` entry.

    Attributes:
        kind: a key of ``STEP_KINDS``.
        index: its position in ``[[data.steps]]`` (0-based), for messages.
        signals: role → the signal (or column) it reads.
        names: role → the signal it makes.
        settings: the kind's settings, resolved to SI numbers and 3-vectors (engines: a
            tuple of (thrust signal, position, incidence_rad)).
    """

    kind: str
    index: int
    signals: Mapping[str, str]
    names: Mapping[str, str]
    settings: Mapping[str, Any] = field(default_factory=dict)

    @property
    def where(self) -> str:
        return f"steps[{self.index}] ({self.kind})"

    def reads(self) -> list[str]:
        """The names it reads (signals, thrust channels)."""
        names = list(self.signals.values())
        names += [engine[0] for engine in self.settings.get("engines", ())]
        return names


def _signal_name(value: Any, where: str) -> str:
    if not isinstance(value, str) or not value.isidentifier():
        raise PreprocessError(f"{where}: expected a signal or column name, got {describe(value)}")
    return value


def _setting(value: Any, constants: Mapping[str, Any], where: str, unit: str = "") -> Any:
    """A setting: a constant's name, or a quantity (number, list, {value, unit})."""
    if isinstance(value, str):
        if value not in constants:
            raise PreprocessError(
                f"{where}: no constant named {value!r} in [data.constants]; constants: "
                f"{sorted(constants) or 'none'}"
            )
        return constants[value]
    quantity = _quantity(value, where)
    if isinstance(value, Mapping) and unit and value.get("unit"):
        # {value, unit}: delivered in SI; check it measures what the setting needs
        if parse_unit(value["unit"])[1] != parse_unit(unit)[1]:
            raise PreprocessError(
                f"{where}: expected a value in {unit} (or a unit of the same kind), got unit "
                f"{value['unit']!r}"
            )
    return quantity


def _position(value: Any, constants: Mapping[str, Any], where: str) -> tuple[float, float, float]:
    position = _setting(value, constants, where, "m")
    if not isinstance(position, tuple) or len(position) != 3:
        raise PreprocessError(
            f"{where}: expected a position [x, y, z] in m (or the name of such a constant), got "
            f"{describe(position)}"
        )
    return position


def _scalar(value: Any, constants: Mapping[str, Any], where: str, unit: str = "") -> float:
    number = _setting(value, constants, where, unit)
    if isinstance(number, tuple):
        raise PreprocessError(f"{where}: expected one number, got the list {list(number)}")
    return number


def _step_kind(raw: Any, index: int) -> tuple[str, _Kind]:
    """The checked kind of ``[[data.steps]]`` entry ``index`` and its ``_Kind``."""
    where = f"steps[{index}]"
    if not isinstance(raw, Mapping):
        raise PreprocessError(f"{where}: expected a table ([[data.steps]]), got {describe(raw)}")
    kind_name = raw.get("kind")
    if kind_name not in STEP_KINDS:
        raise PreprocessError(
            f"{where}.kind: expected one of {sorted(STEP_KINDS)}, got {kind_name!r}"
        )
    return kind_name, STEP_KINDS[kind_name]


def _check_step_keys(raw: Mapping[str, Any], kind: _Kind, where: str) -> None:
    """No key the kind does not know, every key it requires."""
    allowed = {"kind", "names", *kind.required, *kind.optional}
    if kind.roles:
        allowed.add("signals")
    unknown = sorted(set(raw) - allowed)
    if unknown:
        raise PreprocessError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(allowed)}")
    missing = [k for k in kind.required if k not in raw]
    if missing:
        raise PreprocessError(f"{where}: missing {missing} ({kind.what})")


def _bias_step(
    raw: Mapping[str, Any], constants: Mapping[str, Any], where: str
) -> tuple[dict[str, str], dict[str, Any], dict[str, str]]:
    """(roles, settings, default output names) of a remove_bias step."""
    biases = raw["biases"]
    if not isinstance(biases, Mapping) or not biases:
        raise PreprocessError(
            f"{where}.biases: expected a table signal = bias (in the signal's unit), got "
            f"{describe(biases)}"
        )
    roles = {_signal_name(k, f"{where}.biases"): k for k in biases}
    settings = {
        "biases": {k: _scalar(v, constants, f"{where}.biases.{k}") for k, v in biases.items()}
    }
    defaults = {k: f"{k}_c" for k in biases}
    return roles, settings, defaults


def _step_roles(raw: Mapping[str, Any], kind: _Kind, where: str) -> dict[str, str]:
    """Role → the signal it reads: ``signals`` of the step, by default the role's name."""
    given = raw.get("signals", {})
    if not isinstance(given, Mapping):
        raise PreprocessError(
            f"{where}.signals: expected a table role = signal, got {describe(given)}"
        )
    bad = sorted(set(given) - set(kind.roles))
    if bad:
        raise PreprocessError(f"{where}.signals: unknown role(s) {bad}; roles: {list(kind.roles)}")
    return {
        role: _signal_name(given.get(role, role), f"{where}.signals.{role}") for role in kind.roles
    }


def _step_settings(
    raw: Mapping[str, Any], constants: Mapping[str, Any], where: str
) -> dict[str, Any]:
    """The positions (m), scalar settings (SI) and engines that ``raw`` gives."""
    settings: dict[str, Any] = {}
    for key in ("sensor", "target", "reference_point"):
        if key in raw:
            settings[key] = _position(raw[key], constants, f"{where}.{key}")
    for key, unit in _SETTING_UNITS.items():
        if key in raw:
            settings[key] = _scalar(raw[key], constants, f"{where}.{key}", unit)
    if "engines" in raw:
        settings["engines"] = _engines(raw["engines"], constants, f"{where}.engines")
    return settings


def _output_names(
    raw: Mapping[str, Any], defaults: Mapping[str, str], where: str
) -> dict[str, str]:
    """Role → the signal the step makes: ``names`` of the step, by default ``defaults``."""
    names_given = raw.get("names", {})
    if not isinstance(names_given, Mapping):
        raise PreprocessError(f"{where}.names: expected a table role = name, got {names_given!r}")
    bad = sorted(set(names_given) - set(defaults))
    if bad:
        raise PreprocessError(f"{where}.names: unknown role(s) {bad}; roles: {list(defaults)}")
    return {
        role: _signal_name(names_given.get(role, default), f"{where}.names.{role}")
        for role, default in defaults.items()
    }


def _mass_geometry(settings: Mapping[str, Any]) -> MassGeometry:
    """The ``MassGeometry`` of an aero_coefficients step's settings (SI)."""
    return MassGeometry(
        mass_kg=settings["mass"],
        Ix=settings["Ix"],
        Iy=settings["Iy"],
        Iz=settings["Iz"],
        S_m2=settings["S"],
        cbar_m=settings["cbar"],
        b_m=settings["b"],
        Ixz=settings.get("Ixz", 0.0),
        Ixy=settings.get("Ixy", 0.0),
        Iyz=settings.get("Iyz", 0.0),
        reference_point_m=settings.get("reference_point", (0.0, 0.0, 0.0)),
    )


def _check_geometry(settings: Mapping[str, Any], where: str) -> None:
    """The mass and geometry of an aero_coefficients step make a ``MassGeometry``."""
    try:
        _mass_geometry(settings)
    except PreprocessError as exc:
        raise PreprocessError(f"{where}: {exc}") from None


def _parse_step(raw: Any, index: int, constants: Mapping[str, Any]) -> StepSpec:
    kind_name, kind = _step_kind(raw, index)
    where = f"steps[{index}] ({kind_name})"
    _check_step_keys(raw, kind, where)
    if kind_name == "remove_bias":
        roles, settings, defaults = _bias_step(raw, constants, where)
    else:
        roles = _step_roles(raw, kind, where)
        defaults = {role: name for role, (name, _) in kind.outputs.items()}
        settings = _step_settings(raw, constants, where)
    names = _output_names(raw, defaults, where)
    if kind_name == "aero_coefficients":
        _check_geometry(settings, where)
    return StepSpec(kind_name, index, roles, names, settings)


def _engines(value: Any, constants: Mapping[str, Any], where: str) -> tuple:
    if not isinstance(value, list):
        raise PreprocessError(
            f"{where}: expected a list of {{thrust = signal, position = [x, y, z], "
            f"incidence = rad}}, got {describe(value)}"
        )
    engines = []
    for k, engine in enumerate(value):
        at = f"{where}[{k}]"
        if not isinstance(engine, Mapping) or "thrust" not in engine or "position" not in engine:
            raise PreprocessError(
                f"{at}: expected {{thrust = signal (N), position = [x, y, z] (m), "
                f"incidence = angle (rad, optional)}}, got {describe(engine)}"
            )
        unknown = sorted(set(engine) - _ENGINE_KEYS)
        if unknown:
            raise PreprocessError(f"{at}: unknown key(s) {unknown}; allowed {sorted(_ENGINE_KEYS)}")
        engines.append(
            (
                _signal_name(engine["thrust"], f"{at}.thrust"),
                _position(engine["position"], constants, f"{at}.position"),
                _scalar(engine.get("incidence", 0.0), constants, f"{at}.incidence", "rad"),
            )
        )
    return tuple(engines)


# ------------------------------------------------------------------------------ pipeline


def _units_equal(a: str, b: str) -> bool:
    fa, da = parse_unit(a)
    fb, db = parse_unit(b)
    return da == db and abs(fa - fb) <= 1e-12 * max(abs(fa), abs(fb))


def _channel_names(spec: ChannelSpec) -> list[str]:
    """Names (not column numbers) a channel specification reads."""
    if spec.expr is not None:
        return [c for c in expression_columns(parse_expression(spec.expr)) if isinstance(c, str)]
    return [spec.column] if isinstance(spec.column, str) else []


@dataclass(frozen=True)
class Pipeline:
    """Checked constants, signals and steps, with their order of evaluation.

    Attributes:
        constants: name → SI number or tuple (positions).
        signals: name → ``ChannelSpec``.
        steps: the ``StepSpec`` of ``[[data.steps]]``.
        order: ("signal", name) / ("step", index) in the order they are computed.
        units: every made signal → its unit ("" where none is declared).
    """

    constants: Mapping[str, Any]
    signals: Mapping[str, ChannelSpec]
    steps: tuple[StepSpec, ...]
    order: tuple[tuple[str, Any], ...]
    units: Mapping[str, str]

    @property
    def empty(self) -> bool:
        return not (self.constants or self.signals or self.steps)

    def unit_of(self, spec: ChannelSpec) -> str:
        """The delivered unit of a channel: its own, or (a channel that is one signal and
        declares none) the signal's."""
        if spec.unit or spec.expr is not None or spec.column not in self.units:
            return spec.target_unit
        inherited = self.units[spec.column]
        if spec.derivative is not None:
            return f"{inherited}/s" if inherited else "1/s"
        return inherited

    def with_file_units(self, table: Table, names: Mapping[str, Any]) -> Pipeline:
        """The pipeline with the units ``table`` states for the columns its signals read
        (``ChannelSpec.with_file_unit``) in ``units``: a signal that declares no unit and is
        a file column with a stated unit carries that unit's delivered unit, and so do the
        channels made of it. ``names``: the constants and signals (as ``evaluate`` gives)."""
        units = dict(self.units)
        for what, key in self.order:
            if what != "signal":
                continue
            spec = self.signals[key].with_file_unit(
                table, f"signals.{key}", {k: v for k, v in names.items() if k != key}
            )
            units[key] = _signal_unit(key, spec, units)
        return dataclasses.replace(self, units=units)

    def evaluate(
        self,
        table: Table,
        keep: np.ndarray,
        time: np.ndarray,
        dt: float,
        segments: Sequence[slice],
    ) -> dict[str, Any]:
        """Every signal over all rows of ``table`` (NaN outside ``keep``) plus the scalar
        constants: the names channels may use. ``time``: the stored times of all rows (s,
        the expression variable t); ``dt``: the uniform interval (s); ``segments``: slices of
        the kept rows where smoothing and differentiation restart."""
        n = table.n_rows
        env: dict[str, Any] = {k: v for k, v in self.constants.items() if not isinstance(v, tuple)}

        def store(name: str, values: np.ndarray) -> None:
            full = np.full(n, np.nan)
            full[keep] = values
            env[name] = full

        def kept(name: str, where: str, expected: str | None) -> np.ndarray:
            if name in self.units:
                return env[name][keep]
            if name in env:  # a scalar constant
                return np.full(int(keep.sum()), float(env[name]))
            index = table.column_index(name, where)
            unit = table.units[index]
            if expected and unit:
                try:
                    matches = _units_equal(unit, expected)
                except InputError:
                    matches = True  # a label flightid cannot read: not checked
                if not matches:
                    raise PreprocessError(
                        f"{where}: expected {expected}, but column {name!r} is in {unit!r}; "
                        "declare a signal that converts it (unit = ...)"
                    )
            return table.data[keep, index]

        for what, key in self.order:
            if what == "signal":
                spec = self.signals[key]
                where = f"signals.{key}"
                values = spec.evaluate(
                    table, where, keep, time, {k: v for k, v in env.items() if k != key}
                )
                if spec.smooth is not None or spec.derivative is not None:
                    values = apply_steps(values, dt, segments, spec.smooth, spec.derivative, where)
                store(key, values)
                continue
            step = self.steps[key]
            kind = STEP_KINDS[step.kind]
            args = {
                role: kept(name, f"{step.where}.signals.{role}", kind.roles.get(role))
                for role, name in step.signals.items()
            }
            try:
                results = _run_step(step, args, lambda name, w: kept(name, w, "N"))
            except PreprocessError as exc:
                raise PreprocessError(f"{step.where}: {exc}") from None
            for role, values in results.items():
                bad = ~np.isfinite(values)
                if bad.any():
                    raise PreprocessError(
                        f"{step.where}: {int(bad.sum())} non-finite value(s) of "
                        f"{step.names[role]!r}, the first at kept row {int(np.argmax(bad)) + 1}"
                    )
                store(step.names[role], values)
        return env


def _run_step(step: StepSpec, args: Mapping[str, np.ndarray], thrust_of) -> dict:
    """role → values of one step on the kept rows."""
    s = step.settings
    if step.kind == "remove_bias":
        # x_c = x − b
        return {name: args[name] - bias for name, bias in s["biases"].items()}
    target = s.get("target", (0.0, 0.0, 0.0))
    rates = (args["p"], args["q"], args["r"])
    if step.kind == "transfer_air_data":
        V, alpha, beta = transfer_air_data(
            args["V"], args["alpha"], args["beta"], *rates, s["sensor"], target
        )
        return {"V": V, "alpha": alpha, "beta": beta}
    accelerations = (args["ax"], args["ay"], args["az"])
    rate_dots = (args["pdot"], args["qdot"], args["rdot"])
    if step.kind == "transfer_accelerations":
        ax, ay, az = transfer_accelerations(*accelerations, *rates, *rate_dots, s["sensor"], target)
        return {"ax": ax, "ay": ay, "az": az}
    geometry = _mass_geometry(s)
    engines = [
        Engine(thrust_of(name, f"{step.where}.engines[{k}].thrust"), position, incidence)
        for k, (name, position, incidence) in enumerate(s.get("engines", ()))
    ]
    return dict(
        aero_coefficients(
            *accelerations, *rates, *rate_dots, args["qbar"], args["alpha"], geometry, engines
        )
    )


def _parse_signals(signals: Any) -> dict[str, ChannelSpec]:
    """``[data.signals]`` → name → checked ``ChannelSpec``."""
    if signals is not None and not isinstance(signals, Mapping):
        raise PreprocessError(
            f"signals: expected a table of name = channel specification, got {describe(signals)}"
        )
    specs: dict[str, ChannelSpec] = {}
    for name, value in (signals or {}).items():
        if not isinstance(name, str) or not name.isidentifier() or name in ("t", "pi"):
            raise ChannelError(
                f"signals: names must be identifiers other than 't' and 'pi', got {name!r}"
            )
        specs[name] = ChannelSpec.from_value(value, f"signals.{name}")
    return specs


def _parse_steps(steps: Any, constants: Mapping[str, Any]) -> tuple[StepSpec, ...]:
    """``[[data.steps]]`` → the checked ``StepSpec``s."""
    if steps is not None and not isinstance(steps, list):
        raise PreprocessError(f"steps: expected an array of tables [[data.steps]], got {steps!r}")
    return tuple(_parse_step(raw, i, constants) for i, raw in enumerate(steps or ()))


def _makers(
    specs: Mapping[str, ChannelSpec], steps: Sequence[StepSpec], constants: Mapping[str, Any]
) -> dict[str, tuple[str, Any]]:
    """Who makes each name: ("signal", name) or ("step", index); each name made once and
    none a constant's."""
    maker: dict[str, tuple[str, Any]] = {name: ("signal", name) for name in specs}
    for step in steps:
        for role, name in step.names.items():
            if name in maker:
                raise PreprocessError(
                    f"{step.where}.names.{role}: {name!r} is already made by "
                    f"{_node_label(maker[name], steps)}; give it another name (names = {{...}})"
                )
            maker[name] = ("step", step.index)
    for name in maker:
        if name in constants:
            raise PreprocessError(
                f"constants.{name}: the name is also a signal; constants and signals need "
                "different names"
            )
    return maker


def _node_label(node: tuple[str, Any], steps: Sequence[StepSpec]) -> str:
    """'signals.<name>' or the step's 'steps[i] (kind)'."""
    return f"signals.{node[1]}" if node[0] == "signal" else steps[node[1]].where


def _needs(
    specs: Mapping[str, ChannelSpec],
    steps: Sequence[StepSpec],
    maker: Mapping[str, tuple[str, Any]],
    constants: Mapping[str, Any],
) -> dict[tuple[str, Any], set]:
    """What each node (signal, step) needs: the nodes that make the names it reads. A signal
    may not read a list constant."""
    needs: dict[tuple[str, Any], set] = {}
    for name, spec in specs.items():
        needs[("signal", name)] = {
            maker[n] for n in _channel_names(spec) if n in maker and n != name
        }
    for step in steps:
        needs[("step", step.index)] = {maker[n] for n in step.reads() if n in maker}
    for name, spec in specs.items():
        for used in _channel_names(spec):
            value = constants.get(used)
            if isinstance(value, tuple) and used not in maker:
                raise PreprocessError(
                    f"signals.{name}: the constant {used!r} is a list {list(value)}; only "
                    "single numbers can be used in expressions"
                )
    return needs


def _evaluation_order(
    needs: Mapping[tuple[str, Any], set], steps: Sequence[StepSpec]
) -> list[tuple[str, Any]]:
    """The nodes in dependency order (a cycle is a ``PreprocessError`` naming it)."""
    # Kahn's algorithm; among the ready nodes the first declared (signals, then steps)
    nodes = list(needs)
    order: list[tuple[str, Any]] = []
    done: set = set()
    while len(order) < len(nodes):
        ready = [n for n in nodes if n not in done and needs[n] <= done]
        if not ready:
            waiting = [n for n in nodes if n not in done]
            raise PreprocessError(
                "signals and steps depend on each other in a cycle: "
                + _cycle_words(waiting, needs, steps)
            )
        node = ready[0]
        order.append(node)
        done.add(node)
    return order


def _signal_unit(key: str, spec: ChannelSpec, units: Mapping[str, str]) -> str:
    """The unit signal ``key`` delivers: the file column of the same name's, else its own or
    (one signal, no unit declared) that signal's in ``units``."""
    if spec.column == key:  # the file's column of the same name
        return spec.target_unit
    return Pipeline({}, {}, (), (), units).unit_of(spec)


def _check_step_units(step: StepSpec, units: Mapping[str, str]) -> None:
    """The signals a step reads are in the units its roles expect (where both are declared);
    thrust signals in N."""
    kind = STEP_KINDS[step.kind]
    for role, name in step.signals.items():
        expected = kind.roles.get(role)
        got = units.get(name, "")
        if expected and got and not _units_equal(got, expected):
            raise PreprocessError(
                f"{step.where}.signals.{role}: expected {expected}, but the signal {name!r} "
                f"is in {got!r}"
            )
    for engine in step.settings.get("engines", ()):
        got = units.get(engine[0], "")
        if got and not _units_equal(got, "N"):
            raise PreprocessError(
                f"{step.where}.engines: the thrust signal {engine[0]!r} is in {got!r}, expected N"
            )


def _made_units(
    order: Sequence[tuple[str, Any]],
    specs: Mapping[str, ChannelSpec],
    steps: Sequence[StepSpec],
) -> dict[str, str]:
    """Every made signal's unit, checked against what the steps expect where declared."""
    units: dict[str, str] = {}
    for what, key in order:
        if what == "signal":
            units[key] = _signal_unit(key, specs[key], units)
            continue
        step = steps[key]
        _check_step_units(step, units)
        for role, name in step.names.items():
            if step.kind == "remove_bias":
                units[name] = units.get(step.signals[role], "")
            else:
                units[name] = STEP_KINDS[step.kind].outputs[role][1]
    return units


def parse_pipeline(
    constants: Mapping[str, Any] | None = None,
    signals: Mapping[str, Any] | None = None,
    steps: Sequence[Any] | None = None,
) -> Pipeline:
    """Check ``[data.constants]``, ``[data.signals]`` and ``[[data.steps]]`` without data and
    order them (see the module docstring). Errors: ``PreprocessError`` (settings, cycles,
    missing constants, units) and ``ChannelError`` (signal specifications)."""
    consts = parse_constants(constants)
    specs = _parse_signals(signals)
    parsed = _parse_steps(steps, consts)
    maker = _makers(specs, parsed, consts)
    order = _evaluation_order(_needs(specs, parsed, maker, consts), parsed)
    units = _made_units(order, specs, parsed)
    return Pipeline(consts, specs, parsed, tuple(order), units)


def _cycle_words(waiting: list, needs: Mapping, steps: Sequence[StepSpec]) -> str:
    """'signals.a → signals.b → signals.a' for one cycle among the waiting nodes."""

    path = [waiting[0]]
    while True:
        nxt = next(n for n in needs[path[-1]] if n in waiting)
        if nxt in path:
            cycle = path[path.index(nxt) :] + [nxt]
            return " → ".join(_node_label(n, steps) for n in cycle)
        path.append(nxt)
