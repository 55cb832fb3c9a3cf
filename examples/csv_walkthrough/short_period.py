"""Short-period model for the CSV walk-through (docs/cases.md).

dα/dt = Z_α α + (1 + Z_q) q + Z_δe δe
dq/dt = M_α α + M_q q + M_δe δe
outputs α (rad), q (rad/s); input δe (rad)
"""

import numpy as np

STATES = ("alpha", "q")
INPUTS = ("de",)
OUTPUTS = ("alpha", "q")
PARAMETERS = {"Za": -0.5, "Zq": 0.0, "Zde": -0.05, "Ma": -3.0, "Mq": -1.0, "Mde": -5.0}


def f(t, x, u, theta):
    dx = np.empty(2)
    # α̇ = Z_α α + (1 + Z_q) q + Z_δe δe
    dx[0] = theta[0] * x[0] + (1.0 + theta[1]) * x[1] + theta[2] * u[0]
    # q̇ = M_α α + M_q q + M_δe δe
    dx[1] = theta[3] * x[0] + theta[4] * x[1] + theta[5] * u[0]
    return dx


def h(t, x, u, theta):
    y = np.empty(2)
    y[0] = x[0]
    y[1] = x[1]
    return y
