"""State-space models of an airplane: 6-DOF, decoupled longitudinal and lateral, wind axes.

Every builder returns a ``flightid.model.StateSpaceModel`` whose ``f`` and ``h`` are fresh
closures over numeric tables only (constants, index maps, the aerodynamic term tables), so the
simulator can numba-compile them and the pure-Python path runs the very same code.

Models (RP-1153 §2.A, METHOD.md §3):

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
Outputs are chosen by name from V, alpha, beta, theta, phi, ax, ay, az, p, q, r; the
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
from flightid.aircraft.airplane import Airplane
from flightid.aircraft.equations import (
    ALPHA_Q_INPUTS,
    ALPHA_Q_OUTPUTS,
    BODY_STATES,
    OUTPUTS,
    SIGNALS,
    aero_coefficients,
    alpha_q_derivatives,
    alpha_q_outputs,
    alpha_q_signals,
    body_outputs,
    forces_and_moments,
    rigid_body_derivatives,
    signals_from_body,
    wind_axis_derivatives,
)
from flightid.errors import InputError, InputTypeError, describe
from flightid.model.parameters import Parameters
from flightid.model.statespace import StateSpaceModel

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
    "6dof": (BODY_STATES, (), OUTPUTS),
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
    return np.array(
        [
            airplane.mass,
            airplane.Ix,
            airplane.Iy,
            airplane.Iz,
            airplane.Ixz,
            airplane.S,
            airplane.b,
            airplane.cbar,
            airplane.rho,
            airplane.g,
            airplane.thrust_inclination,
        ],
        dtype=float,
    )


@register_jitable
def body_state_from(x, u, src_state, src_input, wind_index):
    """Full body state X = (u, v, w, p, q, r, l_xz, l_yz, l_zz) of a body-axis model.

    Each entry comes from the model state (``src_state[i] ≥ 0``) or an input
    (``src_input[i] ≥ 0``). When the lateral model measures V and α instead of u and w
    (``wind_index`` = input indices of V and α, else −1), with sin β = v/V [2.20]:

        u = V cos α cos β,   w = V sin α cos β                          [2.19–2.21]
    """
    X = np.zeros(9)
    for i in range(9):
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
    return X


@register_jitable
def _loads(X, u, theta, extra_input, thrust_index, tc, tp, fs, fsig, fpow, fspl, fknot, consts):
    """Signals (α, V, rates, controls…), then C = aero model, then forces and moments."""
    sig = signals_from_body(X, u, extra_input, consts[6], consts[7])
    C = aero_coefficients(sig, theta, tc, tp, fs, fsig, fpow, fspl, fknot)
    thrust = u[thrust_index] if thrust_index >= 0 else 0.0
    return sig, forces_and_moments(C, sig[1], sig[0], thrust, consts)


@register_jitable
def _wind_body_state(x):
    """Body state of symmetric flight from (V, α, Θ, q):
    u = V cos α, w = V sin α, l_xz = −sin Θ, l_zz = cos Θ."""
    X = np.zeros(9)
    X[0] = x[0] * np.cos(x[1])
    X[2] = x[0] * np.sin(x[1])
    X[4] = x[3]
    X[6] = -np.sin(x[2])
    X[8] = np.cos(x[2])
    return X


@register_jitable
def _select(full, index, scale):
    """The chosen entries of ``full``, each times its scale (accelerometer sign and unit;
    1 for the other outputs, see Accelerometer)."""
    y = np.empty(index.shape[0])
    for i in range(index.shape[0]):
        y[i] = full[index[i]] * scale[i]
    return y


def _body_functions(src_state, src_input, wind_index, deriv_index, out_index, out_scale,
                    extra_input, thrust_index, tables, consts):  # fmt: skip
    """f and h closures of a body-axis model (6-DOF or decoupled)."""
    tc, tp, fs = tables.term_coef, tables.term_param, tables.factor_start
    fsig, fpow = tables.factor_signal, tables.factor_power
    fspl, fknot = tables.factor_spline, tables.factor_knot
    ones = np.ones(deriv_index.shape[0])

    def f(t, x, u, theta):
        # full body state X = (u, v, w, p, q, r, l_xz, l_yz, l_zz) from states and inputs
        X = body_state_from(x, u, src_state, src_input, wind_index)
        _, F = _loads(
            X, u, theta, extra_input, thrust_index, tc, tp, fs, fsig, fpow, fspl, fknot, consts
        )
        return _select(rigid_body_derivatives(X, F, consts), deriv_index, ones)

    def h(t, x, u, theta):
        X = body_state_from(x, u, src_state, src_input, wind_index)
        sig, F = _loads(
            X, u, theta, extra_input, thrust_index, tc, tp, fs, fsig, fpow, fspl, fknot, consts
        )
        return _select(body_outputs(X, F, sig, consts), out_index, out_scale)

    return f, h


def _wind_functions(out_index, out_scale, extra_input, thrust_index, tables, consts):
    """f and h closures of the wind-axis longitudinal model (states V, α, Θ, q)."""
    tc, tp, fs = tables.term_coef, tables.term_param, tables.factor_start
    fsig, fpow = tables.factor_signal, tables.factor_power
    fspl, fknot = tables.factor_spline, tables.factor_knot

    def f(t, x, u, theta):
        _, F = _loads(
            _wind_body_state(x),
            u,
            theta,
            extra_input,
            thrust_index,
            tc,
            tp,
            fs,
            fsig,
            fpow,
            fspl,
            fknot,
            consts,
        )
        return wind_axis_derivatives(x[0], x[1], x[2], x[3], F, consts)

    def h(t, x, u, theta):
        X = _wind_body_state(x)
        sig, F = _loads(
            X, u, theta, extra_input, thrust_index, tc, tp, fs, fsig, fpow, fspl, fknot, consts
        )
        return _select(body_outputs(X, F, sig, consts), out_index, out_scale)

    return f, h


def _alpha_q_functions(out_index, out_scale, tables, consts):
    """f and h closures of the α–q model (states α, q; inputs V, q̄, Θ, Φ, a_x, p, r,
    controls…; equations.alpha_q_derivatives)."""
    tc, tp, fs = tables.term_coef, tables.term_param, tables.factor_start
    fsig, fpow = tables.factor_signal, tables.factor_power
    fspl, fknot = tables.factor_spline, tables.factor_knot
    cbar = consts[7]

    def f(t, x, u, theta):
        # signals (α, q̂, inputs…), then C_Z, C_m from the aero tables [2.16]
        sig = alpha_q_signals(x, u, cbar)
        C = aero_coefficients(sig, theta, tc, tp, fs, fsig, fpow, fspl, fknot)
        return alpha_q_derivatives(x, u, C, consts)

    def h(t, x, u, theta):
        sig = alpha_q_signals(x, u, cbar)
        C = aero_coefficients(sig, theta, tc, tp, fs, fsig, fpow, fspl, fknot)
        return _select(alpha_q_outputs(x, u, C, consts), out_index, out_scale)

    return f, h


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
) -> StateSpaceModel:
    """The model of ``kind`` (a key of ``_KINDS``): checked arguments, input and output
    names, parameters, then the f and h closures over the numeric tables."""
    if not isinstance(airplane, Airplane):
        raise InputTypeError(f"airplane: expected an Airplane, got {describe(airplane)}")
    if not isinstance(aero, AeroModel):
        raise InputTypeError(f"aero: expected an AeroModel, got {describe(aero)}")
    if kind == "alpha_q":
        _check_alpha_q(airplane, aero)
    states, default_measured, default_outputs = _KINDS[kind]
    measured = _measured_inputs(kind, default_measured, measured)
    outputs = _output_names(kind, default_outputs, outputs)
    inputs = _input_names(kind, airplane, aero, states, controls, outputs, measured)
    parameters = _model_parameters(aero, parameters)
    f, h = _model_functions(
        kind, airplane, aero, parameters, states, inputs, outputs, measured, accelerometer
    )
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
        bad = [o for o in outputs if o in ("beta", "phi", "ay", "p", "r")]
        if bad:
            raise InputError(
                f"outputs: the wind-axis longitudinal model has no lateral outputs, got {bad}"
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
    # thrust acts on u, w and a_x, a_z only: the lateral model takes it only for those outputs
    needs_thrust = kind != "lateral" or bool({"ax", "az"} & set(outputs))
    if needs_thrust and airplane.thrust_input is not None and airplane.thrust_input not in inputs:
        inputs = inputs + (airplane.thrust_input,)
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
):
    """f and h of the model: the index maps from names to positions, the aerodynamic
    tables and the airplane constants, closed over by ``_wind_functions`` /
    ``_body_functions``."""
    if kind == "alpha_q":
        # signal list: α, q̂, then every input (V, q̄, Θ, Φ, a_x, p, r, controls…)
        tables = aero.tables(("alpha", "qhat", *inputs), parameters)
        az_scale = Accelerometer.from_value(accelerometer).factors(airplane.g)[2]
        out_index = np.array([ALPHA_Q_OUTPUTS.index(o) for o in outputs], dtype=np.int64)
        # per output: s_z·k for az (Accelerometer.factors), 1 for alpha and q
        out_scale = np.array([az_scale if o == "az" else 1.0 for o in outputs])
        return _alpha_q_functions(out_index, out_scale, tables, _constants(airplane))
    # signal list: the standard signals, then the non-standard inputs (controls, thrust)
    extra = [i for i, n in enumerate(inputs) if n not in SIGNALS]
    signal_names = SIGNALS + tuple(inputs[i] for i in extra)
    tables = aero.tables(signal_names, parameters)
    consts = _constants(airplane)
    extra_input = np.array(extra, dtype=np.int64)
    thrust_index = inputs.index(airplane.thrust_input) if airplane.thrust_input in inputs else -1
    out_index = np.array([OUTPUTS.index(o) for o in outputs], dtype=np.int64)
    # per output: s_a·k for ax, ay, az (Accelerometer.factors), 1 for the others
    accel = Accelerometer.from_value(accelerometer).factors(airplane.g)
    out_scale = np.array(
        [accel[("ax", "ay", "az").index(o)] if o in ("ax", "ay", "az") else 1.0 for o in outputs]
    )
    if kind == "wind":
        return _wind_functions(out_index, out_scale, extra_input, thrust_index, tables, consts)
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
    return _body_functions(
        src_state, src_input, wind_index, deriv_index, out_index, out_scale, extra_input,
        thrust_index, tables, consts,
    )  # fmt: skip


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
    ) -> StateSpaceModel:
        return _build(
            kind, airplane, aero, parameters, controls, outputs, x0, name, accelerometer, measured
        )

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
