"""The optimizers: MNRES (RP-1153's method), MNR (finite-difference Gauss–Newton), FPS."""

from flightid.estimation.solvers.fps import FPS
from flightid.estimation.solvers.mnr import MNR
from flightid.estimation.solvers.mnres import MNRES

__all__ = ["FPS", "MNR", "MNRES"]
