"""The data-support flag of global-model predictions: held-out data inside, the empty corner of
an L-shaped data set outside (reference: scipy.spatial.Delaunay of the two arms and the exact
distance to the L), the leverage of an extrapolated cubic (reference: numpy.linalg.pinv),
independence of the variables' units, and the range criterion: α below the data's lowest and
Mach above its highest, which neither the k-NN distance nor the leverage catches."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay

from flightid.globalmodel import GlobalModelError, GlobalModelSettings, fit_global_model
from flightid.globalmodel.support import Support, beyond_range, thinned_indices


def _maneuvers(seed=0, n_maneuvers=6, duration_s=20.0, dt=0.02):
    """Smooth trajectories of (alpha, Mach, de) at a few Mach levels, and CL."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, dt)
    parts = {"alpha": [], "Mach": [], "de": []}
    for k in range(n_maneuvers):
        phase = rng.uniform(0, 2 * np.pi, 3)
        parts["alpha"].append(0.15 + 0.12 * np.sin(0.7 * t + phase[0]) + 0.03 * np.sin(2.3 * t))
        # maneuvers at the Mach levels 0.3, 0.4 and 0.9 in turn: none flown around 0.65
        level = (0.3, 0.4, 0.9)[k % 3]
        parts["Mach"].append(level + 0.005 * np.sin(0.2 * t + phase[1]))
        parts["de"].append(0.1 * np.sin(1.1 * t + phase[2]))
    signals = {key: np.concatenate(v) for key, v in parts.items()}
    a, m, d = signals["alpha"], signals["Mach"], signals["de"]
    n = a.size
    signals["CL"] = 0.2 + 5.0 * a - 4.0 * a**2 + 0.5 * a * m + 0.6 * d + 0.002 * rng.normal(size=n)
    index = np.repeat(np.arange(n_maneuvers), t.size)
    return signals, index, dt


def test_held_out_half_of_the_data_is_inside():
    signals, index, dt = _maneuvers()
    rng = np.random.default_rng(1)
    held = rng.random(index.size) < 0.5
    train = {k: v[~held] for k, v in signals.items()}
    model = fit_global_model(
        train,
        ["CL"],
        ["alpha", "Mach", "de"],
        settings=GlobalModelSettings(max_order=3),
        maneuver_index=index[~held],
        dt=dt,
    )
    points = {k: signals[k][held] for k in ("alpha", "Mach", "de")}
    prediction = model.predict(points)["CL"]
    assert np.mean(~prediction.outside) >= 0.98
    # a point between the Mach levels 0.4 and 0.9 flown, at mid α, is outside: no data there
    between = model.predict({"alpha": 0.15, "Mach": [0.35, 0.65], "de": 0.0})["CL"]
    assert between.outside.tolist() == [False, True]
    assert "distance" in between.reason[1].split("+")


def _segment_distance(P, a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    t = np.clip(((P - a) @ (b - a)) / ((b - a) @ (b - a)), 0.0, 1.0)
    return np.linalg.norm(P - (a + t[:, None] * (b - a)), axis=1)


# the L: the unit square without its upper-right quarter, as a closed polygon
L_VERTICES = [(0, 0), (1, 0), (1, 0.5), (0.5, 0.5), (0.5, 1), (0, 1), (0, 0)]


def _distance_to_l_boundary(P):
    return np.min(
        [_segment_distance(P, a, b) for a, b in zip(L_VERTICES[:-1], L_VERTICES[1:], strict=True)],
        axis=0,
    )


def test_the_empty_corner_of_l_shaped_data_is_outside():
    rng = np.random.default_rng(2)
    points = rng.uniform(0, 1, (6000, 2))
    points = points[~((points[:, 0] > 0.5) & (points[:, 1] > 0.5))][:3000]
    x, y = points.T
    z = 1 + x + 2 * y + 0.3 * x * y + rng.normal(0, 0.01, x.size)
    model = fit_global_model(
        {"x": x, "y": y, "z": z}, ["z"], ["x", "y"], settings=GlobalModelSettings(max_order=2)
    )
    grid = np.linspace(-0.3, 1.3, 65)
    G = np.array(np.meshgrid(grid, grid)).reshape(2, -1).T
    prediction = model.predict({"x": G[:, 0], "y": G[:, 1]})["z"]
    far = prediction.distance_ratio > model["z"].support.factor
    # reference: inside the L = inside the Delaunay triangulation of either arm's data
    left, low = points[points[:, 0] <= 0.5], points[points[:, 1] <= 0.5]
    inside = (Delaunay(left).find_simplex(G) >= 0) | (Delaunay(low).find_simplex(G) >= 0)
    away = _distance_to_l_boundary(G) > 0.1
    assert away.sum() > 2000
    assert np.mean(far[away] == ~inside[away]) >= 0.95
    # the empty corner lies inside the data's box (hidden extrapolation) and is flagged
    corner = (G[:, 0] > 0.65) & (G[:, 1] > 0.65) & (G[:, 0] < 1) & (G[:, 1] < 1)
    assert corner.sum() > 50
    assert np.all(prediction.outside[corner])
    assert np.all(~prediction.outside[away & inside])


def test_leverage_of_an_extrapolated_cubic():
    rng = np.random.default_rng(3)
    n = 400
    x, y = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
    z = 0.5 + x - 0.8 * x**3 + 0.2 * y + rng.normal(0, 0.01, n)
    settings = GlobalModelSettings(
        orders={"x": 3, "y": 1}, max_order=3, forced=("1", "x", "x^3", "y")
    )
    model = fit_global_model({"x": x, "y": y, "z": z}, ["z"], ["x", "y"], settings=settings)
    cl = model["z"]
    at = {"x": np.array([0.0, 0.5, 1.5 * np.max(np.abs(x))]), "y": np.array([0.0, 0.0, 0.0])}
    prediction = cl.predict(at)
    # reference: h = φᵀ pinv(ΦᵀΦ) φ, against the largest leverage of the fitted samples
    Phi = cl.regressors({"x": x, "y": y})
    inverse = np.linalg.pinv(Phi.T @ Phi)
    h_max = np.max(np.einsum("ij,jk,ik->i", Phi, inverse, Phi))
    phi0 = cl.regressors(at)
    expected = np.einsum("ij,jk,ik->i", phi0, inverse, phi0) / h_max
    np.testing.assert_allclose(prediction.leverage_ratio, expected, rtol=1e-8)
    assert prediction.leverage_ratio[2] > 1.0 and prediction.outside[2]
    assert "leverage" in prediction.reason[2].split("+")
    assert np.all(prediction.leverage_ratio[:2] < 1.0) and not prediction.outside[:2].any()


def test_support_does_not_depend_on_the_variables_units():
    signals, index, dt = _maneuvers(seed=4, n_maneuvers=3)
    settings = GlobalModelSettings(max_order=2)
    rad = fit_global_model(
        signals, ["CL"], ["alpha", "Mach", "de"], settings=settings, maneuver_index=index, dt=dt
    )
    degrees = {**signals, "alpha": np.degrees(signals["alpha"])}
    deg = fit_global_model(
        degrees, ["CL"], ["alpha", "Mach", "de"], settings=settings, maneuver_index=index, dt=dt
    )
    alpha = np.linspace(-0.1, 0.5, 13)
    points = {"alpha": alpha, "Mach": 0.5, "de": 0.05}
    a = rad.predict(points)["CL"]
    b = deg.predict({**points, "alpha": np.degrees(alpha)})["CL"]
    np.testing.assert_allclose(a.value, b.value, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(a.distance_ratio, b.distance_ratio, rtol=1e-9)
    np.testing.assert_allclose(a.leverage_ratio, b.leverage_ratio, rtol=1e-7)
    np.testing.assert_array_equal(a.outside, b.outside)
    np.testing.assert_allclose(a.upper, b.upper, rtol=1e-9)


def test_the_reference_set_is_thinned_per_maneuver():
    index = np.repeat([0, 1], [100, 37])
    chosen = thinned_indices(index, dt=0.05, spacing_s=0.25, max_reference=1000)
    # one sample in five per maneuver, each maneuver from its own first sample
    np.testing.assert_array_equal(chosen, np.r_[np.arange(0, 100, 5), 100 + np.arange(0, 37, 5)])
    assert thinned_indices(index, None, 0.25, 1000).size == 137
    assert thinned_indices(index, None, 0.25, 50).size == 50


def test_d_ref_is_the_quantile_of_the_reference_knn_distance():
    rng = np.random.default_rng(5)
    V = rng.uniform(-1, 1, (500, 2))
    support = Support.from_data(V, np.zeros(500), None, k=3, quantile=0.9)
    # brute force: distances to every other sample, the 3rd smallest
    D = np.linalg.norm(V[:, None, :] - V[None, :, :], axis=2)
    third = np.sort(D, axis=1)[:, 3]
    assert support.d_ref == pytest.approx(np.quantile(third, 0.9), rel=1e-12)
    far, _, outside, reason = support.measure(np.array([[5.0, 5.0], [0.0, 0.0]]), np.zeros(2))
    assert outside.tolist() == [True, False] and reason == ("distance", "")
    _, _, outside, reason = support.measure(
        np.array([[5.0, 5.0], [0.0, 0.0]]), np.array([2.0, 0.0]), np.array([True, True])
    )
    assert outside.tolist() == [True, True]
    assert reason == ("range+distance+leverage", "range")


MACH_LEVELS = (0.3, 0.45, 0.6, 0.75, 0.9)


def _envelope_maneuvers(seed=0, duration_s=20.0, dt=0.02):
    """(alpha, Mach, qhat, de) trajectories, two maneuvers at each Mach level of
    ``MACH_LEVELS``; CL linear in α (its model extrapolates smoothly)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, dt)
    parts = {k: [] for k in ("alpha", "Mach", "qhat", "de")}
    for k in range(2 * len(MACH_LEVELS)):
        phase = rng.uniform(0, 2 * np.pi, 4)
        alpha = 0.08 + 0.1 * np.sin(0.9 * t + phase[0]) + 0.03 * np.sin(2.9 * t + phase[1])
        parts["alpha"].append(alpha)
        parts["Mach"].append(MACH_LEVELS[k % 5] + 0.01 * np.sin(0.15 * t + phase[2]))
        parts["qhat"].append(0.01 * np.cos(0.9 * t + phase[0]) + 0.004 * np.cos(2.9 * t + phase[1]))
        parts["de"].append(-0.3 * alpha + 0.05 * np.sin(1.3 * t + phase[3]))
    signals = {key: np.concatenate(v) for key, v in parts.items()}
    a, m, q, d = (signals[k] for k in ("alpha", "Mach", "qhat", "de"))
    noise = 0.003 * rng.normal(size=a.size)
    signals["CL"] = 0.1 + 4.5 * a + 1.5 * a * m + 6 * q + 0.5 * d + noise
    return signals, np.repeat(np.arange(2 * len(MACH_LEVELS)), t.size), dt


ENVELOPE = ("alpha", "Mach", "qhat", "de")


@pytest.mark.parametrize("seed", [0, 1])
def test_points_beyond_the_data_range_are_outside(seed):
    signals, index, dt = _envelope_maneuvers(seed)
    model = fit_global_model(
        signals,
        ["CL"],
        list(ENVELOPE),
        settings=GlobalModelSettings(max_order=2, decimate=5),
        maneuver_index=index,
        dt=dt,
    )
    cl = model["CL"]
    low, high = signals["alpha"].min(), signals["alpha"].max()
    # α below the data's lowest by a quarter of its range, at every Mach level flown
    below = low - 0.25 * (high - low)
    p = cl.predict({"alpha": below, "Mach": MACH_LEVELS, "qhat": 0.0, "de": -0.3 * below})
    assert p.outside.all()
    # neither the k-NN distance nor the leverage catches it: only the range does
    assert p.reason == ("range",) * 5
    # Mach 1.0 above the data's 0.91 at α inside the data's range
    alpha = np.linspace(0.0, 0.16, 5)
    p = cl.predict({"alpha": alpha, "Mach": 1.0, "qhat": 0.0, "de": -0.3 * alpha})
    assert p.outside.all() and p.reason == ("range",) * 5
    # held-out maneuvers over the same box: inside
    held, _, _ = _envelope_maneuvers(seed + 10)
    p = cl.predict({k: held[k] for k in ENVELOPE})
    assert np.mean(~p.outside) >= 0.98
    assert not any("range" in reason for reason in p.reason)


def test_the_margin_of_the_range():
    signals, index, dt = _envelope_maneuvers(2)
    settings = GlobalModelSettings(max_order=1, support_margin=0.3)
    model = fit_global_model(
        signals, ["CL"], list(ENVELOPE), settings=settings, maneuver_index=index, dt=dt
    )
    low, high = signals["alpha"].min(), signals["alpha"].max()
    below = low - 0.25 * (high - low)
    p = model["CL"].predict({"alpha": below, "Mach": 0.6, "qhat": 0.0, "de": -0.3 * below})
    # within the 30 % margin: not out of range
    assert "range" not in p.reason[0]
    with pytest.raises(GlobalModelError, match="support_margin"):
        GlobalModelSettings(support_margin=-0.1)


def test_beyond_range_closed_form():
    low, high = np.array([0.0, 2.0, 5.0]), np.array([10.0, 4.0, 5.0])
    X = np.array(
        [
            [-0.19, 2.0, 5.0],  # 1.9 % of the range below: inside the 2 % margin
            [-0.21, 2.0, 5.0],  # 2.1 % below: outside
            [5.0, 4.039, 5.0],  # 1.95 % above
            [5.0, 4.041, 5.0],  # 2.05 % above
            [5.0, 3.0, 5.0 + 1e-9],  # a variable the data held constant: no margin
            [10.0, 2.0, 5.0],  # on the edges
        ]
    )
    expected = [False, True, False, True, True, False]
    assert beyond_range(X, low, high, 0.02).tolist() == expected
    assert not beyond_range(X[:4], low, high, 0.05).any()
