"""The coloured-residual covariance (``flightid.accuracy.coloured_covariance``, computed with
one matrix product per lag since issue 14) against the sandwich written out term by term:

    Cov = M⁻¹ [Σ_i Σ_j A_iᵀ R̂_ν(j − i) A_j] M⁻¹,  A_i = R⁻¹ G_i,  R̂_ν(−k) = R̂_ν(k)ᵀ,

with |i − j| ≤ L and i, j in the same maneuver (Morelli & Klein §6.4; the module docstring).
Seeded random sensitivities and random-walk (coloured) residuals, two maneuvers.
"""

from __future__ import annotations

import numpy as np
import pytest

from flightid.accuracy.coloured import coloured_covariance, residual_autocovariance


def _double_sum(g, nu, r_diag, covariance, lag, maneuver):
    a = g / r_diag[None, :, None]
    gamma = residual_autocovariance(nu, lag, maneuver)
    n, n_f = nu.shape[0], g.shape[2]
    middle = np.zeros((n_f, n_f))
    for i in range(n):
        for j in range(max(0, i - lag), min(n, i + lag + 1)):
            if maneuver[i] != maneuver[j]:
                continue
            k = j - i
            r_k = gamma[k] if k >= 0 else gamma[-k].T
            middle += a[i].T @ r_k @ a[j]
    sandwich = covariance @ middle @ covariance
    return 0.5 * (sandwich + sandwich.T)


@pytest.mark.parametrize("lag", [0, 1, 7, 40])
def test_coloured_covariance_equals_the_double_sum(lag):
    rng = np.random.default_rng(11)
    n, n_o, n_f = 300, 3, 4
    g = rng.standard_normal((n, n_o, n_f))
    nu = np.cumsum(rng.standard_normal((n, n_o)), axis=0) * 0.1
    nu -= nu.mean(axis=0)
    r_diag = np.array([1.0, 2.0, 0.5])
    covariance = np.linalg.inv(np.einsum("iok,o,iol->kl", g, 1.0 / r_diag, g))
    maneuver = np.repeat([0, 1], [170, 130])
    result, used = coloured_covariance(g, nu, r_diag, covariance, lag, maneuver)
    expected = _double_sum(g, nu, r_diag, covariance, lag, maneuver)
    assert used == lag
    np.testing.assert_allclose(result, expected, rtol=1e-12, atol=1e-14 * np.abs(expected).max())
