"""The HFB-320 estimate flown in JSBSim: the figure and numbers of the guide's section
"Flying it in JSBSim" (docs/fly.md).

Runs the shipped case ``examples/cases/hfb320_longitudinal_builtin.toml`` (its flight data
must be present), exports the estimate as a JSBSim aircraft with 20 parameter draws the way
``flightid export RUN --format jsbsim --draws 20`` does, flies the nominal aircraft and every
draw in JSBSim with the recorded elevator and thrust, and prints the RMS difference between
JSBSim's flight and flightid's own simulation of the estimate, per output, in units of the
estimated measurement-noise σ. Writes ``docs/figures/fly_jsbsim_hfb320.png``::

    python docs/fly_jsbsim.py          # needs the jsbsim extra: pip install 'flightid[jsbsim]'
"""

from __future__ import annotations

import math
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "examples" / "cases" / "hfb320_longitudinal_builtin.toml"
FIGURE = ROOT / "docs" / "figures" / "fly_jsbsim_hfb320.png"
RECORD = ROOT / "docs" / "numbers" / "fly_jsbsim.txt"
DRAWS = 20


def flown_outputs(aircraft, data, initial, g_m_s2: float, aerodynamics=None) -> dict:
    """JSBSim's flight of the aircraft (or one of its draws) with the recorded inputs."""
    from flightid.export.jsbsim import fly_jsbsim

    inputs = {name: data.input(name) for name in ("de", "F")}
    flown = fly_jsbsim(aircraft, data.time, inputs, initial, aerodynamics=aerodynamics)
    # the case's accelerometers are in m/s², JSBSim's load factors in g
    flown["ax"], flown["az"] = flown["ax"] * g_m_s2, flown["az"] * g_m_s2
    return flown


def main() -> int:
    from flightid.aircraft import AeroModel, airplane_from_table
    from flightid.cases import load_case, run_case
    from flightid.export.jsbsim import write_jsbsim
    from flightid.simulation import simulate

    case = load_case(CASE)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the case's outlier note
        run = run_case(case)
    estimate, data = run.estimate, run.maneuvers[0]
    spec = case.model
    airplane = airplane_from_table(spec["airplane"])
    with tempfile.TemporaryDirectory() as scratch:
        aircraft = write_jsbsim(
            estimate,
            airplane,
            Path(scratch) / "HFB320",
            aero=AeroModel(spec["aero"]),
            reference_speed=spec.get("reference_speed"),
            rate_speed=spec.get("rate_speed", "V"),
            dynamic_pressure="airplane",
            draws=DRAWS,
            seed=1,
        )
        y = simulate(estimate.model, data)
        V, alpha, theta, q = estimate.model.initial_state()
        # body velocities from V and α: u = V cos α, w = V sin α
        initial = {"u": V * math.cos(alpha), "w": V * math.sin(alpha), "theta": theta, "q": q}
        nominal = flown_outputs(aircraft, data, initial, airplane.g)
        draws = [
            flown_outputs(aircraft, data, initial, airplane.g, aerodynamics=k)
            for k in range(1, DRAWS + 1)
        ]
    sigma = np.sqrt(estimate.r_diag)
    names = estimate.output_names
    units = _units(estimate)
    lines = [
        "<!-- guide: docs/fly.md -->",
        "<!-- numbers: fly-jsbsim -->",
        "| output | unit | RMS(JSBSim − flightid) / σ |",
        "|---|---|---|",
    ]
    for i, name in enumerate(names):
        # RMS over the maneuver of the difference, in units of the noise σ = √R_ii
        ratio = float(np.sqrt(np.mean((nominal[name] - y[:, i]) ** 2)) / sigma[i])
        lines.append(f"| {name} | {units[i]} | {ratio:.1e} |")
    lines.append("<!-- /numbers -->")
    output = "\n".join(lines) + "\n"
    print(output, end="")
    RECORD.write_text(output, encoding="utf-8")
    _figure(data, estimate, y, nominal, draws, units)
    print(f"figure: {FIGURE.relative_to(ROOT)}")
    return 0


def _units(estimate) -> list[str]:
    """The outputs' units ("" where the case gives none)."""
    units = tuple(getattr(estimate, "output_units", None) or ())
    return [units[i] if i < len(units) else "" for i in range(len(estimate.output_names))]


def _figure(data, estimate, y, nominal, draws, units) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = ("alpha", "q", "V", "az")
    figure, axes = plt.subplots(len(shown), 1, figsize=(8, 7.5), sharex=True)
    names = list(estimate.output_names)
    for ax, name in zip(axes, shown, strict=True):
        i = names.index(name)
        spread = np.array([d[name] for d in draws])
        ax.fill_between(data.time, spread.min(axis=0), spread.max(axis=0), color="tab:orange",
                        alpha=0.25, lw=0, label=f"JSBSim, {len(draws)} draws")  # fmt: skip
        ax.plot(data.time, data.output(name), ".", ms=2, color="0.45", label="measured")
        ax.plot(data.time, y[:, i], color="tab:blue", lw=1.6, label="flightid")
        ax.plot(data.time, nominal[name], "--", color="k", lw=0.9, label="JSBSim")
        ax.set_ylabel(f"{name} [{units[i]}]" if units[i] else name, fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, lw=0.4, alpha=0.5)
    axes[0].legend(fontsize=7, ncol=4, loc="upper right")
    axes[-1].set_xlabel("time, s", fontsize=8)
    figure.suptitle("HFB-320 estimate flown in JSBSim with the recorded elevator and thrust",
                    fontsize=9)  # fmt: skip
    figure.tight_layout()
    figure.savefig(FIGURE, dpi=110)


if __name__ == "__main__":
    sys.exit(main())
