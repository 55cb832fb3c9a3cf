"""Filter error for linear models: exact discretisation and analytic gradients (Jategaonkar,
*Flight Vehicle System Identification*, 2nd ed., ch. 5; FVSysID's ``ml_fem_lin2``).

For a model that is linear in the states and inputs,

    ẋ = A x + B u + b_x + F w,    y = C x + D u + b_y,

(A … b_y functions of θ) the steady-state filter runs on the exact discretisation

    Φ = e^{AΔt},  Ψ = ∫₀^Δt e^{Aτ} dτ   (one ``expm`` of [[A, I], [0, 0]]·Δt = [[Φ, Ψ], [0, I]]),
    ỹ_k = C x̃_k + D u_k + b_y,   e_k = z_k − ỹ_k,   x̂_k = x̃_k + K e_k,
    x̃_{k+1} = Φ x̂_k + Ψ B (u_k + u_{k+1})/2 + Ψ b_x,   x̃_1 = x0,

and the sensitivities H = ∂ỹ/∂θ come from differentiating these recursions (no filter
passes): with Ā = A − P Cᵀ R⁻¹ C / Δt, ∂P/∂θ_j solves the Lyapunov equation

    Ā ∂P + ∂P Āᵀ = −(∂A P + P ∂Aᵀ − P (∂Cᵀ R⁻¹ C + Cᵀ R⁻¹ ∂C) P / Δt + ∂(F Fᵀ)),

∂K = ∂P Cᵀ R⁻¹ + P ∂Cᵀ R⁻¹ (R is the fixed weighting), ∂Φ and ∂Ψ are the Fréchet
derivative of the same ``expm``, and the state sensitivities follow prediction and
correction. The reference (``ml_fem_lin2``) sums 12 Taylor terms for Φ and Ψ; at
‖A‖Δt ≈ 0.35 (y13aus) that series agrees with ``expm`` to ~1e-13 (tested).

The matrices and their θ-derivatives are read from the model functions: A, B, C, D, b_x,
b_y exactly from unit state/input vectors (the model is checked to be linear in x and u at
random points), ∂/∂θ_j by central differences of those matrices (exact up to rounding for
models affine in each parameter, as every ``type = "linear"`` model and y13aus are; these
cost model-function calls, not filter passes).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import scipy.linalg

# the per-sample steps of the filter and sensitivity loops: compiled inlined into the loops
# (numba IR inlining), as fast as written out in them
try:
    from numba.extending import register_jitable
except ImportError:  # pragma: no cover - the kernels then run as plain Python

    def register_jitable(**options) -> Callable:
        return lambda function: function


from flightid.errors import EstimationError, InputError

#: relative tolerance of the linearity check of f and h in x and u
LINEARITY_RTOL = 1e-8


class NotLinearError(InputError):
    """The model is not linear in the states and inputs (the linear filter needs it)."""


def system_matrices(
    f: Callable, h: Callable, theta: np.ndarray, n_x: int, n_u: int, t: float = 0.0
) -> tuple[np.ndarray, ...]:
    """(A, B, b_x, C, D, b_y) of a model linear in x and u, read exactly from f and h.

    A[:, i] = f(e_i, 0) − f(0, 0), b_x = f(0, 0), likewise B, C, D, b_y.
    """
    x0, u0 = np.zeros(n_x), np.zeros(n_u)
    bx = np.asarray(f(t, x0, u0, theta), dtype=float).copy()
    by = np.asarray(h(t, x0, u0, theta), dtype=float).copy()
    eye_x, eye_u = np.eye(n_x), np.eye(n_u)
    a = np.column_stack([f(t, eye_x[i], u0, theta) - bx for i in range(n_x)])
    c = np.column_stack([h(t, eye_x[i], u0, theta) - by for i in range(n_x)])
    if n_u:
        b = np.column_stack([f(t, x0, eye_u[i], theta) - bx for i in range(n_u)])
        d = np.column_stack([h(t, x0, eye_u[i], theta) - by for i in range(n_u)])
    else:
        b, d = np.zeros((n_x, 0)), np.zeros((len(by), 0))
    return a, b, bx, c, d, by


def check_linear(
    f: Callable, h: Callable, theta: np.ndarray, n_x: int, n_u: int, seed: int = 0
) -> None:
    """Raise ``NotLinearError`` unless f and h equal A x + B u + b at three random points."""
    a, b, bx, c, d, by = system_matrices(f, h, theta, n_x, n_u)
    rng = np.random.default_rng(seed)
    for _ in range(3):
        x, u = rng.normal(size=n_x) * 3.0, rng.normal(size=n_u) * 3.0
        for name, got, want in (
            ("f", f(0.0, x, u, theta), a @ x + b @ u + bx),
            ("h", h(0.0, x, u, theta), c @ x + d @ u + by),
        ):
            got = np.asarray(got, dtype=float)
            if not np.allclose(got, want, rtol=LINEARITY_RTOL, atol=LINEARITY_RTOL):
                raise NotLinearError(
                    f"model: analytic filter gradients need {name} linear in the states and "
                    f"inputs; at a random (x, u) {name} = {got}, its linear part gives {want}"
                )


def discretise(a: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(Φ, Ψ) = (e^{AΔt}, ∫₀^Δt e^{Aτ} dτ) from expm([[A, I], [0, 0]] Δt)."""
    n = a.shape[0]
    m = np.zeros((2 * n, 2 * n))
    m[:n, :n], m[:n, n:] = a * dt, np.eye(n) * dt
    e = scipy.linalg.expm(m)
    return e[:n, :n], e[:n, n:]


def discretise_taylor(a: np.ndarray, dt: float, terms: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """The reference's series: Φ = Σ_{k=0..terms} (AΔt)^k/k!, Ψ = Σ A^k Δt^{k+1}/(k+1)!."""
    n = a.shape[0]
    phi, psi, power = np.zeros((n, n)), np.zeros((n, n)), np.eye(n)
    for k in range(terms + 1):
        phi += power * dt**k / math.factorial(k)
        psi += power * dt ** (k + 1) / math.factorial(k + 1)
        power = power @ a
    return phi, psi


def discretise_derivative(
    a: np.ndarray, da: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(Φ, Ψ, ∂Φ, ∂Ψ) for one direction ∂A: the Fréchet derivative of the augmented expm."""
    n = a.shape[0]
    m, dm = np.zeros((2 * n, 2 * n)), np.zeros((2 * n, 2 * n))
    m[:n, :n], m[:n, n:], dm[:n, :n] = a * dt, np.eye(n) * dt, da * dt
    e, de = scipy.linalg.expm_frechet(m, dm)
    return e[:n, :n], e[:n, n:], de[:n, :n], de[:n, n:]


def covariance_derivative(
    a: np.ndarray,
    c: np.ndarray,
    p: np.ndarray,
    r_diag: np.ndarray,
    dt: float,
    da: np.ndarray,
    dc: np.ndarray,
    dffT: np.ndarray,
) -> np.ndarray:
    """∂P for one direction from the differentiated CARE (a Lyapunov equation).

    A P + P Aᵀ − P Cᵀ R⁻¹ C P / Δt + F Fᵀ = 0 differentiated (R fixed):
    Ā ∂P + ∂P Āᵀ = −(∂A P + P ∂Aᵀ − P (∂Cᵀ R⁻¹ C + Cᵀ R⁻¹ ∂C) P / Δt + ∂(F Fᵀ)),
    Ā = A − P Cᵀ R⁻¹ C / Δt.
    """
    rinv = 1.0 / np.asarray(r_diag, dtype=float)
    ctrc = c.T @ (c * rinv[:, None])
    a_bar = a - p @ ctrc / dt
    dctrc = dc.T @ (c * rinv[:, None])
    # right-hand side −(∂A P + P ∂Aᵀ − P (∂CᵀR⁻¹C + CᵀR⁻¹∂C) P / Δt + ∂(FFᵀ))
    rhs = -(da @ p + p @ da.T - p @ (dctrc + dctrc.T) @ p / dt + dffT)
    dp = scipy.linalg.solve_continuous_lyapunov(a_bar, rhs)
    return 0.5 * (dp + dp.T)


@register_jitable(inline="always")
def _filtered_output(c, d, by, x, u, z, k, y, e):  # pragma: no cover - numba
    """ỹ_k = C x̃_k + D u_k + b_y into y[k], and the innovation e_k = z_k − ỹ_k into e."""
    n_x, n_o, n_u = c.shape[1], c.shape[0], u.shape[1]
    for i in range(n_o):
        # ỹ_k = C x̃_k + D u_k + b_y
        acc = by[i]
        for j in range(n_x):
            acc += c[i, j] * x[j]
        for j in range(n_u):
            acc += d[i, j] * u[k, j]
        y[k, i] = acc
        e[i] = z[k, i] - acc


@register_jitable(inline="always")
def _corrected_state(x, gain, e, xhat):  # pragma: no cover - numba
    """x̂_k = x̃_k + K e_k into xhat."""
    for i in range(x.shape[0]):
        acc = x[i]
        for j in range(e.shape[0]):
            acc += gain[i, j] * e[j]
        xhat[i] = acc


@register_jitable(inline="always")
def _input_drive(b, bx, u, k, ubar, drive):  # pragma: no cover - numba
    """ū_k = (u_k + u_{k+1})/2 into ubar, and B ū_k + b_x into drive."""
    n_u = u.shape[1]
    for j in range(n_u):
        ubar[j] = 0.5 * (u[k, j] + u[k + 1, j])
    for i in range(bx.shape[0]):
        acc = bx[i]
        for j in range(n_u):
            acc += b[i, j] * ubar[j]
        drive[i] = acc


@register_jitable(inline="always")
def _predicted_state(phi, psi, xhat, drive, x):  # pragma: no cover - numba
    """x̃_{k+1} = Φ x̂_k + Ψ (B ū_k + b_x) into x."""
    for i in range(x.shape[0]):
        acc = 0.0
        for j in range(x.shape[0]):
            acc += phi[i, j] * xhat[j] + psi[i, j] * drive[j]
        x[i] = acc


def _filter_loop(phi, psi, b, bx, c, d, by, gain, x0, u, z, y):  # pragma: no cover - numba
    n, n_x, n_o, n_u = u.shape[0], phi.shape[0], c.shape[0], u.shape[1]
    x = x0.copy()
    xhat = np.empty(n_x)
    e = np.empty(n_o)
    ubar = np.empty(n_u)
    drive = np.empty(n_x)
    for k in range(n):
        _filtered_output(c, d, by, x, u, z, k, y, e)
        _corrected_state(x, gain, e, xhat)
        if k + 1 < n:
            _input_drive(b, bx, u, k, ubar, drive)
            _predicted_state(phi, psi, xhat, drive, x)


def _sensitivity_loop(
    phi, psi, dphi, dpsi, b, bx, c, d, by, db, dbx, dc, dd, dby, gain, dgain, x0, dx0, u, z, y, g
):  # pragma: no cover - numba
    """The filter loop (same helpers) and, beside it, the state and output sensitivities."""
    n, n_x, n_o, n_u = u.shape[0], phi.shape[0], c.shape[0], u.shape[1]
    n_p = dphi.shape[2]
    x = x0.copy()
    s = dx0.copy()
    xhat = np.empty(n_x)
    shat = np.empty((n_x, n_p))
    e = np.empty(n_o)
    ubar = np.empty(n_u)
    drive = np.empty(n_x)
    ddrive = np.empty((n_x, n_p))
    for k in range(n):
        _filtered_output(c, d, by, x, u, z, k, y, e)
        for i in range(n_o):
            # ∂ỹ_k = ∂C x̃_k + C S̃_k + ∂D u_k + ∂b_y
            for p in range(n_p):
                acc = dby[i, p]
                for j in range(n_x):
                    acc += dc[i, j, p] * x[j] + c[i, j] * s[j, p]
                for j in range(n_u):
                    acc += dd[i, j, p] * u[k, j]
                g[k, i, p] = acc
        _corrected_state(x, gain, e, xhat)
        for i in range(n_x):
            # ∂x̂_k = S̃_k + ∂K e_k − K ∂ỹ_k
            for p in range(n_p):
                acc = s[i, p]
                for j in range(n_o):
                    acc += dgain[i, j, p] * e[j] - gain[i, j] * g[k, j, p]
                shat[i, p] = acc
        if k + 1 < n:
            _input_drive(b, bx, u, k, ubar, drive)
            # ∂(B ū_k + b_x) = ∂B ū_k + ∂b_x
            for i in range(n_x):
                for p in range(n_p):
                    acc = dbx[i, p]
                    for j in range(n_u):
                        acc += db[i, j, p] * ubar[j]
                    ddrive[i, p] = acc
            _predicted_state(phi, psi, xhat, drive, x)
            for i in range(n_x):
                # S̃_{k+1} = ∂Φ x̂_k + Φ ∂x̂_k + ∂Ψ (B ū_k + b_x) + Ψ (∂B ū_k + ∂b_x)
                for p in range(n_p):
                    acc = 0.0
                    for j in range(n_x):
                        acc += dphi[i, j, p] * xhat[j] + phi[i, j] * shat[j, p]
                        acc += dpsi[i, j, p] * drive[j] + psi[i, j] * ddrive[j, p]
                    s[i, p] = acc


_KERNELS: dict[str, Callable] = {}


def _kernel(name: str) -> Callable:
    """The numba-compiled loop (the plain Python loop if numba is missing)."""
    if name not in _KERNELS:
        function = {"filter": _filter_loop, "sensitivity": _sensitivity_loop}[name]
        try:
            import numba

            _KERNELS[name] = numba.njit(cache=True)(function)
        except ImportError:  # pragma: no cover
            _KERNELS[name] = function
    return _KERNELS[name]


def _c(array: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(array, dtype=float)


def linear_filter(
    matrices: tuple[np.ndarray, ...],
    gain: np.ndarray,
    x0: np.ndarray,
    u: np.ndarray,
    z: np.ndarray,
    dt: float,
) -> np.ndarray:
    """Filtered outputs ỹ (N, n_o) of one maneuver with the exact discretisation."""
    a, b, bx, c, d, by = matrices
    phi, psi = discretise(a, dt)
    y = np.empty((u.shape[0], c.shape[0]))
    _kernel("filter")(
        _c(phi), _c(psi), _c(b), _c(bx), _c(c), _c(d), _c(by), _c(gain), _c(x0), _c(u), _c(z), y
    )
    return y


def linear_filter_sensitivities(
    matrices: tuple[np.ndarray, ...],
    derivatives: tuple[np.ndarray, ...],
    gain: np.ndarray,
    dgain: np.ndarray,
    x0: np.ndarray,
    dx0: np.ndarray,
    u: np.ndarray,
    z: np.ndarray,
    dt: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(ỹ (N, n_o), H = ∂ỹ/∂θ (N, n_o, n_p)) of one maneuver.

    ``derivatives`` = (∂A, ∂B, ∂b_x, ∂C, ∂D, ∂b_y), each with the parameter as last axis;
    ``dgain`` = ∂K (n_x, n_o, n_p); ``dx0`` = ∂x0 (n_x, n_p).
    """
    a, b, bx, c, d, by = matrices
    da, db, dbx, dc, dd, dby = derivatives
    n_p = da.shape[-1]
    phi, psi = discretise(a, dt)
    dphi = np.zeros(da.shape)
    dpsi = np.zeros(da.shape)
    for j in range(n_p):
        if np.any(da[..., j]):
            _, _, dphi[..., j], dpsi[..., j] = discretise_derivative(a, da[..., j], dt)
    n = u.shape[0]
    y = np.empty((n, c.shape[0]))
    g = np.empty((n, c.shape[0], n_p))
    _kernel("sensitivity")(
        *(_c(m) for m in (phi, psi, dphi, dpsi, b, bx, c, d, by, db, dbx, dc, dd, dby)),
        _c(gain),
        _c(dgain),
        _c(x0),
        _c(dx0),
        _c(u),
        _c(z),
        y,
        g,
    )
    return y, g


def matrix_derivatives(
    matrices: Callable[[np.ndarray], tuple[np.ndarray, ...]],
    theta: np.ndarray,
    index: np.ndarray,
    relative_step: float = 1e-4,
) -> tuple[np.ndarray, ...]:
    """(∂A, ∂B, ∂b_x, ∂C, ∂D, ∂b_y) with respect to θ[index] (parameter as last axis), by
    central differences of ``matrices(θ)`` (exact up to rounding for models affine in each
    parameter; model-function calls, no filter passes)."""
    if not len(index):
        raise EstimationError("analytic filter gradients: no free parameters")
    parts = [[] for _ in range(6)]
    for j in index:
        step = relative_step * max(abs(theta[j]), 1.0)
        plus, minus = theta.copy(), theta.copy()
        plus[j] += step
        minus[j] -= step
        hi, lo = matrices(plus), matrices(minus)
        for i in range(6):
            # ∂M/∂θ_j = (M(θ + δ e_j) − M(θ − δ e_j)) / 2δ
            parts[i].append((hi[i] - lo[i]) / (2.0 * step))
    return tuple(np.stack(p, axis=-1) for p in parts)
