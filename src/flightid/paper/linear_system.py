"""The linear second-order system of RP-1153 examples 1 and 2 [6.1–6.2].

    dx/dt = A x + B u,  x(0) = 0,  y = x
    A = [[θ1, θ2], [θ3, θ4]],  B = [θ5, θ6]ᵀ

True values θ = (0, −1.5, 1.0, −0.5, 0.2, 0.1); start values (0.01, −1.6, 1.1, −0.6, 0.25,
0.15) (paper, tables II and III).
"""

from __future__ import annotations

import numpy as np

from flightid.model import Parameter, Parameters, StateSpaceModel

TRUE_VALUES = (0.0, -1.5, 1.0, -0.5, 0.2, 0.1)  # RP-1153 table II, "True value"
START_VALUES = (0.01, -1.6, 1.1, -0.6, 0.25, 0.15)  # RP-1153 table II, "Initial value"
NAMES = ("theta1", "theta2", "theta3", "theta4", "theta5", "theta6")


def f(t, x, u, theta):
    """dx/dt = A x + B u."""
    dx = np.empty(2)
    dx[0] = theta[0] * x[0] + theta[1] * x[1] + theta[4] * u[0]
    dx[1] = theta[2] * x[0] + theta[3] * x[1] + theta[5] * u[0]
    return dx


def h(t, x, u, theta):
    """y = x (both states measured)."""
    return x.copy()


def linear_model(values=START_VALUES) -> StateSpaceModel:
    """The example-1/2 model with the given parameter values (default: the paper's start)."""
    parameters = Parameters(
        Parameter(name, value, scale=max(abs(true), 0.01))
        for name, value, true in zip(NAMES, values, TRUE_VALUES, strict=True)
    )
    return StateSpaceModel(
        states=("x1", "x2"),
        inputs=("u",),
        outputs=("x1", "x2"),
        f=f,
        h=h,
        parameters=parameters,
        x0=(0.0, 0.0),
        name="RP-1153 linear second-order system",
    )
