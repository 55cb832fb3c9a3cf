"""The shared Gauss–Newton path after issue 14 part 4 (blockwise factor, batched differences
differenced into G, the confirmation completing MNR's last forward differences): checked
against closed forms that do not use flightid's code.

Reference: a model linear in its parameters with two outputs, y = X(u) θ + noise, whose
sensitivities are exactly the regressors X; the weighted least-squares solution, its
information matrix XᵀR⁻¹X and covariance (XᵀR⁻¹X)⁻¹ are computed here with numpy's lstsq /
einsum / inv. Speed is measured in bench/gauss_newton_overhead.py, never here.
"""

from __future__ import annotations

import numpy as np
import pytest

import flightid.estimation.problem as problem_module
from conftest import pendulum_data, pendulum_model
from flightid.data.flightdata import FlightData
from flightid.estimation import MNR, Convergence, OutputErrorProblem, estimate
from flightid.estimation.gauss_newton import (
    gauss_newton_step,
    information_matrix,
    triangular_factor,
)
from flightid.estimation.objective import Objective
from flightid.model.statespace import StateSpaceModel

N = 1500  # 2 outputs: three blocks of samples in the blockwise factor (512, 512, 476)
SIGMA = np.array([0.05, 0.2])
TRUTH = np.array([0.3, -1.2, 0.8, 0.5, -0.7])


def h_two_outputs(t, x, u, theta):
    # y1 = θ0 + θ1·u1 + θ2·u1·u2;  y2 = θ1·u2 + θ3·sin(u2) + θ4
    return np.array(
        [
            theta[0] + theta[1] * u[0] + theta[2] * u[0] * u[1],
            theta[1] * u[1] + theta[3] * np.sin(u[1]) + theta[4],
        ]
    )


def _regressors(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """X (N, 2, 5): ∂y_ik/∂θ_j of h_two_outputs, written out by hand."""
    x = np.zeros((u1.size, 2, 5))
    x[:, 0, 0], x[:, 0, 1], x[:, 0, 2] = 1.0, u1, u1 * u2
    x[:, 1, 1], x[:, 1, 3], x[:, 1, 4] = u2, np.sin(u2), 1.0
    return x


@pytest.fixture(scope="module")
def linear_case():
    rng = np.random.default_rng(14)
    t = np.arange(N) * 0.02
    u1, u2 = rng.uniform(-1.0, 1.0, N), rng.uniform(-2.0, 2.0, N)
    x = _regressors(u1, u2)
    z = np.einsum("ikj,j->ik", x, TRUTH) + rng.normal(size=(N, 2)) * SIGMA
    data = FlightData(t, {"u1": u1, "u2": u2}, {"y1": z[:, 0], "y2": z[:, 1]})
    model = StateSpaceModel(
        (),
        ("u1", "u2"),
        ("y1", "y2"),
        None,
        h_two_outputs,
        {"a": 0.0, "b": 0.1, "c": 0.0, "d": 0.2, "e": 0.0},
    )
    return model, data, x, z


def _weighted_least_squares(x, z, r_diag, moving=None):
    """θ minimising Σ_i (z_i − X_i θ)ᵀR⁻¹(z_i − X_i θ), by numpy's lstsq on rows (i, k)."""
    w = 1.0 / np.sqrt(r_diag)
    a = (x * w[None, :, None]).reshape(-1, x.shape[-1])
    b = (z * w[None, :]).reshape(-1)
    theta = np.zeros(x.shape[-1])
    moving = np.ones(x.shape[-1], dtype=bool) if moving is None else moving
    theta[moving] = np.linalg.lstsq(a[:, moving], b, rcond=None)[0]
    return theta, a, b


def test_information_matrix_and_step_are_the_weighted_least_squares_ones(linear_case):
    _, _, x, z = linear_case
    r_diag = SIGMA**2
    theta_ls, a, b = _weighted_least_squares(x, z, r_diag)
    # M = Σ_i X_iᵀ R⁻¹ X_i, summed here without flightid
    m_reference = np.einsum("ikj,k,ikl->jl", x, 1.0 / r_diag, x)
    # G as the solvers hold it: a view of an (n_f, N, n_o) array, and a contiguous copy
    strided = np.moveaxis(np.ascontiguousarray(np.moveaxis(x, -1, 0)), 0, -1)
    for g in (x, strided):
        np.testing.assert_allclose(information_matrix(g, r_diag), m_reference, rtol=1e-12)
        # from θ = 0 the residuals are z, and one Gauss–Newton step lands on the LS solution
        step = gauss_newton_step(g, z, r_diag)
        np.testing.assert_allclose(step.step, theta_ls, rtol=1e-10)
        assert step.rank == 5 and step.undetermined == ()
        # predicted drop ΔθᵀMΔθ = ‖AΔθ‖²
        assert step.predicted_reduction == pytest.approx(np.sum((a @ theta_ls) ** 2), rel=1e-10)
        # the blockwise triangle T of [A | b]: TᵀT = [A | b]ᵀ[A | b]
        t = triangular_factor(g, z, r_diag)
        ab = np.column_stack([a, b])
        np.testing.assert_allclose(t.T @ t, ab.T @ ab, rtol=1e-10, atol=1e-9 * np.abs(ab).max())
        assert np.allclose(np.tril(t, -1), 0.0)
    # held parameters: Δθ_j = 0 for them, the others the LS solution over the moving columns
    held = np.array([False, True, False, False, True])
    theta_held, _, _ = _weighted_least_squares(x, z, r_diag, moving=~held)
    step = gauss_newton_step(strided, z, r_diag, held=held)
    np.testing.assert_allclose(step.step, theta_held, rtol=1e-10, atol=1e-14)
    assert np.all(step.step[held] == 0.0)


def test_a_rank_deficient_problem_names_its_undetermined_parameters(linear_case):
    _, _, x, z = linear_case
    g = x.copy()
    g[..., 4] = 2.0 * g[..., 3]  # θ3 and θ4 move the outputs together
    step = gauss_newton_step(g, z, SIGMA**2)
    assert step.rank == 4
    assert set(step.undetermined) == {3, 4}


def test_finite_differences_use_the_relative_step_and_give_the_regressors(linear_case):
    model, data, x, _ = linear_case
    problem = OutputErrorProblem(model, data)
    theta = np.array([0.4, -2.0, 0.0, 1e-5, 3.0])
    forward = problem.differences(theta, relative_step=1e-6)
    # δ_j = 10⁻⁶·max(|θ_j|, floor_j), floor 1e-3 (no scale given)
    np.testing.assert_array_equal(forward.steps, 1e-6 * np.maximum(np.abs(theta), 1e-3))
    assert forward.plain and not forward.central
    # exact derivative of a linear model: X, up to the rounding of the difference, ε·|y|/δ_j
    rounding = 8 * np.finfo(float).eps * np.abs(forward.outputs).max() / forward.steps
    assert np.all(np.abs(forward.g - x).max(axis=(0, 1)) <= rounding)
    # the quotient itself, from two integrations written out here
    j = 1
    bumped = theta.copy()
    bumped[j] += forward.steps[j]
    quotient = (problem.outputs(bumped[None])[0] - problem.outputs(theta[None])[0]) / (
        forward.steps[j]
    )
    np.testing.assert_array_equal(forward.g[..., j], quotient)


@pytest.mark.parametrize("central", [False, True])
def test_batches_of_perturbations_give_the_same_sensitivities(monkeypatch, central):
    problem = OutputErrorProblem(pendulum_model(), pendulum_data())
    theta = problem.theta_start
    whole, outputs = problem.sensitivities(theta, central=central)
    before = problem.evaluations
    # one trajectory per batch: every batch boundary is crossed
    monkeypatch.setattr(problem_module, "DIFFERENCE_BATCH_BYTES", 1)
    batched, _ = problem.sensitivities(theta, outputs, central=central)
    np.testing.assert_array_equal(batched, whole)
    assert problem.evaluations - before == (2 if central else 1) * problem.n_free


def test_completing_forward_differences_gives_the_central_ones():
    problem = OutputErrorProblem(pendulum_model(), pendulum_data())
    theta = problem.theta_start
    forward = problem.differences(theta, relative_step=1e-6)
    forward_g = forward.g.copy()
    before = problem.evaluations
    completed = problem.complete_central(forward)
    assert problem.evaluations - before == problem.n_free  # the backward half only
    assert completed.central and completed.g is forward.g  # in place, no second G
    scratch, _ = problem.sensitivities(theta, forward.outputs, relative_step=1e-6, central=True)
    scale = np.abs(scratch).max(axis=(0, 1))
    agreement = np.abs(completed.g - scratch).max(axis=(0, 1)) / scale
    one_sided = np.abs(forward_g - scratch).max(axis=(0, 1)) / scale
    # equal to rounding, where the forward quotients differ at O(δ)
    assert np.all(agreement < 1e-7), agreement
    assert np.all(one_sided > 100 * agreement), (one_sided, agreement)


def test_estimate_is_the_weighted_least_squares_solution_with_its_cramer_rao_matrix(
    linear_case,
):
    model, data, x, z = linear_case
    r_diag = SIGMA**2
    est = estimate(model, data, MNR(), noise="fixed", R=r_diag)
    assert est.converged, est.message
    theta_ls, _, _ = _weighted_least_squares(x, z, r_diag)
    # MNR stops once the next step is below 10⁻³ relative; the linear model's first step
    # lands on the optimum up to the finite differences' rounding
    np.testing.assert_allclose(est.values, theta_ls, rtol=1e-7)
    m_reference = np.einsum("ikj,k,ikl->jl", x, 1.0 / r_diag, x)
    np.testing.assert_allclose(est.information_matrix, m_reference, rtol=1e-7)
    np.testing.assert_allclose(est.covariance, np.linalg.inv(m_reference), rtol=1e-6)
    np.testing.assert_allclose(est.std, np.sqrt(np.diag(np.linalg.inv(m_reference))), rtol=1e-6)
    np.testing.assert_allclose(est.sensitivities, x, rtol=0, atol=1e-8)
    # MNR's last forward differences at θ̂ are half of the central ones: n_f more integrations
    assert est.accuracy_evaluations == x.shape[-1]
    assert not est.sensitivities.flags.writeable
    assert len(est.cost_history) == len(est.evaluation_history) >= 2
    assert est.wall_time_s > 0


def test_user_steps_are_not_taken_for_the_confirmation_half(linear_case):
    # forward differences with another step are not half of the confirmation's central ones
    model, data, _, _ = linear_case
    est = estimate(
        model,
        data,
        MNR(relative_step=1e-5),
        noise="fixed",
        R=SIGMA**2,
        convergence=Convergence(),
    )
    assert est.converged
    assert est.accuracy_evaluations == 2 * 5


def test_confirmation_steps_on_forward_differences_and_decides_on_central_ones():
    # MNR with the paper's tests at 0.5 stops short (measured: 7 passes, 36 integrations,
    # its last forward differences at θ̂); the confirmation then takes its passes on forward
    # differences (n_f + 1 integrations each: no backward half where a full step lowers the
    # cost) and completes only the end point's to central ones (n_f more), which decide
    # "converged" and give the Cramér–Rao matrix. Before: 2·n_f + 1 per pass.
    loose = Convergence(cost_rtol=0.5, param_rtol=0.5)
    model, data = pendulum_model((6.0, 0.8, 0.1, 3.0)), pendulum_data()
    r_diag = np.array([0.01, 0.05]) ** 2  # pendulum_data's noise variances
    problem = OutputErrorProblem(model, data)
    objective = Objective(problem, r_diag, "fixed", loose)
    stop = MNR().minimize(objective, problem.theta_start)
    solver_evaluations, n_f = problem.evaluations, problem.n_free
    assert stop.converged and stop.differences is not None  # the solver's forward half at θ̂

    est = estimate(model, data, MNR(), noise="fixed", R=r_diag, convergence=loose)
    passes = est.iterations - stop.iterations
    assert est.converged and passes >= 1, est.message
    assert est.optimality_sigma <= loose.confirm_sigma
    # per pass: one integration at the full step, then the forward half at the new point;
    # at the end point its backward half. The end point's two halves are the accuracy G's.
    total = est.equivalent_evaluations + est.accuracy_evaluations
    assert total == solver_evaluations + passes * (1 + n_f) + n_f
    assert est.accuracy_evaluations == 2 * n_f
    # the Cramér–Rao sensitivities are the central differences at θ̂, to rounding
    theta_hat = est.values[problem.free_index]
    central, _ = problem.sensitivities(theta_hat, relative_step=1e-6, central=True)
    forward, _ = problem.sensitivities(theta_hat, relative_step=1e-6)
    scale = np.abs(central).max(axis=(0, 1))
    agreement = np.abs(est.sensitivities - central).max(axis=(0, 1)) / scale
    one_sided = np.abs(forward - central).max(axis=(0, 1)) / scale
    assert np.all(agreement < 1e-7) and np.all(one_sided > 100 * agreement)
