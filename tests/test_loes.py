"""Short-period low-order equivalent systems (``flightid.export.loes``): a response that is
of the LOES form returns its own parameters; a two-state short-period model returns its
closed-form transfer function; the mismatch is that of MIL-STD-1797A."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flightid.export.loes import (
    LoesError,
    fit_short_period_loes,
    loes_response,
    short_period_loes,
)
from flightid.model.linearization import linearize
from test_predict import short_period


@pytest.mark.parametrize(
    "true",
    [(-4.5, 1.2, 0.55, 3.1, 0.08), (-12.0, 0.6, 0.3, 5.0, 0.15), (2.0, 2.5, 0.9, 1.5, 0.02)],
)
def test_a_second_order_response_with_delay_returns_its_own_parameters(true):
    w = np.logspace(-1, 1, 40)
    # start away from the truth: ζ = 0.5, ω at the peak of |H|·ω
    fit = fit_short_period_loes(w, loes_response(w, true))
    assert fit.parameters == pytest.approx(true, rel=1e-4, abs=1e-6)
    assert fit.mismatch < 1e-8


def test_a_two_state_short_period_model_returns_its_transfer_function():
    values = {"Za": -1.2, "Zde": -0.15, "Ma": -6.0, "Mq": -1.8, "Mde": -8.0}
    linear = linearize(short_period(values), [0.0, 0.0], [0.0])
    fit = short_period_loes(linear, "de", "q")
    za, zde, ma, mq, mde = values.values()
    # q/δe = (M_δe s + M_α Z_δe − Z_α M_δe) / (s² − (Z_α + M_q) s + Z_α M_q − M_α)
    wn = math.sqrt(za * mq - ma)
    zeta = -(za + mq) / (2 * wn)
    inv_t = (ma * zde - za * mde) / mde
    assert fit.gain == pytest.approx(mde, rel=1e-4)
    assert fit.inverse_t_theta2_1_per_s == pytest.approx(inv_t, rel=1e-4)
    assert fit.natural_frequency_rad_s == pytest.approx(wn, rel=1e-4)
    assert fit.damping_ratio == pytest.approx(zeta, rel=1e-4)
    assert fit.time_delay_s == pytest.approx(0.0, abs=1e-6)
    assert fit.to_dict()["points"] == 40


def test_mismatch_is_the_mil_std_1797a_sum():
    w = np.logspace(-1, 1, 25)
    true = (-4.5, 1.2, 0.55, 3.1, 0.08)
    # the "high-order" response: the LOES times a first-order lag 1/(s/20 + 1)
    h = loes_response(w, true) / (1j * w / 20.0 + 1.0)
    fit = fit_short_period_loes(w, h)
    ratio = fit.response() / h
    gain_db = 20 * np.log10(np.abs(ratio))
    phase_deg = np.degrees(np.angle(ratio))
    # M = (20/n) Σ [ΔG² + 0.01745 ΔΦ²]
    expected = 20.0 / w.size * np.sum(gain_db**2 + 0.01745 * phase_deg**2)
    assert fit.mismatch == pytest.approx(expected, rel=1e-9)
    # the lag's phase at low frequency looks like a further delay of about 1/20 s
    assert 0.08 + 0.02 < fit.time_delay_s < 0.08 + 0.08
    assert fit.mismatch < 10.0


def test_errors_are_named():
    w = np.logspace(-1, 1, 10)
    with pytest.raises(LoesError, match="same length"):
        fit_short_period_loes(w, np.ones(5))
    with pytest.raises(LoesError, match="increasing"):
        fit_short_period_loes(w[::-1], np.ones(10))
    with pytest.raises(LoesError, match="non-zero"):
        fit_short_period_loes(w, np.zeros(10))
    linear = linearize(short_period(), [0.0, 0.0], [0.0])
    with pytest.raises(LoesError, match="an input of"):
        short_period_loes(linear, "da", "q")
    with pytest.raises(LoesError, match="points"):
        short_period_loes(linear, band_rad_s=(1.0, 0.5))
