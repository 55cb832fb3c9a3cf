"""Model structure determination: least squares with statistics, recursive least squares,
modified stepwise regression and the equation-error set-up for airplanes (METHOD §4–§5)."""

from flightid.regression.differentiate import smooth_derivative
from flightid.regression.equation_error import (
    Airframe,
    equation_error_signals,
    force_coefficients,
    moment_coefficients,
    nondimensional_rates,
)
from flightid.regression.least_squares import LeastSquaresError, LeastSquaresResult, least_squares
from flightid.regression.recursive import RecursiveLeastSquares, SlidingWindowLeastSquares
from flightid.regression.stepwise import Step, StepwiseError, StepwiseResult, stepwise

__all__ = [
    "Airframe",
    "LeastSquaresError",
    "LeastSquaresResult",
    "RecursiveLeastSquares",
    "SlidingWindowLeastSquares",
    "Step",
    "StepwiseError",
    "StepwiseResult",
    "equation_error_signals",
    "force_coefficients",
    "least_squares",
    "moment_coefficients",
    "nondimensional_rates",
    "smooth_derivative",
    "stepwise",
]
