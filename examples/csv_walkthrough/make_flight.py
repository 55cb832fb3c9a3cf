"""Write my_flight.csv: a simulated short-period 3-2-1-1 maneuver with seeded noise.

True values (Za, Zq, Zde, Ma, Mq, Mde) = (-0.8, 0.05, -0.1, -4.5, -1.6, -7.0); dt = 0.02 s;
angles in degrees in the file, as many data systems record them. Run: python make_flight.py
"""

import numpy as np

rng = np.random.default_rng(6)
dt, n = 0.02, 501
t = np.arange(n) * dt
de = np.zeros(n)
for start, length, sign in ((1.0, 1.5, 1), (2.5, 1.0, -1), (3.5, 0.5, 1), (4.0, 0.5, -1)):
    de[(t >= start) & (t < start + length)] = sign * np.deg2rad(2.0)
theta = np.array([-0.8, 0.05, -0.1, -4.5, -1.6, -7.0])
x = np.zeros(2)
xs = np.empty((n, 2))
for k in range(n):
    xs[k] = x
    # Euler at a 10x finer step between samples (the "truth" differs from the RK4 model)
    for _ in range(10):
        a, q = x
        d = de[k]
        x = x + dt / 10 * np.array(
            [
                theta[0] * a + (1 + theta[1]) * q + theta[2] * d,
                theta[3] * a + theta[4] * q + theta[5] * d,
            ]
        )
alpha = np.rad2deg(xs[:, 0]) + rng.normal(0, 0.02, n)
q = np.rad2deg(xs[:, 1]) + rng.normal(0, 0.05, n)
with open("my_flight.csv", "w") as out:
    out.write("time [s],elevator [deg],AOA [deg],pitch_rate [deg/s]\n")
    for row in zip(t, np.rad2deg(de), alpha, q, strict=True):
        out.write(",".join(f"{v:.6f}" for v in row) + "\n")
