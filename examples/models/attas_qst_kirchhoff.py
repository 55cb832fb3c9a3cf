"""ATTAS quasi-steady stall with Kirchhoff flow separation (the book's TC27).

No states: the outputs are algebraic in the measured inputs δe (rad), q (rad/s, raw),
α (rad, smoothed), V (m/s, smoothed), α̇ (rad/s) and Mach:

    q*     = q c̄ / V                                  (full chord, as the reference)
    CLde   = −Cmde c̄ / 15                            (15 m: elevator–wing distance)
    C_Llin = CL0 + (CLal + CLMa Mach) α + CLde δe
    C_Dlin = CD0 + C_Llin² / (Efak π 7.22)
    C_mlin = Cm0 + Cmal α + Cmq q* + Cmde δe
    τ      = 0 if α̇ > 0, else Tau2 c̄ / V             (the lag acts only while α decreases)
    X      = ½ [1 − tanh(A1 (α − τ α̇ − AlStar))]      (flow separation point, 1 attached)
    C_L    = C_Llin + CLal α (((1 + √X)/2)² − 1)
    C_D    = C_Dlin + CD_X0 (1 − X)
    C_m    = C_mlin + CM_X0 (1 − X)

AlStar in rad. Parameters in the reference's order with its start values (all 14 free).
"""

import math

import numpy as np

STATES = ()
INPUTS = ("de", "q", "alpha", "V", "alpha_dot", "Mach")
OUTPUTS = ("CD", "CL", "Cm")
PARAMETERS = {
    "CD0": 0.05,
    "Efak": 1.0,
    "CL0": 0.25,
    "CLal": 5.0,
    "CLMa": 0.0,
    "Cm0": 0.22,
    "Cmal": -1.2,
    "Cmq": -11.0,
    "Cmde": -1.8,
    "A1": 35.0,
    "AlStar": 0.29,
    "Tau2": 21.0,
    "CD_X0": 0.05,
    "CM_X0": -0.1,
}

CBAR = 3.159  # m
ASPECT_RATIO = 7.22
ELEVATOR_ARM = 15.0  # m, elevator–wing distance


def h(t, x, u, theta):
    de, q, alpha, V, alpha_dot, mach = u[0], u[1], u[2], u[3], u[4], u[5]
    CD0, Efak, CL0, CLal, CLMa = theta[0], theta[1], theta[2], theta[3], theta[4]
    Cm0, Cmal, Cmq, Cmde = theta[5], theta[6], theta[7], theta[8]
    A1, AlStar, Tau2, CD_X0, CM_X0 = theta[9], theta[10], theta[11], theta[12], theta[13]
    # q* = q c̄ / V
    qs = q * CBAR / V
    # CLde = −Cmde c̄ / 15
    CLde = -Cmde * CBAR / ELEVATOR_ARM
    # C_Llin = CL0 + (CLal + CLMa Mach) α + CLde δe
    CLlin = CL0 + (CLal + CLMa * mach) * alpha + CLde * de
    # C_Dlin = CD0 + C_Llin² / (Efak π 7.22)
    CDlin = CD0 + CLlin * CLlin / (Efak * math.pi * ASPECT_RATIO)
    # C_mlin = Cm0 + Cmal α + Cmq q* + Cmde δe
    Cmlin = Cm0 + Cmal * alpha + Cmq * qs + Cmde * de
    # τ = 0 if α̇ > 0, else Tau2 c̄ / V
    tau = 0.0 if alpha_dot > 0.0 else Tau2 * CBAR / V
    # X = ½ [1 − tanh(A1 (α − τ α̇ − AlStar))]
    X = 0.5 * (1.0 - math.tanh(A1 * (alpha - tau * alpha_dot - AlStar)))
    y = np.empty(3)
    # C_D = C_Dlin + CD_X0 (1 − X)
    y[0] = CDlin + CD_X0 * (1.0 - X)
    # C_L = C_Llin + CLal α (((1 + √X)/2)² − 1)
    s = 0.5 * (1.0 + math.sqrt(X))
    y[1] = CLlin + CLal * alpha * (s * s - 1.0)
    # C_m = C_mlin + CM_X0 (1 − X)
    y[2] = Cmlin + CM_X0 * (1.0 - X)
    return y
