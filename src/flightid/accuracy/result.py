"""``AccuracyResult``: what ``assess`` found, and its JSON form ``accuracy_json``."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from flightid.accuracy.nonlinearity import Nonlinearity
from flightid.errors import InputError
from flightid.results import (
    ResultSurface,
    check_level,
    check_method,
    contour_level,
    ellipsoid_intervals,
    finite_or_none,
    render_summary,
)

if TYPE_CHECKING:  # annotations only: the profile and the search load where they run
    from flightid.accuracy.profile import ProfileLimits
    from flightid.accuracy.search import SearchLimits

__all__ = ["AccuracyResult", "accuracy_json", "INTERVAL_METHODS"]

# interval methods an AccuracyResult can hold, in report order (profile and search when run)
INTERVAL_METHODS = ("cr", "cr_simultaneous", "cr_coloured", "cr_beale", "profile", "search")
# the ones that follow from the information matrix and may be re-levelled without new runs
_QUADRATIC = ("cr", "cr_simultaneous", "cr_coloured", "cr_beale")


@dataclass(frozen=True, eq=False)
class AccuracyResult(ResultSurface):
    """Accuracy statements for the free parameters of an estimate.

    The result surface (``flightid.results``): ``summary()``, ``to_dict()`` / ``to_json()``,
    ``to_frame()`` (pandas: every held interval as ``<method>_lower`` / ``<method>_upper``),
    ``conf_int(level=None, method="cr")`` and ``plot()``.

    All intervals are (n_f, 2) arrays [lower, upper] over the *free* parameters, in their
    units, at ``level`` and of ``kind`` (individual or simultaneous, see ``levels``).

    Attributes:
        names: free-parameter names.
        level, kind, distribution: the confidence statement.
        center: the estimate θ̂ the Cramér–Rao intervals are centred on.
        theta_min, cost_min: the polished minimum of J the likelihood region is measured from.
        s2: residual variance factor [5.30]; n_data: N·n_o; n_free: n_p.
        delta: contour level Δ; delta_beale: Δ with Beale's correction [5.28].
        std: Cramér–Rao bounds σ_j = √(M⁻¹)_jj (as in the estimate, under its R).
        std_scaled: s·σ_j, the standard errors the t intervals use (= σ_j when R = R̂).
        std_coloured: standard errors corrected for coloured residuals.
        coloured_lag: the autocorrelation lag L used by the correction.
        covariance, covariance_coloured, correlation: (n_f × n_f).
        ci_cr: ellipsoid projection θ̂ ± √(Δ C_jj) [5.24–5.27].
        ci_cr_simultaneous: the same at the simultaneous level, whatever ``kind`` is.
        ci_cr_coloured: θ̂ ± √(Δ/s² · C^col_jj) (the coloured covariance already holds s²).
        ci_cr_beale: θ̂ ± √(Δ_B C_jj).
        nonlinearity: Beale's N_φ and its parts.
        profile, search: likelihood-region limits, or None if not run.
        evaluations: integrations spent per part ("polish", "beale", "profile", "search").
        warnings: messages (also issued as ``AccuracyWarning``).
        units: unit of each free parameter (``Parameter.unit``; ``()`` when not given).
    """

    names: tuple[str, ...]
    level: float
    kind: str
    distribution: str
    center: np.ndarray
    theta_min: np.ndarray
    cost_min: float
    s2: float
    n_data: int
    n_free: int
    delta: float
    delta_beale: float
    std: np.ndarray
    std_scaled: np.ndarray
    std_coloured: np.ndarray
    coloured_lag: int
    covariance: np.ndarray
    covariance_coloured: np.ndarray
    correlation: np.ndarray
    ci_cr: np.ndarray
    ci_cr_simultaneous: np.ndarray
    ci_cr_coloured: np.ndarray
    ci_cr_beale: np.ndarray
    nonlinearity: Nonlinearity
    profile: ProfileLimits | None
    search: SearchLimits | None
    evaluations: dict = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    units: tuple[str, ...] = ()

    @property
    def methods(self) -> tuple[str, ...]:
        """The interval methods this result holds (``conf_int``'s choices)."""
        return tuple(m for m in INTERVAL_METHODS if getattr(self, f"ci_{m}") is not None)

    @property
    def conf_int_names(self) -> list[str]:
        """The rows of ``conf_int``: the free parameters, in order."""
        return list(self.names)

    @property
    def unit_map(self) -> dict[str, str]:
        """{free parameter: unit}; ``""`` where none is known."""
        units = tuple(self.units) or ("",) * len(self.names)
        return dict(zip(self.names, units, strict=True))

    def conf_int(self, level: float | None = None, method: str = "cr") -> np.ndarray:
        """The (n_f, 2) intervals [lower, upper] of ``method`` (one of ``methods``).

        Args:
            level: None (default) or the result's ``level``: the held intervals. Another
                level re-levels the quadratic methods with ``contour_level`` (same ``kind``
                and ``distribution``):
                ``cr`` θ̂ ± √(Δ C_jj); ``cr_simultaneous`` with the simultaneous Δ;
                ``cr_beale`` with Δ_B = Δ · (Δ_B/Δ of the assessment) [5.28];
                ``cr_coloured`` θ̂ ± √(Δ/s² · C^col_jj). Profile and search limits exist at
                the assessed level only (run ``assess(..., level=...)`` again).
            method: ``cr``, ``cr_simultaneous``, ``cr_coloured``, ``cr_beale``, ``profile``,
                ``search``.

        Returns:
            (n_f, 2) array in the parameters' units, rows as in ``conf_int_names``; an open
            side is ±inf.
        """
        check_method(method, INTERVAL_METHODS)
        table = getattr(self, f"ci_{method}")
        if table is None:
            raise InputError(
                f"method: {method!r} was not run in this assessment; held: {list(self.methods)}"
            )
        if level is None or abs(check_level(level) - self.level) <= 1e-12:
            return np.array(table, dtype=float)
        if method not in _QUADRATIC:
            raise InputError(
                f"level: the {method} limits were traced at level {self.level:g}, got "
                f"{level!r}; run flightid.accuracy.assess(..., level={level!r}) for them"
            )
        kind = "simultaneous" if method == "cr_simultaneous" else self.kind
        delta = contour_level(level, self.n_data, self.n_free, self.s2, kind, self.distribution)
        if method == "cr_beale":
            # Δ_B = Δ · [1 + N n_o (n_p + 2)/((N n_o − n_p) n_p) N_φ]        [5.28–5.29]
            delta *= self.delta_beale / self.delta
        if method == "cr_coloured":
            # the coloured covariance carries s² already: level Δ / s²
            return ellipsoid_intervals(self.center, self.covariance_coloured, delta / self.s2)
        return ellipsoid_intervals(self.center, self.covariance, delta)

    def _frame_rows(self) -> list[dict]:
        rows = []
        units = self.unit_map
        for j, name in enumerate(self.names):
            row = {
                "name": name,
                "estimate": float(self.center[j]),
                "std": float(self.std[j]),
                "std_scaled": float(self.std_scaled[j]),
                "std_coloured": float(self.std_coloured[j]),
            }
            for method in self.methods:
                lower, upper = getattr(self, f"ci_{method}")[j]
                row[f"{method}_lower"] = float(lower)
                row[f"{method}_upper"] = float(upper)
            row["unit"] = units[name]
            rows.append(row)
        return rows

    def to_dict(self) -> dict:
        """JSON-ready statement: level, kind, distribution, s², Δ, N_φ, per parameter the
        estimate, standard errors, unit and every held interval ([lower, upper], an open
        side null), evaluations and warnings. (``accuracy_json`` merges the same into an
        estimate's document for results.json.)"""
        parameters = []
        for row in self._frame_rows():
            entry = {"name": row["name"], "unit": row["unit"]}
            for key in ("estimate", "std", "std_scaled", "std_coloured"):
                entry[key] = finite_or_none(row[key])
            for method in self.methods:
                entry[f"ci_{method}"] = [
                    finite_or_none(row[f"{method}_lower"]),
                    finite_or_none(row[f"{method}_upper"]),
                ]
            parameters.append(entry)
        return {
            "confidence_level": float(self.level),
            "interval_kind": self.kind,
            "distribution": self.distribution,
            "methods": list(self.methods),
            "s2": float(self.s2),
            "delta": float(self.delta),
            "delta_beale": float(self.delta_beale),
            "cost_min": float(self.cost_min),
            "coloured_lag": int(self.coloured_lag),
            "nonlinearity": self.nonlinearity.to_dict(),
            "evaluations": {k: int(v) for k, v in self.evaluations.items()},
            "warnings": list(self.warnings),
            "parameters": parameters,
        }

    @property
    def ci_profile(self) -> np.ndarray | None:
        return None if self.profile is None else self.profile.intervals

    @property
    def ci_search(self) -> np.ndarray | None:
        return None if self.search is None else self.search.intervals

    def interval(self, name: str, method: str = "cr") -> tuple[float, float]:
        """(lower, upper) of one free parameter by ``method`` (cr, cr_coloured, cr_beale,
        cr_simultaneous, profile, search)."""
        table = getattr(self, f"ci_{method}")
        if table is None:
            raise KeyError(f"method {method!r} was not run")
        j = self.names.index(name)
        return float(table[j, 0]), float(table[j, 1])

    def summary(self) -> str:
        """A table of the intervals beside each other (``flightid.report.text``)."""
        return render_summary(self)


def _pair(values) -> list:
    """[lo, hi] with JSON-safe numbers: infinite or NaN ends become None."""
    return [float(v) if np.isfinite(v) else None for v in values]


def accuracy_json(estimate, accuracy: AccuracyResult) -> dict:
    """``estimate.to_dict()`` with the accuracy statements merged in.

    Each free parameter entry gains ``ci_cr``, ``ci_cr_simultaneous``, ``ci_cr_coloured``,
    ``ci_cr_beale``, ``std_scaled``, ``std_coloured`` and, when run, ``ci_profile`` and
    ``ci_search`` (each a [lower, upper] pair; an unbounded end is null). Fixed parameters
    get null intervals.
    Top level: ``confidence_level``, ``interval_kind``, ``distribution``, ``nonlinearity``
    (``N_phi``, ``beale_factor``, ...) and ``accuracy`` (levels, lag, evaluations, warnings,
    statuses).
    """
    document = estimate.to_dict()
    free_names = list(accuracy.names)
    for entry in document["parameters"]:
        name = entry["name"]
        if name not in free_names:
            for key in ("ci_cr", "ci_cr_simultaneous", "ci_cr_coloured", "ci_cr_beale"):
                entry[key] = None
            if accuracy.profile is not None:
                entry["ci_profile"] = None
            if accuracy.search is not None:
                entry["ci_search"] = None
            entry["std_scaled"] = entry["std_coloured"] = None
            continue
        j = free_names.index(name)
        entry["ci_cr"] = _pair(accuracy.ci_cr[j])
        entry["ci_cr_simultaneous"] = _pair(accuracy.ci_cr_simultaneous[j])
        entry["ci_cr_coloured"] = _pair(accuracy.ci_cr_coloured[j])
        entry["ci_cr_beale"] = _pair(accuracy.ci_cr_beale[j])
        for key, value in (
            ("std_scaled", accuracy.std_scaled[j]),
            ("std_coloured", accuracy.std_coloured[j]),
        ):
            entry[key] = float(value) if np.isfinite(value) else None
        if accuracy.profile is not None:
            entry["ci_profile"] = _pair(accuracy.profile.intervals[j])
            entry["profile_status"] = list(accuracy.profile.statuses[j])
        if accuracy.search is not None:
            entry["ci_search"] = _pair(accuracy.search.intervals[j])
    document["confidence_level"] = float(accuracy.level)
    document["interval_kind"] = accuracy.kind
    document["distribution"] = accuracy.distribution
    document["nonlinearity"] = accuracy.nonlinearity.to_dict()
    details = {
        "s2": float(accuracy.s2),
        "delta": float(accuracy.delta),
        "delta_beale": float(accuracy.delta_beale),
        "cost_min": float(accuracy.cost_min),
        "coloured_lag": int(accuracy.coloured_lag),
        "evaluations": {k: int(v) for k, v in accuracy.evaluations.items()},
        "warnings": list(accuracy.warnings),
        "correlation": [
            [float(v) if np.isfinite(v) else None for v in row] for row in accuracy.correlation
        ],
    }
    if accuracy.search is not None:
        details["search"] = {
            "evaluations": int(accuracy.search.evaluations),
            "inside_points": int(accuracy.search.inside),
            "seed": int(accuracy.search.seed),
            "settled": [[bool(v) for v in row] for row in accuracy.search.settled],
        }
    if accuracy.profile is not None:
        details["profile"] = {"evaluations": int(accuracy.profile.total_evaluations)}
    document["accuracy"] = details
    return document
