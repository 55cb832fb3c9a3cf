"""Output sensitivities by integrating the sensitivity equations alongside the states.

For S = ∂x/∂θ (n_s × n_f, the free parameters) [RP-1153 §6, "analytic" MNR]:

    dS/dt = f_x S + f_θ,        S(t0) = ∂x0/∂θ
    G_i   = ∂y_i/∂θ = h_x S_i + h_θ

integrated with the same fixed-step scheme as the states (Euler or RK4, the input between
samples by the same ``input_interpolation`` rule as ``flightid.simulate.kernels``: "linear",
u at the half step the mean of the neighbouring samples, or "zoh", u held at u_k). The
Jacobians f_x, f_θ, h_x, h_θ come from forward differences of the user's f and h at every
stage (step ``relative_step`` × max(|v|, 1) for a state, × max(|θ_j|, typical_j) for a
parameter), so no derivative has to be written by hand; the sensitivities are those of the
*continuous* equations, not differences of two finished trajectories.

Cost: each stage evaluates f (and each sample h) 1 + n_s + n_f times instead of once, so one
pass counts as 1 + n_s + n_f equivalent evaluations — about n_s more than finite-difference
MNR. The gain is accuracy of G (no difference of nearly equal trajectories), not speed.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from flightid.simulate.kernels import ZOH

__all__ = ["make_sensitivity_kernel"]


def _identity(function: Callable) -> Callable:
    return function


def _jacobian(fun: Callable) -> Callable:
    """(∂fun/∂x, ∂fun/∂θ_free) by forward differences about ``base`` = fun(t, x, u, θ)."""

    def jacobians(t, x, u, theta, free_index, steps, rel, base):
        n_s = x.shape[0]
        n_f = free_index.shape[0]
        m = base.shape[0]
        jx = np.empty((m, n_s))
        jt = np.empty((m, n_f))
        for j in range(n_s):
            d = rel * max(abs(x[j]), 1.0)
            xp = x.copy()
            xp[j] += d
            col = (fun(t, xp, u, theta) - base) / d
            for i in range(m):
                jx[i, j] = col[i]
        for j in range(n_f):
            d = steps[j]
            tp = theta.copy()
            tp[free_index[j]] += d
            col = (fun(t, x, u, tp) - base) / d
            for i in range(m):
                jt[i, j] = col[i]
        return jx, jt

    return jacobians


def _build(f: Callable, h: Callable, jit: Callable) -> Callable:
    """The kernel, with every helper passed through ``jit`` (numba.njit or the identity)."""
    jac_f = jit(_jacobian(f))
    jac_h = jit(_jacobian(h))

    def rates(t, x, u, theta, free_index, steps, rel, s):
        """(dx/dt, dS/dt = f_x S + f_θ)."""
        dx = f(t, x, u, theta)
        jx, jt = jac_f(t, x, u, theta, free_index, steps, rel, dx)
        ds = jt.copy()
        for i in range(ds.shape[0]):
            for j in range(ds.shape[1]):
                acc = 0.0
                for k in range(x.shape[0]):
                    acc += jx[i, k] * s[k, j]
                ds[i, j] += acc
        return dx, ds

    rates = jit(rates)

    def kernel(
        theta, x0, s0, free_index, steps, rel, t, u, method, interpolation, n_outputs, y_out, g_out
    ):
        x = x0.copy()
        s = s0.copy()
        n_samples = t.shape[0]
        for k in range(n_samples):
            uk = u[k]
            y = h(t[k], x, uk, theta)
            hx, ht = jac_h(t[k], x, uk, theta, free_index, steps, rel, y)
            finite = True
            for i in range(n_outputs):
                y_out[k, i] = y[i]
                if not math.isfinite(y[i]):
                    finite = False
                for j in range(s.shape[1]):
                    # G = h_x S + h_θ
                    acc = ht[i, j]
                    for m in range(x.shape[0]):
                        acc += hx[i, m] * s[m, j]
                    g_out[k, i, j] = acc
            if not finite:
                return k
            if k == n_samples - 1:
                break
            dt = t[k + 1] - t[k]
            if method == 0:
                dx, ds = rates(t[k], x, uk, theta, free_index, steps, rel, s)
                x = x + dt * dx
                s = s + dt * ds
            else:
                if interpolation == ZOH:
                    # zero-order hold: u(t) = u_k on [t_k, t_{k+1})
                    u_half = uk
                    u_end = uk
                else:
                    # linear: u_k+½ = (u_k + u_{k+1})/2, u(t_{k+1}) = u_{k+1}
                    u_end = u[k + 1]
                    u_half = 0.5 * (uk + u_end)
                k1x, k1s = rates(t[k], x, uk, theta, free_index, steps, rel, s)
                k2x, k2s = rates(
                    t[k] + 0.5 * dt,
                    x + 0.5 * dt * k1x,
                    u_half,
                    theta,
                    free_index,
                    steps,
                    rel,
                    s + 0.5 * dt * k1s,
                )
                k3x, k3s = rates(
                    t[k] + 0.5 * dt,
                    x + 0.5 * dt * k2x,
                    u_half,
                    theta,
                    free_index,
                    steps,
                    rel,
                    s + 0.5 * dt * k2s,
                )
                k4x, k4s = rates(
                    t[k] + dt, x + dt * k3x, u_end, theta, free_index, steps, rel, s + dt * k3s
                )
                x = x + (dt / 6.0) * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
                s = s + (dt / 6.0) * (k1s + 2.0 * k2s + 2.0 * k3s + k4s)
        return -1

    return jit(kernel)


def make_sensitivity_kernel(f: Callable, h: Callable, compiled: bool = True) -> Callable:
    """The sensitivity kernel for ``f`` and ``h``: numba-compiled, or the same loop in Python.

    ``kernel(theta, x0, s0, free_index, steps, rel, t, u, method, interpolation, n_outputs,
    y_out, g_out)`` (``method``: 0 Euler, 1 RK4; ``interpolation``: 0 linear, 1 zoh)
    fills y_out (N, n_o) and g_out (N, n_o, n_f) and returns −1, or the sample index at which
    the outputs became non-finite.
    """
    if not compiled:
        return _build(getattr(f, "py_func", f), getattr(h, "py_func", h), _identity)
    import numba

    jit_f = f if hasattr(f, "py_func") else numba.njit(f)
    jit_h = h if hasattr(h, "py_func") else numba.njit(h)
    return _build(jit_f, jit_h, numba.njit)
