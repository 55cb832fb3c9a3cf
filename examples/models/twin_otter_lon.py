"""NASA Twin Otter longitudinal short-period model for output error
(SIDPAC's Twin Otter flight data: α and q integrated, other states measured).

States α (rad), q (rad/s). Inputs: Δδe (rad, elevator about its first sample), V (m/s),
Θ, Φ (rad), a_x (m/s², measured specific force), q̄ (Pa), and α_m, Δα_m (rad: measured α and
measured α about its first sample; their difference is the reference α_0 of the maneuver).
Outputs α, q and a_z (g).

    Δα  = α − α_0,   q̂ = q c̄ / (2V)
    C_Z = C_Zα Δα + C_Zδe Δδe + C_Zo
    C_m = C_mα Δα + C_mq q̂ + C_mδe Δδe + C_mo
    A_z = q̄ S C_Z / m                                   (specific force along z, m/s²)
    dα/dt = q + [cos α (g cos Θ cos Φ + A_z) + sin α (g sin Θ − A_x)] / V
    dq/dt = q̄ S c̄ C_m / I_y
    a_z = A_z / g

The α equation is α̇ = (u ẇ − w u̇)/V² with β ≈ 0, v ≈ 0 and the body-axis force equations
(u̇ = −q w − g sin Θ + A_x, ẇ = q u + g cos Θ cos Φ + A_z). Mass properties and geometry are
those stored in totter_lon_020213f1_018.mat (mass 338.7861 slug, I_yy 24273 slug·ft²,
S 422.483473 ft², c̄ 6.496063 ft), converted to SI.
"""

import math

import numpy as np

STATES = ("alpha", "q")
INPUTS = ("de", "V", "theta", "phi", "ax", "qbar", "alpha_m", "dalpha_m")
OUTPUTS = ("alpha", "q", "az")
# start values: equation-error least squares on maneuver 018 (C_Z, C_m channels), rounded
PARAMETERS = {
    "CZa": -6.6,
    "CZde": -0.19,
    "CZo": -0.45,
    "Cma": -1.5,
    "Cmq": -36.0,
    "Cmde": -1.9,
    "Cmo": 0.0,
}

G = 9.80665  # m/s²
SLUG = 14.5939029372  # kg
FT = 0.3048  # m
MASS = 338.7861 * SLUG  # kg
IYY = 24273.0 * SLUG * FT * FT  # kg·m²
S = 422.483473 * FT * FT  # m²
CBAR = 6.496063 * FT  # m


def f(t, x, u, theta):
    alpha, q = x[0], x[1]
    dde, V, th, ph, ax, qbar = u[0], u[1], u[2], u[3], u[4], u[5]
    alpha0 = u[6] - u[7]
    dalpha = alpha - alpha0
    qhat = q * CBAR / (2.0 * V)
    cz = theta[0] * dalpha + theta[1] * dde + theta[2]
    cm = theta[3] * dalpha + theta[4] * qhat + theta[5] * dde + theta[6]
    az = qbar * S * cz / MASS
    dx = np.empty(2)
    # dα/dt = q + [cos α (g cos Θ cos Φ + A_z) + sin α (g sin Θ − A_x)] / V
    dx[0] = (
        q
        + (
            math.cos(alpha) * (G * math.cos(th) * math.cos(ph) + az)
            + math.sin(alpha) * (G * math.sin(th) - ax)
        )
        / V
    )
    # dq/dt = q̄ S c̄ C_m / I_y
    dx[1] = qbar * S * CBAR * cm / IYY
    return dx


def h(t, x, u, theta):
    alpha, q = x[0], x[1]
    dde, qbar = u[0], u[5]
    alpha0 = u[6] - u[7]
    cz = theta[0] * (alpha - alpha0) + theta[1] * dde + theta[2]
    y = np.empty(3)
    y[0] = alpha
    y[1] = q
    # a_z = q̄ S C_Z / (m g)
    y[2] = qbar * S * cz / (MASS * G)
    return y
