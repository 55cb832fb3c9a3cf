"""The result of an input design: the designed input, its predicted accuracy, and reports.

``DesignResult`` answers the common result calls (``flightid.results``): ``summary()``,
``to_frame()``,
``to_dict()`` (one results.json entry: ``parameters`` [{name, value, std, free, unit,
initial}] with std the *predicted* Cramér–Rao bound, plus ``inputs`` {time, one series per
input}, ``predicted`` {name: σ}, the settings, peak factors and the reference maneuver's
prediction), ``to_json()`` and ``plot()``; its result folder is written by
``flightid.report.estimator_reports.write_design_files``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flightid.design.information import PredictedAccuracy
from flightid.design.optimize import Candidate, DesignProblem
from flightid.design.signals import relative_peak_factor
from flightid.numbers import format_sigma, format_with_sigma

__all__ = ["DesignResult"]


@dataclass(frozen=True)
class DesignResult:
    """A finished design (``flightid.cases.design_case.run_design_case``)."""

    problem: DesignProblem
    best: Candidate
    tried: tuple[Candidate, ...]
    reference: tuple[PredictedAccuracy, dict] | None = None
    title: str = ""
    case_file: str = ""
    wall_time_s: float = 0.0

    # ------------------------------------------------------------------ numbers
    @property
    def predicted(self) -> dict[str, float]:
        """parameter name → predicted σ of the designed input."""
        accuracy = self.best.accuracy
        return {n: float(s) for n, s in zip(accuracy.names, accuracy.std, strict=True)}

    def peak_factors(self) -> dict[str, dict[str, float]]:
        """Per input: RPF of the sampled designed input; for a multisine also the fine-grid
        RPF of the optimised and of the Schroeder phases."""
        factors = {}
        for j, name in enumerate(self.best.input_names):
            entry = {"sampled": relative_peak_factor(self.best.perturbations[:, j])}
            if self.best.multisine is not None:
                entry["optimised"] = float(self.best.multisine.rpf[j])
                entry["schroeder"] = float(self.best.multisine.rpf_schroeder[j])
            factors[name] = entry
        return factors

    def _absolute_inputs(self) -> dict[str, np.ndarray]:
        return {
            spec.name: spec.trim + self.best.perturbations[:, j]
            for j, spec in enumerate(self.problem.inputs)
        }

    # ------------------------------------------------------------------ surface
    def summary(self) -> str:
        problem, best = self.problem, self.best
        lines = [
            f"input design: {self.title}" if self.title else "input design",
            f"  signal {problem.signal}, criterion {problem.criterion} = "
            f"{best.criterion_value:.6g}, {len(self.tried)} candidates, "
            f"{problem.duration_s:g} s at {problem.dt_s:g} s",
        ]
        for j, spec in enumerate(problem.inputs):
            setting = best.setting.get(spec.name, {})
            described = ", ".join(f"{k} {v}" for k, v in setting.items())
            lines.append(
                f"  {spec.name}: trim {spec.trim:.6g}, peak |Δu| "
                f"{best.peak_amplitudes[j]:.6g} (limit {spec.amplitude:.6g}), {described}"
            )
        for name, entry in self.peak_factors().items():
            text = ", ".join(f"{k} {v:.4f}" for k, v in entry.items())
            lines.append(f"  relative peak factor {name}: {text}")
        for output, peak in best.response_peak.items():
            limit = problem.limits.get(output)
            suffix = f" (limit {limit:.6g})" if limit is not None else ""
            lines.append(f"  peak |Δ{output}| {peak:.6g}{suffix}")
        reference = self.reference
        header = f"  {'parameter':<12}{'value':>13}{'predicted σ':>14}{'σ %':>9}"
        if reference is not None:
            header += f"{'reference σ':>14}{'ratio':>8}"
        lines += ["", header]
        accuracy = best.accuracy
        for j, name in enumerate(accuracy.names):
            value, sigma = accuracy.values[j], accuracy.std[j]
            percent = 100 * sigma / abs(value) if value != 0 else float("nan")
            # σ to two significant digits, the value to the predicted σ's decimal place
            value_text, sigma_text = format_with_sigma(value, sigma)
            row = f"  {name:<12}{value_text:>13}{sigma_text:>14}{percent:>9.2f}"
            if reference is not None:
                ref = reference[0].std_of(name)
                row += f"{format_sigma(ref):>14}{sigma / ref:>8.3f}"
            lines.append(row)
        if reference is not None:
            facts = reference[1]
            amplitude = ", ".join(f"{k} {v:.4g}" for k, v in facts["peak_amplitude"].items())
            response = ", ".join(f"{k} {v:.4g}" for k, v in facts["response_peak"].items())
            lines.append(
                f"  reference: {facts['name']} ({facts['duration_s']:.4g} s, peak |Δu| "
                f"{amplitude}, peak |Δy| {response}); ratio = designed σ / reference σ"
            )
        correlation = accuracy.correlation
        n = len(accuracy.names)
        pairs = [
            (abs(correlation[i, k]), accuracy.names[i], accuracy.names[k], correlation[i, k])
            for i in range(n)
            for k in range(i + 1, n)
        ]
        if pairs:
            _, a, b, r = max(pairs)
            lines.append(f"  largest predicted correlation: {a}–{b} {r:+.3f}")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        problem, best = self.problem, self.best
        accuracy = best.accuracy
        parameters = problem.model.parameters
        units = {p.name: p.unit for p in parameters}
        entry = {
            "method": "input_design",
            "signal": problem.signal,
            "criterion": problem.criterion,
            "criterion_parameters": list(problem.parameters),
            "criterion_value": best.criterion_value,
            "duration_s": problem.duration_s,
            "dt_s": problem.dt_s,
            "inputs": {
                "time": best.time,
                **{n: best.perturbations[:, j] for j, n in enumerate(best.input_names)},
            },
            "trim": {spec.name: spec.trim for spec in problem.inputs},
            "held": {n: np.ravel(v).tolist() for n, v in problem.held.items()},
            "amplitude_limits": {spec.name: spec.amplitude for spec in problem.inputs},
            "amplitude_factors": dict(zip(best.input_names, best.amplitude_factors, strict=True)),
            "setting": best.setting,
            "peak_factors": self.peak_factors(),
            "noise_std": dict(zip(accuracy.output_names, accuracy.noise_std.tolist(), strict=True)),
            "limits": dict(problem.limits),
            "response_peak": best.response_peak,
            "predicted": self.predicted,
            "parameters": [
                {
                    "name": name,
                    "value": float(accuracy.values[j]),
                    "std": float(accuracy.std[j]),
                    "free": True,
                    "unit": units.get(name, ""),
                    "initial": float(accuracy.values[j]),
                }
                for j, name in enumerate(accuracy.names)
            ],
            "correlation": {"names": list(accuracy.names), "matrix": accuracy.correlation},
            "candidates": [
                {
                    "setting": c.setting,
                    "amplitude_factors": list(c.amplitude_factors),
                    "criterion_value": c.criterion_value,
                }
                for c in self.tried
            ],
            "wall_time_s": self.wall_time_s,
            "case": {"title": self.title, "file": self.case_file},
        }
        if self.reference is not None:
            ref, facts = self.reference
            entry["reference"] = {
                **facts,
                "predicted": {n: float(s) for n, s in zip(ref.names, ref.std, strict=True)},
                "criterion_value": ref.criterion(problem.criterion, problem.parameters),
            }
        return entry

    def to_frame(self):
        """The predicted accuracy as a pandas DataFrame indexed by parameter name: value,
        predicted std (and the reference's, with a reference maneuver)."""
        from flightid.results import require_pandas

        pandas = require_pandas("DesignResult.to_frame()")
        accuracy = self.best.accuracy
        rows = []
        for j, name in enumerate(accuracy.names):
            row = {"name": name, "value": accuracy.values[j], "std": accuracy.std[j]}
            if self.reference is not None:
                row["reference_std"] = self.reference[0].std_of(name)
            rows.append(row)
        return pandas.DataFrame(rows).set_index("name")

    def to_json(self, indent: int | None = 2) -> str:
        from flightid.jsonout import dumps

        return dumps(self.to_dict(), indent=indent)

    def plot(self, path: str | Path | None = None, *, dpi: int = 100):
        """Designed input(s), predicted responses and the predicted relative bounds (and the
        reference maneuver's) in one figure; saved as PNG to ``path`` when given."""
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt

        best = self.best
        accuracy = best.accuracy
        n_in, n_out = len(best.input_names), len(accuracy.output_names)
        rows = n_in + n_out + 1
        figure, axes = plt.subplots(rows, 1, figsize=(7.5, 1.6 * rows + 1.0))
        t = best.time
        for j, name in enumerate(best.input_names):
            axes[j].plot(t, best.perturbations[:, j], lw=0.9)
            limit = self.problem.inputs[j].amplitude
            axes[j].axhline(limit, color="0.6", ls=":", lw=0.8)
            axes[j].axhline(-limit, color="0.6", ls=":", lw=0.8)
            axes[j].set_ylabel(f"Δ{name}")
        for i, name in enumerate(accuracy.output_names):
            ax = axes[n_in + i]
            ax.plot(t, accuracy.outputs[:, i], lw=0.9, color="C1")
            ax.set_ylabel(name)
        axes[n_in + n_out - 1].set_xlabel("time (s)")
        ax = axes[-1]
        scale = np.maximum(np.abs(accuracy.values), accuracy.typical)
        x = np.arange(len(accuracy.names))
        width = 0.4 if self.reference is not None else 0.8
        ax.bar(x, 100 * accuracy.std / scale, width, label=f"designed ({self.problem.signal})")
        if self.reference is not None:
            ref = self.reference[0]
            ax.bar(x + width, 100 * ref.std / scale, width, label="reference maneuver")
            ax.legend(fontsize=7)
        ax.set_xticks(x + (width / 2 if self.reference is not None else 0))
        ax.set_xticklabels(accuracy.names, fontsize=7)
        ax.set_ylabel("predicted σ (%)")
        figure.suptitle(self.title or "input design", fontsize=9)
        figure.tight_layout()
        if path is not None:
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            figure.savefig(path, dpi=dpi)
        return figure
