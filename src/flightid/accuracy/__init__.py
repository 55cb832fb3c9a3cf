"""Accuracy of output-error estimates (RP-1153 §5): intervals from the information matrix at a
confidence level, Cramér–Rao bounds corrected for coloured residuals, Beale's nonlinearity
measure, likelihood-region limits by random search and by profile likelihood, and the
whiteness of any estimator's residuals (autocorrelation band, Ljung–Box).

Entry point: ``assess(estimate, data, level=0.95, methods=("cr", "profile"))``; JSON:
``accuracy_json(estimate, result)``.
"""

from flightid.accuracy.assess import METHODS, assess, problem_for, region_contour
from flightid.accuracy.coloured import coloured_covariance
from flightid.accuracy.contour import Contour, polish_minimum
from flightid.accuracy.intervals import AccuracyWarning, correlation_matrix, correlation_warnings
from flightid.accuracy.levels import beale_factor
from flightid.accuracy.nonlinearity import Nonlinearity, beale_nonlinearity
from flightid.accuracy.profile import ProfileCurve, ProfileLimits, profile_curve, profile_limits
from flightid.accuracy.result import AccuracyResult, accuracy_json
from flightid.accuracy.search import SearchLimits, random_search
from flightid.accuracy.slices import CostSlice, cost_slice
from flightid.accuracy.whiteness import Whiteness, estimate_whiteness, residual_whiteness
from flightid.results import contour_level, ellipsoid_intervals, residual_variance_factor

__all__ = [
    "METHODS",
    "AccuracyResult",
    "AccuracyWarning",
    "Contour",
    "CostSlice",
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
