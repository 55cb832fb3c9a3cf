"""Monte Carlo coverage of the frequency-domain output-error intervals.

Truth: the ATTAS short-period model at its time-domain estimates (the values
``flightid run examples/cases/attas_short_period.toml --json`` prints, with Z0 and M0),
driven by the *measured* elevator of Elv1 and Elv2 (25 s each, Δt = 0.04 s) from the
measured initial α, q, simulated by ``scipy.signal.lsim`` (exact first-order hold, an
implementation independent of flightid's simulator). Seeded white Gaussian noise with the
time-domain residual variances R (α: 3.06e-6 rad², q: 9.19e-6 rad²/s²) is added; each
realisation is estimated by ``flightid.frequency.output_error`` on 0.1–1.5 Hz exactly as the
case file ``examples/cases/attas_short_period_frequency_domain.toml`` does (mean removed,
boundary values and constants as nuisance parameters), from the truth as start.

For every free parameter we count how often the truth lies in θ̂ ± 1.96 σ, with σ the
Cramér–Rao bound M⁻¹ ("CR") and the coloured-residual sandwich ("coloured"), and report the
RMS of (θ̂ − θ)/σ (1 when the bounds are the size of the scatter). ``--step`` sets the
frequency spacing (0.04 Hz = 1/T: independent frequencies; 0.02 Hz oversamples by 2).

Usage::

    python bench/frequency_monte_carlo.py [--n 200] [--seed 1000] [--step 0.04]

The binomial standard error of a coverage near 0.95 over 200 realisations is ≈ 0.015.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scipy.signal import StateSpace, lsim

from flightid.cases import load_case
from flightid.cases.build import load_maneuvers, resolve_data_dir
from flightid.frequency import LinearSystem, frequency_grid, maneuver_spectra, output_error

ROOT = Path(__file__).resolve().parents[1]
NAMES = ("Za", "Zq", "Zde", "Ma", "Mq", "Mde")
# time-domain estimates (flightid run examples/cases/attas_short_period.toml --json)
TRUTH = np.array([-0.483009, 0.102721, 0.675976, -4.935225, -2.012224, -7.226836])
Z0, M0 = -0.008885, 0.476384
R = np.array([3.0640e-6, 9.1949e-6])


def system_of(theta: np.ndarray) -> LinearSystem:
    za, zq, zde, ma, mq, mde = theta
    A = np.array([[za, 1.0 + zq], [ma, mq]])
    B = np.array([[zde], [mde]])
    return LinearSystem(A, B, np.eye(2), np.zeros((2, 1)), np.zeros(2), np.zeros(2))


def noise_free_records():
    case = load_case(ROOT / "examples/cases/attas_short_period.toml")
    records = []
    s = system_of(TRUTH)
    for m in load_maneuvers(case, resolve_data_dir(case)):
        t = m.time - m.time[0]
        de = m.input("de")
        x0 = [m.output("alpha")[0], m.output("q")[0]]
        # ẋ = A x + B δe + [Z0, M0]: the constants as a second, constant input
        B = np.hstack([s.B, np.eye(2)])
        u = np.column_stack([de, np.full_like(de, Z0), np.full_like(de, M0)])
        _, y, _ = lsim(StateSpace(s.A, B, s.C, np.zeros((2, 3))), u, t, X0=x0, interp=True)
        records.append((m.time, de, y))
    return records


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, default=200)
    parser.add_argument("--seed", type=int, default=1000)
    parser.add_argument("--step", type=float, default=0.04)
    args = parser.parse_args()
    band = frequency_grid((0.1, 1.5), args.step)
    records = noise_free_records()
    rng = np.random.default_rng(args.seed)
    z_cr, z_col = [], []
    started = time.perf_counter()
    for _ in range(args.n):
        spectra = []
        for t, de, y in records:
            noisy = y + rng.standard_normal(y.shape) * np.sqrt(R)
            spectra.append(maneuver_spectra(t, de, noisy, band))
        fit = output_error(
            system_of, TRUTH, np.ones(6, bool), spectra, ("alpha", "q"), ("alpha", "q")
        )
        z_cr.append((fit.theta - TRUTH) / fit.std_cr)
        z_col.append((fit.theta - TRUTH) / fit.std_coloured)
    elapsed = time.perf_counter() - started
    z_cr, z_col = np.array(z_cr), np.array(z_col)
    print(
        f"frequency-domain output error, ATTAS short period, {args.n} runs, seed {args.seed}, "
        f"band 0.1-1.5 Hz, step {args.step} Hz ({band.size} frequencies), {elapsed:.1f} s"
    )
    print("| parameter | coverage CR | coverage coloured | RMS z CR | RMS z coloured |")
    print("|---|---|---|---|---|")
    for j, name in enumerate(NAMES):
        print(
            f"| {name} | {np.mean(np.abs(z_cr[:, j]) < 1.96):.3f} | "
            f"{np.mean(np.abs(z_col[:, j]) < 1.96):.3f} | "
            f"{np.sqrt(np.mean(z_cr[:, j] ** 2)):.2f} | {np.sqrt(np.mean(z_col[:, j] ** 2)):.2f} |"
        )
    print(
        f"| all | {np.mean(np.abs(z_cr) < 1.96):.3f} | {np.mean(np.abs(z_col) < 1.96):.3f} | "
        f"{np.sqrt(np.mean(z_cr**2)):.2f} | {np.sqrt(np.mean(z_col**2)):.2f} |"
    )


if __name__ == "__main__":
    main()
