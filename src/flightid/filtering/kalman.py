"""Steady-state (constant-gain) Kalman filter of the filter error method.

System with process noise (Jategaonkar, *Flight Vehicle System Identification*, 2nd ed.,
ch. 5; FVSysID's ``ml_fem2``):

    ẋ(t) = f(x, u, θ) + F w(t),   w white, zero mean, unit intensity
    z_k  = g(x_k, u_k, θ) + v_k,   v_k ~ N(0, R)

Linearised at a point (x*, u*): A = ∂f/∂x, C = ∂g/∂x (central differences, absolute step
Δx). The steady-state covariance P of the predicted state solves the continuous algebraic
Riccati equation

    A P + P Aᵀ − (1/Δt) P Cᵀ R⁻¹ C P + F Fᵀ = 0                          (CARE)

and the gain is K = P Cᵀ R⁻¹ (x̂_k = x̃_k + K (z_k − ỹ_k)). R is the weighting of the
innovations (their covariance estimate). ``riccati_solution`` returns the stabilising
solution through ``scipy.linalg.solve_continuous_are`` (a Schur method): with
a = Aᵀ, b = Cᵀ, q = FFᵀ, r = Δt·R it solves aᵀX + Xa − X b r⁻¹ bᵀ X + q = 0, which is CARE.
``potter_solution`` is the reference tool's method (eigenvectors of the Hamiltonian) and
serves as an independent cross-check.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.linalg

from flightid.errors import EstimationError, InputError

__all__ = [
    "linearise",
    "riccati_solution",
    "potter_solution",
    "steady_state_gain",
    "RiccatiError",
]


class RiccatiError(EstimationError):
    """The algebraic Riccati equation has no stabilising solution at these values."""


def linearise(
    f: Callable,
    h: Callable,
    t: float,
    x: np.ndarray,
    u: np.ndarray,
    theta: np.ndarray,
    step: float = 1e-4,
) -> tuple[np.ndarray, np.ndarray]:
    """A = ∂f/∂x and C = ∂h/∂x at (t, x, u, θ) by central differences with absolute ``step``.

    Returns:
        (A (n_x × n_x), C (n_o × n_x)).
    """
    x = np.asarray(x, dtype=float)
    n_x = x.size
    columns_f, columns_h = [], []
    for j in range(n_x):
        plus, minus = x.copy(), x.copy()
        plus[j] += step
        minus[j] -= step
        # ∂f/∂x_j ≈ (f(x + Δ e_j) − f(x − Δ e_j)) / (2Δ), the same for h
        columns_f.append(np.asarray(f(t, plus, u, theta)) - np.asarray(f(t, minus, u, theta)))
        columns_h.append(np.asarray(h(t, plus, u, theta)) - np.asarray(h(t, minus, u, theta)))
    a = np.column_stack(columns_f) / (2.0 * step)
    c = np.column_stack(columns_h) / (2.0 * step)
    return a, c


def _check(a: np.ndarray, c: np.ndarray, ffT: np.ndarray, r_diag: np.ndarray, dt: float):
    a = np.atleast_2d(np.asarray(a, dtype=float))
    c = np.atleast_2d(np.asarray(c, dtype=float))
    ffT = np.atleast_2d(np.asarray(ffT, dtype=float))
    r_diag = np.atleast_1d(np.asarray(r_diag, dtype=float))
    n_x = a.shape[0]
    if a.shape != (n_x, n_x) or c.shape[1] != n_x or ffT.shape != (n_x, n_x):
        raise InputError(
            f"Riccati: expected A (n×n), C (m×n), FFᵀ (n×n); got {a.shape}, {c.shape}, {ffT.shape}"
        )
    if r_diag.shape != (c.shape[0],) or np.any(r_diag <= 0) or not np.all(np.isfinite(r_diag)):
        raise InputError(
            f"Riccati: expected {c.shape[0]} positive weighting variances R, got {r_diag!r}"
        )
    if not dt > 0:
        raise InputError(f"Riccati: expected a positive sampling interval dt, got {dt!r}")
    return a, c, ffT, r_diag


def riccati_solution(
    a: np.ndarray, c: np.ndarray, ffT: np.ndarray, r_diag: np.ndarray, dt: float
) -> np.ndarray:
    """Stabilising solution P of A P + P Aᵀ − (1/Δt) P Cᵀ R⁻¹ C P + F Fᵀ = 0.

    Args:
        a: A (n × n), 1/s.
        c: C (m × n).
        ffT: F Fᵀ (n × n), the process-noise intensity.
        r_diag: diagonal of R (m,), the weighting (innovation covariance).
        dt: sampling interval Δt, s.
    Raises:
        RiccatiError: no stabilising symmetric solution exists (e.g. an unstable mode that
            the outputs do not see).
    """
    a, c, ffT, r_diag = _check(a, c, ffT, r_diag, dt)
    try:
        # aᵀX + Xa − X b r⁻¹ bᵀ X + q = 0 with a = Aᵀ, b = Cᵀ, q = FFᵀ, r = Δt R  ⇔  CARE
        p = scipy.linalg.solve_continuous_are(a.T, c.T, ffT, dt * np.diag(r_diag))
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise RiccatiError(f"the Riccati equation has no stabilising solution ({exc})") from None
    if not np.all(np.isfinite(p)):
        raise RiccatiError("the Riccati solution is not finite")
    return 0.5 * (p + p.T)


def potter_solution(
    a: np.ndarray, c: np.ndarray, ffT: np.ndarray, r_diag: np.ndarray, dt: float
) -> np.ndarray:
    """P by Potter's method (the reference tool's): eigenvectors of the Hamiltonian

        H = [[A, −FFᵀ], [−Cᵀ R⁻¹ C / Δt, −Aᵀ]]

    belonging to the n eigenvalues of largest real part, split into upper and lower blocks
    E₁, E₂; P = −Re(E₁ E₂⁻¹). Same arguments as ``riccati_solution``.
    """
    a, c, ffT, r_diag = _check(a, c, ffT, r_diag, dt)
    n = a.shape[0]
    ctrc = c.T @ (c / r_diag[:, None]) / dt
    hamiltonian = np.block([[a, -ffT], [-ctrc, -a.T]])
    values, vectors = np.linalg.eig(hamiltonian)
    order = np.argsort(values.real)[::-1][:n]
    e1, e2 = vectors[:n, order], vectors[n:, order]
    try:
        # P = −Re(E₁ E₂⁻¹)
        p = -np.real(np.linalg.solve(e2.T, e1.T).T)
    except np.linalg.LinAlgError as exc:
        raise RiccatiError(f"Potter's method: E₂ is singular ({exc})") from None
    return 0.5 * (p + p.T)


def steady_state_gain(
    a: np.ndarray, c: np.ndarray, f_matrix: np.ndarray, r_diag: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """K = P Cᵀ R⁻¹ with P from CARE (Potter's method; the Schur solver if that fails).

    Args:
        a: the linearised system's state matrix A (n × n).
        c: the linearised system's output matrix C (m × n).
        f_matrix: the process-noise distribution matrix F (n × q).
        r_diag: R's diagonal (m,).
        dt: Δt, s.

    Returns:
        The gain K (n × m) and the state prediction covariance P (n × n), as the pair (K, P).
    """
    f_matrix = np.atleast_2d(np.asarray(f_matrix, dtype=float))
    # Potter's method: one eigen-decomposition of the 2n × 2n Hamiltonian, about 100× faster
    # than the Schur solver for the small systems here; tests check it against scipy's
    p = potter_solution(a, c, f_matrix @ f_matrix.T, r_diag, dt)
    if not np.all(np.isfinite(p)) or np.any(
        np.linalg.eigvalsh(p) < -1e-12 * max(1.0, np.abs(p).max())
    ):
        p = riccati_solution(a, c, f_matrix @ f_matrix.T, r_diag, dt)
    # K = P Cᵀ R⁻¹
    k = (p @ np.atleast_2d(c).T) / np.asarray(r_diag, dtype=float)[None, :]
    return k, p
