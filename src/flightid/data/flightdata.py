"""``FlightData``: one maneuver's time, input and output channels, validated at the door.

Checks made on construction (each failure names the argument):

* time is one-dimensional, finite, strictly increasing and uniform (relative spread of the
  intervals below ``1e-6`` by default), with at least two samples;
* every channel is finite and has the same length as time;
* channel names are unique identifiers;
* every value is a real number: complex values are refused (their imaginary part would be
  lost without a word), as are strings and other objects.

Arrays are copied and made read-only, so nothing the user passed is modified later.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from flightid.errors import InputError, InputTypeError, describe

__all__ = ["FlightData"]


def _real_array(values: object, argument: str) -> np.ndarray:
    """``values`` as a new float array; complex values, strings and other objects are an
    ``InputTypeError`` naming ``argument`` (a cast to float would drop an imaginary part)."""
    try:
        array = np.asarray(values)
    except (TypeError, ValueError):
        array = None
    if array is not None and np.iscomplexobj(array):
        raise InputTypeError(
            f"{argument}: expected real numbers, got complex values ({describe(array)}, dtype "
            f"{array.dtype}); pass the part you mean (np.real(...), np.abs(...))"
        )
    try:
        return np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise InputTypeError(
            f"{argument}: expected a numeric series, got {describe(values)}"
        ) from None


def _as_channel_matrix(
    values: Mapping[str, np.ndarray] | np.ndarray | None,
    names: Sequence[str] | None,
    n_samples: int,
    argument: str,
) -> tuple[tuple[str, ...], np.ndarray]:
    """Turn a mapping or an (N, k) matrix with names into (names, read-only matrix)."""
    if values is None:
        return (), np.zeros((n_samples, 0))
    if isinstance(values, Mapping):
        if names is not None:
            raise InputError(f"{argument}: pass names only with a matrix, not with a mapping")
        names = list(values)
        columns = []
        for name in names:
            column = _real_array(values[name], f"{argument}[{name!r}]")
            if column.ndim != 1:
                raise InputError(
                    f"{argument}[{name!r}]: expected a one-dimensional series, "
                    f"got {describe(column)}"
                )
            if column.shape[0] != n_samples:
                raise InputError(
                    f"{argument}[{name!r}]: expected {n_samples} samples (the length of time), "
                    f"got {column.shape[0]}"
                )
            columns.append(column)
        matrix = np.column_stack(columns) if columns else np.zeros((n_samples, 0))
    else:
        if isinstance(values, (str, bytes)):
            raise InputTypeError(
                f"{argument}: expected a mapping of name to series or a numeric matrix, "
                f"got {describe(values)}"
            )
        matrix = _real_array(values, argument)
        if matrix.ndim == 1:
            matrix = matrix[:, None]
        if matrix.ndim != 2:
            raise InputError(
                f"{argument}: expected a 2-D matrix (samples × channels), got {describe(matrix)}"
            )
        if matrix.shape[0] != n_samples:
            raise InputError(
                f"{argument}: expected {n_samples} rows (the length of time), got {matrix.shape[0]}"
            )
        if names is None:
            raise InputError(f"{argument}: a matrix needs its channel names (argument names)")
        names = list(names)
        if len(names) != matrix.shape[1]:
            raise InputError(
                f"{argument}: {matrix.shape[1]} columns but {len(names)} names {names}"
            )
    for name in names:
        if not isinstance(name, str) or not name.isidentifier():
            raise InputError(f"{argument}: channel names must be identifiers, got {describe(name)}")
    if len(set(names)) != len(names):
        raise InputError(f"{argument}: channel names must be unique, got {names}")
    bad = ~np.isfinite(matrix)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise InputError(
            f"{argument}[{names[col]!r}]: values must be finite; found "
            f"{int(bad[:, col].sum())} non-finite value(s), the first at sample {row}"
        )
    matrix = np.ascontiguousarray(matrix)
    matrix.flags.writeable = False
    return tuple(names), matrix


@dataclass(frozen=True, eq=False)
class FlightData:
    """Time histories of one maneuver.

    Args:
        time: sample times, s; strictly increasing, uniform.
        inputs: measured inputs (controls and measured variables used as inputs), as a
            mapping ``{name: series}`` or an (N, n_u) matrix with ``input_names``.
        outputs: measured outputs, as a mapping or an (N, n_o) matrix with ``output_names``.
        units: optional ``{channel: unit}`` for reports.
        name: label of the maneuver.
        uniform_rtol: accepted relative spread of the sampling intervals.
        notes: what was done to the stored time base to make it uniform (re-gridding,
            joining recordings, resampling), one line each, for reports and results.
    """

    time: np.ndarray
    inputs: np.ndarray
    outputs: np.ndarray
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    units: Mapping[str, str] = field(default_factory=dict)
    name: str = ""
    notes: tuple[str, ...] = ()

    def __init__(
        self,
        time: np.ndarray,
        inputs: Mapping[str, np.ndarray] | np.ndarray | None = None,
        outputs: Mapping[str, np.ndarray] | np.ndarray | None = None,
        *,
        input_names: Sequence[str] | None = None,
        output_names: Sequence[str] | None = None,
        units: Mapping[str, str] | None = None,
        name: str = "",
        uniform_rtol: float = 1e-6,
        notes: Sequence[str] = (),
    ) -> None:
        t = _real_array(time, "time")
        if not isinstance(name, str):
            raise InputTypeError(
                f"name: expected a string (the maneuver's label), got {describe(name)}"
            )
        if units is not None and (
            not isinstance(units, Mapping)
            or not all(
                isinstance(k, str) and (v is None or isinstance(v, str)) for k, v in units.items()
            )
        ):
            raise InputTypeError(
                f"units: expected a mapping {{channel name: unit string}}, got {describe(units)}"
            )
        if (
            isinstance(uniform_rtol, bool)
            or not isinstance(uniform_rtol, (int, float))
            or not (np.isfinite(uniform_rtol) and uniform_rtol >= 0)
        ):
            raise InputError(
                f"uniform_rtol: expected a relative spread ≥ 0 (e.g. 1e-6), got "
                f"{describe(uniform_rtol)}"
            )
        if t.ndim != 1 or t.shape[0] < 2:
            raise InputError(
                f"time: expected a 1-D series of at least 2 samples, got {describe(t)}"
            )
        if not np.all(np.isfinite(t)):
            raise InputError(
                f"time: values must be finite; found {int((~np.isfinite(t)).sum())} "
                "non-finite value(s)"
            )
        dt = np.diff(t)
        if np.any(dt <= 0):
            k = int(np.argmax(dt <= 0))
            raise InputError(
                f"time: must be strictly increasing; t[{k}] = {t[k]} is followed by "
                f"t[{k + 1}] = {t[k + 1]}"
            )
        spread = (dt.max() - dt.min()) / dt.mean()
        if spread > uniform_rtol:
            raise InputError(
                f"time: sampling must be uniform (fixed-step integration at the data interval); "
                f"intervals range from {dt.min():.6g} to {dt.max():.6g} s"
            )
        t.flags.writeable = False
        n = t.shape[0]
        in_names, u = _as_channel_matrix(inputs, input_names, n, "inputs")
        out_names, z = _as_channel_matrix(outputs, output_names, n, "outputs")
        clash = sorted(set(in_names) & set(out_names))
        if clash:
            raise InputError(f"inputs and outputs: a channel cannot be both, got {clash}")
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "inputs", u)
        object.__setattr__(self, "outputs", z)
        object.__setattr__(self, "input_names", in_names)
        object.__setattr__(self, "output_names", out_names)
        object.__setattr__(self, "units", dict(units or {}))
        object.__setattr__(self, "name", str(name))
        try:
            lines = tuple(notes)
        except TypeError:
            lines = None
        if isinstance(notes, str) or lines is None or not all(isinstance(n, str) for n in lines):
            raise InputTypeError(f"notes: expected a sequence of strings, got {describe(notes)}")
        object.__setattr__(self, "notes", lines)

    # ------------------------------------------------------------------ properties
    @property
    def n_samples(self) -> int:
        return int(self.time.shape[0])

    @property
    def dt(self) -> float:
        """Sampling interval, s."""
        return float((self.time[-1] - self.time[0]) / (self.n_samples - 1))

    def input(self, name: str) -> np.ndarray:
        """The input channel ``name``."""
        return self.inputs[:, self._position(name, self.input_names, "input")]

    def output(self, name: str) -> np.ndarray:
        """The output channel ``name``."""
        return self.outputs[:, self._position(name, self.output_names, "output")]

    def channel(self, name: str) -> np.ndarray:
        """Any channel, input or output."""
        if name in self.input_names:
            return self.input(name)
        if name in self.output_names:
            return self.output(name)
        raise KeyError(
            f"no channel named {name!r}; inputs: {list(self.input_names)}, "
            f"outputs: {list(self.output_names)}"
        )

    @staticmethod
    def _position(name: str, names: tuple[str, ...], kind: str) -> int:
        try:
            return names.index(name)
        except ValueError:
            raise KeyError(f"no {kind} channel named {name!r}; {kind}s: {list(names)}") from None

    # ------------------------------------------------------------------ derived copies
    def select(
        self, inputs: Sequence[str] | None = None, outputs: Sequence[str] | None = None
    ) -> FlightData:
        """Copy keeping (and ordering) the named input and output channels."""
        inputs = list(self.input_names if inputs is None else inputs)
        outputs = list(self.output_names if outputs is None else outputs)
        return FlightData(
            self.time,
            {n: self.channel(n) for n in inputs},
            {n: self.channel(n) for n in outputs},
            units=self.units,
            name=self.name,
            notes=self.notes,
        )

    def slice_time(self, start: float | None = None, stop: float | None = None) -> FlightData:
        """Copy restricted to start ≤ t ≤ stop (s)."""
        keep = np.ones(self.n_samples, dtype=bool)
        if start is not None:
            keep &= self.time >= start - 1e-9
        if stop is not None:
            keep &= self.time <= stop + 1e-9
        if keep.sum() < 2:
            raise InputError(
                f"start/stop: the interval [{start}, {stop}] keeps fewer than 2 samples"
            )
        return FlightData(
            self.time[keep],
            self.inputs[keep],
            self.outputs[keep],
            input_names=self.input_names,
            output_names=self.output_names,
            units=self.units,
            name=self.name,
            notes=self.notes,
        )

    def with_outputs(self, outputs: np.ndarray) -> FlightData:
        """Copy with the output matrix replaced (same names); used to add simulated noise."""
        return FlightData(
            self.time,
            self.inputs,
            outputs,
            input_names=self.input_names,
            output_names=self.output_names,
            units=self.units,
            name=self.name,
            notes=self.notes,
        )

    def __repr__(self) -> str:
        return (
            f"FlightData({self.name or 'unnamed'}: {self.n_samples} samples at dt={self.dt:g} s, "
            f"inputs={list(self.input_names)}, outputs={list(self.output_names)})"
        )
