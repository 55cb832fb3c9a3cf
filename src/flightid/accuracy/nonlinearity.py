"""Beale's intrinsic nonlinearity measure N_φ [RP-1153 5.31–5.43].

The solution locus P(θ) = {y_i(θ)} is compared with its tangent plane at θ̂. Take W = 2·n_p
points θ_w = θ̂ ± c·σ_j·e_j (each free parameter moved both ways by c of its standard error
σ_j; c = 1 by default, configurable — the factor in the scan of [5.43] is unreadable; ``assess``
passes the standard errors s·√(M⁻¹)_jj, which equal the Cramér–Rao bounds when R = R̂). With
δY_i,w = y_i(θ_w) − y_i(θ̂) and the sensitivities G_i at θ̂:

    φ_w = (Σ_i G_iᵀR⁻¹G_i)⁻¹ Σ_i G_iᵀR⁻¹ δY_i,w                     [5.41]  (foot of perpendicular)
    Q_φ = Σ_w Σ_i (δY_i,w − G_i φ_w)ᵀ R⁻¹ (δY_i,w − G_i φ_w)         [5.39]
    D   = Σ_w ( Σ_i δY_i,wᵀ R⁻¹ δY_i,w )²                          [5.35]
    N_φ = n_p s² Q_φ / D                                            [5.34]

with s² = J(θ̂)/(N·n_o − n_p) [5.30]. N_φ = 0 for a model linear in θ. Parameters with an
infinite bound (undetermined) cannot be perturbed and are left out (W shrinks).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightid.accuracy.levels import beale_factor
from flightid.errors import InputError
from flightid.estimation.problem import OutputErrorProblem

__all__ = ["Nonlinearity", "beale_nonlinearity"]


@dataclass(frozen=True)
class Nonlinearity:
    """Beale's measure and its ingredients."""

    n_phi: float  # N_φ [5.34], dimensionless
    q_phi: float  # Q_φ [5.39]
    d: float  # D [5.35]
    s2: float  # s² [5.30]
    perturbation: float  # c: points at θ̂ ± c σ_j e_j
    points: int  # W
    beale_factor: float  # 1 + N n_o (n_p + 2)/((N n_o − n_p) n_p) N_φ [5.29]
    evaluations: int  # integrations spent (W + 1)

    def to_dict(self) -> dict:
        return {
            "N_phi": float(self.n_phi),
            "Q_phi": float(self.q_phi),
            "D": float(self.d),
            "s2": float(self.s2),
            "perturbation_sigmas": float(self.perturbation),
            "points": int(self.points),
            "beale_factor": float(self.beale_factor),
            "evaluations": int(self.evaluations),
        }


def beale_nonlinearity(
    problem: OutputErrorProblem,
    theta_hat: np.ndarray,
    sensitivities: np.ndarray,
    r_diag: np.ndarray,
    std: np.ndarray,
    s2: float,
    perturbation: float = 1.0,
) -> Nonlinearity:
    """N_φ at θ̂ with W = 2·n_p points perturbed by ``perturbation``·σ_j.

    Args:
        problem: the output-error problem (free parameters = θ).
        theta_hat: θ̂ (n_f,).
        sensitivities: G at θ̂ (N, n_o, n_f).
        r_diag: R (n_o,).
        std: σ_j (n_f,), the standard errors; inf entries are skipped.
        s2: s² [5.30].
        perturbation: c > 0, in standard errors.
    """
    if not (np.isfinite(perturbation) and perturbation > 0):
        raise InputError(f"perturbation: expected a positive multiple of σ, got {perturbation!r}")
    theta_hat = np.asarray(theta_hat, dtype=float)
    std = np.asarray(std, dtype=float)
    usable = np.flatnonzero(np.isfinite(std) & (std > 0))
    n_free = theta_hat.size
    if usable.size == 0:
        nan = float("nan")
        return Nonlinearity(nan, nan, nan, s2, perturbation, 0, nan, 0)
    start = problem.evaluations
    steps = perturbation * std[usable]
    # θ_w = θ̂ ± c σ_j e_j                                               [5.43]
    points = np.repeat(theta_hat[None, :], 2 * usable.size + 1, axis=0)
    rows = np.arange(usable.size)
    points[1 + rows, usable] += steps
    points[1 + usable.size + rows, usable] -= steps
    outputs = problem.outputs(points)
    if not np.all(np.isfinite(outputs)):
        raise InputError(
            "perturbation: a point θ̂ ± c·σ_j e_j makes the simulation diverge; "
            "use a smaller perturbation"
        )
    weight = 1.0 / np.sqrt(np.asarray(r_diag, dtype=float))
    # δY_i,w = y_i(θ_w) − y_i(θ̂), weighted by R^(−½) and stacked over (i, k)
    delta_y = ((outputs[1:] - outputs[0][None]) * weight[None, None, :]).reshape(
        outputs.shape[0] - 1, -1
    )
    a = (np.asarray(sensitivities, dtype=float) * weight[None, :, None]).reshape(-1, n_free)
    a = a[:, usable]
    # φ_w = (Σ GᵀR⁻¹G)⁻¹ Σ GᵀR⁻¹ δY_w  (least squares on the weighted, stacked rows)  [5.41]
    phi, *_ = np.linalg.lstsq(a, delta_y.T, rcond=None)
    off_plane = delta_y.T - a @ phi
    # Q_φ = Σ_w Σ_i (δY − Gφ)ᵀ R⁻¹ (δY − Gφ)                            [5.39]
    q_phi = float(np.sum(off_plane**2))
    # D = Σ_w (Σ_i δYᵀ R⁻¹ δY)²                                          [5.35]
    d = float(np.sum(np.sum(delta_y**2, axis=1) ** 2))
    # N_φ = n_p s² Q_φ / D                                                [5.34]
    n_phi = n_free * s2 * q_phi / d if d > 0 else float("nan")
    n_data = outputs.shape[1] * outputs.shape[2]
    return Nonlinearity(
        n_phi=float(n_phi),
        q_phi=q_phi,
        d=d,
        s2=float(s2),
        perturbation=float(perturbation),
        points=int(2 * usable.size),
        beale_factor=beale_factor(n_phi, n_data, n_free),
        evaluations=problem.evaluations - start,
    )
