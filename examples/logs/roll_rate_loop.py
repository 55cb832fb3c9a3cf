"""Multirotor roll-rate loop: the closed-loop response of the roll rate p to its setpoint.

p/p_cmd = ω_n² e^(−τs) / (s² + 2ζω_n s + ω_n²)
states p (rad/s), pdot (rad/s²); input p_cmd (rad/s, the rate setpoint); output p (rad/s).
The delay τ is not written here: the case file declares it (``[model] input_delays``).
"""

import numpy as np

STATES = ("p", "pdot")
INPUTS = ("p_cmd",)
OUTPUTS = ("p",)
PARAMETERS = {"wn": 30.0, "zeta": 0.8}  # start values: ω_n (rad/s), ζ (-)


def f(t, x, u, theta):
    wn, zeta = theta[0], theta[1]
    dx = np.empty(2)
    dx[0] = x[1]
    # p̈ = ω_n² (p_cmd − p) − 2ζω_n ṗ
    dx[1] = wn * wn * (u[0] - x[0]) - 2.0 * zeta * wn * x[1]
    return dx


def h(t, x, u, theta):
    y = np.empty(1)
    y[0] = x[0]
    return y
