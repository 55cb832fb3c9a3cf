"""ATTAS lateral-directional motion, linear derivatives, one maneuver of
the ATTAS lateral flight data (FVSysID ``fAttasAilRud1``).

    dp/dt = L_p p + L_r r + L_δa δa + L_δr δr + L_β β
    dr/dt = N_p p + N_r r + N_δa δa + N_δr δr + N_β β
    outputs ṗ, ṙ (the right-hand sides), a_y = Y_p p + Y_r r + Y_δa δa + Y_δr δr + Y_β β,
    p, r

β is measured and used as an input. The state biases b_x and output biases b_y of the
standard case are not written here: the case file adds them ([biases.states],
[biases.outputs]), so ṗ, ṙ outputs carry b_y but not b_x, exactly as in the standard case.
Units: rad, rad/s, rad/s², m/s².
"""

import numpy as np

STATES = ("p", "r")
INPUTS = ("da", "dr", "beta")
OUTPUTS = ("pdot", "rdot", "ay", "p", "r")
PARAMETERS = {
    "Lp": -3.53744,
    "Lr": 0.475534,
    "Lda": -4.93279,
    "Ldr": 0.73334,
    "Lbeta": -4.34076,
    "Np": -0.086939,
    "Nr": -0.169526,
    "Nda": -0.192049,
    "Ndr": -0.74855,
    "Nbeta": 1.55155,
    "Yp": 0.0364,
    "Yr": 2.130,
    "Yda": 0.740,
    "Ydr": 2.279,
    "Ybeta": -5.193,
}


def f(t, x, u, theta):
    p, r = x[0], x[1]
    da, dr, beta = u[0], u[1], u[2]
    dx = np.empty(2)
    # ṗ = L_p p + L_r r + L_δa δa + L_δr δr + L_β β
    dx[0] = theta[0] * p + theta[1] * r + theta[2] * da + theta[3] * dr + theta[4] * beta
    # ṙ = N_p p + N_r r + N_δa δa + N_δr δr + N_β β
    dx[1] = theta[5] * p + theta[6] * r + theta[7] * da + theta[8] * dr + theta[9] * beta
    return dx


def h(t, x, u, theta):
    p, r = x[0], x[1]
    da, dr, beta = u[0], u[1], u[2]
    y = np.empty(5)
    y[0] = theta[0] * p + theta[1] * r + theta[2] * da + theta[3] * dr + theta[4] * beta
    y[1] = theta[5] * p + theta[6] * r + theta[7] * da + theta[8] * dr + theta[9] * beta
    # a_y = Y_p p + Y_r r + Y_δa δa + Y_δr δr + Y_β β
    y[2] = theta[10] * p + theta[11] * r + theta[12] * da + theta[13] * dr + theta[14] * beta
    y[3] = p
    y[4] = r
    return y
