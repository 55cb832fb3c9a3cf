"""The rigid-body kinematic model of flight-path reconstruction (data compatibility).

Measured specific forces and angular rates drive the kinematic equations; the integrated
motion is compared with the measured air data, attitude and altitude. Sensor errors (biases,
scale factors, time delays) are parameters of the model (Jategaonkar, *Flight Vehicle System
Identification*, 2nd ed., ch. 10; Klein & Morelli, *Aircraft System Identification*, ch. 10).

Kinematic quantities (units: L is the length unit of the data, m or ft; angles in rad)::

    u, v, w  body-axis velocity at the CG (L/s)     φ, θ, ψ  Euler angles (rad)
    h        altitude (L)                            x_N, y_E  position north, east (L)

Each is an integrated state, or a measured input channel of the same name (a decoupled
model: e.g. longitudinal u, w, θ with v and φ measured).

Inputs (always): ``ax ay az`` specific forces at the accelerometer (L/s²), ``p q r`` body
rates (rad/s); ``pdot qdot rdot`` (rad/s²) when the accelerometer is away from the CG.

Sensor model of every sensor s (measured m, true x), with the bias and scale parameters of
that sensor when it has them (otherwise b = 0, f = 1)::

    m = f·(x − x_ref) + x_ref + b          bias_convention = "sensor" (default; FVSysID's)
    m = f·(x − x_ref) + x_ref − b          bias_convention = "correction" (x = m + b at f = 1;
                                           SIDPAC's compatibility biases)
    f = parameter                           scale_convention = "factor" (default; start 1)
    f = 1 + parameter                       scale_convention = "fraction" (SIDPAC's "scf",
                                           start 0)

x_ref is 0 unless ``scale_reference`` gives a constant (SIDPAC scales the change from the
first sample: x_ref = the model output there). Inputs are corrected by inverting the model,
x = (m − x_ref ∓ b)/f + x_ref; the angular accelerations are never corrected.

u, v, w are the inertial (ground-relative) velocity; with a constant wind (W_N, W_E, W_D) in
the north-east-down frame (parameters ``wind``, L/s) the air data see the air-relative
velocity, the ground speeds and positions the inertial one. Without wind both are the same.

State equations (g gravity, L/s²; (x_A, y_A, z_A) accelerometer position from the CG)::

    a_xCG = a_x' + x_A(q² + r²) − y_A(p q − ṙ) − z_A(p r + q̇)
    a_yCG = a_y' − x_A(p q + ṙ) + y_A(p² + r²) − z_A(q r − ṗ)
    a_zCG = a_z' − x_A(p r − q̇) − y_A(q r + ṗ) + z_A(p² + q²)
    u̇ = a_xCG − g sin θ + r v − q w
    v̇ = a_yCG + g sin φ cos θ + p w − r u
    ẇ = a_zCG + g cos φ cos θ + q u − p v
    φ̇ = p + (q sin φ + r cos φ) tan θ
    θ̇ = q cos φ − r sin φ
    ψ̇ = (q sin φ + r cos φ) / cos θ
    ḣ = u sin θ − v sin φ cos θ − w cos φ cos θ
    (V_N, V_E, V_D) = R·(u, v, w),  R = R_z(ψ) R_y(θ) R_x(φ) (body → north-east-down):
    V_N = u cθ cψ + v (sφ sθ cψ − cφ sψ) + w (cφ sθ cψ + sφ sψ)
    V_E = u cθ sψ + v (sφ sθ sψ + cφ cψ) + w (cφ sθ sψ − sφ cψ)
    V_D = −u sθ + v sφ cθ + w cφ cθ                               (ḣ = −V_D)
    ẋ_N = V_N,  ẏ_E = V_E

Observation equations (air-data boom at (x_NB, y_NB, z_NB) from the CG)::

    (u_a, v_a, w_a) = (u, v, w) − Rᵀ·(W_N, W_E, W_D)      air-relative (= u, v, w without wind)
    u_NB = u_a − r y_NB + q z_NB,  v_NB = v_a − p z_NB + r x_NB,  w_NB = w_a − q x_NB + p y_NB
    V = √(u_a² + v_a² + w_a²)  (velocity_at = "cg", default)  or  √(u_NB² + v_NB² + w_NB²)
        ("airdata")
    α = atan2(w_NB, u_NB)
    β = atan2(v_NB, u_NB)  (beta = "atan2", default)  or  asin(v_NB / V_NB)  ("asin", SIDPAC)
    φ, θ, ψ, h, x_N, y_E: the states
    V_N, V_E, V_D as above (inertial, at the CG)
    V_G = √(V_N² + V_E²)  (horizontal ground speed),  χ = atan2(V_E, V_N)  (track, rad)

and each output passes through its sensor model. Output time delays are applied by the
simulator to the whole output (``output_delays``); because the delay weights sum to one, a
delayed f·α_NB + b equals f·α_NB(delayed) + b (docs/compat.md).

The model functions are closures over numeric tables only, so numba compiles them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numba.extending import register_jitable

from flightid.errors import InputError, InputTypeError, describe
from flightid.model.forms import with_out_form
from flightid.model.parameters import Parameter, Parameters
from flightid.model.statespace import DELAY_CONVENTIONS, StateSpaceModel

__all__ = [
    "QUANTITIES",
    "DEFAULT_STATES",
    "OUTPUTS",
    "GROUND_OUTPUTS",
    "WIND",
    "SENSOR_INPUTS",
    "RATE_DERIVATIVES",
    "KinematicSpec",
    "kinematic_model",
    "kinematic_spec",
]

# the kinematic quantities, in the order of the full vector X inside f and h
QUANTITIES = ("u", "v", "w", "φ", "θ", "ψ", "h", "x_N", "y_E")
# the default integrated states (positions only when asked for)
DEFAULT_STATES = QUANTITIES[:7]
# the outputs, in the order of the full output vector inside h
OUTPUTS = ("V", "α", "β", "φ", "θ", "ψ", "h", "x_N", "y_E", "V_N", "V_E", "V_D", "V_G", "χ")
# outputs of the ground-speed / position extension (inertial velocity, positions)
GROUND_OUTPUTS = OUTPUTS[7:]
# constant-wind parameters (north, east, down; L/s), in the order of the wind vector
WIND = ("W_N", "W_E", "W_D")
# measured inputs driving the model, and the angular accelerations of the transfer terms
SENSOR_INPUTS = ("ax", "ay", "az", "p", "q", "r")
RATE_DERIVATIVES = ("pdot", "qdot", "rdot")
# the kinematic quantities each state equation and output reads (besides the inputs)
_STATE_NEEDS = {
    "u": ("θ", "v", "w"),
    "v": ("φ", "θ", "u", "w"),
    "w": ("φ", "θ", "u", "v"),
    "φ": ("φ", "θ"),
    "θ": ("φ",),
    "ψ": ("φ", "θ"),
    "h": ("u", "v", "w", "φ", "θ"),
    "x_N": ("u", "v", "w", "φ", "θ", "ψ"),
    "y_E": ("u", "v", "w", "φ", "θ", "ψ"),
}
_GROUND_NEEDS = ("u", "v", "w", "φ", "θ", "ψ")
_OUTPUT_NEEDS = {
    "V": ("u", "v", "w"),
    "α": ("u", "v", "w"),
    "β": ("u", "v", "w"),
    "φ": ("φ",),
    "θ": ("θ",),
    "ψ": ("ψ",),
    "h": ("h",),
    "x_N": ("x_N",),
    "y_E": ("y_E",),
    **dict.fromkeys(("V_N", "V_E", "V_D", "V_G", "χ"), _GROUND_NEEDS),
}
# air-data outputs: with wind they read the attitude as well (Rᵀ·W)
_AIR_OUTPUTS = ("V", "α", "β")
# parameter-name suffix of each input sensor (b_ax, f_p, ...)
_INPUT_SUFFIX = dict(zip(SENSOR_INPUTS, SENSOR_INPUTS, strict=True))
BIAS_CONVENTIONS = ("sensor", "correction")
SCALE_CONVENTIONS = ("factor", "fraction")
VELOCITY_AT = ("cg", "airdata")
BETA_DEFINITIONS = ("atan2", "asin")
LENGTH_UNITS = ("m", "ft")
# constants table layout (_C_*: index into ``consts``)
_C_G, _C_XA, _C_YA, _C_ZA, _C_XN, _C_YN, _C_ZN = 0, 1, 2, 3, 4, 5, 6
_C_SIGN, _C_SCALE0, _C_VBOOM, _C_ASIN, _C_PDOT = 7, 8, 9, 10, 11
# 1.0 when the model has wind parameters (else the air data read u, v, w unchanged)
_C_WIND = 12
# 1.0 when positions are integrated or ground speeds are outputs (else they are not computed)
_C_GROUND = 13
_NQ, _NO = len(QUANTITIES), len(OUTPUTS)


# ------------------------------------------------------------------------------ equations


@register_jitable
def full_quantities(x, u, src_state, src_input):
    """X = (u, v, w, φ, θ, ψ, h, x_N, y_E): each from the state (``src_state[i] ≥ 0``) or a
    measured input (``src_input[i] ≥ 0``), else 0."""
    X = np.zeros(_NQ)
    for i in range(_NQ):
        if src_state[i] >= 0:
            X[i] = x[src_state[i]]
        elif src_input[i] >= 0:
            X[i] = u[src_input[i]]
    return X


@register_jitable
def _sensor_scale(theta, index, consts):
    # f = parameter ("factor") or 1 + parameter ("fraction"); 1 without a scale parameter
    if index < 0:
        return 1.0
    return consts[_C_SCALE0] + theta[index]


@register_jitable
def corrected_inputs(u, theta, in_bias, in_scale, in_ref, consts):
    """(a_x', a_y', a_z', p, q, r): the measured inputs with the sensor model inverted,
    x = (m − x_ref − s·b)/f + x_ref (s = +1 "sensor", −1 "correction")."""
    c = np.empty(6)
    for i in range(6):
        b = theta[in_bias[i]] if in_bias[i] >= 0 else 0.0
        f = _sensor_scale(theta, in_scale[i], consts)
        # x = (m − x_ref − s·b)/f + x_ref
        c[i] = (u[i] - in_ref[i] - consts[_C_SIGN] * b) / f + in_ref[i]
    return c


@register_jitable
def kinematic_derivatives(X, c, u, consts):
    """dX/dt of the nine kinematic quantities from the corrected inputs ``c``."""
    ax, ay, az, p, q, r = c[0], c[1], c[2], c[3], c[4], c[5]
    k = int(consts[_C_PDOT])
    pd = u[k] if k >= 0 else 0.0
    qd = u[k + 1] if k >= 0 else 0.0
    rd = u[k + 2] if k >= 0 else 0.0
    g, xa, ya, za = consts[_C_G], consts[_C_XA], consts[_C_YA], consts[_C_ZA]
    # accelerations at the CG from the accelerometer at (x_A, y_A, z_A) [Jategaonkar ch. 10]
    axcg = ax + xa * (q * q + r * r) - ya * (p * q - rd) - za * (p * r + qd)
    aycg = ay - xa * (p * q + rd) + ya * (p * p + r * r) - za * (q * r - pd)
    azcg = az - xa * (p * r - qd) - ya * (q * r + pd) + za * (p * p + q * q)
    uu, v, w, phi, th = X[0], X[1], X[2], X[3], X[4]
    sphi, cphi, sth, cth = math.sin(phi), math.cos(phi), math.sin(th), math.cos(th)
    d = np.empty(_NQ)
    # u̇ = a_xCG − g sin θ + r v − q w
    d[0] = axcg - g * sth + r * v - q * w
    # v̇ = a_yCG + g sin φ cos θ + p w − r u
    d[1] = aycg + g * sphi * cth + p * w - r * uu
    # ẇ = a_zCG + g cos φ cos θ + q u − p v
    d[2] = azcg + g * cphi * cth + q * uu - p * v
    # φ̇ = p + (q sin φ + r cos φ) tan θ
    d[3] = p + (q * sphi + r * cphi) * sth / cth
    # θ̇ = q cos φ − r sin φ
    d[4] = q * cphi - r * sphi
    # ψ̇ = (q sin φ + r cos φ) / cos θ
    d[5] = (q * sphi + r * cphi) / cth
    # ḣ = u sin θ − v sin φ cos θ − w cos φ cos θ
    d[6] = uu * sth - v * sphi * cth - w * cphi * cth
    d[7] = 0.0
    d[8] = 0.0
    if consts[_C_GROUND] > 0.5:
        # ẋ_N = V_N, ẏ_E = V_E: (V_N, V_E, V_D) = R·(u, v, w)
        g_n, g_e, _ = ground_velocity(X)
        d[7] = g_n
        d[8] = g_e
    return d


@register_jitable
def ground_velocity(X):
    """(V_N, V_E, V_D) = R·(u, v, w), R = R_z(ψ) R_y(θ) R_x(φ) body → north-east-down."""
    uu, v, w = X[0], X[1], X[2]
    sf, cf = math.sin(X[3]), math.cos(X[3])
    st, ct = math.sin(X[4]), math.cos(X[4])
    sp, cp = math.sin(X[5]), math.cos(X[5])
    # V_N = u cθ cψ + v (sφ sθ cψ − cφ sψ) + w (cφ sθ cψ + sφ sψ)
    vn = uu * ct * cp + v * (sf * st * cp - cf * sp) + w * (cf * st * cp + sf * sp)
    # V_E = u cθ sψ + v (sφ sθ sψ + cφ cψ) + w (cφ sθ sψ − sφ cψ)
    ve = uu * ct * sp + v * (sf * st * sp + cf * cp) + w * (cf * st * sp - sf * cp)
    # V_D = −u sθ + v sφ cθ + w cφ cθ
    vd = -uu * st + v * sf * ct + w * cf * ct
    return vn, ve, vd


@register_jitable
def body_wind(X, theta, wind):
    """(W_x, W_y, W_z) = Rᵀ·(W_N, W_E, W_D): the constant wind in body axes (0 for a
    component without a parameter)."""
    wn = theta[wind[0]] if wind[0] >= 0 else 0.0
    we = theta[wind[1]] if wind[1] >= 0 else 0.0
    wd = theta[wind[2]] if wind[2] >= 0 else 0.0
    sf, cf = math.sin(X[3]), math.cos(X[3])
    st, ct = math.sin(X[4]), math.cos(X[4])
    sp, cp = math.sin(X[5]), math.cos(X[5])
    # W_x = W_N cθ cψ + W_E cθ sψ − W_D sθ
    wx = wn * ct * cp + we * ct * sp - wd * st
    # W_y = W_N (sφ sθ cψ − cφ sψ) + W_E (sφ sθ sψ + cφ cψ) + W_D sφ cθ
    wy = wn * (sf * st * cp - cf * sp) + we * (sf * st * sp + cf * cp) + wd * sf * ct
    # W_z = W_N (cφ sθ cψ + sφ sψ) + W_E (cφ sθ sψ − sφ cψ) + W_D cφ cθ
    wz = wn * (cf * st * cp + sf * sp) + we * (cf * st * sp - sf * cp) + wd * cf * ct
    return wx, wy, wz


@register_jitable
def true_outputs(X, c, theta, wind, consts):
    """The outputs (``OUTPUTS``) without sensor errors; α, β (and V with velocity_at =
    "airdata") at the air-data boom, from the corrected rates in ``c`` and the air-relative
    velocity (inertial minus the wind ``theta[wind]`` in body axes)."""
    p, q, r = c[3], c[4], c[5]
    xn, yn, zn = consts[_C_XN], consts[_C_YN], consts[_C_ZN]
    uu, v, w = X[0], X[1], X[2]
    if consts[_C_WIND] > 0.5:
        # (u_a, v_a, w_a) = (u, v, w) − Rᵀ·(W_N, W_E, W_D)
        wx, wy, wz = body_wind(X, theta, wind)
        uu, v, w = uu - wx, v - wy, w - wz
    # velocity at the boom: V_NB = V_CG + ω × r_NB
    unb = uu - r * yn + q * zn
    vnb = v - p * zn + r * xn
    wnb = w - q * xn + p * yn
    vboom = math.sqrt(unb * unb + vnb * vnb + wnb * wnb)
    y = np.empty(_NO)
    # V = √(u_a² + v_a² + w_a²) at the CG, or at the boom
    y[0] = vboom if consts[_C_VBOOM] > 0.5 else math.sqrt(uu * uu + v * v + w * w)
    # α = atan2(w_NB, u_NB)
    y[1] = math.atan2(wnb, unb)
    # β = atan2(v_NB, u_NB), or asin(v_NB / V_NB)
    y[2] = math.asin(vnb / vboom) if consts[_C_ASIN] > 0.5 else math.atan2(vnb, unb)
    # φ θ ψ h x_N y_E: the kinematic quantities
    for i in range(3, 9):
        y[i] = X[i]
    for i in range(9, _NO):
        y[i] = 0.0
    if consts[_C_GROUND] > 0.5:
        vn, ve, vd = ground_velocity(X)
        y[9] = vn
        y[10] = ve
        y[11] = vd
        # V_G = √(V_N² + V_E²), χ = atan2(V_E, V_N)
        y[12] = math.sqrt(vn * vn + ve * ve)
        y[13] = math.atan2(ve, vn)
    return y


@register_jitable
def sensor_outputs(y, theta, out_bias, out_scale, out_ref, consts):
    """m = f·(y − y_ref) + y_ref + s·b for each output of ``OUTPUTS``."""
    m = np.empty(_NO)
    for i in range(_NO):
        b = theta[out_bias[i]] if out_bias[i] >= 0 else 0.0
        f = _sensor_scale(theta, out_scale[i], consts)
        # m = f·(y − y_ref) + y_ref + s·b
        m[i] = f * (y[i] - out_ref[i]) + out_ref[i] + consts[_C_SIGN] * b
    return m


@register_jitable
def _kinematic_f(x, u, theta, src_state, src_input, deriv_index, in_bias, in_scale, in_ref,
                 consts, out):  # fmt: skip
    """dx/dt of the kinematic model into ``out``: the chosen entries of dX/dt."""
    X = full_quantities(x, u, src_state, src_input)
    c = corrected_inputs(u, theta, in_bias, in_scale, in_ref, consts)
    d = kinematic_derivatives(X, c, u, consts)
    for i in range(deriv_index.shape[0]):
        out[i] = d[deriv_index[i]]


@register_jitable
def _kinematic_h(x, u, theta, src_state, src_input, out_index, in_bias, in_scale, in_ref,
                 out_bias, out_scale, out_ref, wind, consts, out):  # fmt: skip
    """y of the kinematic model into ``out``: the chosen sensor outputs."""
    X = full_quantities(x, u, src_state, src_input)
    c = corrected_inputs(u, theta, in_bias, in_scale, in_ref, consts)
    y_true = true_outputs(X, c, theta, wind, consts)
    m = sensor_outputs(y_true, theta, out_bias, out_scale, out_ref, consts)
    for i in range(out_index.shape[0]):
        out[i] = m[out_index[i]]


# ------------------------------------------------------------------------------ the model


@dataclass(frozen=True)
class KinematicSpec:
    """The numeric tables of one kinematic model (what its f and h close over) and its names.

    Attributes:
        states: the integrated kinematic quantities, in state order.
        inputs: input channels: ax ay az p q r [pdot qdot rdot] then the measured
            kinematic quantities.
        outputs: the output channels.
        parameters: the sensor parameters and delays, in model order.
        length_unit: "m" or "ft" (labels only).
        wind: θ indices of the wind parameters W_N, W_E, W_D (−1: none).
    """

    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    parameters: Parameters
    length_unit: str
    src_state: np.ndarray
    src_input: np.ndarray
    deriv_index: np.ndarray
    out_index: np.ndarray
    in_bias: np.ndarray
    in_scale: np.ndarray
    in_ref: np.ndarray
    out_bias: np.ndarray
    out_scale: np.ndarray
    out_ref: np.ndarray
    wind: np.ndarray
    consts: np.ndarray

    def functions(self):
        """(f, h): numba-compilable closures over the tables, in return form carrying their
        out forms (``flightid.model.forms``; the out forms still allocate their
        intermediate vectors, not their result)."""
        src_state, src_input = self.src_state, self.src_input
        deriv_index, out_index = self.deriv_index, self.out_index
        in_bias, in_scale, in_ref = self.in_bias, self.in_scale, self.in_ref
        out_bias, out_scale, out_ref = self.out_bias, self.out_scale, self.out_ref
        wind, consts = self.wind, self.consts
        n_x, n_y = deriv_index.shape[0], out_index.shape[0]

        def f_out(t, x, u, theta, out):
            _kinematic_f(
                x, u, theta, src_state, src_input, deriv_index, in_bias, in_scale, in_ref,
                consts, out,
            )  # fmt: skip

        def h_out(t, x, u, theta, out):
            _kinematic_h(
                x, u, theta, src_state, src_input, out_index, in_bias, in_scale, in_ref,
                out_bias, out_scale, out_ref, wind, consts, out,
            )  # fmt: skip

        def f(t, x, u, theta):
            dx = np.empty(n_x)
            _kinematic_f(
                x, u, theta, src_state, src_input, deriv_index, in_bias, in_scale, in_ref,
                consts, dx,
            )  # fmt: skip
            return dx

        def h(t, x, u, theta):
            y = np.empty(n_y)
            _kinematic_h(
                x, u, theta, src_state, src_input, out_index, in_bias, in_scale, in_ref,
                out_bias, out_scale, out_ref, wind, consts, y,
            )  # fmt: skip
            return y

        return with_out_form(f, f_out), with_out_form(h, h_out)

    def reconstruction_function(self):
        """h_rec(t, x, u, θ) = (states, true outputs (all of ``OUTPUTS``), corrected inputs
        (six)); names in ``reconstruction_names``."""
        src_state, src_input = self.src_state, self.src_input
        in_bias, in_scale, in_ref = self.in_bias, self.in_scale, self.in_ref
        wind, consts = self.wind, self.consts
        n_x = len(self.states)

        def h_rec(t, x, u, theta):
            X = full_quantities(x, u, src_state, src_input)
            c = corrected_inputs(u, theta, in_bias, in_scale, in_ref, consts)
            y = true_outputs(X, c, theta, wind, consts)
            out = np.empty(n_x + _NO + 6)
            for i in range(n_x):
                out[i] = x[i]
            for i in range(_NO):
                out[n_x + i] = y[i]
            for i in range(6):
                out[n_x + _NO + i] = c[i]
            return out

        return h_rec

    @property
    def reconstruction_names(self) -> tuple[str, ...]:
        return (*self.states, *OUTPUTS, *SENSOR_INPUTS)

    @property
    def has_wind(self) -> bool:
        """True when the model has wind parameters."""
        return bool(self.consts[_C_WIND] > 0.5)

    @property
    def has_ground(self) -> bool:
        """True when positions are integrated or ground speeds are outputs."""
        return bool(self.consts[_C_GROUND] > 0.5)

    def unit(self, name: str) -> str:
        """Unit of a kinematic quantity, output or input channel of the model."""
        return _unit(self.length_unit, name)

    def output_sensor(self, name: str) -> tuple[int, int, float]:
        """(bias θ index, scale θ index, x_ref) of output ``name`` (−1: none)."""
        i = OUTPUTS.index(name)
        return int(self.out_bias[i]), int(self.out_scale[i]), float(self.out_ref[i])

    def invert_output(self, name: str, measured: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """The measured output with its sensor model inverted: (m − y_ref − s·b)/f + y_ref."""
        b_i, f_i, ref = self.output_sensor(name)
        b = theta[b_i] if b_i >= 0 else 0.0
        f = (self.consts[_C_SCALE0] + theta[f_i]) if f_i >= 0 else 1.0
        # y = (m − y_ref − s·b)/f + y_ref
        return (np.asarray(measured, dtype=float) - ref - self.consts[_C_SIGN] * b) / f + ref


def _unit(L: str, name: str) -> str:
    """Unit of a kinematic quantity, output or input channel (L: the length unit)."""
    if name in ("u", "v", "w", "V", "V_N", "V_E", "V_D", "V_G", *WIND):
        return f"{L}/s"
    if name in ("h", "x_N", "y_E"):
        return L
    if name in ("ax", "ay", "az"):
        return f"{L}/s^2"
    if name in ("p", "q", "r"):
        return "rad/s"
    if name in RATE_DERIVATIVES:
        return "rad/s^2"
    return "rad"


def _names(value: object, argument: str, allowed: Sequence[str]) -> tuple[str, ...]:
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise InputTypeError(f"{argument}: expected a list of names from {list(allowed)}, "
                             f"got {describe(value)}")  # fmt: skip
    names = tuple(value)
    for name in names:
        if name not in allowed:
            raise InputError(f"{argument}: expected names from {list(allowed)}, got {name!r}")
    if len(set(names)) != len(names):
        raise InputError(f"{argument}: names must be unique, got {list(names)}")
    return names


def _position(value: object, argument: str) -> tuple[float, float, float]:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, str) or not isinstance(value, Sequence) or len(value) != 3:
        raise InputError(f"{argument}: expected three numbers (x, y, z) from the CG, got "
                         f"{describe(value)}")  # fmt: skip
    out = []
    for i, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise InputError(f"{argument}[{i}]: expected a finite number, got {describe(v)}")
        out.append(float(v))
    return out[0], out[1], out[2]


def _choice(value: object, argument: str, allowed: Sequence[str]) -> str:
    if value not in allowed:
        raise InputError(f"{argument}: expected one of {list(allowed)}, got {describe(value)}")
    return str(value)


def _states_and_outputs(states: object, outputs: object) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The checked integrated states and outputs (default: every output the states give)."""
    states = _names(states, "states", QUANTITIES)
    if not states:
        raise InputError("states: expected at least one integrated kinematic quantity")
    if outputs is None:
        outputs = tuple(
            o for o in OUTPUTS if o in _AIR_OUTPUTS or o in states
        )  # every output the states give
    outputs = _names(outputs, "outputs", OUTPUTS)
    if not outputs:
        raise InputError("outputs: expected at least one output")
    for o in outputs:
        if o in QUANTITIES and o not in states:
            raise InputError(
                f"outputs: {o!r} is not an integrated state (states {list(states)}); a "
                "measured attitude, altitude or position cannot be an output of its own model"
            )
    return states, outputs


def _gravity(g: object) -> float:
    """The checked gravity, L/s²: a positive finite number."""
    if isinstance(g, bool) or not isinstance(g, (int, float)):
        raise InputTypeError(f"g: expected a number (L/s²), got {describe(g)}")
    g = float(g)
    if not (math.isfinite(g) and g > 0):
        raise InputError(f"g: expected a positive finite number (L/s²), got {g!r}")
    return g


def _scale_reference(scale_reference: Mapping[str, float] | None) -> dict[str, float]:
    """The checked {sensor: x_ref} of the scale factors (an output or a sensor input)."""
    reference = dict(scale_reference or {})
    for name, value in reference.items():
        if name not in OUTPUTS and name not in SENSOR_INPUTS:
            raise InputError(
                f"scale_reference: {name!r} is not an output {list(OUTPUTS)} or input "
                f"{list(SENSOR_INPUTS)}"
            )
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(f"scale_reference.{name}: expected a number, got {describe(value)}")
    return reference


@dataclass(frozen=True)
class _Options:
    """The checked arguments of ``kinematic_spec`` (positions: (x, y, z) from the CG, L)."""

    states: tuple[str, ...]
    outputs: tuple[str, ...]
    wind: tuple[str, ...]
    g: float
    accelerometer: tuple[float, float, float]
    airdata: tuple[float, float, float]
    velocity_at: str
    beta: str
    bias_convention: str
    scale_convention: str
    length_unit: str
    input_biases: tuple[str, ...]
    input_scales: tuple[str, ...]
    output_biases: tuple[str, ...]
    output_scales: tuple[str, ...]
    reference: dict[str, float]
    delays: tuple[str, ...]
    renames: dict[str, str]


def _measured_quantities(opt: _Options) -> tuple[str, ...]:
    """The kinematic quantities the state equations and outputs read but do not integrate."""
    needed = {q for s in opt.states for q in _STATE_NEEDS[s]} | {
        q for o in opt.outputs for q in _OUTPUT_NEEDS[o]
    }
    if opt.wind and any(o in _AIR_OUTPUTS for o in opt.outputs):
        # the air data read the wind in body axes, Rᵀ·W: the attitude
        needed |= {"φ", "θ", "ψ"}
    return tuple(q for q in QUANTITIES if q in needed and q not in opt.states)


@dataclass
class _ParameterTable:
    """The (default name, start value, unit) of each parameter and the θ index tables."""

    defaults: list[tuple[str, float, str]]
    in_bias: np.ndarray
    in_scale: np.ndarray
    out_bias: np.ndarray
    out_scale: np.ndarray
    wind: np.ndarray

    def add(self, name: str, value: float, unit: str) -> int:
        """Append a parameter; its θ index."""
        self.defaults.append((name, value, unit))
        return len(self.defaults) - 1


def _parameter_table(opt: _Options) -> _ParameterTable:
    """Parameters: input biases, input scales, then per output f then b, wind, then delays."""
    L = opt.length_unit
    scale_start = 1.0 if opt.scale_convention == "factor" else 0.0
    table = _ParameterTable(
        defaults=[],
        in_bias=-np.ones(6, dtype=np.int64),
        in_scale=-np.ones(6, dtype=np.int64),
        out_bias=-np.ones(len(OUTPUTS), dtype=np.int64),
        out_scale=-np.ones(len(OUTPUTS), dtype=np.int64),
        wind=-np.ones(3, dtype=np.int64),
    )
    for i, s in enumerate(SENSOR_INPUTS):
        if s in opt.input_biases:
            table.in_bias[i] = table.add(f"b_{_INPUT_SUFFIX[s]}", 0.0, _unit(L, s))
    for i, s in enumerate(SENSOR_INPUTS):
        if s in opt.input_scales:
            table.in_scale[i] = table.add(f"f_{_INPUT_SUFFIX[s]}", scale_start, "")
    for o in opt.outputs:
        i = OUTPUTS.index(o)
        if o in opt.output_scales:
            table.out_scale[i] = table.add(f"f_{o}", scale_start, "")
        if o in opt.output_biases:
            table.out_bias[i] = table.add(f"b_{o}", 0.0, _unit(L, o))
    for i, component in enumerate(WIND):
        if component in opt.wind:
            table.wind[i] = table.add(component, 0.0, _unit(L, component))
    for name in opt.delays:
        table.add(name, 0.0, "s")
    return table


def _renamed_parameters(
    defaults: list[tuple[str, float, str]], renames: Mapping[str, str]
) -> Parameters:
    """The free parameters, each under its name in ``renames`` or its default name."""
    default_names = [d[0] for d in defaults]
    for key in renames:
        if key not in default_names:
            raise InputError(
                f"names: {key!r} is not a parameter of this model; its parameters: {default_names}"
            )
    try:
        return Parameters(
            [Parameter(renames.get(n, n), v, free=True, unit=u) for n, v, u in defaults]
        )
    except InputError as exc:
        raise InputError(f"names: {exc}") from None


def _sources(
    states: tuple[str, ...], measured: tuple[str, ...], inputs: tuple[str, ...]
) -> tuple[np.ndarray, np.ndarray]:
    """Per kinematic quantity, its state index and its input index (−1: not that source)."""
    src_state = -np.ones(len(QUANTITIES), dtype=np.int64)
    src_input = -np.ones(len(QUANTITIES), dtype=np.int64)
    for i, q in enumerate(QUANTITIES):
        if q in states:
            src_state[i] = states.index(q)
        elif q in measured:
            src_input[i] = inputs.index(q)
    return src_state, src_input


def _constants(opt: _Options, transfer: bool, ground: bool) -> np.ndarray:
    """The constants vector read by the compiled model functions (the _C_* indices)."""
    return np.array(
        [
            opt.g,
            *opt.accelerometer,
            *opt.airdata,
            1.0 if opt.bias_convention == "sensor" else -1.0,
            0.0 if opt.scale_convention == "factor" else 1.0,
            1.0 if opt.velocity_at == "airdata" else 0.0,
            1.0 if opt.beta == "asin" else 0.0,
            float(len(SENSOR_INPUTS)) if transfer else -1.0,
            1.0 if opt.wind else 0.0,
            1.0 if ground else 0.0,
        ]
    )


def kinematic_spec(
    *,
    states: Sequence[str] = DEFAULT_STATES,
    outputs: Sequence[str] | None = None,
    g: float = 9.80665,
    accelerometer_position: Sequence[float] = (0.0, 0.0, 0.0),
    airdata_position: Sequence[float] = (0.0, 0.0, 0.0),
    velocity_at: str = "cg",
    beta: str = "atan2",
    input_biases: Sequence[str] = SENSOR_INPUTS,
    input_scales: Sequence[str] = (),
    output_biases: Sequence[str] | None = None,
    output_scales: Sequence[str] | None = None,
    bias_convention: str = "sensor",
    scale_convention: str = "factor",
    scale_reference: Mapping[str, float] | None = None,
    wind: Sequence[str] = (),
    delays: Sequence[str] = (),
    names: Mapping[str, str] | None = None,
    length_unit: str = "m",
) -> KinematicSpec:
    """The tables of a kinematic model; the arguments are those of ``kinematic_model``."""
    states, outputs = _states_and_outputs(states, outputs)
    default_sensors = tuple(o for o in ("α", "β") if o in outputs)
    # checked in this order: the first bad argument is the one reported
    opt = _Options(
        states=states,
        outputs=outputs,
        wind=_names(wind, "wind", WIND),
        g=_gravity(g),
        accelerometer=_position(accelerometer_position, "accelerometer_position"),
        airdata=_position(airdata_position, "airdata_position"),
        velocity_at=_choice(velocity_at, "velocity_at", VELOCITY_AT),
        beta=_choice(beta, "beta", BETA_DEFINITIONS),
        bias_convention=_choice(bias_convention, "bias_convention", BIAS_CONVENTIONS),
        scale_convention=_choice(scale_convention, "scale_convention", SCALE_CONVENTIONS),
        length_unit=_choice(length_unit, "length_unit", LENGTH_UNITS),
        input_biases=_names(input_biases, "input_biases", SENSOR_INPUTS),
        input_scales=_names(input_scales, "input_scales", SENSOR_INPUTS),
        output_biases=_names(
            default_sensors if output_biases is None else output_biases, "output_biases", outputs
        ),
        output_scales=_names(
            default_sensors if output_scales is None else output_scales, "output_scales", outputs
        ),
        reference=_scale_reference(scale_reference),
        delays=tuple(delays),
        renames=dict(names or {}),
    )
    states, outputs = opt.states, opt.outputs
    # measured kinematic quantities: what the state equations and outputs read, not integrated
    measured = _measured_quantities(opt)
    ground = bool({"x_N", "y_E"} & set(states)) or any(o in GROUND_OUTPUTS for o in outputs)
    transfer = any(v != 0.0 for v in opt.accelerometer)
    inputs = (*SENSOR_INPUTS, *(RATE_DERIVATIVES if transfer else ()), *measured)
    table = _parameter_table(opt)
    parameters = _renamed_parameters(table.defaults, opt.renames)
    src_state, src_input = _sources(states, measured, inputs)
    return KinematicSpec(
        states=states,
        inputs=inputs,
        outputs=outputs,
        parameters=parameters,
        length_unit=opt.length_unit,
        src_state=src_state,
        src_input=src_input,
        deriv_index=np.array([QUANTITIES.index(s) for s in states], dtype=np.int64),
        out_index=np.array([OUTPUTS.index(o) for o in outputs], dtype=np.int64),
        in_bias=table.in_bias,
        in_scale=table.in_scale,
        in_ref=np.array([float(opt.reference.get(s, 0.0)) for s in SENSOR_INPUTS]),
        out_bias=table.out_bias,
        out_scale=table.out_scale,
        out_ref=np.array([float(opt.reference.get(o, 0.0)) for o in OUTPUTS]),
        wind=table.wind,
        consts=_constants(opt, transfer, ground),
    )


def kinematic_model(
    *,
    states: Sequence[str] = DEFAULT_STATES,
    outputs: Sequence[str] | None = None,
    g: float = 9.80665,
    accelerometer_position: Sequence[float] = (0.0, 0.0, 0.0),
    airdata_position: Sequence[float] = (0.0, 0.0, 0.0),
    velocity_at: str = "cg",
    beta: str = "atan2",
    input_biases: Sequence[str] = SENSOR_INPUTS,
    input_scales: Sequence[str] = (),
    output_biases: Sequence[str] | None = None,
    output_scales: Sequence[str] | None = None,
    bias_convention: str = "sensor",
    scale_convention: str = "factor",
    scale_reference: Mapping[str, float] | None = None,
    wind: Sequence[str] = (),
    output_delays: Mapping[str, str] | None = None,
    input_delays: Mapping[str, str] | None = None,
    delay_convention: str = "fractional",
    names: Mapping[str, str] | None = None,
    length_unit: str = "m",
    x0=None,
    name: str = "kinematic",
) -> StateSpaceModel:
    """The flight-path reconstruction model (module docstring: equations).

    Args:
        states: integrated kinematic quantities from ``QUANTITIES`` (u v w φ θ ψ h, the
            default, and the positions x_N, y_E); the others the equations need become
            measured input channels of the same name (e.g. ``("u", "w", "θ")`` takes v and φ
            as inputs).
        outputs: from ``OUTPUTS`` (V α β φ θ ψ h x_N y_E V_N V_E V_D V_G χ); default V, α,
            β and the integrated φ, θ, ψ, h, x_N, y_E, which must be states to be outputs.
            V_N V_E V_D (ground-speed components), V_G (horizontal ground speed) and χ
            (track, atan2(V_E, V_N), in (−π, π]) are inertial, at the CG.
        g: gravity, L/s² (9.80 m/s² in FVSysID's ATTAS flight-path reconstruction;
            32.174 ft/s² for SIDPAC's files).
        accelerometer_position: (x_A, y_A, z_A) from the CG, L, body axes; away from the CG
            the model takes the inputs pdot, qdot, rdot (rad/s²) for the transfer terms.
        airdata_position: (x_NB, y_NB, z_NB) of the air-data boom from the CG, L.
        velocity_at: "cg" (V at the CG, default) or "airdata" (at the boom).
        beta: "atan2" (β = atan2(v_NB, u_NB), default) or "asin" (asin(v_NB/V_NB)).
        input_biases: sensors of ``SENSOR_INPUTS`` with a bias parameter b_ax … b_r
            (default all six; start 0).
        input_scales: sensors with a scale-factor parameter f_ax … f_r (default none).
        output_biases: outputs with a bias b_<o> (default α and β where they are outputs).
        output_scales: outputs with a scale factor f_<o> (default α and β: the parameters
            are then f_α, b_α, f_β, b_β).
        bias_convention: "sensor" (m = f·x + b, default) or "correction" (x = m + b).
        scale_convention: "factor" (f, start 1) or "fraction" (f = 1 + λ, λ start 0).
        scale_reference: {sensor: x_ref}: scale about x_ref (default 0).
        wind: constant-wind components from ``WIND`` (W_N W_E W_D, L/s, start 0) with a
            parameter, added after the output sensors' parameters; the air data (V, α, β)
            then use the air-relative velocity (u, v, w) − Rᵀ·W, the ground speeds and
            positions the inertial (u, v, w). Default none (no wind).
        output_delays: {output: delay parameter name}; the delay parameters (s, start 0)
            are added after the sensor (and wind) parameters.
        input_delays: {input channel: delay parameter name}: the model reads the input at
            t − τ (``StateSpaceModel``); parameters after the output delays'.
        delay_convention: "fractional" or "two_sample" (``StateSpaceModel``).
        names: {default parameter name: name}: report the parameters under other names
            (e.g. SIDPAC's {"b_ax": "ax_bias"}).
        length_unit: "m" or "ft": the unit L of the data (labels and parameter units).
        x0: initial states (one tuple, or one per maneuver), as ``StateSpaceModel``.
        name: model name.

    All parameters start free; fix them with ``Parameters.with_values`` / ``replace``, or in
    a case file's [parameters].

    Raises:
        InputError, InputTypeError: a bad argument (the message names it).
    """
    delays = dict(output_delays or {})
    for output in delays:
        if output not in OUTPUTS:
            raise InputError(f"output_delays: {output!r} is not an output {list(OUTPUTS)}")
    in_delays = dict(input_delays or {})
    delay_convention = _choice(delay_convention, "delay_convention", DELAY_CONVENTIONS)
    spec = kinematic_spec(
        states=states,
        outputs=outputs,
        g=g,
        accelerometer_position=accelerometer_position,
        airdata_position=airdata_position,
        velocity_at=velocity_at,
        beta=beta,
        input_biases=input_biases,
        input_scales=input_scales,
        output_biases=output_biases,
        output_scales=output_scales,
        bias_convention=bias_convention,
        scale_convention=scale_convention,
        scale_reference=scale_reference,
        wind=wind,
        delays=tuple(dict.fromkeys([*delays.values(), *in_delays.values()])),
        names=names,
        length_unit=length_unit,
    )
    return model_from_spec(spec, x0=x0, name=name, output_delays=delays,
                           input_delays=in_delays, delay_convention=delay_convention)  # fmt: skip


def model_from_spec(
    spec: KinematicSpec,
    *,
    x0=None,
    name: str = "kinematic",
    output_delays: Mapping[str, str] | None = None,
    input_delays: Mapping[str, str] | None = None,
    delay_convention: str = "fractional",
) -> StateSpaceModel:
    """The ``StateSpaceModel`` of ``spec``."""
    f, h = spec.functions()
    for output in output_delays or {}:
        if output not in spec.outputs:
            raise InputError(
                f"output_delays: {output!r} is not an output of the model {list(spec.outputs)}"
            )
    for channel in input_delays or {}:
        if channel not in spec.inputs:
            raise InputError(
                f"input_delays: {channel!r} is not an input of the model {list(spec.inputs)}"
            )
    return StateSpaceModel(
        states=spec.states,
        inputs=spec.inputs,
        outputs=spec.outputs,
        f=f,
        h=h,
        parameters=spec.parameters,
        x0=tuple(x0) if x0 is not None else (0.0,) * len(spec.states),
        name=name,
        output_delays=dict(output_delays) if output_delays else None,
        input_delays=dict(input_delays) if input_delays else None,
        delay_convention=delay_convention,
    )
