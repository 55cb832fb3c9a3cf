"""Accuracy formulas recomputed independently, in plain numpy, from METHOD §10 and §9.

These tests exist because hand-made mutants of ``flightid.accuracy`` survived the suite
(issue 10 §6): N_φ without its factor n_p, D with the square in the wrong place, the
coloured-residual covariance without its N·n_o/(N·n_o − n_p) factor. Each quantity is
recomputed here from the paper's formulas with explicit sums over samples, without calling
the code under test for anything but the simulated outputs of the model.

    φ_w = (Σ_i G_iᵀR⁻¹G_i)⁻¹ Σ_i G_iᵀR⁻¹ δY_i,w                     [5.41]
    Q_φ = Σ_w Σ_i (δY_i,w − G_i φ_w)ᵀ R⁻¹ (δY_i,w − G_i φ_w)         [5.39]
    D   = Σ_w ( Σ_i δY_i,wᵀ R⁻¹ δY_i,w )²                          [5.35]
    N_φ = n_p s² Q_φ / D,   s² = J(θ̂)/(N n_o − n_p)                 [5.34], [5.30]
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from conftest import PENDULUM_TRUE, pendulum_data, pendulum_model
from flightid.accuracy import assess
from flightid.accuracy.levels import beale_factor
from flightid.accuracy.nonlinearity import beale_nonlinearity
from flightid.errors import InputError
from flightid.estimation.problem import OutputErrorProblem
from flightid.results import check_level, contour_level, residual_variance_factor
from flightid.simulation import simulate
from test_accuracy_models import exp_estimate, exp_model, linear_estimate


def _beale_by_hand(y_of, theta_hat, g, r_diag, steps, s2):
    """Q_φ, D, N_φ from METHOD §10 with explicit loops over points w and samples i.

    Args:
        y_of: θ (n_p,) → outputs (N, n_o).
        theta_hat: θ̂ (n_p,).
        g: sensitivities G_i (N, n_o, n_p) at θ̂.
        r_diag: R (n_o,).
        steps: |Δθ_j| (n_p,), the perturbation of each parameter.
        s2: s² [5.30].
    """
    n_p = theta_hat.size
    r_inv = np.diag(1.0 / np.asarray(r_diag, dtype=float))
    y_hat = y_of(theta_hat)
    # M = Σ_i G_iᵀ R⁻¹ G_i
    m = sum(g[i].T @ r_inv @ g[i] for i in range(g.shape[0]))
    points = []
    for j in range(n_p):
        for sign in (1.0, -1.0):
            theta_w = theta_hat.copy()
            theta_w[j] += sign * steps[j]
            points.append(theta_w)
    q_phi = 0.0
    d = 0.0
    for theta_w in points:
        dy = y_of(theta_w) - y_hat  # δY_i,w (N, n_o)
        # φ_w = M⁻¹ Σ_i G_iᵀ R⁻¹ δY_i,w                                   [5.41]
        rhs = sum(g[i].T @ r_inv @ dy[i] for i in range(g.shape[0]))
        phi = np.linalg.solve(m, rhs)
        # Q_φ += Σ_i (δY_i,w − G_i φ_w)ᵀ R⁻¹ (δY_i,w − G_i φ_w)              [5.39]
        for i in range(g.shape[0]):
            e = dy[i] - g[i] @ phi
            q_phi += e @ r_inv @ e
        # D += (Σ_i δY_i,wᵀ R⁻¹ δY_i,w)²                                   [5.35]
        d += sum(dy[i] @ r_inv @ dy[i] for i in range(g.shape[0])) ** 2
    # N_φ = n_p s² Q_φ / D                                                 [5.34]
    return q_phi, d, n_p * s2 * q_phi / d


@pytest.fixture(scope="module")
def exp_case():
    est, data = exp_estimate()
    return est, data


def test_beale_n_phi_through_assess_matches_a_plain_numpy_recomputation(exp_case):
    est, data = exp_case
    accuracy = assess(est, data, methods="cr", polish=False, warn=False)
    theta_hat = np.asarray(est.values, dtype=float)  # all three parameters are free
    g = np.asarray(est.sensitivities, dtype=float)
    r = np.asarray(est.r_diag, dtype=float)
    model = exp_model()
    measured = np.column_stack([data.output("y")])

    def y_of(theta):
        return simulate(model, data, theta=theta)

    n, n_o = measured.shape
    n_p = theta_hat.size
    # s² = J(θ̂)/(N n_o − n_p), J = Σ_i ν_iᵀ R⁻¹ ν_i                       [5.30], [3.46]
    nu = measured - y_of(theta_hat)
    s2 = float(np.sum(nu**2 / r)) / (n * n_o - n_p)
    assert accuracy.s2 == pytest.approx(s2, rel=1e-12)
    # Beale points at θ̂ ± s σ_j e_j, σ_j = √(M⁻¹)_jj (assess's default: one standard error)
    m = np.einsum("iop,o,ioq->pq", g, 1.0 / r, g)
    steps = np.sqrt(s2 * np.diag(np.linalg.inv(m)))
    q_phi, d, n_phi = _beale_by_hand(y_of, theta_hat, g, r, steps, s2)
    nl = accuracy.nonlinearity
    assert nl.points == 2 * n_p
    assert nl.q_phi == pytest.approx(q_phi, rel=1e-6)
    assert nl.d == pytest.approx(d, rel=1e-9)
    assert nl.n_phi == pytest.approx(n_phi, rel=1e-6)
    # the model is genuinely nonlinear in b: N_φ is small but far from round-off
    assert 1e-7 < n_phi < 1e-2
    # Beale's factor 1 + N n_o (n_p + 2)/((N n_o − n_p) n_p) N_φ              [5.29]
    factor = 1.0 + n * n_o * (n_p + 2) / ((n * n_o - n_p) * n_p) * n_phi
    assert nl.beale_factor == pytest.approx(factor, rel=1e-9)


@pytest.fixture(scope="module")
def pendulum_point():
    """The two-output pendulum at an arbitrary θ̂ (the formula does not need an optimum), R with
    unequal entries, and central-difference sensitivities computed here."""
    model = pendulum_model(PENDULUM_TRUE)
    data = pendulum_data()
    theta_hat = np.array(PENDULUM_TRUE) * np.array([1.02, 0.9, 1.1, 0.97])
    r = np.array([0.01**2, 0.05**2])
    n_p = theta_hat.size

    def y_of(theta):
        return simulate(model, data, theta=theta, compiled=False)

    # G_i = ∂y_i/∂θ by central differences
    h = 1e-6 * np.abs(theta_hat)
    g = np.stack(
        [
            (y_of(theta_hat + h[j] * np.eye(n_p)[j]) - y_of(theta_hat - h[j] * np.eye(n_p)[j]))
            / (2 * h[j])
            for j in range(n_p)
        ],
        axis=-1,
    )

    def problem():
        return OutputErrorProblem(model, data, compiled=False)

    return problem, theta_hat, g, r, y_of


def test_beale_terms_two_outputs_unequal_weights_any_point(pendulum_point):
    """Every term by hand, perturbation 2."""
    problem, theta_hat, g, r, y_of = pendulum_point
    n_p = theta_hat.size
    std = np.array([0.05, 0.02, 0.03, 0.01])
    s2 = 1.3
    result = beale_nonlinearity(problem(), theta_hat, g, r, std, s2, perturbation=2.0)
    q_phi, d, n_phi = _beale_by_hand(y_of, theta_hat, g, r, 2.0 * std, s2)
    assert result.q_phi == pytest.approx(q_phi, rel=1e-8)
    assert result.d == pytest.approx(d, rel=1e-10)
    assert result.n_phi == pytest.approx(n_phi, rel=1e-8)
    # far from round-off (4.5e-6, Q_φ ≈ 0.65): a wrong factor cannot hide below tolerance
    assert result.n_phi > 1e-6 and result.q_phi > 0.1
    assert result.evaluations == 2 * n_p + 1 and result.points == 2 * n_p
    assert (result.s2, result.perturbation) == (1.3, 2.0)
    # Beale's factor [5.29] with N n_o scalar measurements
    n_data = 2 * pendulum_data().n_samples
    factor = 1.0 + n_data * (n_p + 2) / ((n_data - n_p) * n_p) * result.n_phi
    assert result.beale_factor == pytest.approx(factor, rel=1e-12)
    # the default perturbation is one standard error; evaluations count this call only
    used = problem()
    used.outputs(theta_hat[None, :])
    default = beale_nonlinearity(used, theta_hat, g, r, std, s2)
    q_phi1, d1, _ = _beale_by_hand(y_of, theta_hat, g, r, std, s2)
    assert default.perturbation == 1.0
    assert default.q_phi == pytest.approx(q_phi1, rel=1e-8)
    assert default.d == pytest.approx(d1, rel=1e-10)
    # the JSON form carries the same numbers under the documented keys
    assert default.to_dict() == {
        "N_phi": default.n_phi, "Q_phi": default.q_phi, "D": default.d, "s2": 1.3,
        "perturbation_sigmas": 1.0, "points": 8, "beale_factor": default.beale_factor,
        "evaluations": 9,
    }  # fmt: skip


def test_beale_skips_undetermined_parameters(pendulum_point):
    """An infinite (or zero) standard error is not perturbed: W = 2 (n_p − 1), and the tangent
    plane is spanned by the sensitivities of the perturbed parameters only."""
    problem, theta_hat, g, r, y_of = pendulum_point
    usable = [0, 2, 3]
    std = np.array([0.05, np.inf, 0.03, 0.01])
    result = beale_nonlinearity(problem(), theta_hat, g, r, std, 1.0)
    assert result.points == 6 and result.evaluations == 7

    def y_usable(theta_sub):
        theta = theta_hat.copy()
        theta[usable] = theta_sub
        return y_of(theta)

    q_phi, d, _ = _beale_by_hand(y_usable, theta_hat[usable], g[:, :, usable], r, std[usable], 1.0)
    assert result.q_phi == pytest.approx(q_phi, rel=1e-8)
    assert result.d == pytest.approx(d, rel=1e-10)
    with_zero = beale_nonlinearity(problem(), theta_hat, g, r, np.where(std == np.inf, 0, std), 1.0)
    assert with_zero.points == 6 and with_zero.q_phi == pytest.approx(q_phi, rel=1e-8)
    # nothing to perturb: N_φ is undefined (NaN), no integration is spent
    none = beale_nonlinearity(problem(), theta_hat, g, r, np.full(4, np.inf), 1.0)
    assert (none.points, none.evaluations, none.s2, none.perturbation) == (0, 0, 1.0, 1.0)
    assert all(math.isnan(v) for v in (none.n_phi, none.q_phi, none.d, none.beale_factor))


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_beale_perturbation_must_be_positive_and_finite(pendulum_point, bad):
    problem, theta_hat, g, r, _ = pendulum_point
    with pytest.raises(InputError, match="perturbation: expected a positive multiple of σ, got"):
        beale_nonlinearity(problem(), theta_hat, g, r, np.full(4, 0.01), 1.0, perturbation=bad)


def test_beale_n_phi_is_zero_for_a_model_linear_in_its_parameters():
    # closed form: δY_w = G Δθ_w exactly, so δY − Gφ = 0 and Q_φ = 0 (METHOD §10)
    est, data = linear_estimate()
    accuracy = assess(est, data, methods="cr", polish=False, warn=False)
    assert accuracy.nonlinearity.d > 0
    assert accuracy.nonlinearity.n_phi == pytest.approx(0.0, abs=1e-12)


def test_coloured_sigma_equals_scaled_cr_sigma_for_white_single_output_residuals(exp_case):
    """With lag L = 0 and one output the coloured sandwich reduces to the scaled CR bound.

    Derivation (one output, R a scalar, r̂ = (1/N) Σ_i ν_i² = R̂_ν(0), M = Σ_i G_iᵀG_i / R):
        middle = Σ_i G_iᵀ R⁻¹ r̂ R⁻¹ G_i = (r̂/R) M
        Cov_c  = M⁻¹ middle M⁻¹ · N n_o/(N n_o − n_p) = (r̂/R) M⁻¹ · N/(N − n_p)
        s²     = J/(N − n_p) = (N r̂/R)/(N − n_p)
    so Cov_c = s² M⁻¹: σ_coloured = s σ_CR = std_scaled, to round-off. Without the factor
    N n_o/(N n_o − n_p) the ratio would be √((N − n_p)/N) = √(38/41) ≈ 0.963.
    """
    est, data = exp_case
    accuracy = assess(est, data, methods="cr", max_lag=0, polish=False, warn=False)
    assert accuracy.coloured_lag == 0
    n, n_p = accuracy.n_data, accuracy.n_free
    assert (n, n_p) == (41, 3)
    np.testing.assert_allclose(accuracy.std_coloured / accuracy.std_scaled, 1.0, rtol=1e-9)
    # and the scaled bound itself is s·σ_CR with s² = J/(N − n_p)
    s = np.sqrt(accuracy.cost_min / (n - n_p))
    np.testing.assert_allclose(accuracy.std_scaled, s * np.sqrt(np.diag(est.covariance)))


# ---------------------------------------------------------------- levels: boundaries, defaults
def test_contour_level_defaults_are_individual_t_intervals():
    # t_{0.975}(10)² = F_{0.95}(1, 10): the individual-interval level with the paper's F
    expected = stats.t.ppf(0.975, 10) ** 2
    assert contour_level(0.95, 12, 2, 1.0) == pytest.approx(expected, rel=1e-12)
    assert contour_level(0.95, 12, 2, 2.0) == pytest.approx(2.0 * expected, rel=1e-12)


def test_levels_at_the_smallest_degrees_of_freedom():
    # N·n_o − n_p = 1 is the smallest usable case: s² = J/1, Δ = s² t²_{0.975}(1)
    assert residual_variance_factor(5.0, 3, 2) == 5.0
    assert contour_level(0.95, 3, 2, 1.0) == pytest.approx(stats.t.ppf(0.975, 1) ** 2)
    # and N·n_o − n_p = 0 is refused with a message naming the counts
    with pytest.raises(InputError, match=r"need more scalar measurements \(N·n_o = 2\)"):
        residual_variance_factor(5.0, 2, 2)
    with pytest.raises(InputError, match=r"N·n_o = 2 must exceed the 2 free parameters"):
        contour_level(0.95, 2, 2, 1.0)
    # the χ² level needs no degrees of freedom
    assert contour_level(0.95, 2, 2, 1.0, distribution="normal") == pytest.approx(
        stats.chi2.ppf(0.95, 1)
    )


def test_level_arguments_are_checked_by_name():
    with pytest.raises(InputError, match=r"level: expected a probability such as 0\.95, got 'x'"):
        check_level("x")
    with pytest.raises(InputError, match="level: expected a probability strictly between 0 and 1"):
        check_level(1.0)
    with pytest.raises(InputError, match=r"kind: expected one of \('individual', 'simultaneous'\)"):
        contour_level(0.95, 12, 2, 1.0, kind="joint")
    with pytest.raises(InputError, match=r"distribution: expected one of \('t', 'normal'\)"):
        contour_level(0.95, 12, 2, 1.0, distribution="F")


def test_beale_factor_of_an_undefined_n_phi_is_nan():
    assert math.isnan(beale_factor(float("nan"), 100, 4))
    assert beale_factor(0.0, 100, 4) == 1.0


def test_beale_reports_a_diverging_perturbed_point(pendulum_point):
    # c − 10³: strong negative damping, the pendulum's simulation overflows within 8 s
    problem, theta_hat, g, r, _ = pendulum_point
    std = np.array([0.05, 1e3, 0.03, 0.01])
    with (
        np.errstate(over="ignore", invalid="ignore"),
        pytest.raises(InputError, match="simulation diverge; use a smaller perturbation"),
    ):
        beale_nonlinearity(problem(), theta_hat, g, r, std, 1.0)
