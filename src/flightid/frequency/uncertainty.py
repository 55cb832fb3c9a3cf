"""Standard errors of the frequency-domain estimators: what a frequency grid finer than 1/T
does to the information, and the coloured-residual (sandwich) covariance.

Correlation of a finite Fourier transform across the grid. White noise v_i of variance σ²
sampled at Δt has, over a record of N samples (T = NΔt), the transform V(f) = Δt Σ_i v_i
e^{−j2πfτ_i} with

    E[V(f_k) V*(f_l)] = σ² Δt² Σ_i e^{−j2π(f_k − f_l)τ_i} = σ² Δt T · ρ(f_k − f_l),
    ρ(δ) = e^{−jπδ(T−Δt)} sin(πδT) / (N sin(πδΔt))            (ρ(0) = 1)

(the Dirichlet kernel). ρ vanishes at δ = m/T, m ≠ 0: on a grid of step 1/T (or a multiple
of it) the transforms are uncorrelated and the Cramér–Rao bound, which counts every
frequency as an independent measurement, is right. On a grid of step Δf < 1/T they are
not: the least-squares estimate θ̂ = H⁻¹ Σ_k J_kᴴ ε_k, H = Σ_k J_kᴴ J_k, has the covariance

    Cov(θ̂) = H⁻¹ [Σ_k Σ_l J_kᴴ E(ε_k ε_lᴴ) J_l] H⁻¹
            ≈ H⁻¹ [Σ_k J_kᴴ s J_k Σ_l ρ(f_k − f_l)] H⁻¹         (J smooth over ~1/T)
            = c · s H⁻¹,        c = Σ_m ρ(mΔf) ≈ (1/Δf) ∫ ρ(δ) dδ = 1/(T Δf)

(the sum of the kernel over the grid is the number of grid points within one resolution
width 1/T). So the information of an oversampled grid is that of its T·Δf independent
fraction: a grid ten times finer than 1/T multiplies Σ_k J_kᴴ J_k by ten and would shrink
every σ by √10 = 3.16 if the bound counted every point; ``grid_factor`` returns
c = max(1, 1/(T·Δf)) per maneuver and the estimators compute

    Cov_CR(θ̂) = H⁻¹ [Σ_m c_m H_m] H⁻¹            (H_m: maneuver m's part of H)

which is c·H⁻¹ for one maneuver and does not depend on the grid step below 1/T. Coarser
grids (Δf ≥ 1/T) keep c = 1: their points are (nearly) uncorrelated, and they simply use
fewer of the record's independent frequencies.

Coloured residuals. Model error, noise in the regressors and the grid correlation above
make the residuals correlated across frequency and of unequal size; the sandwich

    Cov_c(θ̂) = H⁻¹ [Σ_k Σ_l J_kᵀ R̂(k − l) J_l] H⁻¹,     R̂(m) = (1/K) Σ_k r_{k+m} r_kᵀ

per maneuver, all lags, on the real-stacked rows r_k (and J_k) of frequency k (Morelli &
Klein, "Determining the accuracy of maximum likelihood parameter estimates with colored
residuals", NASA CR-194893, 1994, here along the frequency index) estimates the covariance
from the residuals themselves. ``sandwich_middle`` evaluates the double sum in O(K log K)
with the cross-correlation theorem: with zero-padded FFTs F_J (over k, per row component a
and parameter i) and F_r of length L ≥ 2K − 1,

    Σ_m Σ_l J_{l+m}ᵀ R̂(m) J_l = (1/(K L)) Re Σ_f g(f) g(f)ᴴ,    g_i(f) = Σ_a F_J[f, a, i] F̄_r[f, a]

For white residuals of equal size R̂(m ≠ 0) → 0 and it tends to the Cramér–Rao bound at
step 1/T.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from flightid.frequency.fourier import ManeuverSpectra

__all__ = ["grid_factor", "grid_factors", "sandwich_middle", "sandwich_covariance"]


def grid_factor(frequencies_hz: np.ndarray, duration_s: float) -> float:
    """c = max(1, 1/(T·Δf)): how many grid points share one independent frequency of a
    record of length T (s); Δf is the median spacing of the (sorted) frequencies (Hz)."""
    f = np.sort(np.asarray(frequencies_hz, dtype=float))
    if f.size < 2 or not duration_s > 0:
        return 1.0
    step = float(np.median(np.diff(f)))
    if not step > 0:
        return 1.0
    # c = max(1, 1/(T Δf))
    return max(1.0, 1.0 / (duration_s * step))


def grid_factors(spectra: Sequence[ManeuverSpectra]) -> np.ndarray:
    """``grid_factor`` of each maneuver's frequencies and record length."""
    return np.array([grid_factor(s.frequencies_hz, s.duration_s) for s in spectra])


def sandwich_middle(jacobian: np.ndarray, residuals: np.ndarray) -> np.ndarray:
    """Σ_m Σ_l J_{l+m}ᵀ R̂(m) J_l over all lags of one maneuver (p, p).

    Args:
        jacobian: (K, w, p) real rows of the K frequencies (w real components each).
        residuals: (K, w) the real-stacked residuals of the same frequencies.
    """
    k_count = jacobian.shape[0]
    length = int(2 ** np.ceil(np.log2(max(2 * k_count - 1, 1))))
    # zero-padded transforms along the frequency index
    f_j = np.fft.rfft(jacobian, n=length, axis=0)
    f_r = np.fft.rfft(residuals, n=length, axis=0)
    # g_i(f) = Σ_a F_J[f, a, i] conj(F_r[f, a])
    g = np.einsum("fai,fa->fi", f_j, f_r.conj())
    # full-spectrum sum from the half spectrum of real sequences: bins 1 … L/2 − 1 twice
    weights = np.full(g.shape[0], 2.0)
    weights[0] = 1.0
    if length % 2 == 0:
        weights[-1] = 1.0
    # (1/(K L)) Re Σ_f g gᴴ
    return np.real(np.einsum("f,fi,fj->ij", weights, g, g.conj())) / (k_count * length)


def sandwich_covariance(
    jacobian_blocks: Sequence[np.ndarray], residual_blocks: Sequence[np.ndarray]
) -> np.ndarray:
    """Cov_c = H⁻¹ [Σ_maneuvers sandwich_middle] H⁻¹, H = Σ JᵀJ (lags never cross from
    one maneuver to the next)."""
    p = jacobian_blocks[0].shape[2]
    H = np.zeros((p, p))
    middle = np.zeros((p, p))
    for jac, res in zip(jacobian_blocks, residual_blocks, strict=True):
        flat = jac.reshape(-1, p)
        H += flat.T @ flat
        middle += sandwich_middle(jac, res)
    H_inv = np.linalg.inv(H)
    return H_inv @ middle @ H_inv


def grid_corrected_inverse(
    jacobian_blocks: Sequence[np.ndarray], factors: Sequence[float]
) -> np.ndarray:
    """H⁻¹ [Σ_m c_m H_m] H⁻¹ with H_m = J_mᵀ J_m and H = Σ_m H_m (the Cramér–Rao inverse
    information of an unweighted fit whose maneuver m counts c_m grid points per
    independent frequency; see the module docstring)."""
    p = jacobian_blocks[0].shape[-1]
    H = np.zeros((p, p))
    weighted = np.zeros((p, p))
    for jac, c in zip(jacobian_blocks, factors, strict=True):
        flat = jac.reshape(-1, p)
        block = flat.T @ flat
        H += block
        weighted += float(c) * block
    H_inv = np.linalg.inv(H)
    return H_inv @ weighted @ H_inv
