"""``FilterErrorProblem``: the output-error problem of the filter error method, whose
"outputs" are a steady-state Kalman filter's predictions and whose residuals are its
innovations (the model, the filter pass and the diag(KC) ≤ 1 constraint:
``flightid.estimation.filter_error``). ``LinearFilterErrorProblem``
(``flightid.estimation.filter_error_linear``) adds analytic gradients to it; the estimator
(``estimate_filter_error``) chooses between the two.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from flightid.data.flightdata import FlightData
from flightid.errors import EstimationError, InputError
from flightid.estimation.problem import OutputErrorProblem
from flightid.filtering.kalman import RiccatiError, linearise, steady_state_gain
from flightid.model.binding import input_matrix, output_matrix
from flightid.model.forms import kernel_function, out_form_of
from flightid.model.statespace import StateSpaceModel
from flightid.simulation.kernels import RK4, make_step, record_sample, step_buffers
from flightid.simulation.simulator import SimulationBatch

__all__ = [
    "FilterErrorProblem",
    "FilterPoint",
    "KC_TOLERANCE",
    "LINEARISATIONS",
    "process_noise_name",
]

_METHODS = {"euler": 0, "rk4": RK4}
# diag(KC) may exceed 1 by this much before a θ counts as infeasible (round-off)
KC_TOLERANCE = 1e-6
# where A and C are linearised: "start" (x0 of the first maneuver, u_1)
LINEARISATIONS = ("start",)
# the filter-pass kernels built in this process, per (f, h) object and compiled flag
_FILTER_KERNELS: dict[tuple, tuple] = {}


def process_noise_name(state_index: int) -> str:
    """Default name of the process-noise element on state number ``state_index`` (0-based):
    F11, F22, … (the reference's names)."""
    return f"F{state_index + 1}{state_index + 1}"


def _filter_source(f_out: Callable, h_out: Callable, jit: Callable = lambda fn: fn) -> Callable:
    """The filter-pass loop over a batch, closed over the out-form model functions (no
    allocation per step: ``flightid.simulation.kernels``)."""
    step = jit(make_step(f_out))
    buffers_for = jit(step_buffers)
    record = jit(record_sample)

    def kernel(thetas, x0s, gains, t, u, z, method, interpolation, n_outputs, y_out, flag):
        n_batch = thetas.shape[0]
        n_samples = t.shape[0]
        for b in range(n_batch):
            theta = thetas[b]
            gain = gains[b]
            x = x0s[b].copy()
            y = np.empty(n_outputs)
            buffers = buffers_for(x.shape[0], u.shape[1])
            flag[b] = -1
            for k in range(n_samples):
                # ỹ_k = g(x̃_k, u_k)
                h_out(t[k], x, u[k], theta, y)
                if not record(y, x, y_out[b], k, n_outputs):
                    flag[b] = k
                    break
                if k == n_samples - 1:
                    break
                # x̂_k = x̃_k + K (z_k − ỹ_k)
                for i in range(x.shape[0]):
                    for j in range(n_outputs):
                        x[i] += gain[i, j] * (z[k, j] - y[j])
                # x̃_{k+1}: the state equation integrated from x̂_k
                step(t, u, k, x, theta, method, interpolation, buffers)

    return kernel


def _filter_kernel(f: Callable, h: Callable, compiled: bool) -> Callable:
    """The filter kernel of the model functions ``f``, ``h`` (return forms; the kernel runs
    their out forms, ``flightid.model.forms``), kept per (f, h)."""
    key = (id(f), id(h), compiled)
    entry = _FILTER_KERNELS.get(key)
    if entry is not None and entry[0] is f and entry[1] is h:
        return entry[2]
    f_out, h_out = out_form_of(f), out_form_of(h)
    if compiled:
        import numba

        from flightid.model.kernel_cache import cached_njit

        kernel = cached_njit(
            _filter_source(kernel_function(f_out, True), kernel_function(h_out, True), numba.njit)
        )
    else:
        kernel = _filter_source(kernel_function(f_out, False), kernel_function(h_out, False))
    _FILTER_KERNELS[key] = (f, h, kernel)
    return kernel


@dataclass(frozen=True)
class FilterPoint:
    """The steady-state filter at one full parameter vector."""

    gain: np.ndarray  # K (n_x × n_o)
    covariance: np.ndarray  # P (n_x × n_x)
    a: np.ndarray  # A = ∂f/∂x at the linearisation point
    c: np.ndarray  # C = ∂g/∂x there
    kc: np.ndarray  # diag(KC) (n_x,)


def _check_filter_model(
    model: StateSpaceModel, linearisation: str, process_noise: Mapping[str, str]
) -> None:
    """The filter error method's needs: states, no time delays, a known linearisation and
    a process-noise element for at least one state."""
    if not model.has_states:
        raise InputError("model: the filter error method needs a model with states")
    if model.output_delays or model.input_delays:
        raise InputError(
            "model: time delays (output_delays / input_delays) are not supported by the "
            "filter error method; estimate them by output error first and fix them"
        )
    if linearisation not in LINEARISATIONS:
        raise InputError(
            f"linearisation: expected one of {list(LINEARISATIONS)}, got {linearisation!r}"
        )
    if not isinstance(process_noise, Mapping) or not process_noise:
        raise InputError(
            "process_noise: expected {state: parameter name} for at least one state, "
            f"got {process_noise!r}"
        )


def _process_noise_indices(
    model: StateSpaceModel, process_noise: Mapping[str, str]
) -> tuple[list[int], list[int]]:
    """(state indices, parameter indices) of the process-noise elements {state: parameter}."""
    names = model.parameters.names
    noise_states: list[int] = []
    noise_parameters: list[int] = []
    for state, parameter in process_noise.items():
        if state not in model.states:
            raise InputError(
                f"process_noise: {state!r} is not a state of the model {list(model.states)}"
            )
        if parameter not in names:
            raise InputError(
                f"process_noise.{state}: {parameter!r} is not a parameter of the model"
            )
        noise_states.append(model.states.index(state))
        noise_parameters.append(names.index(parameter))
    return noise_states, noise_parameters


def _uniform_interval(maneuvers: Sequence[FlightData]) -> float:
    """The one sampling interval Δt (s) of all maneuvers (the steady-state gain needs it)."""
    steps = [np.diff(m.time) for m in maneuvers if m.n_samples > 1]
    dt = float(np.mean(steps[0])) if steps else 0.0
    if not dt > 0 or any(not np.allclose(s, dt, rtol=1e-6, atol=0) for s in steps):
        raise InputError(
            "data: the filter error method needs one uniform sampling interval over all "
            f"maneuvers; got intervals {sorted({float(np.round(s.mean(), 9)) for s in steps})}"
        )
    return dt


def _maneuver_arrays(
    model: StateSpaceModel, maneuvers: Sequence[FlightData]
) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """Per maneuver the contiguous time (N,), inputs (N, n_u) and measured outputs (N, n_o)
    in the model's channel order."""
    times = [np.ascontiguousarray(maneuver.time, dtype=float) for maneuver in maneuvers]
    inputs = [input_matrix(model, maneuver) for maneuver in maneuvers]
    measured = [output_matrix(model, maneuver) for maneuver in maneuvers]
    return times, inputs, measured


class FilterErrorProblem(OutputErrorProblem):
    """Output-error interface over filter passes: outputs are the filtered predictions ỹ.

    Args:
        model: the state-space model; its parameters include the process-noise elements.
        data: one maneuver or a list (all with the same sampling interval).
        process_noise: {state name: parameter name}: F = diag over those states (F_ii = the
            parameter's value; states not named get no process noise).
        method: ``"rk4"`` or ``"euler"``.
        compiled: run the numba filter kernel.
        input_interpolation: ``"linear"`` or ``"zoh"`` (as ``OutputErrorProblem``).
        linearisation: where A and C are taken: ``"start"`` — x0 of the first maneuver and
            its first input sample u_1 (the reference's fixed point).
        gain_r: the weighting R (n_o,) for gain and cost (default: ones; the estimator sets it).
        linearisation_step: Δx of the central differences for A and C (absolute).
        pinned: states whose F element sits on its constraint: it is not a free parameter
            but solved, for every θ, from diag(KC)_i = 1 (the active-set treatment of the
            constraint by ``estimate_filter_error``); their parameters must be fixed.
    """

    def __init__(
        self,
        model: StateSpaceModel,
        data: FlightData | Sequence[FlightData],
        process_noise: Mapping[str, str],
        method: str = "rk4",
        compiled: bool = True,
        input_interpolation: str = "linear",
        linearisation: str = "start",
        gain_r: np.ndarray | None = None,
        linearisation_step: float = 1e-4,
        pinned: Sequence[str] = (),
    ) -> None:
        super().__init__(
            model, data, method=method, compiled=compiled, input_interpolation=input_interpolation
        )
        _check_filter_model(model, linearisation, process_noise)
        self.noise_states, self.noise_parameters = _process_noise_indices(model, process_noise)
        self.process_noise = dict(process_noise)
        self.pinned: list[int] = self._pinned_positions(pinned)
        self._pin_start: dict[int, float] = {}
        self.linearisation = linearisation
        self.linearisation_step = float(linearisation_step)
        self.dt = _uniform_interval(self.maneuvers)
        n_o = len(model.outputs)
        self.gain_r = np.ones(n_o) if gain_r is None else np.asarray(gain_r, dtype=float)
        self.filter_passes = 0
        self._method = _METHODS[method]
        self._interpolation = 0 if input_interpolation == "linear" else 1
        self._times, self._inputs, self._measured = _maneuver_arrays(model, self.maneuvers)
        self._x0_maps = [
            model.initial_state_maps(i if model.per_maneuver_x0 else 0)
            for i in range(len(self.maneuvers))
        ]
        self._theta_maps = [
            model.function_theta_map(i) if model.substitutes_parameters else None
            for i in range(len(self.maneuvers))
        ]
        self._kernel = _filter_kernel(model.f, model.h, compiled and self.simulator.compiled)

    def _pinned_positions(self, pinned: Sequence[str]) -> list[int]:
        """Positions in noise_states / noise_parameters of the ``pinned`` states, whose F
        elements must be fixed parameters (they are solved from their constraint)."""
        positions = []
        for state in pinned:
            if state not in self.process_noise:
                raise InputError(f"pinned: {state!r} has no process-noise element")
            position = list(self.process_noise).index(state)
            if self.free_mask[self.noise_parameters[position]]:
                raise InputError(
                    f"pinned: the F element of {state!r} ({self.process_noise[state]}) is "
                    "solved from its constraint; it must not be a free parameter"
                )
            positions.append(position)
        return positions

    # ------------------------------------------------------------------ accounting
    @property
    def evaluations(self) -> int:
        """Filter passes so far (plus plain simulations): the equivalent evaluations."""
        return self.filter_passes + self.simulator.evaluations

    # ------------------------------------------------------------------ the filter
    def _f_theta(self, full: np.ndarray, maneuver: int) -> np.ndarray:
        theta_map = self._theta_maps[maneuver]
        return full if theta_map is None else full[theta_map]

    def _x0(self, full: np.ndarray, maneuver: int) -> np.ndarray:
        constants, index = self._x0_maps[maneuver]
        x0 = constants.copy()
        mask = index >= 0
        x0[mask] = full[index[mask]]
        return x0

    def f_matrix(self, full: np.ndarray) -> np.ndarray:
        """F (n_x × n_x), diagonal, from the process-noise parameters of ``full``."""
        f_matrix = np.zeros((len(self.model.states), len(self.model.states)))
        for state, parameter in zip(self.noise_states, self.noise_parameters, strict=True):
            f_matrix[state, state] = full[parameter]
        return f_matrix

    def linearisation_point(self, full: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """(t, x, u) of the gain's linearisation: x0 and u_1 of the first maneuver."""
        return float(self._times[0][0]), self._x0(full, 0), self._inputs[0][0]

    def complete(self, full: np.ndarray, r_diag: np.ndarray | None = None) -> np.ndarray:
        """``full`` with the pinned F elements solved from diag(KC)_i = 1 (a copy).

        F_ii = exp(φ_i) with φ the root of diag(KC)_i(F) − 1 = 0 over the pinned states
        (``scipy.optimize.root``, Powell's hybrid method, each residual one Riccati solve).

        Raises:
            RiccatiError: no F puts the gain on the constraint.
        """
        full = np.array(full, dtype=float)
        if not self.pinned:
            return full
        import scipy.optimize

        r_diag = self.gain_r if r_diag is None else np.asarray(r_diag, dtype=float)
        indices = [self.noise_parameters[i] for i in self.pinned]
        states = [self.noise_states[i] for i in self.pinned]

        def residual(phi: np.ndarray) -> np.ndarray:
            full[indices] = np.exp(phi)
            try:
                kc = self._filter_point(full, r_diag).kc
            except RiccatiError:
                return np.full(len(indices), 1e3)
            # diag(KC)_i − 1 for the pinned states
            return kc[states] - 1.0

        start = np.log([max(abs(self._pin_start.get(i, full[i])), 1e-12) for i in indices])
        solution = scipy.optimize.root(residual, start, method="hybr", options={"xtol": 1e-12})
        if not solution.success or np.max(np.abs(residual(solution.x))) > 1e-8:
            raise RiccatiError(
                f"no process noise puts diag(KC) on 1 for the pinned states ({solution.message})"
            )
        full[indices] = np.exp(solution.x)
        for i, value in zip(indices, full[indices], strict=True):
            self._pin_start.setdefault(i, float(value))
        return full

    def filter_point(self, full: np.ndarray, r_diag: np.ndarray | None = None) -> FilterPoint:
        """A, C, P, K and diag(KC) at the full parameter vector ``full`` (pinned F elements
        solved from their constraint first).

        Raises:
            RiccatiError: no stabilising solution of the Riccati equation.
        """
        return self._filter_point(self.complete(full, r_diag), r_diag)

    def _filter_point(self, full: np.ndarray, r_diag: np.ndarray | None = None) -> FilterPoint:
        r_diag = self.gain_r if r_diag is None else np.asarray(r_diag, dtype=float)
        t0, x, u = self.linearisation_point(full)
        theta = self._f_theta(full, 0)
        a, c = linearise(self.model.f, self.model.h, t0, x, u, theta, self.linearisation_step)
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(c))):
            raise RiccatiError("the linearised system (A, C) is not finite")
        k, p = steady_state_gain(a, c, self.f_matrix(full), r_diag, self.dt)
        # diag(KC)
        kc = np.einsum("ij,ji->i", k, c)
        return FilterPoint(k, p, a, c, kc)

    def run(self, theta_free_batch: np.ndarray, check_kc: bool = True) -> SimulationBatch:
        """Filter passes for a batch (B, n_f) of free-parameter vectors: B evaluations.

        A row whose Riccati equation has no stabilising solution, or whose gain violates
        diag(KC) ≤ 1 (``check_kc``), is flagged like a diverged simulation (NaN outputs).
        """
        full = self.full_theta(np.atleast_2d(theta_free_batch))
        n_batch = full.shape[0]
        n_x, n_o = len(self.model.states), len(self.model.outputs)
        gains = np.zeros((n_batch, n_x, n_o))
        diverged = np.zeros(n_batch, dtype=bool)
        messages = [""] * n_batch
        for b in range(n_batch):
            try:
                point = self.filter_point(full[b])
            except RiccatiError as exc:
                diverged[b], messages[b] = True, f"no steady-state gain: {exc}"
                continue
            if check_kc and np.any(point.kc > 1.0 + KC_TOLERANCE):
                diverged[b] = True
                messages[b] = (
                    f"the gain violates diag(KC) ≤ 1 (diag(KC) = "
                    f"{np.array2string(point.kc, precision=4)})"
                )
                continue
            gains[b] = point.gain
        outputs = np.full((n_batch, self.n_samples, n_o), np.nan)
        rows = np.flatnonzero(~diverged)
        start = 0
        for i, (t, u, z) in enumerate(zip(self._times, self._inputs, self._measured, strict=True)):
            stop = start + t.shape[0]
            if rows.size:
                x0s = np.ascontiguousarray(np.array([self._x0(full[b], i) for b in rows]))
                thetas = np.ascontiguousarray(np.array([self._f_theta(full[b], i) for b in rows]))
                block = np.empty((rows.size, t.shape[0], n_o))
                flag = np.empty(rows.size, dtype=np.int64)
                self._kernel(
                    thetas,
                    x0s,
                    np.ascontiguousarray(gains[rows]),
                    t,
                    u,
                    z,
                    self._method,
                    self._interpolation,
                    n_o,
                    block,
                    flag,
                )
                outputs[rows, start:stop] = block
                for r, b in enumerate(rows):
                    if flag[r] >= 0 and not diverged[b]:
                        diverged[b] = True
                        messages[b] = (
                            f"filter pass diverged in maneuver {i} at t = {t[flag[r]]:.4g} s "
                            f"(sample {int(flag[r])})"
                        )
            start = stop
        outputs[diverged] = np.nan
        self.filter_passes += n_batch
        return SimulationBatch(outputs, diverged, tuple(messages))

    def simulate(self, theta_free: np.ndarray) -> np.ndarray:
        """Plain simulation (K = 0, no process noise) at ``theta_free``: outputs (N, n_o)."""
        full = self.full_theta(np.asarray(theta_free, dtype=float)[None, :])
        batch = self.simulator.run(full)
        self._raise_if_diverged(batch, "simulation at the start values (K = 0)")
        return batch.outputs[0]

    def sensitivities_from_equations(self, theta_free, relative_step=1e-7):
        raise EstimationError(
            "the filter error method takes its sensitivities from finite differences of "
            "filter passes (MNR) or from MNRES's surface; sensitivities = 'equations' is for "
            "output error"
        )


# ---------------------------------------------------------------------- the estimator
