"""State-space models of an airplane: 6-DOF, decoupled longitudinal and lateral, wind axes.

Every builder turns the model into numeric tables only (constants, index maps from the
model's states and inputs to the body state, the aerodynamic term tables, ``ModelSpec``) and
returns a ``flightid.model.StateSpaceModel`` whose ``f`` and ``h`` are made from them in one
of two ways (the builders' ``code`` argument):

* ``"generated"`` (default): straight-line scalar code written for this model by
  ``flightid.aircraft.codegen`` and imported from a content-named file
  (``flightid.aircraft.generated``, so numba's disk cache keeps it between processes);
  about as fast as hand-written code in the simulation kernel;
* ``"tables"``: the reference implementation, closures over the tables evaluated by the
  ``register_jitable`` helpers of ``flightid.aircraft.equations`` at every call. A model the
  generator does not cover (``codegen.uncovered``) takes this path too.

Either way the simulator can numba-compile ``f``/``h`` and the pure-Python path runs the
same code; ``f.model_code`` says which path a model has.

Models (RP-1153 §2.A, equations 2.5–2.15):

* ``six_dof_model``: states u v w p q r l_xz l_yz l_zz.
* ``longitudinal_model``: states u w q l_xz l_yz l_zz; the measured lateral motion v, p, r
  enters as inputs [2.27–2.29].
* ``lateral_model``: states v p r l_xz l_yz l_zz; the measured longitudinal motion u, w, q
  (or V, α, q) enters as inputs [2.30–2.32].
* ``wind_axis_longitudinal_model``: states V alpha theta q.
* ``alpha_q_longitudinal_model``: states alpha q; V, q̄, θ, φ, a_x (g), p, r are measured
  inputs (thrust carried by a_x), C_Z and C_m only, outputs alpha, q, az (the SIDPAC-style
  output-error model of a stepwise case).

Units: m/s, rad, rad/s; the thrust input (if the airplane names one) in N; controls in the
units the aerodynamic model's derivatives assume (rad for the paper's examples).
Outputs are chosen by name from V, alpha, beta, theta, phi, ax, ay, az, p, q, r, pdot, qdot,
rdot (docs/aircraft.md says which model has which, and what each includes and omits); the
accelerations are body-axis specific forces in g units (a_z ≈ −1 g in level flight) unless an
``accelerometer`` convention says otherwise (sign per axis, g or m/s², ``Accelerometer``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from numba.extending import register_jitable

from flightid.aircraft.accelerometer import Accelerometer
from flightid.aircraft.aero import AeroModel
from flightid.aircraft.airplane import Airplane, AirplaneDataError
from flightid.aircraft.codegen import ModelSpec, model_source, uncovered
from flightid.aircraft.equations import (
    ALPHA_Q_INPUTS,
    ALPHA_Q_OUTPUTS,
    ALPHADOT_SIGNAL,
    BETADOT_SIGNAL,
    BODY_STATES,
    OUTPUTS,
    SIGNALS,
    aero_coefficients_into,
    alpha_q_derivatives_into,
    alpha_q_outputs_into,
    alpha_q_signals_into,
    alpha_rate,
    beta_rate,
    body_outputs_into,
    engine_loads,
    forces_and_moments_into,
    rigid_body_derivatives_into,
    signals_from_body_into,
    solve_rate_terms,
    wind_axis_derivatives_into,
)
from flightid.aircraft.generated import load_source
from flightid.errors import InputError, InputTypeError, describe
from flightid.model.forms import with_out_form
from flightid.model.parameters import Parameters
from flightid.model.statespace import StateSpaceModel
from flightid.model.terms import Abs, Spline

__all__ = [
    "six_dof_model",
    "longitudinal_model",
    "lateral_model",
    "wind_axis_longitudinal_model",
    "alpha_q_longitudinal_model",
    "DEFAULT_OUTPUTS",
    "LATERAL_MEASURED",
]

# Model kind → (states, measured inputs taken from the other axis, default outputs)
_KINDS = {
    "6dof": (BODY_STATES, (), OUTPUTS[:11]),
    "longitudinal": (
        ("u", "w", "q", "l_xz", "l_yz", "l_zz"),
        ("v", "p", "r"),
        ("V", "alpha", "q", "theta", "ax", "az"),
    ),
    "lateral": (
        ("v", "p", "r", "l_xz", "l_yz", "l_zz"),
        ("u", "w", "q"),
        ("beta", "p", "r", "phi", "ay"),
    ),
    "wind": (("V", "alpha", "theta", "q"), (), ("V", "alpha", "theta", "q", "ax", "az")),
    "alpha_q": (("alpha", "q"), ALPHA_Q_INPUTS, ALPHA_Q_OUTPUTS),
}
DEFAULT_OUTPUTS = {kind: spec[2] for kind, spec in _KINDS.items()}


def _constants(airplane: Airplane) -> np.ndarray:
    """``equations.CONSTANTS`` of the airplane. A longitudinal-only airplane (no I_x, I_z, b)
    gets I_x = I_z = I_y, I_xz = 0 and b = c̄ as placeholders: they then multiply only terms
    that are zero or unused (the (I_z − I_x) p r coupling; the builders refuse models that
    need b, I_x or I_z, ``_check_airplane``)."""
    no_lateral_inertia = airplane.Ix is None
    return np.array(
        [
            airplane.mass,
            airplane.Iy if no_lateral_inertia else airplane.Ix,
            airplane.Iy,
            airplane.Iy if no_lateral_inertia else airplane.Iz,
            0.0 if no_lateral_inertia else airplane.Ixz,
            airplane.S,
            airplane.cbar if airplane.b is None else airplane.b,
            airplane.cbar,
            airplane.rho,
            airplane.g,
            airplane.thrust_inclination,
        ],
        dtype=float,
    )


def _extra_constants(airplane: Airplane, reference_speed: float | None, rate_speed: str):
    """``equations.EXTRA_CONSTANTS``: l_T, V0 (0 if none), 1 if rates use V0, s, I_p Ω."""
    return np.array(
        [
            airplane.thrust_moment_arm,
            0.0 if reference_speed is None else float(reference_speed),
            1.0 if rate_speed == "V0" else 0.0,
            float(airplane.rotation),
            airplane.engine_momentum,
        ],
        dtype=float,
    )


@register_jitable
def body_state_from(x, u, src_state, src_input, wind_index, X):
    """Full body state X = (u, v, w, p, q, r, l_xz, l_yz, l_zz) of a body-axis model, written
    into ``X`` (9 entries).

    Each entry comes from the model state (``src_state[i] ≥ 0``) or an input
    (``src_input[i] ≥ 0``), else 0. When the lateral model measures V and α instead of u and
    w (``wind_index`` = input indices of V and α, else −1), with sin β = v/V [2.20]:

        u = V cos α cos β,   w = V sin α cos β                          [2.19–2.21]
    """
    for i in range(9):
        X[i] = 0.0
        if src_state[i] >= 0:
            X[i] = x[src_state[i]]
        elif src_input[i] >= 0:
            X[i] = u[src_input[i]]
    if wind_index[0] >= 0:
        V = u[wind_index[0]]
        alpha = u[wind_index[1]]
        sin_beta = X[1] / V
        cos_beta = math.sqrt(max(0.0, 1.0 - sin_beta * sin_beta))
        X[0] = V * math.cos(alpha) * cos_beta
        X[2] = V * math.sin(alpha) * cos_beta


@register_jitable
def _loads(sig, X, u, theta, idx, tc, tp, fs, fsig, fpow, fspl, fknot, consts, extra, C, F):
    """Loads F = (X, Y, Z, L, M, N) into ``F``: C = aero model of the signals [2.16] (into
    ``C``), forces and moments [2.14–2.15], thrust moment and engine terms
    (``engine_loads``). ``idx`` = (thrust, propeller torque, engine momentum input indices or
    −1, lateral flag, α̇ flag, β̇ flag)."""
    aero_coefficients_into(sig, theta, tc, tp, fs, fsig, fpow, fspl, fknot, C)
    thrust = u[idx[0]] if idx[0] >= 0 else 0.0
    forces_and_moments_into(C, sig[1], sig[0], thrust, consts, F)
    engine_loads(F, X, u, thrust, idx[1], idx[2], extra)


@register_jitable
def _rate_normaliser(sig, extra, length):
    """length/(2 V_n): α̇̂ per unit α̇ (length c̄) or β̇̂ per unit β̇ (length b)."""
    Vn = extra[1] if extra[2] > 0.5 else sig[0]
    return length / (2.0 * Vn)


# entries of the work array of the body-axis solution: signals (18 + extra inputs) first,
# then C (8), F (6), D (9), F_α, F_β (6 each), D_α, D_β (9 each), a trial F (6) and D (9)
_BODY_WORK = 8 + 6 + 9 + 6 + 6 + 9 + 9 + 6 + 9


@register_jitable
def _body_solution(X, u, theta, extra_input, idx, tc, tp, fs, fsig, fpow, fspl, fknot, consts,
                   extra, work):  # fmt: skip
    """Signals, loads F and body derivatives D at the body state X, with the α̇ and β̇ terms
    solved in closed form (equations module docstring): D = D0 + α̇ D_α + β̇ D_β.

    Everything is written into ``work`` (18 + len(extra_input) + ``_BODY_WORK`` entries);
    returns the views (sig, F, D) of it.
    """
    n_sig = 18 + extra_input.shape[0]
    sig = work[:n_sig]
    C = work[n_sig : n_sig + 8]
    F = work[n_sig + 8 : n_sig + 14]
    D = work[n_sig + 14 : n_sig + 23]
    signals_from_body_into(X, u, extra_input, consts[6], consts[7], extra[1], extra[2], sig)
    _loads(sig, X, u, theta, idx, tc, tp, fs, fsig, fpow, fspl, fknot, consts, extra, C, F)
    rigid_body_derivatives_into(X, F, consts, D)
    if idx[4] == 0 and idx[5] == 0:
        return sig, F, D
    F_alpha = work[n_sig + 23 : n_sig + 29]
    F_beta = work[n_sig + 29 : n_sig + 35]
    D_alpha = work[n_sig + 35 : n_sig + 44]
    D_beta = work[n_sig + 44 : n_sig + 53]
    F_trial = work[n_sig + 53 : n_sig + 59]
    D_trial = work[n_sig + 59 : n_sig + 68]
    for i in range(6):
        F_alpha[i] = 0.0
        F_beta[i] = 0.0
    for i in range(9):
        D_alpha[i] = 0.0
        D_beta[i] = 0.0
    # α̇̂ = α̇ c̄/(2V_n), β̇̂ = β̇ b/(2V_n): the signal of a unit rate
    k_alpha = _rate_normaliser(sig, extra, consts[7])
    k_beta = _rate_normaliser(sig, extra, consts[6])
    if idx[4] == 1:
        sig[ALPHADOT_SIGNAL] = k_alpha
        _loads(sig, X, u, theta, idx, tc, tp, fs, fsig, fpow, fspl, fknot, consts, extra, C,
               F_trial)  # fmt: skip
        sig[ALPHADOT_SIGNAL] = 0.0
        for i in range(6):
            # the loads of a unit α̇
            F_alpha[i] = F_trial[i] - F[i]
            F_trial[i] = F[i] + F_alpha[i]
        # D is affine in F: the response to the loads of a unit α̇
        rigid_body_derivatives_into(X, F_trial, consts, D_trial)
        for i in range(9):
            D_alpha[i] = D_trial[i] - D[i]
    if idx[5] == 1:
        sig[BETADOT_SIGNAL] = k_beta
        _loads(sig, X, u, theta, idx, tc, tp, fs, fsig, fpow, fspl, fknot, consts, extra, C,
               F_trial)  # fmt: skip
        sig[BETADOT_SIGNAL] = 0.0
        for i in range(6):
            F_beta[i] = F_trial[i] - F[i]
            F_trial[i] = F[i] + F_beta[i]
        rigid_body_derivatives_into(X, F_trial, consts, D_trial)
        for i in range(9):
            D_beta[i] = D_trial[i] - D[i]
    lateral = idx[3] == 1
    alpha_dot, beta_dot = solve_rate_terms(
        alpha_rate(X, D), alpha_rate(X, D_alpha), alpha_rate(X, D_beta),
        beta_rate(X, D, lateral), beta_rate(X, D_alpha, lateral), beta_rate(X, D_beta, lateral),
    )  # fmt: skip
    sig[ALPHADOT_SIGNAL] = alpha_dot * k_alpha
    sig[BETADOT_SIGNAL] = beta_dot * k_beta
    # D = D0 + α̇ D_α + β̇ D_β, F likewise
    for i in range(6):
        F[i] = F[i] + alpha_dot * F_alpha[i] + beta_dot * F_beta[i]
    for i in range(9):
        D[i] = D[i] + alpha_dot * D_alpha[i] + beta_dot * D_beta[i]
    return sig, F, D


@register_jitable
def _wind_body_state(x, X):
    """Body state of symmetric flight from (V, α, Θ, q), into ``X``:
    u = V cos α, w = V sin α, l_xz = −sin Θ, l_zz = cos Θ."""
    for i in range(9):
        X[i] = 0.0
    X[0] = x[0] * np.cos(x[1])
    X[2] = x[0] * np.sin(x[1])
    X[4] = x[3]
    X[6] = -np.sin(x[2])
    X[8] = np.cos(x[2])


@register_jitable
def _body_f(x, u, theta, src_state, src_input, wind_index, deriv_index, out_index, out_scale,
            extra_input, idx, tc, tp, fs, fsig, fpow, fspl, fknot, consts, extra, out):  # fmt: skip
    """dx/dt of a body-axis model into ``out``: the chosen entries of dX/dt (arguments as
    ``_body_h``'s, ``_kernel_arguments``)."""
    work = np.empty(9 + 18 + extra_input.shape[0] + _BODY_WORK)
    X = work[:9]
    # full body state X = (u, v, w, p, q, r, l_xz, l_yz, l_zz) from states and inputs
    body_state_from(x, u, src_state, src_input, wind_index, X)
    _, _, D = _body_solution(
        X, u, theta, extra_input, idx, tc, tp, fs, fsig, fpow, fspl, fknot, consts, extra,
        work[9:],
    )  # fmt: skip
    for i in range(deriv_index.shape[0]):
        out[i] = D[deriv_index[i]]


@register_jitable
def _body_h(x, u, theta, src_state, src_input, wind_index, deriv_index, out_index, out_scale,
            extra_input, idx, tc, tp, fs, fsig, fpow, fspl, fknot, consts, extra, out):  # fmt: skip
    """y of a body-axis model into ``out``: the chosen outputs, each times its scale
    (accelerometer sign and unit; 1 for the other outputs, see Accelerometer)."""
    work = np.empty(9 + 14 + 18 + extra_input.shape[0] + _BODY_WORK)
    X = work[:9]
    full = work[9:23]
    body_state_from(x, u, src_state, src_input, wind_index, X)
    sig, F, D = _body_solution(
        X, u, theta, extra_input, idx, tc, tp, fs, fsig, fpow, fspl, fknot, consts, extra,
        work[23:],
    )  # fmt: skip
    body_outputs_into(X, F, sig, consts, D[3], D[4], D[5], full)
    for i in range(out_index.shape[0]):
        out[i] = full[out_index[i]] * out_scale[i]


@register_jitable
def _wind_solution(x, u, theta, extra_input, idx, tc, tp, fs, fsig, fpow, fspl, fknot, consts,
                   extra, work):  # fmt: skip
    """Body state, signals, loads and d(V, α, Θ, q)/dt of the wind-axis form, with the α̇
    terms solved in closed form: α̇ = D0[1]/(1 − D_α[1]). Everything is written into
    ``work`` (9 + 18 + len(extra_input) + ``_BODY_WORK`` entries); returns the views
    (X, sig, F, D)."""
    n_sig = 18 + extra_input.shape[0]
    X = work[:9]
    sig = work[9 : 9 + n_sig]
    rest = work[9 + n_sig :]
    C = rest[:8]
    F = rest[8:14]
    D = rest[14:18]
    _wind_body_state(x, X)
    signals_from_body_into(X, u, extra_input, consts[6], consts[7], extra[1], extra[2], sig)
    _loads(sig, X, u, theta, idx, tc, tp, fs, fsig, fpow, fspl, fknot, consts, extra, C, F)
    wind_axis_derivatives_into(x[0], x[1], x[2], x[3], F, consts, D)
    if idx[4] == 1:
        F_alpha = rest[18:24]
        F_trial = rest[24:30]
        D_alpha = rest[30:34]
        D_trial = rest[34:38]
        # α̇̂ = α̇ c̄/(2V_n) of a unit α̇
        k_alpha = _rate_normaliser(sig, extra, consts[7])
        sig[ALPHADOT_SIGNAL] = k_alpha
        _loads(sig, X, u, theta, idx, tc, tp, fs, fsig, fpow, fspl, fknot, consts, extra, C,
               F_trial)  # fmt: skip
        for i in range(6):
            F_alpha[i] = F_trial[i] - F[i]
            F_trial[i] = F[i] + F_alpha[i]
        wind_axis_derivatives_into(x[0], x[1], x[2], x[3], F_trial, consts, D_trial)
        for i in range(4):
            D_alpha[i] = D_trial[i] - D[i]
        # α̇ = D0[1] + α̇ D_α[1]  ⇒  α̇ = D0[1]/(1 − D_α[1])
        alpha_dot = D[1] / (1.0 - D_alpha[1])
        sig[ALPHADOT_SIGNAL] = alpha_dot * k_alpha
        for i in range(6):
            F[i] = F[i] + alpha_dot * F_alpha[i]
        for i in range(4):
            D[i] = D[i] + alpha_dot * D_alpha[i]
    return X, sig, F, D


@register_jitable
def _wind_f(x, u, theta, out_index, out_scale, extra_input, idx, tc, tp, fs, fsig, fpow, fspl,
            fknot, consts, extra, out):  # fmt: skip
    """d(V, α, Θ, q)/dt of the wind-axis model into ``out`` (arguments as ``_wind_h``'s)."""
    work = np.empty(9 + 18 + extra_input.shape[0] + _BODY_WORK)
    _, _, _, D = _wind_solution(
        x, u, theta, extra_input, idx, tc, tp, fs, fsig, fpow, fspl, fknot, consts, extra, work
    )
    for i in range(4):
        out[i] = D[i]


@register_jitable
def _wind_h(x, u, theta, out_index, out_scale, extra_input, idx, tc, tp, fs, fsig, fpow, fspl,
            fknot, consts, extra, out):  # fmt: skip
    """y of the wind-axis model into ``out`` (chosen outputs times their scales)."""
    work = np.empty(14 + 9 + 18 + extra_input.shape[0] + _BODY_WORK)
    full = work[:14]
    X, sig, F, D = _wind_solution(
        x, u, theta, extra_input, idx, tc, tp, fs, fsig, fpow, fspl, fknot, consts, extra,
        work[14:],
    )  # fmt: skip
    # symmetric flight: ṗ = ṙ = 0, q̇ = M/I_y
    body_outputs_into(X, F, sig, consts, 0.0, D[3], 0.0, full)
    for i in range(out_index.shape[0]):
        out[i] = full[out_index[i]] * out_scale[i]


@register_jitable
def _alpha_q_f(x, u, theta, out_index, out_scale, tc, tp, fs, fsig, fpow, fspl, fknot, consts,
               out):  # fmt: skip
    """d(α, q)/dt of the α–q model into ``out``: signals (α, q̂, inputs…), then C_Z, C_m from
    the aero tables [2.16] (equations.alpha_q_derivatives; arguments as ``_alpha_q_h``'s)."""
    work = np.empty(10 + u.shape[0])
    sig = work[: 2 + u.shape[0]]
    C = work[2 + u.shape[0] :]
    alpha_q_signals_into(x, u, consts[7], sig)
    aero_coefficients_into(sig, theta, tc, tp, fs, fsig, fpow, fspl, fknot, C)
    alpha_q_derivatives_into(x, u, C, consts, out)


@register_jitable
def _alpha_q_h(x, u, theta, out_index, out_scale, tc, tp, fs, fsig, fpow, fspl, fknot, consts,
               out):  # fmt: skip
    """y of the α–q model into ``out`` (chosen outputs times their scales)."""
    work = np.empty(13 + u.shape[0])
    sig = work[: 2 + u.shape[0]]
    C = work[2 + u.shape[0] : 10 + u.shape[0]]
    full = work[10 + u.shape[0] :]
    alpha_q_signals_into(x, u, consts[7], sig)
    aero_coefficients_into(sig, theta, tc, tp, fs, fsig, fpow, fspl, fknot, C)
    alpha_q_outputs_into(x, u, C, consts, full)
    for i in range(out_index.shape[0]):
        out[i] = full[out_index[i]] * out_scale[i]


# the table path's f and h kernels by model kind: out form, arguments (x, u, θ, the
# ``_kernel_arguments`` of the model, out)
_TABLE_KERNELS = {
    "alpha_q": (_alpha_q_f, _alpha_q_h),
    "wind": (_wind_f, _wind_h),
    "6dof": (_body_f, _body_h),
    "longitudinal": (_body_f, _body_h),
    "lateral": (_body_f, _body_h),
}


def _kernel_arguments(spec: ModelSpec) -> tuple:
    """The arguments of the model's table-path kernels after (x, u, θ): the index maps and
    output scales of ``spec`` its kind has, the aerodynamic tables, ``equations.CONSTANTS``
    and (but α–q) ``EXTRA_CONSTANTS`` values."""
    tables = spec.tables
    aero = (
        tables.term_coef, tables.term_param, tables.factor_start, tables.factor_signal,
        tables.factor_power, tables.factor_spline, tables.factor_knot,
    )  # fmt: skip
    if spec.kind == "alpha_q":
        return (spec.out_index, spec.out_scale, *aero, spec.consts)
    engine = (spec.extra_input, spec.idx, *aero, spec.consts, spec.extra)
    if spec.kind == "wind":
        return (spec.out_index, spec.out_scale, *engine)
    return (
        spec.src_state, spec.src_input, spec.wind_index, spec.deriv_index, spec.out_index,
        spec.out_scale, *engine,
    )  # fmt: skip


def _table_functions(spec: ModelSpec, n_states: int):
    """f and h closures of the table path (``_TABLE_KERNELS`` over ``_kernel_arguments``),
    in return form carrying their out forms (``flightid.model.forms``). The arguments are
    one constant tuple, unpacked into the call: numba compiles the same calls as with the
    arrays named one by one."""
    f_kernel, h_kernel = _TABLE_KERNELS[spec.kind]
    args = _kernel_arguments(spec)
    n_outputs = spec.out_index.shape[0]

    def f_out(t, x, u, theta, out):
        f_kernel(x, u, theta, *args, out)

    def h_out(t, x, u, theta, out):
        h_kernel(x, u, theta, *args, out)

    def f(t, x, u, theta):
        out = np.empty(n_states)
        f_kernel(x, u, theta, *args, out)
        return out

    def h(t, x, u, theta):
        out = np.empty(n_outputs)
        h_kernel(x, u, theta, *args, out)
        return out

    return with_out_form(f, f_out), with_out_form(h, h_out)


# The lateral model's two ways of taking the measured longitudinal motion.
LATERAL_MEASURED = (("u", "w", "q"), ("V", "alpha", "q"))


def _measured_inputs(kind: str, default: tuple[str, ...], measured) -> tuple[str, ...]:
    """The other axis's measured motion entering as inputs (checked)."""
    if measured is None:
        return default
    if isinstance(measured, str) or not isinstance(measured, Sequence):
        raise InputTypeError(
            f"measured: expected a list of names such as ['V', 'alpha', 'q'], "
            f"got {describe(measured)}"
        )
    measured = tuple(measured)
    if kind != "lateral":
        if measured != default:
            raise InputError(
                f"measured: the {kind} model takes the measured inputs {list(default)}, "
                f"got {list(measured)}"
            )
        return measured
    if sorted(measured) not in [sorted(choice) for choice in LATERAL_MEASURED]:
        raise InputError(
            f"measured: the lateral model takes u, w, q (m/s, m/s, rad/s) or V, alpha, q "
            f"(m/s, rad, rad/s) as measured inputs, in any order; got {list(measured)}"
        )
    return measured


def _build(
    kind: str,
    airplane: Airplane,
    aero: AeroModel,
    parameters: Parameters | None,
    controls: Sequence[str] | None,
    outputs: Sequence[str] | None,
    x0,
    name: str | None,
    accelerometer=None,
    measured: Sequence[str] | None = None,
    reference_speed: float | None = None,
    rate_speed: str = "V",
    code: str = "generated",
) -> StateSpaceModel:
    """The model of ``kind`` (a key of ``_KINDS``): checked arguments, input and output
    names, parameters, then f and h from the numeric tables (``_model_functions``)."""
    if code not in MODEL_CODES:
        raise InputError(f"code: expected one of {list(MODEL_CODES)}, got {describe(code)}")
    if not isinstance(airplane, Airplane):
        raise InputTypeError(f"airplane: expected an Airplane, got {describe(airplane)}")
    if not isinstance(aero, AeroModel):
        raise InputTypeError(f"aero: expected an AeroModel, got {describe(aero)}")
    if kind == "alpha_q":
        _check_alpha_q(airplane, aero)
    _check_reference_speed(aero, reference_speed, rate_speed)
    _check_rate_terms(kind, aero)
    _check_airplane(kind, airplane, aero)
    states, default_measured, default_outputs = _KINDS[kind]
    measured = _measured_inputs(kind, default_measured, measured)
    outputs = _output_names(kind, default_outputs, outputs)
    inputs = _input_names(kind, airplane, aero, states, controls, outputs, measured)
    parameters = _model_parameters(aero, parameters)
    f, h = _model_functions(
        kind, airplane, aero, parameters, states, inputs, outputs, measured, accelerometer,
        _extra_constants(airplane, reference_speed, rate_speed), code,
    )  # fmt: skip
    return StateSpaceModel(
        states=states,
        inputs=inputs,
        outputs=outputs,
        f=f,
        h=h,
        parameters=parameters,
        x0=tuple(x0) if x0 is not None else (),
        name=name or f"{airplane.name} {kind}",
    )


# Which kinds may use the α̇ and β̇ terms: α̇ needs u̇ and ẇ of the model (not measured u,
# w), β̇ needs v̇ of the model.
_RATE_TERM_KINDS = {
    "alphadot_hat": ("6dof", "longitudinal", "wind"),
    "betadot_hat": ("6dof", "lateral"),
}


def _check_reference_speed(aero: AeroModel, reference_speed, rate_speed) -> None:
    """V/V0, (V − V0)/V0 and rate_speed = "V0" need the reference speed V0 > 0 (m/s)."""
    if rate_speed not in ("V", "V0"):
        raise InputError(
            f"rate_speed: expected 'V' (p̂ = p b/2V, …) or 'V0' (p̂ = p b/2V0, …), "
            f"got {describe(rate_speed)}"
        )
    if reference_speed is not None and (
        isinstance(reference_speed, bool)
        or not isinstance(reference_speed, (int, float))
        or not math.isfinite(reference_speed)
        or reference_speed <= 0
    ):
        raise InputError(
            f"reference_speed: expected V0 > 0 in m/s or None, got {describe(reference_speed)}"
        )
    users = [s for s in aero.signals if s in ("Vrel", "dVrel")]
    if rate_speed == "V0":
        users.append("rate_speed = 'V0'")
    if users and reference_speed is None:
        raise InputError(
            f"reference_speed: {users} need the reference speed V0 (m/s); give reference_speed=V0"
        )


def _check_rate_terms(kind: str, aero: AeroModel) -> None:
    """α̇̂ and β̇̂ enter linearly (power 1, no spline or abs) and only where the model
    integrates the motion they differentiate (``_RATE_TERM_KINDS``)."""
    for coefficient in aero.coefficients:
        for term in aero.terms(coefficient):
            for key, power in term.factors:
                name = key.signal if isinstance(key, (Spline, Abs)) else key
                if name not in _RATE_TERM_KINDS:
                    continue
                if kind not in _RATE_TERM_KINDS[name]:
                    raise InputError(
                        f"aero: {coefficient} term {term.label!r}: {name} terms need the "
                        f"model's own {'α̇' if name == 'alphadot_hat' else 'β̇'}; the models "
                        f"that have it: {list(_RATE_TERM_KINDS[name])}, this one is {kind!r}"
                    )
                if power != 1 or isinstance(key, (Spline, Abs)):
                    raise InputError(
                        f"aero: {coefficient} term {term.label!r}: {name} must enter linearly "
                        "(power 1, no spline or abs), so that the implicit equations are "
                        "solved in closed form"
                    )


def _check_airplane(kind: str, airplane: Airplane, aero: AeroModel) -> None:
    """The lateral and 6-DOF models need I_x, I_z and b; terms in p̂, r̂, β̇̂ need b."""
    if kind in ("6dof", "lateral"):
        label = "the 6-DOF model" if kind == "6dof" else "the lateral model"
        airplane.require(("Ix", "Iz", "b"), label)
    uses_span = [s for s in aero.signals if s in ("phat", "rhat", "betadot_hat")]
    if uses_span:
        airplane.require(("b",), f"the aerodynamic terms in {uses_span}")
    if kind in ("wind", "alpha_q"):
        for field in ("propeller_torque_input", "engine_momentum_input"):
            if getattr(airplane, field) is not None:
                raise AirplaneDataError(
                    f"airplane.{field}: the {kind} model has no roll or yaw motion for the "
                    f"engine terms; expected None, got {getattr(airplane, field)!r}"
                )


def _check_alpha_q(airplane: Airplane, aero: AeroModel) -> None:
    """The α–q model takes C_Z and C_m only, and thrust through the measured a_x."""
    if sorted(aero.coefficients) != ["CZ", "Cm"]:
        raise InputError(
            f"aero: the α–q model takes the coefficients CZ and Cm (both, no others), got "
            f"{list(aero.coefficients)}"
        )
    if airplane.thrust_input is not None:
        raise InputError(
            f"airplane.thrust_input: the α–q model carries thrust in the measured a_x; expected "
            f"None, got {airplane.thrust_input!r}"
        )


def _output_names(
    kind: str, default: tuple[str, ...], outputs: Sequence[str] | None
) -> tuple[str, ...]:
    """The chosen output names (default: the kind's), checked against ``OUTPUTS``."""
    outputs = tuple(default if outputs is None else outputs)
    unknown = [o for o in outputs if o not in OUTPUTS]
    if unknown:
        raise InputError(f"outputs: unknown output names {unknown}; available: {list(OUTPUTS)}")
    if kind == "alpha_q":
        bad = [o for o in outputs if o not in ALPHA_Q_OUTPUTS]
        if bad:
            raise InputError(
                f"outputs: the α–q model has the outputs {list(ALPHA_Q_OUTPUTS)}, got {bad}"
            )
    if kind == "wind":
        bad = [o for o in outputs if o in ("beta", "phi", "ay", "p", "r", "pdot", "rdot")]
        if bad:
            raise InputError(
                f"outputs: the wind-axis longitudinal model has no lateral outputs, got {bad}"
            )
    # the decoupled models integrate only their own axis: ṗ, ṙ (q̇) would be model values
    # for measured motion
    other_axis = {"longitudinal": ("pdot", "rdot"), "lateral": ("qdot",)}.get(kind, ())
    bad = [o for o in outputs if o in other_axis]
    if bad:
        raise InputError(
            f"outputs: the {kind} model takes the other axis's motion as measured inputs and has "
            f"no output {bad}"
        )
    return outputs


def _input_names(
    kind: str,
    airplane: Airplane,
    aero: AeroModel,
    states: tuple[str, ...],
    controls: Sequence[str] | None,
    outputs: tuple[str, ...],
    measured: tuple[str, ...],
) -> tuple[str, ...]:
    """Inputs: the controls, the thrust (where the model uses it), the measured motion
    (α–q model: the measured variables first, then the controls)."""
    if kind == "alpha_q":
        return _alpha_q_input_names(aero, states, controls, measured)
    if controls is None:
        # the aerodynamic model's signals that are not standard signals, in first-use order
        controls = tuple(s for s in aero.signals if s not in SIGNALS and s != airplane.thrust_input)
    if isinstance(controls, str):
        raise InputTypeError(f"controls: expected a list of names, got the string {controls!r}")
    controls = tuple(controls)
    clash = sorted(set(controls) & (set(SIGNALS) | set(states)))
    if clash:
        raise InputError(
            f"controls: {clash} are names of standard signals or states; choose other names"
        )
    inputs = controls
    # thrust acts on u, w, q and a_x, a_z: the lateral model takes it only for a_x, a_z
    needs_thrust = kind != "lateral" or bool({"ax", "az"} & set(outputs))
    if needs_thrust and airplane.thrust_input is not None and airplane.thrust_input not in inputs:
        inputs = inputs + (airplane.thrust_input,)
    # engine: the propeller torque acts on p (6-DOF, lateral), the rotor momentum on q and r
    engine = [airplane.engine_momentum_input]
    if kind in ("6dof", "lateral"):
        engine.append(airplane.propeller_torque_input)
    for channel in engine:
        if channel is not None and channel not in inputs:
            inputs = inputs + (channel,)
    return inputs + measured


def _alpha_q_input_names(
    aero: AeroModel,
    states: tuple[str, ...],
    controls: Sequence[str] | None,
    measured: tuple[str, ...],
) -> tuple[str, ...]:
    """Inputs of the α–q model: V, q̄, Θ, Φ, a_x, p, r, then the controls (default: the aero
    model's signals other than alpha, qhat and the measured ones, in first-use order)."""
    if controls is None:
        controls = tuple(s for s in aero.signals if s not in ("alpha", "qhat", *measured))
    if isinstance(controls, str):
        raise InputTypeError(f"controls: expected a list of names, got the string {controls!r}")
    controls = tuple(controls)
    clash = sorted(set(controls) & {"alpha", "qhat", *states, *measured})
    if clash:
        raise InputError(
            f"controls: {clash} are names of the α–q model's signals, states or measured "
            "inputs; choose other names"
        )
    return measured + controls


def _model_parameters(aero: AeroModel, parameters) -> Parameters:
    """The full parameter set (default: the aero model's, all zero), holding every
    parameter of the aerodynamic model."""
    if parameters is None:
        parameters = aero.parameters()
    elif not isinstance(parameters, Parameters):
        parameters = Parameters(parameters)
    missing = [n for n in aero.parameter_names if n not in parameters]
    if missing:
        raise InputError(
            f"parameters: missing the aerodynamic model's parameters {missing}; "
            f"use aero.parameters(values) to build them"
        )
    return parameters


def _model_functions(
    kind: str,
    airplane: Airplane,
    aero: AeroModel,
    parameters: Parameters,
    states: tuple[str, ...],
    inputs: tuple[str, ...],
    outputs: tuple[str, ...],
    measured: tuple[str, ...],
    accelerometer,
    extra_consts: np.ndarray,
    code: str = "generated",
):
    """f and h of the model from the index maps from names to positions, the aerodynamic
    tables and the airplane constants: generated straight-line code (``code="generated"``,
    where ``codegen`` covers the model) or the table path closing over them
    (``_table_functions``)."""
    if kind == "alpha_q":
        # signal list: α, q̂, then every input (V, q̄, Θ, Φ, a_x, p, r, controls…)
        tables = aero.tables(("alpha", "qhat", *inputs), parameters)
        az_scale = Accelerometer.from_value(accelerometer).factors(airplane.g)[2]
        out_index = np.array([ALPHA_Q_OUTPUTS.index(o) for o in outputs], dtype=np.int64)
        # per output: s_z·k for az (Accelerometer.factors), 1 for alpha and q
        out_scale = np.array([az_scale if o == "az" else 1.0 for o in outputs])
        spec = ModelSpec(kind, tables, _constants(airplane), out_index, out_scale)
        return _chosen_functions(spec, code, len(states))
    # signal list: the standard signals, then the non-standard inputs (controls, thrust)
    extra = [i for i, n in enumerate(inputs) if n not in SIGNALS]
    signal_names = SIGNALS + tuple(inputs[i] for i in extra)
    tables = aero.tables(signal_names, parameters)
    consts = _constants(airplane)
    extra_input = np.array(extra, dtype=np.int64)
    index = lambda name: inputs.index(name) if name in inputs else -1  # noqa: E731
    signals = set(aero.signals)
    # thrust, propeller torque, engine momentum input indices (−1: none), lateral flag (β̇
    # from v̇ alone), and whether the model has α̇ and β̇ terms
    idx = np.array(
        [
            index(airplane.thrust_input),
            index(airplane.propeller_torque_input),
            index(airplane.engine_momentum_input),
            1 if kind == "lateral" else 0,
            1 if "alphadot_hat" in signals else 0,
            1 if "betadot_hat" in signals else 0,
        ],
        dtype=np.int64,
    )
    out_index = np.array([OUTPUTS.index(o) for o in outputs], dtype=np.int64)
    # per output: s_a·k for ax, ay, az (Accelerometer.factors), 1 for the others
    accel = Accelerometer.from_value(accelerometer).factors(airplane.g)
    out_scale = np.array(
        [accel[("ax", "ay", "az").index(o)] if o in ("ax", "ay", "az") else 1.0 for o in outputs]
    )
    if kind == "wind":
        spec = ModelSpec(
            kind, tables, consts, out_index, out_scale, extra_consts, extra_input, idx
        )  # fmt: skip
        return _chosen_functions(spec, code, len(states))
    src_state = np.array(
        [states.index(s) if s in states else -1 for s in BODY_STATES], dtype=np.int64
    )
    src_input = np.array(
        [inputs.index(s) if s in measured else -1 for s in BODY_STATES], dtype=np.int64
    )
    # input indices of V and α when they replace u and w (lateral model), else −1
    wind_index = np.array(
        [inputs.index("V"), inputs.index("alpha")] if "V" in measured else [-1, -1],
        dtype=np.int64,
    )
    deriv_index = np.array([BODY_STATES.index(s) for s in states], dtype=np.int64)
    spec = ModelSpec(
        kind, tables, consts, out_index, out_scale, extra_consts, extra_input, idx, src_state,
        src_input, wind_index, deriv_index,
    )  # fmt: skip
    return _chosen_functions(spec, code, len(states))


# the two implementations of a built-in model's f and h (builders' ``code`` argument)
MODEL_CODES = ("generated", "tables")


def _chosen_functions(spec: ModelSpec, code: str, n_states: int):
    """f and h (return form carrying the out form) of the model ``spec``: the generated
    straight-line module (``codegen``, ``generated``) where ``code`` is "generated" and
    ``codegen.uncovered(spec)`` is None, else the table path (``_table_functions``). Each
    function says which in its attribute ``model_code`` ("generated" or "tables")."""
    if code == "generated" and uncovered(spec) is None:
        module = load_source(model_source(spec))
        f = with_out_form(module.f, module.f_out)
        h = with_out_form(module.h, module.h_out)
        f.model_code = h.model_code = "generated"
        return f, h
    f, h = _table_functions(spec, n_states)
    f.model_code = h.model_code = "tables"
    return f, h


def _model_builder(kind: str, name: str, doc: str):
    """A public builder of the ``kind`` model: ``(airplane, aero, parameters=None, *,
    controls, outputs, x0, name, accelerometer, measured) -> StateSpaceModel``."""

    def build(
        airplane: Airplane,
        aero: AeroModel,
        parameters: Parameters | None = None,
        *,
        controls: Sequence[str] | None = None,
        outputs: Sequence[str] | None = None,
        x0=None,
        name: str | None = None,
        accelerometer: Accelerometer | Mapping[str, str] | str | None = None,
        measured: Sequence[str] | None = None,
        reference_speed: float | None = None,
        rate_speed: str = "V",
        code: str = "generated",
    ) -> StateSpaceModel:
        return _build(
            kind, airplane, aero, parameters, controls, outputs, x0, name, accelerometer,
            measured, reference_speed, rate_speed, code,
        )  # fmt: skip

    build.__name__ = build.__qualname__ = name
    build.__doc__ = doc
    return build


six_dof_model = _model_builder(
    "6dof",
    "six_dof_model",
    """Body-axis 6-DOF model, states (u, v, w, p, q, r, l_xz, l_yz, l_zz) [2.5–2.13].

    Args:
        airplane: mass, inertia, geometry, density, thrust line.
        aero: the aerodynamic model; its parameters must be in ``parameters``.
        parameters: full parameter set (default: the aero model's parameters, all zero).
        controls: control input names (default: the aero model's non-standard signals).
        outputs: output names (default all: V, alpha, beta, theta, phi, ax, ay, az, p, q, r).
        x0: initial state (numbers or parameter names), e.g. from ``trim``.
        accelerometer: sign and unit convention of the outputs ax, ay, az: an
            ``Accelerometer``, a mapping of its fields (``{"az": "up", "unit": "m/s^2"}``), a
            preset (``"body"``, ``"load_factor"``) or None (body axes, g units, a_z ≈ −1 g in
            level flight).
        measured: the other axis's measured motion taken as inputs; only the lateral model
            offers a choice (the 6-DOF model has none: None or ``()``).
        reference_speed: V0, m/s, for the signals Vrel = V/V0 and dVrel = (V − V0)/V0 and
            for ``rate_speed = "V0"``.
        rate_speed: "V" (default: p̂ = p b/2V, q̂ = q c̄/2V, r̂, α̇̂ = α̇ c̄/2V, β̇̂ = β̇ b/2V)
            or "V0" (the same with the constant V0).
        code: "generated" (default: f and h as straight-line code written for this model,
            ``flightid.aircraft.codegen``, where it covers the model, else the table path)
            or "tables" (the reference: f and h walking the aerodynamic term tables).

    Outputs may include pdot, qdot, rdot (rad/s², the angular accelerations). Terms in
    alphadot_hat (6-DOF, longitudinal, wind-axis models) and betadot_hat (6-DOF, lateral)
    are solved in closed form (``flightid.aircraft.equations``).
    """,
)

longitudinal_model = _model_builder(
    "longitudinal",
    "longitudinal_model",
    """Decoupled longitudinal model: states (u, w, q, l_xz, l_yz, l_zz); the measured lateral
    motion v (m/s), p, r (rad/s) enters as inputs [2.27–2.29]. Default outputs V, alpha, q,
    theta, ax, az. Arguments as for ``six_dof_model``.""",
)

lateral_model = _model_builder(
    "lateral",
    "lateral_model",
    """Decoupled lateral model: states (v, p, r, l_xz, l_yz, l_zz); the measured longitudinal
    motion enters as inputs [2.30–2.32]: u, w (m/s) and q (rad/s) by default, or with
    ``measured=("V", "alpha", "q")`` the airspeed V (m/s), angle of attack α (rad) and q, from
    which u = V cos α cos β and w = V sin α cos β with sin β = v/V. Default outputs beta, p,
    r, phi, ay. Other arguments as for ``six_dof_model``.""",
)

wind_axis_longitudinal_model = _model_builder(
    "wind",
    "wind_axis_longitudinal_model",
    """Wind-axis longitudinal model: states (V, alpha, theta, q) (m/s, rad, rad, rad/s) of
    symmetric flight. Default outputs V, alpha, theta, q, ax, az. Arguments as for
    ``six_dof_model``.""",
)

alpha_q_longitudinal_model = _model_builder(
    "alpha_q",
    "alpha_q_longitudinal_model",
    """α–q longitudinal model: states (alpha, q) (rad, rad/s); the measured V, q̄, Θ, Φ, a_x
    (g), p, r enter as inputs, in that order, followed by the controls (body axes, β ≈ 0,
    thrust carried by the measured a_x; equations in ``flightid.aircraft.equations``):

        dα/dt = q + (q̄S/(mV)) C_Z cos α − (g a_x/V) sin α + (g/V)(cos Φ cos Θ cos α + sin Θ sin α)
        dq/dt = (q̄ S c̄ C_m + (I_z − I_x) p r + I_xz (r² − p²))/I_y
        outputs alpha, q, az = q̄ S C_Z/(m g) (g units; ``accelerometer`` may change sign/unit)

    ``aero`` gives exactly the coefficients CZ and Cm, with terms in alpha, qhat = q c̄/(2V)
    and any input channel (measured variables or controls, e.g. ``de`` in rad). The airplane's
    mass, S, c̄, I_x, I_y, I_z, I_xz and g are used, in any one consistent unit system (q̄ is
    measured, so ρ is not used, nor b); ``thrust_input`` must be None. Outputs: any of alpha,
    q, az. Other arguments as for ``six_dof_model`` (``measured`` is fixed: None or the list
    above).""",
)
