"""Extended Kalman filter on the augmented state x_a = (x, θ) (Jategaonkar, *Flight Vehicle
System Identification*, 2nd ed., ch. 7.3; FVSysID's ``ekf_mod``).

At k = 1 there is no prediction: x̃_1 = x_a0, P̃_1 = P0. For k ≥ 2:

    x̃_k = RK4 of x̂_{k−1} over [t_{k−1}, t_k]            (inputs u_{k−1}, u_k)
    A   = ∂f_a/∂x_a at (x̂_{k−1}, u_{k−1})                 central differences, step h
    Φ   = Σ_{j=0..10} (A dt)^j / j!                        truncated series of e^{A dt}
    P̃_k = Φ P̂_{k−1} Φᵀ + Q,   Q = diag(Q_states, 0, …, 0)  (per step, not × dt)

Correction at every sample:

    C   = ∂g/∂x_a at (x̃_k, u_k)
    S   = C P̃ Cᵀ + R0,   K = P̃ Cᵀ S⁻¹
    x̂_k = x̃_k + K (z_k − g(x̃_k, u_k))
    P̂_k = (I − KC) P̃ (I − KC)ᵀ + K R0 Kᵀ                 (Joseph form)

R0 stays fixed. With no free parameter this is the ordinary EKF of the model (for a linear
model: the linear Kalman filter with transition matrix Φ).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from flightid.errors import InputError, describe
from flightid.recursive.augmented import AugmentedModel, absolute_steps
from flightid.recursive.augmented_filter import AugmentedFilter
from flightid.recursive.base import float_array

__all__ = ["ExtendedKalmanFilter", "transition_series"]

SERIES_TERMS = 10


def transition_series(A: np.ndarray, dt: float, terms: int = SERIES_TERMS) -> np.ndarray:
    """Φ = Σ_{j=0..terms} (A dt)^j / j!  (the reference's truncated matrix exponential)."""
    Adt = A * dt
    term = np.eye(A.shape[0])
    phi = term.copy()
    for j in range(1, terms + 1):
        # (A dt)^j / j! = (A dt)^{j−1}/(j−1)! · (A dt) / j
        term = term @ Adt / j
        phi += term
    return phi


class ExtendedKalmanFilter(AugmentedFilter):
    """EKF with the parameters in the state.

    Args:
        augmented: the augmented model (``AugmentedModel``).
        p0: initial covariance, a number (× I) or n diagonal values.
        q_states: per-step process-noise covariance of the states (number or n_x values);
            the parameters get none.
        r0: measurement-noise covariance, a number (× I) or n_y diagonal values.
        jacobian_step: absolute central-difference step h (number or n values).
    """

    method = "ekf"

    def __init__(
        self,
        augmented: AugmentedModel,
        p0: float | Sequence[float],
        q_states: float | Sequence[float],
        r0: float | Sequence[float],
        jacobian_step: float | Sequence[float] = 1e-4,
    ) -> None:
        super().__init__(augmented, p0)
        self.Q, self.R0 = self._additive_noise(q_states, r0)
        n = augmented.n
        steps = float_array(jacobian_step, "jacobian_step", f"a positive number or {n} of them")
        if steps.ndim > 1 or (steps.ndim == 1 and steps.size != n) or not np.all(steps > 0):
            raise InputError(
                f"jacobian_step: expected a positive number or {n} positive numbers, got "
                f"{describe(jacobian_step)}"
            )
        self.h = absolute_steps(augmented.x_a0, steps)

    def _correct(self, t: float, x_pred: np.ndarray, P_pred: np.ndarray, u, z) -> None:
        aug = self.augmented
        C = aug.output_jacobian(x_pred, u, self.h, t)
        y_pred = aug.outputs(x_pred[None, :], u, t)[0]
        # S = C P̃ Cᵀ + R0
        S = C @ P_pred @ C.T + self.R0
        # K = P̃ Cᵀ S⁻¹
        K = np.linalg.solve(S, C @ P_pred).T
        nu = z - y_pred
        self._innovation(nu, S)
        # x̂ = x̃ + K (z − g(x̃, u))
        x = x_pred + K @ nu
        # P̂ = (I − KC) P̃ (I − KC)ᵀ + K R0 Kᵀ
        I_KC = np.eye(aug.n) - K @ C
        P = I_KC @ P_pred @ I_KC.T + K @ self.R0 @ K.T
        self.x, self.P = self._checked(x, P)

    def _first(self, t, u, z) -> None:
        # k = 1: x̃_1 = x_a0, P̃_1 = P0 (no prediction, no Q)
        self._correct(t, self.x, self.P, u, z)

    def _step(self, t_prev, t, u_prev, u, z) -> None:
        aug = self.augmented
        dt = t - t_prev
        x_pred = aug.rk4(self.x[None, :], u_prev, u, dt, t_prev)[0]
        A = aug.state_jacobian(self.x, u_prev, self.h, t_prev)
        phi = transition_series(A, dt)
        # P̃ = Φ P̂ Φᵀ + Q
        P_pred = phi @ self.P @ phi.T + self.Q
        self._correct(t, x_pred, P_pred, u, z)
