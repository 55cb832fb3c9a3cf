"""flightid — airplane parameter estimation with honest accuracy statements.

Output-error maximum likelihood with the MNRES, MNR and FPS optimizers of NASA RP-1153
(Murphy, 1986), model-structure determination by stepwise regression, and confidence limits
from the likelihood region.
"""

from flightid.data import FlightData
from flightid.estimation import FPS, MNR, MNRES, Convergence, Estimate, estimate
from flightid.model import Parameter, Parameters, StateSpaceModel
from flightid.simulate import Simulator, simulate

__version__ = "0.1.0"

__all__ = [
    "Convergence",
    "Estimate",
    "FPS",
    "MNR",
    "MNRES",
    "estimate",
    "FlightData",
    "Parameter",
    "Parameters",
    "StateSpaceModel",
    "Simulator",
    "simulate",
    "__version__",
]
