"""``ChannelSpec``: one channel of ``FlightData`` declared as a column or an expression, with
scale, offset, unit conversion and the unit the file states (``flightid.data.loaders``)."""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flightid.data.expressions import (
    _evaluate,
    _lookup,
    expression_columns,
    parse_expression,
)
from flightid.data.preprocess import parse_derivative, parse_smooth
from flightid.data.table import (
    ChannelError,
    FileUnitError,
    Table,
)
from flightid.data.units import channel_conversion, parse_unit, same_unit
from flightid.errors import InputError, describe

_SPEC_KEYS = {
    "column",
    "expr",
    "scale",
    "offset",
    "unit",
    "to",
    "ignore_file_unit",
    "subtract",
    "smooth",
    "derivative",
}


# unit labels with which files say "no unit" (dimensionless counts, unknown): not a unit
_NO_UNIT_LABELS = {"", "-", "--", "none", "n/a", "unknown", "instance", "satellites"}


def stated_unit(label: str) -> str:
    """The unit a file's label states ("" where the label says there is none: ``-``,
    ``UNKNOWN``, ArduPilot's ``instance`` and ``satellites``)."""
    label = label.strip()
    return "" if label.lower() in _NO_UNIT_LABELS else label


def _linear_in_columns(tree: tuple, names: Mapping[str, Any]) -> bool:
    """True when an expression is a sum of column terms, each times or divided by numbers
    or scalar constants (``($29 - $28) / 2``, ``-q``, ``2 * p``): its result then has the
    unit of its columns. Functions, ``t``, signals and products of columns are not."""
    kind = tree[0]
    if kind == "col":
        return not (isinstance(tree[1], str) and tree[1] in names)
    if kind == "neg":
        return _linear_in_columns(tree[1], names)
    if kind in ("+", "-"):
        return _linear_in_columns(tree[1], names) and _linear_in_columns(tree[2], names)
    if kind == "*":
        left, right = tree[1], tree[2]
        return (_is_number(left, names) and _linear_in_columns(right, names)) or (
            _is_number(right, names) and _linear_in_columns(left, names)
        )
    if kind == "/":
        return _linear_in_columns(tree[1], names) and _is_number(tree[2], names)
    return False


def _is_number(tree: tuple, names: Mapping[str, Any]) -> bool:
    """True for a number, a scalar constant or arithmetic over them."""
    kind = tree[0]
    if kind == "num":
        return True
    if kind == "col":
        return isinstance(tree[1], str) and tree[1] in names and np.ndim(names[tree[1]]) == 0
    if kind == "neg":
        return _is_number(tree[1], names)
    if kind in ("+", "-", "*", "/"):
        return _is_number(tree[1], names) and _is_number(tree[2], names)
    return False


@dataclass(frozen=True)
class ChannelSpec:
    """How to compute one channel from a table.

    Attributes:
        column: 1-based column number or column name (or use ``expr``).
        expr: arithmetic expression over ``$N`` / column names, with functions, ``pi`` and
            the time variable ``t`` (see the module docstring).
        scale, offset: value = source · scale + offset (in the source unit), then
            converted by the unit rule.
        unit: the source unit (e.g. ``"deg"``). Without ``to`` the values are delivered in
            SI with angles in rad (``flightid.data.units.channel_conversion``); an unknown
            unit is refused.
        to: the delivered unit (e.g. ``"deg"`` to keep degrees, ``"g"`` to keep g); the
            channel's unit in reports. ``to`` alone is allowed where the file states the
            column's unit.
        ignore_file_unit: use the case's ``unit`` (or none) whatever unit the file states
            for the column(s); by default a unit the file states (CSV header ``q [deg/s]``,
            MATLAB ``varlab``, DataFlash FMTU, Parquet/HDF5 metadata) is the source unit
            when the case declares none, and a declared unit that contradicts it is a
            ``FileUnitError`` (``with_file_unit``).
        subtract: ``"first"`` or ``"mean"``: remove that reference value (perturbations).
        smooth: ``"smoothMulTS"``, ``{"savgol": [window, order]}`` or
            ``{"butter": [order, cutoff_hz]}`` (``flightid.data.preprocess``), stored as a
            tuple; applied per maneuver and segment after ``subtract``.
        derivative: ``"ndiff8"`` or ``{"savgol": [window, order]}``: deliver the rate of
            the (smoothed) channel, unit ``…/s``; applied after ``smooth``.

    Order: source → scale/offset → unit conversion → subtract → smooth → derivative.
    """

    column: int | str | None = None
    expr: str | None = None
    scale: float = 1.0
    offset: float = 0.0
    unit: str = ""
    to: str = ""
    ignore_file_unit: bool = False
    subtract: str | None = None
    smooth: tuple | None = None
    derivative: tuple | None = None

    @classmethod
    def from_value(cls, value: Any, where: str) -> ChannelSpec:
        """From a column number/name, an expression string containing an operator, or a
        mapping with the keys of this class."""
        if isinstance(value, ChannelSpec):
            return value
        if isinstance(value, bool):
            raise ChannelError(f"{where}: expected a column or a mapping, got {value!r}")
        if isinstance(value, int):
            return cls(column=value)
        if isinstance(value, str):
            if re.search(r"[-+*/()$]", value):
                return cls(expr=value)
            return cls(column=value)
        if not isinstance(value, Mapping):
            raise ChannelError(
                f"{where}: expected a column number, a column name, an expression or a table "
                f"with keys {sorted(_SPEC_KEYS)}, got {describe(value)}"
            )
        unknown = sorted(set(value) - _SPEC_KEYS)
        if unknown:
            raise ChannelError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(_SPEC_KEYS)}")
        if ("column" in value) == ("expr" in value):
            raise ChannelError(f"{where}: give exactly one of 'column' and 'expr'")
        for key in ("scale", "offset"):
            if key in value and (
                isinstance(value[key], bool) or not isinstance(value[key], (int, float))
            ):
                raise ChannelError(f"{where}.{key}: expected a number, got {describe(value[key])}")
        for key in ("unit", "to", "expr"):
            if key in value and not isinstance(value[key], str):
                raise ChannelError(f"{where}.{key}: expected a string, got {describe(value[key])}")
        if value.get("subtract") not in (None, "first", "mean"):
            raise ChannelError(
                f"{where}.subtract: expected 'first' or 'mean', got {value['subtract']!r}"
            )
        if not isinstance(value.get("ignore_file_unit", False), bool):
            raise ChannelError(
                f"{where}.ignore_file_unit: expected true or false, got "
                f"{describe(value['ignore_file_unit'])}"
            )
        fields = {k: value[k] for k in value}
        fields["smooth"] = parse_smooth(value.get("smooth"), f"{where}.smooth")
        fields["derivative"] = parse_derivative(value.get("derivative"), f"{where}.derivative")
        spec = cls(**fields)
        if spec.expr is not None:
            parse_expression(spec.expr)  # fail early
        if spec.unit:
            spec.conversion(where)  # unknown units and dimension mismatches fail early
        elif spec.to:
            try:  # the source unit may come from the file; ``to`` must be a unit
                parse_unit(spec.to)
            except InputError as exc:
                raise ChannelError(f"{where}.to: {exc}") from None
        return spec

    def conversion(self, where: str = "channel") -> tuple[float, str]:
        """(factor, delivered unit) by the channel rule of ``channel_conversion``."""
        if self.to and not self.unit:
            raise ChannelError(
                f"{where}: to = {self.to!r} needs the unit the values are recorded in; "
                "neither the channel (unit = ...) nor the file states one"
            )
        try:
            return channel_conversion(self.unit, self.to)
        except InputError as exc:
            raise ChannelError(f"{where}: {exc}") from None

    def with_file_unit(
        self, table: Table, where: str, names: Mapping[str, Any] | None = None
    ) -> ChannelSpec:
        """This channel with the unit its file states for it (``Table.units``).

        A column's stated unit, or for an expression that is a sum of columns times numbers
        (``_linear_in_columns``) the one unit all its columns state, is the source unit when
        the channel declares none; a declared unit must mean the same unit, else
        ``FileUnitError`` naming both. An expression that reads columns with stated units
        and is not such a sum needs a declared unit (of its result). ``ignore_file_unit``
        skips all of this. ``names``: signals and constants (not columns)."""
        if self.ignore_file_unit:
            return self
        names = names or {}
        tree = parse_expression(self.expr) if self.expr is not None else ("col", self.column)
        stated: dict[str, str] = {}
        unstated = False
        for ref in expression_columns(tree):
            if isinstance(ref, str) and ref in names:
                unstated = True
                continue
            try:
                index = table.column_index(ref, where)
            except ChannelError:
                return self  # evaluate names the missing column
            label = stated_unit(table.units[index])
            name = table.names[index] or f"${index + 1}"
            if label:
                stated[name] = label
            else:
                unstated = True
        if not stated:
            return self
        labels = set(stated.values())
        if len(labels) == 1 and not unstated and _linear_in_columns(tree, names):
            return self._apply_stated(labels.pop(), stated, table, where)
        if self.unit:
            return self  # the declared unit of a result the file's units do not determine
        raise FileUnitError(
            f"{where}: the expression {self.expr!r} reads columns whose file states their "
            f"units ({_unit_list(stated)}); declare the unit of its result (unit = ...), or "
            "ignore_file_unit = true to use the recorded numbers as they are"
        )

    def _apply_stated(
        self, label: str, stated: Mapping[str, str], table: Table, where: str
    ) -> ChannelSpec:
        """The spec with the file's unit ``label`` as its source unit (see
        ``with_file_unit``)."""
        source = table.source or "the file"
        try:
            parse_unit(label)
        except InputError:
            if self.unit:
                return self  # a label flightid cannot read: the declared unit applies
            raise FileUnitError(
                f"{where}: {source} states the unit {label!r} for {_unit_list(stated)}, which "
                "flightid cannot read; declare the unit the values are in (unit = ...), or "
                "use them as recorded (ignore_file_unit = true)"
            ) from None
        if not self.unit:
            return dataclasses.replace(self, unit=label)
        if same_unit(self.unit, label):
            return self
        raise FileUnitError(
            f"{where}: the channel declares unit = {self.unit!r}, but {source} states "
            f"{label!r} for {_unit_list(stated)}; remove 'unit' to use the file's, correct it, "
            "or set ignore_file_unit = true if the file's label is wrong"
        )

    @property
    def target_unit(self) -> str:
        """The unit the values are delivered in ("" where no unit is declared; with a
        ``derivative``, that unit per s)."""
        unit = self.to or self.conversion()[1]
        if self.derivative is not None:
            return f"{unit}/s" if unit else "1/s"
        return unit

    def evaluate(
        self,
        table: Table,
        where: str,
        keep: np.ndarray | None = None,
        time: np.ndarray | None = None,
        names: Mapping[str, Any] | None = None,
    ) -> np.ndarray:
        """The channel's values in the target unit, on the rows ``keep`` (default all).
        ``time``: the values of the expression variable ``t`` on all rows (s); None inside the
        time channel itself, where ``t`` is the column named t. ``names``: signals (arrays
        over all rows) and constants (numbers) that names refer to before columns
        (``flightid.data.pipeline``). The file's units apply as ``with_file_unit`` says."""
        spec = self.with_file_unit(table, where, names)
        if spec is not self:
            return spec.evaluate(table, where, keep, time, names)
        if self.expr is not None:
            try:
                tree = parse_expression(self.expr)
            except ChannelError as exc:
                raise ChannelError(f"{where}: {exc}") from None
            problems: list = []
            values = _evaluate(tree, table, where, time, problems, names)
            values = np.broadcast_to(np.asarray(values, dtype=float), (table.n_rows,)).copy()
            rows = np.ones(table.n_rows, dtype=bool) if keep is None else keep
            for words, refused, argument in problems:
                refused = np.broadcast_to(refused, (table.n_rows,)) & rows
                if refused.any():
                    k = int(np.argmax(refused))
                    bad = np.broadcast_to(np.asarray(argument, dtype=float), (table.n_rows,))[k]
                    raise ChannelError(
                        f"{where}: {words}, got {bad:.6g} at row {k + 1} of "
                        f"{table.source or 'the table'} ({int(refused.sum())} row(s) in all)"
                    )
        else:
            values = np.broadcast_to(
                np.asarray(_lookup(self.column, table, where, names), dtype=float),
                (table.n_rows,),
            ).copy()
        factor, _ = self.conversion(where)
        # value = (source · scale + offset) · factor   (scale, offset in the source unit)
        values = (values * self.scale + self.offset) * factor
        if keep is not None:
            values = values[keep]
        if self.subtract == "first":
            values = values - values[0]
        elif self.subtract == "mean":
            values = values - values.mean()
        bad = ~np.isfinite(values)
        if bad.any():
            raise ChannelError(
                f"{where}: {int(bad.sum())} non-finite value(s) in {table.source or 'the table'}, "
                f"the first at row {int(np.argmax(bad)) + 1}"
            )
        return values


def _unit_list(stated: Mapping[str, str]) -> str:
    """``column 'q' [deg/s]`` or ``columns 'p' [deg/s], 'q' [rad/s]`` for messages."""
    words = ", ".join(f"{name!r} [{unit}]" for name, unit in stated.items())
    return f"column{'s' if len(stated) > 1 else ''} {words}"


def _specs(mapping: Mapping[str, Any] | None, where: str) -> dict[str, ChannelSpec]:
    if mapping is None:
        return {}
    if not isinstance(mapping, Mapping):
        raise ChannelError(
            f"{where}: expected a mapping of channel name to column/spec, got {describe(mapping)}"
        )
    specs = {}
    for name, value in mapping.items():
        if not isinstance(name, str) or not name.isidentifier():
            raise ChannelError(f"{where}: channel names must be identifiers, got {name!r}")
        specs[name] = ChannelSpec.from_value(value, f"{where}.{name}")
    return specs
