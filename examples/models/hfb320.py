"""HFB-320 longitudinal motion in wind axes, with thrust (the HFB-320
longitudinal flight data of FVSysID, ``hfb320_1_10.asc``).

States V (m/s), α (rad), Θ (rad), q (rad/s); inputs δe (rad) and thrust F (N); outputs V, α,
Θ, q, q̇ (rad/s²), a_x, a_z (m/s²). Aerodynamic model linear in V/V0, α, q and δe:

    C_D = C_D0 + C_DV·V/V0 + C_Dα·α
    C_L = C_L0 + C_LV·V/V0 + C_Lα·α
    C_m = C_m0 + C_mV·V/V0 + C_mα·α + C_mq·q·(c̄/2)/V0 + C_mδe·δe

Written with module-level constants and plain arithmetic so that numba compiles f and h.
"""

import math

import numpy as np

STATES = ("V", "alpha", "theta", "q")
INPUTS = ("de", "F")
OUTPUTS = ("V", "alpha", "theta", "q", "qdot", "ax", "az")

# name: start value (the standard case's start values; the case file may override them)
PARAMETERS = {
    "CD0": 5.67516e-3,
    "CDV": 7.72612e-3,
    "CDa": 6.74256e-1,
    "CL0": -3.18267e-1,
    "CLV": 2.60317e-1,
    "CLa": 5.37576,
    "Cm0": 4.98218e-2,
    "CmV": 1.89182e-2,
    "Cma": -4.98586e-1,
    "Cmq": -2.58439e1,
    "Cmde": -9.90687e-1,
}

# Airplane constants of the standard case (README: m = 7472 kg, S = 30.097 m², c̄ = 2.43 m,
# I_y = 9.142e4 kg·m², σ_T = 0.0524 rad, ρ = 0.792 kg/m³, V0 = 104.67 m/s).
G = 9.80665  # m/s²
MASS = 7472.0  # kg
RHO = 0.792  # kg/m³
V0 = 104.67  # m/s
SIGMA_T = 0.0524  # rad, thrust inclination
S_OVER_M = 4.028e-3  # m²/kg
SC_OVER_IY = 8.0027e-4  # m³/(kg·m²)
LT_OVER_IY = -7.0153e-6  # 1/(kg·m), thrust moment arm / I_y
HALF_CHORD = 1.215  # m, c̄/2


def f(t, x, u, theta):
    V, alpha, th, q = x[0], x[1], x[2], x[3]
    thrust = u[1]
    v_rel = V / V0
    # C_D, C_L, C_m (README, "HFB-320 longitudinal"); θ in the order of PARAMETERS
    cd = theta[0] + theta[1] * v_rel + theta[2] * alpha
    cl = theta[3] + theta[4] * v_rel + theta[5] * alpha
    cm = theta[6] + theta[7] * v_rel + theta[8] * alpha + theta[9] * q * HALF_CHORD / V0
    cm += theta[10] * u[0]
    qbar = 0.5 * RHO * V * V
    dx = np.empty(4)
    # dV/dt = −(S/m) q̄ C_D + F cos(α + σ_T)/m + g sin(α − Θ)
    dx[0] = (
        -S_OVER_M * qbar * cd + thrust * math.cos(alpha + SIGMA_T) / MASS + G * math.sin(alpha - th)
    )
    # dα/dt = −(S/m) q̄ C_L / V − F sin(α + σ_T)/(m V) + q + g cos(α − Θ)/V
    dx[1] = (
        -S_OVER_M * qbar * cl / V
        - thrust * math.sin(alpha + SIGMA_T) / (MASS * V)
        + q
        + G * math.cos(alpha - th) / V
    )
    # dΘ/dt = q
    dx[2] = q
    # dq/dt = (S c̄ / I_y) q̄ C_m + (l_T / I_y) F
    dx[3] = SC_OVER_IY * qbar * cm + LT_OVER_IY * thrust
    return dx


def h(t, x, u, theta):
    V, alpha, th, q = x[0], x[1], x[2], x[3]
    thrust = u[1]
    v_rel = V / V0
    # C_D, C_L, C_m (README, "HFB-320 longitudinal"); θ in the order of PARAMETERS
    cd = theta[0] + theta[1] * v_rel + theta[2] * alpha
    cl = theta[3] + theta[4] * v_rel + theta[5] * alpha
    cm = theta[6] + theta[7] * v_rel + theta[8] * alpha + theta[9] * q * HALF_CHORD / V0
    cm += theta[10] * u[0]
    qbar = 0.5 * RHO * V * V
    # C_X = C_L sin α − C_D cos α,  C_Z = −C_L cos α − C_D sin α
    cx = cl * math.sin(alpha) - cd * math.cos(alpha)
    cz = -cl * math.cos(alpha) - cd * math.sin(alpha)
    y = np.empty(7)
    y[0] = V
    y[1] = alpha
    y[2] = th
    y[3] = q
    # q̇ = dq/dt
    y[4] = SC_OVER_IY * qbar * cm + LT_OVER_IY * thrust
    # a_x = (S/m) q̄ C_X + F cos σ_T / m,  a_z = (S/m) q̄ C_Z − F sin σ_T / m
    y[5] = S_OVER_M * qbar * cx + thrust * math.cos(SIGMA_T) / MASS
    y[6] = S_OVER_M * qbar * cz - thrust * math.sin(SIGMA_T) / MASS
    return y
