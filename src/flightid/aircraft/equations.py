"""Rigid-body equations of motion of an airplane, in a form numba compiles and Python runs.

Body axes, rigid body, XZ plane of symmetry, no spinning rotors, flat non-rotating earth
[RP-1153 2.5–2.15]. The attitude is carried by the three direction cosines of the body axes
with respect to the local vertical,

    l_xz = −sin Θ,   l_yz = sin Φ cos Θ,   l_zz = cos Φ cos Θ,

and the body state is X = (u, v, w, p, q, r, l_xz, l_yz, l_zz) (m/s, rad/s, –). With
q̄ = ½ρV², F = (X, Y, Z) the aerodynamic plus thrust force and (L, M, N) the moments:

    du/dt = −q w + r v + g l_xz + X/m                                   [2.5]
    dv/dt = −r u + p w + g l_yz + Y/m                                   [2.6]
    dw/dt = −p v + q u + g l_zz + Z/m                                   [2.7]
    dp/dt = (I_z F1 + I_xz F2)/Γ                                        [2.8]
    dq/dt = ((I_z − I_x) p r + I_xz (r² − p²) + M)/I_y                  [2.9]
    dr/dt = (I_xz F1 + I_x F2)/Γ                                        [2.10]
    F1 = (I_y − I_z) q r + I_xz p q + L,   F2 = (I_x − I_y) p q − I_xz q r + N
    Γ = I_x I_z − I_xz²
    dl_xz/dt = r l_yz − q l_zz                                          [2.11]
    dl_yz/dt = −r l_xz + p l_zz                                         [2.12]
    dl_zz/dt = q l_xz − p l_yz                                          [2.13]

Forces from the coefficients, thrust T inclined α_T above the body x axis [2.14–2.15]:

    X = q̄ S (C_X + C_L sin α − C_D cos α) + T cos α_T
    Y = q̄ S C_Y
    Z = q̄ S (C_Z − C_L cos α − C_D sin α) − T sin α_T
    L = q̄ S b C_l,   M = q̄ S c̄ C_m,   N = q̄ S b C_n

(a model gives either C_X, C_Z or C_D, C_L; the absent ones are zero).

Thrust moment and engine (``engine_loads``; Airplane docstring): M += l_T T; a rotor of
angular momentum h_E along body x adds −ω × h_E, i.e. M −= r h_E, N += q h_E; the propeller
shaft torque Q adds the rolling moment L −= s Q.

Outputs [2.19–2.26]: V = √(u²+v²+w²), α = atan(w/u), β = asin(v/V), Θ = asin(−l_xz),
Φ = atan(l_yz/l_zz) (four-quadrant), a_x,y,z = (X, Y, Z)/(m g) in g units, p, q, r, and the
angular accelerations ṗ, q̇, ṙ (rad/s², the right-hand sides [2.8–2.10]).

Signals of the aerodynamic terms (``SIGNALS``): besides the state variables, the
non-dimensional rates p̂ = p b/(2V_n), q̂ = q c̄/(2V_n), r̂ = r b/(2V_n), α̇̂ = α̇ c̄/(2V_n),
β̇̂ = β̇ b/(2V_n), with V_n = V (default) or the reference speed V0 (``rate_speed = "V0"``),
and the speed ratios V/V0 (``Vrel``) and (V − V0)/V0 (``dVrel``).

α̇ and β̇ terms make the equations implicit: the coefficients depend on α̇ = (u ẇ − w u̇)/(u²+w²)
and β̇ = (v̇ (u²+w²) − v (u u̇ + w ẇ))/(V² √(u²+w²)), which depend on the forces. The terms are
linear in α̇̂ and β̇̂ (power 1, enforced), so every derivative is affine in (α̇, β̇):
D = D0 + α̇ D_α + β̇ D_β, with D0 the derivatives at α̇ = β̇ = 0 and D_α, D_β the responses
to a unit rate. The kinematic relations then give the 2×2 linear system

    (1 − a_α) α̇ − a_β β̇ = a_0,   −b_α α̇ + (1 − b_β) β̇ = b_0

(a_•, b_• the kinematic α̇, β̇ of D0, D_α, D_β), solved in closed form (Cramer) in
``solve_rate_terms``; the wind-axis form has α̇ = D[1] directly: α̇ = D0[1]/(1 − D_α[1]).

Wind-axis longitudinal form (states V, α, Θ, q; β = Φ = p = r = 0), obtained from the body
equations with u = V cos α, w = V sin α:

    dV/dt = (X cos α + Z sin α)/m − g sin(Θ − α)
    dα/dt = q + (Z cos α − X sin α)/(m V) + g cos(Θ − α)/V
    dΘ/dt = q
    dq/dt = M / I_y

α–q longitudinal form (states α, q; V, q̄, Θ, Φ, a_x (g), p, r measured inputs; body axes,
β ≈ 0, thrust carried by the measured a_x, RP-1153 §2.A). With u = V cos α, w = V sin α, the α̇
line is (u ẇ − w u̇)/V² with u̇, ẇ from [2.5], [2.7], in which X/m = g a_x and
Z = q̄ S C_Z:

    dα/dt = q + (q̄ S/(m V)) C_Z cos α − (g a_x/V) sin α + (g/V)(cos Φ cos Θ cos α + sin Θ sin α)
    dq/dt = (q̄ S c̄ C_m + (I_z − I_x) p r + I_xz (r² − p²))/I_y                     [2.9]
    a_z = q̄ S C_Z/(m g)                                                          [2.26]

(q̄ is the measured dynamic pressure, not ½ρV², so ρ is not used; the terms of C_Z and C_m
see the signals α, q̂ = q c̄/(2V) and the inputs, ``alpha_q_signals``).

Every function here is decorated with ``register_jitable``: called from Python it is plain
Python, called from a numba-compiled model function it is compiled inline. The functions that
return an array have an ``_into`` twin writing into a caller's array (the same arithmetic),
from which the models' out-form functions are built without any allocation per call.
"""

from __future__ import annotations

import math

import numpy as np
from numba.extending import register_jitable

__all__ = [
    "SIGNALS",
    "BODY_STATES",
    "OUTPUTS",
    "CONSTANTS",
    "signals_from_body",
    "aero_coefficients",
    "forces_and_moments",
    "rigid_body_derivatives",
    "body_outputs",
    "wind_axis_derivatives",
    "EXTRA_CONSTANTS",
    "engine_loads",
    "alpha_rate",
    "beta_rate",
    "solve_rate_terms",
    "ALPHA_Q_INPUTS",
    "ALPHA_Q_OUTPUTS",
    "alpha_q_signals",
    "alpha_q_derivatives",
    "alpha_q_outputs",
    "signals_from_body_into",
    "aero_coefficients_into",
    "forces_and_moments_into",
    "rigid_body_derivatives_into",
    "body_outputs_into",
    "wind_axis_derivatives_into",
    "alpha_q_signals_into",
    "alpha_q_derivatives_into",
    "alpha_q_outputs_into",
]

# Body state X, in order.
BODY_STATES = ("u", "v", "w", "p", "q", "r", "l_xz", "l_yz", "l_zz")
# Standard signals available to aerodynamic terms; model inputs not listed here follow them.
SIGNALS = (
    "V", "alpha", "beta", "u", "v", "w", "p", "q", "r", "phat", "qhat", "rhat", "theta", "phi",
    "Vrel", "dVrel", "alphadot_hat", "betadot_hat",
)  # fmt: skip
N_STANDARD_SIGNALS = len(SIGNALS)
# positions of α̇̂ and β̇̂ in the signal vector
ALPHADOT_SIGNAL = SIGNALS.index("alphadot_hat")
BETADOT_SIGNAL = SIGNALS.index("betadot_hat")
# Full output vector, in order; models pick a subset.
OUTPUTS = (
    "V", "alpha", "beta", "theta", "phi", "ax", "ay", "az", "p", "q", "r", "pdot", "qdot", "rdot",
)  # fmt: skip
# Measured inputs of the α–q form, first in its input vector (controls follow), and its outputs.
ALPHA_Q_INPUTS = ("V", "qbar", "theta", "phi", "ax", "p", "r")
ALPHA_Q_OUTPUTS = ("alpha", "q", "az")
# Constant vector layout (closed over by the model functions).
CONSTANTS = ("mass", "Ix", "Iy", "Iz", "Ixz", "S", "b", "cbar", "rho", "g", "alpha_T")
# Second constant vector: thrust moment arm l_T (m), reference speed V0 (m/s, 0 if none),
# 1 if the rates are normalised with V0 (else V), rotor sense s (±1), constant I_p Ω (kg·m²/s).
EXTRA_CONSTANTS = ("thrust_arm", "V0", "rate_speed_V0", "rotation", "engine_momentum")


@register_jitable
def signals_from_body(X, U, extra_input, b, cbar, V0, rate_V0):
    """Signal vector (see ``SIGNALS``) from the body state X and the input vector U; the
    rates are normalised with V_n = V0 where ``rate_V0`` is 1, else V; α̇̂ = β̇̂ = 0 (set by
    ``solve_rate_terms``)."""
    sig = np.empty(18 + extra_input.shape[0])
    signals_from_body_into(X, U, extra_input, b, cbar, V0, rate_V0, sig)
    return sig


@register_jitable
def signals_from_body_into(X, U, extra_input, b, cbar, V0, rate_V0, sig):
    """``signals_from_body`` written into ``sig`` (18 + len(extra_input) entries)."""
    n_extra = extra_input.shape[0]
    u = X[0]
    v = X[1]
    w = X[2]
    # V = sqrt(u² + v² + w²)                                         [2.19]
    V = math.sqrt(u * u + v * v + w * w)
    sig[0] = V
    # α = atan(w/u)                                                   [2.21]
    sig[1] = math.atan2(w, u)
    # β = asin(v/V)                                                   [2.20]
    sig[2] = math.asin(v / V)
    sig[3] = u
    sig[4] = v
    sig[5] = w
    sig[6] = X[3]
    sig[7] = X[4]
    sig[8] = X[5]
    # V_n = V0 (rate_speed = "V0") or V
    Vn = V0 if rate_V0 > 0.5 else V
    # p̂ = p b/2V_n, q̂ = q c̄/2V_n, r̂ = r b/2V_n
    sig[9] = X[3] * b / (2.0 * Vn)
    sig[10] = X[4] * cbar / (2.0 * Vn)
    sig[11] = X[5] * b / (2.0 * Vn)
    # Θ = asin(−l_xz), Φ = atan(l_yz/l_zz)                           [2.22–2.23]
    sig[12] = math.asin(max(-1.0, min(1.0, -X[6])))
    sig[13] = math.atan2(X[7], X[8])
    sig[14] = 0.0
    sig[15] = 0.0
    if V0 > 0.0:
        # V/V0 and (V − V0)/V0
        sig[14] = V / V0
        sig[15] = (V - V0) / V0
    # α̇̂ = β̇̂ = 0 until solve_rate_terms
    sig[16] = 0.0
    sig[17] = 0.0
    for j in range(n_extra):
        sig[18 + j] = U[extra_input[j]]


@register_jitable
def aero_coefficients(
    sig, theta, term_coef, term_param, factor_start, factor_signal, factor_power, factor_spline,
    factor_knot,
):  # fmt: skip
    """Coefficient vector (CX, CY, CZ, CD, CL, Cl, Cm, Cn): C = Σ θ_k Π factor^power [2.16].

    The tables are those of ``flightid.aircraft.aero.AeroTables``; a factor is its signal x,
    the first-order spline (x − knot)₊ = max(x − knot, 0) where ``factor_spline`` is 1, or
    its absolute value |x| where it is 2.
    """
    C = np.empty(8)
    aero_coefficients_into(
        sig, theta, term_coef, term_param, factor_start, factor_signal, factor_power,
        factor_spline, factor_knot, C,
    )  # fmt: skip
    return C


@register_jitable
def aero_coefficients_into(
    sig, theta, term_coef, term_param, factor_start, factor_signal, factor_power, factor_spline,
    factor_knot, C,
):  # fmt: skip
    """``aero_coefficients`` written into ``C`` (8 entries)."""
    for i in range(8):
        C[i] = 0.0
    for k in range(term_coef.shape[0]):
        value = theta[term_param[k]]
        for j in range(factor_start[k], factor_start[k + 1]):
            x = sig[factor_signal[j]]
            if factor_spline[j] == 1:
                # (x − k)₊ = max(x − k, 0)
                x = max(x - factor_knot[j], 0.0)
            elif factor_spline[j] == 2:
                # |x|
                x = abs(x)
            value *= x ** factor_power[j]
        C[term_coef[k]] += value


@register_jitable
def forces_and_moments(C, alpha, V, thrust, consts):
    """Body-axis forces (X, Y, Z) in N and moments (L, M, N) in N·m [2.14–2.15]."""
    out = np.empty(6)
    forces_and_moments_into(C, alpha, V, thrust, consts, out)
    return out


@register_jitable
def forces_and_moments_into(C, alpha, V, thrust, consts, out):
    """``forces_and_moments`` written into ``out`` (6 entries)."""
    S = consts[5]
    # q̄ = ½ ρ V²
    qbar = 0.5 * consts[8] * V * V
    sa = math.sin(alpha)
    ca = math.cos(alpha)
    alpha_T = consts[10]
    # X = q̄S(C_X + C_L sin α − C_D cos α) + T cos α_T
    out[0] = qbar * S * (C[0] + C[4] * sa - C[3] * ca) + thrust * math.cos(alpha_T)
    # Y = q̄S C_Y
    out[1] = qbar * S * C[1]
    # Z = q̄S(C_Z − C_L cos α − C_D sin α) − T sin α_T
    out[2] = qbar * S * (C[2] - C[4] * ca - C[3] * sa) - thrust * math.sin(alpha_T)
    # L = q̄Sb C_l, M = q̄Sc̄ C_m, N = q̄Sb C_n
    out[3] = qbar * S * consts[6] * C[5]
    out[4] = qbar * S * consts[7] * C[6]
    out[5] = qbar * S * consts[6] * C[7]


@register_jitable
def engine_loads(F, X, U, thrust, torque_index, momentum_index, extra):
    """Add the thrust moment and the engine terms to the loads F (in place; Airplane docs):

    M += l_T T,   M −= r h_E,   N += q h_E,   L −= s Q,   h_E = s I_p Ω
    """
    # M_T = l_T T
    F[4] += extra[0] * thrust
    s = extra[3]
    # h_E = s I_p Ω, constant or from an input channel
    h = s * (U[momentum_index] if momentum_index >= 0 else extra[4])
    # −ω × h_E with h_E = (h, 0, 0): (0, −r h, q h)
    F[4] -= X[5] * h
    F[5] += X[4] * h
    if torque_index >= 0:
        # reaction of the propeller shaft torque on the airframe: L_E = −s Q
        F[3] -= s * U[torque_index]
    return F


@register_jitable
def alpha_rate(X, D):
    """α̇ = (u ẇ − w u̇)/(u² + w²) from the body state X and its derivative D (linear in D)."""
    u = X[0]
    w = X[2]
    return (u * D[2] - w * D[0]) / (u * u + w * w)


@register_jitable
def beta_rate(X, D, lateral):
    """β̇ = (v̇ (u²+w²) − v (u u̇ + w ẇ))/(V² √(u²+w²)) (linear in D); with ``lateral`` (u, w
    measured, their derivatives unknown) the u̇, ẇ part is left out: β̇ = v̇ √(u²+w²)/V²."""
    u = X[0]
    v = X[1]
    w = X[2]
    uw2 = u * u + w * w
    V2 = uw2 + v * v
    if lateral:
        return D[1] * math.sqrt(uw2) / V2
    return (D[1] * uw2 - v * (u * D[0] + w * D[2])) / (V2 * math.sqrt(uw2))


@register_jitable
def solve_rate_terms(a0, a_alpha, a_beta, b0, b_alpha, b_beta):
    """(α̇, β̇) of the linear system (1 − a_α) α̇ − a_β β̇ = a_0, −b_α α̇ + (1 − b_β) β̇ = b_0
    (module docstring), by Cramer's rule."""
    # det = (1 − a_α)(1 − b_β) − a_β b_α
    det = (1.0 - a_alpha) * (1.0 - b_beta) - a_beta * b_alpha
    alpha_dot = (a0 * (1.0 - b_beta) + a_beta * b0) / det
    beta_dot = ((1.0 - a_alpha) * b0 + b_alpha * a0) / det
    return alpha_dot, beta_dot


@register_jitable
def rigid_body_derivatives(X, F, consts):
    """dX/dt of the body state X under forces/moments F = (X, Y, Z, L, M, N) [2.5–2.13]."""
    D = np.empty(9)
    rigid_body_derivatives_into(X, F, consts, D)
    return D


@register_jitable
def rigid_body_derivatives_into(X, F, consts, D):
    """``rigid_body_derivatives`` written into ``D`` (9 entries)."""
    m = consts[0]
    Ix = consts[1]
    Iy = consts[2]
    Iz = consts[3]
    Ixz = consts[4]
    g = consts[9]
    u = X[0]
    v = X[1]
    w = X[2]
    p = X[3]
    q = X[4]
    r = X[5]
    lxz = X[6]
    lyz = X[7]
    lzz = X[8]
    # du/dt = −q w + r v + g l_xz + X/m                               [2.5]
    D[0] = -q * w + r * v + g * lxz + F[0] / m
    # dv/dt = −r u + p w + g l_yz + Y/m                               [2.6]
    D[1] = -r * u + p * w + g * lyz + F[1] / m
    # dw/dt = −p v + q u + g l_zz + Z/m                               [2.7]
    D[2] = -p * v + q * u + g * lzz + F[2] / m
    # Γ = I_x I_z − I_xz²; F1, F2 as in the module docstring
    gamma = Ix * Iz - Ixz * Ixz
    F1 = (Iy - Iz) * q * r + Ixz * p * q + F[3]
    F2 = (Ix - Iy) * p * q - Ixz * q * r + F[5]
    # dp/dt = (I_z F1 + I_xz F2)/Γ                                    [2.8]
    D[3] = (Iz * F1 + Ixz * F2) / gamma
    # dq/dt = ((I_z − I_x) p r + I_xz (r² − p²) + M)/I_y              [2.9]
    D[4] = ((Iz - Ix) * p * r + Ixz * (r * r - p * p) + F[4]) / Iy
    # dr/dt = (I_xz F1 + I_x F2)/Γ                                    [2.10]
    D[5] = (Ixz * F1 + Ix * F2) / gamma
    # direction cosines                                               [2.11–2.13]
    D[6] = r * lyz - q * lzz
    D[7] = -r * lxz + p * lzz
    D[8] = q * lxz - p * lyz


@register_jitable
def body_outputs(X, F, sig, consts, pdot, qdot, rdot):
    """Full output vector (V, α, β, Θ, Φ, a_x, a_y, a_z, p, q, r, ṗ, q̇, ṙ) [2.19–2.26]."""
    out = np.empty(14)
    body_outputs_into(X, F, sig, consts, pdot, qdot, rdot, out)
    return out


@register_jitable
def body_outputs_into(X, F, sig, consts, pdot, qdot, rdot, out):
    """``body_outputs`` written into ``out`` (14 entries)."""
    mg = consts[0] * consts[9]
    out[0] = sig[0]
    out[1] = sig[1]
    out[2] = sig[2]
    out[3] = sig[12]
    out[4] = sig[13]
    # a = F/(m g), g units                                            [2.24–2.26]
    out[5] = F[0] / mg
    out[6] = F[1] / mg
    out[7] = F[2] / mg
    out[8] = X[3]
    out[9] = X[4]
    out[10] = X[5]
    # ṗ, q̇, ṙ: the right-hand sides of [2.8–2.10]
    out[11] = pdot
    out[12] = qdot
    out[13] = rdot


@register_jitable
def wind_axis_derivatives(V, alpha, theta_pitch, q, F, consts):
    """d(V, α, Θ, q)/dt of the wind-axis longitudinal form (see the module docstring)."""
    D = np.empty(4)
    wind_axis_derivatives_into(V, alpha, theta_pitch, q, F, consts, D)
    return D


@register_jitable
def wind_axis_derivatives_into(V, alpha, theta_pitch, q, F, consts, D):
    """``wind_axis_derivatives`` written into ``D`` (4 entries)."""
    m = consts[0]
    g = consts[9]
    sa = math.sin(alpha)
    ca = math.cos(alpha)
    # dV/dt = (X cos α + Z sin α)/m − g sin(Θ − α)
    D[0] = (F[0] * ca + F[2] * sa) / m - g * math.sin(theta_pitch - alpha)
    # dα/dt = q + (Z cos α − X sin α)/(m V) + g cos(Θ − α)/V
    D[1] = q + (F[2] * ca - F[0] * sa) / (m * V) + g * math.cos(theta_pitch - alpha) / V
    # dΘ/dt = q
    D[2] = q
    # dq/dt = M/I_y
    D[3] = F[4] / consts[2]


@register_jitable
def alpha_q_signals(x, U, cbar):
    """Signal vector of the α–q form: (α, q̂, U…) with x = (α, q) and U the inputs
    (V, q̄, Θ, Φ, a_x, p, r, controls…)."""
    sig = np.empty(2 + U.shape[0])
    alpha_q_signals_into(x, U, cbar, sig)
    return sig


@register_jitable
def alpha_q_signals_into(x, U, cbar, sig):
    """``alpha_q_signals`` written into ``sig`` (2 + len(U) entries)."""
    sig[0] = x[0]
    # q̂ = q c̄/(2V)
    sig[1] = x[1] * cbar / (2.0 * U[0])
    for k in range(U.shape[0]):
        sig[2 + k] = U[k]


@register_jitable
def alpha_q_derivatives(x, U, C, consts):
    """d(α, q)/dt of the α–q form (module docstring); C the coefficient vector
    (``aero_coefficients``: C_Z = C[2], C_m = C[6])."""
    D = np.empty(2)
    alpha_q_derivatives_into(x, U, C, consts, D)
    return D


@register_jitable
def alpha_q_derivatives_into(x, U, C, consts, D):
    """``alpha_q_derivatives`` written into ``D`` (2 entries)."""
    m = consts[0]
    Ix = consts[1]
    Iy = consts[2]
    Iz = consts[3]
    Ixz = consts[4]
    S = consts[5]
    cbar = consts[7]
    g = consts[9]
    alpha = x[0]
    q = x[1]
    V = U[0]
    qbar = U[1]
    theta_pitch = U[2]
    phi = U[3]
    ax = U[4]
    p = U[5]
    r = U[6]
    # dα/dt = q + (q̄S/(mV)) C_Z cos α − (g a_x/V) sin α + (g/V)(cos Φ cos Θ cos α + sin Θ sin α)
    D[0] = (
        q
        + qbar * S / (m * V) * C[2] * math.cos(alpha)
        - g * ax / V * math.sin(alpha)
        + g
        / V
        * (
            math.cos(phi) * math.cos(theta_pitch) * math.cos(alpha)
            + math.sin(theta_pitch) * math.sin(alpha)
        )
    )
    # dq/dt = (q̄ S c̄ C_m + (I_z − I_x) p r + I_xz (r² − p²))/I_y                 [2.9]
    D[1] = (qbar * S * cbar * C[6] + (Iz - Ix) * p * r + Ixz * (r * r - p * p)) / Iy


@register_jitable
def alpha_q_outputs(x, U, C, consts):
    """Full output vector of the α–q form (α, q, a_z): a_z = q̄ S C_Z/(m g) in g [2.26]."""
    out = np.empty(3)
    alpha_q_outputs_into(x, U, C, consts, out)
    return out


@register_jitable
def alpha_q_outputs_into(x, U, C, consts, out):
    """``alpha_q_outputs`` written into ``out`` (3 entries)."""
    out[0] = x[0]
    out[1] = x[1]
    # a_z = q̄ S C_Z/(m g)                                             [2.26]
    out[2] = U[1] * consts[5] * C[2] / (consts[0] * consts[9])
