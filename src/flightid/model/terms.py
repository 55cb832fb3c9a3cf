"""Regressor terms written the way an engineer writes them, parsed without ``eval``.

A term is a product of factors raised to non-negative integer powers, or the constant 1. A
factor is a signal or a first-order spline of a signal:

    "1"                       constant (bias) term
    "alpha"                   a signal
    "alpha*beta"              a product
    "beta^3"                  a power (also "beta**3")
    "alpha*phat"              products with non-dimensional rates, controls, ...
    "spline1(alpha,0.15)"     first-order spline (α − 0.15)₊ = max(α − 0.15, 0)
    "spline1(alpha,0.15)^2"   second-order spline (α − 0.15)₊²
    "phat*spline1(alpha,0.1)" a spline times a signal (e.g. roll damping changing past stall)
    "abs(de)"                 the absolute value |δe| (e.g. drag that grows with either
                              deflection: C_D = … + C_D|δe| |δe|)

The spline factor is the usual flight-test form of a nonlinearity that sets in past a knot
(stall, flow separation): (x − k)₊ = max(x − k, 0) is zero below the knot k and
grows linearly above it, so C = θ₀ + θ₁ α + θ₂ (α − k)₊ is a broken line with slope θ₁ below k
and θ₁ + θ₂ above. The knot is a number in the units of the signal (rad for α); it is part of
the model structure, not a parameter.

Grammar (whitespace ignored):

    term    := "1" | factor ("*" factor)*
    factor  := basis [("^" | "**") INTEGER]
    basis   := NAME | "spline1" "(" NAME "," NUMBER ")" | "abs" "(" NAME ")"
    NUMBER  := ["+" | "-"] digits ["." digits] [("e" | "E") ["+" | "-"] digits]

Repeated factors merge (``alpha*alpha`` is ``alpha^2``); a power above ``MAX_POWER`` (64)
is refused. Anything else is a ``TermError``
naming the text and the position of the problem. Signals are looked up by name at evaluation
time; an unknown signal is a ``TermError`` too.

A ``Term`` keeps its factors as ``(key, power)`` pairs; the key is a signal name (``str``) or a
``Spline(signal, knot)``. ``Term.label`` is the canonical text (it parses back to the same
term) and ``Term.identifier`` the NASA-style parameter-name suffix: ``alpha_beta3`` for
α·β³, and for a spline the signal, ``_s`` and the knot with "." written "p" and "-" written "m":
``spline1(alpha,0.15)`` → ``alpha_s0p15``, ``spline1(alpha,-0.05)`` → ``alpha_sm0p05``, a power
appended after an underscore (``spline1(alpha,0.15)^2`` → ``alpha_s0p15_2``). An
absolute value ``abs(de)`` (key ``Abs(signal)``) is named ``abs_de``; ``abs(de)*alpha`` →
``abs_de_alpha``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from flightid.errors import InputError

__all__ = ["Abs", "Spline", "Term", "TermError", "parse_term", "parse_terms", "evaluate_terms"]


class TermError(InputError):
    """A malformed term or a term that names an unknown signal."""


_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_INT = re.compile(r"[0-9]+")
# the highest power of one factor (also after merging repeats): polynomial terms of flight
# data stay far below it, and larger ones only overflow
MAX_POWER = 64
_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_FUNCTIONS = ("spline1", "abs")


def _knot_text(knot: float) -> str:
    """Shortest text that reads back as the same float: 0.15, -0.05, 1e-05, 0."""
    text = repr(float(knot))
    return text[:-2] if text.endswith(".0") else text


@dataclass(frozen=True)
class Spline:
    """First-order spline of a signal: (x − knot)₊ = max(x − knot, 0).

    Attributes:
        signal: name of the signal x.
        knot: k, in the units of the signal (rad for angles).
    """

    signal: str
    knot: float

    @property
    def label(self) -> str:
        """Canonical text, e.g. ``"spline1(alpha,0.15)"``."""
        return f"spline1({self.signal},{_knot_text(self.knot)})"

    @property
    def identifier(self) -> str:
        """Parameter-name part, e.g. ``"alpha_s0p15"`` ("." → "p", "-" → "m")."""
        knot = _knot_text(self.knot).replace("-", "m").replace("+", "").replace(".", "p")
        return f"{self.signal}_s{knot}"

    def evaluate(self, x: np.ndarray) -> np.ndarray:
        # (x − k)₊ = max(x − k, 0)
        return np.maximum(np.asarray(x, dtype=float) - self.knot, 0.0)

    def __str__(self) -> str:
        return self.label


@dataclass(frozen=True)
class Abs:
    """Absolute value of a signal: |x|.

    Attributes:
        signal: name of the signal x.
    """

    signal: str

    @property
    def label(self) -> str:
        """Canonical text, e.g. ``"abs(de)"``."""
        return f"abs({self.signal})"

    @property
    def identifier(self) -> str:
        """Parameter-name part, e.g. ``"abs_de"``."""
        return f"abs_{self.signal}"

    def evaluate(self, x: np.ndarray) -> np.ndarray:
        # |x|
        return np.abs(np.asarray(x, dtype=float))

    def __str__(self) -> str:
        return self.label


@dataclass(frozen=True)
class Term:
    """A product of factor powers; ``factors == ()`` is the constant term.

    ``factors`` holds ``(key, power)`` pairs: key a signal name, a ``Spline`` or an ``Abs``.
    """

    factors: tuple[tuple[str | Spline | Abs, int], ...]

    @property
    def is_constant(self) -> bool:
        return not self.factors

    @property
    def signals(self) -> tuple[str, ...]:
        """Names of the signals the term reads (a spline reads its signal), first-use order."""
        seen: dict[str, None] = {}
        for key, _ in self.factors:
            seen.setdefault(key.signal if isinstance(key, (Spline, Abs)) else key, None)
        return tuple(seen)

    @property
    def splines(self) -> tuple[Spline, ...]:
        """The spline factors of the term."""
        return tuple(key for key, _ in self.factors if isinstance(key, Spline))

    @property
    def label(self) -> str:
        """Canonical text, e.g. ``"alpha*beta^3"``; ``"1"`` for the constant."""
        if not self.factors:
            return "1"
        return "*".join(str(key) if power == 1 else f"{key}^{power}" for key, power in self.factors)

    @property
    def identifier(self) -> str:
        """NASA-style parameter-name suffix: ``alpha_beta3``, ``alpha_s0p15``; ``"0"`` for 1."""
        if not self.factors:
            return "0"
        parts = []
        for key, power in self.factors:
            if isinstance(key, (Spline, Abs)):
                parts.append(key.identifier if power == 1 else f"{key.identifier}_{power}")
            else:
                parts.append(key if power == 1 else f"{key}{power}")
        return "_".join(parts)

    def evaluate(
        self, signals: Mapping[str, np.ndarray], n_samples: int | None = None
    ) -> np.ndarray:
        """The regressor time history: Π factor^power (ones for the constant term)."""
        if not self.factors:
            if n_samples is None:
                n_samples = len(next(iter(signals.values())))
            return np.ones(n_samples)
        value = None
        for key, power in self.factors:
            name = key.signal if isinstance(key, (Spline, Abs)) else key
            if name not in signals:
                raise TermError(
                    f"term {self.label!r}: unknown signal {name!r}; available signals: "
                    f"{sorted(signals)}"
                )
            x = np.asarray(signals[name], dtype=float)
            if isinstance(key, (Spline, Abs)):
                x = key.evaluate(x)
            factor = x**power
            value = factor if value is None else value * factor
        return value

    def __str__(self) -> str:
        return self.label


def _parse_abs(text: str, source: str, position: int) -> tuple[Abs, int]:
    """Argument of ``abs(NAME)`` starting after the '('; returns (basis, end)."""
    match = _NAME.match(source, position)
    if match is None or match.end() >= len(source) or source[match.end()] != ")":
        raise TermError(
            f"term {text!r}: expected a signal name and ')' at position {position} in abs; "
            "write abs(signal), e.g. abs(de)"
        )
    return Abs(match.group()), match.end() + 1


def _parse_call(text: str, source: str, function: str, position: int) -> tuple[Spline | Abs, int]:
    """Arguments of ``spline1(NAME, NUMBER)`` or ``abs(NAME)`` starting after the '(';
    returns (basis, end)."""
    if function == "abs":
        return _parse_abs(text, source, position)
    usage = f"{function}(signal, knot), e.g. {function}(alpha,0.15)"
    match = _NAME.match(source, position)
    if match is None:
        raise TermError(
            f"term {text!r}: expected a signal name as the first argument of {function} at "
            f"position {position}; write {usage}"
        )
    signal = match.group()
    position = match.end()
    if position >= len(source) or source[position] != ",":
        raise TermError(
            f"term {text!r}: expected ',' after {signal!r} in {function}; write {usage}"
        )
    number = _NUMBER.match(source, position + 1)
    if number is None:
        raise TermError(
            f"term {text!r}: expected a number (the knot) at position {position + 1} in "
            f"{function}; write {usage}"
        )
    # + 0.0 turns a knot of -0 into 0 (one canonical label)
    knot = float(number.group()) + 0.0
    if not math.isfinite(knot):
        raise TermError(f"term {text!r}: the knot of {function} must be finite, got {knot}")
    position = number.end()
    if position >= len(source) or source[position] != ")":
        raise TermError(f"term {text!r}: expected ')' at position {position}; write {usage}")
    return Spline(signal, knot), position + 1


def parse_term(text: str) -> Term:
    """Parse one term (see the module docstring for the grammar)."""
    if not isinstance(text, str):
        raise TermError(f"term: expected a string such as 'alpha*beta', got {text!r}")
    source = "".join(text.split()).replace("**", "^")
    if source == "1":
        return Term(())
    if not source:
        raise TermError("term: empty text; expected e.g. 'alpha', 'alpha*beta' or 'beta^3'")
    powers: dict[str | Spline | Abs, int] = {}
    order: list[str | Spline | Abs] = []
    position = 0
    while True:
        match = _NAME.match(source, position)
        if match is None:
            raise TermError(
                f"term {text!r}: expected a signal name at position {position} "
                f"(near {source[position : position + 8]!r})"
            )
        key: str | Spline | Abs = match.group()
        position = match.end()
        if position < len(source) and source[position] == "(":
            if key not in _FUNCTIONS:
                raise TermError(
                    f"term {text!r}: unknown function {key!r}; the functions are {_FUNCTIONS}"
                )
            key, position = _parse_call(text, source, key, position + 1)
        power = 1
        if position < len(source) and source[position] == "^":
            number = _INT.match(source, position + 1)
            if number is None:
                raise TermError(
                    f"term {text!r}: expected a non-negative integer power after '^' of "
                    f"{str(key)!r}"
                )
            digits = number.group().lstrip("0") or "0"
            if len(digits) > 2 or int(digits) > MAX_POWER:
                raise TermError(
                    f"term {text!r}: the power of {str(key)!r} is {digits[:20]}"
                    f"{'...' if len(digits) > 20 else ''}; at most {MAX_POWER} is allowed"
                )
            power = int(digits)
            position = number.end()
        if key not in powers:
            order.append(key)
            powers[key] = 0
        powers[key] += power
        if powers[key] > MAX_POWER:
            raise TermError(
                f"term {text!r}: the factors {str(key)!r} multiply to the power {powers[key]}; "
                f"at most {MAX_POWER} is allowed"
            )
        if position == len(source):
            break
        if source[position] != "*":
            raise TermError(
                f"term {text!r}: unexpected {source[position]!r} at position {position}; "
                "terms are products like 'alpha*beta', powers like 'beta^3' or splines like "
                "'spline1(alpha,0.15)'"
            )
        position += 1
    factors = tuple((key, powers[key]) for key in order if powers[key] > 0)
    return Term(factors)


def parse_terms(texts: Iterable[str]) -> list[Term]:
    """Parse several terms; duplicates (after canonicalisation) are an error."""
    terms = [parse_term(t) for t in texts]
    labels = [t.label for t in terms]
    repeated = sorted({label for label in labels if labels.count(label) > 1})
    if repeated:
        raise TermError(f"terms: repeated terms {repeated}")
    return terms


def evaluate_terms(terms: Iterable[Term], signals: Mapping[str, np.ndarray]) -> np.ndarray:
    """Regressor matrix (N, n_terms) with one column per term."""
    columns = [term.evaluate(signals) for term in terms]
    n = len(next(iter(signals.values()))) if signals else 0
    return np.column_stack(columns) if columns else np.zeros((n, 0))
