"""The report of a global model (``flightid.globalmodel.GlobalModel``): its files and its
section of the stages' page.

Files beside results.json:

    global_model.json        the whole model (reloadable: ``flightid.globalmodel.
                             load_global_model``; it predicts without the data)
    global_model_terms.csv   coefficient, parameter, term, unit, value, std (the default σ:
                             coloured-residual where the residuals are coloured), std_cr
    figures/carpet_<C>.svg   per coefficient a carpet plot (``carpet_svg``)

The carpet plot shows the coefficient against the first variable, one curve for each of a
few values of the second variable spread over its data range, the other variables held at
0 where 0 lies in their data range, else at its middle. Around each curve two bands are
shaded: darker the function interval (the coefficient itself, with the model error: what a
simulator needs), lighter around it the prediction interval (a new measurement, with its
noise besides). Where a point lies outside the data's support (``Prediction.outside``) the
curve is dashed and the bands are left out: there the model is an extrapolation, and the
intervals do not hold.
"""

from __future__ import annotations

import csv
import html
from pathlib import Path

import numpy as np

from flightid.report import svg_axes as ax
from flightid.report.page import (
    EstimateRow,
    correlation_from_covariance,
    correlation_section,
    image,
    table,
)
from flightid.report.svg_axes import Panel, PanelText, axis_label

__all__ = [
    "carpet_svg",
    "global_model_correlations",
    "global_model_rows",
    "global_model_sections",
    "write_global_model_files",
]

MODEL_FILE = "global_model.json"
TERMS_FILE = "global_model_terms.csv"
# one colour per curve of a carpet
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b")
BAND_OPACITY = 0.15
# the function interval, drawn over the prediction interval's band
FUNCTION_BAND_OPACITY = 0.3


def _held_value(low: float, high: float) -> float:
    """0 where it lies in [low, high], else the middle of the range."""
    return 0.0 if low <= 0.0 <= high else 0.5 * (low + high)


def carpet_points(model, x: str, by: str | None, n_by: int = 4, n_x: int = 61):
    """The carpet's grid: (x values, by values (or [None]), points per curve, held values).
    x spans its data range widened by 10 % on each side (so the support flag shows)."""
    norm = model.normalisation
    names = list(norm.names)
    low = dict(zip(names, np.asarray(norm.low, dtype=float), strict=True))
    high = dict(zip(names, np.asarray(norm.high, dtype=float), strict=True))
    width = high[x] - low[x] or 1.0
    xs = np.linspace(low[x] - 0.1 * width, high[x] + 0.1 * width, n_x)
    held = {n: _held_value(low[n], high[n]) for n in names if n not in (x, by)}
    levels = [None] if by is None else list(np.linspace(low[by], high[by], n_by))
    curves = []
    for level in levels:
        point = {n: np.full(n_x, v) for n, v in held.items()}
        point[x] = xs
        if by is not None:
            point[by] = np.full(n_x, level)
        curves.append(point)
    return xs, levels, curves, held


def _fmt(value: float) -> str:
    return f"{value:.4g}"


def _root(variance) -> str:
    """sqrt of a variance for the page ("–" where it is not known)."""
    value = float("nan") if variance is None else float(variance)
    return f"{np.sqrt(value):.4g}" if np.isfinite(value) and value >= 0 else "–"


def carpet_svg(model, x: str | None = None, by: str | None = None, level: float = 0.95) -> str:
    """A carpet plot of one coefficient's global model (``CoefficientModel``) as SVG (module
    docstring); ``x``, ``by``: the variables on the axis and across the curves (default the
    model's first and second variables)."""
    names = list(model.normalisation.names)
    x = x or names[0]
    if by is None and len(names) > 1:
        by = next(n for n in names if n != x)
    xs, levels, curves, held = carpet_points(model, x, by)
    predictions = [model.predict(point, level=level) for point in curves]
    values = np.concatenate(
        [np.concatenate([p.value, p.lower[~p.outside], p.upper[~p.outside]]) for p in predictions]
    )
    scale = ax.y_scale(values[np.isfinite(values)], 5)
    width, height = 7.0 * ax.PX_PER_IN, 3.6 * ax.PX_PER_IN
    left = ax.y_label_margin([scale])
    ticks = ax.nice_ticks(float(xs[0]), float(xs[-1]), 7)
    labels, _ = ax.tick_labels(ticks)
    panel = Panel(left, 52.0, width - left - 20.0, height, float(xs[0]), float(xs[-1]), scale)
    entries = []
    units = dict(zip(names, model.normalisation.units, strict=True))
    for k, (value, prediction) in enumerate(zip(levels, predictions, strict=True)):
        colour = COLOURS[k % len(COLOURS)]
        inside = ~np.asarray(prediction.outside, dtype=bool)
        # inserted beneath the curves: the function interval first, the prediction interval
        # then beneath it
        function = [np.where(inside, prediction.function_lower, np.nan),
                    np.where(inside, prediction.function_upper, np.nan)]  # fmt: skip
        ax.band_between(panel, xs, *function, colour, FUNCTION_BAND_OPACITY)
        lower = np.where(inside, prediction.lower, np.nan)
        upper = np.where(inside, prediction.upper, np.nan)
        ax.band_between(panel, xs, lower, upper, colour, BAND_OPACITY)
        ax.polyline(panel, xs, np.where(inside, prediction.value, np.nan), colour, 1.6)
        # outside the support: dashed, one sample into the support so the line is unbroken
        outside = ~inside
        outside = outside | np.roll(outside, 1) | np.roll(outside, -1)
        ax.polyline(panel, xs, np.where(outside, prediction.value, np.nan), colour, 1.2, dash="5 3")
        if value is not None:
            entries.append(("line", colour, f"{by} = {_fmt(value)}"))
    held_text = ", ".join(f"{n} = {_fmt(v)}" for n, v in held.items())
    title = f"{model.response}: global model, {level:.0%} intervals"
    text = PanelText(
        axis_label(model.response, "–"),  # an aerodynamic coefficient: dimensionless
        title,
        axis_label(x, units.get(x, "")),
        True,
        tuple(entries),
    )
    body = [ax.render_panel(panel, ticks, labels, text)]
    notes = [
        "darker band: function interval (the coefficient itself, with its model error)",
        "lighter band: prediction interval (a new measurement, with its noise too)",
        "dashed: outside the data's support (extrapolation)"
        + (f"; held: {held_text}" if held_text else ""),
    ]
    for row, note in enumerate(notes):
        body.append(
            f"<text x='{left:.1f}' y='{52.0 + height + 48.0 + 14.0 * row:.1f}' "
            f"font-size='{ax.TICK_PX}'>{ax.escape(note)}</text>"
        )
    return ax.document(width, 52.0 + height + 60.0 + 14.0 * (len(notes) - 1), body)


def write_global_model_files(model, directory: Path) -> list[str]:
    """Write ``global_model.json`` and ``global_model_terms.csv`` into ``directory``;
    returns their names."""
    directory = Path(directory)
    model.write(directory / MODEL_FILE)
    with (directory / TERMS_FILE).open("w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(["coefficient", "parameter", "term", "unit", "value", "std", "std_cr"])
        for name, coefficient in model.coefficients.items():
            for row in coefficient.to_dict()["terms"]:
                writer.writerow(
                    [
                        name,
                        row["parameter"],
                        row["term"],
                        row["unit"],
                        repr(row["value"]),
                        repr(row["std"]),
                        repr(row["std_cr"]),
                    ]
                )
    return [MODEL_FILE, TERMS_FILE]


def _terms_table(coefficient) -> str:
    entry = coefficient.to_dict()
    rows = []
    for row in entry["terms"]:
        share = row.get("cost_share")
        rows.append(
            [
                html.escape(row["parameter"]),
                f"<code>{html.escape(row['term'])}</code>",
                f"{row['value']:.6g}",
                f"{row['std']:.3g}",
                f"{row['std_cr']:.3g}",
                "–" if share is None or not np.isfinite(share) else f"{100 * share:.2f} %",
            ]
        )
    headers = ["parameter", "term", "value", "σ (default)", "CR σ", "cost share"]
    chosen = (
        f"{len(entry['terms'])} table values fitted"
        if coefficient.tables is not None
        else f"{len(entry['terms'])} of {entry['n_candidates']} candidate terms selected by "
        "predicted squared error"
    )
    facts = (
        f"<p>{chosen}; N = {entry['n_samples']}, N_eff = {entry['n_eff']:.0f}, "
        f"R² = {entry['r2']:.5f}, fit RMS = {entry['rms_fit']:.4g}, PSE = {entry['pse']:.4g} "
        f"(σ²_max = {entry['sigma2_max']:.4g}); σ: {entry['std_kind']} "
        f"(residual lag {entry['coloured_lag']}); prediction intervals with the "
        f"{entry['residual_variance']} residual variance; σ_noise = "
        f"{_root(entry['noise_variance'])} (measurement noise, from sample differences), "
        f"σ_model = {_root(entry['model_error_variance'])} (model error: the function "
        f"interval).</p>"
    )
    return facts + table(headers, rows) + _tables_section(coefficient)


def _tables_section(coefficient) -> str:
    """Each table of a table model: its breakpoints and, per grid point, the value with its
    σ and whether the data or the smoothing determined it ("" for a term model)."""
    tables = coefficient.tables
    if tables is None:
        return ""
    parts = []
    for c, component in enumerate(tables.components):
        grid = np.meshgrid(*(component.breakpoints[v] for v in component.variables), indexing="ij")
        rows = []
        for g in np.ndindex(component.grid_shape):
            value, std = tables.values[c][g], tables.value_std[c][g]
            note = "no data" if tables.dropped[c][g] else "filled" if tables.filled[c][g] else ""
            rows.append([f"{mesh[g]:.6g}" for mesh in grid] + [f"{value:.6g}", f"{std:.3g}", note])
        parts.append(
            f"<p>Table <code>{html.escape(component.label)}</code> (degree "
            f"{component.degree}): values at its breakpoints.</p>"
            + table([*component.variables, "value", "σ", "note"], rows)
        )
    return "".join(parts)


def global_model_sections(
    stage, model, directory: Path, figures: bool = True
) -> list[tuple[str, str]]:
    """(heading, HTML) per coefficient of the stage's global model: the selected terms
    with their σ and the fit, and the carpet plot (written to figures/carpet_<C>.svg)."""
    directory = Path(directory)
    write_global_model_files(model, directory)
    sections = [
        (
            f"Global model: stage {stage.name}",
            f"<p>{len(model.sources)} maneuvers; the variables and their data range:</p>"
            + variables_table(model),
        )
    ]
    for name, coefficient in model.coefficients.items():
        fragment = _terms_table(coefficient)
        if figures:
            svg = carpet_svg(coefficient).encode("utf-8")
            file = f"carpet_{name}.svg"
            (directory / "figures").mkdir(parents=True, exist_ok=True)
            (directory / "figures" / file).write_bytes(svg)
            fragment += image((file, svg), f"{name} over the envelope (carpet plot)")
        heading = f"Global model: stage {stage.name}, {name}"
        sections.append((heading, fragment))
    return sections


def variables_table(model) -> str:
    """The variables' names, units and data ranges."""
    rows = [
        [
            html.escape(v["name"]),
            html.escape(v["unit"] or "–"),
            f"{v['low']:.4g}",
            f"{v['high']:.4g}",
        ]
        for v in model.normalisation.to_dict()
    ]
    return table(["variable", "unit", "low", "high"], rows)


def global_model_rows(model) -> list[EstimateRow]:
    """Every selected term of every coefficient as a row of the estimates table and of
    estimates.csv (the parameter's name, unit, value, default σ and Cramér–Rao σ)."""
    rows = []
    for coefficient in model.coefficients.values():
        for j, name in enumerate(coefficient.parameters):
            rows.append(
                EstimateRow(
                    name=name,
                    unit=coefficient.units[j] if coefficient.units else "",
                    value=float(coefficient.estimates[j]),
                    std=float(coefficient.std[j]),
                    std_cr=float(coefficient.std_cr[j]),
                    std_kind=coefficient.std_kind,
                )
            )
    return rows


def global_model_correlations(model) -> str:
    """The correlation matrix of each coefficient's parameters (from the default
    covariance), one table per coefficient with more than one term."""
    parts = []
    for name, coefficient in model.coefficients.items():
        if len(coefficient.parameters) < 2:
            continue
        parts.append(f"<h3>{html.escape(name)} (global model)</h3>")
        parts.append(
            correlation_section(
                list(coefficient.parameters), correlation_from_covariance(coefficient.covariance)
            )
        )
    return "".join(parts)
