"""Unscented Kalman filters on the augmented state x_a = (x, θ) (Jategaonkar, *Flight Vehicle
System Identification*, 2nd ed., ch. 7.4): additive noise (``UnscentedKalmanFilter``, as
FVSysID's ``ukf_mod``) and noise augmentation (``AugmentedUnscentedKalmanFilter``, as
``ukf_mod_augmented``).

Sigma points of a mean m (dimension n) and covariance P, with α = 0.5, β = 2, κ = 3 − n:

    λ = α²(n + κ) − n,   γ = √(n + λ)
    X_0 = m,   X_i = m − γ·col_i(√P),   X_{n+i} = m + γ·col_i(√P)      (i = 1..n)
    W_m0 = λ/(n + λ),   W_c0 = W_m0 + 1 − α² + β,   W_mi = W_ci = 1/(2(n + λ))

√P is the symmetric principal square root (sqrtm, ``symmetric_sqrt``), not a Cholesky
factor. For a linear map these weights and points give the transformed mean and covariance
exactly: Σ W_m X_i = m and Σ W_c (X_i − m)(X_i − m)ᵀ = 2·W_ci·γ²·√P√Pᵀ = P.

Additive noise, each step k ≥ 2 (at k = 1 the points of (x_a0, P0) are used unpropagated,
but Q is still added):

    X_i ← RK4 of the sigma points of (x̂_{k−1}, P̂_{k−1})      (u_{k−1}, u_k; θ of the point)
    x̃ = Σ W_m X_i,          P_xx = Σ W_c (X_i − x̃)(X_i − x̃)ᵀ + Q
    Y_i = g(X_i, u_k),       ỹ = Σ W_m Y_i
    P_yy = Σ W_c (Y_i − ỹ)(Y_i − ỹ)ᵀ + R0,   P_xy = Σ W_c (X_i − x̃)(Y_i − ỹ)ᵀ
    K = P_xy P_yy⁻¹,   x̂ = x̃ + K (z_k − ỹ),   P̂ = P_xx − K P_yy Kᵀ

Noise augmentation: the sigma-point state is (x_a, w, v) of dimension n_a = n + n_x + n_y
(κ = 3 − n_a) with mean (x̂, 0, 0) and covariance blkdiag(P̂, diag(Q_states), R0) at every
step; each point is propagated with its own w added to ẋ (held over the RK4 step) and its
own v added to its output; P_xx and P_yy are the spreads alone (no + Q, + R0). Q_states is
there the variance of a noise on ẋ, not a per-step covariance of x as in the EKF and the
additive-noise UKF.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import linalg

from flightid.recursive.augmented import AugmentedModel
from flightid.recursive.augmented_filter import AugmentedFilter
from flightid.recursive.base import diagonal_matrix, symmetric_sqrt

__all__ = [
    "UnscentedKalmanFilter",
    "AugmentedUnscentedKalmanFilter",
    "unscented_weights",
    "sigma_points",
]

ALPHA = 0.5
BETA = 2.0


def unscented_weights(
    n: int, alpha: float = ALPHA, beta: float = BETA, kappa: float | None = None
) -> tuple[np.ndarray, np.ndarray, float]:
    """(W_m, W_c, γ) for dimension ``n`` (κ = 3 − n unless given); 2n + 1 weights each."""
    kappa = 3.0 - n if kappa is None else kappa
    # λ = α²(n + κ) − n
    lam = alpha**2 * (n + kappa) - n
    wm = np.full(2 * n + 1, 1.0 / (2.0 * (n + lam)))
    wc = wm.copy()
    # W_m0 = λ/(n + λ),  W_c0 = W_m0 + 1 − α² + β
    wm[0] = lam / (n + lam)
    wc[0] = wm[0] + 1.0 - alpha**2 + beta
    # γ = √(n + λ)
    return wm, wc, float(np.sqrt(n + lam))


def sigma_points(mean: np.ndarray, P: np.ndarray, gamma: float) -> np.ndarray:
    """(2n + 1) × n: m, m − γ·col_i(√P) (i = 1..n), m + γ·col_i(√P)."""
    root = symmetric_sqrt(P)
    # rows: X_0 = m, X_i = m − γ √P[:, i], X_{n+i} = m + γ √P[:, i]
    return np.vstack([mean[None, :], mean - gamma * root.T, mean + gamma * root.T])


def _spread(wc: np.ndarray, A: np.ndarray, a: np.ndarray, B: np.ndarray, b: np.ndarray):
    """Σ W_c (A_i − a)(B_i − b)ᵀ."""
    return (wc[:, None] * (A - a)).T @ (B - b)


class UnscentedKalmanFilter(AugmentedFilter):
    """UKF with additive process and measurement noise (settings as ``ExtendedKalmanFilter``,
    without the Jacobian step)."""

    method = "ukf"

    def __init__(
        self,
        augmented: AugmentedModel,
        p0: float | Sequence[float],
        q_states: float | Sequence[float],
        r0: float | Sequence[float],
    ) -> None:
        super().__init__(augmented, p0)
        self.Q, self.R0 = self._additive_noise(q_states, r0)
        self.wm, self.wc, self.gamma = unscented_weights(augmented.n)

    def _correct(self, t: float, X: np.ndarray, u, z) -> None:
        wm, wc = self.wm, self.wc
        # x̃ = Σ W_m X_i,  P_xx = Σ W_c (X_i − x̃)(·)ᵀ + Q
        x_pred = wm @ X
        P_xx = _spread(wc, X, x_pred, X, x_pred) + self.Q
        # Y_i = g(X_i, u_k),  ỹ = Σ W_m Y_i
        Y = self.augmented.outputs(X, u, t)
        y_pred = wm @ Y
        P_yy = _spread(wc, Y, y_pred, Y, y_pred) + self.R0
        P_xy = _spread(wc, X, x_pred, Y, y_pred)
        # K = P_xy P_yy⁻¹
        K = np.linalg.solve(P_yy, P_xy.T).T
        nu = z - y_pred
        self._innovation(nu, P_yy)
        # x̂ = x̃ + K (z − ỹ),  P̂ = P_xx − K P_yy Kᵀ
        self.x, self.P = self._checked(x_pred + K @ nu, P_xx - K @ P_yy @ K.T)

    def _first(self, t, u, z) -> None:
        # k = 1: the sigma points of (x_a0, P0), not propagated (Q still added)
        self._correct(t, sigma_points(self.x, self.P, self.gamma), u, z)

    def _step(self, t_prev, t, u_prev, u, z) -> None:
        X = sigma_points(self.x, self.P, self.gamma)
        X = self.augmented.rk4(X, u_prev, u, t - t_prev, t_prev)
        self._correct(t, X, u, z)


class AugmentedUnscentedKalmanFilter(AugmentedFilter):
    """UKF with the noises in the sigma-point state (x_a, w, v): ``q_states`` is the variance
    of a noise added to ẋ (number or n_x values), ``r0`` that of the output noise."""

    method = "ukf_aug"

    def __init__(
        self,
        augmented: AugmentedModel,
        p0: float | Sequence[float],
        q_states: float | Sequence[float],
        r0: float | Sequence[float],
    ) -> None:
        super().__init__(augmented, p0)
        self.Qw = diagonal_matrix(q_states, augmented.n_x, "q_states")
        self.R0 = diagonal_matrix(r0, augmented.n_y, "r0", positive=True)
        self.n_a = augmented.n + augmented.n_x + augmented.n_y
        self.wm, self.wc, self.gamma = unscented_weights(self.n_a)

    def _points(self) -> np.ndarray:
        """Sigma points of (x̂, 0, 0) with covariance blkdiag(P̂, Q, R0)."""
        aug = self.augmented
        mean = np.concatenate([self.x, np.zeros(aug.n_x + aug.n_y)])
        return sigma_points(mean, linalg.block_diag(self.P, self.Qw, self.R0), self.gamma)

    def _correct(self, t: float, XA: np.ndarray, u, z) -> None:
        aug = self.augmented
        wm, wc = self.wm, self.wc
        X = XA[:, : aug.n]
        V = XA[:, aug.n + aug.n_x :]
        x_pred = wm @ X
        # P_xx from the spread alone
        P_xx = _spread(wc, X, x_pred, X, x_pred)
        # Y_i = g(X_i, u_k) + v_i
        Y = aug.outputs(X, u, t) + V
        y_pred = wm @ Y
        P_yy = _spread(wc, Y, y_pred, Y, y_pred)
        P_xy = _spread(wc, X, x_pred, Y, y_pred)
        K = np.linalg.solve(P_yy, P_xy.T).T
        nu = z - y_pred
        self._innovation(nu, P_yy)
        self.x, self.P = self._checked(x_pred + K @ nu, P_xx - K @ P_yy @ K.T)

    def _first(self, t, u, z) -> None:
        # k = 1: the sigma points of (x_a0, 0, 0; P0, Q, R0), not propagated
        self._correct(t, self._points(), u, z)

    def _step(self, t_prev, t, u_prev, u, z) -> None:
        aug = self.augmented
        XA = self._points()
        W = XA[:, aug.n : aug.n + aug.n_x]
        # ẋ = f + w_i, w_i held over the step
        X = aug.rk4(XA[:, : aug.n], u_prev, u, t - t_prev, t_prev, w=W)
        self._correct(t, np.hstack([X, XA[:, aug.n :]]), u, z)
