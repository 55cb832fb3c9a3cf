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

from flightid.simulate.kernels import _identity, make_step

__all__ = ["make_sensitivity_kernel"]


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


def _rates(f: Callable, jac_f: Callable) -> Callable:
    """The right-hand side of the stacked state and sensitivity equations."""

    def rates(t, z, u, p):
        """dz/dt = (dx/dt, dS/dt = f_x S + f_θ), with p = (θ, free_index, steps, rel)."""
        theta, free_index, steps, rel = p
        n_f = free_index.shape[0]
        n_s = z.shape[0] // (1 + n_f)
        x = z[:n_s].copy()
        dx = f(t, x, u, theta)
        jx, jt = jac_f(t, x, u, theta, free_index, steps, rel, dx)
        dz = np.empty(z.shape[0])
        for i in range(n_s):
            dz[i] = dx[i]
        for i in range(n_s):
            for j in range(n_f):
                acc = 0.0
                for k in range(n_s):
                    acc += jx[i, k] * z[n_s + k * n_f + j]
                # (dS/dt)_ij = (f_θ)_ij + Σ_k (f_x)_ik S_kj
                dz[n_s + i * n_f + j] = jt[i, j] + acc
        return dz

    return rates


def _build(f: Callable, h: Callable, jit: Callable) -> Callable:
    """The kernel, with every helper passed through ``jit`` (numba.njit or the identity).

    The states and sensitivities are stepped together as one vector z = (x, vec S) (S row by
    row) by the state kernel's own ``make_step``, so Euler / RK4 and the input rule are those
    of ``flightid.simulate.kernels``.
    """
    jac_h = jit(_jacobian(h))
    rates = jit(_rates(f, jit(_jacobian(f))))
    step = jit(make_step(rates))

    def kernel(
        theta, x0, s0, free_index, steps, rel, t, u, method, interpolation, n_outputs, y_out, g_out
    ):
        n_s = x0.shape[0]
        n_f = free_index.shape[0]
        # z = (x, S row by row)
        z = np.empty(n_s * (1 + n_f))
        for i in range(n_s):
            z[i] = x0[i]
            for j in range(n_f):
                z[n_s + i * n_f + j] = s0[i, j]
        p = (theta, free_index, steps, rel)
        n_samples = t.shape[0]
        for k in range(n_samples):
            x = z[:n_s].copy()
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
                        acc += hx[i, m] * z[n_s + m * n_f + j]
                    g_out[k, i, j] = acc
            if not finite:
                return k
            if k == n_samples - 1:
                break
            z = step(t, u, k, z, p, method, interpolation)
        return -1

    return kernel


def make_sensitivity_kernel(f: Callable, h: Callable, compiled: bool = True) -> Callable:
    """The sensitivity kernel for ``f`` and ``h``: numba-compiled (its machine code cached on
    disk, ``flightid.simulate.cache``), or the same loop in Python.

    ``kernel(theta, x0, s0, free_index, steps, rel, t, u, method, interpolation, n_outputs,
    y_out, g_out)`` (``method``: 0 Euler, 1 RK4; ``interpolation``: 0 linear, 1 zoh)
    fills y_out (N, n_o) and g_out (N, n_o, n_f) and returns −1, or the sample index at which
    the outputs became non-finite.
    """
    if not compiled:
        return _build(getattr(f, "py_func", f), getattr(h, "py_func", h), _identity)
    import numba

    from flightid.simulate.cache import cached_njit

    jit_f = f if hasattr(f, "py_func") else numba.njit(f)
    jit_h = h if hasattr(h, "py_func") else numba.njit(h)
    return cached_njit(_build(jit_f, jit_h, numba.njit))
