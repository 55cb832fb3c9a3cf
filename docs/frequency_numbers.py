"""The measured numbers of docs/frequency.md: the comparison with the time domain and the
Monte Carlo coverage, printed by the benchmark scripts that measure them.

    python docs/frequency_numbers.py [--record] [--write] [--check]

Fits the multirotor rate-loop example (a delayed second-order loop simulated with scipy,
seeded) with the input delay free, held and absent, and over 20 noise seeds; runs
``bench/frequency_comparison.py`` (the case files' band 0.1–1.5 Hz, and 0.04–3 Hz) and
``bench/frequency_monte_carlo.py --n 200`` at the steps 0.04 Hz and 0.02 Hz, and prints
their tables as the guide quotes them (the lines that state a wall time without it). About
5 minutes on one core, most of it the Monte Carlo runs.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys

import case_numbers as cn
import numpy as np

BENCH = cn.ROOT / "bench"


def bench(script: str, *arguments: str, data_dir: str | None = None) -> str:
    """What ``python bench/SCRIPT ARGUMENTS`` prints."""
    environment = dict(os.environ, PYTHONPATH=str(cn.ROOT / "src"))
    if data_dir:
        environment["FLIGHTID_DATA"] = data_dir
    done = subprocess.run(
        [sys.executable, str(BENCH / script), *arguments],
        capture_output=True,
        text=True,
        env=environment,
        check=False,
    )
    if done.returncode != 0:
        raise SystemExit(f"bench/{script} failed: {done.stderr.strip()}")
    return done.stdout


def comparison_tables(output: str) -> list[str]:
    """The tables and summary lines of ``bench/frequency_comparison.py``, one per case, each
    without the heading line that states the wall times."""
    blocks = re.split(r"\n(?=\S+\.toml \(time domain)", "\n" + output.strip())
    return [block.split("\n", 1)[1].strip() for block in blocks if block.strip()]


def without_wall_time(output: str) -> str:
    """``…, 16.1 s`` at the end of the Monte Carlo heading line removed."""
    return re.sub(r", [\d.]+ s$", "", output.strip(), count=1, flags=re.MULTILINE)


# The multirotor rate-loop example: p/p_cmd = ω_n² e^{−τs}/(s² + 2ζω_n s + ω_n²)
WN, ZETA, TAU = 42.0, 0.6, 0.025  # rad/s, -, s
DT = 0.005  # s (200 Hz)


def multisine(t: np.ndarray) -> np.ndarray:
    """Schroeder-phased multisine, 0.2–12 Hz in 0.2 Hz steps, rad/s."""
    freqs = np.arange(1, 61) * 0.2
    k = np.arange(1, freqs.size + 1)
    phase = -np.pi * k * (k - 1) / freqs.size
    waves = np.cos(2 * np.pi * freqs[None, :] * t[:, None] + phase[None, :])
    return 0.2 * waves.sum(axis=1) / np.sqrt(freqs.size / 2)


def rate_loop_record(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, p_cmd, p): the loop simulated by scipy on a 2 kHz grid fed the exactly delayed
    multisine, sampled at 200 Hz for 20 s, noise N(0, 0.02²) on p."""
    from scipy import signal

    t_fine = np.arange(4000 * 10 + 1) * DT / 10
    loop = signal.lti([WN**2], [1.0, 2 * ZETA * WN, WN**2])
    _, p, _ = signal.lsim(loop, multisine(t_fine - TAU), t_fine)
    t = t_fine[::10]
    rng = np.random.default_rng(seed)
    return t, multisine(t), p[::10] + 0.02 * rng.standard_normal(t.size)


def rate_loop_spectra(seed: int):
    """The transforms of ``rate_loop_record(seed)`` on 0.2–12 Hz, step 0.05 Hz."""
    from flightid.frequency import frequency_grid, maneuver_spectra

    t, u, y = rate_loop_record(seed)
    grid = frequency_grid((0.2, 12.0), 0.05)
    return maneuver_spectra(t, u[:, None], y[:, None], grid, input_quadrature="trapezoid")


def _loop_f(t, x, u, theta):
    # ṗ = r, ṙ = −ω_n² p − 2ζω_n r + ω_n² p_cmd
    wn, zeta = theta[0], theta[1]
    return np.array([x[1], -(wn**2) * x[0] - 2 * zeta * wn * x[1] + wn**2 * u[0]])


def _loop_h(t, x, u, theta):
    return np.array([x[0]])


def loop_model(delay: str):
    """The loop model from ω_n = 30, ζ = 0.5; τ free from 0, held at 0.025 s, or absent."""
    from flightid.model import Parameter, Parameters, StateSpaceModel

    parameters = [Parameter("wn", 30.0), Parameter("zeta", 0.5)]
    if delay != "none":
        held = delay == "fixed"
        parameters.append(Parameter("tau", TAU if held else 0.0, free=not held))
    return StateSpaceModel(
        states=("p", "r"),
        inputs=("p_cmd",),
        outputs=("p",),
        f=_loop_f,
        h=_loop_h,
        parameters=Parameters(parameters),
        input_delays=None if delay == "none" else {"p_cmd": "tau"},
    )


def loop_fit(spectra, delay: str):
    """Frequency-domain output error of ``loop_model(delay)``."""
    from flightid.frequency import linear_system, output_error

    model = loop_model(delay)
    return output_error(
        lambda theta: linear_system(model, theta),
        model.parameters.values,
        model.parameters.free_mask,
        [spectra],
        model.states,
        model.outputs,
    )


def delay_table() -> str:
    """The three fits on noise seed 1, ± Cramér–Rao σ."""
    spectra = rate_loop_spectra(1)
    rows = []
    for delay, label in (("free", "input delay, free"), ("fixed", "input delay, fixed"),
                         ("none", "no delay")):  # fmt: skip
        fit = loop_fit(spectra, delay)
        sigma = fit.std_cr
        cells = [f"{fit.theta[0]:.5g} ± {sigma[0]:.3g}", f"{fit.theta[1]:.4g} ± {sigma[1]:.2g}"]
        if delay == "free":
            cells.append(f"{fit.theta[2]:.4g} ± {sigma[2]:.2g}")
        else:
            cells.append(f"{TAU:g} (held)" if delay == "fixed" else "—")
        rows.append([label, "converged" if fit.converged else "not converged", *cells])
    return cn.table(["model", "status", "ω_n (rad/s)", "ζ", "τ (s)"], rows)


def delay_seeds(seeds: int = 20) -> str:
    """The standardised errors of the free-delay fit over ``seeds`` noise seeds."""
    z = []
    for seed in range(1, seeds + 1):
        fit = loop_fit(rate_loop_spectra(seed), "free")
        # (θ̂ − θ_true) / σ_CR
        z.append((fit.theta - np.array([WN, ZETA, TAU])) / fit.std_cr)
    z = np.array(z)
    means = ", ".join(f"{v:.2f}" for v in z.mean(axis=0))
    spreads = ", ".join(f"{v:.2f}" for v in z.std(axis=0, ddof=1))
    return (
        f"Over {seeds} noise seeds the standardised errors (θ̂ − θ)/σ_CR of ω_n, ζ, τ had means "
        f"{means} and standard deviations {spreads}."
    )


def build(data_dir: str | None) -> list[str]:
    regions = [cn.region("frequency-delay-example", f"{delay_table()}\n\n{delay_seeds()}")]
    for band, label in ((None, "case-band"), (("0.04", "3.0"), "wide-band")):
        output = bench("frequency_comparison.py", *(("--band", *band) if band else ()))
        tables = comparison_tables(output)
        for case, table in zip(("short-period", "lateral"), tables, strict=True):
            regions.append(cn.region(f"frequency-{label}-{case}", table))
    for step in ("0.04", "0.02"):
        output = bench("frequency_monte_carlo.py", "--n", "200", "--step", step)
        block = f"```\n{without_wall_time(output)}\n```"
        regions.append(cn.region(f"frequency-monte-carlo-{step}", block))
    return regions


if __name__ == "__main__":
    raise SystemExit(cn.main("frequency.md", "frequency_numbers", build))
