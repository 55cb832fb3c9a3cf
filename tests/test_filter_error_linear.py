"""Linear filter error (CASES.md §1c): exact discretisation and analytic gradients.

Independent checks: the Taylor series of the reference against expm; ∂P from the Lyapunov
equation against central differences of the Riccati solver; H against central differences of
filter passes; the filter pass against a NumPy loop written here; the estimate against the
generic (RK4, finite-difference) path on y13aus.
"""

from pathlib import Path

import numpy as np
import pytest
import scipy.linalg

from flightid.cases import load_case, run_case
from flightid.cases.run import prepare_case
from flightid.cases.spec import CaseError
from flightid.estimation.filter_error import FilterErrorProblem, _problem
from flightid.estimation.filter_error_linear import LinearFilterErrorProblem
from flightid.filtering import riccati_solution
from flightid.filtering.linear import (
    NotLinearError,
    check_linear,
    covariance_derivative,
    discretise,
    discretise_taylor,
)

CASES = Path(__file__).resolve().parents[1] / "examples" / "cases"
DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data not present")

# y13aus start values of CASES.md §1: A = [[Lp, Lr], [Np, Nr]], Δt = 0.05 s
A = np.array([[-6.7, 1.83], [-0.906, -0.665]])
C = np.vstack([A, [[-0.64, 1.30], [1.0, 0.0], [0.0, 1.0]]])
DT = 0.05


def test_taylor_series_of_the_reference_equals_expm():
    phi, psi = discretise(A, DT)
    phi_t, psi_t = discretise_taylor(A, DT, terms=12)
    # ‖AΔt‖ ≈ 0.35: the 12-term remainder is below 0.35¹³/13! ≈ 2e-16
    assert np.max(np.abs(phi - phi_t)) < 1e-12
    assert np.max(np.abs(psi - psi_t)) < 1e-12
    # Ψ = A⁻¹(Φ − I) for invertible A (independent identity)
    assert np.allclose(psi, np.linalg.solve(A, phi - np.eye(2)), atol=1e-14)
    # three Taylor terms are visibly worse: the test distinguishes the series
    assert np.max(np.abs(phi - discretise_taylor(A, DT, terms=2)[0])) > 1e-5


def test_covariance_derivative_against_central_differences_of_the_riccati_solver():
    rng = np.random.default_rng(3)
    r_diag = np.array([0.08, 0.0017, 0.004, 0.002, 0.0019])
    f_matrix = np.diag([0.17, 0.12])
    p = riccati_solution(A, C, f_matrix @ f_matrix.T, r_diag, DT)
    da, dc = rng.normal(size=A.shape), rng.normal(size=C.shape)
    df = np.diag(rng.normal(size=2))
    dffT = df @ f_matrix.T + f_matrix @ df.T
    dp = covariance_derivative(A, C, p, r_diag, DT, da, dc, dffT)
    h = 1e-6
    plus = riccati_solution(A + h * da, C + h * dc, (f_matrix + h * df) @ (f_matrix + h * df).T,
                            r_diag, DT)  # fmt: skip
    minus = riccati_solution(A - h * da, C - h * dc, (f_matrix - h * df) @ (f_matrix - h * df).T,
                             r_diag, DT)  # fmt: skip
    numeric = (plus - minus) / (2 * h)
    assert np.max(np.abs(dp - numeric)) < 1e-6 * np.max(np.abs(numeric))


def test_nonlinear_model_is_refused():
    def f(t, x, u, theta):
        return np.array([theta[0] * x[0] ** 2 + u[0]])

    def h(t, x, u, theta):
        return np.array([x[0]])

    with pytest.raises(NotLinearError, match="linear in the states"):
        check_linear(f, h, np.array([1.0]), 1, 1)


@pytest.fixture(scope="module")
def y13_problem():
    case = load_case(CASES / "y13aus_lateral_filter_error_linear.toml")
    prepared = prepare_case(case, data_dir=DATA)
    problem = LinearFilterErrorProblem(
        prepared.model, list(prepared.maneuvers), prepared.process_noise
    )
    problem.gain_r = problem.noise_covariance(problem.simulate(problem.theta_start))
    return problem, prepared


def _central(problem, theta, relative=1e-6):
    columns = []
    for j in range(theta.size):
        step = relative * max(abs(theta[j]), 1e-2)
        plus, minus = theta.copy(), theta.copy()
        plus[j] += step
        minus[j] -= step
        # H_j = (ỹ(θ + δ e_j) − ỹ(θ − δ e_j)) / 2δ
        up = problem.run(plus, check_kc=False).outputs[0]
        down = problem.run(minus, check_kc=False).outputs[0]
        columns.append((up - down) / (2 * step))
    return np.stack(columns, axis=-1)


@needs_data
def test_filter_pass_equals_an_expm_loop_written_here(y13_problem):
    problem, _ = y13_problem
    full = problem.theta_start_full
    point = problem.filter_point(full)
    a, b, bx, c, d, by = problem.matrices(full)
    u, z = problem._inputs[0], problem._measured[0]
    aug = np.zeros((4, 4))
    aug[:2, :2], aug[:2, 2:] = a * DT, np.eye(2) * DT
    e = scipy.linalg.expm(aug)
    x, ys = np.zeros(2), []
    for k in range(len(u)):
        y = c @ x + d @ u[k] + by
        ys.append(y)
        xh = x + point.gain @ (z[k] - y)
        if k + 1 < len(u):
            x = e[:2, :2] @ xh + e[:2, 2:] @ (b @ (u[k] + u[k + 1]) / 2 + bx)
    got = problem.run(problem.theta_start).outputs[0]
    assert np.max(np.abs(got - np.array(ys))) < 1e-12
    # the model read as matrices: A = [[Lp, Lr], [Np, Nr]] at the start values of CASES.md §1
    assert np.allclose(a, A, atol=1e-14)


@needs_data
def test_analytic_sensitivities_equal_central_differences(y13_problem):
    problem, _ = y13_problem
    theta = problem.theta_start
    h_analytic, outputs = problem.sensitivities(theta)
    numeric = _central(problem, theta)
    assert np.allclose(outputs, problem.run(theta).outputs[0], atol=1e-14)
    scale = np.max(np.abs(numeric), axis=(0, 1))
    error = np.max(np.abs(h_analytic - numeric), axis=(0, 1)) / scale
    assert np.max(error) < 1e-6, error


@needs_data
def test_analytic_sensitivities_with_pinned_process_noise(y13_problem):
    # F11, F22 solved from diag(KC) = 1 for every θ (the active constraint at the optimum);
    # the implicit-function chain rule against central differences of filter passes.
    # Values near the y13aus optimum (regression values of the case, rounded)
    problem, prepared = y13_problem
    values = dict(Lp=-5.72, Lr=1.72, Lda=-14.9, Ldr=0.2, Lv=-0.0884, Np=-0.621, Nr=-0.722,
                  Nda=-0.43, Ndr=-2.83, Nv=0.0092, Yp=-0.297, Yr=1.415, Yda=-0.51, Ydr=2.69,
                  Yv=-0.18, F11=0.167, F22=0.124)  # fmt: skip
    full = problem.theta_start_full.copy()
    for name, value in values.items():
        full[problem.model.parameters.names.index(name)] = value
    settings = {"gradients": "analytic"}
    pinned = _problem(problem.model, problem.maneuvers, prepared.process_noise, ["p", "r"],
                      full, settings)  # fmt: skip
    pinned.gain_r = np.array([0.0823, 0.00171, 0.00396, 0.00208, 0.00185])
    theta = pinned.theta_start
    h_analytic, _ = pinned.sensitivities(theta)
    numeric = _central(pinned, theta, relative=1e-5)
    scale = np.max(np.abs(numeric), axis=(0, 1))
    error = np.max(np.abs(h_analytic - numeric), axis=(0, 1)) / scale
    assert np.max(error) < 1e-5, error


@needs_data
def test_y13aus_linear_case_same_optimum_fewer_passes():
    linear = run_case(load_case(CASES / "y13aus_lateral_filter_error_linear.toml"), data_dir=DATA)
    generic = run_case(load_case(CASES / "y13aus_lateral_filter_error.toml"), data_dir=DATA)
    lin, gen = linear.estimate, generic.estimate
    assert lin.converged, lin.message
    assert lin.free_names == gen.free_names
    free = gen.free
    deviation = np.abs(lin.values[free] - gen.values[free]) / gen.std[free]
    # measured 0.016 σ at most (Lda, Nda): exact discretisation vs RK4
    assert np.max(deviation) < 0.05, deviation
    # measured 207 vs 1219 filter passes
    assert lin.equivalent_evaluations < 0.3 * gen.equivalent_evaluations


@needs_data
def test_linear_cost_equals_the_generic_rk4_cost(y13_problem):
    # the generic path (RK4, linearly interpolated inputs, numba kernel) at the same θ and R:
    # both discretisations are O(Δt⁴)-close for this smooth model; measured 3e-4 relative
    problem, prepared = y13_problem
    generic = FilterErrorProblem(prepared.model, list(prepared.maneuvers), prepared.process_noise)
    generic.gain_r = problem.gain_r.copy()
    theta = problem.theta_start
    linear_cost = problem.cost(problem.run(theta).outputs[0], problem.gain_r)
    generic_cost = generic.cost(generic.run(theta).outputs[0], generic.gain_r)
    assert abs(linear_cost - generic_cost) < 1e-3 * generic_cost


def test_case_rejects_an_unknown_gradient_option(tmp_path):
    text = (CASES / "y13aus_lateral_filter_error_linear.toml").read_text()
    path = tmp_path / "case.toml"
    path.write_text(text.replace('filter_gradients = "analytic"', 'filter_gradients = "exact"'))
    with pytest.raises(CaseError, match="filter_gradients"):
        load_case(path)
