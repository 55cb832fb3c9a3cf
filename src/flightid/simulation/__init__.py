"""Fixed-step simulation (Euler, RK4) of state-space models, compiled or pure Python."""

from flightid.simulation.simulator import SimulationBatch, Simulator, simulate

__all__ = ["SimulationBatch", "Simulator", "simulate"]
