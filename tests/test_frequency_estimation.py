"""Frequency-domain equation error and output error on simulated linear data.

The data come from scipy.signal.lsim (exact first-order-hold discretisation: the continuous
system driven by the straight lines between the input samples), an implementation
independent of flightid's simulator. Truth values are the ATTAS short-period time-domain
estimates, rounded (any stable values would do).
"""

import numpy as np
import pytest
from scipy.signal import StateSpace, lsim

from flightid.errors import InputError
from flightid.frequency import (
    LinearSystem,
    equation_error,
    frequency_grid,
    linear_system,
    maneuver_spectra,
    output_error,
)
from flightid.model import Parameters, StateSpaceModel

NAMES = ("Za", "Zq", "Zde", "Ma", "Mq", "Mde")
TRUTH = np.array([-0.483, 0.1027, 0.676, -4.935, -2.012, -7.227])
STATES = ("alpha", "q")


def system_of(theta: np.ndarray) -> LinearSystem:
    za, zq, zde, ma, mq, mde = theta
    # α̇ = Z_α α + (1 + Z_q) q + Z_δe δe ;  q̇ = M_α α + M_q q + M_δe δe
    A = np.array([[za, 1.0 + zq], [ma, mq]])
    B = np.array([[zde], [mde]])
    return LinearSystem(A, B, np.eye(2), np.zeros((2, 1)), np.zeros(2), np.zeros(2))


def simulate(seed: int, dt: float = 0.04, noise: bool = True, duration: float = 25.0):
    """A 3-2-1-1-like elevator input, x(0) ≠ 0, seeded white measurement noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration + 0.5 * dt, dt)
    u = np.zeros_like(t)
    for start, stop, level in [(1, 3, 1), (3, 5, -1), (5, 6, 1), (6, 7, -1), (12, 14, 0.5)]:
        u[(t >= start) & (t < stop)] = level
    u = np.deg2rad(2.0) * u
    s = system_of(TRUTH)
    _, y, _ = lsim(StateSpace(s.A, s.B, s.C, s.D), u, t, X0=[0.01, -0.005], interp=True)
    if noise:
        y = y + rng.standard_normal(y.shape) * np.array([1e-3, 2e-3])
    return t, u, y


BAND = frequency_grid((0.1, 1.5), 0.04)


def spectra(noise: bool, seeds=(1, 2), dt: float = 0.04):
    return [maneuver_spectra(*simulate(s, dt, noise), BAND) for s in seeds]


def test_equation_error_recovers_a_b_on_noise_free_data():
    # fine sampling: the only error left is the quadrature's O((ωΔt)²)
    fit = equation_error(
        system_of, 0.5 * TRUTH, np.ones(6, bool), spectra(False, dt=0.005), STATES, STATES
    )
    np.testing.assert_allclose(fit.theta, TRUTH, rtol=2e-5, atol=2e-6)
    assert fit.estimated.all()


def test_output_error_recovers_the_truth_on_noise_free_data():
    fit = output_error(system_of, 0.6 * TRUTH, np.ones(6, bool), spectra(False), STATES, STATES)
    np.testing.assert_allclose(fit.theta, TRUTH, rtol=1e-3)


def test_output_error_within_3_sigma_on_noisy_seeded_data():
    fit = output_error(system_of, 0.6 * TRUTH, np.ones(6, bool), spectra(True), STATES, STATES)
    assert fit.converged, fit.message
    z = (fit.theta - TRUTH) / fit.std
    assert np.all(np.abs(z) < 3.0), dict(zip(NAMES, z, strict=True))
    z_coloured = (fit.theta - TRUTH) / fit.std_coloured
    assert np.all(np.abs(z_coloured) < 3.0), dict(zip(NAMES, z_coloured, strict=True))
    # the bounds are of the size the noise implies, not inflated: σ(M_δe) ≪ 1 % of M_δe
    assert fit.std[5] < 0.01 * abs(TRUTH[5])


def test_equation_error_within_3_sigma_on_noisy_seeded_data():
    fit = equation_error(system_of, TRUTH, np.ones(6, bool), spectra(True), STATES, STATES)
    z = (fit.theta - TRUTH) / fit.std
    assert np.all(np.abs(z) < 3.0), dict(zip(NAMES, z, strict=True))


def test_fixed_parameters_keep_their_values():
    free = np.array([True, True, True, False, True, True])
    start = 0.6 * TRUTH
    start[3] = TRUTH[3]
    fit = output_error(system_of, start, free, spectra(False), STATES, STATES)
    assert fit.theta[3] == TRUTH[3]
    assert np.isnan(fit.std[3])
    np.testing.assert_allclose(fit.theta, TRUTH, rtol=1e-3)


def _affine_model(nonlinear: bool = False) -> StateSpaceModel:
    def f(t, x, u, theta):
        extra = 0.1 * x[0] ** 2 if nonlinear else 0.0
        return np.array(
            [
                theta[0] + theta[1] * x[0] + (1 + theta[2]) * x[1] + theta[3] * u[0] + extra,
                theta[4] + theta[5] * x[0] + theta[6] * x[1] + theta[7] * u[0],
            ]
        )

    def h(t, x, u, theta):
        return np.array([x[0], x[1]])

    params = Parameters(
        {
            "Z0": 0.01,
            "Za": -0.5,
            "Zq": 0.1,
            "Zde": 0.7,
            "M0": 0.2,
            "Ma": -5.0,
            "Mq": -2.0,
            "Mde": -7.0,
        }
    )
    return StateSpaceModel(STATES, ("de",), STATES, f, h, params, x0=(0.0, 0.0))


def test_linear_system_of_a_model_matches_the_hand_written_matrices():
    model = _affine_model()
    system = linear_system(model)
    np.testing.assert_allclose(system.A, [[-0.5, 1.1], [-5.0, -2.0]])
    np.testing.assert_allclose(system.B, [[0.7], [-7.0]])
    np.testing.assert_allclose(system.f0, [0.01, 0.2])
    np.testing.assert_allclose(system.C, np.eye(2))


def test_a_nonlinear_model_is_refused_by_name():
    with pytest.raises(InputError, match="linear in the states"):
        linear_system(_affine_model(nonlinear=True))


@pytest.mark.parametrize("estimator", [output_error, equation_error])
def test_a_free_mask_of_the_wrong_length_is_a_named_error_in_both_estimators(estimator):
    # both estimators check their start and mask the same way (output_error.checked_start)
    spectra = [maneuver_spectra(*simulate(1), frequency_grid((0.1, 1.5), 0.04))]
    with pytest.raises(InputError, match="free: expected a mask of the shape of theta_start"):
        estimator(system_of, TRUTH, np.ones(5, bool), spectra, STATES, STATES)
    with pytest.raises(InputError, match="spectra: expected at least one maneuver"):
        estimator(system_of, TRUTH, np.ones(6, bool), [], STATES, STATES)


def test_too_few_frequencies_is_a_named_error():
    short = [maneuver_spectra(*simulate(1), frequency_grid((0.1, 0.14), 0.04))]
    with pytest.raises(InputError, match="band_hz/step_hz"):
        output_error(system_of, TRUTH, np.ones(6, bool), short, STATES, STATES)


def test_cramer_rao_bounds_have_the_size_of_the_scatter():
    """Small seeded Monte Carlo (24 runs): the pooled spread of (θ̂ − θ)/σ_CR is 1 within
    its sampling error. A bound off by √2 (e.g. M = JᵀJ instead of 2JᵀJ for the real-stacked
    residuals) gives 0.71 or 1.41 and fails. The large study is bench/frequency_monte_carlo.py."""
    z = []
    for run in range(24):
        data = [maneuver_spectra(*simulate(500 + 2 * run + k), BAND) for k in (0, 1)]
        fit = output_error(system_of, TRUTH, np.ones(6, bool), data, STATES, STATES)
        z.append((fit.theta - TRUTH) / fit.std_cr)
    spread = float(np.sqrt(np.mean(np.square(z))))
    assert 0.8 < spread < 1.25, spread


@pytest.mark.slow
@pytest.mark.parametrize(
    "step_hz, lowest_cr, lowest_coloured",
    [
        (0.04, 0.90, 0.88),  # 1/T: independent frequencies, CR bounds right
        (0.02, 0.88, 0.88),  # oversampled by 2: the grid factor c = 2 keeps the CR bound
    ],
)
def test_monte_carlo_coverage_of_95_percent_intervals(step_hz, lowest_cr, lowest_coloured):
    """150 seeded runs: coverage of θ̂ ± 1.96σ pooled over the 6 parameters (binomial
    standard error ≈ 0.007 pooled). The same study on the measured ATTAS input is
    bench/frequency_monte_carlo.py (numbers in docs/frequency.md)."""
    band = frequency_grid((0.1, 1.5), step_hz)
    inside_cr, inside_coloured = [], []
    for run in range(150):
        data = [maneuver_spectra(*simulate(9000 + 2 * run + k), band) for k in (0, 1)]
        fit = output_error(system_of, TRUTH, np.ones(6, bool), data, STATES, STATES)
        inside_cr.append(np.abs(fit.theta - TRUTH) < 1.96 * fit.std_cr)
        inside_coloured.append(np.abs(fit.theta - TRUTH) < 1.96 * fit.std_coloured)
    coverage_cr = float(np.mean(inside_cr))
    coverage_coloured = float(np.mean(inside_coloured))
    assert lowest_cr <= coverage_cr <= 0.99, coverage_cr
    assert lowest_coloured <= coverage_coloured <= 0.99, coverage_coloured
