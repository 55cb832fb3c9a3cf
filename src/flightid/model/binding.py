"""A model bound to the maneuvers it runs on: the checks and arrays every simulation needs.

Binding a ``StateSpaceModel`` to data resolves, maneuver by maneuver,

* the time vector t (s) and the input matrix u (N × n_u, the model's inputs in order, each
  read from the data's inputs or outputs);
* the initial-state and function-parameter maps of that maneuver;
* for the unstable-airplane options (``flightid.model.unstable``): the stabilizing gain S
  (n_s × n_o) with the measured outputs z it feeds back, and the multiple-shooting intervals
  (first sample, parameter index per state).

and checks that the data fit the model (one ``x0`` and one set of per-maneuver parameters per
maneuver, every input channel present, S of the right shape, shooting intervals inside their
maneuvers). The simulator integrates on these arrays; ``check_model`` evaluates f and h on
them without integrating, so both see the same maneuvers and refuse the same data.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from flightid.data.flightdata import FlightData
from flightid.errors import InputError, InputTypeError, describe
from flightid.model.statespace import StateSpaceModel

__all__ = [
    "INTEGRATION_METHODS",
    "BoundFeedback",
    "BoundManeuvers",
    "as_data_list",
    "bind_feedback",
    "bind_maneuvers",
    "check_method",
    "input_matrix",
    "output_matrix",
]

# the fixed-step integration methods of flightid.simulation (names as case files write them)
INTEGRATION_METHODS = ("euler", "rk4")


def check_method(method: object) -> str:
    """``method`` if it names an integration method, else an ``InputError``."""
    if method not in INTEGRATION_METHODS:
        raise InputError(f"method: expected one of {sorted(INTEGRATION_METHODS)}, got {method!r}")
    return method


def as_data_list(data: FlightData | Sequence[FlightData]) -> list[FlightData]:
    """One ``FlightData`` or a non-empty list of them, as a list (maneuvers)."""
    if isinstance(data, FlightData):
        return [data]
    if isinstance(data, (str, bytes, Mapping)) or not isinstance(data, Iterable):
        raise InputTypeError(
            f"data: expected a FlightData or a non-empty list of FlightData, got {describe(data)}"
        )
    items = list(data)
    if not items or not all(isinstance(d, FlightData) for d in items):
        raise InputError("data: expected a FlightData or a non-empty list of FlightData")
    return items


@dataclass(frozen=True)
class BoundManeuvers:
    """The maneuvers of a model, with the arrays the simulation kernels read.

    Attributes:
        maneuvers: the data, one ``FlightData`` per maneuver.
        times: per maneuver, t (s), contiguous float64 (N,).
        inputs: per maneuver, u (N × n_u), the model's inputs in order, contiguous float64.
        x0_maps: per maneuver, ``model.initial_state_maps`` of that maneuver.
        theta_maps: per maneuver, θ_f = θ[map] (``model.function_theta_map``), or None where
            f and h receive θ itself.
    """

    maneuvers: list[FlightData]
    times: list[np.ndarray]
    inputs: list[np.ndarray]
    x0_maps: list
    theta_maps: list


def bind_maneuvers(
    model: StateSpaceModel, data: FlightData | Sequence[FlightData]
) -> BoundManeuvers:
    """Check that ``data`` fit ``model`` and read the time and input arrays of each maneuver.

    Raises:
        InputTypeError / InputError: data that is not one or a list of ``FlightData``; initial
            states or per-maneuver parameters for another number of maneuvers; a model input
            that is no channel of a maneuver.
    """
    maneuvers = as_data_list(data)
    if model.per_maneuver_x0 and len(model.x0) != len(maneuvers):
        raise InputError(
            f"data: the model gives initial states for {len(model.x0)} maneuvers, "
            f"but {len(maneuvers)} were given"
        )
    n_per = model.n_parameter_maneuvers
    if n_per and n_per != len(maneuvers):
        raise InputError(
            f"data: the model gives per-maneuver parameters "
            f"{list(model.maneuver_parameters)} for {n_per} maneuvers, but "
            f"{len(maneuvers)} were given"
        )
    times, inputs = [], []
    for i, maneuver in enumerate(maneuvers):
        missing = [
            n
            for n in model.inputs
            if n not in maneuver.input_names and n not in maneuver.output_names
        ]
        if missing:
            raise InputError(
                f"data[{i}] ({maneuver.name or 'unnamed'}): the model's inputs {missing} are "
                f"not channels of the data (inputs {list(maneuver.input_names)}, outputs "
                f"{list(maneuver.output_names)})"
            )
        times.append(np.ascontiguousarray(maneuver.time, dtype=float))
        inputs.append(input_matrix(model, maneuver))
    x0_maps = [
        model.initial_state_maps(i if model.per_maneuver_x0 else 0) for i in range(len(maneuvers))
    ]
    # θ_f = θ[map]: the θ that f and h receive in each maneuver (None: θ itself)
    theta_maps = [
        model.function_theta_map(i) if model.substitutes_parameters else None
        for i in range(len(maneuvers))
    ]
    return BoundManeuvers(maneuvers, times, inputs, x0_maps, theta_maps)


@dataclass(frozen=True)
class BoundFeedback:
    """The unstable-airplane options of a model, checked against its maneuvers.

    Attributes:
        feedback: True when the model has a stabilizing gain or shooting intervals.
        gain: S (n_s × n_o), or a 0 × 0 array without a gain.
        measured: per maneuver, the measured outputs z (N × n_o) the gain feeds back
            (N × 0 without a gain).
        intervals: per maneuver, [(first sample, parameter index per state)] of the
            shooting intervals 2, 3, ... (empty without shooting).
        n_defects: continuity defects per simulation, n_s × (number of interval boundaries).
    """

    feedback: bool
    gain: np.ndarray
    measured: list[np.ndarray]
    intervals: list[list[tuple[int, np.ndarray]]]
    n_defects: int


def _measured_outputs(model: StateSpaceModel, maneuvers: list[FlightData]) -> list[np.ndarray]:
    """Per maneuver, the measured outputs z (N × n_o) a stabilizing gain feeds back."""
    measured = []
    for i, maneuver in enumerate(maneuvers):
        missing = [n for n in model.outputs if n not in maneuver.output_names]
        if missing:
            raise InputError(
                f"data[{i}] ({maneuver.name or 'unnamed'}): the stabilized simulation "
                f"needs the measured outputs {missing}; outputs "
                f"{list(maneuver.output_names)}"
            )
        measured.append(output_matrix(model, maneuver))
    return measured


def input_matrix(model: StateSpaceModel, maneuver: FlightData) -> np.ndarray:
    """The model's inputs u (N × n_u, contiguous, in the model's input order) from the
    maneuver's channels (a model input may be a measured output); N × 0 without inputs."""
    u = (
        np.column_stack([maneuver.channel(n) for n in model.inputs])
        if model.inputs
        else np.zeros((maneuver.n_samples, 0))
    )
    return np.ascontiguousarray(u, dtype=float)


def output_matrix(model: StateSpaceModel, maneuver: FlightData) -> np.ndarray:
    """The measured outputs z (N × n_o, contiguous, in the model's output order)."""
    return np.ascontiguousarray(
        np.column_stack([maneuver.output(n) for n in model.outputs]), dtype=float
    )


def _shooting_intervals(
    model: StateSpaceModel, shooting: Sequence, times: list[np.ndarray]
) -> list[list[tuple[int, np.ndarray]]]:
    """Per maneuver, [(first sample, parameter index per state)] of intervals 2, 3, ..."""
    if len(shooting) != len(times):
        raise InputError(
            f"shooting: intervals for {len(shooting)} maneuvers, but {len(times)} were given"
        )
    n_s = len(model.states)
    names = model.parameters.names
    bound: list[list[tuple[int, np.ndarray]]] = [[] for _ in times]
    for i, (intervals, t) in enumerate(zip(shooting, times, strict=True)):
        previous = 0
        for start, states in intervals:
            if not previous < start < t.shape[0] - 1 or len(states) != n_s:
                raise InputError(
                    f"shooting[{i}]: an interval starts at sample {start}; expected "
                    f"increasing samples inside the maneuver (1 … {t.shape[0] - 2}) "
                    f"with one parameter per state"
                )
            previous = start
            index = np.array([names.index(n) for n in states], dtype=np.int64)
            bound[i].append((int(start), index))
    return bound


def bind_feedback(model: StateSpaceModel, maneuvers: BoundManeuvers) -> BoundFeedback:
    """The stabilizing gain, measured outputs and shooting intervals of the model
    (``flightid.model.unstable``), checked against the maneuvers.

    Raises:
        InputError: S of another shape than n_s × n_o, S with output delays, a maneuver
            without the measured outputs S needs, shooting intervals for another number of
            maneuvers or outside their maneuver.
    """
    gain = getattr(model, "stabilizing_gain", None)
    shooting = getattr(model, "shooting", None)
    n_s, n_o = len(model.states), len(model.outputs)
    bound_gain = np.zeros((0, 0))
    measured = [np.zeros((t.shape[0], 0)) for t in maneuvers.times]
    if gain is not None:
        gain = np.ascontiguousarray(gain, dtype=float)
        if gain.shape != (n_s, n_o):
            raise InputError(
                f"stabilizing_gain: expected a {n_s} × {n_o} matrix (states "
                f"{list(model.states)} × outputs {list(model.outputs)}), got {gain.shape}"
            )
        if model.output_delay_maps():
            raise InputError(
                "stabilizing_gain: not available with output delays (the correction "
                "uses the undelayed output of h)"
            )
        bound_gain = gain
        measured = _measured_outputs(model, maneuvers.maneuvers)
    intervals: list[list[tuple[int, np.ndarray]]] = [[] for _ in maneuvers.times]
    if shooting is not None:
        intervals = _shooting_intervals(model, shooting, maneuvers.times)
    return BoundFeedback(
        feedback=gain is not None or shooting is not None,
        gain=bound_gain,
        measured=measured,
        intervals=intervals,
        n_defects=n_s * sum(len(v) for v in intervals),
    )
