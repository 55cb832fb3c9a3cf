"""Linear models of a model or an estimate: ``flightid.model.linearization.linearize`` and
``Estimate.linearize`` (A, B, C, D, the covariance of the entries, conversions)."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from flightid.estimation import estimate
from flightid.model.linearization import LinearizationError, LinearModel, linearize
from flightid.model.parameters import Parameter, Parameters
from flightid.model.statespace import StateSpaceModel
from flightid.results import MissingDependencyError
from test_predict import TRUE, maneuver, short_period

A = np.array([[-0.8, 1.0, 0.1], [-4.0, -1.5, 0.0], [0.0, 1.0, 0.0]])
B = np.array([[-0.1, 0.02], [-6.0, 0.5], [0.0, 0.0]])
C = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [2.0, 0.3, -1.0]])
D = np.array([[0.0, 0.0], [0.0, 0.0], [0.7, 0.0]])
ENTRIES = np.concatenate([A.ravel(), B.ravel(), C.ravel(), D.ravel()])


def entry_model(free: np.ndarray) -> StateSpaceModel:
    """ẋ = A x + B u, y = C x + D u with every entry a parameter (row-major A, B, C, D)."""

    def f(t, x, u, th):
        a = th[:9].reshape(3, 3)
        b = th[9:15].reshape(3, 2)
        return a @ x + b @ u

    def h(t, x, u, th):
        c = th[15:24].reshape(3, 3)
        d = th[24:30].reshape(3, 2)
        return c @ x + d @ u

    parameters = Parameters(
        [Parameter(f"e{k}", float(v), free=bool(free[k])) for k, v in enumerate(ENTRIES)]
    )
    return StateSpaceModel(("x1", "x2", "x3"), ("u1", "u2"), ("y1", "y2", "y3"), f, h, parameters)


def random_covariance(n: int, seed: int) -> np.ndarray:
    m = np.random.default_rng(seed).normal(size=(n, n))
    return 1e-4 * (m @ m.T + n * np.eye(n))


def test_a_linear_model_is_returned_exactly_with_the_covariance_mapped_by_the_selection():
    free = np.ones(ENTRIES.size, dtype=bool)
    free[[2, 10, 29]] = False  # three entries fixed: their rows of the covariance are 0
    model = entry_model(free)
    p = random_covariance(int(free.sum()), 1)
    # a point away from 0: the Jacobians of a linear model do not depend on it
    linear = linearize(model, [0.3, -2.0, 5.0], [0.1, 40.0], covariance=p)
    for name, known in zip("ABCD", (A, B, C, D), strict=True):
        np.testing.assert_allclose(getattr(linear, name), known, rtol=0, atol=1e-8)
    # Cov vec(A, B, C, D) = S P Sᵀ with S the selection of the free entries
    selection = np.eye(ENTRIES.size)[:, free]
    # (to 1e-6 of the largest entry: nested central differences, rounding only)
    mapped = selection @ p @ selection.T
    np.testing.assert_allclose(linear.covariance, mapped, rtol=0, atol=1e-6 * np.abs(p).max())
    np.testing.assert_allclose(
        linear.block_std("A"), np.sqrt(np.diag(mapped))[:9].reshape(3, 3), rtol=1e-6
    )
    # the operating point and the values of f and h there
    np.testing.assert_allclose(linear.f0, A @ [0.3, -2.0, 5.0] + B @ [0.1, 40.0], atol=1e-12)
    np.testing.assert_allclose(linear.y0, C @ [0.3, -2.0, 5.0] + D @ [0.1, 40.0], atol=1e-12)


def test_a_nonlinear_model_gives_its_jacobians_at_the_point():
    # pendulum with a torque input: φ̈ = −(g/l) sin φ − c φ̇ + k u ; y = (φ, l sin φ)
    def f(t, x, u, th):
        return np.array([x[1], -th[0] * np.sin(x[0]) - th[1] * x[1] + th[2] * u[0]])

    def h(t, x, u, th):
        return np.array([x[0], 2.0 * np.sin(x[0])])

    model = StateSpaceModel(
        ("phi", "phidot"), ("u",), ("phi", "s"), f, h, Parameters({"w2": 9.0, "c": 0.4, "k": 2})
    )
    phi = 0.3
    linear = linearize(model, {"phi": phi, "phidot": 0.2}, {"u": 0.5})
    np.testing.assert_allclose(linear.A, [[0, 1], [-9.0 * np.cos(phi), -0.4]], atol=1e-8)
    np.testing.assert_allclose(linear.B, [[0], [2.0]], atol=1e-8)
    np.testing.assert_allclose(linear.C, [[1, 0], [2.0 * np.cos(phi), 0]], atol=1e-8)
    np.testing.assert_allclose(linear.D, [[0], [0]], atol=1e-8)
    assert linear.covariance is None and np.isnan(linear.block_std("A")).all()


def test_operating_point_and_covariance_are_checked():
    model = entry_model(np.ones(ENTRIES.size, dtype=bool))
    with pytest.raises(LinearizationError, match="expected 3 values"):
        linearize(model, [0.0, 0.0])
    with pytest.raises(LinearizationError, match="missing"):
        linearize(model, {"x1": 0.0}, [0.0, 0.0])
    with pytest.raises(LinearizationError, match="finite"):
        linearize(model, [0.0, np.nan, 0.0])
    with pytest.raises(LinearizationError, match="covariance"):
        linearize(model, [0.0] * 3, covariance=np.eye(3))
    p = np.eye(ENTRIES.size)
    p[0, 0] = np.inf
    with pytest.raises(LinearizationError, match="non-finite"):
        linearize(model, [0.0] * 3, covariance=p)
    with pytest.raises(LinearizationError, match="block"):
        linearize(model, [0.0] * 3).block_std("E")


@pytest.fixture(scope="module")
def fitted():
    data = maneuver(1, "estimation")
    start = short_period({k: 1.2 * v for k, v in TRUE.items()})
    return estimate(start, data), data


def test_estimate_linearize_holds_the_estimates_and_their_sigma(fitted):
    result, data = fitted
    value = dict(zip(result.names, result.values, strict=True))
    sigma = dict(zip(result.names, result.std, strict=True))
    for at in (None, data, ([0.01, 0.0], [0.0])):
        linear = result.linearize(at=at)
        # α̇ = Z_α α + q + Z_δe δe, q̇ = M_α α + M_q q + M_δe δe: A, B hold the estimates
        np.testing.assert_allclose(
            linear.A, [[value["Za"], 1.0], [value["Ma"], value["Mq"]]], rtol=1e-7, atol=1e-9
        )
        np.testing.assert_allclose(linear.B, [[value["Zde"]], [value["Mde"]]], rtol=1e-7)
        # σ of an entry that is one parameter: that parameter's σ (delta method, exact here)
        std_a, std_b = linear.block_std("A"), linear.block_std("B")
        np.testing.assert_allclose(
            [std_a[0, 0], std_a[1, 0], std_a[1, 1], std_b[0, 0], std_b[1, 0]],
            [sigma[n] for n in ("Za", "Ma", "Mq", "Zde", "Mde")],
            rtol=1e-5,
        )
        assert std_a[0, 1] == 0.0
    point = result.linearize(at=data)
    assert point.x0.tolist() == [data.output("alpha")[0], data.output("q")[0]]
    assert point.u0.tolist() == pytest.approx([np.mean(data.input("de"))])
    assert point.state_units == ("rad", "rad/s") and point.input_units == ("rad",)
    assert "mean inputs" in point.operating_point
    assert result.linearize().u0.tolist() == [0.0]
    with pytest.raises(LinearizationError, match="at: expected"):
        result.linearize(at="trim")


def test_conversions_summary_and_json(fitted):
    result, _ = fitted
    linear = result.linearize()
    system = linear.to_scipy()
    np.testing.assert_array_equal(system.A, linear.A)
    np.testing.assert_array_equal(system.D, linear.D)
    entry = linear.to_dict()
    text = json.dumps(entry, allow_nan=False)
    assert '"A_std"' in text and '"short period"' in text
    assert entry["operating_point"]["x"] == linear.x0.tolist()
    summary = linear.summary()
    assert "A (rows ['alpha', 'q']" in summary and "short period" in summary
    assert isinstance(linear, LinearModel) and "LinearModel" in repr(linear)


def test_to_control_names_the_missing_extra(fitted, monkeypatch):
    linear = fitted[0].linearize()
    monkeypatch.setitem(sys.modules, "control", None)  # import control → ImportError
    with pytest.raises(MissingDependencyError, match=r"flightid\[control\]"):
        linear.to_control()


def test_to_control_gives_a_named_state_space(fitted):
    control = pytest.importorskip("control")
    linear = fitted[0].linearize()
    system = linear.to_control()
    assert isinstance(system, control.StateSpace)
    np.testing.assert_array_equal(system.A, linear.A)
    assert list(system.state_labels) == ["alpha", "q"]
    assert list(system.input_labels) == ["de"]


def test_measured_states_as_inputs_and_delays_are_noted():
    # ṗ = L_p p + L_β β_m with β a measured input: A is the roll subsystem only
    def f(t, x, u, th):
        return np.array([th[0] * x[0] + th[1] * u[0]])

    def h(t, x, u, th):
        return np.array([x[0]])

    parameters = Parameters({"Lp": -2.0, "Lb": -10.0, "tau": 0.05})
    model = StateSpaceModel(("p",), ("beta",), ("p",), f, h, parameters, output_delays={"p": "tau"})
    linear = linearize(model, [0.0], [0.0])
    assert any("['beta'] are measured states" in n for n in linear.notes)
    assert any("delayed by tau = 0.05 s" in n for n in linear.notes)
    assert "measured states" in linear.modes().summary()
    assert linear.to_dict()["notes"] == list(linear.notes)
    plain = StateSpaceModel(("p",), ("da",), ("p",), f, h, Parameters({"Lp": -2.0, "Lb": 1.0}))
    assert linearize(plain, [0.0], [0.0]).notes == ()


def test_an_undetermined_parameter_leaves_the_entries_without_sigma(fitted):
    from dataclasses import replace

    result, _ = fitted
    covariance = np.array(result.covariance)
    covariance[0, :] = covariance[:, 0] = np.inf
    std = np.array(result.std)
    std[0] = np.inf
    undetermined = replace(
        result, covariance=covariance, std_cr=std, std=std, covariance_default=None
    )
    linear = undetermined.linearize()
    assert linear.covariance is None and np.isnan(linear.block_std("A")).all()
    assert any("['Za'] are undetermined" in n for n in linear.notes)
    np.testing.assert_allclose(linear.A, result.linearize().A, rtol=1e-12)
    assert np.isnan(linear.modes()[0].natural_frequency_std)
