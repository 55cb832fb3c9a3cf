"""Output-error maximum-likelihood estimation: problem, noise policies, solvers, result."""

from flightid.estimation.convergence import Convergence
from flightid.estimation.driver import estimate
from flightid.estimation.problem import OutputErrorProblem, estimate_noise_covariance
from flightid.estimation.result import Estimate
from flightid.estimation.solvers import FPS, MNR, MNRES

__all__ = [
    "Convergence",
    "Estimate",
    "FPS",
    "MNR",
    "MNRES",
    "OutputErrorProblem",
    "estimate",
    "estimate_noise_covariance",
]
