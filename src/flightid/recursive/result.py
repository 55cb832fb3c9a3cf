"""``RecursiveResult``: what a recursive (online) estimation produced.

Parameter time histories with their σ (one row per sample; for the FTR one row per update),
the reported final values and the last filtered values:

* reported value (rule ``report = "last_N"``, the reporting of FVSysID's ``mainRPE``): the
  mean over the last N rows of the estimates and of their σ — N = 10 samples for the
  filters, 5 updates for the FTR — or the last row (``"final"``);
* ``last_filtered``: the estimate and σ of the very last row.

Which σ ``std`` is, per method:

* EKF, UKF, UKF_aug: sqrt(diag P̂) of the filter covariance, the Cramér–Rao-type σ of the
  filter's noise model (also ``std_cr``). It holds only when that model describes the data,
  which the innovation tests check (``flightid.recursive.base``: a mean normalised
  innovation squared a factor 10 away from n_y, or too many innovations far outside their
  covariance, make the status ``inconsistent`` with the figure in the warning);
* FTR: the least-squares σ of each equation (``flightid.recursive.ftr``; also ``std_cr``);
* EFRLS: none. sqrt(diag P) of the forgetting-factor RLS matrix depends on P0 and λ, not on
  the data's noise (±3.6 for an L_p known to ±0.003), so it is not a standard error: it is
  reported as ``rls_scale``, ``std`` and ``std_cr`` are NaN (null in results.json), and the
  summary says so.

The result answers the common result surface (``flightid.results``): ``summary()``,
``to_dict()`` (one results.json entry), ``to_json()``, ``to_frame()``, ``conf_int()``,
and ``plot()``; its result folder is written by
``flightid.report.estimator_reports.write_recursive_files``.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from flightid.errors import InputError
from flightid.numbers import format_at_sigma, format_with_sigma
from flightid.results import ResultSurface, t_intervals

__all__ = ["RecursiveResult", "report_rows"]


def report_rows(report: str, n_rows: int) -> int:
    """Number of last history rows the ``report`` rule averages ("last_N" or "final")."""
    if report == "final":
        return 1
    match = re.fullmatch(r"last_(\d+)", report) if isinstance(report, str) else None
    if match is None or int(match.group(1)) < 1:
        raise InputError(f"report: expected 'final' or 'last_N' (N >= 1), got {report!r}")
    return min(int(match.group(1)), n_rows)


@dataclass(frozen=True, eq=False)
class RecursiveResult(ResultSurface):
    """A recursive estimation run (see the module docstring).

    Attributes:
        method: "ekf", "ukf", "ukf_aug", "efrls" or "ftr".
        parameter_names: the estimated parameters.
        time_s: time of each history row (s).
        samples: 1-based sample number of each history row.
        theta_history, std_history: (rows × parameters) estimates and σ.
        state_names, state_history: filtered model states (filters only).
        report: the rule of the reported value ("last_N" or "final").
        units, initial: per parameter (initial None for the FTR: no start values).
        n_samples: samples processed.
        nis: normalised innovation squared ν'S⁻¹ν per corrected sample (EKF, UKFs).
        warnings: filter-health warnings (``flightid.recursive.base``).
        wall_time_s: time spent in the estimator (s).
        settings: the estimator's settings.
        meta: case information (title, file, model, outputs, output_units, R0, maneuvers).
        model: the state-space model whose free parameters the filter estimated (at its
            start values; ``estimated_model`` sets the reported values), or None (FTR: it
            regresses the coefficients of measured-state equations, no model).
        covariance: the parameter block of the filter's last covariance P̂ (EKF, UKFs), over
            ``parameter_names``; None for the EFRLS (its P is no covariance) and the FTR.
    """

    method: str
    parameter_names: tuple[str, ...]
    time_s: np.ndarray
    samples: np.ndarray
    theta_history: np.ndarray
    std_history: np.ndarray
    state_names: tuple[str, ...]
    state_history: np.ndarray
    report: str
    units: tuple[str, ...]
    initial: tuple[float, ...] | None
    n_samples: int
    nis: np.ndarray
    warnings: tuple[str, ...]
    wall_time_s: float
    settings: Mapping[str, Any] = field(default_factory=dict)
    meta: Mapping[str, Any] = field(default_factory=dict)
    model: Any = None
    covariance: np.ndarray | None = None

    def __post_init__(self) -> None:
        report_rows(self.report, self.theta_history.shape[0])
        if not (np.all(np.isfinite(self.theta_history)) and np.all(np.isfinite(self.std_history))):
            raise InputError(f"{self.method}: non-finite parameter history (the filter diverged)")

    # ------------------------------------------------------------------ values

    @property
    def n_report(self) -> int:
        """History rows averaged for the reported value."""
        return report_rows(self.report, self.theta_history.shape[0])

    @property
    def values(self) -> np.ndarray:
        """Reported estimates: mean of the last ``n_report`` rows."""
        return self.theta_history[-self.n_report :].mean(axis=0)

    @property
    def has_standard_error(self) -> bool:
        """False for the EFRLS, whose σ history is an RLS scale, not a standard error."""
        return self.method != "efrls"

    @property
    def std(self) -> np.ndarray:
        """Reported σ: mean of the last ``n_report`` rows of σ (NaN for the EFRLS: no
        standard error, see ``rls_scale``)."""
        if not self.has_standard_error:
            return np.full(self.theta_history.shape[1], np.nan)
        return self.std_history[-self.n_report :].mean(axis=0)

    @property
    def std_cr(self) -> np.ndarray:
        """The Cramér–Rao-type σ: the filter covariance's (EKF, UKFs) or the least-squares
        one (FTR); equal to ``std``."""
        return self.std

    @property
    def rls_scale(self) -> np.ndarray:
        """EFRLS: mean over the last ``n_report`` rows of sqrt(diag P) of the RLS matrix (not
        a standard error); NaN for the other methods."""
        if self.has_standard_error:
            return np.full(self.theta_history.shape[1], np.nan)
        return self.std_history[-self.n_report :].mean(axis=0)

    @property
    def last_filtered(self) -> np.ndarray:
        """Estimates of the last history row."""
        return self.theta_history[-1].copy()

    @property
    def last_filtered_std(self) -> np.ndarray:
        """σ of the last history row (NaN for the EFRLS)."""
        if not self.has_standard_error:
            return np.full(self.theta_history.shape[1], np.nan)
        return self.std_history[-1].copy()

    @property
    def estimates(self) -> dict[str, float]:
        """Reported estimates, name → value."""
        return dict(zip(self.parameter_names, self.values.tolist(), strict=True))

    @property
    def converged(self) -> bool:
        """True when the filter ran through without a health warning."""
        return not self.warnings

    @property
    def conf_int_names(self) -> list[str]:
        return list(self.parameter_names)

    def conf_int(self, level: float = 0.95, method: str = "normal") -> np.ndarray:
        """value ± z_{(1+c)/2}·σ per parameter ((n, 2) array; normal quantile: the filter σ
        has no degrees of freedom)."""
        from flightid.results import check_method

        check_method(method, ("normal",))
        return t_intervals(self.values, self.std, level, 1, distribution="normal")

    # ------------------------------------------------------------------ the model in use

    def _require_model(self, call: str):
        from flightid.simulation.prediction import PredictionError

        if self.model is None:
            raise PredictionError(
                f"{call}: this {self.method} result holds no state-space model (the FTR "
                f"regresses the coefficients of measured-state equations); nothing to {call}"
            )
        return self.model

    @property
    def estimated_model(self):
        """The model with its free parameters at the reported ``values`` (the others at their
        fixed values); ``PredictionError`` for a result without a model (FTR)."""
        from flightid.simulation.prediction import model_at_estimate

        model = self._require_model("estimated_model")
        names = self.parameter_names
        return model_at_estimate(model, names, self.values, names)

    def _no_covariance(self) -> str:
        if self.method == "efrls":
            return (
                "the EFRLS gives no parameter covariance (its P depends on P0 and the "
                "forgetting factor, not on the noise of the data)"
            )
        return f"this {self.method} result holds no parameter covariance"

    def predict(self, data, x0=None, *, bands: bool = False):
        """The estimated model (reported values) on other data: outputs, residuals and fit
        numbers per maneuver (``flightid.simulation.prediction.predict_result``); RK4 with
        linearly interpolated inputs, the filters' own propagation.

        Args:
            data: a ``FlightData`` (one ``Prediction``) or a list (a tuple of them).
            x0: initial states (one value per state or ``{state: value}``, or a list per
                maneuver); states not given start at the data's channel of that name.
            bands: σ of the outputs from ``covariance`` (delta method); ``PredictionError``
                for the EFRLS and FTR, which have none.
        """
        from flightid.simulation.prediction import predict_result

        return predict_result(
            self.estimated_model,
            data,
            x0,
            bands=bands,
            covariance=self.covariance,
            no_covariance=self._no_covariance(),
        )

    def simulate(self, inputs, x0=None) -> np.ndarray:
        """Outputs (N_total, n_o) of the estimated model driven by the inputs of ``inputs``
        (a ``FlightData`` or a list), from ``x0`` (as in ``predict``)."""
        from flightid.simulation.prediction import simulate_result

        return simulate_result(self.estimated_model, inputs, x0)

    def linearize(self, at=None):
        """The estimated model linearized about ``at`` (None: its initial state, inputs 0; a
        ``FlightData``: its initial state and mean inputs; or ``(x, u)``), with the
        covariance of A, B, C, D from ``covariance`` (none, with a note, for the EFRLS);
        returns a ``LinearModel`` (``modes()``)."""
        from flightid.simulation.prediction import linearize_result

        outputs, units = self.meta.get("outputs", ()), self.meta.get("output_units", ())
        units = dict(zip(outputs, units, strict=False))
        return linearize_result(
            self.estimated_model,
            at,
            covariance=self.covariance,
            no_covariance=self._no_covariance(),
            units=units,
        )

    # ------------------------------------------------------------------ surface

    def _frame_rows(self) -> list[dict]:
        rows = []
        for j, name in enumerate(self.parameter_names):
            rows.append(
                {
                    "name": name,
                    "value": float(self.values[j]),
                    "std": float(self.std[j]),
                    "rls_scale": float(self.rls_scale[j]),
                    "last_filtered": float(self.theta_history[-1, j]),
                    "last_filtered_std": float(self.last_filtered_std[j]),
                    "initial": None if self.initial is None else self.initial[j],
                    "unit": self.units[j],
                }
            )
        return rows

    def summary(self) -> str:
        """Readable table of the reported values, σ and last filtered values."""
        title = self.meta.get("title", "")
        lines = [
            f"Recursive estimation ({self.method})" + (f": {title}" if title else ""),
            f"{self.n_samples} samples, {self.theta_history.shape[0]} history rows, reported "
            f"value = mean over the last {self.n_report} rows ({self.report}); "
            f"{self.wall_time_s:.3f} s in the estimator",
            "",
            f"{'parameter':<12} {'value':>14} {'std':>12} {'last filtered':>14} "
            f"{'initial':>12}  unit",
        ]
        for row in self._frame_rows():
            initial = "" if row["initial"] is None else f"{row['initial']:12.6g}"
            # σ to two significant digits, each value to its σ's decimal place (six
            # significant digits where the filter gives no σ)
            value, std = format_with_sigma(row["value"], row["std"])
            std = f"{std:>12}" if np.isfinite(row["std"]) else f"{'—':>12}"
            last = format_at_sigma(row["last_filtered"], row["last_filtered_std"])
            lines.append(
                f"{row['name']:<12} {value:>14} {std} {last:>14} {initial:>12}  {row['unit']}"
            )
        if not self.has_standard_error:
            scales = ", ".join(
                f"{n} {v:.3g}" for n, v in zip(self.parameter_names, self.rls_scale, strict=True)
            )
            lines += ["", f"NOTE: {self._std_note()}", f"rls_scale: {scales}"]
        if self.warnings:
            lines.append("")
            lines.extend(f"WARNING: {w}" for w in self.warnings)
        return "\n".join(lines)

    def _std_note(self) -> str:
        if not self.has_standard_error:
            return (
                "the EFRLS gives no standard error: sqrt(diag P) of its RLS matrix "
                "(rls_scale) depends on P0 and the forgetting factor, not on the noise of "
                "the data; std is null"
            )
        if self.method == "ftr":
            return "std = std_cr: least-squares σ of each state equation, σ² = Σ|ε|²/(2n_f − n_p)"
        return (
            "std = std_cr: sqrt(diag P) of the filter covariance; it holds when the filter's "
            "noise model describes the data (innovation tests: status 'inconsistent' otherwise)"
        )

    def to_dict(self) -> dict:
        """One results.json entry (docs/schema/results.schema.json) with the recursive
        run under ``"recursive"`` and each parameter's ``last_filtered`` / ``last_filtered_std``."""
        meta = self.meta
        parameters = []
        for row in self._frame_rows():
            entry = {
                "name": row["name"],
                "value": row["value"],
                "initial": row["initial"],
                "std": _finite_or_none(row["std"]),
                "std_cr": _finite_or_none(row["std"]),
                "free": True,
                "unit": row["unit"],
                "last_filtered": row["last_filtered"],
                "last_filtered_std": _finite_or_none(row["last_filtered_std"]),
            }
            if not self.has_standard_error:
                entry["rls_scale"] = row["rls_scale"]
            parameters.append(entry)
        message = (
            f"{self.method}: one pass over {self.n_samples} samples; reported value = mean "
            f"over the last {self.n_report} history rows"
        )
        if self.warnings:
            message += "; WARNING: " + "; ".join(self.warnings)
        nis = self.nis[np.isfinite(self.nis)] if self.nis.size else self.nis
        return {
            "method": self.method,
            "estimator": "recursive",
            "converged": self.converged,
            # a one-pass filter does not iterate: "completed", or "inconsistent" when a health
            # check failed (docs/schema/results.schema.json)
            "status": "completed" if self.converged else "inconsistent",
            "message": message,
            "cost": None,
            "iterations": 1,
            "equivalent_evaluations": 0,
            "accuracy_evaluations": 0,
            "noise_cycles": 0,
            "noise_policy": "fixed" if self.method in ("ekf", "ukf", "ukf_aug") else "none",
            "integration": "none" if self.method == "ftr" else "rk4",
            "wall_time_s": float(self.wall_time_s),
            "R": [float(v) for v in meta.get("R0", [])],
            "outputs": list(meta.get("outputs", [])),
            "output_units": list(meta.get("output_units", [])),
            "fit_rms": [float(v) for v in meta.get("innovation_rms", [])],
            "cost_history": [],
            "evaluation_history": [],
            "parameters": parameters,
            "case": {
                "title": str(meta.get("title", "")),
                "file": str(meta.get("file", "")),
                "model": str(meta.get("model", "")),
            },
            "maneuvers": list(meta.get("maneuvers", [])),
            "prediction": [],
            "recursive": {
                "method": self.method,
                "report": self.report,
                "report_rows": self.n_report,
                "samples": int(self.n_samples),
                "history_rows": int(self.theta_history.shape[0]),
                "settings": {k: _plain(v) for k, v in self.settings.items()},
                "warnings": list(self.warnings),
                "nis_mean": float(np.mean(nis)) if nis.size else None,
                "nis_expected": (len(meta.get("outputs", [])) or None) if nis.size else None,
                "std_note": self._std_note(),
            },
        }

    def history_table(self) -> tuple[list[str], np.ndarray]:
        """(column names, rows) of the parameter histories: time_s, sample, each parameter
        and its σ, then the filtered states."""
        columns = ["time_s", "sample"]
        blocks = [self.time_s[:, None], self.samples[:, None].astype(float)]
        for j, name in enumerate(self.parameter_names):
            columns += [name, f"{name}_std"]
            blocks += [self.theta_history[:, j : j + 1], self.std_history[:, j : j + 1]]
        if self.state_history.size:
            columns += list(self.state_names)
            blocks.append(self.state_history)
        return columns, np.hstack(blocks)

    def plot(self, path: str | Path | None = None, *, dpi: int = 100, parameters=None):
        """Parameter histories with ±σ bands (one panel per parameter; ``parameters`` picks
        a subset by name); saved as PNG to ``path`` when given."""
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt

        names = list(self.parameter_names) if parameters is None else list(parameters)
        unknown = [n for n in names if n not in self.parameter_names]
        if unknown:
            raise InputError(f"parameters: {unknown} are not among {list(self.parameter_names)}")
        n_cols = 2 if len(names) > 3 else 1
        n_rows = int(np.ceil(len(names) / n_cols))
        figure, axes = plt.subplots(
            n_rows, n_cols, figsize=(4.2 * n_cols, 1.5 * n_rows + 0.6), sharex=True, squeeze=False
        )
        for ax, name in zip(axes.flat, names, strict=False):
            j = self.parameter_names.index(name)
            value, sigma = self.theta_history[:, j], self.std_history[:, j]
            ax.fill_between(self.time_s, value - sigma, value + sigma, color="C0", alpha=0.25,
                            linewidth=0)  # fmt: skip
            ax.plot(self.time_s, value, color="C0", linewidth=0.9)
            ax.axhline(self.values[j], color="C3", linewidth=0.7, linestyle="--")
            ax.set_ylabel(name, fontsize=8)
            ax.tick_params(labelsize=7)
            span = np.ptp(value[len(value) // 5 :]) + 4 * float(np.median(sigma[len(value) // 2 :]))
            centre = self.values[j]
            if np.isfinite(span) and span > 0:
                ax.set_ylim(centre - 1.5 * span, centre + 1.5 * span)
        for ax in list(axes.flat)[len(names) :]:
            ax.set_visible(False)
        for ax in axes[-1]:
            ax.set_xlabel("time (s)", fontsize=8)
        figure.suptitle(
            f"{self.method}: parameter estimates ± σ (dashed: reported value)", fontsize=9
        )
        figure.tight_layout()
        if path is not None:
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            figure.savefig(path, dpi=dpi)
        return figure


def _finite_or_none(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def _plain(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value
