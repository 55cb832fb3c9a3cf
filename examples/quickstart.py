"""Quick start: estimate the parameters of a user-written nonlinear model.

    python examples/quickstart.py

A damped pendulum driven by a torque: dθ/dt = ω, dω/dt = −k sin θ − c ω + b τ. We simulate
"flight data" with known parameters and seeded noise, then estimate k, c, b from a start
20 % off with MNRES (output-error maximum likelihood, R estimated from the residuals).
"""

import numpy as np

from flightid import FlightData, Parameters, StateSpaceModel, simulate
from flightid.estimation import MNRES, estimate


def f(t, x, u, theta):
    """State derivative: [dθ/dt, dω/dt]."""
    return np.array([x[1], -theta[0] * np.sin(x[0]) - theta[1] * x[1] + theta[2] * u[0]])


def h(t, x, u, theta):
    """Outputs: angle (rad) and rate (rad/s)."""
    return np.array([x[0], x[1]])


def main() -> None:
    model = StateSpaceModel(
        states=("angle", "rate"),
        inputs=("torque",),
        outputs=("angle", "rate"),
        f=f,
        h=h,
        parameters=Parameters({"k": 7.2, "c": 0.4, "b": 2.4}),
        name="pendulum",
    )
    t = np.arange(0.0, 10.0, 0.02)
    torque = np.where((t > 1.0) & (t < 2.0), 1.0, 0.0) - np.where((t > 5) & (t < 5.5), 2.0, 0.0)
    truth = model.with_parameters(model.parameters.with_values({"k": 9.0, "c": 0.3, "b": 2.0}))
    clean = simulate(truth, FlightData(t, {"torque": torque}))
    noisy = clean + np.random.default_rng(0).normal(0.0, [0.005, 0.02], clean.shape)
    data = FlightData(
        t,
        {"torque": torque},
        {"angle": noisy[:, 0], "rate": noisy[:, 1]},
        units={"angle": "rad", "rate": "rad/s", "torque": "N·m"},
    )

    result = estimate(model, data, MNRES())
    print(result.summary())


if __name__ == "__main__":
    main()
