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
