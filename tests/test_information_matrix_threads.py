"""The information matrix is summed on one BLAS thread (a threaded product waited for a
busy core on a loaded machine), and equals Σ_i G_iᵀ R⁻¹ G_i computed independently."""

from __future__ import annotations

import contextlib

import numpy as np

from flightid.estimation import gauss_newton


def test_information_matrix_runs_on_one_blas_thread_and_is_gt_r_inverse_g(monkeypatch):
    entered = []
    original = gauss_newton.one_blas_thread

    @contextlib.contextmanager
    def spy():
        entered.append(True)
        with original():
            yield

    monkeypatch.setattr(gauss_newton, "one_blas_thread", spy)
    rng = np.random.default_rng(2)
    g = rng.normal(size=(3001, 4, 6))
    r_diag = np.array([0.5, 2.0, 1.0, 4.0])
    m = gauss_newton.information_matrix(g, r_diag)
    assert entered == [True]
    # independent reference: M_jl = Σ_i Σ_k G_ikj G_ikl / r_k
    reference = np.einsum("ikj,ikl,k->jl", g, g, 1.0 / r_diag)
    np.testing.assert_allclose(m, reference, rtol=1e-12)
