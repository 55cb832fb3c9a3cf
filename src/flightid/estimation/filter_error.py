"""The filter error method: maximum likelihood with process noise (Jategaonkar ch. 5).

Model (CASES.md §1b):

    ẋ(t) = f(x, u, θ) + F w(t),   F = diag(F_11, …) (parameters),  w: unit white noise
    z_k  = g(x_k, u_k, θ) + v_k

A steady-state Kalman filter runs in every evaluation (a *filter pass*):

    ỹ_k = g(x̃_k, u_k)                  x̃_1 = x0 (each maneuver restarts at its x0)
    e_k = z_k − ỹ_k                     (innovation)
    x̂_k = x̃_k + K e_k                   (correction)
    x̃_{k+1} = RK4 of ẋ = f(x, u) from x̂_k over [t_k, t_{k+1}]   (prediction)

with K = P Cᵀ R⁻¹ and P the stabilising solution of A P + P Aᵀ − (1/Δt) P CᵀR⁻¹C P + FFᵀ = 0
(``flightid.filtering.kalman``), A = ∂f/∂x and C = ∂g/∂x by central differences (Δx = 1e-4)
at the linearisation point (x0 of the first maneuver, u_1: the reference's choice; for a
linear model the point does not matter). R is the weighting, the innovations' covariance.

``FilterErrorProblem`` is an ``OutputErrorProblem`` whose "outputs" are the filtered
predictions ỹ and whose residuals are the innovations: for a given weighting R (held in the
problem as ``gain_r``, used for the gain and the cost), the negative log-likelihood is
Σ eᵀR⁻¹e + const, and every piece of output-error machinery — MNR and MNRES, the halving
search, the Gauss–Newton step and the central-difference confirmation — runs on it
unchanged. One filter pass is one equivalent evaluation.

The constraint diag(KC) ≤ 1 (a larger element would mean a negative measurement-noise
variance, R − CPCᵀ) is enforced by the problem: a θ that violates it gives no filter pass
(it is reported like a diverged simulation, cost +∞), so the step control keeps every
accepted iterate feasible; where the optimum lies on the constraint, the estimator *pins*
the state's F element (``FilterErrorProblem(pinned=...)``: solved for every θ from
diag(KC)_i = 1, no longer free) — an active set, released when lowering the element lowers
the cost. The reference schedule (``relaxation="reference"``) instead corrects each
Gauss–Newton step with the linearised constraint, as CASES.md §1b describes.

R and F are both estimated. The estimate the book defines is the fixed point where θ (system
parameters and F) is Gauss–Newton-optimal under the weighting R and R equals the innovations'
covariance, R = diag((1/N) Σ e_k e_kᵀ). ``relaxation="fixed_point"`` (default) reaches it
directly: converge θ with R held (a well-posed ML problem: R fixed, gain and cost consistent),
set R to the innovations' covariance, repeat until R moves by less than ``r_rtol``. No step
of it needs the book's heuristic F compensation, which only tries to keep K unchanged across
an R update so that a single schedule of steps converges; both schedules stop at the same
fixed point (tests/test_filter_error.py, docs/turbulence.md).
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from flightid.coloured import default_sigma
from flightid.data.flightdata import FlightData
from flightid.errors import EstimationError, InputError, InputTypeError, describe
from flightid.estimation.confirm import confirm_convergence
from flightid.estimation.convergence import Convergence
from flightid.estimation.driver import _covariance, check_call_options
from flightid.estimation.gauss_newton import information_matrix
from flightid.estimation.objective import Objective
from flightid.estimation.problem import OutputErrorProblem
from flightid.estimation.result import Estimate
from flightid.estimation.solvers import MNR, MNRES
from flightid.filtering.kalman import RiccatiError, linearise, steady_state_gain
from flightid.model.check import check_model
from flightid.model.forms import kernel_function, out_form_of
from flightid.model.statespace import StateSpaceModel
from flightid.simulate.kernels import RK4, make_step, record_sample, step_buffers
from flightid.simulate.simulator import SimulationBatch

__all__ = [
    "FilterErrorProblem",
    "FilterPoint",
    "estimate_filter_error",
    "RELAXATIONS",
    "LINEARISATIONS",
    "process_noise_name",
]

RELAXATIONS = ("fixed_point", "reference")
LINEARISATIONS = ("start",)
_METHODS = {"euler": 0, "rk4": RK4}
# diag(KC) may exceed 1 by this much before a θ counts as infeasible (round-off)
KC_TOLERANCE = 1e-6


def process_noise_name(state_index: int) -> str:
    """Default name of the process-noise element on state number ``state_index`` (0-based):
    F11, F22, … (the reference's names)."""
    return f"F{state_index + 1}{state_index + 1}"


def _filter_source(f_out: Callable, h_out: Callable, jit: Callable = lambda fn: fn) -> Callable:
    """The filter-pass loop over a batch, closed over the out-form model functions (no
    allocation per step: ``flightid.simulate.kernels``)."""
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


_FILTER_KERNELS: dict[tuple, tuple] = {}


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

        from flightid.simulate.cache import cached_njit

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
    times, inputs, measured = [], [], []
    for maneuver in maneuvers:
        times.append(np.ascontiguousarray(maneuver.time, dtype=float))
        u = (
            np.column_stack([maneuver.channel(n) for n in model.inputs])
            if model.inputs
            else np.zeros((maneuver.n_samples, 0))
        )
        inputs.append(np.ascontiguousarray(u, dtype=float))
        measured.append(
            np.ascontiguousarray(np.column_stack([maneuver.output(n) for n in model.outputs]))
        )
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


@dataclass
class _Trace:
    """Histories over all cycles and active sets."""

    costs: list[float] = field(default_factory=list)
    evaluations: list[int] = field(default_factory=list)
    r_updates: list[int] = field(default_factory=list)
    iterations: int = 0
    cycles: int = 0
    passes: int = 0  # filter passes of the problems already finished

    def record(self, objective: Objective, problem: FilterErrorProblem) -> None:
        self.r_updates.append(len(self.costs))
        self.costs.extend(objective.cost_history)
        self.evaluations.extend(self.passes + e for e in objective.evaluation_history)


@dataclass
class _Outcome:
    """Where an estimation ended, in the terms ``estimate_filter_error`` reports."""

    problem: FilterErrorProblem
    full: np.ndarray  # full parameter vector (pinned F elements solved)
    outputs: np.ndarray
    r_diag: np.ndarray
    sensitivities: np.ndarray  # G over the free parameters of ``problem``
    accuracy_evaluations: int
    sigma: float
    converged: bool
    status: str
    message: str
    pinned: tuple[str, ...] = ()


def _check_solver(solver):
    solver = MNR() if solver is None else solver
    if not isinstance(solver, (MNR, MNRES)):
        raise InputTypeError(
            f"solver: the filter error method runs with MNR() or MNRES(), got {describe(solver)}"
        )
    if isinstance(solver, MNR) and solver.sensitivities != "differences":
        raise InputError(
            "solver: MNR(sensitivities='equations') is for output error; the filter error "
            "method uses finite differences of filter passes"
        )
    return solver


def _cycles(problem, solver, r_diag, convergence, r_rtol, max_cycles, progress, trace):
    """Converge θ with R held, set R to the innovations' covariance, repeat.

    Returns (theta, confirmation, R, state, message) with state "converged", "stuck" (a
    cycle did not converge) or "max_cycles".
    """
    theta = problem.theta_start
    r_diag = np.array(r_diag, dtype=float)
    change = float("nan")
    for _cycle in range(1, max_cycles + 1):
        problem.gain_r = r_diag.copy()
        objective = Objective(problem, r_diag, "fixed", convergence, progress)
        outcome = solver.minimize(objective, theta)
        confirmation = confirm_convergence(
            objective, outcome, "fixed", fallback=isinstance(solver, MNRES)
        )
        trace.iterations += outcome.iterations + confirmation.passes
        trace.cycles += 1
        trace.record(objective, problem)
        final = confirmation.outcome
        theta = final.theta
        if not final.converged:
            return theta, confirmation, r_diag, "stuck", final.message
        r_new = problem.noise_covariance(final.outputs)
        # largest relative change of an innovation variance: R has settled when ≤ r_rtol
        change = float(np.max(np.abs(r_new - r_diag) / r_diag))
        if change <= r_rtol:
            message = (
                "converged: θ Gauss–Newton-optimal under R, and R equal to the innovations' "
                f"covariance within {change:.2g} (relative; tolerance {r_rtol:g})"
            )
            return theta, confirmation, r_diag, "converged", message
        theta = _compensated_start(problem, theta, r_diag, r_new)
        r_diag = r_new
    message = f"R did not settle within {max_cycles} cycles (last relative change {change:.3g})"
    return theta, confirmation, r_diag, "max_cycles", message


def _compensated_start(
    problem: FilterErrorProblem, theta: np.ndarray, r_old: np.ndarray, r_new: np.ndarray
) -> np.ndarray:
    """Start values of the next cycle: the free F elements rescaled for the new R so that
    the gain stays about the same (the reference's compensation formula, used here only to
    give the next cycle a feasible, nearby start — the cycle then converges under the new R):

        F_jj ← F_jj · Σ_i C_ij² r_i,old⁻¹ (r_i,new/r_i,old)^½ / Σ_i C_ij² r_i,old⁻¹

    If the gain still violates diag(KC) ≤ 1 there, the free F elements are halved (at most
    20 times) until it does not.
    """
    full = problem.full_theta(theta)
    c2 = problem.filter_point(full, r_old).c ** 2
    theta = np.array(theta, dtype=float)
    free = list(problem.free_index)
    moved = []
    for state, parameter in zip(problem.noise_states, problem.noise_parameters, strict=True):
        if parameter not in free:
            continue
        weights = c2[:, state] / r_old
        if np.sum(weights) <= 0:
            continue
        # F_jj ← F_jj Σ_i C_ij² r_i⁻¹ (r_i,new/r_i)^½ / Σ_i C_ij² r_i⁻¹
        theta[free.index(parameter)] *= np.sum(weights * np.sqrt(r_new / r_old)) / np.sum(weights)
        moved.append(free.index(parameter))
    for _ in range(20):
        try:
            kc = problem.filter_point(problem.full_theta(theta), r_new).kc
        except RiccatiError:
            kc = np.full(1, np.inf)
        if np.all(kc <= 1.0) or not moved:
            break
        theta[moved] *= 0.5
    return theta


def _problem(model, data, process_noise, pinned, values, settings) -> FilterErrorProblem:
    """The problem with the pinned states' F elements fixed (solved from diag(KC) = 1)."""
    parameters = model.parameters.with_values(values)
    names = [process_noise[s] for s in pinned]
    if names:
        parameters = parameters.with_free(names, False)
    return _new_problem(
        model.with_parameters(parameters), data, process_noise, settings, pinned=pinned
    )


#: how the filter error method gets H = ∂ỹ/∂θ: finite differences of filter passes, or
#: analytic for models linear in states and inputs (flightid.estimation.filter_error_linear)
GRADIENTS = ("differences", "analytic")


def _new_problem(model, data, process_noise, settings, **extra) -> FilterErrorProblem:
    """``FilterErrorProblem``, or ``LinearFilterErrorProblem`` for gradients = "analytic"."""
    settings = dict(settings)
    if settings.pop("gradients", "differences") == "analytic":
        from flightid.estimation.filter_error_linear import LinearFilterErrorProblem

        return LinearFilterErrorProblem(model, data, process_noise, **settings, **extra)
    return FilterErrorProblem(model, data, process_noise, **settings, **extra)


def _fixed_point(
    model,
    data,
    process_noise,
    solver,
    r_start,
    convergence,
    r_rtol,
    max_cycles,
    progress,
    trace,
    settings,
) -> _Outcome:
    """Fixed-point relaxation with an active set for diag(KC) ≤ 1.

    A state whose diag(KC) element reaches 1 while the cycle cannot converge becomes
    *pinned*: its F element is solved from diag(KC)_i = 1 for every θ, so the constraint
    holds exactly and the remaining parameters are estimated without it. A pinned element is
    released again when lowering it lowers the cost (the constraint's multiplier has the
    wrong sign). The loop ends when no state joins or leaves.
    """
    states = list(process_noise)
    free_noise = [s for s in states if model.parameters[process_noise[s]].free]
    pinned: list[str] = []
    values = model.parameters.values
    r_diag = np.array(r_start, dtype=float)
    message = ""
    for _ in range(2 * len(states) + 3):
        problem = _problem(model, data, process_noise, pinned, values, settings)
        problem.gain_r = r_diag.copy()
        theta, confirmation, r_diag, state, message = _cycles(
            problem, solver, r_diag, convergence, r_rtol, max_cycles, progress, trace
        )
        trace.passes += problem.evaluations
        full = problem.complete(problem.full_theta(theta), r_diag)
        values = full
        kc = problem.filter_point(full, r_diag).kc
        if state == "stuck":
            candidates = [
                s
                for s in free_noise
                if s not in pinned and kc[problem.model.states.index(s)] > 1.0 - 1e-3
            ]
            if candidates:
                pinned.append(max(candidates, key=lambda s: kc[problem.model.states.index(s)]))
                continue
            break
        if state != "converged":
            break
        # release a pinned element whose decrease lowers the cost
        outputs = confirmation.outcome.outputs
        cost = float(problem.cost(outputs, r_diag))
        released = None
        for s in pinned:
            index = model.parameters.index(process_noise[s])
            trial_values = full.copy()
            trial_values[index] *= 1.0 - 1e-3
            rest = [p for p in pinned if p != s]
            trial = _problem(model, data, process_noise, rest, trial_values, settings)
            trial.gain_r = r_diag.copy()
            trial_batch = trial.run(trial.theta_start)
            trace.passes += trial.evaluations
            if (
                not trial_batch.diverged[0]
                and float(trial.cost(trial_batch.outputs[0], r_diag)) < cost
            ):
                released = s
                break
        if released is None:
            break
        pinned.remove(released)
        values = full
    outcome = confirmation.outcome
    converged = state == "converged"
    status = "converged" if converged else outcome.status
    if not converged and status == "converged":
        status = "max_iterations"
    if pinned:
        names = [process_noise[s] for s in pinned]
        message += (
            f"; the constraint diag(KC) ≤ 1 is active for {pinned}: {names} solved from "
            "diag(KC)_i = 1 (their bounds by the delta method)"
        )
    return _Outcome(
        problem,
        full,
        outcome.outputs,
        r_diag,
        confirmation.sensitivities,
        confirmation.sensitivity_evaluations,
        confirmation.sigma,
        converged,
        status,
        message,
        tuple(pinned),
    )


def _reference(problem, r_start, progress, trace) -> _Outcome:
    from flightid.estimation.filter_reference import reference_relaxation

    run = reference_relaxation(problem, r_start, progress)
    trace.costs, trace.evaluations = run.cost_history, run.evaluation_history
    trace.iterations, trace.cycles, trace.r_updates = run.iterations, run.r_updates, []
    trace.passes = problem.evaluations
    status = "converged" if run.converged else "max_iterations"
    return _Outcome(
        problem,
        problem.full_theta(run.theta),
        run.outputs,
        run.r_diag,
        run.sensitivities,
        0,
        float("nan"),
        run.converged,
        status,
        run.message,
    )


def _pinned_jacobian(outcome: _Outcome, model: StateSpaceModel) -> np.ndarray:
    """T (n_f × n_r): ∂(originally free parameters)/∂(free parameters of the last problem);
    identity rows for the free ones, ∂F_ii/∂θ_r for a pinned element (finite differences of
    the constraint solution, no filter pass)."""
    problem = outcome.problem
    original = np.flatnonzero(model.parameters.free_mask)
    reduced = problem.free_index
    theta = outcome.full[reduced]
    base = problem.complete(outcome.full, outcome.r_diag)
    t = np.zeros((original.size, reduced.size))
    for j, index in enumerate(reduced):
        t[list(original).index(index), j] = 1.0
    pinned = [problem.noise_parameters[i] for i in problem.pinned]
    for j in range(reduced.size):
        step = 1e-6 * max(abs(theta[j]), problem.typical[j])
        moved = outcome.full.copy()
        moved[reduced[j]] += step
        moved = problem.complete(moved, outcome.r_diag)
        for index in pinned:
            # ∂F_ii/∂θ_j ≈ (F_ii(θ + δ e_j) − F_ii(θ)) / δ
            t[list(original).index(index), j] = (moved[index] - base[index]) / step
    return t


def _pinned_weighting_covariance(outcome: _Outcome, model: StateSpaceModel) -> np.ndarray:
    """The covariance (n_f × n_f, original free parameters) a pinned F element takes from the
    estimated weighting R, which the delta method over θ alone leaves out.

    A pinned element is solved from diag(KC)_i = 1 at the estimated R, so it moves with R̂
    (for a directly measured state F_ii ≈ √(R_ii/Δt): half of R̂'s relative error). R̂ is the
    innovations' covariance, R̂_i = (1/N) Σ_k e_ik², whose variance for Gaussian innovations
    is 2 R_i²/N; its error is uncorrelated with θ̂'s to first order:

        Cov_R = J_R diag(2 R²/N) J_Rᵀ,   J_R = ∂F_pin/∂R (finite differences of the
        constraint solution, no filter pass)
    """
    problem = outcome.problem
    original = list(np.flatnonzero(model.parameters.free_mask))
    r_diag = np.asarray(outcome.r_diag, dtype=float)
    base = problem.complete(outcome.full, r_diag)
    pinned = [problem.noise_parameters[i] for i in problem.pinned]
    jacobian = np.zeros((len(original), r_diag.size))
    for i in range(r_diag.size):
        step = 1e-6 * r_diag[i]
        moved_r = r_diag.copy()
        moved_r[i] += step
        moved = problem.complete(outcome.full, moved_r)
        for index in pinned:
            # ∂F_pin/∂R_i ≈ (F_pin(R + δ e_i) − F_pin(R)) / δ
            jacobian[original.index(index), i] = (moved[index] - base[index]) / step
    # Var(R̂_i) = 2 R_i² / N
    variance_r = 2.0 * r_diag**2 / problem.n_samples
    return (jacobian * variance_r) @ jacobian.T


def estimate_filter_error(
    model: StateSpaceModel,
    data: FlightData | Sequence[FlightData],
    process_noise: Mapping[str, str],
    solver: MNR | MNRES | None = None,
    *,
    relaxation: str = "fixed_point",
    method: str = "rk4",
    input_interpolation: str = "linear",
    linearisation: str = "start",
    convergence: Convergence | None = None,
    r_rtol: float = 1e-4,
    max_cycles: int = 30,
    compiled: bool = True,
    progress: Callable[[int, int, float], None] | None = None,
    gradients: str = "differences",
) -> Estimate:
    """Filter-error maximum-likelihood estimate (system parameters and F elements).

    Args:
        model: the model; its parameters include the process-noise elements (e.g. F11).
        data: one maneuver or a list (same sampling interval).
        process_noise: {state: parameter name} of the diagonal F.
        solver: ``MNR()`` (default) or ``MNRES()`` (``relaxation="fixed_point"``); the
            reference schedule always takes its own forward-difference Gauss–Newton steps.
        relaxation: ``"fixed_point"`` (converge θ under R, update R, repeat until R settles;
            the constraint by an active set) or ``"reference"`` (the reference tool's
            schedule: R₀ for 3 steps, then an R update with F compensation after every
            step, linearised constraint; CASES.md §1b).
        method, input_interpolation: integration as in ``estimate``.
        linearisation: where A and C are taken (``"start"``: x0, u_1).
        convergence: the solver's stopping rules (default ``Convergence()``).
        r_rtol: ``fixed_point``: R has settled when no variance changes by more than this
            fraction in a cycle.
        max_cycles: ``fixed_point``: R updates at most (per active set).
        compiled: numba filter kernel.
        progress: called after every accepted pass with (pass, filter passes, cost).
        gradients: ``"differences"`` (H by finite differences of filter passes) or
            ``"analytic"``: a model linear in states and inputs, filtered with the exact
            discretisation Φ = e^{AΔt}, H from the differentiated Riccati equation and
            filter recursion (``LinearFilterErrorProblem``; docs/turbulence.md).

    Returns:
        An ``Estimate``: ``predicted`` are the filtered outputs ỹ, ``residuals`` the
        innovations, ``r_diag`` the final weighting R (the innovations' covariance),
        ``cost`` = Σ eᵀR⁻¹e under it, ``equivalent_evaluations`` the filter passes of the
        optimiser, the Cramér–Rao bounds √diag(M⁻¹) with M from the sensitivities of the
        filtered outputs at θ̂ (central differences; the reference schedule: its last
        forward-difference step, CASES.md Q14); ``noise_policy`` is
        ``"filter_error/<relaxation>"`` and the message gives det R and diag(KC).
    """
    if not isinstance(model, StateSpaceModel):
        raise InputTypeError(f"model: expected a StateSpaceModel, got {describe(model)}")
    if relaxation not in RELAXATIONS:
        raise InputError(f"relaxation: expected one of {list(RELAXATIONS)}, got {relaxation!r}")
    solver = _check_solver(solver)
    convergence = Convergence() if convergence is None else convergence
    if not isinstance(convergence, Convergence):
        raise InputTypeError(f"convergence: expected a Convergence, got {describe(convergence)}")
    check_call_options(compiled, progress)
    started = _time.perf_counter()
    check_model(model, data, method=method)
    settings = {
        "method": method,
        "compiled": compiled,
        "input_interpolation": input_interpolation,
        "linearisation": linearisation,
    }
    if gradients not in GRADIENTS:
        raise InputError(f"gradients: expected one of {list(GRADIENTS)}, got {gradients!r}")
    settings["gradients"] = gradients
    problem = _new_problem(model, data, process_noise, settings)
    problem.check_enough_data()
    # R₀: one pass with K = 0 (a plain simulation) at the start values
    r_start = problem.noise_covariance(problem.simulate(problem.theta_start))
    trace = _Trace()
    if relaxation == "reference":
        outcome = _reference(problem, r_start, progress, trace)
        solver_name = "mnr"
        solver_settings = {"relative_step": 1e-4, "schedule": "reference (ml_fem2)"}
    else:
        trace.passes = problem.evaluations
        outcome = _fixed_point(
            model,
            data,
            process_noise,
            solver,
            r_start,
            convergence,
            r_rtol,
            max_cycles,
            progress,
            trace,
            settings,
        )
        solver_name, solver_settings = solver.name, solver.settings()
    last = outcome.problem
    r_diag, outputs, full = outcome.r_diag, outcome.outputs, outcome.full
    point = last.filter_point(full, r_diag)
    det_r = float(np.prod(last.noise_covariance(outputs)))
    filter_passes = trace.passes
    message = outcome.message + (
        f"; det R = {det_r:.6g} (innovations), diag(KC) = "
        f"{np.array2string(point.kc, precision=4)}, {filter_passes} filter passes"
    )
    if relaxation == "reference" and np.any(point.kc > 1.0 - 1e-3):
        message += "; the constraint diag(KC) ≤ 1 is active"
    m_reduced = information_matrix(outcome.sensitivities, r_diag)
    covariance_r, std_r, undetermined = _covariance(m_reduced, np.zeros(last.n_free, dtype=bool))
    free_mask = model.parameters.free_mask
    n_f = int(free_mask.sum())
    if outcome.pinned:
        # Cov = T Cov_r Tᵀ (delta method for the F elements solved from the constraint)
        t = _pinned_jacobian(outcome, model)
        # the pinned elements also move with R̂: Cov = T Cov_r Tᵀ + J_R Cov(R̂) J_Rᵀ
        covariance_weighting = _pinned_weighting_covariance(outcome, model)
        covariance = t @ covariance_r @ t.T + covariance_weighting
        std_free = np.sqrt(np.maximum(np.diag(covariance), 0.0))
        m = np.linalg.pinv(covariance)
        g = np.zeros((last.n_samples, last.n_outputs, n_f))
        g[:, :, np.any(t[:, :] == 1.0, axis=1)] = outcome.sensitivities
    else:
        covariance, std_free, m, g = covariance_r, std_r, m_reduced, outcome.sensitivities
    if undetermined:
        names = [last.free_names[j] for j in undetermined]
        message += f"; the information matrix is singular: {names} cannot be determined"
    # free process-noise elements: their bound treats the weighting R as known although the
    # gain depends on it; measured (bench/sigma_coverage.py, filter_error: F11 spread 1.26 σ,
    # 2σ coverage 0.83) it is somewhat optimistic
    free_process_noise = [
        name
        for state, name in last.process_noise.items()
        if name in model.parameters.free_names and state not in outcome.pinned
    ]
    if free_process_noise:
        message += (
            f"; the σ of the process-noise parameters {free_process_noise} may be up to about "
            "1.3× too small (their bound takes R as known)"
        )
    residuals = last.residuals(outputs)
    # the default σ from the innovations: Cramér–Rao when white, coloured-residual otherwise
    sigma = default_sigma(
        outcome.sensitivities, residuals, r_diag, covariance_r, last.maneuver_index
    )
    covariance_default = sigma.covariance
    if outcome.pinned:
        # Cov = T Cov_r Tᵀ + J_R Cov(R̂) J_Rᵀ for the default covariance as for the
        # Cramér–Rao one (the pinned elements move with R̂ whatever the residuals' colour)
        covariance_default = t @ covariance_default @ t.T + covariance_weighting
    std_cr = np.full(full.shape, np.nan)
    std_cr[free_mask] = std_free
    std = np.full(full.shape, np.nan)
    std[free_mask] = np.sqrt(np.maximum(np.diag(covariance_default), 0.0))
    std[free_mask] = np.where(np.isfinite(std_free), std[free_mask], std_free)
    estimated_model = model.with_parameters(model.parameters.with_values(full))
    accuracy = outcome.accuracy_evaluations
    return Estimate(
        names=tuple(model.parameters.names),
        values=full,
        initial=model.parameters.values,
        free=free_mask,
        std=std,
        std_cr=std_cr,
        std_kind=sigma.kind,
        residuals_white=sigma.residuals_white,
        coloured_lag=sigma.lag,
        covariance=covariance,
        covariance_default=covariance_default,
        information_matrix=m,
        sensitivities=g,
        r_diag=np.asarray(r_diag, dtype=float),
        cost=float(last.cost(outputs, r_diag)),
        cost_history=tuple(trace.costs),
        evaluation_history=tuple(trace.evaluations),
        noise_update_passes=tuple(trace.r_updates[1:]),
        equivalent_evaluations=int(filter_passes - accuracy),
        accuracy_evaluations=int(accuracy),
        iterations=int(trace.iterations),
        noise_cycles=int(trace.cycles),
        converged=bool(outcome.converged),
        status=outcome.status,
        message=message,
        time=last.time,
        measured=last.measured,
        predicted=outputs,
        residuals=residuals,
        maneuver_index=last.maneuver_index,
        output_names=tuple(model.outputs),
        output_units=tuple(
            next((m.units[n] for m in last.maneuvers if m.units.get(n)), "") for n in model.outputs
        ),
        solver=solver_name,
        solver_settings=solver_settings,
        noise_policy=f"filter_error/{relaxation}",
        method=method,
        input_interpolation=input_interpolation,
        wall_time_s=_time.perf_counter() - started,
        model=estimated_model,
        optimality_sigma=outcome.sigma,
    )
