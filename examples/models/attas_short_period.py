"""ATTAS short-period motion (the ATTAS elevator flight data, the book's short-period case).

dα/dt = Z_0 + Z_α α + (1 + Z_q) q + Z_δe δe
dq/dt = M_0 + M_α α + M_q q + M_δe δe
outputs α (rad), q (rad/s); input δe (rad).
"""

import numpy as np

STATES = ("alpha", "q")
INPUTS = ("de",)
OUTPUTS = ("alpha", "q")
PARAMETERS = {
    "Z0": -2.52504e-3,
    "Za": -0.213832,
    "Zq": 2.78189e-2,
    "Zde": 0.166147,
    "M0": 0.271618,
    "Ma": -2.73646,
    "Mq": -1.08034,
    "Mde": -3.18940,
}


def f(t, x, u, theta):
    alpha, q = x[0], x[1]
    de = u[0]
    dx = np.empty(2)
    # α̇ = Z_0 + Z_α α + (1 + Z_q) q + Z_δe δe
    dx[0] = theta[0] + theta[1] * alpha + (1.0 + theta[2]) * q + theta[3] * de
    # q̇ = M_0 + M_α α + M_q q + M_δe δe
    dx[1] = theta[4] + theta[5] * alpha + theta[6] * q + theta[7] * de
    return dx


def h(t, x, u, theta):
    y = np.empty(2)
    y[0] = x[0]
    y[1] = x[1]
    return y
