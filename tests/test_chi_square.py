"""The χ² survival function of the whiteness test (flightid.accuracy.chi_square) against two
independent references: mpmath's regularized incomplete gamma at 40 digits (the exact
value) and scipy.special.chdtrc, over degrees of freedom 1 … 2000 and arguments from far
below the mean to deep in the upper tail."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import chdtrc

from flightid.accuracy.chi_square import chi_square_survival

DOFS = [*range(1, 41), 57, 100, 169, 170, 171, 338, 339, 340, 500, 999, 1000, 1500, 2000]


def _arguments(dof: int) -> np.ndarray:
    """Far below the mean, around it (−5 … +40 σ) and far above it."""
    around = dof + math.sqrt(2 * dof) * np.linspace(-5, 40, 46)
    xs = np.concatenate([dof * np.geomspace(1e-6, 0.5, 12), around, dof * np.geomspace(2, 60, 12)])
    return xs[xs > 0]


def test_agrees_with_the_exact_value():
    mpmath = pytest.importorskip("mpmath")
    mpmath.mp.dps = 40
    worst = 0.0
    for dof in DOFS:
        for x in _arguments(dof):
            exact = float(
                mpmath.gammainc(mpmath.mpf(dof) / 2, mpmath.mpf(float(x)) / 2, mpmath.inf,
                                regularized=True)
            )  # fmt: skip
            if 1e-300 < exact < 1.0:
                worst = max(worst, abs(chi_square_survival(dof, x) - exact) / exact)
    # scipy's chdtrc is 2e-12 from the exact value at worst on this grid
    assert worst < 5e-13


def test_agrees_with_scipy():
    for dof in DOFS:
        xs = _arguments(dof)
        expected = chdtrc(dof, xs)
        got = chi_square_survival(dof, xs)
        assert got.shape == xs.shape
        shown = expected > 1e-300
        np.testing.assert_allclose(got[shown], expected[shown], rtol=5e-12, atol=0)
        # below 1e-300 both are (near) zero
        assert np.all(got[~shown] < 1e-290)


def test_edges_and_broadcasting():
    assert chi_square_survival(3, 0.0) == 1.0
    assert chi_square_survival(3, -2.0) == 1.0
    assert chi_square_survival(3, math.inf) == 0.0
    assert math.isnan(chi_square_survival(3, math.nan))
    assert math.isnan(chi_square_survival(0, 1.0))
    assert isinstance(chi_square_survival(4, 2.5), float)
    # χ²(2): P(X > q) = e^(−q/2) exactly
    q = np.array([[0.1, 1.0], [10.0, 100.0]])
    np.testing.assert_allclose(chi_square_survival(2, q), np.exp(-q / 2), rtol=1e-15)
    # χ²(1): erfc(√(q/2)); broadcasting over the degrees of freedom
    assert chi_square_survival(1, 2.0) == math.erfc(1.0)
    np.testing.assert_allclose(
        chi_square_survival(np.array([1, 2, 3]), 2.0), chdtrc([1, 2, 3], 2.0), rtol=1e-13
    )
