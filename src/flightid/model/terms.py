"""Regressor terms written the way an engineer writes them, parsed without ``eval``.

A term is a product of signals raised to non-negative integer powers, or the constant 1:

    "1"            constant (bias) term
    "alpha"        a signal
    "alpha*beta"   a product
    "beta^3"       a power (also "beta**3")
    "alpha*phat"   products with non-dimensional rates, controls, ...

Grammar (whitespace ignored):

    term   := "1" | factor ("*" factor)*
    factor := NAME [("^" | "**") INTEGER]

Anything else is a ``TermError`` naming the text and the position of the problem. Signals are
looked up by name at evaluation time; an unknown signal is a ``TermError`` too.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from flightid.errors import InputError

__all__ = ["Term", "TermError", "parse_term", "parse_terms", "evaluate_terms"]


class TermError(InputError):
    """A malformed term or a term that names an unknown signal."""


_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_INT = re.compile(r"[0-9]+")


@dataclass(frozen=True)
class Term:
    """A product of signal powers; ``factors == ()`` is the constant term."""

    factors: tuple[tuple[str, int], ...]

    @property
    def is_constant(self) -> bool:
        return not self.factors

    @property
    def signals(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.factors)

    @property
    def label(self) -> str:
        """Canonical text, e.g. ``"alpha*beta^3"``; ``"1"`` for the constant."""
        if not self.factors:
            return "1"
        return "*".join(name if power == 1 else f"{name}^{power}" for name, power in self.factors)

    def evaluate(
        self, signals: Mapping[str, np.ndarray], n_samples: int | None = None
    ) -> np.ndarray:
        """The regressor time history: Π signal^power (ones for the constant term)."""
        if not self.factors:
            if n_samples is None:
                n_samples = len(next(iter(signals.values())))
            return np.ones(n_samples)
        value = None
        for name, power in self.factors:
            if name not in signals:
                raise TermError(
                    f"term {self.label!r}: unknown signal {name!r}; available signals: "
                    f"{sorted(signals)}"
                )
            factor = np.asarray(signals[name], dtype=float) ** power
            value = factor if value is None else value * factor
        return value

    def __str__(self) -> str:
        return self.label


def parse_term(text: str) -> Term:
    """Parse one term (see the module docstring for the grammar)."""
    if not isinstance(text, str):
        raise TermError(f"term: expected a string such as 'alpha*beta', got {text!r}")
    source = text.replace(" ", "").replace("**", "^")
    if source == "1":
        return Term(())
    if not source:
        raise TermError("term: empty text; expected e.g. 'alpha', 'alpha*beta' or 'beta^3'")
    powers: dict[str, int] = {}
    order: list[str] = []
    position = 0
    while True:
        match = _NAME.match(source, position)
        if match is None:
            raise TermError(
                f"term {text!r}: expected a signal name at position {position} "
                f"(near {source[position : position + 8]!r})"
            )
        name = match.group()
        position = match.end()
        power = 1
        if position < len(source) and source[position] == "^":
            number = _INT.match(source, position + 1)
            if number is None:
                raise TermError(
                    f"term {text!r}: expected a non-negative integer power after '^' of {name!r}"
                )
            power = int(number.group())
            position = number.end()
        if name not in powers:
            order.append(name)
            powers[name] = 0
        powers[name] += power
        if position == len(source):
            break
        if source[position] != "*":
            raise TermError(
                f"term {text!r}: unexpected {source[position]!r} at position {position}; "
                "terms are products like 'alpha*beta' or powers like 'beta^3'"
            )
        position += 1
    factors = tuple((name, powers[name]) for name in order if powers[name] > 0)
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
