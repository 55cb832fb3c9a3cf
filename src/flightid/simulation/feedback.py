"""Kernels with a state correction and interval end states: stabilised output error and
multiple shooting (docs/unstable.md).

**Stabilised output error** (Jategaonkar ch. 9; FVSysID test case TC09). At every sample k:

    1. y_k = h(t_k, x_k, u_k, θ)                     (the output; the residual is z_k − y_k)
    2. x_k ← x_k + S (z_k − y_k)                      (S: constant gain, n_s × n_o)
    3. x_{k+1} = step(x_k)                            (Euler or RK4 from the corrected state)

A constant output-feedback gain keeps an unstable model's simulation near the measured
trajectory; the residual keeps the output of step 1 (before the correction).
With S = 0 this is the plain simulation of ``flightid.simulation.kernels``.

The sensitivity equations carry the same correction: with G_k = ∂y_k/∂θ = h_x S_k + h_θ
(S_k = ∂x_k/∂θ here the state sensitivity), step 2 gives

    S_k ← S_k − S G_k

before the sensitivities are stepped to k + 1 (the measured z_k does not depend on θ).

**Interval end states** (multiple shooting, ``flightid.model.unstable``): the state kernel also
returns the state at its last sample, *before* any correction there, so that the continuity
defect of an interval is x_end(interval m) − x0(interval m + 1).

Both kernels are numba-compiled like the plain ones (disk cache by digest,
``flightid.model.kernel_cache``) and take the out-form model functions; the loops allocate
nothing per step. The batch loop of the state kernel is a ``prange`` (parallel for batches of
several trajectories, ``flightid.simulation.kernels.BatchKernel``); the sensitivity kernel is
the one of ``flightid.simulation.sensitivity``, given the gain and the measured outputs.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import prange

from flightid.simulation.kernels import (
    BatchKernel,
    _identity,
    make_step,
    record_sample,
    step_buffers,
)
from flightid.simulation.sensitivity import make_sensitivity_kernel

__all__ = ["make_feedback_kernel", "make_feedback_sensitivity_kernel"]


def _feedback_source(f_out: Callable, h_out: Callable, jit: Callable = _identity) -> Callable:
    """The batch loop with the state correction and the end state (helpers through ``jit``)."""
    step = jit(make_step(f_out))
    buffers_for = jit(step_buffers)
    record = jit(record_sample)

    def kernel(
        thetas,
        x0s,
        t,
        u,
        method,
        interpolation,
        n_outputs,
        y_out,
        diverged_at,
        z,
        gain,
        x_end,
    ):
        n_batch = thetas.shape[0]
        n_samples = t.shape[0]
        n_states = x0s.shape[1]
        stabilize = gain.shape[0] > 0
        for b in prange(n_batch):
            theta = thetas[b]
            x = x0s[b].copy()
            y = np.empty(n_outputs)
            buffers = buffers_for(n_states, u.shape[1])
            diverged_at[b] = -1
            for k in range(n_samples):
                h_out(t[k], x, u[k], theta, y)
                if not record(y, x, y_out[b], k, n_outputs):
                    diverged_at[b] = k
                    for j in range(n_states):
                        x_end[b, j] = np.nan
                    break
                if k == n_samples - 1:
                    # the end state, before any correction at this sample
                    for j in range(n_states):
                        x_end[b, j] = x[j]
                    break
                if stabilize:
                    for i in range(n_states):
                        acc = 0.0
                        for j in range(n_outputs):
                            acc += gain[i, j] * (z[k, j] - y[j])
                        # x_k ← x_k + S (z_k − y_k)
                        x[i] += acc
                step(t, u, k, x, theta, method, interpolation, buffers)

    return kernel


def make_feedback_kernel(f_out: Callable, h_out: Callable, compiled: bool = True) -> Callable:
    """The batch kernel with state correction and end states for the out-form ``f_out`` and
    ``h_out``.

    ``kernel(thetas, x0s, t, u, method, interpolation, n_outputs, y_out, diverged_at, z,
    gain, x_end)``: as the plain kernel (``flightid.simulation.kernels``), plus the measured
    outputs ``z`` (N, n_o) and the gain ``gain`` (n_s, n_o) of the correction (a (0, 0)
    array: none), and ``x_end`` (B, n_s) receiving each trajectory's state at its last sample
    (NaN where it diverged).
    """
    from flightid.model.forms import kernel_function, out_form_of

    # functions in return form (the former interface) are adapted
    f_out, h_out = out_form_of(f_out), out_form_of(h_out)
    if not compiled:
        return _feedback_source(kernel_function(f_out, False), kernel_function(h_out, False))
    import numba

    return BatchKernel(
        _feedback_source(kernel_function(f_out, True), kernel_function(h_out, True), numba.njit)
    )


def make_feedback_sensitivity_kernel(
    f_out: Callable, h_out: Callable, compiled: bool = True
) -> Callable:
    """The sensitivity kernel (``flightid.simulation.sensitivity``) with the state correction.

    ``kernel(theta, x0, s0, free_index, steps, rel, t, u, method, interpolation, n_outputs,
    y_out, g_out, z, gain)``; returns −1 or the sample where the state or the outputs became
    non-finite.
    """
    return make_sensitivity_kernel(f_out, h_out, compiled)
