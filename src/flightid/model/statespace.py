"""State-space models written by the user in plain Python.

    dx/dt = f(t, x, u, θ),   x(t0) = x0          [RP-1153 2.1–2.2]
    y     = h(t, x, u, θ)                        [2.3]

``f`` and ``h`` take the time (s), the state vector, the input vector (in the order of
``inputs``) and the *full* parameter vector θ (in the order of ``parameters``, free and fixed)
and return 1-D float arrays of length ``len(states)`` and ``len(outputs)``. Functions that
numba can compile are run compiled; anything else still runs, in pure Python.

Models without states (output error on algebraic outputs, nonlinear regression): give
``states=()`` and ``f=None``; the outputs are then y_k = h(t_k, [], u_k, θ) at every sample
(``x`` is an empty array) and the simulator evaluates h alone, without integrating.

Initial states: each entry of ``x0`` is a number (fixed) or the name of a parameter (so the
initial state can be estimated). With several maneuvers, ``x0`` may be a list with one such
specification per maneuver.

Output time delays: ``output_delays={"r": "tau_r"}`` delays the simulated output ``r`` by the
parameter ``tau_r`` (s), which can then be fixed or estimated like any parameter; the rule
between samples is ``delay_convention`` ("fractional" or "two_sample", see
``flightid.simulate.simulator.apply_output_delays`` and docs/method.md, "Time delays").
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from flightid.errors import InputError, InputTypeError, describe
from flightid.model.parameters import Parameters

__all__ = ["StateSpaceModel", "InitialState", "DELAY_CONVENTIONS"]

InitialState = Sequence[float | str]
# how a delayed output is formed between samples (flightid.simulate.simulator):
# "fractional": s(t_k − τ), linear between the bracketing samples, any τ;
# "two_sample": the reference's rule (τ/dt)·s_{k−1} + (1 − τ/dt)·s_k
DELAY_CONVENTIONS = ("fractional", "two_sample")


def _names(values: Sequence[str], argument: str) -> tuple[str, ...]:
    if isinstance(values, str):
        raise InputTypeError(f"{argument}: expected a list of names, got the string {values!r}")
    names = tuple(values)
    for name in names:
        if not isinstance(name, str) or not name.isidentifier():
            raise InputError(f"{argument}: names must be identifiers, got {describe(name)}")
    if len(set(names)) != len(names):
        raise InputError(f"{argument}: names must be unique, got {list(names)}")
    return names


@dataclass(frozen=True, eq=False)
class StateSpaceModel:
    """A nonlinear state-space model with named states, inputs, outputs and parameters.

    Args:
        states: state names.
        inputs: input channel names, looked up by name in the ``FlightData``.
        outputs: output channel names, looked up by name in the ``FlightData``.
        f: state derivative ``f(t, x, u, theta) -> dx/dt``; ``None`` for a model without
            states (``states=()``), where it becomes ``no_state_derivative``.
        h: output map ``h(t, x, u, theta) -> y``.
        parameters: ``Parameters`` (or anything ``Parameters`` accepts).
        x0: initial state: numbers and/or parameter names (one list, or one per maneuver).
        name: label for reports.
        output_delays: ``{output name: parameter name}``: the simulated output is delayed by
            that parameter's value (s); default none.
        delay_convention: ``"fractional"`` (default) or ``"two_sample"`` (the reference's
            rule); see ``flightid.simulate.simulator.apply_output_delays``.
    """

    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    f: Callable | None
    h: Callable
    parameters: Parameters
    x0: tuple = ()
    name: str = "model"
    output_delays: dict[str, str] | None = None  # a dict ({} for none) after __post_init__
    delay_convention: str = "fractional"

    def __post_init__(self) -> None:
        object.__setattr__(self, "states", _names(self.states, "states"))
        object.__setattr__(self, "inputs", _names(self.inputs, "inputs"))
        object.__setattr__(self, "outputs", _names(self.outputs, "outputs"))
        if self.f is None:
            if self.states:
                raise InputTypeError(
                    f"f: expected a function (t, x, u, theta) -> dx/dt for the states "
                    f"{list(self.states)}, got None (f=None is only for a model without states)"
                )
            # no states: dx/dt is the empty array, never integrated (simulate.kernels)
            from flightid.simulate.kernels import no_state_derivative

            object.__setattr__(self, "f", no_state_derivative)
        if not self.outputs:
            raise InputError("outputs: expected at least one output name, got none")
        for argument in ("f", "h"):
            if not callable(getattr(self, argument)):
                raise InputTypeError(
                    f"{argument}: expected a function (t, x, u, theta) -> array, "
                    f"got {describe(getattr(self, argument))}"
                )
        if not isinstance(self.parameters, Parameters):
            object.__setattr__(self, "parameters", Parameters(self.parameters))
        x0 = self.x0 if len(self.x0) else (0.0,) * len(self.states)
        if _is_per_maneuver(x0):
            checked = tuple(tuple(self._check_x0(spec, i)) for i, spec in enumerate(x0))
        else:
            checked = tuple(self._check_x0(x0, None))
        object.__setattr__(self, "x0", checked)
        self._check_delays()

    # ----------------------------------------------------------------- output delays
    def _check_delays(self) -> None:
        delays = {} if self.output_delays is None else self.output_delays
        if not isinstance(delays, dict):
            raise InputTypeError(
                f"output_delays: expected a mapping {{output name: parameter name}}, "
                f"got {describe(delays)}"
            )
        for output, parameter in delays.items():
            if output not in self.outputs:
                raise InputError(
                    f"output_delays: {output!r} is not an output of the model; "
                    f"outputs: {list(self.outputs)}"
                )
            if not isinstance(parameter, str) or parameter not in self.parameters:
                raise InputError(
                    f"output_delays[{output!r}]: expected the name of a parameter (the delay "
                    f"in s), got {describe(parameter)}; parameters: {self.parameters.names}"
                )
        if self.delay_convention not in DELAY_CONVENTIONS:
            raise InputError(
                f"delay_convention: expected one of {list(DELAY_CONVENTIONS)}, "
                f"got {describe(self.delay_convention)}"
            )
        object.__setattr__(self, "output_delays", dict(delays))

    def output_delay_maps(self) -> list[tuple[int, int]]:
        """(output index, parameter index) of every delayed output, in output order."""
        return [
            (self.outputs.index(o), self.parameters.index(self.output_delays[o]))
            for o in self.outputs
            if o in self.output_delays
        ]

    # ----------------------------------------------------------------- initial state
    def _check_x0(self, spec: InitialState, maneuver: int | None) -> list:
        where = "x0" if maneuver is None else f"x0[{maneuver}]"
        spec = list(spec)
        if len(spec) != len(self.states):
            raise InputError(
                f"{where}: expected {len(self.states)} entries "
                f"(one per state {list(self.states)}), "
                f"got {len(spec)}"
            )
        checked: list[float | str] = []
        for state, entry in zip(self.states, spec, strict=True):
            if isinstance(entry, str):
                if entry not in self.parameters:
                    raise InputError(
                        f"{where}[{state!r}]: {entry!r} is not a parameter name; "
                        f"parameters: {self.parameters.names}"
                    )
                checked.append(entry)
            else:
                try:
                    value = float(entry)
                except (TypeError, ValueError):
                    raise InputTypeError(
                        f"{where}[{state!r}]: expected a number or a parameter name, "
                        f"got {describe(entry)}"
                    ) from None
                if not np.isfinite(value):
                    raise InputError(f"{where}[{state!r}]: must be finite, got {value}")
                checked.append(value)
        return checked

    @property
    def has_states(self) -> bool:
        """False for a model without states (outputs y = h(t, [], u, θ), nothing integrated)."""
        return len(self.states) > 0

    @property
    def per_maneuver_x0(self) -> bool:
        return _is_per_maneuver(self.x0)

    def x0_spec(self, maneuver: int = 0) -> tuple:
        """Initial-state specification used for maneuver number ``maneuver``."""
        if not self.per_maneuver_x0:
            return self.x0
        if not 0 <= maneuver < len(self.x0):
            raise InputError(
                f"maneuver: the model gives initial states for {len(self.x0)} maneuvers, "
                f"asked for number {maneuver}"
            )
        return self.x0[maneuver]

    def initial_state_maps(self, maneuver: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """(constants, parameter index or -1) arrays describing x0 of one maneuver."""
        spec = self.x0_spec(maneuver)
        constants = np.array([0.0 if isinstance(e, str) else e for e in spec], dtype=float)
        index = np.array(
            [self.parameters.index(e) if isinstance(e, str) else -1 for e in spec], dtype=np.int64
        )
        return constants, index

    def initial_state(self, theta: np.ndarray | None = None, maneuver: int = 0) -> np.ndarray:
        """x0 for the full parameter vector ``theta`` (default: the parameters' values)."""
        theta = self.parameters.values if theta is None else np.asarray(theta, dtype=float)
        constants, index = self.initial_state_maps(maneuver)
        x0 = constants.copy()
        mask = index >= 0
        x0[mask] = theta[index[mask]]
        return x0

    # ----------------------------------------------------------------- copies
    def with_parameters(self, parameters: Parameters) -> StateSpaceModel:
        """Copy with another parameter set (same names in the same order)."""
        parameters = parameters if isinstance(parameters, Parameters) else Parameters(parameters)
        if parameters.names != self.parameters.names:
            raise InputError(
                f"parameters: expected the names {self.parameters.names}, got {parameters.names}"
            )
        return replace(self, parameters=parameters)

    def with_x0(self, x0) -> StateSpaceModel:
        """Copy with another initial-state specification."""
        return replace(self, x0=tuple(x0) if not isinstance(x0, tuple) else x0)

    def __repr__(self) -> str:
        return (
            f"StateSpaceModel({self.name}: states={list(self.states)}, inputs={list(self.inputs)}, "
            f"outputs={list(self.outputs)}, {len(self.parameters)} parameters "
            f"({len(self.parameters.free_names)} free))"
        )


def _is_per_maneuver(x0) -> bool:
    """True if x0 is a list of per-maneuver specifications (a list of lists)."""
    return len(x0) > 0 and all(
        isinstance(e, (list, tuple)) or (isinstance(e, np.ndarray) and e.ndim == 1) for e in x0
    )
