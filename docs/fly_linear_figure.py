"""The Bode plot and step response of the linearized HFB-320 estimate (docs/fly.md).

Runs the HFB-320 case with the built-in wind-axis model, linearizes the estimate at the
initial state and mean inputs of its maneuver, and draws, from ``LinearModel.to_scipy()``,
the frequency response from the elevator to α and q and the response of α, q and V to a
−1° elevator step (a perturbation from the operating point), with the short-period and
phugoid frequencies marked. Writes docs/figures/fly_bode_step_hfb320.png.

    python docs/fly_linear_figure.py
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
from scipy import signal

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "examples" / "cases" / "hfb320_longitudinal_builtin.toml"
FIGURE = ROOT / "docs" / "figures" / "fly_bode_step_hfb320.png"
STEP_RAD = math.radians(-1.0)  # elevator step, rad (trailing edge up: nose up)


def linear_hfb320():
    """The linear model of the HFB-320 estimate at its maneuver's operating point."""
    from flightid.cases import run_case

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the case's two 6-σ outliers in α
        run = run_case(CASE, accuracy="none")
    return run.estimate.linearize(at=run.maneuvers[0])


def siso(system: signal.StateSpace, linear, output: str, input_name: str) -> signal.StateSpace:
    """The single-input single-output part of ``system`` from ``input_name`` to ``output``."""
    i, j = linear.outputs.index(output), linear.inputs.index(input_name)
    return signal.StateSpace(system.A, system.B[:, [j]], system.C[[i], :], system.D[[i]][:, [j]])


def frequency_response(system: signal.StateSpace, omega: np.ndarray) -> np.ndarray:
    """H(jω) of a single-input single-output ``system`` at the frequencies ``omega`` (rad/s)."""
    n = system.A.shape[0]
    # H(jω) = C (jω I − A)⁻¹ B + D, solved per frequency (no transfer-function polynomials)
    return np.array(
        [
            (system.C @ np.linalg.solve(1j * w * np.eye(n) - system.A, system.B))[0, 0]
            + system.D[0, 0]
            for w in omega
        ]
    )


def main() -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    linear = linear_hfb320()
    system = linear.to_scipy()
    modes = linear.modes()
    omega = np.logspace(-2, 1.5, 600)  # rad/s
    figure, axes = plt.subplots(2, 2, figsize=(10, 6.5))
    for output, colour in (("alpha", "C0"), ("q", "C1")):
        response = frequency_response(siso(system, linear, output, "de"), omega)
        magnitude_db = 20.0 * np.log10(np.abs(response))
        phase_deg = np.degrees(np.unwrap(np.angle(response)))
        w = omega
        axes[0, 0].semilogx(w, magnitude_db, colour, label=f"{output} / de")
        axes[1, 0].semilogx(w, phase_deg, colour, label=f"{output} / de")
    for mode in modes:
        if np.isfinite(mode.natural_frequency):
            for axis in axes[:, 0]:
                axis.axvline(mode.natural_frequency, color="grey", lw=0.8, ls=":")
            axes[0, 0].annotate(mode.name, (mode.natural_frequency, 0.95),
                                xycoords=("data", "axes fraction"), fontsize=8,
                                rotation=90, va="top", ha="right")  # fmt: skip
    axes[0, 0].set_ylabel("magnitude (dB)")
    axes[1, 0].set_ylabel("phase (deg)")
    axes[1, 0].set_xlabel("frequency (rad/s)")
    axes[0, 0].set_title("Bode plot from the elevator")
    axes[0, 0].legend(fontsize=8)
    t = np.linspace(0.0, 120.0, 2401)  # s
    for k, (output, unit, scale) in enumerate(
        (("alpha", "deg", 180 / math.pi), ("q", "deg/s", 180 / math.pi), ("V", "m/s", 1.0))
    ):
        _, y = signal.step(siso(system, linear, output, "de"), T=t)
        axis = axes[0, 1] if k < 2 else axes[1, 1]
        axis.plot(t, STEP_RAD * y * scale, f"C{k}", label=f"Δ{output} ({unit})")
    axes[0, 1].set_title("response to a −1° elevator step")
    axes[0, 1].legend(fontsize=8)
    axes[1, 1].legend(fontsize=8)
    axes[1, 1].set_xlabel("time (s)")
    for axis in axes.flat:
        axis.grid(True, which="both", alpha=0.3)
    figure.suptitle("HFB-320 estimate, linearized at its maneuver's operating point")
    figure.tight_layout()
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(FIGURE, dpi=110)
    print(modes.summary())
    print(f"wrote {FIGURE.relative_to(ROOT)}")
    return FIGURE


if __name__ == "__main__":
    main()
