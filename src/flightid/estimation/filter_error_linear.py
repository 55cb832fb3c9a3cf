"""``LinearFilterErrorProblem``: the filter error method for linear models with the exact
discretisation and analytic sensitivities (``flightid.filtering.linear``; as FVSysID's
``ml_fem_lin2``, Jategaonkar ch. 5).

Filter passes use Φ = e^{AΔt}, Ψ (not RK4), and ``sensitivities`` returns H = ∂ỹ/∂θ from
the differentiated Riccati equation (Lyapunov) and the differentiated filter recursion: one
filter pass plus the sensitivity recursion per Gauss–Newton step instead of n_f filter
passes. MNR, the fixed-point relaxation and the Cramér–Rao bounds all go through
``sensitivities``. Pinned F elements (the active constraint diag(KC) = 1) fall back to
finite differences of filter passes.
"""

from __future__ import annotations

import numpy as np

from flightid.errors import InputError
from flightid.estimation.filter_error_problem import KC_TOLERANCE, FilterErrorProblem
from flightid.filtering.kalman import RiccatiError
from flightid.filtering.linear import (
    check_linear,
    covariance_derivative,
    linear_filter,
    linear_filter_sensitivities,
    matrix_derivatives,
    system_matrices,
)
from flightid.simulation.simulator import SimulationBatch


class LinearFilterErrorProblem(FilterErrorProblem):
    """``FilterErrorProblem`` for a model linear in states and inputs (same arguments).

    Raises:
        NotLinearError: f or h is not linear in x and u.
        InputError: parameters substituted per maneuver (not supported here).
    """

    def __init__(self, model, data, process_noise, **settings) -> None:
        super().__init__(model, data, process_noise, **settings)
        maps = [m for m in self._theta_maps if m is not None]
        if any(not np.array_equal(m, maps[0]) for m in maps[1:]):
            raise InputError(
                "model: analytic filter gradients do not support per-maneuver parameters"
            )
        self._n_x, self._n_u = len(model.states), len(model.inputs)
        check_linear(
            model.f, model.h, self._f_theta(self.theta_start_full, 0), self._n_x, self._n_u
        )
        self.sensitivity_passes = 0

    def matrices(self, full: np.ndarray) -> tuple[np.ndarray, ...]:
        """(A, B, b_x, C, D, b_y) at the full parameter vector."""
        theta = self._f_theta(full, 0)
        return system_matrices(self.model.f, self.model.h, theta, self._n_x, self._n_u)

    def run(self, theta_free_batch: np.ndarray, check_kc: bool = True) -> SimulationBatch:
        """Filter passes (exact discretisation) for a batch (B, n_f): B evaluations."""
        full = self.full_theta(np.atleast_2d(theta_free_batch))
        n_batch, n_o = full.shape[0], len(self.model.outputs)
        outputs = np.full((n_batch, self.n_samples, n_o), np.nan)
        diverged = np.zeros(n_batch, dtype=bool)
        messages = [""] * n_batch
        for b in range(n_batch):
            try:
                theta = self.complete(full[b])
                point = self._filter_point(theta)
            except RiccatiError as exc:
                diverged[b], messages[b] = True, f"no steady-state gain: {exc}"
                continue
            if check_kc and np.any(point.kc > 1.0 + KC_TOLERANCE):
                diverged[b] = True
                messages[b] = f"the gain violates diag(KC) ≤ 1 (diag(KC) = {point.kc})"
                continue
            outputs[b] = self._pass(theta, point.gain)
            if not np.all(np.isfinite(outputs[b])):
                diverged[b], messages[b] = True, "filter pass diverged"
        outputs[diverged] = np.nan
        self.filter_passes += n_batch
        return SimulationBatch(outputs, diverged, tuple(messages))

    def _pass(self, full: np.ndarray, gain: np.ndarray) -> np.ndarray:
        matrices = self.matrices(full)
        blocks = [
            linear_filter(matrices, gain, self._x0(full, i), u, z, self.dt)
            for i, (u, z) in enumerate(zip(self._inputs, self._measured, strict=True))
        ]
        return np.concatenate(blocks)

    def gain_derivatives(self, full: np.ndarray, derivatives: tuple[np.ndarray, ...], index):
        """(K, P, ∂P, ∂K) for the parameters ``index`` of ``full`` (last axis), R = the
        weighting; ``derivatives`` are the matrices' derivatives along the same ``index``."""
        point = self._filter_point(full)
        a, _, _, c, _, _ = self.matrices(full)
        da, dc = derivatives[0], derivatives[3]
        r_diag = self.gain_r
        f_matrix = self.f_matrix(full)
        n_p = len(index)
        dp = np.empty((self._n_x, self._n_x, n_p))
        dk = np.empty((self._n_x, c.shape[0], n_p))
        for j, parameter_index in enumerate(index):
            df = np.zeros_like(f_matrix)
            for state, parameter in zip(self.noise_states, self.noise_parameters, strict=True):
                if parameter == parameter_index:
                    df[state, state] = 1.0
            # ∂(FFᵀ) = ∂F Fᵀ + F ∂Fᵀ
            dffT = df @ f_matrix.T + f_matrix @ df.T
            dp[..., j] = covariance_derivative(
                a, c, point.covariance, r_diag, self.dt, da[..., j], dc[..., j], dffT
            )
            # ∂K = ∂P Cᵀ R⁻¹ + P ∂Cᵀ R⁻¹
            dk[..., j] = (dp[..., j] @ c.T + point.covariance @ dc[..., j].T) / r_diag
        return point.gain, point.covariance, dp, dk

    def analytic_sensitivities(self, theta_free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(H (N, n_o, n_f), ỹ (N, n_o)) at ``theta_free``: one filter pass's work.

        Pinned F elements (diag(KC)_i = 1 for every θ) enter by the implicit function
        theorem: ∂F_pin/∂θ = −(∂kc_pin/∂F_pin)⁻¹ ∂kc_pin/∂θ with kc = diag(KC), and every
        derivative gains the term ∂/∂F_pin · ∂F_pin/∂θ.
        """
        full = self.complete(self.full_theta(np.asarray(theta_free, dtype=float)))
        matrices = self.matrices(full)
        pinned_index = np.array([self.noise_parameters[i] for i in self.pinned], dtype=int)
        index = np.concatenate([self.free_index, pinned_index])
        derivatives = matrix_derivatives(self.matrices, full, index)
        gain, _, _, dgain = self.gain_derivatives(full, derivatives, index)
        n_f = self.free_index.size
        if pinned_index.size:
            c, dc = matrices[3], derivatives[3]
            rows = [self.noise_states[i] for i in self.pinned]
            # ∂diag(KC) = diag(∂K C + K ∂C)
            dkc = np.einsum("imp,mi->ip", dgain, c) + np.einsum("im,mip->ip", gain, dc)
            dkc = dkc[rows]
            # ∂F_pin/∂θ = −(∂kc_pin/∂F_pin)⁻¹ ∂kc_pin/∂θ
            chain = -np.linalg.solve(dkc[:, n_f:], dkc[:, :n_f])
            derivatives = tuple(d[..., :n_f] + d[..., n_f:] @ chain for d in derivatives)
            dgain = dgain[..., :n_f] + dgain[..., n_f:] @ chain
        ys, gs = [], []
        free = list(self.free_index)
        for i, (u, z) in enumerate(zip(self._inputs, self._measured, strict=True)):
            _, x0_index = self._x0_maps[i]
            dx0 = np.zeros((self._n_x, n_f))
            for state, position in enumerate(x0_index):
                if position >= 0 and position in free:
                    dx0[state, free.index(position)] = 1.0
            y, g = linear_filter_sensitivities(
                matrices, derivatives, gain, dgain, self._x0(full, i), dx0, u, z, self.dt
            )
            ys.append(y)
            gs.append(g)
        self.filter_passes += 1
        self.sensitivity_passes += 1
        return np.concatenate(gs), np.concatenate(ys)

    def sensitivities(self, theta_free, outputs=None, relative_step=1e-6, central=False):
        """Analytic H (``analytic_sensitivities``)."""
        return self.analytic_sensitivities(theta_free)

    def sensitivities_from_equations(self, theta_free, relative_step=1e-7):
        """The same analytic H."""
        return self.sensitivities(theta_free)
