"""Shared fixtures: small models and data sets used across the core tests."""

from __future__ import annotations

import os

# One BLAS thread: the suite's matrices are small and its machines have 2 cores, where
# OpenBLAS's threads cost more than they give (measured: 70 s against 156 s for the suite).
# Set before numpy is first imported; an explicit setting in the environment wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

from flightid.data import FlightData
from flightid.model import Parameter, Parameters, StateSpaceModel
from flightid.simulation import simulate

# Hypothesis: derandomised by default, so every run draws the same examples (a failure seen
# once is seen again; no flaky red builds). HYPOTHESIS_PROFILE=explore draws fresh examples
# for a local bug hunt; the example database is off so runs do not depend on earlier runs.
settings.register_profile(
    "ci",
    derandomize=True,
    database=None,
    deadline=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile("explore", derandomize=False, database=None, deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


def pendulum_f(t, x, u, theta):
    """Damped pendulum with a torque input: a model nonlinear in its states and parameters."""
    dx = np.empty(2)
    dx[0] = x[1]
    dx[1] = (
        -theta[0] * np.sin(x[0]) - theta[1] * x[1] - theta[2] * x[1] * abs(x[1]) + theta[3] * u[0]
    )
    return dx


def pendulum_h(t, x, u, theta):
    y = np.empty(2)
    y[0] = x[0]
    y[1] = x[1]
    return y


PENDULUM_TRUE = (9.0, 0.4, 0.3, 2.0)
PENDULUM_START = (8.0, 0.5, 0.2, 2.3)


def pendulum_model(values=PENDULUM_START) -> StateSpaceModel:
    return StateSpaceModel(
        states=("angle", "rate"),
        inputs=("torque",),
        outputs=("angle", "rate"),
        f=pendulum_f,
        h=pendulum_h,
        parameters=Parameters(
            Parameter(n, v) for n, v in zip(("k", "c", "d", "b"), values, strict=True)
        ),
        x0=(0.0, 0.0),
        name="pendulum",
    )


def pendulum_data(sigma=(0.01, 0.05), seed=7) -> FlightData:
    t = np.arange(0.0, 8.0 + 1e-9, 0.02)
    torque = np.where((t > 0.5) & (t < 1.5), 2.0, 0.0) - np.where((t > 3.0) & (t < 3.6), 3.0, 0.0)
    inputs = FlightData(t, {"torque": torque})
    clean = simulate(pendulum_model(PENDULUM_TRUE), inputs)
    rng = np.random.default_rng(seed)
    noisy = clean + rng.normal(0.0, 1.0, clean.shape) * np.asarray(sigma)
    return FlightData(t, {"torque": torque}, {"angle": noisy[:, 0], "rate": noisy[:, 1]})


@pytest.fixture(scope="session")
def pendulum():
    return pendulum_model(), pendulum_data()
