"""Fixed-step integration kernels: Euler and 4th-order Runge–Kutta at the data interval.

For a batch of B parameter vectors θ_b and initial states x0_b, each kernel integrates

    x_{k+1} = x_k + Δt · f(t_k, x_k, u_k, θ)                        (Euler)

    k1 = f(t_k,        x_k,            u_k,   θ)                      (RK4)
    k2 = f(t_k + Δt/2, x_k + Δt/2·k1,  u_k+½, θ)
    k3 = f(t_k + Δt/2, x_k + Δt/2·k2,  u_k+½, θ)
    k4 = f(t_k + Δt,   x_k + Δt·k3,    u_k+1, θ)
    x_{k+1} = x_k + Δt/6 · (k1 + 2k2 + 2k3 + k4)

and records y_k = h(t_k, x_k, u_k, θ). The input between samples follows the
``input_interpolation`` setting:

    "linear" (default, as the reference tools do): u varies linearly between samples,
             u_k+½ = (u_k + u_{k+1})/2,   u at the end of the step = u_{k+1}
    "zoh"    (zero-order hold): u(t) = u_k on [t_k, t_{k+1}),
             u_k+½ = u_k,                 u at the end of the step = u_k (the left limit)

"linear" suits inputs measured from a continuous signal (a surface deflection sampled by the
data system); "zoh" suits inputs that really are held between samples (a computer-generated
input applied at the sample rate, or data simulated that way). Euler uses u_k only, so both
settings give the same Euler trajectory.

A trajectory whose state or output becomes non-finite stops there; its ``diverged_at`` entry
gives the sample index (−1 where the whole trajectory is finite) and the remaining outputs are
left as NaN for the caller to report — they never reach an estimate.

``make_step`` is the stepping routine (Euler or RK4, with the input rule above) of the
feedback, filter and sensitivity kernels (the latter steps the stacked (x, S) with the
sensitivity equations, ``flightid.simulation.sensitivity``). The plain state kernel writes the
same stages out in its loop, with the same arithmetic (bit-identical results): a call of the
step per sample cost as much as a cheap model's f (measured).

Model functions are called in their out form ``f(t, x, u, θ, out)`` (``flightid.model.forms``);
the stages k1…k4, the stage state and the half-step input live in arrays allocated once per
trajectory, so integrating allocates nothing per step. Batches run their trajectories in a
``prange``: in parallel (``BatchKernel``) for batches of at least ``PARALLEL_MIN_SAMPLES``
samples in all where the parallel variant has measured faster than the serial one
(``VariantTimer``), each trajectory with its own arrays, bit-identical to the serial run.

A model without states (``StateSpaceModel(states=(), f=None, ...)``) is not integrated: its
kernel (``stateless=True``) evaluates y_k = h(t_k, [], u_k, θ) at every sample, with x an
empty float64 array; ``method`` and ``interpolation`` do not matter there.

The same Python source runs compiled (numba ``njit``) or interpreted; ``make_kernel`` builds
both from the user's ``f`` and ``h``. The compiled kernel is kept on disk between runs, keyed
by a digest of the model functions (``flightid.model.kernel_cache``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
from numba import prange

from flightid.model.statespace import no_state_derivative

__all__ = [
    "make_kernel",
    "make_step",
    "step_buffers",
    "record_sample",
    "BatchKernel",
    "VariantTimer",
    "PARALLEL_MIN_SAMPLES",
    "no_state_derivative",
    "EULER",
    "RK4",
    "LINEAR",
    "ZOH",
    "INTERPOLATIONS",
]

EULER = 0
RK4 = 1
# input interpolation between samples (kernel argument ``interpolation``)
LINEAR = 0
ZOH = 1
INTERPOLATIONS = {"linear": LINEAR, "zoh": ZOH}
# the parallel variants run where a call integrates at least this many samples (trajectories ×
# samples, or sensitivity columns × samples): below, the threads' start-up and the parallel
# variant's compilation (several seconds, once per model) cost more than they give
PARALLEL_MIN_SAMPLES = 20_000


def make_step(rate: Callable) -> Callable:
    """The integration step for the out-form ``rate(t, x, u, p, out)`` writing dx/dt into
    ``out`` (``p`` passed through).

    ``step(t, u, k, x, p, method, interpolation, buffers)`` advances x from t[k] to t[k+1]
    in place: Euler, or RK4 with the input between samples by ``interpolation`` (module
    docstring). ``buffers`` = ``step_buffers(n_states, n_inputs)``: the stages k1…k4, the
    stage state and the half-step input, allocated once per trajectory, so the step itself
    allocates nothing.
    """

    def step(t, u, k, x, p, method, interpolation, buffers):
        k1, k2, k3, k4, x_stage, u_mid = buffers
        n = x.shape[0]
        dt = t[k + 1] - t[k]
        uk = u[k]
        if method == EULER:
            rate(t[k], x, uk, p, k1)
            for i in range(n):
                # x_{k+1} = x_k + Δt · f(t_k, x_k, u_k)
                x[i] = x[i] + dt * k1[i]
            return
        if interpolation == ZOH:
            # zero-order hold: u(t) = u_k on [t_k, t_{k+1})
            u_half = uk
            u_end = uk
        else:
            # linear: u_k+½ = (u_k + u_{k+1})/2, u(t_{k+1}) = u_{k+1}
            u_end = u[k + 1]
            for j in range(u_mid.shape[0]):
                u_mid[j] = 0.5 * (uk[j] + u_end[j])
            u_half = u_mid
        half = 0.5 * dt
        rate(t[k], x, uk, p, k1)
        for i in range(n):
            x_stage[i] = x[i] + half * k1[i]
        rate(t[k] + 0.5 * dt, x_stage, u_half, p, k2)
        for i in range(n):
            x_stage[i] = x[i] + half * k2[i]
        rate(t[k] + 0.5 * dt, x_stage, u_half, p, k3)
        for i in range(n):
            x_stage[i] = x[i] + dt * k3[i]
        rate(t[k] + dt, x_stage, u_end, p, k4)
        sixth = dt / 6.0
        for i in range(n):
            # x_{k+1} = x_k + Δt/6 · (k1 + 2k2 + 2k3 + k4)
            x[i] = x[i] + sixth * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])

    return step


def step_buffers(n_states: int, n_inputs: int) -> tuple:
    """Work arrays of ``make_step``: k1, k2, k3, k4, the stage state (n_states each) and the
    half-step input (n_inputs)."""
    return (
        np.empty(n_states),
        np.empty(n_states),
        np.empty(n_states),
        np.empty(n_states),
        np.empty(n_states),
        np.empty(n_inputs),
    )


def record_sample(y, x, y_block, k, n_outputs):
    """Record the outputs ``y`` of sample ``k`` in ``y_block[k]`` (one trajectory's (N, n_o)
    outputs) and check them and the state ``x``: True if all are finite; otherwise the
    trajectory stops here and ``y_block[k:]`` is filled with NaN (False)."""
    finite = True
    for j in range(n_outputs):
        y_block[k, j] = y[j]
        if not math.isfinite(y[j]):
            finite = False
    for j in range(x.shape[0]):
        if not math.isfinite(x[j]):
            finite = False
    if not finite:
        for kk in range(k, y_block.shape[0]):
            for j in range(n_outputs):
                y_block[kk, j] = np.nan
    return finite


def _identity(function: Callable) -> Callable:
    return function


def _fill_nan(y_block, k, n_outputs):
    """``y_block[k:, :n_outputs] = NaN`` (a trajectory stopped at sample k)."""
    for kk in range(k, y_block.shape[0]):
        for j in range(n_outputs):
            y_block[kk, j] = np.nan


def _check_sizes(x0s, n_outputs, y_out, fixed_states, fixed_outputs):
    """Raise ``ValueError`` where a kernel built for ``fixed_states`` states and
    ``fixed_outputs`` outputs (−1: any) is called with other sizes."""
    if fixed_states >= 0 and x0s.shape[1] != fixed_states:
        raise ValueError("kernel: the initial states have another size than the model's states")
    if fixed_outputs >= 0 and (n_outputs != fixed_outputs or y_out.shape[2] != fixed_outputs):
        raise ValueError("kernel: n_outputs differs from the number of the model's outputs")


def _kernel_source(
    f_out: Callable,
    h_out: Callable,
    jit: Callable = _identity,
    n_states: int = -1,
    n_outputs_fixed: int = -1,
) -> Callable:
    """The integration loop over a batch, closed over the out-form model functions (helpers
    passed through ``jit``: numba.njit or the identity). The batch loop is a ``prange``: run
    in parallel when compiled with ``parallel=True``; every trajectory has its own buffers,
    so the results do not depend on how the batch is split.

    ``n_states`` and ``n_outputs_fixed`` (≥ 0) fix the sizes in the compiled code (numba
    freezes closure values): the loops over the states then have a known length, which the
    compiler unrolls (measured 8 % of a 9-state RK4 step); a call with other sizes raises
    ``ValueError``. −1: the sizes are read from the arguments."""
    fill_nan = jit(_fill_nan)
    check_sizes = jit(_check_sizes)

    def kernel(thetas, x0s, t, u, method, interpolation, n_outputs, y_out, diverged_at):
        check_sizes(x0s, n_outputs, y_out, n_states, n_outputs_fixed)
        n_batch = thetas.shape[0]
        n_samples = t.shape[0]
        n_inputs = u.shape[1]
        n_y = n_outputs_fixed if n_outputs_fixed >= 0 else n_outputs
        for b in prange(n_batch):
            theta = thetas[b]
            x = x0s[b].copy()
            n = n_states if n_states >= 0 else x.shape[0]
            y = np.empty(n_y)
            # the stages of make_step, written out here: a call of the step per sample
            # costs as much as a cheap model's f (measured); same arithmetic
            k1 = np.empty(n)
            k2 = np.empty(n)
            k3 = np.empty(n)
            k4 = np.empty(n)
            x_stage = np.empty(n)
            u_mid = np.empty(n_inputs)
            diverged_at[b] = -1
            y_block = y_out[b]
            for k in range(n_samples):
                h_out(t[k], x, u[k], theta, y)
                # record y_k; all of it and the state finite (& does not branch per value)
                finite = True
                for j in range(n_y):
                    y_block[k, j] = y[j]
                    finite = finite & math.isfinite(y[j])
                for i in range(n):
                    finite = finite & math.isfinite(x[i])
                if not finite:
                    # non-finite: the trajectory stops here, its outputs from k on are NaN
                    fill_nan(y_block, k, n_y)
                    diverged_at[b] = k
                    break
                if k == n_samples - 1:
                    break
                dt = t[k + 1] - t[k]
                uk = u[k]
                if method == EULER:
                    f_out(t[k], x, uk, theta, k1)
                    for i in range(n):
                        # x_{k+1} = x_k + Δt · f(t_k, x_k, u_k)
                        x[i] = x[i] + dt * k1[i]
                    continue
                if interpolation == ZOH:
                    u_half = uk
                    u_end = uk
                else:
                    u_end = u[k + 1]
                    for j in range(n_inputs):
                        u_mid[j] = 0.5 * (uk[j] + u_end[j])
                    u_half = u_mid
                half = 0.5 * dt
                f_out(t[k], x, uk, theta, k1)
                for i in range(n):
                    x_stage[i] = x[i] + half * k1[i]
                f_out(t[k] + 0.5 * dt, x_stage, u_half, theta, k2)
                for i in range(n):
                    x_stage[i] = x[i] + half * k2[i]
                f_out(t[k] + 0.5 * dt, x_stage, u_half, theta, k3)
                for i in range(n):
                    x_stage[i] = x[i] + dt * k3[i]
                f_out(t[k] + dt, x_stage, u_end, theta, k4)
                sixth = dt / 6.0
                for i in range(n):
                    # x_{k+1} = x_k + Δt/6 · (k1 + 2k2 + 2k3 + k4)
                    x[i] = x[i] + sixth * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])

    return kernel


def _output_kernel_source(h_out: Callable, jit: Callable = _identity) -> Callable:
    """The batch loop of a model without states: y_k = h(t_k, [], u_k, θ) at every sample
    (no integration; ``method`` and ``interpolation`` are accepted and unused)."""
    record = jit(record_sample)

    def kernel(thetas, x0s, t, u, method, interpolation, n_outputs, y_out, diverged_at):
        n_batch = thetas.shape[0]
        n_samples = t.shape[0]
        for b in prange(n_batch):
            theta = thetas[b]
            x = np.empty(0)
            y = np.empty(n_outputs)
            diverged_at[b] = -1
            for k in range(n_samples):
                # y_k = h(t_k, [], u_k, θ)
                h_out(t[k], x, u[k], theta, y)
                if not record(y, x, y_out[b], k, n_outputs):
                    diverged_at[b] = k
                    break

    return kernel


class BatchKernel:
    """A compiled batch kernel that runs batches of more than one trajectory on the numba
    threads (``parallel=True``, the ``prange`` over trajectories) and single trajectories,
    or everything when numba has one thread, serially. Both variants compute every
    trajectory with the same operations in the same order: the results are bit-identical.

    The parallel variant is used for batches of at least ``min_parallel_samples`` samples
    in all (``PARALLEL_MIN_SAMPLES``) and compiled on the first batch that uses it; if numba
    cannot compile it, the serial one runs instead (a ``CompileWarning`` says so).

    Which variant runs such a batch is decided by their measured speed (``VariantTimer``):
    the threads of the parallel variant wait for each other at the end of the batch, so on
    cores shared with other busy processes (one thread descheduled) it can take longer than
    the serial variant; the batch then runs serially until a probe finds the parallel
    variant faster again.
    """

    def __init__(self, source: Callable) -> None:
        from flightid.model.kernel_cache import cached_njit

        self.source = source
        self.serial = cached_njit(source)
        self.parallel = cached_njit(source, parallel=True)
        # False after the parallel variant failed to compile (or to run batches serially)
        self.parallel_ok = True
        self.parallel_runs = 0
        self.min_parallel_samples = PARALLEL_MIN_SAMPLES
        self.timer = VariantTimer()

    @property
    def stats(self):
        """numba's cache statistics of the serial variant (the one single trajectories use)."""
        return self.serial.stats

    def use_parallel(self, n_batch: int, n_samples: int) -> bool:
        """True if a batch of ``n_batch`` trajectories of ``n_samples`` samples may run on
        the numba threads (whether it does: ``VariantTimer.choose``)."""
        import numba

        return (
            self.parallel_ok
            and n_batch > 1
            and n_batch * n_samples >= self.min_parallel_samples
            and numba.get_num_threads() > 1
        )

    def __call__(self, thetas, *arguments):
        # arguments: x0s, t, u, ...
        work = thetas.shape[0] * arguments[1].shape[0]
        if not self.use_parallel(thetas.shape[0], arguments[1].shape[0]):
            return self.serial(thetas, *arguments)
        parallel = self.timer.choose()
        start = time.perf_counter()
        if parallel:
            self.parallel_ok, result = run_parallel_variant(
                self.parallel, (thetas, *arguments), "batch kernel", "running batches serially"
            )
            if not self.parallel_ok:
                return self.serial(thetas, *arguments)
            self.parallel_runs += 1
        else:
            result = self.serial(thetas, *arguments)
        # the first parallel run compiles (or loads) the variant: not a measure of its speed
        if not (parallel and self.parallel_runs == 1):
            self.timer.record(parallel, (time.perf_counter() - start) / work)
        return result


class VariantTimer:
    """Chooses between a kernel's serial and parallel variant by their measured time per
    sample (equal results either way: only the speed differs).

    Each variant's time per sample is a running mean, m ← m + ``WEIGHT``·(s − m), of its
    recent batches. The parallel variant runs first; then the serial one is measured once;
    after that the faster runs, and every ``PROBE_EVERY``-th batch runs the other one, so a
    change of the machine's load (other processes starting or ending) is followed.
    """

    WEIGHT = 0.3
    PROBE_EVERY = 8

    def __init__(self) -> None:
        self.seconds_per_sample = {True: None, False: None}  # parallel → running mean
        self.calls = 0

    def choose(self) -> bool:
        """True: run the parallel variant."""
        self.calls += 1
        parallel, serial = self.seconds_per_sample[True], self.seconds_per_sample[False]
        if parallel is None or serial is None:
            return parallel is None
        faster = parallel <= serial
        return (not faster) if self.calls % self.PROBE_EVERY == 0 else faster

    def record(self, parallel: bool, seconds_per_sample: float) -> None:
        """Add a measured time per sample (s) of the variant."""
        mean = self.seconds_per_sample[parallel]
        self.seconds_per_sample[parallel] = (
            seconds_per_sample if mean is None else mean + self.WEIGHT * (seconds_per_sample - mean)
        )


def run_parallel_variant(
    parallel: Callable, arguments: tuple, kernel_name: str, fallback: str
) -> tuple[bool, object]:
    """``(True, parallel(*arguments))``, or ``(False, None)`` where numba cannot compile the
    parallel variant: a ``CompileWarning`` (a ``RuntimeWarning``) then names ``kernel_name``
    and the ``fallback``
    (the caller runs its serial variant). Errors that are not numba's propagate."""
    try:
        return True, parallel(*arguments)
    except Exception as exc:  # numba compilation errors have many classes
        if not type(exc).__module__.startswith("numba"):
            raise
        import warnings

        from flightid.errors import CompileWarning

        # a FlightIdWarning: one line "flightid: warning: ..." on the terminal
        warnings.warn(
            f"the parallel {kernel_name} did not compile ({type(exc).__name__}); {fallback}",
            CompileWarning,
            stacklevel=3,
        )
        return False, None


def make_kernel(
    f_out: Callable,
    h_out: Callable,
    compiled: bool = True,
    stateless: bool = False,
    sizes: tuple[int, int] | None = None,
) -> tuple[Callable, bool]:
    """Build the batch kernel for the out-form ``f_out`` and ``h_out`` (``model.f_out``,
    ``model.h_out``; ``stateless``: the model has no states, the kernel evaluates h alone at
    every sample and ``f_out`` is not called).

    Returns ``(kernel, is_compiled)``. With ``compiled=True`` the kernel is numba-compiled if
    numba can compile ``f``, ``h`` and the loop (checked lazily by the first call: see
    ``Simulator``), its machine code is cached on disk (``flightid.model.kernel_cache``), and
    batches of several trajectories run in parallel (``BatchKernel``); with
    ``compiled=False`` it is the same loop in plain Python. ``sizes`` = (n_states,
    n_outputs) fixes them in the compiled state kernel (``_kernel_source``): faster loops.
    """
    from flightid.model.forms import kernel_function, out_form_of

    # functions in return form (the former interface) are adapted
    f_out, h_out = out_form_of(f_out), out_form_of(h_out)
    if not compiled:
        py_h = kernel_function(h_out, False)
        if stateless:
            return _output_kernel_source(py_h), False
        return _kernel_source(kernel_function(f_out, False), py_h), False
    import numba

    jit_h = kernel_function(h_out, True)
    if stateless:
        return BatchKernel(_output_kernel_source(jit_h, numba.njit)), True
    jit_f = kernel_function(f_out, True)
    n_states, n_outputs = sizes if sizes is not None else (-1, -1)
    source = _kernel_source(jit_f, jit_h, numba.njit, int(n_states), int(n_outputs))
    return BatchKernel(source), True
