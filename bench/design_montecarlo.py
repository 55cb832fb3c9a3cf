"""Proof by simulation of the input design: predicted vs realised σ.

For two airplanes, a designed input and the reference maneuver of the same duration and
amplitude are each flown in simulation ``--runs`` times with fresh seeded measurement noise
(numpy ``default_rng([seed, case, input, run])``), and every run is estimated by output-error
ML (``flightid.estimation.estimate``, MNRES, R estimated with the "max" policy, started from
the true values, x0 known). The realised σ of each parameter is the standard deviation of its
estimates over the runs; the predicted σ is the Cramér–Rao bound of
``flightid.design.information.predict_accuracy`` for the same input and noise σ.

* ATTAS short period (``examples/cases/short_period_design.toml``): 8 parameters at the
  a-priori values of the case; reference = the flight-test Elv1 elevator input (25 s, peak
  |Δδe| 0.0495 rad); designed = the case's D-optimal multisine (same duration, peak |Δδe| ≤
  0.0495 rad, α and q responses no larger than the reference's own simulated ones); noise
  σ_α = 1.75e-3 rad, σ_q = 3.03e-3 rad/s (√R of the standard ATTAS run).
* RP-1153 example 3 (``flightid.paper.example3``): the 19 lateral derivatives at the
  simulation values, noise of case 2 (table IV); reference = the example's aileron and rudder
  doublets (±0.1 rad, 24 s at 0.05 s); designed = a D-optimal orthogonal multisine on δa and
  δr (band 0.05–1.5 Hz searched, peak ≤ 0.1 rad each, 24 s, β, p, r, Φ responses limited to
  the reference's own simulated peaks). The longitudinal inputs u, w, q (measured inputs of the
  decoupled lateral model) are the example's series in both.

The realised σ of n runs has a relative standard error of about 1/√(2(n − 1)) (4.1 % for
n = 300), so the 15 % acceptance band is ≈ 3.7 of them. The script prints, per case, one
row per parameter: predicted and realised σ of the reference and of the designed input, the
ratio realised/predicted, and designed/reference (realised); then the relative peak factors
of the generated multisines (optimised vs Schroeder phases). Exit status 1 when a realised σ
falls outside ±15 % of its prediction.

Usage::

    python bench/design_montecarlo.py [--runs 300] [--seed 17] [--case attas|example3|all]
        [--figures docs/figures]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TOLERANCE = 0.15


def _monte_carlo(model, data, noise_std, runs, seed, tags):
    """Estimates (runs × n_f) of ``model``'s free parameters over noisy copies of ``data``."""
    from flightid.data.flightdata import FlightData
    from flightid.estimation import MNRES, estimate
    from flightid.simulation import simulate

    clean = simulate(model, data)
    inputs = {n: data.input(n) for n in data.input_names}
    sigma = np.array([noise_std[o] for o in model.outputs])
    estimates, failed = [], 0
    for run in range(runs):
        rng = np.random.default_rng([seed, *tags, run])
        noisy = clean + rng.standard_normal(clean.shape) * sigma
        flown = FlightData(data.time, inputs, {o: noisy[:, i] for i, o in enumerate(model.outputs)})
        result = estimate(model, flown, MNRES(), noise="max")
        if not result.converged:
            failed += 1
            continue
        estimates.append(result.values)
    return np.array(estimates), failed


def _table(title, names, reference, designed, runs):
    """Markdown rows and the worst |realised/predicted − 1| of both inputs."""
    (ref_pred, ref_real, ref_failed), (des_pred, des_real, des_failed) = reference, designed
    lines = [
        f"### {title}",
        "",
        f"{runs} runs per input (not converged: reference {ref_failed}, designed {des_failed}).",
        "",
        "| parameter | reference σ predicted | reference σ realised | ratio | "
        "designed σ predicted | designed σ realised | ratio | designed / reference (realised) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    worst = 0.0
    for j, name in enumerate(names):
        r1 = ref_real[j] / ref_pred[j]
        r2 = des_real[j] / des_pred[j]
        worst = max(worst, abs(r1 - 1), abs(r2 - 1))
        lines.append(
            f"| {name} | {ref_pred[j]:.4g} | {ref_real[j]:.4g} | {r1:.3f} | {des_pred[j]:.4g} | "
            f"{des_real[j]:.4g} | {r2:.3f} | {des_real[j] / ref_real[j]:.3f} |"
        )
    gain_pred = np.exp(np.mean(np.log(des_pred / ref_pred)))
    gain_real = np.exp(np.mean(np.log(des_real / ref_real)))
    lines += [
        "",
        f"geometric mean of designed/reference σ: predicted {gain_pred:.3f}, realised "
        f"{gain_real:.3f}; worst |realised/predicted − 1| = {worst:.3f} "
        f"({'PASS' if worst <= TOLERANCE else 'FAIL'} at {TOLERANCE:.0%})",
        "",
    ]
    return lines, worst


def attas(runs: int, seed: int):
    """Reference Elv1 and two designs: the case's (response limits = the reference's peaks)
    and the same without response limits (amplitude and duration only)."""
    from dataclasses import replace

    from flightid.cases import load_case
    from flightid.cases.build import load_maneuvers, resolve_data_dir
    from flightid.cases.design_case import run_design_case
    from flightid.data.flightdata import FlightData
    from flightid.design.optimize import design_input, trim_state

    case = load_case(ROOT / "examples" / "cases" / "short_period_design.toml")
    result = run_design_case(case)
    problem = result.problem
    noise = dict(problem.noise_std)
    # the reference: Elv1's measured δe, x0 the trim at its first sample (as the case predicts)
    elv1 = load_maneuvers(case, resolve_data_dir(case))[0]
    de = elv1.channel("de")
    reference_model = problem.model.with_x0(tuple(trim_state(problem.model, {"de": de[0]})))
    reference_data = FlightData(elv1.time, {"de": de}, name="Elv1")
    ref_acc = result.reference[0]
    estimates, failed = _monte_carlo(reference_model, reference_data, noise, runs, seed, (1, 0))
    reference = (ref_acc.std, estimates.std(axis=0, ddof=1), failed)
    free_problem = replace(problem, limits={})
    free_best, _ = design_input(free_problem)
    lines, worst, designs = [], 0.0, []
    for tag, label, design_problem, best in (
        (1, "amplitude, duration and response ≤ the reference's (the shipped case)", problem,
         result.best),
        (2, "amplitude and duration only", free_problem, free_best),
    ):  # fmt: skip
        data = design_problem.flight_data(best.perturbations)
        estimates, failed = _monte_carlo(problem.model, data, noise, runs, seed, (1, tag))
        designed = (best.accuracy.std, estimates.std(axis=0, ddof=1), failed)
        peaks = ", ".join(f"{o} {v:.4g}" for o, v in best.response_peak.items())
        header = (
            f"ATTAS short period, 8 parameters — limits: {label}. Reference Elv1 (25 s, peak "
            f"|Δδe| {result.reference[1]['peak_amplitude']['de']:.4f} rad) vs designed multisine "
            f"(band {best.setting['de']['band_hz']} Hz, peak |Δδe| {best.peak_amplitudes[0]:.4f} "
            f"rad, peak |Δy| {peaks})"
        )
        block, w = _table(header, best.accuracy.names, reference, designed, runs)
        lines += block
        worst = max(worst, w)
        designs.append((f"ATTAS design, {label.split(' (')[0]}", best.multisine))
    return lines, worst, designs


def example3(runs: int, seed: int, candidates: int = 6):
    """Reference doublets and two designs: response limits = the reference's peaks, and
    amplitude and duration only."""
    from dataclasses import replace

    from flightid.data.flightdata import FlightData
    from flightid.design.information import predict_accuracy
    from flightid.design.optimize import DesignProblem, InputSpec, design_input
    from flightid.paper.example3 import NOISE_STD, SIMULATION_VALUES, _truth, example3_model
    from flightid.simulation import simulate

    trim, t, inputs, longitudinal, _ = _truth()
    model = example3_model(SIMULATION_VALUES)
    noise = dict(NOISE_STD[2])
    reference_data = FlightData(t, {"da": inputs["da"], "dr": inputs["dr"], **longitudinal})
    # the reference's own response peaks about the trim-input response: the design's limits
    steady = FlightData(
        t,
        {"da": np.full(t.shape, trim.inputs["da"]), "dr": np.full(t.shape, trim.inputs["dr"]),
         **longitudinal},
    )  # fmt: skip
    peaks = np.max(np.abs(simulate(model, reference_data) - simulate(model, steady)), axis=0)
    limits = {o: float(p) for o, p in zip(model.outputs, peaks, strict=True) if o != "ay"}
    problem = DesignProblem(
        model,
        (
            InputSpec("da", 0.1, float(trim.inputs["da"])),
            InputSpec("dr", 0.1, float(trim.inputs["dr"])),
        ),
        float(t[-1]),
        float(t[1] - t[0]),
        noise,
        band_hz=(0.05, 1.5),
        held=longitudinal,
        limits=limits,
        candidates=candidates,
    )
    reference_acc = predict_accuracy(model, reference_data, noise)
    estimates, failed = _monte_carlo(model, reference_data, noise, runs, seed, (3, 0))
    reference = (reference_acc.std, estimates.std(axis=0, ddof=1), failed)
    limit_text = ", ".join(f"{o} {v:.4g}" for o, v in limits.items())
    lines, worst, designs = [], 0.0, []
    for tag, label, design_problem in (
        (1, f"amplitude, duration and response ≤ the reference's ({limit_text})", problem),
        (2, "amplitude and duration only", replace(problem, limits={})),
    ):
        best, _ = design_input(design_problem)
        data = design_problem.flight_data(best.perturbations)
        estimates, failed = _monte_carlo(model, data, noise, runs, seed, (3, tag))
        designed = (best.accuracy.std, estimates.std(axis=0, ddof=1), failed)
        bands = ", ".join(
            f"{n} {np.round(best.setting[n]['band_hz'], 3).tolist()} Hz" for n in ("da", "dr")
        )
        peaks = ", ".join(f"{o} {v:.4g}" for o, v in best.response_peak.items())
        header = (
            f"RP-1153 example 3, 19 parameters, noise case 2 — limits: {label}. Reference "
            f"doublets (±0.1 rad, 24 s) vs designed multisine ({bands}; peak |Δu| "
            f"{np.round(best.peak_amplitudes, 4).tolist()} rad; peak |Δy| {peaks})"
        )
        block, w = _table(header, best.accuracy.names, reference, designed, runs)
        lines += block
        worst = max(worst, w)
        designs.append((f"example 3 design, {label.split(' (')[0]}", best.multisine))
    return lines, worst, designs


def peak_factor_lines(designs) -> list[str]:
    from flightid.design.multisine import design_multisine

    lines = [
        "### Relative peak factors (RPF = (max − min)/(2√2 rms), dense grid of one period)",
        "",
        "| multisine | input | harmonics | RPF Schroeder phases | RPF optimised |",
        "|---|---|---|---|---|",
    ]
    standard = [
        ("1 input, 20 s, 0.1–2 Hz", design_multisine(("u1",), 20.0, (0.1, 2.0), [1.0])),
        ("2 inputs, 24 s, 0.1–1.5 Hz", design_multisine(("u1", "u2"), 24.0, (0.1, 1.5), [1, 1])),
        (
            "3 inputs, 20 s, 0.1–2 Hz",
            design_multisine(("u1", "u2", "u3"), 20.0, (0.1, 2.0), [1, 1, 1]),
        ),
    ]
    for label, multisine in [*standard, *designs]:
        for j, name in enumerate(multisine.names):
            lines.append(
                f"| {label} | {name} | {multisine.harmonics[j].size} | "
                f"{multisine.rpf_schroeder[j]:.4f} | {multisine.rpf[j]:.4f} |"
            )
    lines.append("")
    return lines


def signal_figure(path: Path) -> None:
    """The generators: doublet, 2-1-1 and 3-2-1-1 timed to f_n = 0.5 Hz, and a two-input
    orthogonal multisine with Schroeder and optimised phases."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from flightid.design.multisine import design_multisine, schroeder_phases, sum_of_cosines
    from flightid.design.signals import doublet, pulse_width_s, three_two_one_one, two_one_one

    t = np.arange(0.0, 8.0 + 1e-9, 0.01)
    f_n = 0.5
    figure, axes = plt.subplots(3, 1, figsize=(7.5, 6.0))
    for k, (label, generator, signal) in enumerate(
        (("doublet", doublet, "doublet"), ("2-1-1", two_one_one, "211"),
         ("3-2-1-1", three_two_one_one, "3211"))
    ):  # fmt: skip
        pulse = pulse_width_s(signal, f_n)
        axes[0].plot(
            t, generator(t, 0.5, pulse, 1.0) - 2.5 * k, label=f"{label}, Δt = {pulse:.2f} s"
        )
    axes[0].set_title("step inputs timed to f_n = 0.5 Hz", fontsize=9)
    axes[0].legend(fontsize=7, loc="lower right")
    axes[0].set_yticks([])
    period = 20.0
    multisine = design_multisine(("u1", "u2"), period, (0.1, 1.5), [1.0, 1.0])
    tm = np.arange(0.0, period + 1e-9, 0.02)
    optimised = multisine.signals(tm)
    for j in range(2):
        k = multisine.harmonics[j]
        schroeder = sum_of_cosines(tm, period, k, schroeder_phases(k.size))
        ax = axes[1 + j]
        ax.plot(tm, schroeder / np.max(np.abs(schroeder)), color="0.6", lw=0.8,
                label=f"Schroeder phases, RPF {multisine.rpf_schroeder[j]:.3f}")  # fmt: skip
        ax.plot(tm, optimised[:, j], lw=0.9, label=f"optimised, RPF {multisine.rpf[j]:.3f}")
        ax.set_ylabel(f"u{j + 1}")
        ax.legend(fontsize=7, loc="lower right")
    axes[1].set_title(
        "orthogonal multisines, 20 s, 0.1–1.5 Hz, harmonics dealt alternately", fontsize=9
    )
    axes[2].set_xlabel("time (s)")
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    plt.close(figure)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=300)
    parser.add_argument("--seed", type=int, default=17)
    parser.add_argument("--case", choices=("attas", "example3", "all"), default="all")
    parser.add_argument(
        "--figures", default=None, help="also write design_signals.png into this folder"
    )
    args = parser.parse_args(argv)
    if args.figures:
        signal_figure(Path(args.figures) / "design_signals.png")
    started = time.perf_counter()
    lines, worst, designs = [], 0.0, []
    if args.case in ("attas", "all"):
        block, w, found = attas(args.runs, args.seed)
        lines += block
        worst = max(worst, w)
        designs += found
    if args.case in ("example3", "all"):
        block, w, found = example3(args.runs, args.seed)
        lines += block
        worst = max(worst, w)
        designs += found
    lines += peak_factor_lines(designs)
    lines.append(
        f"runs {args.runs}, seed {args.seed}; wall time {time.perf_counter() - started:.1f} s"
    )
    print("\n".join(lines))
    return 0 if worst <= TOLERANCE else 1


if __name__ == "__main__":
    sys.exit(main())
