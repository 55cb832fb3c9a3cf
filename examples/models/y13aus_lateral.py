"""Lateral-directional motion in turbulence, y13aus_da1 (the book's TC02;
parameter names as the reference reports them: Lp … Yv, BX1, BX2, BY1 … BY5).

    dp/dt = L_p p + L_r r + L_δa δa + L_δr δr + L_v v + BX1
    dr/dt = N_p p + N_r r + N_δa δa + N_δr δr + N_v v + BX2
    outputs ṗ_model + BY1, ṙ_model + BY2   (ṗ_model, ṙ_model: the right-hand sides without
                                             BX1, BX2)
            a_y = Y_p p + Y_r r + Y_δa δa + Y_δr δr + Y_v v + BY3,  p + BY4,  r + BY5

The lateral velocity v is measured and used as an input. The start values are those of
the reference's case. Units: rad, rad/s, rad/s², m/s, m/s².
"""

import numpy as np

STATES = ("p", "r")
INPUTS = ("da", "dr", "v")
OUTPUTS = ("pdot", "rdot", "ay", "p", "r")
PARAMETERS = {
    "Lp": -6.7,
    "Lr": 1.83,
    "Lda": -18.3,
    "Ldr": 0.43,
    "Lv": -0.114,
    "Np": -0.906,
    "Nr": -0.665,
    "Nda": -0.66,
    "Ndr": -2.82,
    "Nv": 0.0069,
    "Yp": -0.64,
    "Yr": 1.30,
    "Yda": -1.40,
    "Ydr": 2.79,
    "Yv": -0.193,
    "BX1": 0.08,
    "BX2": -0.089,
    "BY1": 0.08,
    "BY2": -0.089,
    "BY3": 0.044,
    "BY4": -0.0034,
    "BY5": -0.0015,
}


def f(t, x, u, theta):
    p, r = x[0], x[1]
    da, dr, v = u[0], u[1], u[2]
    dx = np.empty(2)
    # ṗ = L_p p + L_r r + L_δa δa + L_δr δr + L_v v + BX1
    dx[0] = theta[0] * p + theta[1] * r + theta[2] * da + theta[3] * dr + theta[4] * v + theta[15]
    # ṙ = N_p p + N_r r + N_δa δa + N_δr δr + N_v v + BX2
    dx[1] = theta[5] * p + theta[6] * r + theta[7] * da + theta[8] * dr + theta[9] * v + theta[16]
    return dx


def h(t, x, u, theta):
    p, r = x[0], x[1]
    da, dr, v = u[0], u[1], u[2]
    y = np.empty(5)
    # y1 = ṗ_model + BY1, y2 = ṙ_model + BY2 (the right-hand sides without BX1, BX2)
    y[0] = theta[0] * p + theta[1] * r + theta[2] * da + theta[3] * dr + theta[4] * v + theta[17]
    y[1] = theta[5] * p + theta[6] * r + theta[7] * da + theta[8] * dr + theta[9] * v + theta[18]
    # y3 = a_y = Y_p p + Y_r r + Y_δa δa + Y_δr δr + Y_v v + BY3
    y[2] = theta[10] * p + theta[11] * r + theta[12] * da + theta[13] * dr + theta[14] * v
    y[2] += theta[19]
    # y4 = p + BY4, y5 = r + BY5
    y[3] = p + theta[20]
    y[4] = r + theta[21]
    return y
