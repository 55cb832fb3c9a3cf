"""MNRES, secant form (issue 14): Broyden's rank-one update of the estimated sensitivities, the
trust-region step from the normal matrix, and the solver on the paper's example 1."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg.lapack

from flightid.estimation import MNR, MNRES, estimate
from flightid.estimation.solvers.mnres import (
    _exact_normal,
    _secant_step,
    _SecantState,
)
from flightid.paper.examples12 import EXAMPLE1_CONVERGENCE, example1_data, example_model
from flightid.paper.linear_system import TRUE_VALUES


def _state(rng, n_samples=50, n_outputs=3, n_free=5, scale=None):
    jacobian = rng.normal(size=(n_samples, n_outputs, n_free))
    return _SecantState.from_jacobian(
        np.zeros(n_free),
        np.zeros((n_samples, n_outputs)),
        0.0,
        np.ones(n_free) if scale is None else scale,
        jacobian,
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
    # secant default: one disappointing carried pass per 20 free parameters before a sweep
    assert MNRES()._max_rejections(22) == 1
    assert MNRES()._max_rejections(39) == 1
    assert MNRES()._max_rejections(40) == 2
    assert MNRES(max_rejections=1)._max_rejections(40) == 1
    assert MNRES(form="algebraic")._max_rejections(40) == 2
    assert MNRES(form="recursive")._max_rejections() == 2


def test_secant_update_is_least_change_in_the_scaled_coordinates():
    # G is kept in θ units, the update is Broyden's in ϑ = θ / scale: G_ϑ = G S must equal
    # G_ϑ + u Δϑᵀ/‖Δϑ‖² with u = Δy − G_ϑΔϑ, computed here independently in ϑ
    rng = np.random.default_rng(5)
    scale = np.array([0.1, 2.0, 50.0, 1e-3, 1.0])
    state = _state(rng, scale=scale)
    g_theta = state.jacobian.copy()
    step = rng.normal(size=5) * scale  # Δθ
    change = rng.normal(size=(50, 3))
    MNRES._secant_update(state, step, change)
    g_vartheta = g_theta * scale
    d_vartheta = step / scale
    u = change - g_vartheta @ d_vartheta
    expected = g_vartheta + u[..., None] * (d_vartheta / (d_vartheta @ d_vartheta))
    np.testing.assert_allclose(state.jacobian * scale, expected, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(state.jacobian @ step, change, rtol=1e-10, atol=1e-12)
    exact = _exact_normal(state.jacobian)
    np.testing.assert_allclose(state.normal_by_output, exact, rtol=1e-10, atol=1e-10)


def test_sweep_sensitivities_are_kept_once_and_updated_in_place():
    # a finite-difference G is a view of a C-ordered (n_f, N, n_o) array: the state keeps
    # that memory (no copy), and the rank-one updates write into it
    rng = np.random.default_rng(6)
    columns = rng.normal(size=(5, 40, 3))
    g = np.moveaxis(columns, 0, -1)
    state = _SecantState.from_jacobian(np.zeros(5), np.zeros((40, 3)), 0.0, np.ones(5), g)
    assert np.shares_memory(state.columns, columns)
    MNRES._secant_update(state, rng.normal(size=5), rng.normal(size=(40, 3)))
    assert np.shares_memory(state.columns, columns)
    np.testing.assert_array_equal(state.jacobian, g)
    # blocks from the columns equal those of the (N, n_o, n_f) array
    np.testing.assert_allclose(_exact_normal(state.columns, 3), _exact_normal(g), rtol=1e-12)


def test_damped_step_after_a_failure_when_the_radius_is_a_small_part_of_gauss_newton():
    # ill-conditioned M: two weak directions (columns 0/1 and 2/3 nearly collinear), the
    # second pair 100× larger, so the column metric D = diag √M_jj is far from a multiple
    # of I and an identity-damped step differs (there ‖(M + μD²)Δϑ − c‖ ≈ 0.1 for any μ)
    rng = np.random.default_rng(7)
    a = rng.normal(size=(300, 4))
    a[:, 1] = a[:, 0] + 1e-3 * rng.normal(size=300)
    a[:, 3] = a[:, 2] + 1e-3 * rng.normal(size=300)
    a[:, 2:] *= 100.0
    b = rng.normal(size=300)
    normal, gradient = a.T @ a, a.T @ b
    held = np.zeros(4, dtype=bool)
    gn, _ = _secant_step(normal, gradient, held, np.inf)
    length = np.linalg.norm(gn)
    radius = length / 20.0
    _, shortened = _secant_step(normal, gradient, held, radius)
    _, damped = _secant_step(normal, gradient, held, radius, damped=True)
    np.testing.assert_allclose(shortened, gn / 20.0, rtol=1e-9)
    # Levenberg–Marquardt in the column metric: length Δ and (M + μD²)Δϑ = c for one μ > 0
    np.testing.assert_allclose(np.linalg.norm(damped), radius, rtol=1e-5)
    d2 = np.diag(normal)
    direction = d2 * damped
    mu = -((normal @ damped - gradient) @ direction) / (direction @ direction)
    assert mu > 0
    atol = 1e-6 * np.max(np.abs(gradient))
    np.testing.assert_allclose(normal @ damped + mu * direction, gradient, rtol=0, atol=atol)

    # it predicts a larger drop than the shortened Gauss–Newton step of the same length
    def drop(step):
        return 2.0 * gradient @ step - step @ normal @ step

    assert drop(damped) > drop(shortened)
    # a radius that keeps more than 1/8 of the Gauss–Newton step: still shortened Gauss–Newton
    _, kept = _secant_step(normal, gradient, held, length / 4.0, damped=True)
    np.testing.assert_allclose(kept, gn / 4.0, rtol=1e-9)


def _long_linear_problem(duration_s=1000.0):
    from flightid.estimation import OutputErrorProblem
    from flightid.paper.examples12 import _measured

    t = np.arange(0.0, duration_s + 1e-9, 0.01)
    data = _measured(t, np.sin(t), 0.0, 0)
    return OutputErrorProblem(example_model(), data, method="euler")


def test_a_new_sweep_holds_one_sensitivity_array_at_a_time():
    # Before: the carried G stayed alive while the sweep differenced into a new array and
    # scaled it into a third (peak ≈ 2 G above the carried one; measured 665 MB for a
    # 128 MB G at N = 1e5, bench/peers.py --memory). Now the carried G goes first.
    import tracemalloc

    from flightid.estimation import Convergence
    from flightid.estimation.objective import Objective

    problem = _long_linear_problem()
    objective = Objective(problem, np.ones(problem.n_outputs), "fixed", Convergence())
    theta = problem.theta_start
    cost, outputs = objective.evaluate_start(theta)
    solver = MNRES()
    tracemalloc.start()  # before the first G exists, so that freeing it counts
    try:
        first = solver._sweep(objective, theta, outputs, cost, None)
        g_bytes = first.columns.nbytes
        base = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        second = solver._sweep(objective, theta, outputs, cost, first)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert g_bytes > 5e6
    assert first.columns is None
    # Differencing itself holds the new G and a batch of perturbed outputs and states (here,
    # N = 1e5 and n_f = 6, the whole batch: 2 G) at once; minus the carried G freed first:
    # ≈ 2 G. Keeping the carried G (the former code): ≈ 3 G.
    assert peak <= 2.5 * g_bytes, peak / g_bytes
    assert second.columns.nbytes == g_bytes


def test_the_last_sweep_is_handed_to_the_confirmation_when_the_solver_stops_there():
    # started at the optimum of noise-free data: the first sweep settles it; the outcome
    # carries that sweep's forward differences (G itself, not a copy) for the confirmation
    from flightid.estimation import Convergence, OutputErrorProblem
    from flightid.estimation.objective import Objective

    data = example1_data()
    problem = OutputErrorProblem(example_model(TRUE_VALUES), data, method="euler")
    objective = Objective(problem, np.ones(problem.n_outputs), "fixed", EXAMPLE1_CONVERGENCE)
    outcome = MNRES().minimize(objective, problem.theta_start)
    assert outcome.converged, outcome.message
    record = outcome.differences
    assert record is not None
    np.testing.assert_array_equal(record.theta, outcome.theta)
    assert np.shares_memory(record.g, outcome.state.columns)
    # after a secant update the record no longer describes G: it is not handed over
    state = outcome.state
    MNRES._secant_update(state, 1e-3 * np.ones(problem.n_free), np.ones_like(state.outputs))
    assert state.differences is None
    assert Convergence  # imported for the objective's type


def test_secant_kernel_equals_the_numpy_update_and_reductions():
    # one call of the compiled kernel: u = Δy − GΔθ, p_k = G_kᵀu_k with the old G,
    # G ← G + u wᵀ and G_kᵀG_k ← G_kᵀG_k + p_k wᵀ + w p_kᵀ + ‖u_k‖² w wᵀ
    from flightid.estimation.solvers.mnres import _secant_kernel, _secant_pass

    rng = np.random.default_rng(8)
    n_free, n_samples, n_outputs = 6, 37, 3
    columns = rng.normal(size=(n_free, n_samples * n_outputs))
    change, step, w = (
        rng.normal(size=n_samples * n_outputs),
        rng.normal(size=n_free),
        rng.normal(size=n_free),
    )
    step[2] = 0.0  # a parameter held on a bound
    normal = rng.normal(size=(n_outputs, n_free, n_free))
    g_old = np.moveaxis(columns.reshape(n_free, n_samples, n_outputs), 0, -1).copy()
    u = change - columns.T @ step
    expected_p = np.einsum("ikj,ik->kj", g_old, u.reshape(n_samples, n_outputs))
    expected_q = np.sum(u.reshape(n_samples, n_outputs) ** 2, axis=0)
    expected_columns = columns + np.outer(w, u)
    expected_normal = (
        normal
        + expected_p[:, :, None] * w[None, None, :]
        + w[None, :, None] * expected_p[:, None, :]
        + expected_q[:, None, None] * np.outer(w, w)[None]
    )
    for kernel in (_secant_kernel(), _secant_pass):  # compiled and plain Python
        for update_normal in (True, False):
            c, n = columns.copy(), normal.copy()
            kernel(c, change, step, w, n, n_outputs, update_normal)
            np.testing.assert_allclose(c, expected_columns, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(
                n, expected_normal if update_normal else normal, rtol=1e-12, atol=1e-12
            )


def test_triangular_factor_runs_lapack_on_one_thread():
    # the QR blocks of the Gauss–Newton factor (MNRES's confirmation and CR bounds, MNR's
    # passes) are ~1000 × (n_f + 1) whatever N is: one BLAS thread inside, restored after
    from threadpoolctl import ThreadpoolController

    from flightid.estimation import gauss_newton

    controller = ThreadpoolController()
    if not controller.select(user_api="blas").lib_controllers:
        pytest.skip("no BLAS library found by threadpoolctl")

    def blas_threads():
        return {
            c.num_threads for c in ThreadpoolController().select(user_api="blas").lib_controllers
        }

    with controller.limit(limits=2, user_api="blas"):
        seen = []
        original = scipy.linalg.lapack.dgeqrf

        def spy(*args, **kwargs):
            seen.append(blas_threads())
            return original(*args, **kwargs)

        rng = np.random.default_rng(3)
        g, nu = rng.normal(size=(300, 4, 5)), rng.normal(size=(300, 4))
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(scipy.linalg.lapack, "dgeqrf", spy)
            factor = gauss_newton.triangular_factor(g, nu, np.ones(4))
        assert seen and all(threads == {1} for threads in seen)
        assert blas_threads() == {2}
        a = np.concatenate([g.reshape(-1, 5), nu.reshape(-1, 1)], axis=1)
        np.testing.assert_allclose(np.abs(factor), np.abs(np.linalg.qr(a, mode="r")), atol=1e-10)


def test_a_noise_cycle_ends_on_a_proven_carried_model_and_the_estimate_is_mnr_s():
    # HFB-320 (11 free, MAX noise policy, four noise cycles): MNRES ends each cycle as soon as
    # a step on carried sensitivities proven by the previous step moves the cost by less than
    # the tolerance, instead of sweeping again. Regression values (this code, 2026-11-26):
    # 119 simulations in all against MNR's 205; without the rule MNRES took 213. The estimate
    # is the same optimum (central-difference confirmation): within 0.05 Cramér–Rao σ of MNR.
    import dataclasses
    from pathlib import Path

    from flightid.cases import load_case, run_case
    from flightid.cases.build import resolve_data_dir

    case = load_case(
        Path(__file__).resolve().parents[1] / "examples/cases/hfb320_longitudinal_builtin.toml"
    )
    if not (resolve_data_dir(case) / "fvsysid/hfb320_1_10.asc").exists():
        pytest.skip("book data (fvsysid/hfb320_1_10.asc) not found")
    runs = {}
    for solver in ("mnres", "mnr"):
        spec = dataclasses.replace(case, estimation={**case.estimation, "solver": solver})
        runs[solver] = run_case(spec, accuracy="none").estimate
    mnres, mnr = runs["mnres"], runs["mnr"]
    assert mnres.converged and mnr.converged
    assert mnres.noise_cycles >= 3
    assert mnres.equivalent_evaluations <= 150 < mnr.equivalent_evaluations
    for name in mnr.parameters.free_names:
        assert abs(mnres.value(name) - mnr.value(name)) <= 0.05 * mnr.stddev(name), name


def test_the_first_trial_on_a_later_sweep_is_the_full_gauss_newton_step(monkeypatch):
    # After a later sweep the kept radius (shrunk by the carried passes) does not limit the
    # first trial: it is the Gauss–Newton step itself (the paper's rule). Recorded here: the
    # radius _secant_step gets on the first trial after each sweep but the first.
    from flightid.estimation.solvers import mnres as module

    radii, fresh_first = [], []
    original_step = module._secant_step
    original_sweep = module.MNRES._sweep

    def sweep(self, objective, theta, outputs, cost, previous):
        state = original_sweep(self, objective, theta, outputs, cost, previous)
        fresh_first.append(previous is not None)
        return state

    def step(normal, gradient, held, radius, damped):
        if fresh_first and fresh_first[-1]:
            radii.append(radius)
            fresh_first[-1] = False
        return original_step(normal, gradient, held, radius, damped)

    monkeypatch.setattr(module, "_secant_step", step)
    monkeypatch.setattr(module.MNRES, "_sweep", sweep)
    data = example1_data()
    start = tuple(1.5 * v for v in TRUE_VALUES)
    result = estimate(example_model(start), data, MNRES(), convergence=EXAMPLE1_CONVERGENCE)
    assert result.converged
    assert radii, "no later sweep happened: the test needs a start that takes two sweeps"
    assert all(r == np.inf for r in radii), radii


def test_damped_step_on_a_zero_radius_is_named_not_a_division_by_zero():
    from flightid.estimation.solvers.mnres import _damped_step, _TrustRadiusCollapsed

    normal = np.array([[2.0, 0.5], [0.5, 1.0]])
    gradient = np.array([1.0, -1.0])
    moving = np.array([True, True])
    with pytest.raises(_TrustRadiusCollapsed):
        _damped_step(normal, gradient, moving, 0.0)
    # a positive radius still gives the step on the radius: ‖Δϑ‖ = Δ
    step = _damped_step(normal, gradient, moving, 0.1)
    assert np.linalg.norm(step) == pytest.approx(0.1, rel=1e-5)


def test_collapsed_trust_radius_stops_the_secant_search_as_stalled(monkeypatch):
    """Example 2, case 2, with tolerances no step can meet: the rejected trials halve the
    radius until a step no longer moves θ and the radius becomes 0. The search ends as
    stalled with the radius it reached (it raised ZeroDivisionError before)."""
    import flightid.estimation.driver as driver
    from flightid.estimation import Convergence
    from flightid.paper.examples12 import example2_data

    seen = []
    confirm = driver.confirm_convergence

    def recording(objective, outcome, *args, **kwargs):
        seen.append((outcome.status, outcome.converged, outcome.message))
        return confirm(objective, outcome, *args, **kwargs)

    monkeypatch.setattr(driver, "confirm_convergence", recording)
    result = estimate(
        example_model(),
        example2_data(2),
        MNRES(fresh_rejections=40),
        noise="fixed",
        convergence=Convergence(cost_rtol=1e-15, param_rtol=1e-15, max_iterations=60),
    )
    ((status, converged, message),) = seen
    assert status == "stalled" and not converged
    assert message.startswith("stalled: the trust radius collapsed")
    assert "no step lowered the cost down to a radius of " in message
    assert "in ϑ = θ / scale" in message
    # the last positive radius tried: below double precision relative to θ (the steps it
    # allows no longer change θ), not the 0 it ended at
    radius = float(message.split("radius of ")[1].split(" ")[0])
    assert 0.0 < radius < 1e-15
    # the driver judges a stalled solver's end point by central differences (as every
    # stall): the estimate is converged only where that test holds, and says the solver stalled
    assert result.status in ("converged", "stalled")
    if result.converged:
        assert "where the solver stalled" in result.message
