"""Unstable aircraft, short-period motion (the book's unstable-aircraft case, data
``fvsysid/unStabAC_sim.asc``).

Basic model (states w, q; input δe; u0 = 44.5695 m/s constant):

    dw/dt = Z_w w + (u0 + Z_q) q + Z_δe δe
    dq/dt = M_w w + M_q q + M_δe δe
    outputs a_z = Z_w w + Z_q q + Z_δe δe,  w,  q

Units: w in m/s, q in rad/s, δe in rad, a_z in m/s². Parameters are named as the book writes
them (Zδe, Mδe; the reference code calls them zeta, meta); start values are the reference's.
Zq is fixed at −1.4768 by the case files, not here.
"""

import numpy as np

# Constant forward speed u0 (m/s), the reference's value.
U0 = 44.5695

STATES = ("w", "q")
INPUTS = ("de",)
OUTPUTS = ("az", "w", "q")
PARAMETERS = {
    "Zw": -1.22871,
    "Zq": -1.4768,
    "Zδe": -4.20491,
    "Mw": 0.116197,
    "Mq": -2.70670,
    "Mδe": -18.7718,
}


def f(t, x, u, theta):
    w, q = x[0], x[1]
    de = u[0]
    dx = np.empty(2)
    # ẇ = Z_w w + (u0 + Z_q) q + Z_δe δe
    dx[0] = theta[0] * w + (U0 + theta[1]) * q + theta[2] * de
    # q̇ = M_w w + M_q q + M_δe δe
    dx[1] = theta[3] * w + theta[4] * q + theta[5] * de
    return dx


def h(t, x, u, theta):
    w, q = x[0], x[1]
    de = u[0]
    y = np.empty(3)
    # a_z = Z_w w + Z_q q + Z_δe δe
    y[0] = theta[0] * w + theta[1] * q + theta[2] * de
    y[1] = w
    y[2] = q
    return y
