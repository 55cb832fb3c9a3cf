"""Fixed-wing roll mode (roll subsidence) with the roll angle.

ṗ = L_p p + L_δa δa,  φ̇ = p
states p (rad/s), phi (rad); input da (rad, aileron); outputs p (rad/s), phi (rad).
"""

import numpy as np

STATES = ("p", "phi")
INPUTS = ("da",)
OUTPUTS = ("p", "phi")
PARAMETERS = {"Lp": -2.0, "Lda": 15.0}  # start values: L_p (1/s), L_δa (1/s²)


def f(t, x, u, theta):
    dx = np.empty(2)
    # ṗ = L_p p + L_δa δa
    dx[0] = theta[0] * x[0] + theta[1] * u[0]
    # φ̇ = p
    dx[1] = x[0]
    return dx


def h(t, x, u, theta):
    y = np.empty(2)
    y[0] = x[0]
    y[1] = x[1]
    return y
