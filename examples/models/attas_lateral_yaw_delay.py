"""ATTAS lateral-directional motion with a yaw-rate output delay (the book's TC31; set-up of
the reference tool, parameter names as it reports them: Lp … Yβ, BX1, BX2, BY1 … BY5).

    dp/dt = L_p p + L_r r + L_δa δa + L_δr δr + L_β β + BX1
    dr/dt = N_p p + N_r r + N_δa δa + N_δr δr + N_β β + BX2
    outputs ṗ_model + BY1, ṙ_model + BY2   (ṗ_model, ṙ_model: the right-hand sides without
                                             BX1, BX2)
            a_y = Y_p p + Y_r r + Y_δa δa + Y_δr δr + Y_β β + BY3,  p + BY4,  r + BY5

β is measured and used as an input. The case file delays the r output by tDelay_r
([model] output_delays, two-sample convention); a constant bias commutes with that delay,
so y5 = r(delayed) + BY5 as in the reference. Units: rad, rad/s, rad/s², m/s².
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
    "Lβ": -4.34076,
    "Np": -0.086939,
    "Nr": -0.169526,
    "Nda": -0.192049,
    "Ndr": -0.74855,
    "Nβ": 1.55155,
    "Yp": 0.0364,
    "Yr": 2.130,
    "Yda": 0.740,
    "Ydr": 2.279,
    "Yβ": -5.193,
    "BX1": 0.02,
    "BX2": 0.02,
    "BY1": 0.02,
    "BY2": 0.02,
    "BY3": 0.02,
    "BY4": 0.02,
    "BY5": 0.02,
}


def f(t, x, u, theta):
    p, r = x[0], x[1]
    da, dr, beta = u[0], u[1], u[2]
    dx = np.empty(2)
    # ṗ = L_p p + L_r r + L_δa δa + L_δr δr + L_β β + BX1
    dx[0] = (
        theta[0] * p + theta[1] * r + theta[2] * da + theta[3] * dr + theta[4] * beta + theta[15]
    )
    # ṙ = N_p p + N_r r + N_δa δa + N_δr δr + N_β β + BX2
    dx[1] = (
        theta[5] * p + theta[6] * r + theta[7] * da + theta[8] * dr + theta[9] * beta + theta[16]
    )
    return dx


def h(t, x, u, theta):
    p, r = x[0], x[1]
    da, dr, beta = u[0], u[1], u[2]
    y = np.empty(5)
    # ṗ_model + BY1, ṙ_model + BY2 (the right-hand sides without BX1, BX2)
    y[0] = theta[0] * p + theta[1] * r + theta[2] * da + theta[3] * dr + theta[4] * beta + theta[17]
    y[1] = theta[5] * p + theta[6] * r + theta[7] * da + theta[8] * dr + theta[9] * beta + theta[18]
    # a_y = Y_p p + Y_r r + Y_δa δa + Y_δr δr + Y_β β + BY3
    y[2] = (
        theta[10] * p
        + theta[11] * r
        + theta[12] * da
        + theta[13] * dr
        + theta[14] * beta
        + theta[19]
    )
    y[3] = p + theta[20]
    y[4] = r + theta[21]
    return y
