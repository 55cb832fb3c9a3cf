"""Models without states: output error on outputs that are algebraic functions of measured
inputs (nonlinear regression by the ML machinery), ``StateSpaceModel(states=(), f=None)``."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.optimize import least_squares

from flightid import FPS, MNR, MNRES
from flightid.cli.main import main
from flightid.data.flightdata import FlightData
from flightid.errors import InputTypeError, ModelError
from flightid.estimation.driver import estimate
from flightid.model.check import check_model
from flightid.model.statespace import StateSpaceModel
from flightid.simulation.simulator import Simulator, simulate

N = 300


def _inputs(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(N) * 0.02
    return t, rng.uniform(-1.0, 1.0, N), rng.uniform(-2.0, 2.0, N)


def h_linear(t, x, u, theta):
    # y = a + b·u1 + c·u1·u2 + d·sin(u2)
    return np.array([theta[0] + theta[1] * u[0] + theta[2] * u[0] * u[1] + theta[3] * np.sin(u[1])])


def _regressors(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    return np.column_stack([np.ones_like(u1), u1, u1 * u2, np.sin(u2)])


def _linear_case():
    t, u1, u2 = _inputs(7)
    truth = np.array([0.3, -1.2, 0.8, 0.5])
    noise = np.random.default_rng(8).normal(0.0, 0.05, N)
    y = _regressors(u1, u2) @ truth + noise
    data = FlightData(t, {"u1": u1, "u2": u2}, {"y": y})
    model = StateSpaceModel(
        (), ("u1", "u2"), ("y",), None, h_linear, {"a": 0.0, "b": 0.0, "c": 0.0, "d": 0.0}
    )
    return model, data, _regressors(u1, u2), y


def test_simulate_is_h_at_every_sample_compiled_and_python():
    model, data, x, _ = _linear_case()
    theta = np.array([0.1, 2.0, -0.4, 1.5])
    expected = x @ theta  # y_k = h(t_k, [], u_k, θ) written out by hand
    for compiled in (True, False):
        y = simulate(model, data, theta, compiled=compiled)
        np.testing.assert_allclose(y[:, 0], expected, rtol=1e-13, atol=1e-13)
    assert model.states == () and not model.has_states
    assert Simulator(model, data).compiled  # numba compiles the h-only kernel


def test_f_none_needs_no_states():
    with pytest.raises(InputTypeError, match="f=None is only for a model without states"):
        StateSpaceModel(("x",), ("u1",), ("y",), None, h_linear, {"a": 0.0})


@pytest.mark.parametrize("solver", [MNRES(), MNR(), MNR(sensitivities="equations")])
def test_linear_regression_equals_least_squares(solver):
    model, data, x, y = _linear_case()
    est = estimate(model, data, solver)
    assert est.converged
    # independent solution: ordinary least squares (single output, so the ML weight 1/R̂ is
    # one constant and weighted least squares is ordinary least squares)
    theta_ls, *_ = np.linalg.lstsq(x, y, rcond=None)
    np.testing.assert_allclose(est.values, theta_ls, rtol=1e-6)
    # ML noise variance: R̂ = (1/N) Σ (y_k − ŷ_k)²  (RP-1153 eq. for R with noise = "max")
    r_hat = np.mean((y - x @ theta_ls) ** 2)
    np.testing.assert_allclose(est.r_diag, [r_hat], rtol=1e-6)
    # CR bound: G = X (∂y/∂θ), M = Gᵀ R̂⁻¹ G = XᵀX / R̂, so cov = R̂ (XᵀX)⁻¹ — the least-squares
    # covariance s² (XᵀX)⁻¹ with s² = R̂ (the 1/N, not 1/(N − p), variance)
    sigma_ls = np.sqrt(r_hat * np.diag(np.linalg.inv(x.T @ x)))
    np.testing.assert_allclose(est.std, sigma_ls, rtol=1e-5)


def h_exponential(t, x, u, theta):
    # y = a·exp(−b·u)
    return np.array([theta[0] * np.exp(-theta[1] * u[0])])


@pytest.mark.parametrize("solver", [MNRES(), MNR(), FPS()])
def test_nonlinear_regression_equals_scipy_least_squares(solver):
    t, u, _ = _inputs(11)
    y = 2.0 * np.exp(-0.7 * u) + np.random.default_rng(12).normal(0.0, 0.02, N)
    data = FlightData(t, {"u": u}, {"y": y})
    model = StateSpaceModel((), ("u",), ("y",), None, h_exponential, {"a": 1.0, "b": 0.1})
    est = estimate(model, data, solver)
    assert est.converged, est.message

    def residual(p):
        return y - p[0] * np.exp(-p[1] * u)

    # independent solution: scipy's trust-region least squares from the same start
    fit = least_squares(residual, [1.0, 0.1], xtol=1e-14, ftol=1e-14, gtol=1e-14)
    np.testing.assert_allclose(est.values, fit.x, rtol=1e-5)
    r_hat = np.mean(fit.fun**2)
    # CR σ = sqrt(R̂ · diag((JᵀJ)⁻¹)) with J the residual Jacobian at the optimum
    sigma = np.sqrt(r_hat * np.diag(np.linalg.inv(fit.jac.T @ fit.jac)))
    np.testing.assert_allclose(est.std, sigma, rtol=1e-3)


def test_check_model_catches_u_past_its_length_without_states():
    def h_reads_u2(t, x, u, theta):
        return np.array([theta[0] * u[0] + theta[1] * u[2]])

    model, data, _, _ = _linear_case()
    bad = StateSpaceModel((), ("u1", "u2"), ("y",), None, h_reads_u2, {"a": 1.0, "b": 1.0})
    with pytest.raises(ModelError, match=r"read u\[2\] but the model has 2 inputs"):
        check_model(bad, data)
    with pytest.raises(ModelError, match=r"read u\[2\]"):
        estimate(bad, data)
    check = check_model(model, data)  # the good one passes: h only, f is never called
    assert check.f_shape == (0,) and check.h_shape == (1,)
    assert "h (no states, no f) evaluated at 7 samples" in check.summary()


MODULE = """\
import numpy as np

STATES = ()
INPUTS = ("u1", "u2")
OUTPUTS = ("y",)
PARAMETERS = {"a": 0.0, "b": 0.0, "c": 0.0, "d": 0.0}


def h(t, x, u, theta):
    return np.array(
        [theta[0] + theta[1] * u[0] + theta[2] * u[0] * u[1] + theta[3] * np.sin(u[1])]
    )
"""

CASE = """\
title = "regression without states"

[data]
data_dir = "."
file = "flight.csv"
time = "time"

[data.inputs]
u1 = { column = "u1" }
u2 = { column = "u2" }

[data.outputs]
y = { column = "y" }

[model]
module = "regression.py"

[estimation]
solver = "mnr"
"""


def test_case_file_with_a_module_without_states(tmp_path, capsys):
    _, data, x, y = _linear_case()
    rows = np.column_stack([data.time, data.input("u1"), data.input("u2"), y])
    np.savetxt(tmp_path / "flight.csv", rows, delimiter=",", header="time,u1,u2,y", comments="")
    (tmp_path / "regression.py").write_text(MODULE)
    (tmp_path / "case.toml").write_text(CASE)
    # the result folder is a folder of its own: the case's folder is refused
    out = str(tmp_path / "out")
    code = main(["run", str(tmp_path / "case.toml"), "--json", "--quiet", "--out", out])
    assert code == 0
    (entry,) = json.loads(capsys.readouterr().out)["results"]
    assert entry["converged"] is True
    values = {p["name"]: p["value"] for p in entry["parameters"]}
    theta_ls, *_ = np.linalg.lstsq(x, y, rcond=None)  # independent: least squares
    # the CSV holds the data to %.18e, so the fit is the same to round-off
    np.testing.assert_allclose([values[n] for n in "abcd"], theta_ls, rtol=1e-6)
