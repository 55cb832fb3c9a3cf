"""Frequency responses and coherence from data, and LOES fits, on systems with known
analytic responses H(jω) = C (jωI − A)⁻¹ B + D (closed form), data from scipy.signal.lsim."""

import numpy as np
import pytest
from scipy.signal import StateSpace, lsim

from flightid.errors import InputError
from flightid.frequency import fit_loes, frequency_response, loes_response, short_period_loes

DT = 0.02
A = np.array([[-0.48, 1.1], [-4.9, -2.0]])
B = np.array([[0.7, 0.1], [-7.2, 2.0]])
C = np.eye(2)
D = np.zeros((2, 2))


def analytic(freqs_hz: np.ndarray) -> np.ndarray:
    return np.array([C @ np.linalg.solve(2j * np.pi * f * np.eye(2) - A, B) + D for f in freqs_hz])


def two_input_record(seed: int, duration_s: float = 600.0):
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, DT)
    u = rng.standard_normal((t.size, 2))
    u[:, 1] += 0.5 * u[:, 0]  # correlated inputs: the case that needs conditioning
    _, y, _ = lsim(StateSpace(A, B, C, D), u, t)
    return t, u, y


def test_coherence_is_one_for_a_noise_free_static_gain():
    rng = np.random.default_rng(1)
    u = rng.standard_normal(4000)
    fr = frequency_response(u, 3.0 * u, DT, segment_s=10.0, band_hz=(0.1, 5.0))
    np.testing.assert_allclose(fr.coherence, 1.0, atol=1e-10)
    np.testing.assert_allclose(fr.response, 3.0, atol=1e-10)


def test_noise_free_dynamic_system_multiple_and_partial_coherence_near_one():
    t, u, y = two_input_record(2)
    fr = frequency_response(u, y, DT, segment_s=60.0, band_hz=(0.1, 2.0))
    assert fr.multiple_coherence.min() > 0.99
    # below 1 only by the window's bias (segment truncation), largest at the low end
    assert np.median(fr.partial_coherence) > 0.999
    assert fr.partial_coherence.min() > 0.9
    # the ordinary coherence of one of two correlated inputs is not the full story
    assert fr.coherence.min() < 0.9


def test_two_input_response_matches_the_analytic_response_where_coherence_is_high():
    t, u, y = two_input_record(3)
    rng = np.random.default_rng(4)
    noisy = y + 0.05 * rng.standard_normal(y.shape)
    fr = frequency_response(u, noisy, DT, segment_s=60.0, band_hz=(0.1, 2.0))
    exact = analytic(fr.frequencies_hz)
    good = fr.partial_coherence > 0.9
    assert good.mean() > 0.5  # the noise hides part of the band: those points are not judged
    error = np.abs(fr.response - exact) / np.abs(exact)
    assert np.median(error[good]) < 0.03
    assert error[good].max() < 0.15
    # gain and phase views agree with the complex response
    np.testing.assert_allclose(fr.gain_db, 20 * np.log10(np.abs(fr.response)))


def test_singular_inputs_are_refused_by_name():
    rng = np.random.default_rng(5)
    u = rng.standard_normal(3000)
    with pytest.raises(InputError, match="input spectral matrix"):
        frequency_response(np.column_stack([u, 2 * u]), u, DT, segment_s=10.0)


def test_loes_recovers_a_known_short_period_transfer_function():
    # q/δe = K (s + 1/Tθ2) e^{−τs} / (s² + 2ζω s + ω²), K = −7.2, 1/Tθ2 = 0.8, ζ = 0.6, ω = 3
    w = np.linspace(0.5, 12.0, 40)
    response = loes_response([-7.2, -7.2 * 0.8], [2 * 0.6 * 3.0, 9.0], 0.08, w)
    fit, values = short_period_loes(w, response)
    assert fit.cost < 1e-12
    assert values["K_q"] == pytest.approx(-7.2, rel=1e-6)
    assert values["inverse_T_theta2"] == pytest.approx(0.8, rel=1e-6)
    assert values["zeta_sp"] == pytest.approx(0.6, rel=1e-6)
    assert values["omega_sp_rad_s"] == pytest.approx(3.0, rel=1e-6)
    assert values["delay_s"] == pytest.approx(0.08, rel=1e-6)


def test_loes_cost_is_the_mil_std_1797_mismatch():
    # a pure 1 dB gain error everywhere, no phase error: J = 20/n · n · 1² = 20
    w = np.linspace(1.0, 10.0, 20)
    truth = loes_response([1.0], [1.0], 0.0, w)
    fit = fit_loes(w, truth * 10 ** (1 / 20), [1.0], [1.0], fit_delay=False)
    assert fit.numerator[0] == pytest.approx(10 ** (1 / 20), rel=1e-6)
    start_cost = fit_loes(w, truth * 10 ** (1 / 20), [1.0], [1.0], fit_delay=False)
    assert start_cost.cost < 1e-12
    from flightid.frequency.loes import PHASE_WEIGHT

    assert PHASE_WEIGHT == 0.01745
