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

``integration_step`` is the one stepping routine (Euler or RK4, with the input rule above): the
state kernel here steps x with f, the sensitivity kernel (``flightid.simulate.sensitivity``)
steps the stacked (x, S) with the sensitivity equations.

A model without states (``StateSpaceModel(states=(), f=None, ...)``) is not integrated: its
kernel (``stateless=True``) evaluates y_k = h(t_k, [], u_k, θ) at every sample, with x an
empty float64 array; ``method`` and ``interpolation`` do not matter there.

The same Python source runs compiled (numba ``njit``) or interpreted; ``make_kernel`` builds
both from the user's ``f`` and ``h``. The compiled kernel is kept on disk between runs, keyed
by a digest of the model functions (``flightid.simulate.cache``).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

__all__ = [
    "make_kernel",
    "make_step",
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


def make_step(rate: Callable) -> Callable:
    """The integration step for ``rate(t, x, u, p) -> dx/dt`` (``p`` passed through).

    ``step(t, u, k, x, p, method, interpolation)`` returns x at t[k+1] from x at t[k]:
    Euler, or RK4 with the input between samples by ``interpolation`` (module docstring).
    """

    def step(t, u, k, x, p, method, interpolation):
        dt = t[k + 1] - t[k]
        uk = u[k]
        if method == EULER:
            # x_{k+1} = x_k + Δt · f(t_k, x_k, u_k)
            return x + dt * rate(t[k], x, uk, p)
        if interpolation == ZOH:
            # zero-order hold: u(t) = u_k on [t_k, t_{k+1})
            u_half = uk
            u_end = uk
        else:
            # linear: u_k+½ = (u_k + u_{k+1})/2, u(t_{k+1}) = u_{k+1}
            u_end = u[k + 1]
            u_half = 0.5 * (uk + u_end)
        k1 = rate(t[k], x, uk, p)
        k2 = rate(t[k] + 0.5 * dt, x + 0.5 * dt * k1, u_half, p)
        k3 = rate(t[k] + 0.5 * dt, x + 0.5 * dt * k2, u_half, p)
        k4 = rate(t[k] + dt, x + dt * k3, u_end, p)
        # x_{k+1} = x_k + Δt/6 · (k1 + 2k2 + 2k3 + k4)
        return x + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)

    return step


def no_state_derivative(t: float, x: np.ndarray, u: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """dx/dt of a model without states: the empty array (the ``f`` of ``f=None``)."""
    return np.empty(0)


def _identity(function: Callable) -> Callable:
    return function


def _kernel_source(f: Callable, h: Callable, jit: Callable = _identity) -> Callable:
    """The integration loop over a batch, closed over the model functions (helpers passed
    through ``jit``: numba.njit or the identity)."""
    step = jit(make_step(f))

    def kernel(thetas, x0s, t, u, method, interpolation, n_outputs, y_out, diverged_at):
        n_batch = thetas.shape[0]
        n_samples = t.shape[0]
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
                x = step(t, u, k, x, theta, method, interpolation)

    return kernel


def _output_kernel_source(h: Callable) -> Callable:
    """The batch loop of a model without states: y_k = h(t_k, [], u_k, θ) at every sample
    (no integration; ``method`` and ``interpolation`` are accepted and unused)."""

    def kernel(thetas, x0s, t, u, method, interpolation, n_outputs, y_out, diverged_at):
        n_batch = thetas.shape[0]
        n_samples = t.shape[0]
        x = np.empty(0)
        for b in range(n_batch):
            theta = thetas[b]
            diverged_at[b] = -1
            for k in range(n_samples):
                # y_k = h(t_k, [], u_k, θ)
                y = h(t[k], x, u[k], theta)
                finite = True
                for j in range(n_outputs):
                    y_out[b, k, j] = y[j]
                    if not math.isfinite(y[j]):
                        finite = False
                if not finite:
                    diverged_at[b] = k
                    for kk in range(k, n_samples):
                        for j in range(n_outputs):
                            y_out[b, kk, j] = np.nan
                    break

    return kernel


def make_kernel(
    f: Callable, h: Callable, compiled: bool = True, stateless: bool = False
) -> tuple[Callable, bool]:
    """Build the batch kernel for ``f`` and ``h`` (``stateless``: the model has no states, the
    kernel evaluates h alone at every sample and ``f`` is not called).

    Returns ``(kernel, is_compiled)``. With ``compiled=True`` the kernel is numba-compiled if
    numba can compile ``f``, ``h`` and the loop (checked lazily by the first call: see
    ``Simulator``), and its machine code is cached on disk (``flightid.simulate.cache``); with
    ``compiled=False`` it is the same loop in plain Python.
    """
    py_f = getattr(f, "py_func", f)
    py_h = getattr(h, "py_func", h)
    if not compiled:
        if stateless:
            return _output_kernel_source(py_h), False
        return _kernel_source(py_f, py_h), False
    import numba

    from flightid.simulate.cache import cached_njit

    if stateless:
        jit_h = h if hasattr(h, "py_func") else numba.njit(h)
        return cached_njit(_output_kernel_source(jit_h)), True
    jit_f = f if hasattr(f, "py_func") else numba.njit(f)
    jit_h = h if hasattr(h, "py_func") else numba.njit(h)
    return cached_njit(_kernel_source(jit_f, jit_h, numba.njit)), True
