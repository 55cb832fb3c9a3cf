"""Output sensitivities by integrating the sensitivity equations alongside the states.

For S = ∂x/∂θ (n_s × n_f, the free parameters) [RP-1153 §6, "analytic" MNR]:

    dS/dt = f_x S + f_θ,        S(t0) = ∂x0/∂θ
    G_i   = ∂y_i/∂θ = h_x S_i + h_θ

integrated with the same fixed-step scheme as the states (Euler or RK4, the input between
samples by the same ``input_interpolation`` rule as ``flightid.simulation.kernels``: "linear",
u at the half step the mean of the neighbouring samples, or "zoh", u held at u_k). The
Jacobians f_x, f_θ, h_x, h_θ come from forward differences of the user's f and h at every
stage (step ``relative_step`` × max(|v|, 1) for a state, × max(|θ_j|, typical_j) for a
parameter), so no derivative has to be written by hand; the sensitivities are those of the
*continuous* equations, not differences of two finished trajectories.

Cost: each stage evaluates f (and each sample h) 1 + n_s + n_f times instead of once, so one
pass counts as 1 + n_s + n_f equivalent evaluations — about n_s more than finite-difference
MNR. The gain is accuracy of G (no difference of nearly equal trajectories), not speed.

The kernel allocates nothing per step: f and h are called in their out form
(``flightid.model.forms``), the Jacobian columns, the stacked state and the RK4 stages live
in buffers allocated once per call. The columns of S are independent given the state
trajectory (dS_j/dt = f_x S_j + f_θj), so the free parameters are split into blocks that are
integrated side by side on the numba threads (``prange`` over blocks, ``SensitivityKernel``):
each block steps the state and f_x again (1 + n_s evaluations of f per stage) and its own
f_θ columns. Every column is computed with the same operations in the same order whatever
the split, so the result is bit-identical to one block.

The same kernel applies the state correction of the stabilised output error
(``flightid.simulation.feedback``) when it is given a gain.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import prange

from flightid.simulation.kernels import (
    PARALLEL_MIN_SAMPLES,
    _identity,
    make_step,
    record_sample,
    run_parallel_variant,
    step_buffers,
)

__all__ = ["make_sensitivity_kernel", "SensitivityKernel"]


def _jacobian(fun_out: Callable) -> Callable:
    """(∂fun/∂x, ∂fun/∂θ_free) by forward differences about ``base`` = fun(t, x, u, θ), into
    ``jx`` (m × n_s) and ``jt`` (m × n_f); ``xp``, ``tp``, ``col`` are work arrays (n_s,
    len θ, m)."""

    def jacobians(t, x, u, theta, free_index, steps, rel, base, jx, jt, xp, tp, col):
        n_s = x.shape[0]
        n_f = free_index.shape[0]
        m = base.shape[0]
        for j in range(n_s):
            xp[j] = x[j]
        for j in range(n_s):
            d = rel * max(abs(x[j]), 1.0)
            xp[j] = x[j] + d
            fun_out(t, xp, u, theta, col)
            for i in range(m):
                # ∂fun_i/∂x_j ≈ (fun_i(x + d e_j) − fun_i(x))/d
                jx[i, j] = (col[i] - base[i]) / d
            xp[j] = x[j]
        for j in range(theta.shape[0]):
            tp[j] = theta[j]
        for j in range(n_f):
            d = steps[j]
            q = free_index[j]
            tp[q] = theta[q] + d
            fun_out(t, x, u, tp, col)
            for i in range(m):
                # ∂fun_i/∂θ_j ≈ (fun_i(θ + d e_j) − fun_i(θ))/d
                jt[i, j] = (col[i] - base[i]) / d
            tp[q] = theta[q]

    return jacobians


def _rates(f_out: Callable, jac_f: Callable) -> Callable:
    """The right-hand side of the stacked state and sensitivity equations (out form)."""

    def rates(t, z, u, p, dz):
        """dz/dt = (dx/dt, dS/dt = f_x S + f_θ) into ``dz``, with p = (θ, free_index, steps,
        rel, and the work arrays of the Jacobian)."""
        theta, free_index, steps, rel, jx, jt, xp, tp, col = p
        n_f = free_index.shape[0]
        n_s = z.shape[0] // (1 + n_f)
        x = z[:n_s]
        dx = dz[:n_s]
        f_out(t, x, u, theta, dx)
        jac_f(t, x, u, theta, free_index, steps, rel, dx, jx, jt, xp, tp, col)
        for i in range(n_s):
            for j in range(n_f):
                acc = 0.0
                for k in range(n_s):
                    acc += jx[i, k] * z[n_s + k * n_f + j]
                # (dS/dt)_ij = (f_θ)_ij + Σ_k (f_x)_ik S_kj
                dz[n_s + i * n_f + j] = jt[i, j] + acc

    return rates


def _integrate_source(
    h_out: Callable, jac_h: Callable, step: Callable, record: Callable, buffers_for: Callable
) -> Callable:
    """One block of sensitivity columns: the states and S[:, block] stepped together."""

    def integrate(
        theta, x0, s0, free_index, steps, rel, t, u, method, interpolation, n_outputs, y_out,
        g_out, z, gain,
    ):  # fmt: skip
        n_s = x0.shape[0]
        n_f = free_index.shape[0]
        n_theta = theta.shape[0]
        stabilize = gain.shape[0] > 0
        # zz = (x, S row by row)
        zz = np.empty(n_s * (1 + n_f))
        for i in range(n_s):
            zz[i] = x0[i]
            for j in range(n_f):
                zz[n_s + i * n_f + j] = s0[i, j]
        # work arrays, once per call: outputs, h_x, h_θ and those of the Jacobians
        y = np.empty(n_outputs)
        hx = np.empty((n_outputs, n_s))
        ht = np.empty((n_outputs, n_f))
        h_xp = np.empty(n_s)
        h_tp = np.empty(n_theta)
        h_col = np.empty(n_outputs)
        p = (
            theta,
            free_index,
            steps,
            rel,
            np.empty((n_s, n_s)),
            np.empty((n_s, n_f)),
            np.empty(n_s),
            np.empty(n_theta),
            np.empty(n_s),
        )
        buffers = buffers_for(zz.shape[0], u.shape[1])
        n_samples = t.shape[0]
        for k in range(n_samples):
            x = zz[:n_s]
            uk = u[k]
            h_out(t[k], x, uk, theta, y)
            jac_h(t[k], x, uk, theta, free_index, steps, rel, y, hx, ht, h_xp, h_tp, h_col)
            for i in range(n_outputs):
                for j in range(n_f):
                    # G = h_x S + h_θ
                    acc = ht[i, j]
                    for m in range(n_s):
                        acc += hx[i, m] * zz[n_s + m * n_f + j]
                    g_out[k, i, j] = acc
            if not record(y, x, y_out, k, n_outputs):
                return k
            if k == n_samples - 1:
                break
            if stabilize:
                for i in range(n_s):
                    acc = 0.0
                    for o in range(n_outputs):
                        acc += gain[i, o] * (z[k, o] - y[o])
                    # x_k ← x_k + S (z_k − y_k)
                    zz[i] += acc
                    for j in range(n_f):
                        acc = 0.0
                        for o in range(n_outputs):
                            acc += gain[i, o] * g_out[k, o, j]
                        # ∂x_k/∂θ ← ∂x_k/∂θ − S G_k
                        zz[n_s + i * n_f + j] -= acc
            step(t, u, k, zz, p, method, interpolation, buffers)
        return -1

    return integrate


def _build(f_out: Callable, h_out: Callable, jit: Callable) -> Callable:
    """The kernel, with every helper passed through ``jit`` (numba.njit or the identity).

    The states and sensitivities are stepped together as one vector z = (x, vec S) (S row by
    row) by the state kernel's own ``make_step``, so Euler / RK4 and the input rule are those
    of ``flightid.simulation.kernels``; the free parameters are split into ``n_blocks`` blocks
    (a ``prange``: in parallel where compiled with ``parallel=True``).
    """
    jac_h = jit(_jacobian(h_out))
    rates = jit(_rates(f_out, jit(_jacobian(f_out))))
    step = jit(make_step(rates))
    integrate = jit(_integrate_source(h_out, jac_h, step, jit(record_sample), jit(step_buffers)))

    def kernel(
        theta, x0, s0, free_index, steps, rel, t, u, method, interpolation, n_outputs, y_out,
        g_out, z, gain, n_blocks,
    ):  # fmt: skip
        n_f = free_index.shape[0]
        flags = np.empty(n_blocks, dtype=np.int64)
        for block in prange(n_blocks):
            first = block * n_f // n_blocks
            last = (block + 1) * n_f // n_blocks
            # every block computes the same outputs; the first one records them
            y_block = y_out if block == 0 else np.empty_like(y_out)
            flags[block] = integrate(
                theta, x0, s0[:, first:last], free_index[first:last], steps[first:last], rel,
                t, u, method, interpolation, n_outputs, y_block, g_out[:, :, first:last], z,
                gain,
            )  # fmt: skip
        flag = -1
        for block in range(n_blocks):
            if flags[block] >= 0 and (flag < 0 or flags[block] < flag):
                flag = flags[block]
        return flag

    return kernel


class SensitivityKernel:
    """The sensitivity kernel with the column blocks on the numba threads where there are
    several threads, at least two free parameters and at least ``min_parallel_samples``
    (``PARALLEL_MIN_SAMPLES``) samples × free parameters (bit-identical to one block, module
    docstring).

    ``kernel(theta, x0, s0, free_index, steps, rel, t, u, method, interpolation, n_outputs,
    y_out, g_out)`` or, stabilised, ``(..., g_out, z, gain)`` with the measured outputs ``z``
    (N, n_o) and the gain (n_s, n_o); returns −1 or the sample index at which the state or
    the outputs became non-finite.
    """

    def __init__(self, source: Callable, compiled: bool) -> None:
        self.compiled = compiled
        if compiled:
            from flightid.model.kernel_cache import cached_njit

            self.serial = cached_njit(source)
            self.parallel = cached_njit(source, parallel=True)
        else:
            self.serial = self.parallel = source
        self._parallel_ok = compiled
        self.min_parallel_samples = PARALLEL_MIN_SAMPLES

    @property
    def stats(self):
        """numba's cache statistics of the serial (one-block) variant."""
        return self.serial.stats

    def n_blocks(self, n_free: int, n_samples: int) -> int:
        """Blocks of columns for ``n_free`` free parameters and ``n_samples`` samples: one per
        numba thread, at most one per parameter (1 where the parallel kernel is not used)."""
        if not self._parallel_ok or n_free * n_samples < self.min_parallel_samples:
            return 1
        import numba

        return max(1, min(numba.get_num_threads(), n_free))

    def __call__(self, *arguments):
        if len(arguments) == 13:
            # no state correction: an empty gain
            arguments = (*arguments, np.zeros((0, 0)), np.zeros((0, 0)))
        n_blocks = self.n_blocks(arguments[3].shape[0], arguments[6].shape[0])
        if n_blocks > 1:
            self._parallel_ok, result = run_parallel_variant(
                self.parallel, (*arguments, n_blocks), "sensitivity kernel", "running it serially"
            )
            if self._parallel_ok:
                return result
        return self.serial(*arguments, 1)


def make_sensitivity_kernel(f_out: Callable, h_out: Callable, compiled: bool = True) -> Callable:
    """The sensitivity kernel for the out-form ``f_out`` and ``h_out`` (``model.f_out``,
    ``model.h_out``): numba-compiled (its machine code cached on disk,
    ``flightid.model.kernel_cache``), or the same loop in Python.

    ``kernel(theta, x0, s0, free_index, steps, rel, t, u, method, interpolation, n_outputs,
    y_out, g_out)`` (``method``: 0 Euler, 1 RK4; ``interpolation``: 0 linear, 1 zoh)
    fills y_out (N, n_o) and g_out (N, n_o, n_f) and returns −1, or the sample index at which
    the state or the outputs became non-finite. Given also ``z`` and ``gain`` it applies the
    state correction of the stabilised output error (``flightid.simulation.feedback``).
    """
    from flightid.model.forms import kernel_function, out_form_of

    # functions in return form (the former interface) are adapted
    f_out, h_out = out_form_of(f_out), out_form_of(h_out)
    if not compiled:
        source = _build(kernel_function(f_out, False), kernel_function(h_out, False), _identity)
        return SensitivityKernel(source, False)
    import numba

    source = _build(kernel_function(f_out, True), kernel_function(h_out, True), numba.njit)
    return SensitivityKernel(source, True)
