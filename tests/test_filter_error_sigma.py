"""The filter error method's σ and the linearisation point of its steady-state gain, checked
against closed forms written here (scalar Riccati equation, the constraint diag(KC) = 1
solved by hand) and a plain-numpy recomputation of the Cramér–Rao bound."""

import numpy as np
import pytest

from flightid.data.flightdata import FlightData
from flightid.estimation import MNR
from flightid.estimation.filter_error import FilterErrorProblem, estimate_filter_error
from flightid.model.parameters import Parameter, Parameters
from flightid.model.statespace import StateSpaceModel

DT = 0.02


def f_scalar(t, x, u, theta):
    dx = np.empty(1)
    dx[0] = theta[0] * x[0] + theta[1] * u[0]
    return dx


def h_scalar(t, x, u, theta):
    y = np.empty(1)
    y[0] = x[0]
    return y


def _scalar_model(a, b, f11, free_a=False):
    parameters = Parameters(
        [Parameter("a", a, free=free_a), Parameter("b", b), Parameter("F11", f11)]
    )
    return StateSpaceModel(("x",), ("u",), ("z",), f_scalar, h_scalar, parameters, x0=(0.0,))


def _scalar_data(seed, n=1000, a=-1.0, b=1.0, process=0.05, noise=0.0):
    """ẋ = a x + b u + F w sampled exactly (zero-order-hold input, discrete process noise
    variance F²(e^{2aΔt} − 1)/(2a)), z = x + v."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    u = np.where((t % 2.0) < 1.0, 0.3, -0.3)
    phi = np.exp(a * DT)
    gamma = b * (phi - 1.0) / a
    q_d = process**2 * (np.exp(2 * a * DT) - 1.0) / (2 * a)
    x = np.zeros(n)
    for k in range(n - 1):
        x[k + 1] = phi * x[k] + gamma * u[k] + np.sqrt(q_d) * rng.standard_normal()
    z = x + noise * rng.standard_normal(n)
    return FlightData(t, {"u": u}, {"z": z})


def test_pinned_process_noise_sigma_includes_the_weighting_error():
    """State measured without noise: the optimum lies on diag(KC) = 1 and F11 is solved from
    it. For ẋ = a x + F w, z = x the Riccati equation 2aP − P²/(ΔtR) + F² = 0 with
    KC = P/R = 1 gives F = √(R (1/Δt − 2a)) (a fixed): F moves with R̂ alone, and
    Var(R̂) = 2R²/N gives σ_F = F/√(2N). The delta method over θ alone gives σ_F ≈ 0."""
    data = _scalar_data(12)
    result = estimate_filter_error(
        _scalar_model(-1.0, 0.8, 0.03), data, {"x": "F11"}, MNR(), gradients="analytic"
    )
    assert result.converged, result.message
    assert "solved from" in result.message  # the constraint is active: F11 is pinned
    # a pinned element's σ carries R̂'s error: no caveat for it
    assert "may be up to about 1.3× too small" not in result.message
    r = float(result.r_diag[0])
    f_hat = result.value("F11")
    # the constraint by hand: F = √(R (1/Δt − 2a))
    assert f_hat == pytest.approx(np.sqrt(r * (1.0 / DT + 2.0)), rel=1e-6)
    n = data.n_samples
    # σ_F = F / √(2N) (closed form; b does not enter F, so no θ term)
    assert result.stddev("F11") == pytest.approx(f_hat / np.sqrt(2 * n), rel=0.02)


def test_free_process_noise_sigma_is_the_cramer_rao_bound_of_the_sensitivities():
    """Unconstrained estimate: σ = √diag(M⁻¹), M = Σ_k G_kᵀ R⁻¹ G_k, recomputed here with
    plain numpy from the result's own sensitivities and weighting."""
    data = _scalar_data(12, noise=0.01, process=0.03)
    result = estimate_filter_error(
        _scalar_model(-0.8, 0.8, 0.02, free_a=True), data, {"x": "F11"}, MNR()
    )
    assert result.converged, result.message
    assert "solved from" not in result.message
    # a free element's bound takes R as known: measured somewhat optimistic, and said so
    assert "process-noise parameters ['F11'] may be up to about 1.3× too small" in result.message
    g = np.asarray(result.sensitivities)  # (N, n_o, n_f)
    r = np.asarray(result.r_diag)
    m = np.einsum("kip,i,kiq->pq", g, 1.0 / r, g)
    expected = np.sqrt(np.diag(np.linalg.inv(m)))
    np.testing.assert_allclose(result.std[result.free], expected, rtol=1e-9)


def f_input_gain(t, x, u, theta):
    dx = np.empty(1)
    dx[0] = (theta[0] + theta[1] * u[0]) * x[0] + u[0]
    return dx


def test_steady_gain_is_linearised_at_x0_and_the_first_input_sample():
    """A = ∂f/∂x = θ0 + θ1 u depends on the input: the gain must be taken at u_1 (the first
    sample, the reference's point), not u_2. The scalar Riccati equation
    2AP − P²/(ΔtR) + F² = 0 gives P = ΔtR (A + √(A² + F²/(ΔtR))) and K = P/R."""
    n = 50
    t = np.arange(n) * DT
    u = np.zeros(n)
    u[1:] = 1.0  # u_1 = 0, u_2 = 1: A(u_1) = −1, A(u_2) = −3
    data = FlightData(t, {"u": u}, {"z": np.zeros(n)})
    parameters = Parameters([Parameter("a0", -1.0), Parameter("a1", -2.0), Parameter("F11", 0.3)])
    model = StateSpaceModel(("x",), ("u",), ("z",), f_input_gain, h_scalar, parameters, x0=(0.5,))
    problem = FilterErrorProblem(model, data, {"x": "F11"}, compiled=False)
    r = 0.01
    problem.gain_r = np.array([r])
    t0, x0, u0 = problem.linearisation_point(problem.full_theta(problem.theta_start))
    assert t0 == 0.0 and x0.tolist() == [0.5] and u0.tolist() == [0.0]
    point = problem.filter_point(problem.full_theta(problem.theta_start))
    a = -1.0 + -2.0 * u[0]
    assert point.a[0, 0] == pytest.approx(a, rel=1e-8)
    p = DT * r * (a + np.sqrt(a**2 + 0.3**2 / (DT * r)))
    assert point.covariance[0, 0] == pytest.approx(p, rel=1e-8)
    assert point.gain[0, 0] == pytest.approx(p / r, rel=1e-8)


@pytest.fixture(scope="module")
def pinned_result():
    """The scalar case whose F11 is solved from diag(KC) = 1 (as in the test above)."""
    data = _scalar_data(12)
    return estimate_filter_error(
        _scalar_model(-1.0, 0.8, 0.03), data, {"x": "F11"}, MNR(), gradients="analytic"
    )


def test_a_solved_process_noise_element_is_listed_as_solved(pinned_result, tmp_path):
    import csv
    from types import SimpleNamespace

    from flightid.report.html import write_csv

    result = pinned_result
    assert result.solved == ("F11",)
    assert result.role("F11") == "solved" and result.role("b") == "free"
    assert result.role("a") == "fixed"
    # the console summary names the method and marks the row
    text = result.summary()
    assert text.splitlines()[0].startswith("flightid filter-error estimate — ")
    (row,) = [line for line in text.splitlines() if line.startswith("F11 ")]
    assert row.rstrip().endswith("solved")
    (row,) = [line for line in text.splitlines() if line.startswith("b ")]
    assert not row.rstrip().endswith("solved")
    # results.json and estimates.csv
    document = result.to_dict()
    assert document["estimator"] == "filter_error" and document["solved"] == ["F11"]
    roles = {p["name"]: p["role"] for p in document["parameters"]}
    assert roles == {"a": "fixed", "b": "free", "F11": "solved"}
    run = SimpleNamespace(estimate=result, case=SimpleNamespace(accuracy={}))
    write_csv(run, tmp_path / "estimates.csv")
    with (tmp_path / "estimates.csv").open() as stream:
        rows = {r["name"]: r for r in csv.DictReader(stream)}
    assert {n: r["role"] for n, r in rows.items()} == roles


def test_progress_numbers_rise_over_all_cycles_and_active_sets():
    """The pinned case runs several R cycles and two active sets; the callback's pass
    numbers run 0, 1, 2, … without a restart and its filter-pass counts never fall."""
    calls = []
    result = estimate_filter_error(
        _scalar_model(-1.0, 0.8, 0.03),
        _scalar_data(12),
        {"x": "F11"},
        MNR(),
        gradients="analytic",
        progress=lambda passes, evaluations, cost: calls.append((passes, evaluations)),
    )
    assert result.noise_cycles >= 2  # more than one objective reported
    passes = [p for p, _ in calls]
    evaluations = np.array([e for _, e in calls])
    assert passes == list(range(len(calls)))
    assert np.all(np.diff(evaluations) >= 0)
    assert evaluations[-1] <= result.equivalent_evaluations + result.accuracy_evaluations
    # the evaluation history of the convergence display rises too
    assert np.all(np.diff(result.evaluation_history) >= 0)
    # ln det R̂ of the innovations per pass ends at that of the final R (settled to
    # r_rtol = 1e-4 per variance, one output)
    assert len(result.log_det_r_history) == len(result.cost_history)
    assert result.log_det_r_history[-1] == pytest.approx(result.log_det_r, abs=2e-4)
