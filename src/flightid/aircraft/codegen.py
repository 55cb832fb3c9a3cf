"""Straight-line source code of a built-in airplane model's f and h, from its numeric tables.

The table path (``flightid.aircraft.models``) evaluates a model by walking its tables at every
call: the aerodynamic terms (``aero.AeroTables``: per term a coefficient, a parameter and a
list of factors), the index maps from the model's states and inputs to the body state, and
the airplane constants; it calls array helpers (``flightid.aircraft.equations``) and allocates
a work array per call. All of that is fixed when the model is built, so this module writes it
out once as a Python module of scalar code:

* the body state X = (u, v, w, p, q, r, l_xz, l_yz, l_zz) as local names, each the model's
  state, a measured input, or 0;
* only the signals that a term or an output uses (equations.SIGNALS);
* each coefficient C = Σ θ_k Π factor^power [2.16] unrolled in term order, a factor being
  the signal x, the spline max(x − knot, 0.0) or |x|, an integer power written as the
  products of numba's exponentiation by squaring (x³ = x·(x·x)), so a compiled model gives
  the table path's numbers;
* forces and moments [2.14–2.15], the thrust moment and engine terms, the rigid-body
  derivatives [2.5–2.13] (or the wind-axis / α–q forms), the outputs [2.19–2.26], with the
  operations in the table path's order;
* the airplane constants as module-level literals (``repr`` of the float: exact), which
  numba freezes into the compiled code.

α̇ and β̇ terms (power 1, enforced by the builders) make D affine in (α̇, β̇) (equations
module docstring). The table path gets the responses D_α, D_β by evaluating the loads again
with a unit α̇̂ (β̇̂) and differencing; here each coefficient is split into its part without
these terms, C0, and the parts per unit rate, C_α = Σ θ_k Π(other factors)·c̄/(2V_n) and C_β
likewise with b; F_α, F_β are the forces of C_α, C_β (no thrust or engine part) and D_α, D_β
the parts of the derivatives linear in F. Then, as in ``equations.solve_rate_terms``,

    (1 − a_α) α̇ − a_β β̇ = a_0,   −b_α α̇ + (1 − b_β) β̇ = b_0,   D = D0 + α̇ D_α + β̇ D_β

and in wind axes α̇ = D0[1]/(1 − D_α[1]). These agree with the table path to rounding (a few
ulps of the loads), not bit for bit.

The body of each function is a list of single assignments; a statement is kept only if an
``out`` entry depends on it (h of a model with outputs V, α, β, Θ, Φ, p, q, r computes no
loads at all). ``model_source`` writes the module: ``f_out(t, x, u, theta, out)`` and
``h_out`` (out form), ``f(t, x, u, theta)`` and ``h`` (return form, calling the out form,
which is ``register_jitable`` so that a compiled ``f`` may call it). ``uncovered`` says why a
model cannot be written this way (None: it can); such a model keeps the table path.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from flightid.aircraft.aero import AeroTables
from flightid.aircraft.equations import (
    ALPHA_Q_OUTPUTS,
    ALPHADOT_SIGNAL,
    BETADOT_SIGNAL,
    BODY_STATES,
    CONSTANTS,
    OUTPUTS,
)

__all__ = ["ModelSpec", "KINDS", "MAX_TERMS", "uncovered", "model_source"]

# the model kinds written here (models._KINDS)
KINDS = ("6dof", "longitudinal", "lateral", "wind", "alpha_q")
# more terms than this keep the table path (the compile time grows with the source)
MAX_TERMS = 400
# coefficient names, in aero.COEFFICIENTS order
_COEFFICIENTS = ("CX", "CY", "CZ", "CD", "CL", "Cl", "Cm", "Cn")
# local names of the standard body-axis signals (equations.SIGNALS order)
_SIGNAL_NAMES = (
    "V", "alpha", "beta", "ub", "vb", "wb", "p", "q", "r", "phat", "qhat", "rhat",
    "theta_pitch", "phi", "Vrel", "dVrel", "alphadot_hat", "betadot_hat",
)  # fmt: skip
_BODY_NAMES = ("ub", "vb", "wb", "p", "q", "r", "lxz", "lyz", "lzz")
_NAME = re.compile(r"[A-Za-z_][A-Za-z_0-9]*")


@dataclass(frozen=True)
class ModelSpec:
    """The numeric description of a built-in model (what ``models._model_functions`` closes
    over): kind (``KINDS``), aerodynamic tables, ``equations.CONSTANTS`` and
    ``EXTRA_CONSTANTS`` values, index maps (−1: none) and output scales.

    Body-axis kinds: ``src_state``/``src_input`` (per body state: the state or input index),
    ``wind_index`` (inputs V and α of a lateral model measuring them), ``deriv_index`` (body
    state of each model state). All but α–q: ``extra_input`` (inputs that are signals 18…),
    ``idx`` (thrust, propeller torque, engine momentum inputs, lateral flag, α̇ and β̇ flags).
    """

    kind: str
    tables: AeroTables
    consts: np.ndarray
    out_index: np.ndarray
    out_scale: np.ndarray
    extra: np.ndarray = field(default_factory=lambda: np.zeros(5))
    extra_input: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    idx: np.ndarray = field(default_factory=lambda: -np.ones(6, dtype=np.int64))
    src_state: np.ndarray | None = None
    src_input: np.ndarray | None = None
    wind_index: np.ndarray | None = None
    deriv_index: np.ndarray | None = None


def uncovered(spec: ModelSpec) -> str | None:
    """Why ``spec`` cannot be written as straight-line code (None if it can): an unknown
    kind, too many terms, or α̇̂/β̇̂ not entering linearly and alone."""
    if spec.kind not in KINDS:
        return f"model kind {spec.kind!r} has no generated form"
    tables = spec.tables
    if tables.term_coef.shape[0] > MAX_TERMS:
        return f"{tables.term_coef.shape[0]} aerodynamic terms (more than {MAX_TERMS})"
    if spec.kind == "alpha_q":
        return None
    for k in range(tables.term_coef.shape[0]):
        rates = 0
        for j in range(tables.factor_start[k], tables.factor_start[k + 1]):
            if tables.factor_signal[j] in (ALPHADOT_SIGNAL, BETADOT_SIGNAL):
                rates += 1
                if tables.factor_power[j] != 1 or tables.factor_spline[j] != 0:
                    return "an α̇̂ or β̇̂ factor that is not linear"
        if rates > 1:
            return "a term with both α̇̂ and β̇̂ (not affine in the rates)"
    return None


class _Body:
    """A function body as single assignments ``name = expr`` (with an optional comment line
    above), kept only where an ``out`` entry depends on them."""

    def __init__(self) -> None:
        self.statements: list[tuple[str, str, str | None]] = []
        self.targets: set[str] = set()

    def let(self, name: str, expr: str, comment: str | None = None) -> str:
        if name in self.targets:
            raise ValueError(f"codegen: {name} assigned twice")
        self.targets.add(name)
        self.statements.append((name, expr, comment))
        return name

    def lines(self, outputs: list[tuple[str, str | None]]) -> list[str]:
        """The statements the ``out[i] = expr`` lines need, then those lines."""
        needed = {n for expr, _ in outputs for n in _NAME.findall(expr)}
        kept = []
        for name, expr, comment in reversed(self.statements):
            if name in needed:
                kept.append((name, expr, comment))
                needed |= set(_NAME.findall(expr))
        lines = []
        for name, expr, comment in reversed(kept):
            if comment:
                lines.append(f"    # {comment}")
            lines.append(f"    {name} = {expr}")
        for i, (expr, comment) in enumerate(outputs):
            if comment:
                lines.append(f"    # {comment}")
            lines.append(f"    out[{i}] = {expr}")
        return lines


def _lit(value: float) -> str:
    """A float literal that reads back exactly."""
    text = repr(float(value))
    return f"({text})" if text.startswith("-") else text


def _power(base: str, power: int) -> str:
    """base**power as numba computes it for an integer power (exponentiation by squaring:
    r = 1; while n: if n & 1: r *= a; n >>= 1; a *= a), products only."""
    result, square, n = None, base, int(power)
    while n:
        if n & 1:
            result = square if result is None else f"({result} * {square})"
        n >>= 1
        if n:
            square = f"({square} * {square})"
    return "1.0" if result is None else result


def _sum(parts: list[str]) -> str:
    """Left-to-right sum of the terms ('- x' entries subtract); 0.0 if none."""
    if not parts:
        return "0.0"
    text = parts[0][2:] if parts[0].startswith("- ") else parts[0]
    if parts[0].startswith("- "):
        text = f"-{text}"
    for part in parts[1:]:
        text += f" {part}" if part.startswith("- ") else f" + {part}"
    return text


class _Aero:
    """The coefficients of the aero tables as expressions of signal names: C0 (no α̇̂, β̇̂
    terms) and the parts per unit α̇̂ and β̇̂ (the factor replaced by ``k_alpha``/``k_beta``)."""

    def __init__(self, body: _Body, tables: AeroTables, signal_name) -> None:
        self.body = body
        self.tables = tables
        self.signal_name = signal_name
        self.factors: dict[tuple[int, int, float], str] = {}
        self.used = {int(s) for s in tables.factor_signal}
        n = tables.term_coef.shape[0]
        # per part (0: C0, 1: α̇̂, 2: β̇̂) and coefficient, the term expressions in term order
        self.terms: list[list[list[str]]] = [[[] for _ in range(8)] for _ in range(3)]
        for k in range(n):
            part, factors = 0, [f"theta[{int(tables.term_param[k])}]"]
            for j in range(tables.factor_start[k], tables.factor_start[k + 1]):
                signal = int(tables.factor_signal[j])
                if signal == ALPHADOT_SIGNAL:
                    part = 1
                    factors.append("k_alpha")
                elif signal == BETADOT_SIGNAL:
                    part = 2
                    factors.append("k_beta")
                else:
                    base = self._factor(signal, int(tables.factor_spline[j]), tables.factor_knot[j])
                    factors.append(_power(base, int(tables.factor_power[j])))
            self.terms[part][int(tables.term_coef[k])].append(" * ".join(factors))

    def _factor(self, signal: int, kind: int, knot: float) -> str:
        """The factor's base: the signal, (x − knot)₊ or |x| (a local name for the last two)."""
        name = self.signal_name(signal)
        if kind == 0:
            return name
        key = (signal, kind, float(knot))
        if key not in self.factors:
            local = f"spline_{len(self.factors)}" if kind == 1 else f"abs_{len(self.factors)}"
            if kind == 1:
                # (x − k)₊ = max(x − k, 0)
                expr, comment = f"max({name} - {_lit(knot)}, 0.0)", f"({name} − {float(knot)!r})₊"
            else:
                expr, comment = f"abs({name})", f"|{name}|"
            self.factors[key] = local
            self.body.let(local, expr, comment)
        return self.factors[key]

    def has(self, part: int) -> bool:
        return any(self.terms[part])

    def emit(self, part: int, suffix: str = "") -> list[str | None]:
        """Assign the coefficients of ``part`` (names CX…, with ``suffix``); per coefficient
        its name, or None where it has no terms (zero)."""
        names: list[str | None] = []
        for c, name in enumerate(_COEFFICIENTS):
            terms = self.terms[part][c]
            if not terms:
                names.append(None)
                continue
            comment = None
            if c == 0 or all(n is None for n in names):
                comment = "C = Σ θ_k Π factor^power  [2.16]" if part == 0 else (
                    "coefficients per unit α̇ (α̇̂ = α̇ c̄/2V_n)" if part == 1
                    else "coefficients per unit β̇ (β̇̂ = β̇ b/2V_n)"
                )  # fmt: skip
            names.append(self.body.let(name + suffix, _sum(terms), comment))
        return names


def _constants_block(spec: ModelSpec) -> list[str]:
    """Module-level constants: equations.CONSTANTS, and those derived from them."""
    c = {name: float(v) for name, v in zip(CONSTANTS, spec.consts, strict=True)}
    values = {
        "M": c["mass"], "IX": c["Ix"], "IY": c["Iy"], "IZ": c["Iz"], "IXZ": c["Ixz"],
        "S": c["S"], "B": c["b"], "CBAR": c["cbar"], "RHO": c["rho"], "G": c["g"],
        # m g; Γ = I_x I_z − I_xz²; cos α_T, sin α_T of the thrust line
        "MG": c["mass"] * c["g"],
        "GAMMA": c["Ix"] * c["Iz"] - c["Ixz"] * c["Ixz"],
        "COS_ALPHA_T": math.cos(c["alpha_T"]),
        "SIN_ALPHA_T": math.sin(c["alpha_T"]),
    }  # fmt: skip
    lines = ["# airplane constants (SI units): mass, inertia, geometry, ρ, g, thrust line"]
    lines += [f"{name} = {_lit(value)}" for name, value in values.items()]
    return lines


def _body_state(body: _Body, spec: ModelSpec) -> None:
    """X = (u, v, w, p, q, r, l_xz, l_yz, l_zz) from the states and measured inputs."""
    if spec.kind == "wind":
        # symmetric flight from (V, α, Θ, q): u = V cos α, w = V sin α, l_xz = −sin Θ,
        # l_zz = cos Θ
        exprs = ["x[0] * np.cos(x[1])", "0.0", "x[0] * np.sin(x[1])", "0.0", "x[3]", "0.0",
                 "-np.sin(x[2])", "0.0", "np.cos(x[2])"]  # fmt: skip
        for i, (name, expr) in enumerate(zip(_BODY_NAMES, exprs, strict=True)):
            body.let(name, expr, "body state of symmetric flight" if i == 0 else None)
        return
    exprs = []
    for i in range(9):
        if spec.src_state[i] >= 0:
            exprs.append(f"x[{int(spec.src_state[i])}]")
        elif spec.src_input[i] >= 0:
            exprs.append(f"u[{int(spec.src_input[i])}]")
        else:
            exprs.append("0.0")
    if spec.wind_index[0] >= 0:
        iV, ia = int(spec.wind_index[0]), int(spec.wind_index[1])
        body.let("vb", exprs[1], "body state X from the states and measured inputs")
        body.let("sin_beta", f"vb / u[{iV}]", "u = V cos α cos β, w = V sin α cos β  [2.19–2.21]")
        body.let("cos_beta", "math.sqrt(max(0.0, 1.0 - sin_beta * sin_beta))")
        body.let("ub", f"u[{iV}] * math.cos(u[{ia}]) * cos_beta")
        body.let("wb", f"u[{iV}] * math.sin(u[{ia}]) * cos_beta")
        for i in range(3, 9):
            body.let(_BODY_NAMES[i], exprs[i])
        return
    for i, (name, expr) in enumerate(zip(_BODY_NAMES, exprs, strict=True)):
        body.let(name, expr, "body state X from the states and measured inputs" if i == 0 else None)


def _body_signals(body: _Body, spec: ModelSpec, extra_names: list[str]) -> None:
    """The standard signals (equations.signals_from_body) and the input signals."""
    V0, rate_V0 = float(spec.extra[1]), spec.extra[2] > 0.5
    Vn = _lit(V0) if rate_V0 else "V"
    body.let("V", "math.sqrt(ub * ub + vb * vb + wb * wb)", "V = sqrt(u² + v² + w²)  [2.19]")
    body.let("alpha", "math.atan2(wb, ub)", "α = atan(w/u)  [2.21]")
    body.let("beta", "math.asin(vb / V)", "β = asin(v/V)  [2.20]")
    body.let("phat", f"p * B / (2.0 * {Vn})", "p̂ = p b/2V_n")
    body.let("qhat", f"q * CBAR / (2.0 * {Vn})", "q̂ = q c̄/2V_n")
    body.let("rhat", f"r * B / (2.0 * {Vn})", "r̂ = r b/2V_n")
    body.let("theta_pitch", "math.asin(max(-1.0, min(1.0, -lxz)))", "Θ = asin(−l_xz)  [2.22]")
    body.let("phi", "math.atan2(lyz, lzz)", "Φ = atan(l_yz/l_zz)  [2.23]")
    body.let("Vrel", f"V / {_lit(V0)}" if V0 > 0 else "0.0", "V/V0")
    body.let("dVrel", f"(V - {_lit(V0)}) / {_lit(V0)}" if V0 > 0 else "0.0", "(V − V0)/V0")
    # α̇̂ = α̇ c̄/(2V_n) and β̇̂ = β̇ b/(2V_n) of a unit rate
    body.let("k_alpha", f"CBAR / (2.0 * {Vn})", "α̇̂ per unit α̇: c̄/2V_n")
    body.let("k_beta", f"B / (2.0 * {Vn})", "β̇̂ per unit β̇: b/2V_n")
    for j, name in enumerate(extra_names):
        body.let(name, f"u[{int(spec.extra_input[j])}]", "input signals" if j == 0 else None)


def _forces(body: _Body, C: list[str | None], suffix: str, thrust: str | None) -> list[str]:
    """Forces and moments of the coefficients C [2.14–2.15] (thrust T along the thrust
    line where given): names FX, FY, FZ, FL, FM, FN with ``suffix``."""

    def part(name: str | None, factor: str | None = None, minus: bool = False) -> list[str]:
        if name is None:
            return []
        text = name if factor is None else f"{name} * {factor}"
        return [f"- {text}" if minus else text]

    # X = q̄S(C_X + C_L sin α − C_D cos α) + T cos α_T
    x_parts = part(C[0]) + part(C[4], "sa") + part(C[3], "ca", True)
    z_parts = part(C[2]) + part(C[4], "ca", True) + part(C[3], "sa", True)
    fx = f"qbar * S * ({_sum(x_parts)})" if x_parts else None
    fz = f"qbar * S * ({_sum(z_parts)})" if z_parts else None
    if thrust is not None:
        fx = f"{fx} + {thrust} * COS_ALPHA_T" if fx else f"{thrust} * COS_ALPHA_T"
        fz = f"{fz} - {thrust} * SIN_ALPHA_T" if fz else f"-{thrust} * SIN_ALPHA_T"
    names = []
    exprs = [
        (fx, f"X = q̄S(C_X + C_L sin α − C_D cos α){' + T cos α_T' if thrust else ''}"),
        (f"qbar * S * {C[1]}" if C[1] else None, "Y = q̄S C_Y"),
        (fz, f"Z = q̄S(C_Z − C_L cos α − C_D sin α){' − T sin α_T' if thrust else ''}"),
        (f"qbar * S * B * {C[5]}" if C[5] else None, "L = q̄Sb C_l"),
        (f"qbar * S * CBAR * {C[6]}" if C[6] else None, "M = q̄Sc̄ C_m"),
        (f"qbar * S * B * {C[7]}" if C[7] else None, "N = q̄Sb C_n"),
    ]
    if suffix:
        # loads per unit rate: no thrust or engine part; None where zero
        first = True
        for load, (expr, _) in zip(("FX", "FY", "FZ", "FL", "FM", "FN"), exprs, strict=True):
            comment = "their loads [2.14–2.15] (no thrust or engine part)" if first else None
            names.append(body.let(load + suffix, expr, comment) if expr else None)
            first = first and not expr
        return names
    for load, (expr, comment) in zip(("FX", "FY", "FZ", "FL", "FM", "FN"), exprs, strict=True):
        names.append(body.let(load, expr or "0.0", comment))
    return names


def _linear(*terms: tuple[str, str | None]) -> str | None:
    """Σ coefficient·name over the terms whose name is not None (a coefficient "-c"
    subtracts, "" is 1); None if there are none (zero)."""
    parts = []
    for coefficient, name in terms:
        if name is None:
            continue
        negative = coefficient.startswith("-")
        coefficient = coefficient.lstrip("-")
        text = f"{coefficient} * {name}" if coefficient else name
        parts.append(f"- {text}" if negative else text)
    return _sum(parts) if parts else None


def _engine(body: _Body, spec: ModelSpec, F: list[str], thrust: str | None) -> list[str]:
    """Thrust moment and engine terms (equations.engine_loads): M += l_T T, M −= r h_E,
    N += q h_E, L −= s Q, with h_E = s I_p Ω."""
    F = list(F)
    arm, rotation, momentum = float(spec.extra[0]), float(spec.extra[3]), float(spec.extra[4])
    if thrust is not None and arm != 0.0:
        F[4] = body.let("FM_thrust", f"{F[4]} + {_lit(arm)} * {thrust}", "M_T = l_T T")
    h = None
    if spec.idx[2] >= 0:
        h = body.let("h_E", f"{_lit(rotation)} * u[{int(spec.idx[2])}]", "h_E = s I_p Ω (input)")
    elif rotation * momentum != 0.0:
        h = _lit(rotation * momentum)
    if h is not None:
        # −ω × h_E with h_E = (h, 0, 0): (0, −r h, q h)
        F[4] = body.let("FM_engine", f"{F[4]} - r * {h}", "−ω × h_E: M −= r h_E, N += q h_E")
        F[5] = body.let("FN_engine", f"{F[5]} + q * {h}")
    if spec.idx[1] >= 0:
        F[3] = body.let(
            "FL_engine", f"{F[3]} - {_lit(rotation)} * u[{int(spec.idx[1])}]",
            "propeller shaft torque: L −= s Q",
        )  # fmt: skip
    return F


def _rigid_body(body: _Body, F: list[str], suffix: str = "") -> list[str]:
    """dX/dt under the loads F [2.5–2.13] (equations.rigid_body_derivatives_into)."""
    rows = [
        ("du", f"-q * wb + r * vb + G * lxz + {F[0]} / M",
         "du/dt = −q w + r v + g l_xz + X/m  [2.5]"),
        ("dv", f"-r * ub + p * wb + G * lyz + {F[1]} / M",
         "dv/dt = −r u + p w + g l_yz + Y/m  [2.6]"),
        ("dw", f"-p * vb + q * ub + G * lzz + {F[2]} / M",
         "dw/dt = −p v + q u + g l_zz + Z/m  [2.7]"),
        ("F1", f"(IY - IZ) * q * r + IXZ * p * q + {F[3]}", "F1, F2 (equations docstring)"),
        ("F2", f"(IX - IY) * p * q - IXZ * q * r + {F[5]}", None),
        ("dp", f"(IZ * F1{suffix} + IXZ * F2{suffix}) / GAMMA",
         "dp/dt = (I_z F1 + I_xz F2)/Γ  [2.8]"),
        ("dq", f"((IZ - IX) * p * r + IXZ * (r * r - p * p) + {F[4]}) / IY",
         "dq/dt = ((I_z − I_x) p r + I_xz (r² − p²) + M)/I_y  [2.9]"),
        ("dr", f"(IXZ * F1{suffix} + IX * F2{suffix}) / GAMMA",
         "dr/dt = (I_xz F1 + I_x F2)/Γ  [2.10]"),
        ("dlxz", "r * lyz - q * lzz", "direction cosines  [2.11–2.13]"),
        ("dlyz", "-r * lxz + p * lzz", None),
        ("dlzz", "q * lxz - p * lyz", None),
    ]  # fmt: skip
    names = [body.let(name + suffix, expr, comment) for name, expr, comment in rows]
    return names[:3] + names[5:]


def _rigid_body_response(body: _Body, F: list[str | None], suffix: str) -> list[str | None]:
    """The part of dX/dt linear in the loads F (the response to the loads of a unit rate;
    F entries None where zero); None where it is zero."""
    rows = [
        ("du", _linear(("", F[0])), "/ M"),
        ("dv", _linear(("", F[1])), "/ M"),
        ("dw", _linear(("", F[2])), "/ M"),
        ("dp", _linear(("IZ", F[3]), ("IXZ", F[5])), "/ GAMMA"),
        ("dq", _linear(("", F[4])), "/ IY"),
        ("dr", _linear(("IXZ", F[3]), ("IX", F[5])), "/ GAMMA"),
    ]
    names: list[str | None] = []
    comment = f"D{suffix}: the part of dX/dt linear in the loads"
    for name, numerator, divisor in rows:
        if numerator is None:
            names.append(None)
            continue
        numerator = numerator if " " not in numerator else f"({numerator})"
        names.append(body.let(name + suffix, f"{numerator} {divisor}", comment))
        comment = None
    return names + [None, None, None]


def _rate_lines(body: _Body, D: list[str | None], suffix: str, lateral: bool) -> tuple[str, str]:
    """α̇ and β̇ of the derivatives D (equations.alpha_rate, beta_rate; D entries None where
    zero), names a…, b…; "0.0" where zero."""
    numerator = _linear(("ub", D[2]), ("-wb", D[0]))
    a = "0.0"
    if numerator is not None:
        a = body.let(f"a{suffix}", f"({numerator}) / (ub * ub + wb * wb)")
    b = "0.0"
    if lateral and D[1] is not None:
        b = body.let(f"b{suffix}", f"{D[1]} * math.sqrt(uw2) / V2")
    elif not lateral:
        inner = _linear(("ub", D[0]), ("wb", D[2]))
        numerator = _linear(("uw2", D[1]), ("-vb", f"({inner})" if inner else None))
        if numerator is not None:
            b = body.let(f"b{suffix}", f"({numerator}) / (V2 * math.sqrt(uw2))")
    return a, b


def _solve_rates(body: _Body, spec: ModelSpec, aero: _Aero, F, D, lateral: bool):
    """F and D with the α̇ and β̇ terms solved in closed form (module docstring)."""
    has_a, has_b = aero.has(1), aero.has(2)
    if not (has_a or has_b):
        return F, D
    parts = []
    if has_a:
        Fa = _forces(body, aero.emit(1, "_a"), "_a", None)
        parts.append(("alpha_dot", Fa, _rigid_body_response(body, Fa, "_a")))
    if has_b:
        Fb = _forces(body, aero.emit(2, "_b"), "_b", None)
        parts.append(("beta_dot", Fb, _rigid_body_response(body, Fb, "_b")))
    body.let("uw2", "ub * ub + wb * wb", "kinematic α̇ = (u ẇ − w u̇)/(u²+w²), β̇ (equations)")
    body.let("V2", "uw2 + vb * vb")
    a0, b0 = _rate_lines(body, D, "0", lateral)
    if has_a and has_b:
        aa, ba = _rate_lines(body, parts[0][2], "_a", lateral)
        ab, bb = _rate_lines(body, parts[1][2], "_b", lateral)
        body.let("det", f"(1.0 - {aa}) * (1.0 - {bb}) - {ab} * {ba}",
                 "Cramer: det = (1 − a_α)(1 − b_β) − a_β b_α")  # fmt: skip
        body.let("alpha_dot", f"({a0} * (1.0 - {bb}) + {ab} * {b0}) / det")
        body.let("beta_dot", f"((1.0 - {aa}) * {b0} + {ba} * {a0}) / det")
    elif has_a:
        aa, _ = _rate_lines(body, parts[0][2], "_a", lateral)
        body.let("alpha_dot", f"{a0} / (1.0 - {aa})", "(1 − a_α) α̇ = a_0")
    else:
        _, bb = _rate_lines(body, parts[0][2], "_b", lateral)
        body.let("beta_dot", f"{b0} / (1.0 - {bb})", "(1 − b_β) β̇ = b_0")
    return _superpose(body, F, D, parts, 9)


def _superpose(body: _Body, F, D, parts, n_d: int):
    """F = F0 + α̇ F_α + β̇ F_β and D likewise, for the rates in ``parts``."""
    names = ("FX", "FY", "FZ", "FL", "FM", "FN")
    F_out, D_out = [], []
    comment = "F = F0 + α̇ F_α + β̇ F_β, D likewise"
    for i in range(6):
        terms = [f" + {rate} * {Fr[i]}" for rate, Fr, _ in parts if Fr[i] is not None]
        if not terms:
            F_out.append(F[i])
            continue
        F_out.append(body.let(names[i] + "_t", F[i] + "".join(terms), comment))
        comment = None
    for i in range(n_d):
        terms = [f" + {rate} * {Dr[i]}" for rate, _, Dr in parts if Dr[i] is not None]
        D_out.append(body.let(f"D{i}_t", D[i] + "".join(terms)) if terms else D[i])
    return F_out, D_out


def _outputs(spec: ModelSpec, F, pdot: str, qdot: str, rdot: str) -> list[tuple[str, str | None]]:
    """The chosen outputs (equations.body_outputs_into) times their scales."""
    full = ["V", "alpha", "beta", "theta_pitch", "phi", f"{F[0]} / MG", f"{F[1]} / MG",
            f"{F[2]} / MG", "p", "q", "r", pdot, qdot, rdot]  # fmt: skip
    comments = {5: "a = F/(m g), g units, times the accelerometer scale  [2.24–2.26]"}
    result = []
    for i, index in enumerate(spec.out_index):
        index = int(index)
        expr = full[index]
        if spec.out_scale[i] != 1.0:
            expr = f"({expr}) * {_lit(spec.out_scale[i])}"
        result.append(
            (expr, f"{OUTPUTS[index]}" + (f": {comments[index]}" if index in comments else ""))
        )
    return result


def _body_model(
    spec: ModelSpec,
) -> tuple[_Body, list[tuple[str, str | None]], list[tuple[str, str | None]]]:
    """Statements of a body-axis or wind-axis model, and the f and h output lines."""
    body = _Body()
    extra_names = [f"in_{int(i)}" for i in spec.extra_input]
    names = list(_SIGNAL_NAMES) + extra_names
    _body_state(body, spec)
    _body_signals(body, spec, extra_names)
    aero = _Aero(body, spec.tables, lambda s: names[s])
    C = aero.emit(0)
    body.let("qbar", "0.5 * RHO * V * V", "q̄ = ½ρV²")
    body.let("sa", "math.sin(alpha)")
    body.let("ca", "math.cos(alpha)")
    thrust = None
    if spec.idx[0] >= 0:
        thrust = body.let("thrust", f"u[{int(spec.idx[0])}]", "thrust T (N)")
    F = _engine(body, spec, _forces(body, C, "", thrust), thrust)
    if spec.kind == "wind":
        return _wind_model(body, spec, aero, F)
    D = _rigid_body(body, F)
    F, D = _solve_rates(body, spec, aero, F, D, spec.idx[3] == 1)
    f_lines = [(D[int(i)], f"d{BODY_STATES[int(i)]}/dt") for i in spec.deriv_index]
    return body, f_lines, _outputs(spec, F, D[3], D[4], D[5])


def _wind_model(body: _Body, spec: ModelSpec, aero: _Aero, F):
    """d(V, α, Θ, q)/dt of the wind-axis form (equations.wind_axis_derivatives_into), α̇
    terms solved as α̇ = D0[1]/(1 − D_α[1])."""
    let = body.let
    let("sa_w", "math.sin(x[1])", "wind-axis form, states (V, α, Θ, q)")
    let("ca_w", "math.cos(x[1])")
    D = [
        let("dV", f"({F[0]} * ca_w + {F[2]} * sa_w) / M - G * math.sin(x[2] - x[1])",
            "dV/dt = (X cos α + Z sin α)/m − g sin(Θ − α)"),
        let("dalpha",
            f"x[3] + ({F[2]} * ca_w - {F[0]} * sa_w) / (M * x[0])"
            " + G * math.cos(x[2] - x[1]) / x[0]",
            "dα/dt = q + (Z cos α − X sin α)/(m V) + g cos(Θ − α)/V"),
        let("dtheta", "x[3]", "dΘ/dt = q"),
        let("dq", f"{F[4]} / IY", "dq/dt = M/I_y"),
    ]  # fmt: skip
    if aero.has(1):
        Fa = _forces(body, aero.emit(1, "_a"), "_a", None)
        rows = [
            ("dV_a", _linear(("ca_w", Fa[0]), ("sa_w", Fa[2])), "M"),
            ("dalpha_a", _linear(("ca_w", Fa[2]), ("-sa_w", Fa[0])), "(M * x[0])"),
            ("dtheta_a", None, None),
            ("dq_a", Fa[4], "IY"),
        ]
        Da: list[str | None] = []
        comment = "D_α: the part linear in the loads"
        for name, numerator, divisor in rows:
            if numerator is None:
                Da.append(None)
                continue
            Da.append(let(name, f"({numerator}) / {divisor}", comment))
            comment = None
        let("alpha_dot", f"{D[1]} / (1.0 - {Da[1] or '0.0'})", "α̇ = D0[1]/(1 − D_α[1])")
        F, D = _superpose(body, F, D, [("alpha_dot", Fa, Da)], 4)
    f_lines = [(D[i], f"d{name}/dt") for i, name in enumerate(("V", "α", "Θ", "q"))]
    # symmetric flight: ṗ = ṙ = 0, q̇ = M/I_y
    return body, f_lines, _outputs(spec, F, "0.0", D[3], "0.0")


def _alpha_q_model(spec: ModelSpec):
    """d(α, q)/dt and (α, q, a_z) of the α–q form (equations.alpha_q_derivatives_into)."""
    body = _Body()
    n_inputs = int(spec.tables.factor_signal.max(initial=-1)) - 1
    names = ["alpha", "qhat"] + [f"in_{k}" for k in range(max(n_inputs, 7))]
    body.let("alpha", "x[0]", "signals (α, q̂, inputs V, q̄, Θ, Φ, a_x, p, r, controls…)")
    body.let("q", "x[1]")
    body.let("qhat", "x[1] * CBAR / (2.0 * u[0])", "q̂ = q c̄/(2V)")
    for k in range(len(names) - 2):
        body.let(f"in_{k}", f"u[{k}]")
    aero = _Aero(body, spec.tables, lambda s: names[s])
    C = aero.emit(0)
    CZ, Cm = C[2] or "0.0", C[6] or "0.0"
    body.let(
        "dalpha",
        f"q + in_1 * S / (M * in_0) * {CZ} * math.cos(alpha) - G * in_4 / in_0 * math.sin(alpha)"
        " + G / in_0 * (math.cos(in_3) * math.cos(in_2) * math.cos(alpha)"
        " + math.sin(in_2) * math.sin(alpha))",
        "dα/dt = q + (q̄S/(mV)) C_Z cos α − (g a_x/V) sin α"
        " + (g/V)(cos Φ cos Θ cos α + sin Θ sin α)",
    )  # fmt: skip
    body.let(
        "dq",
        f"(in_1 * S * CBAR * {Cm} + (IZ - IX) * in_5 * in_6"
        " + IXZ * (in_6 * in_6 - in_5 * in_5)) / IY",
        "dq/dt = (q̄ S c̄ C_m + (I_z − I_x) p r + I_xz (r² − p²))/I_y  [2.9]",
    )  # fmt: skip
    full = ["alpha", "q", f"in_1 * S * {CZ} / MG"]
    h_lines = []
    for i, index in enumerate(spec.out_index):
        expr = full[int(index)]
        if spec.out_scale[i] != 1.0:
            expr = f"({expr}) * {_lit(spec.out_scale[i])}"
        comment = ALPHA_Q_OUTPUTS[int(index)] + (
            ": a_z = q̄ S C_Z/(m g)  [2.26]" if index == 2 else ""
        )
        h_lines.append((expr, comment))
    return body, [("dalpha", "dα/dt"), ("dq", "dq/dt")], h_lines


def model_source(spec: ModelSpec, description: str = "") -> str:
    """Python source of the module with ``f_out``, ``h_out`` (out form) and ``f``, ``h``
    (return form) of the model ``spec`` (``uncovered(spec)`` must be None)."""
    reason = uncovered(spec)
    if reason is not None:
        raise ValueError(f"codegen: {reason}")
    if spec.kind == "alpha_q":
        body, f_lines, h_lines = _alpha_q_model(spec)
    else:
        body, f_lines, h_lines = _body_model(spec)
    header = [
        f'"""{spec.kind} model{": " + description if description else ""}: straight-line f and h',
        'written by flightid.aircraft.codegen from the model\'s tables (do not edit)."""',
        "",
        "import math",
        "",
        "import numpy as np",
        "from numba.extending import register_jitable",
        "",
        *_constants_block(spec),
        "",
    ]
    lines = header
    for name, outputs in (("f", f_lines), ("h", h_lines)):
        lines += [
            "",
            "@register_jitable",
            f"def {name}_out(t, x, u, theta, out):",
            *body.lines(outputs),
            "",
            "",
            f"def {name}(t, x, u, theta):",
            f"    out = np.empty({len(outputs)})",
            f"    {name}_out(t, x, u, theta, out)",
            "    return out",
            "",
        ]
    return "\n".join(lines) + "\n"
