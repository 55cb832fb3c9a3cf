"""Model structure determination: least squares with statistics, total least squares,
recursive least squares, modified stepwise regression and the equation-error set-up for
airplanes (RP-1153 §2.B and §3.A; Klein, Batterson & Murphy, NASA TP-1916)."""

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
from flightid.regression.total_least_squares import (
    TotalLeastSquaresError,
    TotalLeastSquaresResult,
    total_least_squares,
)

__all__ = [
    "Airframe",
    "LeastSquaresError",
    "LeastSquaresResult",
    "RecursiveLeastSquares",
    "SlidingWindowLeastSquares",
    "Step",
    "StepwiseError",
    "StepwiseResult",
    "TotalLeastSquaresError",
    "TotalLeastSquaresResult",
    "equation_error_signals",
    "force_coefficients",
    "least_squares",
    "moment_coefficients",
    "nondimensional_rates",
    "smooth_derivative",
    "stepwise",
    "total_least_squares",
]
