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

The same Python source runs compiled (numba ``njit``) or interpreted; ``make_kernel`` builds
both from the user's ``f`` and ``h``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

__all__ = ["make_kernel", "EULER", "RK4", "LINEAR", "ZOH", "INTERPOLATIONS"]

EULER = 0
RK4 = 1
# input interpolation between samples (kernel argument ``interpolation``)
LINEAR = 0
ZOH = 1
INTERPOLATIONS = {"linear": LINEAR, "zoh": ZOH}


def _kernel_source(f: Callable, h: Callable) -> Callable:
    """The integration loop over a batch, closed over the model functions."""

    def kernel(thetas, x0s, t, u, method, interpolation, n_outputs, y_out, diverged_at):
        n_batch = thetas.shape[0]
        n_samples = t.shape[0]
        for b in range(n_batch):
            theta = thetas[b]
            x = x0s[b].copy()
            diverged_at[b] = -1
            for k in range(n_samples):
                uk = u[k]
                y = h(t[k], x, uk, theta)
                finite = True
                for j in range(n_outputs):
                    y_out[b, k, j] = y[j]
                    if not math.isfinite(y[j]):
                        finite = False
                for j in range(x.shape[0]):
                    if not math.isfinite(x[j]):
                        finite = False
                if not finite:
                    diverged_at[b] = k
                    for kk in range(k, n_samples):
                        for j in range(n_outputs):
                            y_out[b, kk, j] = np.nan
                    break
                if k == n_samples - 1:
                    break
                dt = t[k + 1] - t[k]
                if method == 0:
                    x = x + dt * f(t[k], x, uk, theta)
                else:
                    if interpolation == ZOH:
                        # zero-order hold: u(t) = u_k on [t_k, t_{k+1})
                        u_half = uk
                        u_end = uk
                    else:
                        # linear: u_k+½ = (u_k + u_{k+1})/2, u(t_{k+1}) = u_{k+1}
                        u_end = u[k + 1]
                        u_half = 0.5 * (uk + u_end)
                    k1 = f(t[k], x, uk, theta)
                    k2 = f(t[k] + 0.5 * dt, x + 0.5 * dt * k1, u_half, theta)
                    k3 = f(t[k] + 0.5 * dt, x + 0.5 * dt * k2, u_half, theta)
                    k4 = f(t[k] + dt, x + dt * k3, u_end, theta)
                    x = x + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)

    return kernel


def make_kernel(f: Callable, h: Callable, compiled: bool = True) -> tuple[Callable, bool]:
    """Build the batch kernel for ``f`` and ``h``.

    Returns ``(kernel, is_compiled)``. With ``compiled=True`` the kernel is numba-compiled if
    numba can compile ``f``, ``h`` and the loop (checked lazily by the first call: see
    ``Simulator``); with ``compiled=False`` it is the same loop in plain Python.
    """
    py_f = getattr(f, "py_func", f)
    py_h = getattr(h, "py_func", h)
    if not compiled:
        return _kernel_source(py_f, py_h), False
    import numba

    jit_f = f if hasattr(f, "py_func") else numba.njit(cache=False)(f)
    jit_h = h if hasattr(h, "py_func") else numba.njit(cache=False)(h)
    return numba.njit(cache=False)(_kernel_source(jit_f, jit_h)), True
