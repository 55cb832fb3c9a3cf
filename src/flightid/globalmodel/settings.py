"""Settings of a global-model fit, one frozen object checked when it is made.

Case files are parsed into it by ``flightid.cases``; library users build it directly::

    GlobalModelSettings(orders={"alpha": 4, "Mach": 2}, max_order=3, decimate=5)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from flightid.globalmodel.mof import RANKINGS
from flightid.globalmodel.variables import GlobalModelError

__all__ = ["GlobalModelSettings", "METHODS", "RESIDUAL_VARIANCES"]

METHODS = ("mof", "table")
# most variables of one table (JSBSim's row, column and table breakpoints)
_MAX_TABLE_VARIABLES = 3
RESIDUAL_VARIANCES = ("global", "local")


def _integer(name: str, value, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise GlobalModelError(f"{name}: expected an integer ≥ {low}, got {value!r}")
    return int(value)


def _table_entry(k: int, entry) -> dict:
    """One table of ``tables`` checked: {"by": tuple of 1–3 names, "times", "degree"}."""
    if not isinstance(entry, Mapping) or "by" not in entry:
        raise GlobalModelError(
            f"tables[{k}]: expected a mapping {{by = [variables], times = signal, degree = 1|3}}"
            f", got {entry!r}"
        )
    unknown = sorted(set(entry) - {"by", "times", "degree"})
    if unknown:
        raise GlobalModelError(
            f"tables[{k}]: expected keys by, times, degree, got unknown keys {unknown}"
        )
    by = entry["by"]
    by = (by,) if isinstance(by, str) else by
    if (
        not isinstance(by, Sequence)
        or not 1 <= len(by) <= _MAX_TABLE_VARIABLES
        or not all(isinstance(v, str) and v for v in by)
        or len(set(by)) != len(by)
    ):
        raise GlobalModelError(
            f"tables[{k}].by: expected 1 to {_MAX_TABLE_VARIABLES} distinct variable names, "
            f"got {entry['by']!r}"
        )
    times = entry.get("times")
    if times is not None and not (isinstance(times, str) and times):
        raise GlobalModelError(f"tables[{k}].times: expected a signal name, got {times!r}")
    degree = entry.get("degree", 1)
    if isinstance(degree, bool) or degree not in (1, 3):
        raise GlobalModelError(f"tables[{k}].degree: expected 1 or 3, got {degree!r}")
    return {"by": tuple(by), "times": times, "degree": int(degree)}


def _breakpoints_entry(name: str, values) -> tuple[float, ...] | str:
    """One variable's ``breakpoints``: ``"auto"`` or ≥ 2 strictly increasing numbers."""
    if isinstance(values, str):
        if values != "auto":
            raise GlobalModelError(
                f"breakpoints[{name!r}]: expected a list of numbers or 'auto', got {values!r}"
            )
        return "auto"
    if not isinstance(values, Sequence) or len(values) < 2:
        raise GlobalModelError(
            f"breakpoints[{name!r}]: expected at least 2 numbers or 'auto', got {values!r}"
        )
    numbers = tuple(_number(f"breakpoints[{name!r}]", v, -np.inf) for v in values)
    if not all(b > a for a, b in zip(numbers, numbers[1:], strict=False)):
        raise GlobalModelError(
            f"breakpoints[{name!r}]: expected strictly increasing values, got {list(numbers)}"
        )
    return numbers


def _number(name: str, value, low: float, high: float = np.inf, open_low=False) -> float:
    ok = isinstance(value, (int, float, np.number)) and not isinstance(value, bool)
    if ok:
        v = float(value)
        ok = np.isfinite(v) and (v > low if open_low else v >= low) and v <= high
    if not ok:
        bound = f"> {low}" if open_low else f"≥ {low}"
        raise GlobalModelError(f"{name}: expected a finite number {bound}, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class GlobalModelSettings:
    """Options of one coefficient's global model (all checked on construction).

    Attributes:
        method: ``"mof"`` (multivariate orthogonal functions: selected polynomial and spline
            terms) or ``"table"`` (a sum of tables on breakpoints, ``flightid.globalmodel.tables``).
        orders: highest power of each variable in the monomial candidates (a variable not
            listed: ``max_order``).
        max_order: highest total order Σ e_k of a monomial candidate.
        knots: spline knots per variable, signal units: candidates (x − κ)₊^m.
        spline_order: highest power m of a spline candidate.
        cross_with: variables each spline candidate is also multiplied by.
        cross_order: highest power of those variables in the spline products.
        forced: terms always in the model (default the constant ``"1"``).
        sigma2_max: PSE's σ²_max: ``"response"`` (variance of z about its mean, Morelli's
            bound), ``"full"`` (s² of the fit on every candidate) or a number (z's unit²).
        ranking: ``"greedy"`` (order independent) or ``"fixed_order"``.
        max_terms: longest selection path (default every candidate).
        patience: rises of PSE in a row after which the greedy path stops.
        max_candidates: a set-up with more candidates is refused (named error with count).
        decimate: fit every k-th sample of each maneuver.
        level: default level of the prediction intervals.
        residual_variance: σ²_e of the prediction interval: ``"global"`` (s² of the fit) or
            ``"local"`` (mean squared residual of the ``local_k`` nearest samples).
        local_k: neighbours for ``"local"`` (default max(100, N/50)).
        support_k: k of the k-NN support distance.
        spacing_s: thinning of the support reference set, s per sample per maneuver.
        support_quantile: quantile of the reference set's own k-NN distance (d_ref).
        support_factor: distance ratio above which a point is outside the support.
        support_margin: a point beyond the data's range [low, high] of any variable by more
            than support_margin × (high − low) is outside the support.
        tol: relative squared norm under which a candidate counts as dependent.
        tables: (``"table"``) the tables, each a mapping ``{"by": [1–3 variables],
            "times": signal (optional), "degree": 1 or 3 (optional, default 1)}``.
        breakpoints: (``"table"``) {variable: [breakpoints] or ``"auto"``}: ``"auto"`` places
            ``breakpoint_count`` breakpoints at the data quantiles (``auto_breakpoints``), or,
            without a count, chooses the count 3…12 with the least PSE (``choose_breakpoints``).
        breakpoint_count: number of ``"auto"`` breakpoints (None: chosen by PSE).
        smoothing: (``"table"``) λ ≥ 0 of the second-difference penalty (0: none; values
            without data are then dropped, else filled).
        min_weight: (``"table"``) data weight below which a table value has no data.
    """

    method: str = "mof"
    orders: Mapping[str, int] | None = None
    max_order: int = 3
    knots: Mapping[str, Sequence[float]] | None = None
    spline_order: int = 1
    cross_with: Sequence[str] = ()
    cross_order: int = 1
    forced: Sequence[str] = ("1",)
    sigma2_max: float | str = "response"
    ranking: str = "greedy"
    max_terms: int | None = None
    patience: int = 10
    max_candidates: int = 400
    decimate: int = 1
    level: float = 0.95
    residual_variance: str = "global"
    local_k: int | None = None
    support_k: int = 5
    spacing_s: float = 0.1
    support_quantile: float = 0.99
    support_factor: float = 2.0
    support_margin: float = 0.02
    tol: float = field(default=1e-10)
    tables: Sequence[Mapping] | None = None
    breakpoints: Mapping[str, Sequence[float] | str] | None = None
    breakpoint_count: int | None = None
    smoothing: float = 0.0
    min_weight: float = 1.0

    def __post_init__(self) -> None:
        self._check_choices()
        self._check_structure()
        self._check_tables()
        for name, low in (("max_order", 0), ("spline_order", 1), ("cross_order", 1)):
            _integer(name, getattr(self, name), low)
        for name, low in (("patience", 1), ("max_candidates", 1), ("decimate", 1)):
            _integer(name, getattr(self, name), low)
        _integer("support_k", self.support_k, 1)
        if self.max_terms is not None:
            _integer("max_terms", self.max_terms, 1)
        if self.local_k is not None:
            _integer("local_k", self.local_k, 1)
        _number("level", self.level, 0.0, 1.0, open_low=True)
        if self.level >= 1.0:
            raise GlobalModelError(f"level: expected a probability below 1, got {self.level!r}")
        _number("spacing_s", self.spacing_s, 0.0)
        _number("support_quantile", self.support_quantile, 0.0, 1.0, open_low=True)
        _number("support_factor", self.support_factor, 0.0, open_low=True)
        _number("support_margin", self.support_margin, 0.0)
        _number("tol", self.tol, 0.0, 1.0, open_low=True)

    def _check_choices(self) -> None:
        for name, value, allowed in (
            ("method", self.method, METHODS),
            ("ranking", self.ranking, RANKINGS),
            ("residual_variance", self.residual_variance, RESIDUAL_VARIANCES),
        ):
            if value not in allowed:
                raise GlobalModelError(f"{name}: expected one of {list(allowed)}, got {value!r}")
        if isinstance(self.sigma2_max, str):
            if self.sigma2_max not in ("response", "full"):
                raise GlobalModelError(
                    f"sigma2_max: expected 'response', 'full' or a number, got {self.sigma2_max!r}"
                )
        else:
            _number("sigma2_max", self.sigma2_max, 0.0)

    def _check_structure(self) -> None:
        if self.orders is not None:
            if not isinstance(self.orders, Mapping):
                raise GlobalModelError(
                    f"orders: expected a mapping {{variable: highest power}}, got {self.orders!r}"
                )
            for name, value in self.orders.items():
                _integer(f"orders[{name!r}]", value, 0)
        if self.knots is not None:
            if not isinstance(self.knots, Mapping):
                raise GlobalModelError(
                    f"knots: expected a mapping {{variable: [knots]}}, got {self.knots!r}"
                )
            for name, values in self.knots.items():
                if isinstance(values, str) or not isinstance(values, Sequence):
                    raise GlobalModelError(
                        f"knots[{name!r}]: expected a list of numbers, got {values!r}"
                    )
                for value in values:
                    _number(f"knots[{name!r}]", value, -np.inf)
        for name in ("cross_with", "forced"):
            value = getattr(self, name)
            if isinstance(value, str) or not all(isinstance(x, str) for x in value):
                raise GlobalModelError(f"{name}: expected a list of names, got {value!r}")

    def _check_tables(self) -> None:
        """``tables``, ``breakpoints``, ``breakpoint_count``, ``smoothing``, ``min_weight``;
        the tables normalised to tuples of {"by": tuple, "times": str | None, "degree": int}
        and the breakpoints to {variable: tuple of floats | "auto"}."""
        _number("smoothing", self.smoothing, 0.0)
        _number("min_weight", self.min_weight, 0.0)
        if self.breakpoint_count is not None:
            _integer("breakpoint_count", self.breakpoint_count, 2)
        if self.method != "table":
            if self.tables is not None:
                raise GlobalModelError(
                    f"tables: expected only with method = 'table', got method {self.method!r}"
                )
            return
        if (
            self.tables is None
            or isinstance(self.tables, (str, Mapping))
            or not isinstance(self.tables, Sequence)
            or not self.tables
        ):
            raise GlobalModelError(
                f"tables: expected a non-empty list of tables {{by = [variables], times = "
                f"signal, degree = 1|3}} with method = 'table', got {self.tables!r}"
            )
        tables = tuple(_table_entry(k, entry) for k, entry in enumerate(self.tables))
        object.__setattr__(self, "tables", tables)
        breakpoints = self.breakpoints or {}
        if not isinstance(breakpoints, Mapping):
            raise GlobalModelError(
                f"breakpoints: expected a mapping {{variable: [numbers] | 'auto'}}, got "
                f"{self.breakpoints!r}"
            )
        checked = {name: _breakpoints_entry(name, values) for name, values in breakpoints.items()}
        missing = sorted({v for t in tables for v in t["by"]} - set(checked))
        if missing:
            raise GlobalModelError(
                f"breakpoints: expected breakpoints (a list or 'auto') for every table variable, "
                f"missing {missing}"
            )
        object.__setattr__(self, "breakpoints", checked)

    def to_dict(self) -> dict:
        """The settings as plain Python (JSON-ready)."""
        return {
            "method": self.method,
            "orders": None if self.orders is None else dict(self.orders),
            "max_order": self.max_order,
            "knots": None
            if self.knots is None
            else {k: [float(x) for x in v] for k, v in self.knots.items()},
            "spline_order": self.spline_order,
            "cross_with": list(self.cross_with),
            "cross_order": self.cross_order,
            "forced": list(self.forced),
            "sigma2_max": self.sigma2_max,
            "ranking": self.ranking,
            "max_terms": self.max_terms,
            "patience": self.patience,
            "max_candidates": self.max_candidates,
            "decimate": self.decimate,
            "level": self.level,
            "residual_variance": self.residual_variance,
            "local_k": self.local_k,
            "support_k": self.support_k,
            "spacing_s": self.spacing_s,
            "support_quantile": self.support_quantile,
            "support_factor": self.support_factor,
            "support_margin": self.support_margin,
            "tol": self.tol,
            "tables": None
            if self.tables is None
            else [
                {"by": list(t["by"]), "times": t["times"], "degree": t["degree"]}
                for t in self.tables
            ],
            "breakpoints": None
            if self.breakpoints is None
            else {
                k: v if isinstance(v, str) else [float(x) for x in v]
                for k, v in self.breakpoints.items()
            },
            "breakpoint_count": self.breakpoint_count,
            "smoothing": self.smoothing,
            "min_weight": self.min_weight,
        }

    @classmethod
    def from_dict(cls, entry: Mapping) -> GlobalModelSettings:
        """The settings ``to_dict`` wrote."""
        values = dict(entry)
        for name in ("cross_with", "forced"):
            if name in values:
                values[name] = tuple(values[name])
        return cls(**values)
