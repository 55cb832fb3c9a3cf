"""Filter error method: steady-state Kalman gain, filter passes, constraint, recovery.

Independent references: the scalar Riccati equation in closed form, scipy's Schur solver
against Potter's method, a filter loop written out here in NumPy, and seeded simulations
with process noise (the truth is known).
"""

import numpy as np
import pytest

from flightid.data.flightdata import FlightData
from flightid.errors import InputError
from flightid.estimation import MNR, estimate
from flightid.estimation.filter_error import FilterErrorProblem, estimate_filter_error
from flightid.filtering import potter_solution, riccati_solution, steady_state_gain
from flightid.model.parameters import Parameter, Parameters
from flightid.model.statespace import StateSpaceModel

DT = 0.05


def test_scalar_riccati_closed_form():
    # −(c²/(r Δt)) P² + 2 a P + f² = 0  ⇒  P = r Δt (a + √(a² + f² c²/(r Δt))) / c²
    a, c, f, r = -0.7, 2.0, 0.3, 0.04
    expected = r * DT * (a + np.sqrt(a**2 + f**2 * c**2 / (r * DT))) / c**2
    for solve in (riccati_solution, potter_solution):
        p = solve([[a]], [[c]], [[f**2]], [r], DT)
        assert p[0, 0] == pytest.approx(expected, rel=1e-10)
    k, _ = steady_state_gain([[a]], [[c]], [[f]], [r], DT)
    # K = P c / r
    assert k[0, 0] == pytest.approx(expected * c / r, rel=1e-10)


def test_potter_equals_schur_and_residual_vanishes():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(3, 3)) + np.diag([0.5, -1.0, -2.0])  # one unstable mode
    c = rng.normal(size=(4, 3))
    f = np.diag([0.1, 0.02, 0.3])
    r = np.array([0.01, 0.02, 0.05, 0.1])
    p1 = riccati_solution(a, c, f @ f.T, r, DT)
    p2 = potter_solution(a, c, f @ f.T, r, DT)
    np.testing.assert_allclose(p1, p2, rtol=1e-8, atol=1e-12)
    # CARE residual A P + P Aᵀ − (1/Δt) P Cᵀ R⁻¹ C P + F Fᵀ = 0
    residual = a @ p1 + p1 @ a.T - p1 @ c.T @ np.diag(1 / r) @ c @ p1 / DT + f @ f.T
    assert np.max(np.abs(residual)) < 1e-10 * np.max(np.abs(f @ f.T))
    # stabilising: A − P CᵀR⁻¹C/Δt has eigenvalues in the left half plane
    closed = a - p1 @ c.T @ np.diag(1 / r) @ c / DT
    assert np.all(np.linalg.eigvals(closed).real < 0)


# ---------------------------------------------------------------- a linear test model
TRUE = {"a11": -1.2, "a12": 2.0, "a21": -1.5, "a22": -0.8, "b1": 1.5, "b2": -3.0}


def f_lin(t, x, u, theta):
    dx = np.empty(2)
    dx[0] = theta[0] * x[0] + theta[1] * x[1] + theta[4] * u[0]
    dx[1] = theta[2] * x[0] + theta[3] * x[1] + theta[5] * u[0]
    return dx


def h_lin(t, x, u, theta):
    y = np.empty(2)
    y[0] = x[0]
    y[1] = x[1]
    return y


def _model(values, f11=0.05, f22=0.05):
    params = [Parameter(n, v) for n, v in values.items()]
    params += [Parameter("F11", f11), Parameter("F22", f22)]
    return StateSpaceModel(("x1", "x2"), ("u",), ("y1", "y2"), f_lin, h_lin, Parameters(params))


def _simulate(seed, n=600, process=0.4, noise=0.02):
    """Euler-Maruyama at Δt/10 with w of unit intensity through F = diag(process), sampled
    every Δt with measurement noise; seeded."""
    rng = np.random.default_rng(seed)
    a = np.array([[TRUE["a11"], TRUE["a12"]], [TRUE["a21"], TRUE["a22"]]])
    b = np.array([TRUE["b1"], TRUE["b2"]])
    t = np.arange(n) * DT
    u = np.where((t % 4.0) < 2.0, 0.2, -0.2) * (t < 20)
    x = np.zeros(2)
    z = np.empty((n, 2))
    sub = 10
    for k in range(n):
        z[k] = x + noise * rng.normal(size=2)
        for _ in range(sub):
            h = DT / sub
            x = x + h * (a @ x + b * u[k]) + process * np.sqrt(h) * rng.normal(size=2)
    return FlightData(t, {"u": u}, {"y1": z[:, 0], "y2": z[:, 1]})


def test_filter_pass_equals_numpy_loop():
    data = _simulate(1, n=200)
    model = _model(TRUE, 0.3, 0.2)
    problem = FilterErrorProblem(model, data, {"x1": "F11", "x2": "F22"}, compiled=False)
    problem.gain_r = np.array([0.01, 0.02])
    theta = problem.theta_start
    y = problem.run(theta[None, :]).outputs[0]
    # independent: K from the Schur solver, RK4 with mean inputs, the loop written out
    a = np.array([[-1.2, 2.0], [-1.5, -0.8]])
    b = np.array([1.5, -3.0])
    c = np.eye(2)
    f = np.diag([0.3, 0.2])
    p = riccati_solution(a, c, f @ f.T, [0.01, 0.02], DT)
    k = p @ c.T / np.array([0.01, 0.02])
    u = data.input("u")
    z = np.column_stack([data.output("y1"), data.output("y2")])
    x = np.zeros(2)
    expected = np.empty_like(z)
    for i in range(len(u)):
        expected[i] = x
        if i == len(u) - 1:
            break
        xc = x + k @ (z[i] - x)

        def rate(s, v):
            return a @ s + b * v

        um = 0.5 * (u[i] + u[i + 1])
        k1 = rate(xc, u[i])
        k2 = rate(xc + DT / 2 * k1, um)
        k3 = rate(xc + DT / 2 * k2, um)
        k4 = rate(xc + DT * k3, u[i + 1])
        x = xc + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    np.testing.assert_allclose(y, expected, rtol=1e-9, atol=1e-12)


def test_kc_constraint_flags_the_point():
    data = _simulate(2, n=100)
    model = _model(TRUE, 50.0, 50.0)  # huge process noise: K C → beyond 1
    problem = FilterErrorProblem(model, data, {"x1": "F11", "x2": "F22"}, compiled=False)
    problem.gain_r = np.array([1e-4, 1e-4])
    point = problem.filter_point(problem.full_theta(problem.theta_start))
    assert np.max(point.kc) > 1.0
    batch = problem.run(problem.theta_start[None, :])
    assert batch.diverged[0]
    assert "diag(KC)" in batch.messages[0]
    # without the check, the pass runs
    assert not problem.run(problem.theta_start[None, :], check_kc=False).diverged[0]


def test_named_errors():
    data = _simulate(2, n=50)
    with pytest.raises(InputError, match="not a state"):
        FilterErrorProblem(_model(TRUE), data, {"x9": "F11"})
    with pytest.raises(InputError, match="not a parameter"):
        FilterErrorProblem(_model(TRUE), data, {"x1": "G11"})
    with pytest.raises(InputError, match="relaxation"):
        estimate_filter_error(_model(TRUE), data, {"x1": "F11"}, relaxation="book")


def test_recovery_with_process_noise_output_error_biased():
    """Seeded process noise: filter error within 3σ of the truth; output error is not."""
    data = _simulate(7)
    start = {k: v * 1.1 for k, v in TRUE.items()}
    fem = estimate_filter_error(
        _model(start, 0.1, 0.1), data, {"x1": "F11", "x2": "F22"}, solver=MNR()
    )
    assert fem.converged, fem.message
    # F = 0.4 per state, the truth of the simulation
    truth = {**TRUE, "F11": 0.4, "F22": 0.4}
    deviations = {n: (fem.value(n) - v) / fem.stddev(n) for n, v in truth.items()}
    assert all(abs(d) < 3.0 for d in deviations.values()), deviations
    oem_model = StateSpaceModel(
        ("x1", "x2"), ("u",), ("y1", "y2"), f_lin, h_lin, Parameters(list(start.items()))
    )
    oem = estimate(oem_model, data, solver=MNR())
    # measured in Cramér–Rao σ (which assume white residuals): output error's bias shows
    oem_dev = [abs(oem.value(n) - v) / oem.stddev(n, std="cr") for n, v in TRUE.items()]
    assert max(oem_dev) > 3.0
