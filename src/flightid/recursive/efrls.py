"""Extended forgetting-factor recursive least squares on the augmented state (Jategaonkar,
*Flight Vehicle System Identification*, 2nd ed., ch. 7.5; FVSysID's ``efrls_mod``).

No noise covariances: the gain comes from a forgetting-factor RLS matrix P (start P0·I), with
λ < 1 discounting old samples. No correction at k = 1 (x̂_1 = x_a0). For k ≥ 2:

    x̃_k = RK4 of x̂_{k−1}                                  (u_{k−1}, u_k)
    A   = ∂f_a/∂x_a at (x̂_{k−1}, u_{k−1}),  C = ∂g/∂x_a at (x̂_{k−1}, u_k)
          (central differences, h_j = s·|x̂_j|, s if zero; C at the previous corrected state)
    Φ   = e^{A dt}                                          (scipy.linalg.expm)
    S   = λ I + C Φ P Φᵀ Cᵀ,   k = P Φᵀ Cᵀ S⁻¹
    x̂_k = x̃_k + Φ k (z_k − g(x̃_k, u_k))
    P   ← λ⁻¹ Φ (I − k C Φ) P Φᵀ

The reported std is sqrt(diag P) of this matrix: a scaled RLS quantity, not a noise-based
covariance (its size depends on P0 and λ, not on the data's noise).
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from flightid.errors import InputError, describe
from flightid.recursive.augmented import AugmentedModel, relative_steps
from flightid.recursive.augmented_filter import AugmentedFilter

__all__ = ["ExtendedForgettingRLS"]


def _real_number(value: object) -> bool:
    """True for an int or float (numpy's too), not a bool."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_)
    )


class ExtendedForgettingRLS(AugmentedFilter):
    """EFRLS with forgetting factor ``forgetting`` (0 < λ ≤ 1), start matrix ``p0``·I and
    relative Jacobian step ``jacobian_step``."""

    method = "efrls"

    def __init__(
        self,
        augmented: AugmentedModel,
        p0: float = 1e3,
        forgetting: float = 0.998,
        jacobian_step: float = 1e-7,
    ) -> None:
        super().__init__(augmented, p0)
        if np.any(np.diag(self.P0) <= 0):
            raise InputError(f"p0: expected a start matrix > 0 (× I), got {describe(p0)}")
        if not (_real_number(forgetting) and 0.0 < forgetting <= 1.0):
            raise InputError(f"forgetting: expected a number in (0, 1], got {forgetting!r}")
        if not (_real_number(jacobian_step) and np.isfinite(jacobian_step) and jacobian_step > 0):
            raise InputError(f"jacobian_step: expected a positive number, got {jacobian_step!r}")
        self.forgetting = float(forgetting)
        self.step_size = float(jacobian_step)

    def _first(self, t, u, z) -> None:
        # k = 1: no update, x̂_1 = x_a0
        return

    def _step(self, t_prev, t, u_prev, u, z) -> None:
        aug = self.augmented
        lam = self.forgetting
        dt = t - t_prev
        h = relative_steps(self.x, self.step_size)
        A = aug.state_jacobian(self.x, u_prev, h, t_prev)
        C = aug.output_jacobian(self.x, u, h, t)
        x_pred = aug.rk4(self.x[None, :], u_prev, u, dt, t_prev)[0]
        # Φ = e^{A dt}
        phi = linalg.expm(A * dt)
        C_phi = C @ phi
        # S = λI + C Φ P Φᵀ Cᵀ
        S = lam * np.eye(aug.n_y) + C_phi @ self.P @ C_phi.T
        # k = P Φᵀ Cᵀ S⁻¹
        gain = np.linalg.solve(S, C_phi @ self.P).T
        # (S is not an innovation covariance here: no innovation test for EFRLS)
        nu = z - aug.outputs(x_pred[None, :], u, t)[0]
        self._innovation(nu, None)
        # x̂ = x̃ + Φ k ν
        x = x_pred + phi @ (gain @ nu)
        # P ← λ⁻¹ Φ (I − k C Φ) P Φᵀ
        P = phi @ (np.eye(aug.n) - gain @ C_phi) @ self.P @ phi.T / lam
        self.x, self.P = self._checked(x, P)
