"""Example data the package regenerates itself (seeded, deterministic).

``flightid.examples.logs``: a simulated multirotor roll-rate loop written as a PX4 ULog and
a simulated fixed-wing roll mode written as an ArduPilot DataFlash log, each with the truth
it was made from (``flightid example-logs --out DIR`` writes both).
"""
