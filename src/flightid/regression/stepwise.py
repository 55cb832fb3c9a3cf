"""Modified stepwise regression (RP-1153 §2 stage 2; Klein, Batterson & Murphy, NASA TP-1916).

Candidate regressors are terms of the term language (``flightid.model.terms``): "alpha",
"qhat", "alpha*de", "alpha^2", ... evaluated over a mapping of measured signals. Some terms
(by default the constant "1") are always in the model.

Algorithm, starting from the forced terms:

1. Entry. For every candidate j not in the model compute its partial correlation with the
   response after both are adjusted for the terms already in the model,

       r_j = x̃_jᵀ ẑ / (‖x̃_j‖ ‖ẑ‖),   x̃_j, ẑ = residuals of x_j, z regressed on the model terms,

   and enter the candidate with the largest |r_j| if its partial F (F to enter),

       F_j = (RSS_before − RSS_after) / s²_after  =  r_j² (N − n_p − 1) / (1 − r_j²),

   is at least ``f_enter``. (The largest |r_j| is the largest F_j, since F is monotone in r².)
2. Re-test. After every entry, the partial F of each term in the model (t² of its estimate)
   is re-computed; the term with the smallest partial F leaves if that F is below
   ``f_remove`` (forced terms never leave). Repeat until none leaves.
3. Stop when no candidate enters and none leaves (or after ``max_steps``, or when a term set
   would repeat, which guards against cycling when f_remove > f_enter).

Every visited model is recorded in the history with its partial F, overall F, R², s² and
PSE = RSS/N + σ²_max n_p/N. The *selected* model (``select="pse"``, the default) is the one
of minimum PSE among the visited models in which every term passes the F-to-remove test —
significance and PSE judged together, so neither an insignificant term nor an over-fitted
model is chosen; ``select="final"`` takes the model at the stopping point.

σ²_max (PSE's penalty per parameter, z's unit squared): ``"full"`` (default) is s² of the fit
with every candidate term — an estimate of the noise variance, which makes PSE behave like
Mallows' C_p (a term lowers PSE when its partial F exceeds about 1, so the F-to-remove test is
the binding one); ``"response"`` is the variance of z about its mean, the mean-square error of
the constant-only model (Morelli's upper bound), which charges much more per term and selects
small models when one regressor dominates; or a number given by the user.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from flightid.errors import InputError, describe
from flightid.model.terms import Term, parse_term
from flightid.regression.least_squares import LeastSquaresResult, least_squares
from flightid.results import ResultSurface

__all__ = ["Step", "StepwiseResult", "stepwise", "StepwiseError"]


class StepwiseError(InputError):
    """A malformed stepwise-regression set-up."""


def selected_fit_dict(selected: Sequence[str], fit: LeastSquaresResult) -> dict:
    """``selected``, ``parameters`` (name, value, std), ``r2``, ``pse``, ``s2`` of a fit on
    the ``selected`` terms (the part of the JSON every regression result shares)."""
    return {
        "selected": list(selected),
        "parameters": fit.to_dict()["parameters"],
        "r2": float(fit.r2),
        "pse": float(fit.pse),
        "s2": float(fit.s2),
    }


@dataclass(frozen=True)
class Step:
    """One step of the search: what happened and the model it left.

    ``action`` is "start", "enter" or "remove"; ``term`` and ``partial_f`` describe the term
    that entered or left (``partial_correlation`` for entries).
    """

    number: int
    action: Literal["start", "enter", "remove"]
    term: str | None
    partial_f: float
    partial_correlation: float
    terms: tuple[str, ...]
    r2: float
    s2: float
    f_overall: float
    pse: float

    def to_dict(self) -> dict:
        return {
            "step": self.number,
            "action": self.action,
            "term": self.term,
            "partial_f": _finite_or_none(self.partial_f),
            "partial_correlation": _finite_or_none(self.partial_correlation),
            "terms": list(self.terms),
            "r2": _finite_or_none(self.r2),
            "s2": _finite_or_none(self.s2),
            "f_overall": _finite_or_none(self.f_overall),
            "pse": _finite_or_none(self.pse),
        }


def _finite_or_none(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


@dataclass(frozen=True, eq=False)
class StepwiseResult(ResultSurface):
    """Result of a stepwise regression.

    The result surface (``flightid.results``): ``summary()``, ``to_dict()`` / ``to_json()``,
    ``to_frame()`` (pandas; the selected model's estimates), ``conf_int(level=0.95,
    method="t")`` (those of ``fit``) and ``plot()`` (R², PSE per step and the fit).

    Attributes:
        response: name of the modelled coefficient.
        candidates: all candidate term labels (forced terms first).
        forced: the terms that are always in the model.
        selected: the selected term labels, in candidate order.
        fit: the least-squares fit of the selected model.
        steps: history of every step.
        f_enter, f_remove: thresholds used.
        sigma2_max: σ²_max used in PSE.
        select: "pse" or "final".
    """

    response: str
    candidates: tuple[str, ...]
    forced: tuple[str, ...]
    selected: tuple[str, ...]
    fit: LeastSquaresResult
    steps: tuple[Step, ...]
    f_enter: float
    f_remove: float
    sigma2_max: float
    select: str

    @property
    def selected_terms(self) -> list[Term]:
        return [parse_term(label) for label in self.selected]

    def history(self) -> str:
        """The step-by-step history as a text table."""
        lines = [
            f"Stepwise regression for {self.response}: F_enter = {self.f_enter:g}, "
            f"F_remove = {self.f_remove:g}, σ²_max = {self.sigma2_max:.4g}",
            f"{'step':>4s}  {'action':<7s}{'term':<14s}{'partial F':>11s}{'r_partial':>10s}"
            f"{'R²':>10s}{'s²':>12s}{'F':>11s}{'PSE':>12s}  terms",
        ]
        for s in self.steps:
            lines.append(
                f"{s.number:>4d}  {s.action:<7s}{(s.term or '-'):<14s}{s.partial_f:>11.4g}"
                f"{s.partial_correlation:>10.4f}{s.r2:>10.6f}{s.s2:>12.4g}{s.f_overall:>11.4g}"
                f"{s.pse:>12.5g}  {', '.join(s.terms)}"
            )
        lines.append(f"selected ({self.select}): {', '.join(self.selected)}")
        return "\n".join(lines)

    def summary(self) -> str:
        """History followed by the least-squares table of the selected model."""
        return self.history() + "\n\n" + self.fit.summary()

    def to_dict(self) -> dict:
        """The JSON contract: selected, parameters (name, value, std), r2, pse, steps."""
        return {
            **selected_fit_dict(self.selected, self.fit),
            "f_overall": _finite_or_none(self.fit.f_overall),
            "sigma2_max": float(self.sigma2_max),
            "steps": [s.to_dict() for s in self.steps],
        }

    @property
    def conf_int_names(self) -> list[str]:
        """The rows of ``conf_int``: the selected terms, in order."""
        return list(self.fit.names)

    def conf_int(self, level: float = 0.95, method: str = "t") -> np.ndarray:
        """Intervals of the selected model's estimates: ``fit.conf_int(level, method)``
        ((n_p, 2) array; ``"t"`` or ``"normal"``; see ``LeastSquaresResult.conf_int``)."""
        return self.fit.conf_int(level, method)

    def _frame_rows(self) -> list[dict]:
        return self.fit._frame_rows()


def _as_term(item: str | Term, argument: str) -> Term:
    if isinstance(item, Term):
        return item
    if isinstance(item, str):
        return parse_term(item)
    raise StepwiseError(f"{argument}: expected term text such as 'alpha*de', got {describe(item)}")


def stepwise(
    z: np.ndarray,
    candidates: Sequence[str | Term],
    signals: Mapping[str, np.ndarray],
    *,
    forced: Sequence[str | Term] = ("1",),
    f_enter: float = 4.0,
    f_remove: float = 4.0,
    sigma2_max: float | Literal["response", "full"] = "full",
    select: Literal["pse", "final"] = "pse",
    max_steps: int = 100,
    response: str = "z",
    maneuver_index: np.ndarray | None = None,
) -> StepwiseResult:
    """Modified stepwise regression of ``z`` over candidate terms (see the module docstring).

    Args:
        z: response series (N,), e.g. a non-dimensional coefficient.
        candidates: candidate terms (text or ``Term``), evaluated over ``signals``.
        signals: mapping of signal name to series (N,), in the units the terms should use.
        forced: terms always in the model (default the constant ``"1"``).
        f_enter: partial F a candidate needs to enter (≥ 0).
        f_remove: partial F below which a term leaves (≥ 0, ≤ f_enter is advisable).
        sigma2_max: "response", "full" or a number (z's unit squared), see module docstring.
        select: "pse" (model of minimum PSE along the path) or "final".
        max_steps: limit on entries plus removals.
        response: name of z, for reports.
        maneuver_index: (N,) maneuver of each sample when z joins several maneuvers: the
            selected model's coloured-residual σ never pairs samples of different maneuvers.
    """
    z = _check_settings(z, f_enter, f_remove, select)
    forced_labels, labels, columns = _term_columns(z, forced, candidates, signals)
    s2max = _noise_variance(sigma2_max, z, columns, labels)
    search = _Search(z, columns, labels, forced_labels, s2max)
    search.run(max_steps, f_enter, f_remove)
    names, chosen = search.selected(select, f_remove)
    # the selected model again, with its default σ (coloured-residual σ when coloured)
    chosen = least_squares(
        np.column_stack([columns[t] for t in names]),
        z,
        tuple(names),
        sigma2_max=s2max,
        units=dict(zip(chosen.names, chosen.units, strict=True)) if chosen.units else None,
        maneuver_index=maneuver_index,
    )
    return StepwiseResult(
        response=response,
        candidates=tuple(labels),
        forced=tuple(forced_labels),
        selected=tuple(names),
        fit=chosen,
        steps=tuple(search.steps),
        f_enter=float(f_enter),
        f_remove=float(f_remove),
        sigma2_max=s2max,
        select=select,
    )


def _check_settings(z, f_enter: float, f_remove: float, select: str) -> np.ndarray:
    """z as a float series; the F thresholds and the selection rule checked."""
    z = np.asarray(z, dtype=float)
    if z.ndim != 1:
        raise StepwiseError(f"z: expected a one-dimensional series, got {describe(z)}")
    for argument, value in (("f_enter", f_enter), ("f_remove", f_remove)):
        if not (isinstance(value, (int, float)) and np.isfinite(value) and value >= 0):
            raise StepwiseError(f"{argument}: expected a non-negative number, got {value!r}")
    if select not in ("pse", "final"):
        raise StepwiseError(f"select: expected 'pse' or 'final', got {select!r}")
    return z


def _term_columns(
    z: np.ndarray,
    forced: Sequence[str | Term],
    candidates: Sequence[str | Term],
    signals: Mapping[str, np.ndarray],
) -> tuple[list[str], list[str], dict[str, np.ndarray]]:
    """(forced labels, all labels: forced then candidates, label -> evaluated column (N,))."""
    forced_terms = [_as_term(t, "forced") for t in forced]
    candidate_terms = [_as_term(t, "candidates") for t in candidates]
    forced_labels = [t.label for t in forced_terms]
    pool = [t for t in candidate_terms if t.label not in forced_labels]
    labels = forced_labels + [t.label for t in pool]
    if len(set(labels)) != len(labels):
        repeated = sorted({x for x in labels if labels.count(x) > 1})
        raise StepwiseError(f"candidates: repeated terms {repeated}")
    if not pool:
        raise StepwiseError("candidates: expected at least one candidate term, got none")
    n = z.shape[0]
    columns: dict[str, np.ndarray] = {}
    for term in forced_terms + pool:
        column = np.asarray(term.evaluate(signals, n), dtype=float)
        if column.shape != (n,):
            raise StepwiseError(
                f"candidates: term {term.label!r} evaluates to {describe(column)}, "
                f"expected {n} samples like z"
            )
        if not np.all(np.isfinite(column)):
            raise StepwiseError(f"candidates: term {term.label!r} has non-finite values")
        columns[term.label] = column
    return forced_labels, labels, columns


def _noise_variance(
    sigma2_max: float | str, z: np.ndarray, columns: dict[str, np.ndarray], labels: list[str]
) -> float:
    """σ²_max of PSE (z's unit squared): "response", "full" or a number (module docstring)."""
    if isinstance(sigma2_max, str):
        if sigma2_max == "response":
            # variance of z about its mean: the constant-only model's mean-square error
            return float(np.mean((z - z.mean()) ** 2))
        if sigma2_max == "full":
            # s² of the fit with every candidate term
            return least_squares(np.column_stack([columns[x] for x in labels]), z, labels).s2
        raise StepwiseError(
            f"sigma2_max: expected 'response', 'full' or a number, got {sigma2_max!r}"
        )
    s2max = float(sigma2_max)
    if not (np.isfinite(s2max) and s2max >= 0):
        raise StepwiseError(f"sigma2_max: expected a non-negative number, got {sigma2_max!r}")
    return s2max


class _Search:
    """The entry / re-test path of the modified stepwise regression (module docstring),
    recording every visited model."""

    def __init__(
        self,
        z: np.ndarray,
        columns: dict[str, np.ndarray],
        labels: list[str],
        forced_labels: list[str],
        s2max: float,
    ) -> None:
        self.z = z
        self.columns = columns
        self.labels = labels
        self.forced_labels = forced_labels
        self.s2max = s2max
        self.in_model: set[str] = set(forced_labels)
        self.current: LeastSquaresResult | None = None
        self.residual_z = z.copy()
        self.steps: list[Step] = []
        self.visited = {frozenset(self.in_model)}
        self.models: list[tuple[tuple[str, ...], LeastSquaresResult]] = []
        if self.in_model:
            self._move_to(self.in_model, "start", None, np.nan, np.nan)

    def _fit(self, terms: Sequence[str]) -> LeastSquaresResult:
        X = np.column_stack([self.columns[t] for t in terms])
        # the search needs only the classical statistics (partial F, PSE) of many fits
        return least_squares(X, self.z, tuple(terms), sigma2_max=self.s2max, coloured=False)

    def _ordered(self, terms: set[str]) -> tuple[str, ...]:
        return tuple(x for x in self.labels if x in terms)

    def _move_to(self, terms: set[str], action, term, partial_f, r_partial) -> None:
        """Fit the model ``terms``, make it the current one and record the step."""
        self.in_model = terms
        current = self._fit(self._ordered(terms))
        self.current = current
        self.residual_z = current.residuals
        self.visited.add(frozenset(terms))
        self.steps.append(
            Step(
                number=len(self.steps),
                action=action,
                term=term,
                partial_f=float(partial_f),
                partial_correlation=float(r_partial),
                terms=current.names,
                r2=current.r2,
                s2=current.s2,
                f_overall=current.f_overall,
                pse=current.pse,
            )
        )
        self.models.append((current.names, current))

    def _best_candidate(self) -> tuple[str, float] | None:
        """(label, r) of the candidate outside the model with the largest |partial
        correlation| with the response, or None."""
        outside = [t for t in self.labels if t not in self.in_model]
        if not outside:
            return None
        if self.in_model:
            M = np.column_stack([self.columns[t] for t in self._ordered(self.in_model)])
            Q, _ = np.linalg.qr(M)
        residual_z = self.residual_z
        best = None
        for label in outside:
            x = self.columns[label]
            # x̃ = x − Q Qᵀ x : the part of x not explained by the model terms
            x_adj = x - Q @ (Q.T @ x) if self.in_model else x
            denom = np.linalg.norm(x_adj) * np.linalg.norm(residual_z)
            if denom <= 1e-14 * max(np.linalg.norm(x), 1e-300) * max(
                np.linalg.norm(residual_z), 1e-300
            ):
                continue  # collinear with the model, or nothing left to explain
            # r_j = x̃_jᵀ ẑ / (‖x̃_j‖ ‖ẑ‖)
            r = float(x_adj @ residual_z / denom)
            if best is None or abs(r) > abs(best[1]):
                best = (label, r)
        return best

    def _enter(self, f_enter: float) -> str | None:
        """Entry step: the best candidate enters if its F to enter is at least ``f_enter``
        (and the model it makes is new); its label, or None."""
        best = self._best_candidate()
        if best is None:
            return None
        label, r = best
        dof_after = self.z.shape[0] - len(self.in_model) - 1
        # F to enter = r² (N − n_p − 1)/(1 − r²)
        f_in = r * r * dof_after / max(1.0 - r * r, 1e-300) if dof_after > 0 else 0.0
        trial = self.in_model | {label}
        if not f_in >= f_enter or frozenset(trial) in self.visited:
            return None
        self._move_to(trial, "enter", label, f_in, r)
        return label

    def _remove_weak(self, f_remove: float, entered: str | None, max_steps: int) -> bool:
        """Re-test: remove the weakest term while its partial F < ``f_remove`` (never a forced
        term, nor the one just entered); True if any left."""
        removed_any = False
        while self.current is not None and len(self.steps) < max_steps + 1:
            current = self.current
            removable = [
                (current.partial_f[j], name)
                for j, name in enumerate(current.names)
                if name not in self.forced_labels and name != entered
            ]
            if not removable:
                break
            f_out, name = min(removable)
            trial = self.in_model - {name}
            if f_out >= f_remove or frozenset(trial) in self.visited:
                break  # significant, or removing it would revisit a model (a cycle)
            self._move_to(trial, "remove", name, f_out, np.nan)
            removed_any = True
        return removed_any

    def run(self, max_steps: int, f_enter: float, f_remove: float) -> None:
        """Alternate entry and re-test until neither changes the model (or ``max_steps``)."""
        while len(self.steps) < max_steps + 1:
            entered = self._enter(f_enter)
            removed_any = self._remove_weak(f_remove, entered, max_steps)
            if entered is None and not removed_any:
                break
        if self.current is None:
            raise StepwiseError(
                "candidates: no term entered the model and no forced term was given; "
                "lower f_enter or force a term"
            )

    def selected(self, select: str, f_remove: float) -> tuple[tuple[str, ...], LeastSquaresResult]:
        """(terms, fit) of the selected model: minimum PSE among the visited models whose
        terms all pass F-to-remove ("pse"), or the model at the stopping point ("final")."""
        if select != "pse":
            return self.current.names, self.current
        admissible = [
            item
            for item in self.models
            if all(
                f >= f_remove
                for name, f in zip(item[1].names, item[1].partial_f, strict=True)
                if name not in self.forced_labels
            )
        ]
        return min(admissible or self.models, key=lambda item: item[1].pse)
