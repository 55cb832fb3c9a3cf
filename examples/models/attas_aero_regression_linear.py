"""ATTAS aerodynamic model from measured coefficients, linear (the book's TC23).

No states: each output is an algebraic function of the measured inputs (rad, rad/s, m/s),

    C_D = CD0 + CDal α
    C_L = CL0 + CLal α
    C_m = Cm0 + Cmal α + Cmq q* + Cmde δe
    C_Y = CY0 + CYbe β
    C_l = Cl0 + Clbe β + Clp p* + Clr r* + Clda δa
    C_n = Cn0 + Cnbe β + Cnp p* + Cnr r* + Cndr δr

with p* = p (b/2)/V, q* = q c̄/V (full chord, as the reference uses), r* = r (b/2)/V, b/2 = 10.75 m,
c̄ = 3.159 m. Parameters in the reference's order, all starting at 0.
"""

import numpy as np

STATES = ()
INPUTS = ("de", "da", "dr", "p", "q", "r", "alpha", "beta", "V")
OUTPUTS = ("CD", "CL", "Cm", "CY", "Cl", "Cn")
PARAMETERS = {
    name: 0.0
    for name in (
        "CD0 CDal CY0 CYbe CL0 CLal Cl0 Clbe Clp Clr Clda Cm0 Cmal Cmq Cmde Cn0 Cnbe Cnp Cnr Cndr"
    ).split()
}

B_HALF = 10.75  # m, lateral reference length b/2
CBAR = 3.159  # m


def h(t, x, u, theta):
    de, da, dr, p, q, r, alpha, beta, V = u[0], u[1], u[2], u[3], u[4], u[5], u[6], u[7], u[8]
    # reduced rates p* = p (b/2)/V, q* = q c̄/V, r* = r (b/2)/V
    ps = p * B_HALF / V
    qs = q * CBAR / V
    rs = r * B_HALF / V
    y = np.empty(6)
    # C_D = CD0 + CDal α
    y[0] = theta[0] + theta[1] * alpha
    # C_L = CL0 + CLal α
    y[1] = theta[4] + theta[5] * alpha
    # C_m = Cm0 + Cmal α + Cmq q* + Cmde δe
    y[2] = theta[11] + theta[12] * alpha + theta[13] * qs + theta[14] * de
    # C_Y = CY0 + CYbe β
    y[3] = theta[2] + theta[3] * beta
    # C_l = Cl0 + Clbe β + Clp p* + Clr r* + Clda δa
    y[4] = theta[6] + theta[7] * beta + theta[8] * ps + theta[9] * rs + theta[10] * da
    # C_n = Cn0 + Cnbe β + Cnp p* + Cnr r* + Cndr δr
    y[5] = theta[15] + theta[16] * beta + theta[17] * ps + theta[18] * rs + theta[19] * dr
    return y
