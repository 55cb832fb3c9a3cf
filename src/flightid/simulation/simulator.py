"""``Simulator``: output time histories of a model over one or several maneuvers.

One call of ``outputs`` for a batch of B parameter vectors performs B system integrations
(B "equivalent evaluations" in the paper's accounting, RP-1153 §6); the simulator counts them.

Per maneuver k the simulator hands f and h the θ of the model's function layout,
θ_f = θ[``model.function_theta_map(k)``] (per-maneuver parameters), the initial state from
the full θ, and the inputs of that maneuver — delayed per batch row where the model has
``input_delays`` (``delayed_inputs``); output delays act on the finished outputs
(``apply_output_delays``).

Unstable-aircraft options (``flightid.model.unstable``, docs/unstable.md) are read from the
model: a ``stabilizing_gain`` S (n_s × n_o) corrects the state at every sample,
x_k ← x_k + S (z_k − y_k), with z the maneuver's measured outputs; ``shooting`` splits each
maneuver into intervals that start from their own initial-state parameters, and ``run``
returns the continuity defects x_end(interval m) − x0(interval m + 1) beside the outputs
(``SimulationBatch.defects``). Both run through ``flightid.simulation.feedback``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from flightid.data.flightdata import FlightData
from flightid.errors import InputError, SimulationError
from flightid.model.binding import (
    INTEGRATION_METHODS,
    bind_feedback,
    bind_maneuvers,
    check_method,
)
from flightid.model.compilation import is_compile_error, warn_pure_python
from flightid.model.statespace import StateSpaceModel
from flightid.simulation.feedback import make_feedback_kernel
from flightid.simulation.kernels import EULER, INTERPOLATIONS, RK4, make_kernel

__all__ = [
    "Simulator",
    "SimulationBatch",
    "simulate",
    "INPUT_INTERPOLATIONS",
    "check_input_interpolation",
    "delay_weights",
    "apply_output_delays",
    "delayed_inputs",
]

_METHODS = dict(zip(INTEGRATION_METHODS, (EULER, RK4), strict=True))
# input between samples: "linear" (u at the RK4 half step = mean of the neighbouring
# samples) or "zoh" (zero-order hold: u = u_k on [t_k, t_{k+1})); see simulate.kernels
INPUT_INTERPOLATIONS = tuple(INTERPOLATIONS)


def check_input_interpolation(value: object) -> str:
    """``value`` if it is one of ``INPUT_INTERPOLATIONS``, else ``InputError`` naming them."""
    if not isinstance(value, str) or value not in INTERPOLATIONS:
        raise InputError(
            f"input_interpolation: expected one of {list(INPUT_INTERPOLATIONS)} (how the "
            f"input varies between samples), got {value!r}"
        )
    return value


def delay_weights(
    t: np.ndarray, tau: float, convention: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Indices and weights of a delayed signal over one maneuver's times ``t`` (s).

    Returns (i1, i0, c, dc) such that the delayed signal is
    s_τ,k = s[i1_k] + c_k·(s[i0_k] − s[i1_k]) and ∂s_τ,k/∂τ = dc_k·(s[i0_k] − s[i1_k]).

    ``"fractional"``: s_τ,k = s(t_k − τ), linear between the two samples that bracket
    t_k − τ (any sign, any size); before the first sample or after the last the end value is
    held (and ∂/∂τ = 0 there). ``"two_sample"`` (the reference's ``timeDelay``):
    s_τ,k = (τ/dt_k)·s_{k−1} + (1 − τ/dt_k)·s_k with dt_k = t_k − t_{k−1}, and
    s_τ,0 = s_0 at the maneuver's first sample.
    """
    n = t.shape[0]
    k = np.arange(n)
    if n < 2:
        zero = np.zeros(n)
        return k, k, zero, zero
    if convention == "two_sample":
        i0 = np.maximum(k - 1, 0)
        dt = np.empty(n)
        dt[0] = 1.0
        dt[1:] = np.diff(t)
        # s_τ,k = s_k + (τ/dt_k)·(s_{k−1} − s_k);  ∂/∂τ = (s_{k−1} − s_k)/dt_k;  s_τ,0 = s_0
        dc = np.where(k > 0, 1.0 / dt, 0.0)
        return k, i0, tau * dc, dc
    # fractional: target time t_k − τ, held at the maneuver's ends
    target = t - tau
    inside = (target >= t[0]) & (target <= t[-1])
    target = np.clip(target, t[0], t[-1])
    # j: the sample with t_j ≤ target < t_{j+1} (the last interval at the end)
    j = np.clip(np.searchsorted(t, target, side="right") - 1, 0, n - 2)
    h = t[j + 1] - t[j]
    # s(t_k − τ) = s_j + w·(s_{j+1} − s_j),  w = (t_k − τ − t_j)/(t_{j+1} − t_j);
    # ∂w/∂τ = −1/(t_{j+1} − t_j) inside the record, 0 where the end value is held
    w = (target - t[j]) / h
    dw = np.where(inside, -1.0 / h, 0.0)
    return j, j + 1, w, dw


def apply_output_delays(
    model: StateSpaceModel,
    times: Sequence[np.ndarray],
    thetas: np.ndarray,
    outputs: np.ndarray,
) -> np.ndarray:
    """Delay the model's ``output_delays`` channels in ``outputs`` (B, N_total, n_o), in place.

    Each batch row b uses its own delay τ = thetas[b, index]; each maneuver (``times``, s) is
    delayed on its own, so no sample of one maneuver enters another (rule: ``delay_weights``).
    """
    delays = model.output_delay_maps()
    if not delays:
        return outputs
    start = 0
    for t in times:
        stop = start + t.shape[0]
        for b in range(outputs.shape[0]):
            for j, p in delays:
                i1, i0, c, _ = delay_weights(t, float(thetas[b, p]), model.delay_convention)
                s = outputs[b, start:stop, j].copy()
                # s_τ,k = s[i1_k] + c_k·(s[i0_k] − s[i1_k])
                outputs[b, start:stop, j] = s[i1] + c * (s[i0] - s[i1])
        start = stop
    return outputs


def delayed_inputs(
    model: StateSpaceModel, t: np.ndarray, u: np.ndarray, theta: np.ndarray
) -> np.ndarray:
    """One maneuver's input samples ``u`` (N, n_u) at times ``t`` (s) with the model's
    ``input_delays`` applied for the full parameter vector ``theta``.

    A delayed channel becomes ũ_k = u(t_k − τ) by the rule of ``delay_weights`` (the model's
    ``delay_convention``: "fractional", linear between the samples that bracket t_k − τ, any
    sign and size, the maneuver's first / last sample held outside it; or "two_sample"). Only
    this maneuver's samples are used. The integration then treats ũ as the input samples.
    """
    maps = model.input_delay_maps()
    if not maps:
        return u
    out = np.array(u, dtype=float, copy=True)
    for j, p in maps:
        i1, i0, c, _ = delay_weights(t, float(theta[p]), model.delay_convention)
        # ũ_k = u[i1_k] + c_k·(u[i0_k] − u[i1_k])
        out[:, j] = u[i1, j] + c * (u[i0, j] - u[i1, j])
    return np.ascontiguousarray(out)


# Kernels are kept per content of (f, h) (kernel_cache.content_key) so that repeated estimations in
# a process reuse them (across processes the compiled code is kept on disk:
# flightid.model.kernel_cache).
_KERNEL_CACHE: dict[tuple, object] = {}


@dataclass(frozen=True)
class SimulationBatch:
    """Outputs of a batch: ``outputs`` (B, N_total, n_o) and per-trajectory divergence.

    ``diverged[b]`` is True if trajectory b produced a non-finite state or output; its
    outputs from that sample on are NaN and ``messages[b]`` says where. ``defects`` (B, E):
    with multiple shooting, the continuity defects x_end(interval m) − x0(interval m + 1),
    maneuver by maneuver, boundary by boundary, state by state (None without shooting).
    """

    outputs: np.ndarray
    diverged: np.ndarray
    messages: tuple[str, ...]
    defects: np.ndarray | None = None


class Simulator:
    """Integrates a ``StateSpaceModel`` against the inputs of one or more maneuvers.

    Args:
        model: the model.
        data: a ``FlightData`` or a list of them (maneuvers); they must carry the model's
            input channels (outputs are not needed to simulate).
        method: ``"rk4"`` (default) or ``"euler"``.
        compiled: run the numba-compiled kernel (falls back to Python, with a warning, when
            numba cannot compile the model functions).
        input_interpolation: how the input varies between samples in the RK4 stages:
            ``"linear"`` (default; u at the half step = (u_k + u_{k+1})/2) or ``"zoh"``
            (zero-order hold, u = u_k on [t_k, t_{k+1})). Euler uses u_k either way.
    """

    def __init__(
        self,
        model: StateSpaceModel,
        data: FlightData | Sequence[FlightData],
        method: str = "rk4",
        compiled: bool = True,
        input_interpolation: str = "linear",
    ) -> None:
        self.method = check_method(method)
        self.input_interpolation = check_input_interpolation(input_interpolation)
        self._interpolation = INTERPOLATIONS[input_interpolation]
        self.model = model
        bound = bind_maneuvers(model, data)
        self.maneuvers = bound.maneuvers
        self._times = bound.times
        self._inputs = bound.inputs
        self._x0_maps = bound.x0_maps
        # θ_f = θ[map]: the θ that f and h receive in each maneuver (None: θ itself)
        self._theta_maps = bound.theta_maps
        self._bound = bound
        # per call of ``run``: what does not depend on θ, read once here (a frozen model)
        self._n_samples = int(sum(t.shape[0] for t in self._times))
        self._x0_free = [
            (np.flatnonzero(index >= 0), index[index >= 0]) for _, index in self._x0_maps
        ]
        self._method_code = _METHODS[self.method]
        self._has_output_delays = bool(model.output_delay_maps())
        self._has_input_delays = bool(model.input_delay_maps())
        self._kernel, self.compiled = self._get_kernel(compiled)
        self._setup_feedback()
        self.evaluations = 0

    # --------------------------------------------------------------------- feedback
    def _setup_feedback(self) -> None:
        """The stabilizing gain, measured outputs and shooting intervals of the model
        (``flightid.model.unstable``), checked against the maneuvers
        (``flightid.model.binding.bind_feedback``)."""
        bound = bind_feedback(self.model, self._bound)
        self.feedback = bound.feedback
        self._gain = bound.gain
        self._measured = bound.measured
        # per maneuver: [(first sample, parameter index per state)] of intervals 2, 3, ...
        self._intervals = bound.intervals
        self.n_defects = bound.n_defects
        if self.feedback:
            self._feedback_kernel = self._memo(
                ("feedback", self.compiled),
                lambda: make_feedback_kernel(self.model.f_out, self.model.h_out, self.compiled),
            )

    # --------------------------------------------------------------------- kernels
    def _memo(self, kind: tuple, build):
        """The kernel ``kind`` of this model's (f, h): built once per process by ``build()``,
        then reused by every simulator of functions that compute the same: the key is the
        content of the out forms the kernels call (``flightid.model.kernel_cache.content_key``:
        their code, constants and closure values), not the function objects, so a case
        builder making new closures of the same model gets the kernel already compiled."""
        from flightid.model.kernel_cache import content_key

        key = (content_key(self.model.f_out), content_key(self.model.h_out), *kind)
        kernel = _KERNEL_CACHE.get(key)
        if kernel is None:
            kernel = build()
            _KERNEL_CACHE[key] = kernel
        return kernel

    def _get_kernel(self, compiled: bool):
        def build():
            kernel, is_compiled = make_kernel(
                self.model.f_out,
                self.model.h_out,
                compiled,
                stateless=not self.model.has_states,
                sizes=(len(self.model.states), len(self.model.outputs)),
            )
            return self._try_compile(kernel) if is_compiled else (kernel, is_compiled)

        sizes = (len(self.model.states), len(self.model.outputs))
        return self._memo(("state", compiled, self.model.has_states, sizes), build)

    def _try_compile(self, kernel):
        """Run the compiled kernel once on the first samples; fall back to Python on failure."""
        full = self.model.parameters.values
        theta = self.model.function_theta(full, 0)[None, :]
        x0 = self.model.initial_state(full, 0)[None, :]
        n = min(3, self._times[0].shape[0])
        y = np.empty((1, n, len(self.model.outputs)))
        flag = np.empty(1, dtype=np.int64)
        try:
            kernel(
                theta,
                x0,
                self._times[0][:n],
                self._inputs[0][:n],
                _METHODS[self.method],
                self._interpolation,
                len(self.model.outputs),
                y,
                flag,
            )
            return kernel, True
        except Exception as exc:  # numba typing errors have many classes
            if is_compile_error(exc):
                # a wrapper around the user's f/h (case biases) carries the user's own error
                cause = next(
                    (
                        getattr(fn, "compile_failure", None)
                        for fn in (self.model.f_out, self.model.h_out, self.model.f, self.model.h)
                        if getattr(fn, "compile_failure", None) is not None
                    ),
                    exc,
                )
                warn_pure_python(self.model.name, cause, stacklevel=4, function=self.model.f)
                return make_kernel(
                    self.model.f_out,
                    self.model.h_out,
                    compiled=False,
                    stateless=not self.model.has_states,
                )
            raise

    # --------------------------------------------------------------------- running
    @property
    def n_samples(self) -> int:
        """Total number of samples over all maneuvers."""
        return self._n_samples

    def run(self, thetas: np.ndarray) -> SimulationBatch:
        """Outputs for a batch of full parameter vectors ``thetas`` (B, n_params).

        Counts B equivalent evaluations. Non-finite trajectories are flagged, not raised.
        """
        thetas = np.ascontiguousarray(np.atleast_2d(np.asarray(thetas, dtype=float)))
        n_params = len(self.model.parameters)
        if thetas.ndim != 2 or thetas.shape[1] != n_params:
            raise InputError(f"thetas: expected shape (batch, {n_params}), got {thetas.shape}")
        if self.feedback:
            return self._run_feedback(thetas)
        n_batch = thetas.shape[0]
        n_out = len(self.model.outputs)
        outputs = np.empty((n_batch, self.n_samples, n_out))
        diverged = np.zeros(n_batch, dtype=bool)
        messages = [""] * n_batch
        start = 0
        # one maneuver: the kernel writes straight into ``outputs`` (no block and no copy of
        # the B·N·n_o outputs: a batch of 21 × 1001 × 8 spent ~1 ms copying)
        single = len(self._times) == 1
        for i, (t, u, (constants, _), (slots, columns), theta_map) in enumerate(
            zip(
                self._times, self._inputs, self._x0_maps, self._x0_free, self._theta_maps,
                strict=True,
            )
        ):  # fmt: skip
            # x0 = the constants, with the initial-state parameters of θ in their slots
            x0s = np.empty((n_batch, constants.shape[0]))
            x0s[:] = constants
            if slots.size:
                x0s[:, slots] = thetas[:, columns]
            # θ_f = θ[map]: per-maneuver parameters substituted into the θ of f and h
            f_thetas = thetas if theta_map is None else np.ascontiguousarray(thetas[:, theta_map])
            block = outputs if single else np.empty((n_batch, t.shape[0], n_out))
            flag = np.empty(n_batch, dtype=np.int64)
            if not self._has_input_delays:
                self._kernel(f_thetas, x0s, t, u, self._method_code, self._interpolation,
                             n_out, block, flag)  # fmt: skip
            else:
                self._run_delayed_groups(t, u, thetas, f_thetas, x0s, block, flag)
            if not single:
                outputs[:, start : start + t.shape[0]] = block
            for b in np.flatnonzero(flag >= 0) if flag.max() >= 0 else ():
                if not diverged[b]:
                    diverged[b] = True
                    messages[b] = (
                        f"simulation diverged in maneuver {i} at t = {t[flag[b]]:.4g} s "
                        f"(sample {int(flag[b])}): non-finite state or output"
                    )
            start += t.shape[0]
        # output time delays act on the simulated outputs, per row and per maneuver
        if self._has_output_delays:
            apply_output_delays(self.model, self._times, thetas, outputs)
        self.evaluations += n_batch
        return SimulationBatch(outputs, diverged, tuple(messages))

    def _run_delayed_groups(self, t, u, thetas, f_thetas, x0s, block, flag) -> None:
        """The kernel over the batch rows grouped by their input delays: rows that share
        their delays share one delayed input matrix (``_input_groups``)."""
        n_batch, n_out = thetas.shape[0], block.shape[2]
        for rows, u_rows in self._input_groups(t, u, thetas):
            whole = rows.size == n_batch
            sub_block = block if whole else np.empty((rows.size, t.shape[0], n_out))
            sub_flag = flag if whole else np.empty(rows.size, dtype=np.int64)
            self._kernel(
                f_thetas if whole else np.ascontiguousarray(f_thetas[rows]),
                x0s if whole else np.ascontiguousarray(x0s[rows]),
                t,
                u_rows,
                self._method_code,
                self._interpolation,
                n_out,
                sub_block,
                sub_flag,
            )
            if not whole:
                block[rows] = sub_block
                flag[rows] = sub_flag

    def _run_feedback(self, thetas: np.ndarray) -> SimulationBatch:
        """``run`` with the state correction and/or shooting intervals (module docstring).

        Interval m of a maneuver covers samples [s_m, s_{m+1}); it is integrated one sample
        further, to s_{m+1}, for its end state; the defect is x_end − x0(interval m + 1).
        """
        n_batch = thetas.shape[0]
        n_out = len(self.model.outputs)
        n_states = len(self.model.states)
        outputs = np.empty((n_batch, self.n_samples, n_out))
        defects = np.zeros((n_batch, self.n_defects))
        diverged = np.zeros(n_batch, dtype=bool)
        messages = [""] * n_batch
        start, column = 0, 0
        stabilize = self._gain.shape[0] > 0
        for i, (t, u, (constants, index), theta_map) in enumerate(
            zip(self._times, self._inputs, self._x0_maps, self._theta_maps, strict=True)
        ):
            n = t.shape[0]
            x0s = np.repeat(constants[None, :], n_batch, axis=0)
            mask = index >= 0
            x0s[:, mask] = thetas[:, index[mask]]
            f_thetas = thetas if theta_map is None else thetas[:, theta_map]
            firsts = [0] + [s for s, _ in self._intervals[i]]
            lasts = firsts[1:] + [n]
            block = np.empty((n_batch, n, n_out))
            for rows, u_rows in self._input_groups(t, u, thetas):
                for m, (first, last) in enumerate(zip(firsts, lasts, strict=True)):
                    # interval m: samples [first, last), integrated to `last` for x_end
                    stop = min(last + 1, n)
                    x0 = x0s[rows] if m == 0 else thetas[rows][:, self._intervals[i][m - 1][1]]
                    y = np.empty((rows.size, stop - first, n_out))
                    flag = np.empty(rows.size, dtype=np.int64)
                    x_end = np.empty((rows.size, n_states))
                    self._feedback_kernel(
                        np.ascontiguousarray(f_thetas[rows]),
                        np.ascontiguousarray(x0),
                        t[first:stop],
                        np.ascontiguousarray(u_rows[first:stop]),
                        _METHODS[self.method],
                        self._interpolation,
                        n_out,
                        y,
                        flag,
                        self._measured[i][first:stop] if stabilize else self._measured[i],
                        self._gain,
                        x_end,
                    )
                    block[rows, first:last] = y[:, : last - first]
                    for r, b in enumerate(rows):
                        if flag[r] >= 0 and not diverged[b]:
                            k = first + int(flag[r])
                            diverged[b] = True
                            messages[b] = (
                                f"simulation diverged in maneuver {i} at t = {t[k]:.4g} s "
                                f"(sample {k}): non-finite state or output"
                            )
                    if m < len(firsts) - 1:
                        nxt = self._intervals[i][m][1]
                        c = column + m * n_states
                        # continuity defect d = x_end(interval m) − x0(interval m + 1)
                        defects[rows, c : c + n_states] = x_end - thetas[rows][:, nxt]
            outputs[:, start : start + n] = block
            start += n
            column += n_states * len(self._intervals[i])
        apply_output_delays(self.model, self._times, thetas, outputs)
        self.evaluations += n_batch
        return SimulationBatch(
            outputs,
            diverged,
            tuple(messages),
            defects if self.n_defects else None,
        )

    def _input_groups(self, t: np.ndarray, u: np.ndarray, thetas: np.ndarray):
        """(rows, inputs) pairs: the batch rows that share one set of input delays, and that
        maneuver's inputs delayed by them (all rows and ``u`` itself without input delays)."""
        maps = self.model.input_delay_maps()
        if not maps:
            yield np.arange(thetas.shape[0]), u
            return
        taus = thetas[:, [p for _, p in maps]]
        unique, inverse = np.unique(taus, axis=0, return_inverse=True)
        for g in range(unique.shape[0]):
            rows = np.flatnonzero(inverse.ravel() == g)
            yield rows, delayed_inputs(self.model, t, u, thetas[rows[0]])

    def run_with_sensitivities(
        self,
        theta: np.ndarray,
        free_index: np.ndarray,
        steps: np.ndarray,
        relative_step: float = 1e-7,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Outputs (N_total, n_o) and sensitivities G (N_total, n_o, n_f) for one full
        parameter vector, by integrating the sensitivity equations
        (``flightid.simulation.sensitivity``).

        ``steps`` are the finite-difference steps of the free parameters in the Jacobians.
        Counts 1 + n_s + n_f equivalent evaluations (the calls of f per stage, relative to a
        plain integration), plus 2 per free input-delay parameter (its column comes from
        central differences, ``_input_delay_columns``). Raises ``SimulationError`` if the
        trajectory becomes non-finite.
        """
        from flightid.simulation.feedback import make_feedback_sensitivity_kernel
        from flightid.simulation.sensitivity import make_sensitivity_kernel

        if self.n_defects:
            raise SimulationError(
                "sensitivity equations: not available with multiple shooting; use finite "
                "differences (OutputErrorProblem.sensitivities_from_equations falls back)"
            )
        stabilize = self._gain.shape[0] > 0
        if stabilize:
            kernel = self._memo(
                ("feedback-sensitivity", self.compiled),
                lambda: make_feedback_sensitivity_kernel(
                    self.model.f_out, self.model.h_out, self.compiled
                ),
            )
        else:
            kernel = self._memo(
                ("sensitivity", self.compiled),
                lambda: make_sensitivity_kernel(self.model.f_out, self.model.h_out, self.compiled),
            )
        theta = np.ascontiguousarray(theta, dtype=float)
        free_index = np.ascontiguousarray(free_index, dtype=np.int64)
        n_out = len(self.model.outputs)
        n_states = len(self.model.states)
        outputs = np.empty((self.n_samples, n_out))
        g = np.empty((self.n_samples, n_out, free_index.size))
        start = 0
        for i, (t, u, (constants, index), theta_map) in enumerate(
            zip(self._times, self._inputs, self._x0_maps, self._theta_maps, strict=True)
        ):
            x0 = constants.copy()
            mask = index >= 0
            x0[mask] = theta[index[mask]]
            # S(t0) = ∂x0/∂θ: 1 where an initial state is a free parameter
            s0 = np.zeros((n_states, free_index.size))
            for state, parameter in enumerate(index):
                s0[state, free_index == parameter] = 1.0
            f_theta, f_free = self._function_free(theta, free_index, theta_map)
            y_block = np.empty((t.shape[0], n_out))
            g_block = np.empty((t.shape[0], n_out, free_index.size))
            arguments = (
                f_theta,
                x0,
                s0,
                f_free,
                np.asarray(steps, dtype=float),
                relative_step,
                t,
                delayed_inputs(self.model, t, u, theta),
                _METHODS[self.method],
                self._interpolation,
                n_out,
                y_block,
                g_block,
            )
            # the stabilized kernel also takes the measured outputs and the gain
            extra = (self._measured[i], self._gain) if stabilize else ()
            flag = kernel(*arguments, *extra)
            if flag >= 0:
                raise SimulationError(
                    f"simulation diverged in maneuver {i} at t = {t[flag]:.4g} s "
                    f"(sample {int(flag)}): non-finite state or output"
                )
            # output time delays: the delayed sensitivity is the same interpolation of the
            # sensitivity, G_τ,k = G[i1_k] + c_k·(G[i0_k] − G[i1_k]), plus for the delay
            # parameter itself ∂s_τ,k/∂τ = dc_k·(s[i0_k] − s[i1_k]) (undelayed s)
            for j, p in self.model.output_delay_maps():
                i1, i0, c, dc = delay_weights(t, float(theta[p]), self.model.delay_convention)
                s = y_block[:, j].copy()
                gj = g_block[:, j, :].copy()
                y_block[:, j] = s[i1] + c * (s[i0] - s[i1])
                g_block[:, j, :] = gj[i1] + c[:, None] * (gj[i0] - gj[i1])
                g_block[:, j, free_index == p] += (dc * (s[i0] - s[i1]))[:, None]
            outputs[start : start + t.shape[0]] = y_block
            g[start : start + t.shape[0]] = g_block
            start += t.shape[0]
        self.evaluations += 1 + n_states + int(free_index.size)
        self._input_delay_columns(theta, free_index, g)
        return outputs, g

    @staticmethod
    def _function_free(
        theta: np.ndarray, free_index: np.ndarray, theta_map: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """θ_f and the free indices into it for the sensitivity kernel of one maneuver.

        With per-maneuver parameters θ_f = (θ[map], 0): a free parameter that f and h do not
        read in this maneuver (another maneuver's copy) points at the appended dummy slot,
        whose Jacobian columns are zero, so its sensitivity there comes from S(t0) alone.
        """
        if theta_map is None:
            return theta, free_index
        dummy = theta_map.size
        f_theta = np.append(theta[theta_map], 0.0)
        slot = {int(p): s for s, p in enumerate(theta_map)}
        f_free = np.array([slot.get(int(p), dummy) for p in free_index], dtype=np.int64)
        return f_theta, f_free

    def _input_delay_columns(self, theta: np.ndarray, free_index: np.ndarray, g: np.ndarray):
        """Replace, in ``g`` (N, n_o, n_f), the columns of free input-delay parameters by
        central differences of whole simulations (2 equivalent evaluations each):

            ∂y/∂τ ≈ (y(τ + δ) − y(τ − δ)) / (2δ),   δ = 0.01·min Δt

        The sensitivity kernel does not see τ (f and h receive the delayed samples, not τ);
        ũ is piecewise linear in τ with kinks only where t_k − τ crosses a sample time, so a
        step well inside one sample interval gives its slope (docs/method.md, "Time delays").
        """
        columns = [
            (int(j), p)
            for _, p in self.model.input_delay_maps()
            for j in np.flatnonzero(free_index == p)
        ]
        if not columns:
            return
        steps = [np.diff(t) for t in self._times if t.shape[0] > 1]
        delta = 0.01 * min((float(np.min(d)) for d in steps), default=1.0)
        rows = np.repeat(theta[None, :], 2 * len(columns), axis=0)
        for c, (_, p) in enumerate(columns):
            rows[2 * c, p] += delta
            rows[2 * c + 1, p] -= delta
        batch = self.run(rows)
        if batch.diverged.any():
            first = int(np.flatnonzero(batch.diverged)[0])
            raise SimulationError(f"input-delay sensitivity: {batch.messages[first]}")
        for c, (j, _) in enumerate(columns):
            # ∂y/∂τ = (y(τ + δ) − y(τ − δ)) / (2δ)
            g[:, :, j] = (batch.outputs[2 * c] - batch.outputs[2 * c + 1]) / (2.0 * delta)

    def outputs(self, theta: np.ndarray) -> np.ndarray:
        """Outputs (N_total, n_o) for one full parameter vector; raises if it diverges."""
        batch = self.run(np.asarray(theta, dtype=float)[None, :])
        if batch.diverged[0]:
            raise SimulationError(batch.messages[0])
        return batch.outputs[0]


def simulate(
    model: StateSpaceModel,
    data: FlightData | Sequence[FlightData],
    theta: np.ndarray | None = None,
    method: str = "rk4",
    compiled: bool = True,
    input_interpolation: str = "linear",
) -> np.ndarray:
    """Model outputs (N_total, n_o) for parameter vector ``theta`` (default: current values).

    ``method`` and ``input_interpolation`` as in ``Simulator``. Raises ``SimulationError`` if
    the trajectory becomes non-finite.
    """
    simulator = Simulator(
        model, data, method=method, compiled=compiled, input_interpolation=input_interpolation
    )
    theta = model.parameters.values if theta is None else np.asarray(theta, dtype=float)
    return simulator.outputs(theta)
