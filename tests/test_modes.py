"""Modes of a linear model with σ (``flightid.model.modes``): closed forms of the short
period, textbook airplane modes and their names, a seeded Monte Carlo of the σ."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from data_paths import ROOT, needs_data
from flightid.model.linearization import LinearModel, linearize
from flightid.model.modes import ModeError, Modes
from flightid.model.parameters import Parameters
from flightid.model.statespace import StateSpaceModel
from test_predict import short_period

# short period α̇ = Z_α α + q + Z_δe δe, q̇ = M_α α + M_q q + M_δe δe
SP = {"Za": -1.2, "Zde": -0.15, "Ma": -6.0, "Mq": -1.8, "Mde": -8.0}
# a covariance of (Za, Zde, Ma, Mq, Mde) with correlations (seeded), σ ≈ 1–3 % of the values
_M = np.random.default_rng(11).normal(size=(5, 5))
_CORR = np.corrcoef(_M @ _M.T + 5 * np.eye(5))
_SIGMA = np.array([0.02, 0.005, 0.08, 0.04, 0.1])
P_SP = _CORR * np.outer(_SIGMA, _SIGMA)


def from_a(a: np.ndarray, states: tuple[str, ...]) -> LinearModel:
    """A LinearModel holding only A (no inputs, outputs = states)."""
    n = len(states)
    return LinearModel(
        a, np.zeros((n, 0)), np.eye(n), np.zeros((n, 0)), states, (), states,
        np.zeros(n), np.zeros(0), np.zeros(n), np.zeros(n),
    )  # fmt: skip


def test_short_period_closed_form_and_its_delta_method_sigma():
    linear = linearize(short_period(SP), [0.0, 0.0], [0.0], covariance=P_SP)
    modes = linear.modes()
    assert modes.names == ["short period"]
    mode = modes["short period"]
    za, ma, mq = SP["Za"], SP["Ma"], SP["Mq"]
    # ω_n² = Z_α M_q − M_α,  2ζω_n = −(Z_α + M_q)
    wn = math.sqrt(za * mq - ma)
    zeta = -(za + mq) / (2.0 * wn)
    assert mode.natural_frequency == pytest.approx(wn, rel=1e-9)
    assert mode.damping_ratio == pytest.approx(zeta, rel=1e-9)
    assert mode.time_to_half == pytest.approx(math.log(2) / (zeta * wn), rel=1e-9)
    assert math.isnan(mode.time_constant) and math.isnan(mode.time_to_double)
    # σ in closed form: gradients over (Za, Zde, Ma, Mq, Mde) of the formulas above
    g_wn = np.array([mq, 0.0, -1.0, za, 0.0]) / (2.0 * wn)
    g_zeta = -np.array([1.0, 0.0, 0.0, 1.0, 0.0]) / (2.0 * wn) - (za + mq) * (-g_wn) / (2.0 * wn**2)
    assert mode.natural_frequency_std == pytest.approx(math.sqrt(g_wn @ P_SP @ g_wn), rel=1e-5)
    assert mode.damping_ratio_std == pytest.approx(math.sqrt(g_zeta @ P_SP @ g_zeta), rel=1e-5)


def test_mode_sigma_matches_a_monte_carlo_over_parameter_draws():
    linear = linearize(short_period(SP), [0.0, 0.0], [0.0], covariance=P_SP)
    mode = linear.modes()["short period"]
    theta = np.array(list(SP.values()))
    draws = np.random.default_rng(5).multivariate_normal(theta, P_SP, size=4000)
    # eigenvalues of [[Za, 1], [Ma, Mq]] for every draw (numpy, not the module)
    a = np.zeros((draws.shape[0], 2, 2))
    a[:, 0, 0], a[:, 0, 1], a[:, 1, 0], a[:, 1, 1] = draws[:, 0], 1.0, draws[:, 2], draws[:, 3]
    lam = np.linalg.eigvals(a)
    lam = np.where(lam.imag > 0, lam, np.conj(lam))[:, 0]
    wn, zeta = np.abs(lam), -lam.real / np.abs(lam)
    # 4000 draws: sample σ within ±2.2 % (1σ); accept 8 %
    assert wn.std(ddof=1) == pytest.approx(mode.natural_frequency_std, rel=0.08)
    assert zeta.std(ddof=1) == pytest.approx(mode.damping_ratio_std, rel=0.08)
    assert (-lam.real).std(ddof=1) == pytest.approx(mode.eigenvalue_std[0], rel=0.08)
    assert lam.imag.std(ddof=1) == pytest.approx(mode.eigenvalue_std[1], rel=0.08)


@pytest.mark.parametrize("a", [-2.5, 0.5])
def test_real_modes_time_constant_and_times_to_half_or_double(a):
    def f(t, x, u, th):
        return np.array([th[0] * x[0]])

    def h(t, x, u, th):
        return np.array([x[0]])

    model = StateSpaceModel(("x",), (), ("x",), f, h, Parameters({"a": a}))
    sigma_a = 0.05
    (mode,) = linearize(model, [0.0], covariance=[[sigma_a**2]]).modes()
    assert mode.name == "mode 1" and not mode.oscillatory
    assert mode.eigenvalue == pytest.approx(a, abs=1e-9)
    # τ = −1/a, σ_τ = σ_a/a²
    assert mode.time_constant == pytest.approx(-1.0 / a, rel=1e-9)
    assert mode.time_constant_std == pytest.approx(sigma_a / a**2, rel=1e-5)
    half_or_double = mode.time_to_half if a < 0 else mode.time_to_double
    assert half_or_double == pytest.approx(math.log(2) / abs(a), rel=1e-9)
    other = mode.time_to_double if a < 0 else mode.time_to_half
    assert math.isnan(other) and math.isnan(mode.natural_frequency)


# Navion, Nelson (Flight Stability and Automatic Control, 2nd ed., §4.4 and §5.6), U.S. units
U0, G = 176.0, 32.2


def navion_longitudinal() -> LinearModel:
    xu, xw, zu, zw, mw, mwdot, mq = -0.045, 0.036, -0.369, -2.02, -0.05, -0.0051, -2.05
    a = np.array(
        [
            [xu, xw, 0.0, -G],
            [zu, zw, U0, 0.0],
            [mwdot * zu, mw + mwdot * zw, mq + mwdot * U0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ]
    )
    return from_a(a, ("u", "w", "q", "theta"))


def navion_lateral() -> LinearModel:
    yb, lb, lp, lr, nb, np_, nr = -45.72, -15.98, -8.395, 2.19, 4.546, -0.349, -0.76
    a = np.array(
        [
            [yb / U0, 0.0, -1.0, G / U0],
            [lb, lp, lr, 0.0],
            [nb, np_, nr, 0.0],
            [0.0, 1.0, 0.0, 0.0],
        ]
    )
    return from_a(a, ("beta", "p", "r", "phi"))


def test_navion_longitudinal_modes_are_named_short_period_and_phugoid():
    modes = navion_longitudinal().modes()
    # the book's roots: short period −2.5 ± 2.59i, phugoid −0.017 ± 0.213i
    assert modes.names == ["short period", "phugoid"]
    assert modes["short period"].eigenvalue == pytest.approx(-2.5 + 2.59j, abs=0.03)
    assert modes["phugoid"].eigenvalue == pytest.approx(-0.017 + 0.213j, abs=0.003)
    assert modes["short period"].dominant_state in ("w", "q")
    assert modes["phugoid"].dominant_state in ("u", "theta")


def test_navion_lateral_modes_are_named_roll_dutch_roll_and_spiral():
    modes = navion_lateral().modes()
    # the book's roots: roll −8.43, Dutch roll −0.49 ± 2.34i, spiral −0.0088
    assert modes.names == ["roll subsidence", "Dutch roll", "spiral"]
    assert modes["roll subsidence"].eigenvalue.real == pytest.approx(-8.43, abs=0.02)
    assert modes["Dutch roll"].eigenvalue == pytest.approx(-0.49 + 2.34j, abs=0.02)
    # (the spiral root is sensitive to the derivatives' rounding: −0.0083 from those here)
    assert modes["spiral"].eigenvalue.real == pytest.approx(-0.0088, abs=0.001)
    # the same eigenvalues as numpy's
    ours = sorted(
        [m.eigenvalue for m in modes] + [modes["Dutch roll"].eigenvalue.conjugate()],
        key=lambda z: (z.real, z.imag),
    )
    reference = sorted(np.linalg.eigvals(navion_lateral().A), key=lambda z: (z.real, z.imag))
    np.testing.assert_allclose(ours, reference, atol=1e-10)
    # no covariance: σ NaN, JSON null
    entry = json.loads(json.dumps(modes.to_dict(), allow_nan=False))
    assert entry[1]["name"] == "Dutch roll" and entry[1]["omega_n_std_rad_per_s"] is None
    assert entry[1]["omega_n_rad_per_s"] == pytest.approx(abs(modes["Dutch roll"].eigenvalue))
    assert entry[0]["tau_s"] == pytest.approx(1 / 8.43, rel=0.01)


def test_general_models_number_their_modes_and_zero_eigenvalues_are_neutral():
    a = np.array([[-3.0, 0.0, 0.0], [0.0, -0.5, 2.0], [0.0, -2.0, -0.5]])
    modes = from_a(a, ("x1", "x2", "x3")).modes()
    assert isinstance(modes, Modes) and modes.names == ["mode 1", "mode 2"]
    assert modes[0].eigenvalue == pytest.approx(-3.0)
    assert modes["mode 2"].natural_frequency == pytest.approx(math.hypot(0.5, 2.0))
    with pytest.raises(ModeError, match="no mode named"):
        modes["phugoid"]
    neutral = from_a(np.array([[-1.0, 0.0], [1.0, 0.0]]), ("p", "phi")).modes()
    assert "neutral" in neutral.names
    text = modes.summary()
    assert "omega_n [rad/s]" in text and "mode 2" in text


@needs_data("fvsysid/hfb320_1_10.asc")
@pytest.mark.filterwarnings("ignore:.*outlier")
def test_hfb320_modes_and_their_sigma_against_a_monte_carlo():
    from flightid.cases.run import run_case

    run = run_case(ROOT / "examples" / "cases" / "hfb320_longitudinal.toml", accuracy="none")
    result, data = run.estimate, run.maneuvers[0]
    linear = result.linearize(at=data)
    modes = linear.modes()
    assert modes.names == ["short period", "phugoid"]
    sp, ph = modes["short period"], modes["phugoid"]
    # regression values of this estimate (not an independent reference)
    assert sp.natural_frequency == pytest.approx(2.05, abs=0.02)
    assert sp.damping_ratio == pytest.approx(0.41, abs=0.01)
    assert ph.natural_frequency == pytest.approx(0.140, abs=0.002)
    # Monte Carlo: θ ~ N(θ̂, P) over the free parameters, each draw linearized at the same point
    free = np.asarray(result.free, dtype=bool)
    draws = np.random.default_rng(3).multivariate_normal(
        result.values[free], result.covariance_default, size=300
    )
    wn_sp, zeta_sp, wn_ph = [], [], []
    for draw in draws:
        theta = np.array(result.values, dtype=float)
        theta[free] = draw
        model = result.model.with_parameters(result.model.parameters.with_values(theta))
        lam = np.linalg.eigvals(linearize(model, linear.x0, linear.u0).A)
        lam = sorted(lam[lam.imag > 0], key=abs)
        wn_ph.append(abs(lam[0]))
        wn_sp.append(abs(lam[1]))
        zeta_sp.append(-lam[1].real / abs(lam[1]))
    # 300 draws: sample σ within ±4 % (1σ); accept 15 %
    assert np.std(wn_sp, ddof=1) == pytest.approx(sp.natural_frequency_std, rel=0.15)
    assert np.std(zeta_sp, ddof=1) == pytest.approx(sp.damping_ratio_std, rel=0.15)
    assert np.std(wn_ph, ddof=1) == pytest.approx(ph.natural_frequency_std, rel=0.15)
