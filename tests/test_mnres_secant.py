"""MNRES, secant form (issue 14): Broyden's rank-one update of the estimated sensitivities, the
trust-region step from the normal matrix, and the solver on the paper's example 1."""

from __future__ import annotations

import numpy as np

from flightid.estimation import MNR, MNRES, estimate
from flightid.estimation.solvers.mnres import (
    _exact_normal,
    _secant_step,
    _SecantState,
)
from flightid.paper.examples12 import EXAMPLE1_CONVERGENCE, example1_data, example_model
from flightid.paper.linear_system import TRUE_VALUES


def _state(rng, n_samples=50, n_outputs=3, n_free=5):
    jacobian = rng.normal(size=(n_samples, n_outputs, n_free))
    return _SecantState(
        theta=np.zeros(n_free),
        outputs=np.zeros((n_samples, n_outputs)),
        cost=0.0,
        scale=np.ones(n_free),
        jacobian=jacobian,
        normal_by_output=_exact_normal(jacobian),
    )


def test_secant_update_meets_the_secant_condition_and_keeps_the_normal_matrix_exact():
    rng = np.random.default_rng(1)
    state = _state(rng)
    before = state.jacobian.copy()
    for _ in range(3):  # rank-one updates of J_kᵀJ_k (fewer than n_f: no exact recompute)
        step = rng.normal(size=5)
        change = rng.normal(size=(50, 3))
        MNRES._secant_update(state, step, change)
        # Broyden: the updated J reproduces the observed output change along the step
        np.testing.assert_allclose(state.jacobian @ step, change, rtol=1e-12, atol=1e-12)
    assert state.updates == 3
    # the rank-one-updated blocks equal the blocks of the updated J (independent recompute)
    exact = np.stack([state.jacobian[:, k, :].T @ state.jacobian[:, k, :] for k in range(3)])
    np.testing.assert_allclose(state.normal_by_output, exact, rtol=1e-10, atol=1e-10)
    # directions orthogonal to every step are untouched (least-change update)
    steps_span = np.linalg.qr(np.column_stack([rng.normal(size=5)]))[0]
    assert steps_span.shape == (5, 1)
    assert not np.allclose(state.jacobian, before)


def test_secant_update_changes_only_the_stepped_direction():
    rng = np.random.default_rng(2)
    state = _state(rng)
    before = state.jacobian.copy()
    step = np.array([0.0, 0.0, 0.3, 0.0, 0.0])  # along e_3: only column 3 changes
    change = rng.normal(size=(50, 3))
    MNRES._secant_update(state, step, change)
    np.testing.assert_allclose(state.jacobian[..., 2], change / 0.3, rtol=1e-12)
    np.testing.assert_array_equal(state.jacobian[..., [0, 1, 3, 4]], before[..., [0, 1, 3, 4]])


def test_secant_step_is_gauss_newton_inside_and_shortened_gauss_newton_outside():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(200, 4)) * np.array([1.0, 10.0, 0.1, 3.0])
    b = rng.normal(size=200)
    normal, gradient = a.T @ a, a.T @ b
    held = np.zeros(4, dtype=bool)
    expected = np.linalg.lstsq(a, b, rcond=None)[0]
    gn, step = _secant_step(normal, gradient, held, np.inf)
    np.testing.assert_allclose(gn, expected, rtol=1e-9)
    np.testing.assert_array_equal(step, gn)
    radius = 0.25 * np.linalg.norm(expected)
    gn2, step = _secant_step(normal, gradient, held, radius)
    np.testing.assert_allclose(gn2, expected, rtol=1e-9)
    # the Gauss–Newton direction, length Δ
    np.testing.assert_allclose(step, 0.25 * expected, rtol=1e-9)


def test_secant_step_holds_parameters_on_an_active_bound():
    rng = np.random.default_rng(4)
    a = rng.normal(size=(100, 3))
    b = rng.normal(size=100)
    held = np.array([False, True, False])
    gn, step = _secant_step(a.T @ a, a.T @ b, held, np.inf)
    assert gn[1] == 0.0 and step[1] == 0.0
    expected = np.linalg.lstsq(a[:, [0, 2]], b, rcond=None)[0]
    np.testing.assert_allclose(gn[[0, 2]], expected, rtol=1e-9)


def test_secant_mnres_on_example1_one_simulation_per_pass_after_the_sweep():
    data = example1_data()

    def run(solver):
        return estimate(
            example_model(),
            data,
            solver,
            method="euler",
            noise="fixed",
            convergence=EXAMPLE1_CONVERGENCE,
        )

    secant, mnr = run(MNRES()), run(MNR())
    assert secant.converged, secant.message
    # RP-1153 table II: the true values (noise-free data)
    np.testing.assert_allclose(secant.values, TRUE_VALUES, atol=1e-3)
    np.testing.assert_allclose(secant.values, mnr.values, atol=1e-4)
    n_free = len(TRUE_VALUES)
    history = np.array(secant.evaluation_history)
    # the start, one forward-difference sweep (n_f), then one simulation per accepted pass
    assert history[0] == 1 and history[1] == n_free + 2
    assert np.all(np.diff(history[1:]) >= 1)
    assert np.sum(np.diff(history[1:]) == 1) >= 3
    assert len(secant.cost_history) == len(secant.evaluation_history)
    assert secant.wall_time_s > 0
    # regression value (this implementation, 2026-11-23): 13 simulations against MNR's 28
    assert secant.equivalent_evaluations <= mnr.equivalent_evaluations / 2


def test_secant_settings_and_surface_forms():
    assert MNRES().settings()["form"] == "secant"
    assert MNRES()._perturbation() == 1e-3
    assert MNRES(form="algebraic")._perturbation() == 1e-3
    assert MNRES()._max_rejections() == 1
    assert MNRES(form="recursive")._max_rejections() == 2
