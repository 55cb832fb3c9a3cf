"""The Navion 6-DOF model of ``bench/kernel.py`` written as a user model module.

The same equations as the hand-written kernel there (``flightid.aircraft.equations``:
[2.5–2.16], [2.19–2.23]), written the way docs/models.md and ``flightid.cases.usermodel``
document a model module: ``f`` and ``h`` return new arrays (``return np.array([...])``),
constants at module level. States u, v, w (m/s), p, q, r (rad/s), l_xz, l_yz, l_zz (-, the
direction cosines of the weight); inputs de, dr, da (rad), thrust (N); outputs V (m/s),
α, β, Θ, Φ (rad), p, q, r (rad/s); 22 aerodynamic derivatives (per rad).
"""

import math

import numpy as np

from flightid.aircraft import navion

STATES = ("u", "v", "w", "p", "q", "r", "l_xz", "l_yz", "l_zz")
INPUTS = ("de", "dr", "da", "thrust")
OUTPUTS = ("V", "alpha", "beta", "theta", "phi", "p", "q", "r")
PARAMETERS = [
    "CD_0", "CD_alpha",
    "CL_0", "CL_alpha", "CL_qhat", "CL_de",
    "Cm_0", "Cm_alpha", "Cm_qhat", "Cm_de",
    "CY_beta", "CY_dr",
    "Cl_beta", "Cl_phat", "Cl_rhat", "Cl_da", "Cl_dr",
    "Cn_beta", "Cn_phat", "Cn_rhat", "Cn_da", "Cn_dr",
]  # fmt: skip

# the Navion's mass (kg), inertias (kg m²), S (m²), b, c̄ (m), ρ (kg/m³), g (m/s²), thrust
# inclination α_T (rad) and thrust moment arm l_T (m), read from flightid.aircraft.navion()
_NAVION = navion()
MASS = float(_NAVION.mass)
IX = float(_NAVION.Ix)
IY = float(_NAVION.Iy)
IZ = float(_NAVION.Iz)
IXZ = float(_NAVION.Ixz)
AREA = float(_NAVION.S)
SPAN = float(_NAVION.b)
CHORD = float(_NAVION.cbar)
RHO = float(_NAVION.rho)
G = float(_NAVION.g)
THRUST_INCLINATION = float(_NAVION.thrust_inclination)
THRUST_ARM = float(_NAVION.thrust_moment_arm)


def f(t, x, u, theta):
    """dx/dt [2.5–2.13]."""
    uu, v, w, p, q, r = x[0], x[1], x[2], x[3], x[4], x[5]
    lxz, lyz, lzz = x[6], x[7], x[8]
    de, dr, da, thrust = u[0], u[1], u[2], u[3]
    V = math.sqrt(uu * uu + v * v + w * w)
    alpha = math.atan2(w, uu)
    beta = math.asin(v / V)
    # p̂ = p b/2V, q̂ = q c̄/2V, r̂ = r b/2V
    phat = p * SPAN / (2.0 * V)
    qhat = q * CHORD / (2.0 * V)
    rhat = r * SPAN / (2.0 * V)
    CD = theta[0] + theta[1] * alpha
    CL = theta[2] + theta[3] * alpha + theta[4] * qhat + theta[5] * de
    Cm = theta[6] + theta[7] * alpha + theta[8] * qhat + theta[9] * de
    CY = theta[10] * beta + theta[11] * dr
    Cl = theta[12] * beta + theta[13] * phat + theta[14] * rhat + theta[15] * da + theta[16] * dr
    Cn = theta[17] * beta + theta[18] * phat + theta[19] * rhat + theta[20] * da + theta[21] * dr
    # q̄ S = ½ρV² S; forces and moments [2.14–2.15]
    qS = 0.5 * RHO * V * V * AREA
    sa = math.sin(alpha)
    ca = math.cos(alpha)
    X = qS * (CL * sa - CD * ca) + thrust * math.cos(THRUST_INCLINATION)
    Y = qS * CY
    Z = qS * (-CL * ca - CD * sa) - thrust * math.sin(THRUST_INCLINATION)
    L = qS * SPAN * Cl
    M = qS * CHORD * Cm + THRUST_ARM * thrust
    N = qS * SPAN * Cn
    gamma = IX * IZ - IXZ * IXZ
    F1 = (IY - IZ) * q * r + IXZ * p * q + L
    F2 = (IX - IY) * p * q - IXZ * q * r + N
    return np.array(
        [
            -q * w + r * v + G * lxz + X / MASS,
            -r * uu + p * w + G * lyz + Y / MASS,
            -p * v + q * uu + G * lzz + Z / MASS,
            (IZ * F1 + IXZ * F2) / gamma,
            ((IZ - IX) * p * r + IXZ * (r * r - p * p) + M) / IY,
            (IXZ * F1 + IX * F2) / gamma,
            r * lyz - q * lzz,
            -r * lxz + p * lzz,
            q * lxz - p * lyz,
        ]
    )


def h(t, x, u, theta):
    """(V, α, β, Θ, Φ, p, q, r) [2.19–2.23]."""
    V = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
    return np.array(
        [
            V,
            math.atan2(x[2], x[0]),
            math.asin(x[1] / V),
            math.asin(max(-1.0, min(1.0, -x[6]))),
            math.atan2(x[7], x[8]),
            x[3],
            x[4],
            x[5],
        ]
    )
