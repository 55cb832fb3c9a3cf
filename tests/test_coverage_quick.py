"""The fast subset of the measured-coverage study (bench/sigma_coverage.py): its independent
simulator against scipy, and the stated σ of the estimators that should already be honest
against the spread of seeded Monte Carlo estimates."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
import scipy.signal

BENCH = Path(__file__).resolve().parents[1] / "bench" / "sigma_coverage.py"


@pytest.fixture(scope="module")
def study():
    # a script of bench/, loaded by path
    spec = importlib.util.spec_from_file_location("bench_coverage_study", BENCH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_simulator_equals_scipy_lsim_and_the_process_noise_integral(study):
    t, de = study.elevator(10.0)
    a, b = study.system_matrices(study.TRUTH)
    # scipy's own first-order-hold simulation (input linear between samples)
    _, y, _ = scipy.signal.lsim((a, b, np.eye(2), np.zeros((2, 1))), de, t, interp=True)
    np.testing.assert_allclose(study.simulate_states(study.TRUTH, de), y, atol=1e-12)
    f = np.diag([0.02, 0.05])

    # Q_d = ∫₀^Δt e^{Aτ} FFᵀ e^{Aᵀτ} dτ by quadrature
    def integrand(s):
        return scipy.linalg.expm(a * s) @ f @ f.T @ scipy.linalg.expm(a.T * s)

    expected = scipy.integrate.quad_vec(integrand, 0.0, study.DT_S)[0]
    np.testing.assert_allclose(
        study.discrete_process_noise(a, f, study.DT_S), expected, rtol=1e-10, atol=1e-16
    )


def test_output_error_white_noise_sigma_matches_the_monte_carlo_spread(study):
    """60 seeds: spread/σ within 0.7–1.4 (the standard error of a spread over 60 runs is
    ≈ 9 %) and 2σ coverage ≥ 0.85 for every parameter and every σ the result states."""
    rows, failures = study.run_family("output_error_white", 60)
    assert not failures
    assert {r.name for r in rows} == set(study.NAMES)
    for row in rows:
        assert 0.7 <= row.ratio <= 1.4, row
        assert row.cover >= 0.85, row


def test_equation_error_white_sigma_matches_and_coloured_is_flagged(study):
    """Least squares with white residuals: spread/σ within 0.7–1.4 over 60 seeds. With AR(1)
    residuals (pole 0.9) the plain s²(XᵀX)⁻¹ is optimistic; the study must show it (a study
    that cannot see a wrong σ checks nothing)."""
    white, _ = study.run_family("equation_error", 60)
    for row in white:
        assert 0.7 <= row.ratio <= 1.4, row
    coloured, _ = study.run_family("equation_error_coloured", 60)
    plain = [r for r in coloured if r.kind == "std_cr"] or [r for r in coloured if r.kind == "std"]
    assert max(r.ratio for r in plain) > 1.5


def test_airplane_simulator_equals_scipy_and_flightid_calm_model(study):
    """The study's RK4 airplane and flightid's model of it, both against scipy's DOP853 on
    the same equations (tolerance 1e-11): the equations and units of the two agree."""
    t, de = study.elevator(study.AIRPLANE_DURATION_S, study.AIRPLANE_DT_S)
    truth = study.AIRPLANE_TRUTH

    def derivative(time_s, x):
        return study.airplane_derivative(x, np.interp(time_s, t, de), 0.0, truth)

    solution = scipy.integrate.solve_ivp(
        derivative,
        (0.0, t[-1]),
        study.AIRPLANE_X0,
        t_eval=t,
        method="DOP853",
        rtol=1e-11,
        atol=1e-11,
        max_step=study.AIRPLANE_DT_S / 2,
    )
    u, w, q, theta = solution.y
    # V = √(u² + w²), α = atan(w/u)
    expected = np.column_stack([np.hypot(u, w), np.arctan2(w, u), q, theta])
    ours = study.simulate_airplane(truth, de)
    np.testing.assert_allclose(ours, expected, rtol=0, atol=1e-7)
    from flightid.simulation import simulate

    model = study.airplane_model(truth)
    flightid_outputs = simulate(model, study.airplane_data(t, de, ours))
    # flightid: one RK4 step per sample (Δt = 0.04 s), error O(Δt⁴)
    np.testing.assert_allclose(flightid_outputs, expected, rtol=0, atol=2e-5)
    # the gust-state model without gust is the same airplane
    gust_model = study.airplane_gust_model(truth, study.GUST_INTENSITY)
    np.testing.assert_allclose(
        simulate(gust_model, study.airplane_data(t, de, ours)), flightid_outputs, atol=1e-12
    )


def test_dryden_gust_has_the_dryden_variance_and_correlation(study):
    """First-order Dryden: variance σ_w², lag-one correlation e^{−VΔt/L} (200 000 samples)."""
    gust = study.dryden_vertical_gust(np.random.default_rng(3), 200_000, study.AIRPLANE_DT_S)
    gust = gust[1000:]
    assert abs(gust.std() / study.GUST_STD_MS - 1.0) < 0.05
    expected = np.exp(-study.TRIM_SPEED_MS * study.AIRPLANE_DT_S / study.GUST_LENGTH_M)
    assert abs(np.corrcoef(gust[:-1], gust[1:])[0, 1] - expected) < 2e-3


def test_output_error_in_turbulence_default_sigma_closer_than_cramer_rao(study):
    """Output error in Dryden turbulence with the calm-air model (30 seeds): the Cramér–Rao σ
    is optimistic (spread/σ > 2.5 for some parameter) and the default σ, corrected for the
    coloured residuals, is closer for every parameter."""
    rows, failures = study.run_family("airplane_turbulence", 30)
    assert not failures
    ratio = {(r.name, r.kind): r.ratio for r in rows}
    assert max(ratio[n, "std_cr"] for n in study.AIRPLANE_NAMES) > 2.5
    for name in study.AIRPLANE_NAMES:
        assert ratio[name, "std"] < ratio[name, "std_cr"], name
