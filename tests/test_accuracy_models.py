"""Small models for the accuracy tests (helpers only; no tests here)."""

from __future__ import annotations

import numpy as np

from flightid.data import FlightData
from flightid.estimation import MNR, estimate
from flightid.model import Parameter, Parameters, StateSpaceModel
from flightid.simulation import simulate

LINEAR_TRUE = (0.8, -0.5, 0.3, 1.2)
LINEAR_SIGMA = (0.05, 0.1)


def _zero(t, x, u, theta):
    return np.zeros(1)


def _linear_outputs(t, x, u, theta):
    # y1 = θ0 u0 + θ1 u1 + θ2,  y2 = θ3 u0 − θ1 u1  (linear in θ)
    y = np.empty(2)
    y[0] = theta[0] * u[0] + theta[1] * u[1] + theta[2]
    y[1] = theta[3] * u[0] - theta[1] * u[1]
    return y


def linear_regressors(u: np.ndarray) -> np.ndarray:
    """X such that vec(y) = X θ, stacked per sample as (N, n_o, n_p)."""
    n = u.shape[0]
    x = np.zeros((n, 2, 4))
    x[:, 0, 0], x[:, 0, 1], x[:, 0, 2] = u[:, 0], u[:, 1], 1.0
    x[:, 1, 3], x[:, 1, 1] = u[:, 0], -u[:, 1]
    return x


def linear_model(values=LINEAR_TRUE) -> StateSpaceModel:
    """A static two-output regression written as a state-space model (dummy state)."""
    return StateSpaceModel(
        states=("dummy",),
        inputs=("u0", "u1"),
        outputs=("y1", "y2"),
        f=_zero,
        h=_linear_outputs,
        parameters=Parameters(Parameter(f"p{k}", v, scale=1.0) for k, v in enumerate(values)),
        x0=(0.0,),
        name="linear in parameters",
    )


def linear_data(n: int = 60, seed: int = 0, collinear: float = 0.0) -> FlightData:
    """Random inputs (u1 mixed with u0 by ``collinear``) and noisy outputs."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.1
    u = rng.normal(size=(n, 2))
    u[:, 1] = collinear * u[:, 0] + (1.0 - collinear) * u[:, 1]
    inputs = FlightData(t, {"u0": u[:, 0], "u1": u[:, 1]})
    clean = simulate(linear_model(), inputs, method="euler")
    z = clean + rng.normal(size=clean.shape) * np.array(LINEAR_SIGMA)
    return FlightData(t, {"u0": u[:, 0], "u1": u[:, 1]}, {"y1": z[:, 0], "y2": z[:, 1]})


def linear_estimate(seed: int = 0, collinear: float = 0.0):
    data = linear_data(seed=seed, collinear=collinear)
    start = tuple(v + 0.1 for v in LINEAR_TRUE)
    return estimate(linear_model(start), data, MNR(), method="euler", noise="max"), data


# ---------------------------------------------------------------- nonlinear: y = a e^(−b t) + c
EXP_TRUE = (1.0, 0.8, 0.1)


def _decay(t, x, u, theta):
    return np.array([-theta[1] * x[0]])


def _offset(t, x, u, theta):
    return np.array([x[0] + theta[2]])


def exp_model(values=EXP_TRUE) -> StateSpaceModel:
    """dx/dt = −b x, x(0) = a, y = x + c: nonlinear in b."""
    return StateSpaceModel(
        states=("x",),
        inputs=(),
        outputs=("y",),
        f=_decay,
        h=_offset,
        parameters=Parameters(
            [
                Parameter("a", values[0]),
                Parameter("b", values[1]),
                Parameter("c", values[2], scale=0.1),
            ]
        ),
        x0=("a",),
        name="exponential decay",
    )


def exp_data(sigma: float = 0.1, seed: int = 3, duration: float = 4.0) -> FlightData:
    t = np.arange(0.0, duration + 1e-9, 0.1)
    clean = simulate(exp_model(), FlightData(t), method="rk4")
    z = clean[:, 0] + np.random.default_rng(seed).normal(0.0, sigma, t.size)
    return FlightData(t, None, {"y": z})


def exp_estimate(sigma: float = 0.1, seed: int = 3):
    data = exp_data(sigma, seed)
    return estimate(exp_model(), data, MNR(), noise="max"), data
