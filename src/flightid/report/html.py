"""HTML report of a case run: one self-contained page an engineer can hand on.

``write_report(run, out_dir)`` writes (all at once, see ``flightid.report.folder``)

    out_dir/results.json     {"schema_version": "1", "results": [entry], "time_histories":
                             {...}} (the JSON contract, see flightid.cli.run and
                             docs/schema/results.schema.json; strict JSON, see
                             flightid.jsonout)
    out_dir/time_histories.csv  every sample: maneuver, role, time, inputs, measured,
                             predicted, residual (``flightid.report.histories``)
    out_dir/estimates.csv    name, unit, value, std (the default σ), std_cr (the Cramér–Rao
                             bound), std_kind, interval, start, free (and, with an accuracy
                             assessment, the profile and search limits)
    out_dir/figures/*.svg    per maneuver inputs, measured vs predicted outputs and residuals;
                             the same for each held-out maneuver; residual autocorrelation;
                             cost history (*.png with ``[output] figure_format = "png"``)
    out_dir/report.html      everything on one page with the figures embedded (inline SVG,
                             or base64 PNG):
                             provenance (flightid version, UTC time, case file and the SHA-256
                             of its bytes), estimates with units, CR σ beside the coloured-
                             residual σ (``flightid.report.diagnostics``) and a plain warning
                             when the CR bounds are too small, per output R, fit RMS, Theil U
                             and residual whiteness, det R, the prediction check, the cost
                             history with the R re-estimations, the correlation matrix, and
                             the accuracy assessment when the run has one

Intervals: θ̂_j ± k·z_{(1+c)/2}·σ_j with σ_j the estimate's default σ (the Cramér–Rao bound
for white residuals, the coloured-residual σ otherwise: ``Estimate.std_kind``), c the
confidence level and k the ``bound_factor`` of the case (1 by default). The report only reads
results.
"""

from __future__ import annotations

import csv
import html
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from flightid.numbers import format_at_sigma, format_sigma
from flightid.report.diagnostics import COLOURED_RATIO_WARNING
from flightid.report.page import STYLE as _STYLE
from flightid.report.page import correlation_section, files_section
from flightid.report.page import image as _img
from flightid.report.page import table as _table

__all__ = ["write_report", "write_files", "interval_half_widths"]


def interval_half_widths(std: np.ndarray, confidence: float, bound_factor: float) -> np.ndarray:
    """k·z·σ: half widths of the individual intervals (normal quantile z at (1+c)/2)."""
    from scipy.special import ndtri

    # z = Φ⁻¹((1 + c)/2), the standard normal quantile (what scipy.stats.norm.ppf evaluates)
    z = float(ndtri(0.5 * (1.0 + confidence)))
    return bound_factor * z * np.asarray(std, dtype=float)


# ------------------------------------------------------------------------------ figures


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name) or "maneuver"


def channel_units(run) -> dict[str, str]:
    """{channel: unit} of the run: the data's channel units (``FlightData.units``, set by the
    loaders from each channel's ``unit`` / ``to``), the estimate's ``output_units`` where the
    data has none."""
    units: dict[str, str] = {}
    est = run.estimate
    for name, unit in zip(est.output_names, getattr(est, "output_units", ()) or (), strict=False):
        if unit:
            units[name] = unit
    for maneuver in run.maneuvers:
        units.update({k: v for k, v in maneuver.units.items() if v})
    return units


@dataclass
class Figures:
    """Rendered report figures: (file name, SVG text as UTF-8 or PNG bytes) per kind."""

    fits: list[tuple[str, bytes]] = field(default_factory=list)
    prediction: list[tuple[str, bytes]] = field(default_factory=list)
    autocorrelation: tuple[str, bytes] | None = None
    convergence: tuple[str, bytes] | None = None

    def all(self) -> list[tuple[str, bytes]]:
        extra = [f for f in (self.autocorrelation, self.convergence) if f is not None]
        return [*self.fits, *self.prediction, *extra]


FIGURE_FORMATS = ("svg", "png")


def run_figure_format(run) -> str:
    """The run's figure format: ``[output] figure_format`` ("svg" by default)."""
    return str(run.case.output.get("figure_format", "svg"))


def _figure_specs(run) -> tuple[list[str], list[tuple[str, tuple, dict, float]]]:
    """The report's figures as (figure function, arguments, options, weight) and their file
    names without extension: per maneuver and per held-out maneuver its time histories
    with the inputs, then the residual autocorrelation and the cost history. The functions
    are ``flightid.report.figures``' (PNG) and, by the same names,
    ``flightid.report.svg_figures.SVG_FUNCTIONS``' (SVG)."""
    est = run.estimate
    names = list(est.output_names)
    units = channel_units(run)
    steps = getattr(est, "input_interpolation", "linear") == "zoh"
    files: list[str] = []
    specs: list[tuple[str, tuple, dict, float]] = []

    def maneuver_spec(time, inputs, input_names, measured, predicted, outputs, units_, title):
        arguments = (time, inputs, input_names, measured, predicted, outputs, units_, title)
        # drawing time grows with the panels: inputs + 2 per output
        weight = len(input_names) + 2 * len(outputs)
        return ("maneuver_figure", arguments, {"input_steps": steps}, weight)

    for k, maneuver in enumerate(run.maneuvers):
        rows = est.maneuver_index == k
        files.append(f"fit_{k + 1}_{_safe(maneuver.name)}")
        specs.append(
            maneuver_spec(
                est.time[rows],
                maneuver.inputs if maneuver.input_names else None,
                list(maneuver.input_names),
                est.measured[rows],
                est.predicted[rows],
                names,
                units,
                f"maneuver {maneuver.name} (estimation)",
            )
        )
    for p in run.predictions:
        files.append(f"prediction_{_safe(p.name)}")
        specs.append(
            maneuver_spec(
                p.time,
                getattr(p, "inputs", None),
                list(getattr(p, "input_names", ())),
                p.measured,
                p.predicted,
                list(p.output_names),
                {**units, **getattr(p, "units", {})},
                f"maneuver {p.name} (held out: prediction check)",
            )
        )
    coloured = _coloured(run)
    rho, band = _autocorrelation(run, coloured.lag)
    files.append("autocorrelation")
    arguments = (rho, band, run.maneuvers[0].dt, names, coloured.lag)
    specs.append(("autocorrelation_figure", arguments, {}, len(names)))
    files.append("convergence")
    arguments = (
        est.cost_history,
        tuple(getattr(est, "noise_update_passes", ())),
        f"convergence ({est.solver}, noise {est.noise_policy})",
    )
    options = {"log_det_r": getattr(est, "log_det_r_history", ())}
    specs.append(("cost_history_figure", arguments, options, 2.0))
    return files, specs


def figure_jobs(run, dpi: int = 96) -> tuple[list[str], list]:
    """The report's figures as PNG jobs (``flightid.report.drawing``) and their file
    names (``_figure_specs``)."""
    from flightid.report.drawing import FigureJob

    files, specs = _figure_specs(run)
    jobs = []
    for function, arguments, options, weight in specs:
        if function == "maneuver_figure":
            # the time histories are drawn through their envelope per pixel column at this dpi
            options = {**options, "dpi": dpi}
        jobs.append(FigureJob(function, arguments, options, dpi, weight))
    return [f"{name}.png" for name in files], jobs


def render_figures(run, dpi: int = 96, pool=None, figure_format: str | None = None) -> Figures:
    """The report's figures (time histories with inputs per maneuver and per held-out
    maneuver, residual autocorrelation, cost history), each drawn once: as SVG text
    written from the arrays here (``flightid.report.svg_figures``, no matplotlib), or as PNG
    bytes drawn by matplotlib in the worker processes of ``pool``, else of the active
    ``flightid.report.drawing.FigurePool``, else here. ``figure_format``: "svg" or "png";
    None: the run's ``[output] figure_format`` ("svg" by default)."""
    figure_format = figure_format or run_figure_format(run)
    if figure_format not in FIGURE_FORMATS:
        raise ValueError(f"figure_format: expected one of {FIGURE_FORMATS}, got {figure_format!r}")
    if figure_format == "svg":
        from flightid.report.svg_figures import SVG_FUNCTIONS

        files, specs = _figure_specs(run)
        drawn = [
            (f"{name}.svg", SVG_FUNCTIONS[function](*arguments, **options).encode("utf-8"))
            for name, (function, arguments, options, _) in zip(files, specs, strict=True)
        ]
    else:
        from flightid.report.drawing import draw

        files, jobs = figure_jobs(run, dpi)
        drawn = list(zip(files, draw(jobs, pool), strict=True))
    n_fits, n_predictions = len(run.maneuvers), len(run.predictions)
    return Figures(
        fits=drawn[:n_fits],
        prediction=drawn[n_fits : n_fits + n_predictions],
        autocorrelation=drawn[-2],
        convergence=drawn[-1],
    )


def _autocorrelation(run, lag_used: int) -> tuple[np.ndarray, float]:
    """ρ(k) per output up to the shown lag (a quarter of the shortest maneuver, at most 100
    samples, and past the coloured-residual correction's lag L when that is longer)."""
    from flightid.report.diagnostics import autocorrelation_lags, residual_autocorrelation

    est = run.estimate
    shortest = min(int(np.sum(est.maneuver_index == k)) for k in range(len(run.maneuvers)))
    lags = autocorrelation_lags(est.time.shape[0], shortest)
    lags = max(lags, min(lag_used + lag_used // 4 + 1, shortest - 1))
    return residual_autocorrelation(est.residuals, lags, est.maneuver_index)


# (estimate, accuracy, ColouredSigma) of the last _coloured call: the figures and the page
# of one report ask for the same run's corrected σ
_LAST_COLOURED: list[tuple] = []


def _coloured(run):
    from flightid.report.diagnostics import coloured_sigma

    estimate, accuracy = run.estimate, getattr(run, "accuracy", None)
    for kept_estimate, kept_accuracy, result in _LAST_COLOURED:
        if kept_estimate is estimate and kept_accuracy is accuracy:
            return result
    result = coloured_sigma(estimate, accuracy)
    _LAST_COLOURED[:] = [(estimate, accuracy, result)]
    return result


# ------------------------------------------------------------------------------ tables


# the estimates table's last column, by ``Estimate.role``
_ROLE_TEXT = {
    "free": "free",
    "fixed": "fixed",
    "solved": "solved (constraint)",
    "at_bound": "on a bound",
}


def _role(est, name: str) -> str:
    """``Estimate.role`` (free, fixed, solved, at_bound) for any estimate-like result."""
    if name in getattr(est, "solved", ()):
        return "solved"
    if name in getattr(est, "at_bound", ()):
        return "at_bound"
    return "free" if est.free[list(est.names).index(name)] else "fixed"


def _estimate_rows(run) -> list[dict]:
    est = run.estimate
    confidence = float(run.case.accuracy.get("confidence", 0.95))
    factor = float(run.case.accuracy.get("bound_factor", 1.0))
    half = interval_half_widths(np.where(est.free, est.std, 0.0), confidence, factor)
    units = tuple(getattr(est, "parameter_units", ()) or ("",) * len(est.names))
    rows = []
    for i, name in enumerate(est.names):
        free = bool(est.free[i])
        value, std = float(est.values[i]), float(est.std[i])
        rows.append(
            {
                "name": name,
                "unit": units[i],
                "value": value,
                "std": std if free else None,
                "std_cr": float(est.std_cr[i]) if free else None,
                "std_kind": est.std_kind if free else None,
                "relative_percent": 100 * std / abs(value) if free and value != 0 else None,
                "lower": value - half[i] if free else None,
                "upper": value + half[i] if free else None,
                "initial": float(est.initial[i]),
                "free": free,
                # free | fixed | solved (from a constraint) | at_bound
                "role": _role(est, name),
            }
        )
    accuracy = getattr(run, "accuracy", None)
    if accuracy is not None:
        # the likelihood-region limits of the assessment, where they were run
        free_rows = [row for row in rows if row["free"]]
        for label, intervals in (("profile", accuracy.ci_profile), ("search", accuracy.ci_search)):
            for row in rows:
                row[f"{label}_lower"] = row[f"{label}_upper"] = None
            if intervals is None:
                continue
            for row, (lower, upper) in zip(free_rows, intervals, strict=True):
                row[f"{label}_lower"] = float(lower) if np.isfinite(lower) else None
                row[f"{label}_upper"] = float(upper) if np.isfinite(upper) else None
    return rows


def write_csv(run, path: Path) -> None:
    rows = _estimate_rows(run)
    with path.open("w", newline="", encoding="utf-8") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
        writer.writeheader()
        for row in rows:
            writer.writerow({k: ("" if v is None else v) for k, v in row.items()})


def _fmt(value, digits: int = 6) -> str:
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(value)
    if not np.isfinite(value):
        return str(value)
    return f"{value:.{digits}g}"


def _at_sigma(value, sigma) -> str:
    """A value at the decimal place of σ's second significant digit (``flightid.numbers``);
    ``_fmt`` when there is no value or no σ."""
    if value is None or sigma is None:
        return _fmt(value)
    return format_at_sigma(value, sigma)


def _unit(unit: str | None) -> str:
    return html.escape(unit) if unit else "—"


def _provenance(run, generated_utc: str) -> list[list[str]]:
    from flightid._version import __version__

    case = run.case
    digest = getattr(run, "case_sha256", "") or "— (the case was not read from a file)"
    return [
        ["produced by", f"flightid {html.escape(__version__)}"],
        ["generated (UTC)", html.escape(generated_utc)],
        ["case file", f"<code>{html.escape(str(case.path))}</code>"],
        ["case file SHA-256", f"<code>{html.escape(digest)}</code>"],
        ["data directory", f"<code>{html.escape(str(run.data_dir))}</code>"],
        ["model", html.escape(run.model_description)],
    ]


def _run_facts(run) -> list[list[str]]:
    est = run.estimate
    optimality = est.optimality_sigma
    return [
        [
            "maneuvers (estimation)",
            html.escape(
                ", ".join(f"{m.name} ({m.n_samples} samples × {m.dt:g} s)" for m in run.maneuvers)
            ),
        ],
        [
            "maneuvers (held out)",
            html.escape(", ".join(p.name for p in run.predictions) or "none"),
        ],
        [
            "solver / noise policy / integration",
            f"{est.solver} / {est.noise_policy} / {est.method}",
        ],
        ["input interpolation", html.escape(getattr(est, "input_interpolation", "linear"))],
        ["cost J = Σ νᵀR⁻¹ν [–]", _fmt(est.cost)],
        ["passes / R re-estimations", f"{est.iterations} / {est.noise_cycles}"],
        [
            "equivalent evaluations",
            html.escape(
                est.evaluations_text()
                if hasattr(est, "evaluations_text")
                else f"{est.equivalent_evaluations} (+{est.accuracy_evaluations} for the "
                "information matrix)"
            ),
        ],
        [
            "optimality (next Gauss–Newton step) [σ]",
            (_fmt(optimality, 3) if np.isfinite(optimality) else "—")
            + " <span class='small'>(√(ΔθᵀMΔθ) at θ̂; small means at the optimum)</span>",
        ],
        [
            "parameters on a bound",
            html.escape(", ".join(est.at_bound)) if est.at_bound else "none",
        ],
        ["wall time [s]", f"{est.wall_time_s:.2f}"],
    ]


def _coloured_warning(coloured) -> str:
    """The plain-words warning (or note) about coloured residuals."""
    worst = coloured.worst
    if coloured.lag == 0 or worst is None:
        return (
            "<p class='ok'>The residuals are white within the ±1.96/√N band: the Cramér–Rao "
            "σ and the coloured-residual σ agree.</p>"
        )
    name, ratio = worst
    if coloured.understated:
        return (
            "<div class='warning'><b>Warning: coloured residuals.</b> The residuals are "
            f"autocorrelated (correlation outside the white-noise band up to lag "
            f"{coloured.lag} samples), and the Cramér–Rao bounds understate the uncertainty "
            f"by up to ×{ratio:.2g} (parameter <code>{html.escape(name)}</code>). "
            "The σ reported by default (column “coloured σ (default)”, <code>std</code> in "
            "results.json and estimates.csv, the terminal) is the corrected one; the "
            "Cramér–Rao σ is kept as <code>std_cr</code>.</div>"
        )
    return (
        f"<div class='note'>The residuals are coloured (lag {coloured.lag} samples), but the "
        f"corrected σ is at most ×{ratio:.2g} the Cramér–Rao σ (parameter "
        f"<code>{html.escape(name)}</code>).</div>"
    )


def _estimates_table(run, coloured, units: tuple[str, ...]) -> str:
    est = run.estimate
    confidence = float(run.case.accuracy.get("confidence", 0.95))
    factor = float(run.case.accuracy.get("bound_factor", 1.0))
    free_index = {n: j for j, n in enumerate(coloured.names)}
    scaled = abs(coloured.s2 - 1.0) > 0.05
    rows, classes = [], []
    for row, unit in zip(_estimate_rows(run), units, strict=True):
        j = free_index.get(row["name"])
        std_cr = coloured.std_cr[j] if j is not None else None
        std_col = coloured.std_coloured[j] if j is not None else None
        ratio = coloured.ratio[j] if j is not None else None
        high = ratio is not None and np.isfinite(ratio) and ratio > COLOURED_RATIO_WARNING
        ratio_text = _fmt(ratio, 3) if ratio is not None and np.isfinite(ratio) else "—"
        # σ to two significant digits; estimate and interval at the default σ's decimal place
        place = row["std"]
        cells = [
            html.escape(row["name"]),
            _unit(unit),
            _at_sigma(row["value"], place),
            format_sigma(row["std_cr"]),
        ]
        if scaled:
            cells.append(format_sigma(std_cr))
        cells += [
            format_sigma(std_col) if std_col is not None and np.isfinite(std_col) else "—",
            f"<span class='high'>{ratio_text}</span>" if high else ratio_text,
            _fmt(row["relative_percent"], 2),
            _at_sigma(row["lower"], place),
            _at_sigma(row["upper"], place),
            _fmt(row["initial"]),
            _ROLE_TEXT[row["role"]],
        ]
        rows.append(cells)
        classes.append("" if row["free"] else "fixed")
    interval = f"{100 * confidence:g} % interval (σ default)" + (
        f" (×{factor:g})" if factor != 1 else ""
    )
    # the column of the σ the other outputs (terminal, results.json, estimates.csv) report
    coloured_default = est.std_kind == "coloured"
    headers = ["parameter", "unit", "estimate", "CR σ" if coloured_default else "CR σ (default)"]
    if scaled:
        headers.append("s·σ (CR)")
    headers += [
        "coloured σ (default)" if coloured_default else "coloured σ",
        "coloured / CR",
        "σ/|θ| %",
        f"{interval} low",
        "high",
        "start",
        "",
    ]
    note = (
        "<p class='small'>Estimate, σ, intervals and start in the parameter's unit. "
        "(default): the σ reported as <code>std</code> in results.json, estimates.csv and "
        "the terminal, and the one the intervals use — the coloured σ when the residuals are "
        "coloured, the CR σ when they are white. CR σ: "
        "Cramér–Rao bound √((M⁻¹)ⱼⱼ) (<code>std_cr</code>). Coloured σ: the sandwich covariance "
        "M⁻¹[ΣᵢΣⱼ GᵢᵀR⁻¹R̂ν(i−j)R⁻¹Gⱼ]M⁻¹ with the residual autocorrelation up to lag "
        f"L = {coloured.lag} (<code>flightid.accuracy.coloured_covariance</code>), compared "
        f"with s·σ (s² = J/(N·n_o − n_p) = {coloured.s2:.4g}).</p>"
    )
    del est
    return _table(headers, rows, classes) + note


def _squared(unit: str) -> str:
    """``rad`` → ``rad²``, ``rad/s`` → ``(rad/s)²``."""
    return f"({unit})²" if any(c in unit for c in "/ ·*^") else f"{unit}²"


def _outputs_table(run, units: dict[str, str], rho_band) -> str:
    from flightid.accuracy.whiteness import WhitenessError, estimate_whiteness
    from flightid.report.diagnostics import log_det_r, theil_u

    est = run.estimate
    rho, band = rho_band
    u = theil_u(est.measured, est.predicted)
    try:
        # Ljung–Box test per output, as in results.json (flightid.accuracy.whiteness)
        whiteness = estimate_whiteness(est)
    except WhitenessError:
        whiteness = None
    rows = []
    for j, name in enumerate(est.output_names):
        unit = units.get(name)
        outside = int(np.sum(np.abs(rho[1:, j]) > band))
        if whiteness is None:
            test = "—"
        else:
            verdict = "white" if whiteness.white[j] else "<span class='bad'>coloured</span>"
            test = (
                f"{_fmt(float(whiteness.ljung_box[j]), 4)} (p = "
                f"{_fmt(float(whiteness.p_value[j]), 2)}, {verdict})"
            )
        rows.append(
            [
                html.escape(name),
                _unit(unit),
                _fmt(est.r_diag[j], 4),
                _fmt(est.fit_error()[j], 4),
                _fmt(u[j], 3),
                _fmt(float(rho[1, j]) if rho.shape[0] > 1 else None, 3),
                f"{outside} of {rho.shape[0] - 1}",
                test,
            ]
        )
    lb_lags = "m" if whiteness is None else str(whiteness.ljung_box_lags)
    det, log_det = log_det_r(est.r_diag)
    squared = " · ".join(_squared(units.get(n) or "?") for n in est.output_names)
    return (
        _table(
            [
                "output",
                "unit",
                "R (variance) [unit²]",
                "fit RMS [unit]",
                "Theil U [–]",
                "ρ(1) [–]",
                f"lags outside ±1.96/√N = ±{band:.3g}",
                f"Ljung–Box Q({lb_lags}) [–]",
            ],
            rows,
        )
        + _table(
            ["noise covariance", "value"],
            [
                ["det R", f"{_fmt(det, 6)} [{html.escape(squared)}]"],
                ["ln det R", _fmt(log_det, 8)],
            ],
            table_class="facts",
        )
        + "<p class='small'>Theil inequality coefficient U = √(Σν²/N) / (√(Σz²/N) + "
        "√(Σy²/N)): 0 is a perfect fit, below about 0.3 is usually taken as good "
        "agreement. ρ(k): normalised residual autocorrelation. Ljung–Box "
        "Q = N(N+2) Σ_{k=1..m} ρ(k)²/(N − M k), χ²(m) for white residuals (M maneuvers); "
        "“coloured” when p < 0.05 (<code>flightid.accuracy.whiteness</code>).</p>"
    )


def _prediction_section(run, units: dict[str, str], figures) -> str:
    from flightid.report.diagnostics import theil_u

    parts = [
        "<h2>Prediction check on held-out maneuvers</h2>",
        "<p>The estimated model, simulated on maneuvers not used for the estimation.</p>",
    ]
    for k, p in enumerate(run.predictions):
        u = theil_u(p.measured, p.predicted)
        rows = [
            [html.escape(n), _unit(units.get(n)), _fmt(e, 4), _fmt(r, 4), _fmt(t, 3)]
            for n, e, r, t in zip(p.output_names, p.rms, p.r2, u, strict=True)
        ]
        parts.append(
            f"<h3>{html.escape(p.name)} ({p.time.shape[0]} samples)</h3>"
            + _table(["output", "unit", "RMS error [unit]", "R² [–]", "Theil U [–]"], rows)
        )
        if k < len(figures.prediction):
            parts.append(
                _img(figures.prediction[k], f"held-out maneuver {p.name}: inputs, responses")
            )
    return "\n".join(parts)


def _convergence_section(run, figures) -> str:
    """Per pass: equivalent evaluations, ln det R̂ of its residuals, the cost at the R in
    force, and where R was re-estimated (figure and table)."""
    est = run.estimate
    updates = list(getattr(est, "noise_update_passes", ()))
    evaluations = list(est.evaluation_history)
    log_det = list(getattr(est, "log_det_r_history", ()))
    with_log_det = len(log_det) == len(est.cost_history) and any(np.isfinite(log_det))
    rows = []
    for i, cost in enumerate(est.cost_history):
        mark = "R re-estimated before this pass" if i in updates else ""
        evaluation = str(evaluations[i]) if i < len(evaluations) else "—"
        ln_det = [_fmt(log_det[i], 8) if np.isfinite(log_det[i]) else "—"] if with_log_det else []
        rows.append([str(i), evaluation, *ln_det, _fmt(cost), mark])
    tail = [u for u in updates if u >= len(est.cost_history)]
    estimated_r = est.noise_policy != "fixed"
    caption = (
        "ln det R̂ per pass (top) and cost J at fixed R (bottom); dashed: R re-estimated"
        if with_log_det
        else "cost J per pass; dashed: R re-estimated"
    )
    explanation = (
        " ln det R̂ is that of each pass's residuals: the likelihood's measure when R is "
        "estimated, comparable across R updates; it settles at its minimum, "
        f"ln det R = {_fmt(float(np.sum(np.log(est.r_diag))), 8)} of the final R. The cost at "
        "fixed R falls within each stretch under one R and jumps when R is re-estimated "
        "(under R = R̂ it is about N·n_o), so its jumps are not divergence."
        if with_log_det and estimated_r
        else ""
    )
    text = [
        "<h2>Convergence</h2>",
        _img(figures.convergence, caption, "640px") if figures else "",
        f"<p>{est.noise_cycles} R re-estimation(s) (noise policy {html.escape(est.noise_policy)})"
        + (
            "; the last one changed R by less than the tolerance and no pass followed it"
            if tail
            else ""
        )
        + ". Costs are computed under the R in force at that pass."
        + explanation
        + "</p>",
        _table(
            [
                "pass",
                "equivalent evaluations",
                *(["ln det R̂ [–]"] if with_log_det else []),
                "cost J at fixed R [–]",
                "",
            ],
            rows,
        ),
    ]
    return "\n".join(text)


def _modes_section(run) -> str:
    """The modes of the estimated model with σ at the first maneuver's operating point, and
    (with the case's ``[flying_qualities]``) the level each MIL-F-8785C criterion meets at
    95 % (``flightid.export``)."""
    from flightid.export.modal import MODE_HEADERS, mode_rows

    modal = getattr(run, "modal_analysis", None)
    try:
        analysis = modal() if modal is not None else None
    except (ValueError, TypeError, ArithmeticError) as error:
        return f"<h2>Modes</h2><p class='bad'>not computed: {html.escape(str(error))}</p>"
    if analysis is None:
        return ""
    quality = analysis.flying_qualities
    title = "Modes and flying qualities" if quality is not None else "Modes"
    parts = [
        f"<h2>{title}</h2>",
        f"<p>At {html.escape(analysis.linear.operating_point)}; ± 1σ (delta method from the "
        "parameter covariance).</p>",
        _table(MODE_HEADERS, [[html.escape(c) for c in r] for r in mode_rows(analysis.modes)]),
    ]
    parts += [f"<p>{html.escape(n)}</p>" for n in analysis.modes.notes]
    if quality is not None:
        parts.append(
            f"<p>MIL-F-8785C, Class {html.escape(quality.airplane_class)}, Category "
            f"{html.escape(quality.category)}: the level each criterion meets at 95 % "
            "confidence (value ∓ 1.645σ inside the level's limits); limits marked "
            "unverified take no part in the verdict.</p>"
        )
        headers = ["criterion", "value ± σ", "Level 1", "Level 2", "Level 3", "level", "source"]
        parts.append(_table(headers, [[html.escape(c) for c in r] for r in quality.rows()]))
        notes = [r for r in quality.criteria if r.note]
        parts += [f"<p>{html.escape(r.label)}: {html.escape(r.note)}</p>" for r in notes]
        parts += [
            f"<p>{html.escape(n)}</p>" for n in quality.notes if n not in analysis.modes.notes
        ]
    return "\n".join(parts)


def _correlation_section(run) -> str:
    """The correlation matrix of the free estimates, as every report draws it
    (``flightid.report.page.correlation_section``)."""
    est = run.estimate
    threshold = float(run.case.accuracy.get("correlation_warning", 0.9))
    corr = np.asarray(est.correlation, dtype=float)
    if corr.size <= 1:
        return ""
    return "<h2>Correlation matrix [–]</h2>\n" + correlation_section(
        est.free_names, corr, threshold
    )


def render_html(
    run,
    figures: Figures | None,
    generated_utc: str | None = None,
    directory: Path | None = None,
) -> str:
    """The whole report page as one self-contained HTML string (figures embedded); with
    ``directory``, the result folder, a list of links to its files."""

    est = run.estimate
    case = run.case
    generated_utc = generated_utc or _utc_now()
    units = channel_units(run)
    parameter_units = tuple(
        getattr(est, "parameter_units", None)
        or (getattr(est.model.parameters[n], "unit", "") for n in est.names)
    )
    coloured = _coloured(run)
    rho_band = _autocorrelation(run, coloured.lag)
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        "<meta name='viewport' content='width=device-width, initial-scale=1'>",
        "<meta name='generator' content='flightid'>",
        f"<title>{html.escape(case.title)}</title><style>{_STYLE}</style></head><body>",
        f"<h1>{html.escape(case.title)}</h1>",
    ]
    if case.description:
        parts.append(f"<p>{html.escape(case.description)}</p>")
    parts.append(_table(["", ""], _provenance(run, generated_utc), table_class="facts"))
    status_class = "ok" if est.converged else "bad"
    message = est.message
    if message.startswith(est.status + ":"):
        message = message[len(est.status) + 1 :].strip()
    parts.append(
        f"<p class='{status_class}'><b>{html.escape(est.status)}</b>: {html.escape(message)}</p>"
    )
    parts.append(_coloured_warning(coloured))
    parts.append("<h2>Run</h2>" + _table(["item", "value"], _run_facts(run), table_class="facts"))
    # the section order of every flightid report (flightid.report.page): estimates,
    # correlation, residual analysis, fits, then what only this estimator has
    parts.append("<h2>Estimates</h2>" + _estimates_table(run, coloured, parameter_units))
    if getattr(run, "accuracy", None) is not None:
        parts.append(_accuracy_section(run))
    parts.append(_correlation_section(run))
    parts.append(
        "<h2>Residual analysis: noise, fit, whiteness</h2>" + _outputs_table(run, units, rho_band)
    )
    if figures is not None:
        parts.append(_img(figures.autocorrelation, "residual autocorrelation per output"))
    parts.append("<h2>Fit: inputs, measured and predicted outputs, residuals</h2>")
    if figures is None:
        parts.append("<p>Figures were switched off (<code>[output] figures = false</code>).</p>")
    else:
        parts.extend(
            _img(f, f"maneuver {m.name}: inputs, responses, residuals")
            for f, m in zip(figures.fits, run.maneuvers, strict=True)
        )
    if run.predictions:
        parts.append(_prediction_section(run, units, figures or Figures()))
    parts.append(_convergence_section(run, figures))
    parts.append(_modes_section(run))
    parts.append(_trust_section(run))
    if directory is not None:
        parts.append("<h2>Files</h2>" + files_section(directory))
    parts.append("</body></html>")
    return "\n".join(p for p in parts if p)


def _utc_now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S UTC")


def _interval(pair, sigma: float | None = None) -> str:
    """ "[lower, upper]", both at the decimal place of σ's second significant digit
    (``flightid.numbers``; six significant digits without a σ); an open side (no limit
    found) shows as ∓∞, an unknown one as —."""
    lower, upper = (float(v) for v in pair)

    def bound(v: float) -> str:
        return _fmt(v) if sigma is None else format_at_sigma(v, sigma)

    low = "−∞" if lower == -np.inf else bound(lower) if np.isfinite(lower) else "—"
    high = "+∞" if upper == np.inf else bound(upper) if np.isfinite(upper) else "—"
    return f"[{low}, {high}]"


def _accuracy_section(run) -> str:
    """Estimate, CR, profile and search intervals of every free parameter, with N_φ."""
    acc = run.accuracy
    ran = [m for m in ("profile", "search") if getattr(acc, m) is not None]
    headers = ["parameter", "estimate", "s·σ", "CR interval"]
    headers += [f"{m} interval" for m in ran]
    rows = []
    for j, name in enumerate(acc.names):
        sigma = float(acc.std_scaled[j])
        row = [html.escape(name), format_at_sigma(acc.center[j], sigma), format_sigma(sigma)]
        row.append(_interval(acc.ci_cr[j], sigma))
        row += [_interval(getattr(acc, f"ci_{m}")[j], sigma) for m in ran]
        rows.append(row)
    n_phi = acc.nonlinearity.n_phi
    spent = ", ".join(f"{k} {v}" for k, v in acc.evaluations.items())
    facts = [
        ["confidence level", f"{acc.level:g} ({acc.kind}, {acc.distribution} quantiles)"],
        ["methods", ", ".join(["Cramér–Rao", *ran])],
        ["Beale's nonlinearity N_φ", _fmt(n_phi, 3)],
        ["Beale factor on the contour level", _fmt(acc.nonlinearity.beale_factor, 6)],
        ["s², contour level Δ", f"{_fmt(acc.s2, 4)}, {_fmt(acc.delta, 4)}"],
        ["evaluations", html.escape(spent)],
    ]
    if acc.search is not None:
        settled = int(acc.search.settled.sum())
        facts.append(
            [
                "search",
                f"seed {acc.search.seed}, {settled} of {acc.search.settled.size} extremes settled",
            ]
        )
    text = [
        "<h2>Accuracy</h2>",
        "<p>Cramér–Rao intervals project the information-matrix ellipsoid; profile and search "
        "limits are the extremes of each parameter on the likelihood contour "
        "J(θ) − J(θ̂) = Δ (flightid.accuracy). Search limits are inner bounds.</p>",
        _table(["item", "value"], facts),
        _table(headers, rows),
    ]
    if acc.warnings:
        items = "".join(f"<li>{html.escape(w)}</li>" for w in acc.warnings)
        text.append(f"<ul class='bad'>{items}</ul>")
    return "\n".join(text)


def _trust_section(run) -> str:
    """Outliers in the residuals and parameter combinations the data barely determine
    (``flightid.accuracy.outliers`` / ``.identifiability``); empty when neither has findings."""
    screen = getattr(run, "outliers", None)
    weak = getattr(run, "identifiability", None)
    has_outliers = screen is not None and bool(screen.outliers)
    has_weak = weak is not None and bool(weak.combinations)
    if not (has_outliers or has_weak):
        return ""
    text = ["<h2>Where the σ cannot be trusted</h2>"]
    if has_outliers:
        rows = [
            [
                html.escape(o.maneuver_name or str(o.maneuver)),
                str(o.sample),
                _fmt(o.time_s, 6),
                html.escape(o.output),
                _fmt(o.residual, 4),
                _fmt(o.size_sigma, 4),
            ]
            for o in screen.outliers
        ]
        text.append(
            f"<p class='bad'>{html.escape(screen.messages()[-1])}</p>"
            + _table(["maneuver", "sample", "time [s]", "output", "residual", "size [σ]"], rows)
        )
    if has_weak:
        items = "".join(f"<li>{html.escape(c.describe())}</li>" for c in weak.combinations)
        text.append(f"<ul class='bad'>{items}</ul>")
    if has_weak and weak.profiled:
        rows = [
            [
                html.escape(p.name),
                format_at_sigma(p.value, p.std_cr),
                format_sigma(p.std_cr),
                format_sigma(p.std_coloured),
                _interval(p.ci_cr, p.std_cr),
                _interval(p.ci_profile, p.std_cr),
                format_sigma(p.std_profile),
                "fails" if p.quadratic_fails else "holds",
            ]
            for p in weak.profiled
        ]
        headers = ["parameter", "estimate", "CR σ", "coloured σ", "CR interval"]
        headers += ["profile interval", "profile as σ", "quadratic approximation"]
        text.append(
            f"<p>Profile-likelihood intervals at {weak.level:g} beside the quadratic ones "
            f"(Beale's N_φ = {_fmt(weak.n_phi, 3)}).</p>" + _table(headers, rows)
        )
    return "\n".join(text)


def write_files(run, directory: Path) -> Path:
    """Write results.json, estimates.csv, figures and report.html (and, for a kinematic
    model, reconstructed_<maneuver>.csv: ``flightid.compat.reconstruct``) into ``directory``
    (which exists); returns the HTML path. ``write_report`` calls this on a temporary folder.

    results.json is strict JSON (``flightid.jsonout``: NaN / ±inf become null, listed
    under ``"nonfinite"``). The figures are written to ``figures/`` and embedded in
    report.html, so the page stands alone: SVG written here from the arrays (``[output]
    figure_format = "svg"``, the default; inline ``<svg>`` elements in the page), or PNG
    drawn by matplotlib (``"png"``: base64 images; drawn by the active
    ``flightid.report.drawing.FigurePool`` if there is one, else here). ``[output] figures =
    false`` skips the figures (folder and page), ``report = false`` the HTML page.
    """
    from flightid.report.histories import write_results_and_histories

    directory = Path(directory)
    # results.json (versioned: docs/schema/results.schema.json) and time_histories.csv
    write_results_and_histories(run, directory)
    write_csv(run, directory / "estimates.csv")
    # a kinematic (flight-path reconstruction) run adds reconstructed_<maneuver>.csv
    from flightid.compat.reconstruct import write_reconstruction

    write_reconstruction(run, directory)
    figures = None
    if run.case.output.get("figures", True):
        figures = render_figures(run)
    if figures is not None:
        (directory / "figures").mkdir(parents=True, exist_ok=True)
        for name, data in figures.all():
            (directory / "figures" / name).write_bytes(data)
    path = directory / "report.html"
    if run.case.output.get("report", True):
        path.write_text(render_html(run, figures, directory=directory), encoding="utf-8")
    return path


def write_report(run, out_dir: Path, *, overwrite: bool = False) -> Path:
    """Write the run's result folder ``out_dir`` safely; returns the HTML path there.

    The folder is checked and locked, the files are written to a temporary folder beside it
    and moved into place at once (``flightid.report.folder``); a folder that already holds
    a run is replaced (whole) only with ``overwrite=True``.

    Raises:
        OutputError: the folder cannot be used or written (nothing half written remains).
    """
    from flightid.report.folder import ResultFolder

    with ResultFolder.open(out_dir, overwrite=overwrite, label="out_dir") as folder:
        path = folder.write(lambda directory: write_files(run, directory))
        return folder.target / path.name
