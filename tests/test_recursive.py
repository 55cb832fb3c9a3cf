"""Recursive estimators (flightid.recursive) against independent references written here.

* EKF with the parameters in the state converges to a known truth within its σ;
* EKF without free parameters = a plain linear Kalman filter written in this file;
* UKF = EKF on a linear model; UKF weights reproduce a linear transform exactly;
* EFRLS on a static linear regression = the closed-form (weighted, regularised) LS;
* FTR: the recursive DFT = a direct numpy DFT; noise-free data give the true A, B;
* streaming: one by one, in blocks and all at once give identical numbers.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg

from flightid.errors import InputError
from flightid.model.statespace import StateSpaceModel
from flightid.recursive import (
    AugmentedModel,
    AugmentedUnscentedKalmanFilter,
    ExtendedForgettingRLS,
    ExtendedKalmanFilter,
    FourierTransformRegression,
    NoEstimateYetError,
    RecursiveDivergenceError,
    RecursiveEstimator,
    UnscentedKalmanFilter,
    run_recursive,
)
from flightid.recursive.base import symmetric_sqrt
from flightid.recursive.ukf import sigma_points, unscented_weights

# ----------------------------------------------------------------------------- models

# 2-state linear system ẋ = A x + B u, y = x (a short-period-like pair)
A_TRUE = np.array([[-0.8, 1.0], [-4.0, -1.5]])
B_TRUE = np.array([[-0.1], [-6.0]])


def f_linear2(t, x, u, theta):
    dx = np.empty(2)
    # ẋ1 = a11 x1 + a12 x2 + b1 u;  ẋ2 = a21 x1 + a22 x2 + b2 u
    dx[0] = theta[0] * x[0] + theta[1] * x[1] + theta[2] * u[0]
    dx[1] = theta[3] * x[0] + theta[4] * x[1] + theta[5] * u[0]
    return dx


def h_identity2(t, x, u, theta):
    y = np.empty(2)
    y[0] = x[0]
    y[1] = x[1]
    return y


def linear_model(free: bool, start=None) -> StateSpaceModel:
    names = ["a11", "a12", "b1", "a21", "a22", "b2"]
    true = [A_TRUE[0, 0], A_TRUE[0, 1], B_TRUE[0, 0], A_TRUE[1, 0], A_TRUE[1, 1], B_TRUE[1, 0]]
    values = true if start is None else start
    parameters = [(n, v, free and n != "a12") for n, v in zip(names, values, strict=True)]
    return StateSpaceModel(("x1", "x2"), ("u",), ("y1", "y2"), f_linear2, h_identity2, parameters)


def f_scalar(t, x, u, theta):
    dx = np.empty(1)
    # ẋ = a x + b u
    dx[0] = theta[0] * x[0] + theta[1] * u[0]
    return dx


def h_scalar(t, x, u, theta):
    y = np.empty(1)
    y[0] = x[0]
    return y


def square_wave_input(n: int, dt: float, seed: int) -> np.ndarray:
    """Piecewise-constant steps of random level (seeded), each 0.5–1.5 s long."""
    rng = np.random.default_rng(seed)
    u = np.empty(n)
    k = 0
    while k < n:
        length = int(rng.integers(int(0.5 / dt), int(1.5 / dt)))
        u[k : k + length] = rng.choice([-1.0, 1.0]) * rng.uniform(0.3, 1.0)
        k += length
    return u


def simulate_linear(A, B, u, dt, x0, substeps=20):
    """Independent reference integration: RK4 with ``substeps`` per sample interval and the
    input linear between samples (as the filters assume)."""
    x = np.array(x0, dtype=float)
    out = [x.copy()]
    h = dt / substeps
    for k in range(len(u) - 1):
        for s in range(substeps):
            ua = u[k] + (u[k + 1] - u[k]) * s / substeps
            ub = u[k] + (u[k + 1] - u[k]) * (s + 0.5) / substeps
            uc = u[k] + (u[k + 1] - u[k]) * (s + 1) / substeps
            k1 = A @ x + B[:, 0] * ua
            k2 = A @ (x + h / 2 * k1) + B[:, 0] * ub
            k3 = A @ (x + h / 2 * k2) + B[:, 0] * ub
            k4 = A @ (x + h * k3) + B[:, 0] * uc
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(x.copy())
    return np.array(out)


@pytest.fixture(scope="module")
def linear_data():
    dt, n = 0.05, 600
    u = square_wave_input(n, dt, seed=11)
    x = simulate_linear(A_TRUE, B_TRUE, u, dt, [0.0, 0.0])
    rng = np.random.default_rng(12)
    sigma = np.array([0.002, 0.01])
    z = x + rng.normal(size=x.shape) * sigma
    return dt * np.arange(n), u[:, None], z, sigma


# ----------------------------------------------------------------------------- (1) EKF → truth


def test_ekf_scalar_parameters_converge_to_truth_within_sigma():
    """ẋ = a x + b u with a = −1.5, b = 2 (truth), y = x + noise (σ = 0.01, seeded): the EKF
    started at a = −0.5, b = 1 ends within 3σ of the truth, and σ shrinks to below 2 %."""
    dt, n = 0.05, 800
    u = square_wave_input(n, dt, seed=3)
    a, b = -1.5, 2.0
    x = simulate_linear(np.array([[a]]), np.array([[b]]), u, dt, [0.0])[:, 0]
    z = x + np.random.default_rng(4).normal(size=n) * 0.01
    model = StateSpaceModel(("x",), ("u",), ("y",), f_scalar, h_scalar, [("a", -0.5), ("b", 1.0)])
    ekf = ExtendedKalmanFilter(AugmentedModel(model, [0.0]), 10.0, 1e-10, 1e-4, 1e-4)
    result = run_recursive(ekf, dt * np.arange(n), u, z)
    values, std = result.last_filtered, result.last_filtered_std
    assert np.all(std < 0.02 * np.abs([a, b])), std
    assert np.all(np.abs(values - [a, b]) < 3 * std), (values, std)
    # the start is far outside: the filter really moved
    assert abs(values[0] - (-0.5)) > 50 * std[0]
    assert result.converged, result.warnings


def test_ekf_two_state_parameters_converge_to_truth_within_sigma(linear_data):
    t, u, z, sigma = linear_data
    start = [-0.4, 1.0, 0.0, -2.0, -0.5, -3.0]  # a12 fixed at its true value 1.0
    model = linear_model(free=True, start=start)
    ekf = ExtendedKalmanFilter(AugmentedModel(model, [0.0, 0.0]), 10.0, 1e-10, sigma**2, 1e-5)
    result = run_recursive(ekf, t, u, z)
    truth = np.array([-0.8, -0.1, -4.0, -1.5, -6.0])
    assert result.parameter_names == ("a11", "b1", "a21", "a22", "b2")
    assert np.all(np.abs(result.last_filtered - truth) < 3 * result.last_filtered_std), (
        result.last_filtered,
        result.last_filtered_std,
    )
    assert np.all(result.last_filtered_std < 0.05 * np.abs(truth))


# ----------------------------------------------------------------------------- (2) EKF = KF


def plain_kalman_filter(A, B, C, Q, R, P0, x0, t, u, z):
    """Linear KF written out: mean by the RK4 step of the linear system (inputs linear
    between samples), covariance with Φ = e^{A dt} (scipy.linalg.expm), standard update."""
    x, P = np.array(x0, float), P0.copy()
    xs, Ps = [], []
    for k in range(len(t)):
        if k > 0:
            dt = t[k] - t[k - 1]
            u0, u1 = u[k - 1, 0], u[k, 0]
            um = 0.5 * (u0 + u1)
            k1 = A @ x + B[:, 0] * u0
            k2 = A @ (x + dt / 2 * k1) + B[:, 0] * um
            k3 = A @ (x + dt / 2 * k2) + B[:, 0] * um
            k4 = A @ (x + dt * k3) + B[:, 0] * u1
            x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            Phi = linalg.expm(A * dt)
            P = Phi @ P @ Phi.T + Q
        S = C @ P @ C.T + R
        K = P @ C.T @ np.linalg.inv(S)
        x = x + K @ (z[k] - C @ x)
        P = (np.eye(len(x)) - K @ C) @ P
        xs.append(x.copy())
        Ps.append(P.copy())
    return np.array(xs), np.array(Ps)


def test_ekf_without_free_parameters_is_the_linear_kalman_filter(linear_data):
    t, u, z, sigma = linear_data
    model = linear_model(free=False)
    Q = np.diag([1e-6, 4e-6])
    P0 = np.eye(2) * 0.5
    ekf = ExtendedKalmanFilter(AugmentedModel(model, [0.1, -0.2]), 0.5, np.diag(Q), sigma**2, 1e-4)
    online = RecursiveEstimator(ekf)
    states, covariances = [], []
    for k in range(len(t)):
        online.feed(t[k], u[k], z[k])
        states.append(ekf.x.copy())
        covariances.append(ekf.P.copy())
    x_ref, P_ref = plain_kalman_filter(
        A_TRUE, B_TRUE, np.eye(2), Q, np.diag(sigma**2), P0, [0.1, -0.2], t, u, z
    )
    np.testing.assert_allclose(np.array(states), x_ref, rtol=1e-7, atol=1e-11)
    np.testing.assert_allclose(np.array(covariances), P_ref, rtol=1e-6, atol=1e-14)


# ----------------------------------------------------------------------------- (3) UKF vs EKF


def test_ukf_equals_ekf_on_a_linear_model(linear_data):
    """No free parameters and Q = 0: the model is linear, the UKF propagates mean and
    covariance through the RK4 map exactly and the EKF through Φ (series of e^{A dt}); the two
    differ only by the O((A dt)⁵) difference of the RK4 map and e^{A dt}.

    (With Q > 0 they differ by design: the reference UKF adds Q to P_xx but builds P_yy and
    P_xy from the propagated sigma points, which do not carry Q; CASES.md §8.1.)"""
    t, u, z, sigma = linear_data
    model = linear_model(free=False)
    aug = AugmentedModel(model, [0.0, 0.0])
    filters = [
        ExtendedKalmanFilter(aug, 1.0, [0.0, 0.0], sigma**2, 1e-4),
        UnscentedKalmanFilter(aug, 1.0, [0.0, 0.0], sigma**2),
    ]
    histories = []
    for flt in filters:
        rows = []
        for k in range(len(t)):
            flt.feed(t[k], u[k], z[k])
            rows.append(np.concatenate([flt.x, flt.P.ravel()]))
        histories.append(np.array(rows))
    np.testing.assert_allclose(histories[1][:, :2], histories[0][:, :2], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(histories[1][:, 2:], histories[0][:, 2:], rtol=1e-5, atol=1e-12)


def test_ukf_and_ekf_parameter_estimates_agree(linear_data):
    t, u, z, sigma = linear_data
    start = [-0.4, 1.0, 0.0, -2.0, -0.5, -3.0]
    results = []
    for cls in (ExtendedKalmanFilter, UnscentedKalmanFilter, AugmentedUnscentedKalmanFilter):
        aug = AugmentedModel(linear_model(True, start), [0.0, 0.0])
        flt = cls(aug, 10.0, [1e-10, 1e-10], sigma**2)
        results.append(run_recursive(flt, t, u, z))
    ekf = results[0]
    for other in results[1:]:
        assert np.all(np.abs(other.values - ekf.values) < ekf.std), (other.method, other.values)


# ----------------------------------------------------------------------------- (4) UKF weights


@pytest.mark.parametrize("n", [2, 7, 14, 21])
def test_sigma_points_reproduce_mean_and_covariance_of_a_linear_transform(n):
    rng = np.random.default_rng(n)
    mean = rng.normal(size=n)
    L = rng.normal(size=(n, n))
    P = L @ L.T + 0.1 * np.eye(n)
    M = rng.normal(size=(3, n))
    offset = rng.normal(size=3)
    wm, wc, gamma = unscented_weights(n)
    assert wm.sum() == pytest.approx(1.0, abs=1e-12)
    X = sigma_points(mean, P, gamma)
    Y = X @ M.T + offset
    y_mean = wm @ Y
    np.testing.assert_allclose(y_mean, M @ mean + offset, rtol=1e-11, atol=1e-11)
    spread = (wc[:, None] * (Y - y_mean)).T @ (Y - y_mean)
    np.testing.assert_allclose(spread, M @ P @ M.T, rtol=1e-9, atol=1e-9)


def test_symmetric_sqrt_is_scipy_sqrtm():
    rng = np.random.default_rng(5)
    L = rng.normal(size=(9, 9))
    P = L @ L.T
    root = symmetric_sqrt(P)
    np.testing.assert_allclose(root, np.real(linalg.sqrtm(P)), rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(root @ root, P, rtol=1e-10, atol=1e-10)
    with pytest.raises(RecursiveDivergenceError, match="not positive semi-definite"):
        symmetric_sqrt(np.diag([1.0, -0.5]))


def test_ukf_constants_are_those_of_the_reference():
    """CASES.md §8.1: α = 0.5, β = 2, κ = 3 − n, λ = α²(n + κ) − n."""
    n = 14
    wm, wc, gamma = unscented_weights(n)
    lam = 0.25 * 3 - n
    assert gamma == pytest.approx(np.sqrt(n + lam))
    assert wm[0] == pytest.approx(lam / (n + lam))
    assert wc[0] == pytest.approx(lam / (n + lam) + 1 - 0.25 + 2)
    assert wm[1] == pytest.approx(1 / (2 * (n + lam)))


# ----------------------------------------------------------------------------- (5) EFRLS → LS


def f_zero(t, x, u, theta):
    dx = np.empty(1)
    dx[0] = 0.0
    return dx


def h_regression(t, x, u, theta):
    y = np.empty(1)
    # y = θ1 u1 + θ2 u2 + θ3 (a static, equation-error-like regression)
    y[0] = theta[0] * u[0] + theta[1] * u[1] + theta[2]
    return y


@pytest.mark.parametrize("forgetting", [1.0, 0.995])
def test_efrls_on_a_static_regression_is_weighted_least_squares(forgetting):
    """With a dummy state (ẋ = 0) the EFRLS is forgetting-factor RLS: after N samples
    θ̂ = argmin Σ_{k=2..N} λ^{N−k} (z_k − X_k θ)² + λ^{N−1} (θ − θ0)ᵀ P0⁻¹ (θ − θ0), the
    closed form computed here (sample 1 is not used, CASES.md Q12)."""
    rng = np.random.default_rng(21)
    n = 400
    U = rng.normal(size=(n, 2))
    theta_true = np.array([1.5, -0.7, 0.3])
    X = np.column_stack([U, np.ones(n)])
    z = X @ theta_true + 0.05 * rng.normal(size=n)
    theta0 = np.array([0.0, 0.0, 0.0])
    model = StateSpaceModel(
        ("dummy",),
        ("u1", "u2"),
        ("y",),
        f_zero,
        h_regression,
        [("c1", 0.0), ("c2", 0.0), ("c0", 0.0)],
    )
    efrls = ExtendedForgettingRLS(AugmentedModel(model, [0.0]), 1e3, forgetting, 1e-7)
    result = run_recursive(efrls, 0.1 * np.arange(n), U, z[:, None], report="final")
    weights = forgetting ** (n - 1 - np.arange(1, n))
    Xw = X[1:] * weights[:, None]
    prior = forgetting ** (n - 1) / 1e3
    information = Xw.T @ X[1:] + prior * np.eye(3)
    expected = np.linalg.solve(information, Xw.T @ z[1:] + prior * theta0)
    np.testing.assert_allclose(result.values, expected, rtol=1e-7, atol=1e-9)
    # and it approaches the plain least-squares solution
    ls = np.linalg.lstsq(X[1:] * np.sqrt(weights)[:, None], z[1:] * np.sqrt(weights), rcond=None)[0]
    np.testing.assert_allclose(result.values, ls, atol=1e-4)


# ----------------------------------------------------------------------------- (6) FTR


def test_ftr_recursive_dft_equals_direct_dft():
    rng = np.random.default_rng(8)
    n, dt = 300, 0.04
    t = dt * np.arange(n) + 3.0  # phase reference is the first sample
    x = rng.normal(size=(n, 2))
    u = rng.normal(size=(n, 1))
    freq = np.arange(0.2, 1.5, 0.04)
    ftr = FourierTransformRegression(2, 1, freq, update_every=25)
    for k in range(n):
        ftr.feed(t[k], u[k], x[k])
    omega = 2 * np.pi * freq
    # X(ω) = Σ_{k=2..N} (x_k − mean(x_1..x_10)) e^{−jω (t_k − t_1)}
    kernel = np.exp(-1j * np.outer(omega, t[1:] - t[0]))
    np.testing.assert_allclose(ftr.X, kernel @ (x[1:] - x[:10].mean(axis=0)), rtol=1e-11)
    np.testing.assert_allclose(ftr.U, kernel @ (u[1:] - u[:10].mean(axis=0)), rtol=1e-11)
    assert len(ftr.updates) == n // 25
    assert [row[0] for row in ftr.updates] == list(range(25, n + 1, 25))


def test_ftr_recovers_true_a_and_b_from_noise_free_data():
    """A doublet in the middle of a record that starts and ends at rest: jωX = AX + BU holds
    for the finite transforms up to the sum-versus-integral error, small well below Nyquist."""
    dt, n = 0.01, 3000
    t = dt * np.arange(n)
    u = np.where((t > 2) & (t < 3), 1.0, 0.0) - np.where((t > 3) & (t < 4), 1.0, 0.0)
    u = np.convolve(u, np.ones(20) / 20, mode="same")  # smooth edges
    x = simulate_linear(A_TRUE, B_TRUE, u, dt, [0.0, 0.0], substeps=4)
    ftr = FourierTransformRegression(2, 1, np.arange(0.1, 1.5, 0.04), update_every=100)
    RecursiveEstimator(ftr).feed_block(t, u, x)
    estimated = ftr.theta.reshape(2, 3)
    truth = np.hstack([A_TRUE, B_TRUE])
    np.testing.assert_allclose(estimated, truth, rtol=5e-3, atol=5e-3)


def test_ftr_has_no_estimate_before_its_first_update():
    ftr = FourierTransformRegression(1, 1, np.arange(0.2, 1.5, 0.1), update_every=25)
    for k in range(24):
        ftr.feed(0.04 * k, [0.1 * k], [np.sin(k)])
    with pytest.raises(NoEstimateYetError, match="first update comes at sample 25"):
        _ = ftr.theta


# ----------------------------------------------------------------------------- (7) streaming


@pytest.mark.parametrize("kind", ["ekf", "ukf", "ftr"])
def test_streaming_one_by_one_and_in_blocks_equals_batch(linear_data, kind):
    t, u, z, sigma = linear_data

    def make():
        if kind == "ftr":
            return FourierTransformRegression(2, 1, np.arange(0.2, 1.5, 0.04), update_every=20)
        aug = AugmentedModel(linear_model(True, [-0.4, 1.0, 0.0, -2.0, -0.5, -3.0]), [0, 0])
        if kind == "ekf":
            return ExtendedKalmanFilter(aug, 10.0, [1e-10, 1e-10], sigma**2)
        return UnscentedKalmanFilter(aug, 10.0, [1e-10, 1e-10], sigma**2)

    batch = run_recursive(make(), t, u, z)
    single = RecursiveEstimator(make())
    for k in range(len(t)):
        single.feed(t[k], u[k], z[k])
        if k == 250 and kind != "ftr":
            # current values are readable at any time
            assert set(single.estimates) == set(batch.parameter_names)
    blocks = RecursiveEstimator(make())
    for start in range(0, len(t), 97):
        blocks.feed_block(t[start : start + 97], u[start : start + 97], z[start : start + 97])
    for online in (single, blocks):
        result = online.result()
        np.testing.assert_array_equal(result.theta_history, batch.theta_history)
        np.testing.assert_array_equal(result.std_history, batch.std_history)
        assert online.estimates == dict(
            zip(batch.parameter_names, batch.last_filtered, strict=True)
        )


# ----------------------------------------------------------------------------- checks


def test_divergence_is_a_named_error():
    """A strongly unstable model (a = 400 1/s) whose measurements carry no weight (R0 = 1e30)
    overflows: RecursiveDivergenceError naming the sample, never NaN estimates."""
    model = StateSpaceModel(("x",), ("u",), ("y",), f_scalar, h_scalar, [("a", 400.0), ("b", 1.0)])
    ekf = ExtendedKalmanFilter(AugmentedModel(model, [1.0]), 1e-12, 0.0, 1e30)
    t = 0.1 * np.arange(400)
    with pytest.raises(RecursiveDivergenceError, match="diverged at sample"):
        run_recursive(ekf, t, np.ones((400, 1)), np.ones((400, 1)))


def test_bad_settings_and_samples_are_named():
    aug = AugmentedModel(linear_model(True), [0.0, 0.0])
    with pytest.raises(InputError, match="q_states: expected a number or a list of 2"):
        ExtendedKalmanFilter(aug, 10.0, [1e-7, 1e-7, 1e-7], [1e-4, 1e-4])
    with pytest.raises(InputError, match="r0: expected finite values >= 0"):
        UnscentedKalmanFilter(aug, 10.0, 1e-7, [-1.0, 1e-4])
    with pytest.raises(InputError, match="forgetting"):
        ExtendedForgettingRLS(aug, 1e3, 1.5)
    ekf = ExtendedKalmanFilter(aug, 10.0, 1e-7, 1e-4)
    ekf.feed(0.0, [0.0], [0.0, 0.0])
    with pytest.raises(InputError, match="z: expected 2 values"):
        ekf.feed(0.1, [0.0], [0.0])
    with pytest.raises(InputError, match="times must increase"):
        ekf.feed(0.0, [0.0], [0.0, 0.0])
    with pytest.raises(InputError, match="u: expected finite values"):
        ekf.feed(0.2, [np.nan], [0.0, 0.0])


_FTR_F = np.arange(0.1, 1.6, 0.1)  # 15 frequencies, Hz


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ((True, 1, _FTR_F, 5), "n_states: expected a non-negative integer, got True"),
        ((0, 1, _FTR_F, 5), "n_states: expected a non-negative integer, got 0"),
        ((2, -1, _FTR_F, 5), "n_inputs: expected a non-negative integer, got -1"),
        ((2, 1, _FTR_F[:3], 5), "frequencies_hz: expected more than 3 positive frequencies"),
        ((2, 1, [0.1, -1, 2, 3, 4], 5), "frequencies_hz: expected more than 3 positive"),
        ((2, 1, _FTR_F, 0), "update_every: expected a positive integer, got 0"),
        ((2, 1, _FTR_F, 5, None, None, 2.0), "n_mean: expected a positive integer, got 2.0"),
        (
            (2, 1, _FTR_F, 5, [["a", "b", "c"], ["d", "e"]]),
            "parameter_names: expected 2 rows of 3 names, got [['a', 'b', 'c'], ['d', 'e']]",
        ),
        (
            (2, 1, _FTR_F, 5, [["a", "b", "c"], ["d", "e", "a"]]),
            "parameter_names: expected unique names, got ['a', 'b', 'c', 'd', 'e', 'a']",
        ),
        (
            (2, 1, _FTR_F, 5, None, {"Q": 1.0}),
            "offsets: ['Q'] are not parameter names ['A11', 'A12', 'B11', 'A21', 'A22', 'B21']",
        ),
        ((2, 1, _FTR_F, 5, None, {"A12": np.nan}), "offsets['A12']: expected a finite number"),
        ((2, 1, _FTR_F, 5, None, None, 10, [-0.1]), "input_delays_s: expected finite delays"),
    ],
)
def test_ftr_arguments_are_named_input_errors(arguments, message):
    with pytest.raises(InputError) as info:
        FourierTransformRegression(*arguments)
    assert message in str(info.value)


def test_innovation_test_warns_when_the_noise_model_is_wrong(linear_data):
    """R0 100× too small (σ 10× too small): most innovations lie outside their covariance,
    the result says so and is not reported as converged."""
    t, u, z, sigma = linear_data
    aug = AugmentedModel(linear_model(False), [0.0, 0.0])
    right = run_recursive(ExtendedKalmanFilter(aug, 1.0, 1e-8, sigma**2), t, u, z)
    wrong = run_recursive(ExtendedKalmanFilter(aug, 1.0, 1e-8, sigma**2 / 1e4), t, u, z)
    assert right.converged and not right.warnings
    assert not wrong.converged
    assert "innovations lie far outside their covariance" in wrong.warnings[0]
    assert wrong.to_dict()["status"] == "inconsistent"


def test_compiled_and_python_batch_loops_agree_and_match_a_direct_rk4():
    """The numba batch kernels and their plain-Python fallback give the same numbers, and
    one RK4 step of a row equals the RK4 of CASES.md §0 written out here."""
    model = linear_model(True, [-0.4, 1.0, 0.0, -2.0, -0.5, -3.0])
    compiled = AugmentedModel(model, [0.1, -0.2])
    python = AugmentedModel(model, [0.1, -0.2], compiled=False)
    assert compiled.compiled and not python.compiled
    rng = np.random.default_rng(2)
    X = compiled.x_a0 + 0.1 * rng.normal(size=(7, compiled.n))
    u0, u1, dt = np.array([0.3]), np.array([-0.2]), 0.05
    for name in ("rates", "outputs"):
        np.testing.assert_array_equal(getattr(compiled, name)(X, u0), getattr(python, name)(X, u0))
    step = compiled.rk4(X, u0, u1, dt)
    np.testing.assert_array_equal(step, python.rk4(X, u0, u1, dt))
    # direct RK4 of row 0: ū = (u_k + u_{k+1})/2, parameters unchanged
    x, th = X[0, :2], X[0, 2:]
    A = np.array([[th[0], 1.0], [th[2], th[3]]])
    B = np.array([th[1], th[4]])
    k1 = A @ x + B * u0[0]
    k2 = A @ (x + dt / 2 * k1) + B * 0.05
    k3 = A @ (x + dt / 2 * k2) + B * 0.05
    k4 = A @ (x + dt * k3) + B * u1[0]
    np.testing.assert_allclose(step[0, :2], x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4), rtol=1e-14)
    np.testing.assert_array_equal(step[:, 2:], X[:, 2:])
    # central-difference Jacobian of a linear f is A itself (parameter columns: x, u terms)
    J = compiled.state_jacobian(X[0], u0, np.full(compiled.n, 1e-4))
    np.testing.assert_allclose(J[:2, :2], A, rtol=1e-9)
    np.testing.assert_allclose(J[0, 2:5], [x[0], u0[0], 0.0], atol=1e-10)
    assert np.all(J[2:] == 0.0)
