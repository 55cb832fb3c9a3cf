"""Smoothed differentiation and the equation-error coefficients."""

import numpy as np
import pytest

from flightid.errors import InputError
from flightid.regression import (
    Airframe,
    equation_error_signals,
    force_coefficients,
    moment_coefficients,
    smooth_derivative,
)
from flightid.regression.differentiate import default_window


@pytest.mark.parametrize(
    "freq_hz, interior_tol, total_tol",
    # bounds measured for order 4, 21-sample window at 0.02 s (documented in the module)
    [(0.5, 4e-4, 3e-3), (1.0, 6e-3, 2.5e-2)],
)
def test_derivative_of_a_sinusoid(freq_hz, interior_tol, total_tol):
    dt = 0.02
    t = np.arange(0.0, 10.0, dt)
    w = 2 * np.pi * freq_hz
    d = smooth_derivative(np.sin(w * t + 0.4), dt)
    err = np.abs(d - w * np.cos(w * t + 0.4)) / w  # closed form: d/dt sin = ω cos
    window = default_window(dt)
    assert window == 21
    assert err[window:-window].max() < interior_tol
    assert err.max() < total_tol


def test_derivative_is_exact_for_a_quartic_and_reduces_noise():
    dt = 0.05
    t = np.arange(0.0, 5.0, dt)
    x = 1 + 2 * t - t**2 + 0.3 * t**3 - 0.05 * t**4
    exact = 2 - 2 * t + 0.9 * t**2 - 0.2 * t**3
    np.testing.assert_allclose(smooth_derivative(x, dt), exact, atol=1e-9)
    noise = np.random.default_rng(0).normal(size=20000)
    raw = np.std(np.gradient(noise, 0.02))
    smooth = np.std(smooth_derivative(noise, 0.02))
    assert smooth < 0.2 * raw


def test_derivative_errors():
    with pytest.raises(InputError, match="window"):
        smooth_derivative(np.zeros(50), 0.1, window=4)
    with pytest.raises(InputError, match="dt"):
        smooth_derivative(np.zeros(50), -0.1)
    with pytest.raises(InputError, match="at least window"):
        smooth_derivative(np.zeros(5), 0.1)


def _forward_rotational(p, q, r, cl, cm, cn, qS, af):
    """RP-1153 §3 rotational equations (forward direction) to test the inversion."""
    gamma = af.Ix * af.Iz - af.Ixz**2
    F1 = (af.Iy - af.Iz) * q * r + af.Ixz * p * q + qS * af.b * cl
    F2 = (af.Ix - af.Iy) * p * q - af.Ixz * q * r + qS * af.b * cn
    pdot = (af.Iz * F1 + af.Ixz * F2) / gamma
    qdot = ((af.Iz - af.Ix) * p * r + af.Ixz * (r**2 - p**2) + qS * af.cbar * cm) / af.Iy
    rdot = (af.Ixz * F1 + af.Ix * F2) / gamma
    return pdot, qdot, rdot


def test_moment_coefficients_invert_the_equations_of_motion():
    rng = np.random.default_rng(2)
    n = 100
    af = Airframe(mass=1000, S=16.2, b=10.9, cbar=1.5, Ix=1285, Iy=1825, Iz=2667, Ixz=50)
    p, q, r = rng.normal(scale=0.3, size=(3, n))
    cl, cm, cn = rng.normal(scale=0.05, size=(3, n))
    qbar = 2000 + 100 * rng.normal(size=n)
    pdot, qdot, rdot = _forward_rotational(p, q, r, cl, cm, cn, qbar * af.S, af)
    out = moment_coefficients(p, q, r, qbar, af, pdot=pdot, qdot=qdot, rdot=rdot)
    np.testing.assert_allclose(out["Cl"], cl, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(out["Cm"], cm, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(out["Cn"], cn, rtol=1e-10, atol=1e-14)


def test_force_coefficients_from_accelerations():
    af = Airframe(mass=1000.0, S=16.0, g=9.80665)
    # a_z = q̄ S C_Z / (m g)  [2.26]  →  C_Z = −0.5 for a_z = −0.5·2000·16/(1000 g)
    az = -0.5 * 2000 * 16 / (1000 * 9.80665)
    out = force_coefficients(None, None, np.array([az]), 2000.0, af)
    assert out["CZ"][0] == pytest.approx(-0.5, rel=1e-12)
    assert set(out) == {"CZ"}


def test_signals_with_differentiated_rates():
    dt = 0.02
    t = np.arange(0, 8, dt)
    q = 0.05 * np.sin(2.0 * t)
    af = Airframe(mass=300.0, S=400.0, cbar=6.5, Ix=2e4, Iy=2.4e4, Iz=3.8e4, Ixz=1e3, g=32.174)
    channels = {"q": q, "V": np.full(t.size, 240.0), "qbar": np.full(t.size, 56.0), "de": q}
    s = equation_error_signals(channels, af, dt=dt)
    # C_m = I_y q̇/(q̄ S c̄) with p = r = 0 and q̇ = 0.1 cos 2t
    exact = 2.4e4 * 0.1 * np.cos(2.0 * t) / (56.0 * 400.0 * 6.5)
    assert np.max(np.abs(s["Cm"] - exact)) < 2e-3 * np.max(np.abs(exact))
    np.testing.assert_allclose(s["qhat"], q * 6.5 / 480.0)
    assert "Cl" not in s and s["de"] is not None
