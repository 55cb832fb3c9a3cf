"""ATTAS lateral-directional motion with constant terms, outputs p and r,
for the two ATTAS lateral maneuvers (aileron and rudder inputs) estimated together.

    dp/dt = L_p p + L_r r + L_δa δa + L_δr δr + L_β β + L_0
    dr/dt = N_p p + N_r r + N_δa δa + N_δr δr + N_β β + N_0
    outputs p, r (rad/s); β measured, used as an input.
"""

import numpy as np

STATES = ("p", "r")
INPUTS = ("da", "dr", "beta")
OUTPUTS = ("p", "r")
PARAMETERS = {
    "Lp": -3.53744,
    "Lr": 0.675534,
    "Lda": -4.93279,
    "Ldr": 0.73334,
    "Lbeta": -4.34076,
    "L0": 6.50204e-3,
    "Np": -0.086939,
    "Nr": -0.169526,
    "Nda": -0.192049,
    "Ndr": -0.74855,
    "Nbeta": 2.05155,
    "N0": 1.98767e-2,
}


def f(t, x, u, theta):
    p, r = x[0], x[1]
    da, dr, beta = u[0], u[1], u[2]
    dx = np.empty(2)
    # ṗ = L_p p + L_r r + L_δa δa + L_δr δr + L_β β + L_0
    dx[0] = theta[0] * p + theta[1] * r + theta[2] * da + theta[3] * dr + theta[4] * beta + theta[5]
    # ṙ = N_p p + N_r r + N_δa δa + N_δr δr + N_β β + N_0
    dx[1] = (
        theta[6] * p + theta[7] * r + theta[8] * da + theta[9] * dr + theta[10] * beta + theta[11]
    )
    return dx


def h(t, x, u, theta):
    y = np.empty(2)
    y[0] = x[0]
    y[1] = x[1]
    return y
