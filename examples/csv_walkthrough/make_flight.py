"""Write my_flight.csv: a simulated short-period 3-2-1-1 maneuver with seeded noise.

True values (Za, Zq, Zde, Ma, Mq, Mde) = (-0.8, 0.05, -0.1, -4.5, -1.6, -7.0); dt = 0.02 s;
angles in degrees in the file, as many data systems record them.

The elevator is a digital command held constant over each sample interval (zero-order hold,
as a flight-control computer applies it), and the states are propagated exactly for that
held input with the matrix exponential (no integration error):

    x_{k+1} = Φ x_k + Γ δe_k,   Φ = e^{A Δt},   Γ = ∫_0^Δt e^{A s} ds B

(both from one exponential of the augmented matrix [[A, B], [0, 0]] Δt). The case file
my_case.toml therefore declares ``input_interpolation = "zoh"`` under [estimation]: the model
then sees the same held input, and the estimates recover the true values within their
Cramér–Rao bounds. Noise: N(0, 0.02 deg) on α, N(0, 0.05 deg/s) on q, seed 6.

Run: python make_flight.py   (writes my_flight.csv next to this file)
"""

from pathlib import Path

import numpy as np
from scipy.linalg import expm

TRUE = {"Za": -0.8, "Zq": 0.05, "Zde": -0.1, "Ma": -4.5, "Mq": -1.6, "Mde": -7.0}


def flight(seed: int = 6) -> np.ndarray:
    """Rows (t [s], δe [deg], α [deg], q [deg/s]) of the maneuver."""
    rng = np.random.default_rng(seed)
    dt, n = 0.02, 501
    t = np.arange(n) * dt
    de = np.zeros(n)  # rad
    for start, length, sign in ((1.0, 1.5, 1), (2.5, 1.0, -1), (3.5, 0.5, 1), (4.0, 0.5, -1)):
        de[(t >= start) & (t < start + length)] = sign * np.deg2rad(2.0)
    za, zq, zde, ma, mq, mde = TRUE.values()
    # ẋ = A x + B δe with x = (α, q): the model of short_period.py
    a = np.array([[za, 1.0 + zq], [ma, mq]])
    b = np.array([zde, mde])
    augmented = np.zeros((3, 3))
    augmented[:2, :2] = a
    augmented[:2, 2] = b
    # expm([[A, B], [0, 0]] Δt) = [[Φ, Γ], [0, 1]]
    exponential = expm(augmented * dt)
    phi, gamma = exponential[:2, :2], exponential[:2, 2]
    xs = np.zeros((n, 2))
    for k in range(n - 1):
        # x_{k+1} = Φ x_k + Γ δe_k   (δe held at δe_k over [t_k, t_{k+1}))
        xs[k + 1] = phi @ xs[k] + gamma * de[k]
    alpha = np.rad2deg(xs[:, 0]) + rng.normal(0, 0.02, n)
    q = np.rad2deg(xs[:, 1]) + rng.normal(0, 0.05, n)
    return np.column_stack([t, np.rad2deg(de), alpha, q])


def write(path: Path) -> None:
    with open(path, "w") as out:
        out.write("time [s],elevator [deg],AOA [deg],pitch_rate [deg/s]\n")
        for row in flight():
            out.write(",".join(f"{v:.6f}" for v in row) + "\n")


if __name__ == "__main__":
    write(Path(__file__).resolve().parent / "my_flight.csv")
