"""State-space models written by the user in plain Python.

    dx/dt = f(t, x, u, θ),   x(t0) = x0          [RP-1153 2.1–2.2]
    y     = h(t, x, u, θ)                        [2.3]

``f`` and ``h`` take the time (s), the state vector, the input vector (in the order of
``inputs``) and the *full* parameter vector θ (in the order of ``parameters``, free and fixed)
and return 1-D float arrays of length ``len(states)`` and ``len(outputs)``. Functions that
numba can compile are run compiled; anything else still runs, in pure Python.

Two forms (``flightid.model.forms``): the return form above, ``f(t, x, u, theta) -> dx``, or
the out form ``f(t, x, u, theta, out)`` that writes dx into the caller's ``out`` and returns
nothing. The out form lets the simulation kernels integrate without allocating an array per
stage (the return form is adapted: call, then copy — the slower path). The form is
recognised by the number of positional parameters (4 or 5) or given as ``function_form``.
Whatever was written, ``model.f``/``model.h`` are the return forms and
``model.f_out``/``model.h_out`` the out forms.

Models without states (output error on algebraic outputs, nonlinear regression): give
``states=()`` and ``f=None``; the outputs are then y_k = h(t_k, [], u_k, θ) at every sample
(``x`` is an empty array) and the simulator evaluates h alone, without integrating.

Initial states: each entry of ``x0`` is a number (fixed) or the name of a parameter (so the
initial state can be estimated). With several maneuvers, ``x0`` may be a list with one such
specification per maneuver.

Output time delays: ``output_delays={"r": "tau_r"}`` delays the simulated output ``r`` by the
parameter ``tau_r`` (s), which can then be fixed or estimated like any parameter; the rule
between samples is ``delay_convention`` ("fractional" or "two_sample", see
``flightid.simulation.simulator.apply_output_delays`` and docs/method.md, "Time delays").

Input time delays: ``input_delays={"de": "tau_de"}`` feeds the model the input ``de`` at
t − τ (τ = the parameter ``tau_de``, s): the delayed input samples ũ_k = u(t_k − τ) follow the
same rule as a delayed output (``delay_convention``; per maneuver, end values held), and the
integration treats ũ as the input samples (``input_interpolation`` between them); see
``flightid.simulation.simulator.delayed_inputs``.

Parameters per maneuver: ``f`` and ``h`` index θ in the order ``function_parameters``
(default: the names of ``parameters``). A name of ``function_parameters`` that is a key of
``maneuver_parameters`` is not itself a parameter: in maneuver k (0-based) its slot receives
the value of the parameter ``maneuver_parameters[name][k]``. ``with_per_maneuver`` builds
such a model from an ordinary one::

    θ_f,k[s] = θ[index of maneuver_parameters[name_s][k]]   if name_s is per maneuver
               θ[index of name_s]                            otherwise
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from flightid.errors import InputError, InputTypeError, describe
from flightid.model.forms import as_out_form, as_return_form
from flightid.model.forms import function_form as _form_of
from flightid.model.parameters import Parameters

__all__ = [
    "StateSpaceModel",
    "InitialState",
    "DELAY_CONVENTIONS",
    "no_state_derivative",
    "per_maneuver_name",
]

InitialState = Sequence[float | str]
# how a delayed output is formed between samples (flightid.simulation.simulator):
# "fractional": s(t_k − τ), linear between the bracketing samples, any τ;
# "two_sample": the reference's rule (τ/dt)·s_{k−1} + (1 − τ/dt)·s_k
DELAY_CONVENTIONS = ("fractional", "two_sample")


def per_maneuver_name(name: str, maneuver: int) -> str:
    """Name of the copy of parameter ``name`` for maneuver number ``maneuver`` (1-based)."""
    return f"{name}_{maneuver}"


def _names(values: Sequence[str], argument: str) -> tuple[str, ...]:
    if isinstance(values, str):
        raise InputTypeError(f"{argument}: expected a list of names, got the string {values!r}")
    if isinstance(values, Mapping) or not isinstance(values, Iterable):
        raise InputTypeError(f"{argument}: expected a list of names, got {describe(values)}")
    names = tuple(values)
    for name in names:
        if not isinstance(name, str) or not name.isidentifier():
            raise InputError(f"{argument}: names must be identifiers, got {describe(name)}")
    if len(set(names)) != len(names):
        raise InputError(f"{argument}: names must be unique, got {list(names)}")
    return names


def no_state_derivative(t: float, x: np.ndarray, u: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """dx/dt of a model without states: the empty array (the ``f`` of ``f=None``)."""
    return np.empty(0)


@dataclass(frozen=True, eq=False)
class StateSpaceModel:
    """A nonlinear state-space model with named states, inputs, outputs and parameters.

    Args:
        states: state names.
        inputs: input channel names, looked up by name in the ``FlightData``.
        outputs: output channel names, looked up by name in the ``FlightData``.
        f: state derivative ``f(t, x, u, theta) -> dx/dt`` or, out form,
            ``f(t, x, u, theta, out)`` writing dx/dt into ``out``; ``None`` for a model
            without states (``states=()``), where it becomes ``no_state_derivative``.
        h: output map ``h(t, x, u, theta) -> y`` or ``h(t, x, u, theta, out)``.
        parameters: ``Parameters`` (or anything ``Parameters`` accepts).
        x0: initial state: numbers and/or parameter names (one list, or one per maneuver).
        name: label for reports.
        output_delays: ``{output name: parameter name}``: the simulated output is delayed by
            that parameter's value (s); default none.
        delay_convention: ``"fractional"`` (default) or ``"two_sample"`` (the reference's
            rule); see ``flightid.simulation.simulator.apply_output_delays``. It applies to
            output and input delays alike.
        input_delays: ``{input name: parameter name}``: the model receives that input at
            t − τ, τ = the parameter's value (s); default none
            (``flightid.simulation.simulator.delayed_inputs``).
        function_parameters: names, in the order in which ``f`` and ``h`` index θ; default
            the names of ``parameters``. Every name is a parameter or a key of
            ``maneuver_parameters``.
        maneuver_parameters: ``{name: (parameter of maneuver 1, of maneuver 2, ...)}``: the
            slot ``name`` of the θ that f and h receive takes, in each maneuver, the value of
            that maneuver's parameter; default none. See ``with_per_maneuver``.
        function_form: ``"auto"`` (default: 4 positional parameters = return form, 5 = out
            form), ``"return"`` or ``"out"`` (``flightid.model.forms``); it applies to f and
            h. After construction ``f``/``h`` are return forms, ``f_out``/``h_out`` out forms.
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
    input_delays: dict[str, str] | None = None  # a dict ({} for none) after __post_init__
    function_parameters: tuple[str, ...] | None = None  # a tuple after __post_init__
    maneuver_parameters: dict[str, tuple[str, ...]] | None = None  # a dict after
    function_form: str = "auto"

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise InputTypeError(f"name: expected a string, got {describe(self.name)}")
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
            object.__setattr__(self, "f", no_state_derivative)
        if not self.outputs:
            raise InputError("outputs: expected at least one output name, got none")
        for argument in ("f", "h"):
            if not callable(getattr(self, argument)):
                raise InputTypeError(
                    f"{argument}: expected a function (t, x, u, theta) -> array, "
                    f"got {describe(getattr(self, argument))}"
                )
        self._set_function_forms()
        if not isinstance(self.parameters, Parameters):
            object.__setattr__(self, "parameters", Parameters(self.parameters))
        self._check_maneuver_parameters()
        x0 = self.x0 if len(self.x0) else (0.0,) * len(self.states)
        if _is_per_maneuver(x0):
            checked = tuple(tuple(self._check_x0(spec, i)) for i, spec in enumerate(x0))
        else:
            checked = tuple(self._check_x0(x0, None))
        object.__setattr__(self, "x0", checked)
        self._check_delays()

    def _set_function_forms(self) -> None:
        """``f``/``h`` in return form, ``f_out``/``h_out`` in out form (module docstring)."""
        for argument, size in (("f", len(self.states)), ("h", len(self.outputs))):
            fn = getattr(self, argument)
            if _form_of(fn, self.function_form, argument) == "out":
                # the user's out form; the return form allocates and calls it
                fn = as_return_form(fn, size)
                object.__setattr__(self, argument, fn)
            out = getattr(fn, "out_form", None)
            # a return form without its own out form: call, then copy (allocates per call)
            object.__setattr__(self, f"{argument}_out", out if out is not None else as_out_form(fn))

    # ----------------------------------------------------------------- output delays
    def _check_delays(self) -> None:
        for argument, channels, kind, other in (
            ("output_delays", self.outputs, "output", self.inputs),
            ("input_delays", self.inputs, "input", self.outputs),
        ):
            delays = getattr(self, argument)
            delays = {} if delays is None else delays
            if not isinstance(delays, dict):
                raise InputTypeError(
                    f"{argument}: expected a mapping {{{kind} name: parameter name}}, "
                    f"got {describe(delays)}"
                )
            for channel, parameter in delays.items():
                if channel not in channels:
                    also = (
                        f" ({channel!r} is an {'input' if kind == 'output' else 'output'}: "
                        f"use {'input' if kind == 'output' else 'output'}_delays)"
                        if channel in other
                        else ""
                    )
                    raise InputError(
                        f"{argument}: {channel!r} is not an {kind} of the model{also}; "
                        f"{kind}s: {list(channels)}"
                    )
                if not isinstance(parameter, str) or parameter not in self.parameters:
                    raise InputError(
                        f"{argument}[{channel!r}]: expected the name of a parameter (the delay "
                        f"in s), got {describe(parameter)}; parameters: {self.parameters.names}"
                    )
            object.__setattr__(self, argument, dict(delays))
        if self.delay_convention not in DELAY_CONVENTIONS:
            raise InputError(
                f"delay_convention: expected one of {list(DELAY_CONVENTIONS)}, "
                f"got {describe(self.delay_convention)}"
            )

    def output_delay_maps(self) -> list[tuple[int, int]]:
        """(output index, parameter index) of every delayed output, in output order."""
        return [
            (self.outputs.index(o), self.parameters.index(self.output_delays[o]))
            for o in self.outputs
            if o in self.output_delays
        ]

    def input_delay_maps(self) -> list[tuple[int, int]]:
        """(input index, parameter index) of every delayed input, in input order."""
        return [
            (self.inputs.index(i), self.parameters.index(self.input_delays[i]))
            for i in self.inputs
            if i in self.input_delays
        ]

    # ----------------------------------------------------------------- per-maneuver θ
    def _check_maneuver_parameters(self) -> None:
        names = self.parameters.names
        layout = names if self.function_parameters is None else self.function_parameters
        layout = _names(layout, "function_parameters")
        per = {} if self.maneuver_parameters is None else self.maneuver_parameters
        if not isinstance(per, dict):
            raise InputTypeError(
                f"maneuver_parameters: expected a mapping {{name: (parameter of maneuver 1, "
                f"...)}}, got {describe(per)}"
            )
        counts = set()
        checked: dict[str, tuple[str, ...]] = {}
        for name, copies in per.items():
            where = f"maneuver_parameters[{name!r}]"
            if name not in layout:
                raise InputError(
                    f"{where}: {name!r} is not one of the function parameters {list(layout)}"
                )
            if name in self.parameters:
                raise InputError(
                    f"{where}: {name!r} is also a parameter; a per-maneuver slot takes its "
                    f"values from its copies only"
                )
            copies = _names(copies, where)
            if not copies:
                raise InputError(f"{where}: expected one parameter name per maneuver, got none")
            for copy in copies:
                if copy not in self.parameters:
                    raise InputError(f"{where}: {copy!r} is not a parameter; parameters: {names}")
            counts.add(len(copies))
            checked[name] = copies
        if len(counts) > 1:
            raise InputError(
                f"maneuver_parameters: every entry needs the same number of maneuvers, got "
                f"{ {k: len(v) for k, v in checked.items()} }"
            )
        missing = [n for n in layout if n not in checked and n not in self.parameters]
        if missing:
            raise InputError(
                f"function_parameters: {missing} are neither parameters nor per-maneuver "
                f"entries; parameters: {names}"
            )
        object.__setattr__(self, "function_parameters", layout)
        object.__setattr__(self, "maneuver_parameters", checked)
        for k in range(max(self.n_parameter_maneuvers, 1)):
            slots = self.function_theta_map(k)
            if np.unique(slots).size != slots.size:
                fed = [n for n, i in zip(layout, slots, strict=True) if (slots == i).sum() > 1]
                raise InputError(
                    f"maneuver_parameters: in maneuver {k + 1} one parameter feeds several "
                    f"slots of θ {fed}; each parameter may feed one slot per maneuver"
                )

    @property
    def n_parameter_maneuvers(self) -> int:
        """Number of maneuvers the per-maneuver parameters are given for (0: none)."""
        per = self.maneuver_parameters
        return len(next(iter(per.values()))) if per else 0

    def function_theta_map(self, maneuver: int = 0) -> np.ndarray:
        """Indices into θ (the full parameter vector) of every slot of the θ that f and h
        receive in maneuver number ``maneuver`` (0-based): θ_f = θ[map]."""
        per = self.maneuver_parameters
        if per and not 0 <= maneuver < self.n_parameter_maneuvers:
            raise InputError(
                f"maneuver: the model gives per-maneuver parameters for "
                f"{self.n_parameter_maneuvers} maneuvers, asked for number {maneuver}"
            )
        # θ_f[s] = θ[copy of maneuver k] for a per-maneuver slot, θ[name] otherwise
        return np.array(
            [
                self.parameters.index(per[n][maneuver] if n in per else n)
                for n in self.function_parameters
            ],
            dtype=np.int64,
        )

    @property
    def substitutes_parameters(self) -> bool:
        """True if f and h receive another θ than the full parameter vector."""
        return bool(self.maneuver_parameters) or (
            list(self.function_parameters) != self.parameters.names
        )

    def function_theta(self, theta: np.ndarray | None = None, maneuver: int = 0) -> np.ndarray:
        """The θ that f and h receive in maneuver ``maneuver`` (0-based) for the full vector
        ``theta`` (default: the parameters' values)."""
        theta = self.parameters.values if theta is None else np.asarray(theta, dtype=float)
        if not self.substitutes_parameters:
            return theta
        return theta[self.function_theta_map(maneuver)]

    def with_per_maneuver(self, names: Sequence[str], n_maneuvers: int) -> StateSpaceModel:
        """Copy in which each parameter of ``names`` becomes one parameter per maneuver,
        ``NAME_1`` … ``NAME_n`` (start value, free, scale, bounds and unit of ``NAME``).

        The parameters become: the others in their order, then the copies in maneuver-major
        order (all copies of maneuver 1 in parameter order, then maneuver 2, ...). f and h
        still index θ as before (``function_parameters``). With ``n_maneuvers == 1`` the
        model is returned unchanged.
        """
        names = list(_names(names, "names"))
        self._check_per_maneuver_request(names, n_maneuvers)
        if n_maneuvers == 1 or not names:
            return self
        self._check_expandable(names)
        # parameters: the others in order, then maneuver-major copies
        chosen = [p for p in self.parameters if p.name in names]
        parameters = [p for p in self.parameters if p.name not in names]
        for k in range(1, n_maneuvers + 1):
            parameters += [replace(p, name=per_maneuver_name(p.name, k)) for p in chosen]
        per = {
            p.name: tuple(per_maneuver_name(p.name, k) for k in range(1, n_maneuvers + 1))
            for p in chosen
        }
        return replace(
            self,
            parameters=Parameters(parameters),
            function_parameters=self.function_parameters,
            maneuver_parameters=per,
        )

    def _check_per_maneuver_request(self, names: list[str], n_maneuvers: int) -> None:
        """``names`` are parameters of the model; ``n_maneuvers`` an integer ≥ 1."""
        unknown = [n for n in names if n not in self.parameters]
        if unknown:
            raise InputError(
                f"names: {unknown} are not parameters of the model; parameters: "
                f"{self.parameters.names}"
            )
        if isinstance(n_maneuvers, bool) or not isinstance(n_maneuvers, (int, np.integer)):
            raise InputTypeError(f"n_maneuvers: expected an integer, got {describe(n_maneuvers)}")
        if n_maneuvers < 1:
            raise InputError(f"n_maneuvers: expected at least 1, got {n_maneuvers}")

    def _check_expandable(self, names: list[str]) -> None:
        """No per-maneuver parameters yet, and none of ``names`` a time delay or an initial
        state (only parameters that f and h read can be per maneuver)."""
        if self.maneuver_parameters:
            raise InputError(
                "names: the model already has per-maneuver parameters "
                f"{list(self.maneuver_parameters)}; expand all of them in one call"
            )
        used = [
            n
            for n in names
            if n in (self.output_delays or {}).values()
            or n in (self.input_delays or {}).values()
            or any(n in spec for spec in (self.x0 if self.per_maneuver_x0 else (self.x0,)))
        ]
        if used:
            raise InputError(
                f"names: {used} are time delays or initial states; only parameters that f and "
                f"h read can be per maneuver"
            )

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
