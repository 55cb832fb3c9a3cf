"""Linear models declared by terms: every state derivative and output is a sum of products
"coefficient × signal" (docs/unstable.md, "Measured states as inputs").

    dx_i/dt = Σ_terms c · θ_a · θ_b · s        y_j = Σ_terms c · θ_a · θ_b · s

with s a state (the *integrated* one), an input (any data channel, e.g. a *measured* state)
or nothing (a constant term); c a number or a named constant; θ_a, θ_b up to two parameters.
A term is written as its factors joined by ``*``, optionally with a leading ``-``:
``"Zw*w_m"``, ``"u0*q"``, ``"-2*Zq*q"``, ``"q"``, ``"Mq"`` (constant term Mq).

Because each term names its own signal, the measured and the integrated value of the same
state can appear side by side — the "regression start-up" and "equation decoupling" of an
unstable short period (Jategaonkar, *Flight Vehicle System Identification*, 2nd ed., ch. 9;
test cases TC06 and TC07 of its FVSysID software):

    start-up:   ẇ = Zw·w_m + u0·q + Zq·q_m + Zδe·δe    (u0·q the integrated q, Zq·q_m the measured)
    decoupling: a_z = Zw·w + Zq·q + Zδe·δe             (the integrated states)

The functions are numba-compilable closures over the term tables; they allocate only the
returned vector.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence

import numpy as np
from numba.extending import register_jitable

from flightid.errors import InputError
from flightid.model.forms import with_out_form
from flightid.model.parameters import Parameters
from flightid.model.statespace import StateSpaceModel

__all__ = ["linear_model", "parse_term", "LinearTermError"]

# signal kinds in the term tables
_NONE, _STATE, _INPUT = 0, 1, 2
_NUMBER = re.compile(r"^[0-9]*\.?[0-9]+([eE][-+]?[0-9]+)?$")


class LinearTermError(InputError):
    """A term of a linear model that cannot be read."""


def parse_term(
    term: str,
    states: Sequence[str],
    inputs: Sequence[str],
    parameters: Sequence[str],
    constants: Mapping[str, float],
    where: str,
) -> tuple[int, int, float, int, int]:
    """(signal kind, signal index, numeric factor, parameter index a, b) of one term
    (kind 0 none, 1 state, 2 input; parameter indices −1 where absent)."""
    if not isinstance(term, str) or not term.strip():
        raise LinearTermError(f"{where}: expected a term such as 'Zw*w', got {term!r}")
    text = term.replace(" ", "")
    factor = 1.0
    if text.startswith("-"):
        factor, text = -1.0, text[1:]
    kind, index, params = _NONE, -1, []
    for part in text.split("*"):
        if _NUMBER.match(part):
            factor *= float(part)
        elif part in constants:
            factor *= float(constants[part])
        elif part in parameters:
            params.append(parameters.index(part))
        elif part in states or part in inputs:
            if kind != _NONE:
                raise LinearTermError(
                    f"{where}: {term!r} names two signals; a linear term has at most one "
                    f"state or input"
                )
            kind, index = (
                (_STATE, states.index(part))
                if part in states
                else (
                    _INPUT,
                    inputs.index(part),
                )
            )
        else:
            raise LinearTermError(
                f"{where}: {part!r} in {term!r} is not a number, constant, parameter, state or "
                f"input; constants {sorted(constants)}, parameters {list(parameters)}, states "
                f"{list(states)}, inputs {list(inputs)}"
            )
    if len(params) > 2:
        raise LinearTermError(f"{where}: {term!r} has more than two parameter factors")
    if not math.isfinite(factor):
        raise LinearTermError(f"{where}: {term!r} has a non-finite factor")
    params += [-1] * (2 - len(params))
    return kind, index, factor, params[0], params[1]


def _tables(
    equations: Mapping[str, Sequence[str]],
    rows: Sequence[str],
    what: str,
    states: Sequence[str],
    inputs: Sequence[str],
    parameters: Sequence[str],
    constants: Mapping[str, float],
) -> tuple[np.ndarray, ...]:
    extra = [k for k in equations if k not in rows]
    if extra:
        raise LinearTermError(f"{what}: {extra} are not among {list(rows)}")
    missing = [r for r in rows if r not in equations]
    if missing:
        raise LinearTermError(f"{what}: no equation for {missing}")
    entries = []
    for row, terms in equations.items():
        if isinstance(terms, str):
            terms = [terms]
        for k, term in enumerate(terms):
            parsed = parse_term(term, states, inputs, parameters, constants, f"{what}.{row}[{k}]")
            entries.append((rows.index(row), *parsed))
    eq = np.array([e[0] for e in entries], dtype=np.int64)
    kind = np.array([e[1] for e in entries], dtype=np.int64)
    sig = np.array([e[2] for e in entries], dtype=np.int64)
    coef = np.array([e[3] for e in entries], dtype=float)
    pa = np.array([e[4] for e in entries], dtype=np.int64)
    pb = np.array([e[5] for e in entries], dtype=np.int64)
    return eq, kind, sig, coef, pa, pb


@register_jitable
def _accumulate_terms(x, u, theta, eq, kind, sig, coef, pa, pb, out):
    """out_r = Σ_{terms of row r} c·θ_a·θ_b·s, written into ``out``."""
    for r in range(out.shape[0]):
        out[r] = 0.0
    for k in range(eq.shape[0]):
        c = coef[k]
        if pa[k] >= 0:
            c *= theta[pa[k]]
        if pb[k] >= 0:
            c *= theta[pb[k]]
        if kind[k] == 1:
            c *= x[sig[k]]
        elif kind[k] == 2:
            c *= u[sig[k]]
        # out_r += c · θ_a · θ_b · s
        out[eq[k]] += c


def _term_function(n_rows, eq, kind, sig, coef, pa, pb):
    """out_r = Σ_{terms of row r} c·θ_a·θ_b·s: the return form (numba-compilable closure),
    carrying its out form (``flightid.model.forms``)."""

    def evaluate_out(t, x, u, theta, out):
        _accumulate_terms(x, u, theta, eq, kind, sig, coef, pa, pb, out)

    def evaluate(t, x, u, theta):
        out = np.empty(n_rows)
        _accumulate_terms(x, u, theta, eq, kind, sig, coef, pa, pb, out)
        return out

    return with_out_form(evaluate, evaluate_out)


def linear_model(
    states: Sequence[str],
    inputs: Sequence[str],
    outputs: Sequence[str],
    parameters: Mapping[str, float],
    derivatives: Mapping[str, Sequence[str]],
    output_equations: Mapping[str, Sequence[str]],
    constants: Mapping[str, float] | None = None,
    name: str = "linear",
) -> StateSpaceModel:
    """A ``StateSpaceModel`` from term tables (module docstring).

    Args:
        states, inputs, outputs: channel names (inputs may be measured states).
        parameters: ``{name: start value}``, in the order f and h index θ.
        derivatives: ``{state: [terms]}``, one entry per state.
        output_equations: ``{output: [terms]}``, one entry per output.
        constants: ``{name: value}`` usable as factors.
    Raises:
        LinearTermError: a term that cannot be read, or an equation missing.
    """
    constants = dict(constants or {})
    states, inputs, outputs = tuple(states), tuple(inputs), tuple(outputs)
    names = list(parameters)
    clash = sorted(set(constants) & (set(names) | set(states) | set(inputs)))
    if clash:
        raise LinearTermError(f"constants: {clash} are also parameter or channel names")
    for key, value in constants.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise LinearTermError(f"constants.{key}: expected a number, got {value!r}")
    f_tables = _tables(derivatives, states, "derivatives", states, inputs, names, constants)
    h_tables = _tables(
        output_equations, outputs, "output_equations", states, inputs, names, constants
    )
    f = _term_function(len(states), *f_tables)
    h = _term_function(len(outputs), *h_tables)
    return StateSpaceModel(
        states,
        inputs,
        outputs,
        f,
        h,
        Parameters(dict(parameters)),
        x0=(0.0,) * len(states),
        name=name,
    )
