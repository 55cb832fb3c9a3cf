"""Candidate modelling functions of a global model: monomials and splines of the variables.

Monomials Π_k x_k^{e_k} with 0 ≤ e_k ≤ o_k (the per-variable order) and Σ_k e_k ≤ T (the
total order ``max_order``), the constant first, then by increasing total order. With α 4,
β 2, M 2, q̂ 1, δe 2 and T = 3 there are 47 candidates; with T = 4, 87.

Spline terms (x − κ)₊^m (``spline1(x,κ)^m`` of the term language, ``flightid.model.terms``)
for each knot κ of a variable and m = 1 … ``spline_order``, and optionally each of them times
w^c for w in ``cross_with`` and c = 1 … ``cross_order`` (roll damping that changes past stall:
``phat*spline1(alpha,0.35)``).

Candidates are ``Term`` objects over the raw signal names; their columns are evaluated in the
scaled variables u = x/h (``flightid.globalmodel.variables``): a term whose factors carry the
powers p_f of variables with scales h_f is, in scaled form, the raw column divided by
Π_f h_f^{p_f} (a spline (x − κ)₊^m is h^m (u − κ/h)₊^m, an absolute value |x| is h|u|).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from itertools import product

import numpy as np

from flightid.globalmodel.variables import GlobalModelError, Normalisation
from flightid.model.terms import Abs, Spline, Term, TermError, evaluate_terms, parse_term

__all__ = [
    "monomial_exponents",
    "spline_candidates",
    "generate_candidates",
    "term_scale",
    "candidate_columns",
]


def monomial_exponents(
    orders: Mapping[str, int], max_order: int, names: Sequence[str] | None = None
) -> list[tuple[int, ...]]:
    """Exponent tuples (e_1, …, e_m) with 0 ≤ e_k ≤ orders[k] and Σ e_k ≤ ``max_order``,
    ordered by total order, then lexicographically (highest power of the first variable
    first); the constant (0, …, 0) is first. ``names`` fixes the variable order (default
    the order of ``orders``)."""
    names = list(orders) if names is None else list(names)
    boxes = [range(int(orders[name]) + 1) for name in names]
    exponents = [e for e in product(*boxes) if sum(e) <= max_order]
    # total order first, then the earlier variables' powers first (descending)
    exponents.sort(key=lambda e: (sum(e), tuple(-x for x in e)))
    return exponents


def _monomial_term(names: Sequence[str], exponents: Sequence[int]) -> Term:
    parts = [
        name if e == 1 else f"{name}^{e}" for name, e in zip(names, exponents, strict=True) if e > 0
    ]
    return parse_term("*".join(parts) if parts else "1")


def spline_candidates(
    knots: Mapping[str, Sequence[float]],
    spline_order: int = 1,
    cross_with: Sequence[str] = (),
    cross_order: int = 1,
) -> list[Term]:
    """Spline terms (x − κ)₊^m for each knot κ of each variable, m = 1 … ``spline_order``,
    and each of them times w^c, w in ``cross_with`` (other than x), c = 1 … ``cross_order``."""
    terms = []
    for name, values in knots.items():
        for knot in values:
            for m in range(1, spline_order + 1):
                spline = f"spline1({name},{float(knot)!r})" + ("" if m == 1 else f"^{m}")
                terms.append(parse_term(spline))
                for other in cross_with:
                    if other == name:
                        continue
                    for c in range(1, cross_order + 1):
                        power = other if c == 1 else f"{other}^{c}"
                        terms.append(parse_term(f"{power}*{spline}"))
    return terms


def _check_orders(
    variables: Sequence[str], orders: Mapping[str, int] | None, max_order: int
) -> dict[str, int]:
    orders = dict(orders or {})
    unknown = sorted(set(orders) - set(variables))
    if unknown:
        raise GlobalModelError(f"orders: expected variables from {list(variables)}, got {unknown}")
    return {name: int(orders.get(name, max_order)) for name in variables}


def generate_candidates(
    variables: Sequence[str],
    orders: Mapping[str, int] | None,
    max_order: int,
    knots: Mapping[str, Sequence[float]] | None = None,
    spline_order: int = 1,
    cross_with: Sequence[str] = (),
    cross_order: int = 1,
    max_candidates: int = 400,
) -> tuple[Term, ...]:
    """Every candidate term, the constant first (module docstring).

    ``orders`` maps a variable to its highest power (a variable not listed: ``max_order``).

    Raises:
        GlobalModelError: ``orders``, ``knots`` or ``cross_with`` name a signal that is not a
            variable, or there are more than ``max_candidates`` candidates (the count is in
            the message).
    """
    names = list(variables)
    full_orders = _check_orders(names, orders, max_order)
    terms = [_monomial_term(names, e) for e in monomial_exponents(full_orders, max_order, names)]
    knots = dict(knots or {})
    for key, listed in (("knots", list(knots)), ("cross_with", list(cross_with))):
        unknown = sorted(set(listed) - set(names))
        if unknown:
            raise GlobalModelError(f"{key}: expected variables from {names}, got {unknown}")
    try:
        terms += spline_candidates(knots, spline_order, cross_with, cross_order)
    except TermError as error:
        raise GlobalModelError(f"knots: {error}") from None
    labels = [t.label for t in terms]
    if len(set(labels)) != len(labels):
        repeated = sorted({x for x in labels if labels.count(x) > 1})
        raise GlobalModelError(f"knots: repeated candidate terms {repeated}")
    if len(terms) > max_candidates:
        raise GlobalModelError(
            f"candidates: expected at most max_candidates = {max_candidates} candidate terms, "
            f"got {len(terms)} (lower orders / max_order, fewer knots, or raise max_candidates)"
        )
    return tuple(terms)


def term_scale(term: Term, normalisation: Normalisation) -> float:
    """Π_f h_f^{p_f} over the term's factors: its raw column divided by this is its column
    in scaled variables (module docstring); 1 for the constant."""
    scale = 1.0
    for key, power in term.factors:
        name = key.signal if isinstance(key, (Spline, Abs)) else key
        if name not in normalisation.names:
            raise GlobalModelError(
                f"term {term.label!r}: signal {name!r} is not a model variable "
                f"{list(normalisation.names)}"
            )
        scale *= float(normalisation.scale[normalisation.names.index(name)]) ** power
    return scale


def candidate_columns(
    terms: Sequence[Term], signals: Mapping[str, np.ndarray], normalisation: Normalisation
) -> np.ndarray:
    """The candidates' columns in scaled variables (N, M): raw columns / Π h^p."""
    raw = evaluate_terms(terms, signals)
    scales = np.array([term_scale(t, normalisation) for t in terms])
    return raw / scales
