"""Kernels with a state correction and interval end states: stabilised output error and
multiple shooting (docs/unstable.md).

**Stabilised output error** (the book's TC09, CASES.md §3d). At every sample k:

    1. y_k = h(t_k, x_k, u_k, θ)                     (the output; the residual is z_k − y_k)
    2. x_k ← x_k + S (z_k − y_k)                      (S: constant gain, n_s × n_o)
    3. x_{k+1} = step(x_k)                            (Euler or RK4 from the corrected state)

A constant output-feedback gain keeps an unstable model's simulation near the measured
trajectory; the residual keeps the output of step 1 (before the correction, CASES.md Q16).
With S = 0 this is the plain simulation of ``flightid.simulate.kernels``.

The sensitivity equations carry the same correction: with G_k = ∂y_k/∂θ = h_x S_k + h_θ
(S_k = ∂x_k/∂θ here the state sensitivity), step 2 gives

    S_k ← S_k − S G_k

before the sensitivities are stepped to k + 1 (the measured z_k does not depend on θ).

**Interval end states** (multiple shooting, ``flightid.model.unstable``): the state kernel also
returns the state at its last sample, *before* any correction there, so that the continuity
defect of an interval is x_end(interval m) − x0(interval m + 1).

Both kernels are numba-compiled like the plain ones (disk cache by digest,
``flightid.simulate.cache``); the loops add no allocation to the integration step.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from flightid.simulate.kernels import _identity, make_step
from flightid.simulate.sensitivity import _jacobian, _rates

__all__ = ["make_feedback_kernel", "make_feedback_sensitivity_kernel"]


def _feedback_source(f: Callable, h: Callable, jit: Callable = _identity) -> Callable:
    """The batch loop with the state correction and the end state (helpers through ``jit``)."""
    step = jit(make_step(f))

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
        for b in range(n_batch):
            theta = thetas[b]
            x = x0s[b].copy()
            diverged_at[b] = -1
            for k in range(n_samples):
                y = h(t[k], x, u[k], theta)
                finite = True
                for j in range(n_outputs):
                    y_out[b, k, j] = y[j]
                    if not math.isfinite(y[j]):
                        finite = False
                for j in range(n_states):
                    if not math.isfinite(x[j]):
                        finite = False
                if not finite:
                    diverged_at[b] = k
                    for kk in range(k, n_samples):
                        for j in range(n_outputs):
                            y_out[b, kk, j] = np.nan
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
                x = step(t, u, k, x, theta, method, interpolation)

    return kernel


def _feedback_sensitivity_source(f: Callable, h: Callable, jit: Callable) -> Callable:
    """The sensitivity kernel of ``flightid.simulate.sensitivity`` with the state correction
    applied to the states and to their sensitivities."""
    jac_h = jit(_jacobian(h))
    rates = jit(_rates(f, jit(_jacobian(f))))
    step = jit(make_step(rates))

    def kernel(
        theta,
        x0,
        s0,
        free_index,
        steps,
        rel,
        t,
        u,
        method,
        interpolation,
        n_outputs,
        y_out,
        g_out,
        z,
        gain,
    ):
        n_s = x0.shape[0]
        n_f = free_index.shape[0]
        stabilize = gain.shape[0] > 0
        # zz = (x, S row by row)
        zz = np.empty(n_s * (1 + n_f))
        for i in range(n_s):
            zz[i] = x0[i]
            for j in range(n_f):
                zz[n_s + i * n_f + j] = s0[i, j]
        p = (theta, free_index, steps, rel)
        n_samples = t.shape[0]
        for k in range(n_samples):
            x = zz[:n_s].copy()
            uk = u[k]
            y = h(t[k], x, uk, theta)
            hx, ht = jac_h(t[k], x, uk, theta, free_index, steps, rel, y)
            finite = True
            for i in range(n_outputs):
                y_out[k, i] = y[i]
                if not math.isfinite(y[i]):
                    finite = False
                for j in range(n_f):
                    # G = h_x S + h_θ
                    acc = ht[i, j]
                    for m in range(n_s):
                        acc += hx[i, m] * zz[n_s + m * n_f + j]
                    g_out[k, i, j] = acc
            if not finite:
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
            zz = step(t, u, k, zz, p, method, interpolation)
        return -1

    return kernel


def make_feedback_kernel(f: Callable, h: Callable, compiled: bool = True) -> Callable:
    """The batch kernel with state correction and end states for ``f`` and ``h``.

    ``kernel(thetas, x0s, t, u, method, interpolation, n_outputs, y_out, diverged_at, z,
    gain, x_end)``: as the plain kernel (``flightid.simulate.kernels``), plus the measured
    outputs ``z`` (N, n_o) and the gain ``gain`` (n_s, n_o) of the correction (a (0, 0)
    array: none), and ``x_end`` (B, n_s) receiving each trajectory's state at its last sample
    (NaN where it diverged).
    """
    if not compiled:
        return _feedback_source(getattr(f, "py_func", f), getattr(h, "py_func", h))
    import numba

    from flightid.simulate.cache import cached_njit

    jit_f = f if hasattr(f, "py_func") else numba.njit(f)
    jit_h = h if hasattr(h, "py_func") else numba.njit(h)
    return cached_njit(_feedback_source(jit_f, jit_h, numba.njit))


def make_feedback_sensitivity_kernel(f: Callable, h: Callable, compiled: bool = True) -> Callable:
    """The sensitivity kernel (``flightid.simulate.sensitivity``) with the state correction.

    ``kernel(theta, x0, s0, free_index, steps, rel, t, u, method, interpolation, n_outputs,
    y_out, g_out, z, gain)``; returns −1 or the sample where the outputs became non-finite.
    """
    if not compiled:
        return _feedback_sensitivity_source(
            getattr(f, "py_func", f), getattr(h, "py_func", h), _identity
        )
    import numba

    from flightid.simulate.cache import cached_njit

    jit_f = f if hasattr(f, "py_func") else numba.njit(f)
    jit_h = h if hasattr(h, "py_func") else numba.njit(h)
    return cached_njit(_feedback_sensitivity_source(jit_f, jit_h, numba.njit))
