"""Accuracy of output-error estimates (RP-1153 §5): intervals from the information matrix at a
confidence level, Cramér–Rao bounds corrected for coloured residuals, Beale's nonlinearity
measure, likelihood-region limits by random search and by profile likelihood, and the
whiteness of any estimator's residuals (autocorrelation band, Ljung–Box).

Entry point: ``assess(estimate, data, level=0.95, methods=("cr", "profile"))``; JSON:
``accuracy_json(estimate, result)``.

The names are loaded on first use (PEP 562 module ``__getattr__``): importing one submodule
(``flightid.accuracy.levels``) or the package does not import the others, so a command that
needs only the whiteness test does not import the likelihood-region search.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from flightid.lazy_exports import lazy_exports

# public name -> module that defines it
_LAZY_EXPORTS: dict[str, str] = {
    "AccuracyResult": "flightid.accuracy.result",
    "AccuracyWarning": "flightid.accuracy.intervals",
    "Contour": "flightid.accuracy.contour",
    "CostSlice": "flightid.accuracy.slices",
    "METHODS": "flightid.accuracy.assess",
    "Nonlinearity": "flightid.accuracy.nonlinearity",
    "ProfileCurve": "flightid.accuracy.profile",
    "ProfileLimits": "flightid.accuracy.profile",
    "SearchLimits": "flightid.accuracy.search",
    "Whiteness": "flightid.accuracy.whiteness",
    "accuracy_json": "flightid.accuracy.result",
    "assess": "flightid.accuracy.assess",
    "beale_factor": "flightid.accuracy.levels",
    "beale_nonlinearity": "flightid.accuracy.nonlinearity",
    "coloured_covariance": "flightid.accuracy.coloured",
    "contour_level": "flightid.results",
    "correlation_matrix": "flightid.accuracy.intervals",
    "correlation_warnings": "flightid.accuracy.intervals",
    "cost_slice": "flightid.accuracy.slices",
    "ellipsoid_intervals": "flightid.results",
    "estimate_whiteness": "flightid.accuracy.whiteness",
    "polish_minimum": "flightid.accuracy.contour",
    "problem_for": "flightid.accuracy.assess",
    "profile_curve": "flightid.accuracy.profile",
    "profile_limits": "flightid.accuracy.profile",
    "random_search": "flightid.accuracy.search",
    "region_contour": "flightid.accuracy.assess",
    "residual_variance_factor": "flightid.results",
    "residual_whiteness": "flightid.accuracy.whiteness",
}

__all__ = [
    "AccuracyResult",
    "AccuracyWarning",
    "Contour",
    "CostSlice",
    "METHODS",
    "Nonlinearity",
    "ProfileCurve",
    "ProfileLimits",
    "SearchLimits",
    "Whiteness",
    "accuracy_json",
    "assess",
    "beale_factor",
    "beale_nonlinearity",
    "coloured_covariance",
    "contour_level",
    "correlation_matrix",
    "correlation_warnings",
    "cost_slice",
    "ellipsoid_intervals",
    "estimate_whiteness",
    "polish_minimum",
    "problem_for",
    "profile_curve",
    "profile_limits",
    "random_search",
    "region_contour",
    "residual_variance_factor",
    "residual_whiteness",
]

if TYPE_CHECKING:  # static tools see the eager imports
    from flightid.accuracy.assess import METHODS, assess, problem_for, region_contour
    from flightid.accuracy.coloured import coloured_covariance
    from flightid.accuracy.contour import Contour, polish_minimum
    from flightid.accuracy.intervals import (
        AccuracyWarning,
        correlation_matrix,
        correlation_warnings,
    )
    from flightid.accuracy.levels import beale_factor
    from flightid.accuracy.nonlinearity import Nonlinearity, beale_nonlinearity
    from flightid.accuracy.profile import ProfileCurve, ProfileLimits, profile_curve, profile_limits
    from flightid.accuracy.result import AccuracyResult, accuracy_json
    from flightid.accuracy.search import SearchLimits, random_search
    from flightid.accuracy.slices import CostSlice, cost_slice
    from flightid.accuracy.whiteness import Whiteness, estimate_whiteness, residual_whiteness
    from flightid.results import contour_level, ellipsoid_intervals, residual_variance_factor


__getattr__, __dir__ = lazy_exports(__name__, _LAZY_EXPORTS)
