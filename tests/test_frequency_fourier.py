"""Finite Fourier transform (flightid.frequency.fourier) against a direct numpy sum and
closed-form transforms; detrending; input checks."""

import numpy as np
import pytest

from flightid.errors import InputError
from flightid.frequency.fourier import (
    constant_transform,
    finite_fourier_transform,
    frequency_grid,
    maneuver_spectra,
    remove_trend,
)

DT = 0.04
T_END = 20.0
TIME = np.arange(0.0, T_END + 0.5 * DT, DT)
FREQS = frequency_grid((0.1, 2.0), 0.05)
OMEGA = 2 * np.pi * FREQS


def integral_exp(a: np.ndarray, duration: float) -> np.ndarray:
    """Closed form ∫_0^T e^{aτ} dτ = (e^{aT} − 1)/a."""
    return (np.exp(a * duration) - 1.0) / a


def test_rectangle_rule_equals_a_direct_numpy_sum():
    rng = np.random.default_rng(11)
    x = rng.standard_normal((TIME.size, 3))
    # independent second implementation: Δt Σ_i x_i e^{−jωτ_i}, one frequency at a time
    expected = np.array(
        [DT * np.sum(x * np.exp(-1j * w * (TIME - TIME[0]))[:, None], axis=0) for w in OMEGA]
    )
    got = finite_fourier_transform(x, TIME, FREQS, quadrature="rectangle", method="direct")
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)
    got_czt = finite_fourier_transform(x, TIME, FREQS, quadrature="rectangle", method="czt")
    np.testing.assert_allclose(got_czt, expected, rtol=1e-9, atol=1e-10)


def test_time_origin_does_not_matter():
    x = np.sin(1.3 * TIME)
    shifted = finite_fourier_transform(x, TIME + 57.3, FREQS)
    np.testing.assert_allclose(shifted, finite_fourier_transform(x, TIME, FREQS), atol=1e-12)


def test_sinusoid_matches_its_closed_form_transform():
    w0 = 2 * np.pi * 0.73  # not on the grid: no 0/0 in the closed form
    x = np.sin(w0 * TIME)
    # sin(w0 τ) = (e^{jw0τ} − e^{−jw0τ})/2j, so X(ω) = [I(j(w0−ω)) − I(−j(w0+ω))]/2j
    exact = (integral_exp(1j * (w0 - OMEGA), T_END) - integral_exp(-1j * (w0 + OMEGA), T_END)) / 2j
    peak = np.abs(exact).max()
    trapezoid = finite_fourier_transform(x, TIME, FREQS, quadrature="trapezoid")
    rectangle = finite_fourier_transform(x, TIME, FREQS, quadrature="rectangle")
    # trapezoid: O(Δt²) for a smooth signal; the rectangle rule keeps an O(Δt) end error
    assert np.abs(trapezoid - exact).max() < 2e-3 * peak
    assert np.abs(rectangle - exact).max() > 5 * np.abs(trapezoid - exact).max()


def test_decaying_exponential_matches_its_closed_form_transform():
    x = np.exp(-0.5 * TIME)
    exact = integral_exp(-(0.5 + 1j * OMEGA), T_END)
    linear = finite_fourier_transform(x, TIME, FREQS, quadrature="linear")
    assert np.abs(linear - exact).max() < 1e-4 * np.abs(exact).max()


def test_linear_rule_is_exact_for_piecewise_linear_signals():
    # a ramp and a 3-2-1-1 sampled as straight lines between samples: exact transform of the
    # interpolant, computed here by summing the closed-form integral of each straight piece
    rng = np.random.default_rng(5)
    x = rng.standard_normal(TIME.size)
    tau = TIME - TIME[0]
    expected = np.zeros(OMEGA.size, dtype=complex)
    for i in range(TIME.size - 1):
        slope = (x[i + 1] - x[i]) / DT
        a = -1j * OMEGA
        # ∫_{τi}^{τi+Δt} (x_i + slope (τ − τ_i)) e^{aτ} dτ
        e0, e1 = np.exp(a * tau[i]), np.exp(a * tau[i + 1])
        part_const = x[i] * (e1 - e0) / a
        part_slope = slope * ((DT * e1) / a - (e1 - e0) / a**2)
        expected += part_const + part_slope
    got = finite_fourier_transform(x, TIME, FREQS, quadrature="linear")
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-11)


def test_constant_transform_is_the_closed_form():
    exact = integral_exp(-1j * OMEGA, T_END)
    np.testing.assert_allclose(constant_transform(TIME, FREQS), exact, rtol=1e-10, atol=1e-12)


def test_remove_trend_mean_and_line():
    x = 3.0 + 0.25 * TIME
    np.testing.assert_allclose(remove_trend(x, TIME, "linear"), 0.0, atol=1e-10)
    assert abs(remove_trend(x, TIME, "mean").mean()) < 1e-12
    np.testing.assert_array_equal(remove_trend(x, TIME, "none"), x)


def test_boundary_terms_are_constant_on_a_harmonic_grid():
    f = frequency_grid((0.1, 1.0), 1.0 / T_END)
    s = maneuver_spectra(TIME, np.sin(TIME), np.cos(TIME), f)
    assert s.end_phase_constant
    s2 = maneuver_spectra(TIME, np.sin(TIME), np.cos(TIME), frequency_grid((0.1, 1.0), 0.033))
    assert not s2.end_phase_constant


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: frequency_grid((1.0, 0.5), 0.1), "band_hz"),
        (lambda: frequency_grid((0.1, 1.0), 0.0), "step_hz"),
        (lambda: finite_fourier_transform(np.ones(5), np.arange(4.0), [1.0]), "time_s"),
        (
            lambda: finite_fourier_transform([1.0, np.nan, 2.0], np.arange(3.0), [1.0]),
            "signals",
        ),
        (lambda: finite_fourier_transform(np.ones(4), [0, 1, 3, 4.0], [0.1]), "uniform"),
        (
            lambda: finite_fourier_transform(
                np.ones(4), np.arange(4.0), [0.1, 0.3, 0.4], method="czt"
            ),
            "czt",
        ),
        (lambda: remove_trend(np.ones(4), np.arange(4.0), "cubic"), "detrend"),
        (
            lambda: maneuver_spectra(TIME, np.ones(TIME.size), np.ones(TIME.size), [20.0]),
            "Nyquist",
        ),
    ],
)
def test_bad_input_is_a_named_error(call, match):
    with pytest.raises(InputError, match=match):
        call()
