"""Result folders of the frequency-domain, recursive and input-design runs and of the
regression stages, in the layout of the output-error run (``flightid.report.html``).

Every folder holds

    results.json        the results document (``flightid.results.results_document``)
    estimates.csv       name, unit, value, std, std_cr, std_kind, relative_percent, lower,
                        upper, initial, free (the output-error run's columns)
    a time-history CSV  frequency domain: frequency_spectra.csv (measured and model output
                        transforms); recursive: parameter_histories.csv and innovations.csv;
                        design: designed_input.csv (and predicted_accuracy.csv); stages:
                        stage_time_histories.csv (measured and fitted coefficients)
    figures/*.png       the fits of that estimator
    report.html         one page with the sections of ``flightid.report.page`` (regression
                        stages before an output-error stage: stages.html, the output-error
                        stage's report.html beside it)

The writers take the result objects and only read them; ``write_frequency_files``,
``write_recursive_files`` and ``write_design_files`` return the path of report.html.
"""

from __future__ import annotations

import csv
import html
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from flightid.report.page import (
    EstimateRow,
    Page,
    correlation_from_covariance,
    correlation_section,
    estimates_section,
    files_section,
    image,
    provenance_rows,
    render_page,
    residual_section,
    table,
    write_estimates_csv,
)

__all__ = [
    "STAGES_PAGE",
    "write_design_files",
    "write_frequency_files",
    "write_recursive_files",
    "write_results_json",
    "write_stages_files",
]

STAGES_PAGE = "stages.html"


# ------------------------------------------------------------------------------ shared


def write_results_json(directory: str | Path, entry: dict, extra: Mapping | None = None) -> Path:
    """Write ``directory/results.json`` — the results document with the one ``entry`` (and
    the top-level keys ``extra``), strict JSON (``flightid.jsonout``) — and return
    its path."""
    from flightid.jsonout import dumps
    from flightid.results import results_document

    path = Path(directory) / "results.json"
    document = {**results_document([entry]), **(extra or {})}
    path.write_text(dumps(document) + "\n", encoding="utf-8")
    return path


def _save(directory: Path, name: str, figure, dpi: int = 90) -> tuple[str, bytes]:
    """Write ``figures/name`` (PNG) and return (relative path, bytes); a pyplot figure is
    closed afterwards."""
    from flightid.report.figures import png_bytes

    data = png_bytes(figure, dpi)
    (directory / "figures").mkdir(parents=True, exist_ok=True)
    (directory / "figures" / name).write_bytes(data)
    if getattr(figure, "number", None) is not None:  # made by pyplot: release it
        import matplotlib.pyplot as plt

        plt.close(figure)
    return f"figures/{name}", data


def _write_page(directory: Path, page: Page, name: str = "report.html") -> Path:
    page.files_html = files_section(directory, also=(name,))
    path = directory / name
    path.write_text(render_page(page), encoding="utf-8")
    return path


def _status(ok: bool, word: str, message: str) -> str:
    """One line: ``word: message`` without repeating the word the message starts with."""
    message = " ".join(str(message).split())
    if message.lower().startswith(word.lower()):
        message = message[len(word) :].lstrip(" :—-")
    return f"{word}: {message}" if message else word


def _write_csv(path: Path, header: Sequence[str], rows) -> None:
    with path.open("w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(header)
        writer.writerows(rows)


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name) or "stage"


# ------------------------------------------------------------------------------ frequency


def _frequency_rows(result) -> list[EstimateRow]:
    rows = []
    for row in result._frame_rows():
        rows.append(
            EstimateRow(
                name=row["name"],
                unit=row["unit"],
                value=row["value"],
                std=row["std"] if row["free"] else None,
                std_cr=row["std_cr"] if row["free"] else None,
                std_kind="coloured",
                initial=row["initial"],
                free=row["free"],
                note="not estimated" if row["name"] in result.not_estimated else "",
            )
        )
    return rows


def _frequency_residuals(result) -> str:
    """Per output the time-domain equivalent √R of the residual spectral covariance S, and
    the whiteness across frequency of Re V, V = Z − Ŷ."""
    blocks, index = [], []
    for m, (_, z, y) in enumerate(result.output_transforms()):
        blocks.append(np.asarray(z - y))
        index.append(np.full(z.shape[0], m))
    residuals = np.vstack(blocks)
    units = list(result.output_units or [""] * len(result.outputs))
    # the transforms' own scale: no output unit on V
    text = residual_section(
        list(result.outputs),
        [""] * len(result.outputs),
        np.real(residuals),
        maneuver_index=np.concatenate(index),
        what="residual transform (real part)",
        lag_unit="frequency steps",
    )
    equivalent = result.equivalent_variances()
    rows = [
        [
            html.escape(name),
            html.escape(units[j]) or "—",
            f"{np.sqrt(equivalent[j]):.4g}" if np.isfinite(equivalent[j]) else "—",
        ]
        for j, name in enumerate(result.outputs)
    ]
    return (
        "<p>Residual transforms V(f) = Z(f) − Ŷ(f) over the band; their correlation from one "
        "frequency to the next is what the coloured-residual σ accounts for.</p>"
        + table(
            ["output", "unit", "time-domain equivalent of the residual, √R = √(S/(Δt T)) [unit]"],
            rows,
        )
        + text
    )


def write_frequency_files(result, directory: str | Path) -> Path:
    """results.json, estimates.csv, frequency_spectra.csv, figures/bode.png,
    figures/spectra.png and report.html of a frequency-domain result
    (``flightid.cases.frequency_case.FrequencyResult``) in ``directory``; returns the
    path of report.html."""
    from flightid.frequency.plots import bode_figure, spectra_figure

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    write_results_json(directory, result.to_dict())
    rows = _frequency_rows(result)
    write_estimates_csv(rows, directory / "estimates.csv")
    header = ["maneuver", "frequency_hz"]
    for o in result.outputs:
        header += [f"{o}_measured_re", f"{o}_measured_im", f"{o}_model_re", f"{o}_model_im"]
    lines = []
    for m, (f, z, y) in enumerate(result.output_transforms(), start=1):
        for k in range(f.size):
            line = [m, repr(float(f[k]))]
            for j in range(len(result.outputs)):
                line += [
                    repr(float(v)) for v in (z[k, j].real, z[k, j].imag, y[k, j].real, y[k, j].imag)
                ]
            lines.append(line)
    _write_csv(directory / "frequency_spectra.csv", header, lines)
    bode = _save(directory, "bode.png", bode_figure(result))
    spectra = _save(directory, "spectra.png", spectra_figure(result))
    band = result.settings.band_hz
    free_names = [n for n, f in zip(result.names, result.free, strict=True) if f]
    note = html.escape(result.sigma_line())
    if result.not_estimated:
        note += "<br>Not estimated: " + html.escape(", ".join(result.not_estimated)) + " — "
        note += html.escape(next(iter(result.not_estimated.values())))
    page = Page(
        title=result.title or "frequency-domain estimate",
        provenance=provenance_rows(
            result.case_info.get("file"),
            [m.get("name", "") for m in result.maneuvers],
            case_sha256=result.case_info.get("sha256", ""),
            extra=[
                ("model", str(result.case_info.get("model", ""))),
                (
                    "estimator",
                    f"frequency-domain {result.method.replace('_', ' ')}, band "
                    f"{band[0]:g}–{band[1]:g} Hz, step {result.settings.step_hz:g} Hz, "
                    f"{result.frequencies_hz.size} frequencies × {len(result.spectra)} "
                    "maneuver(s)",
                ),
            ],
        ),
        ok=bool(result.converged),
        status=_status(
            result.converged, "converged" if result.converged else "not converged", result.message
        ),
        estimates_html=estimates_section(rows, note=note),
        correlation_html=correlation_section(
            free_names,
            getattr(result, "correlation", None),
            missing="Equation error fits each state equation on its own: there is no joint "
            "covariance of all parameters, so no correlation matrix.",
        ),
        residuals_heading="Residual analysis (frequency domain)",
        residuals_html=_frequency_residuals(result),
        fits=[
            (
                "Fit: Bode magnitude and phase, model and data",
                image(bode, "frequency responses: model (line) and data Z/U (points)"),
            ),
            (
                "Fit: output transforms, measured and model",
                image(spectra, "|Z(f)| measured (points) and |Ŷ(f)| model (line) per output"),
            ),
        ],
        summary_text=result.summary(),
    )
    return _write_page(directory, page)


# ------------------------------------------------------------------------------ recursive


def _recursive_rows(result) -> list[EstimateRow]:
    kind = "least_squares" if result.method == "ftr" else "filter"
    initial = result.initial or (None,) * len(result.parameter_names)
    return [
        EstimateRow(
            name=name,
            unit=result.units[j],
            value=float(result.values[j]),
            std=float(result.std[j]),
            std_cr=float(result.std_cr[j]),
            std_kind=kind,
            initial=initial[j],
            note="" if result.has_standard_error else "no standard error (EFRLS)",
        )
        for j, name in enumerate(result.parameter_names)
    ]


def _recursive_innovations(result) -> tuple[np.ndarray, np.ndarray] | None:
    """(time in s, innovations (n, n_y)) kept by the case run, or None."""
    innovations = result.meta.get("innovations")
    if innovations is None or np.asarray(innovations).size == 0:
        return None
    innovations = np.asarray(innovations, dtype=float)
    # one innovation per corrected sample: the last n samples of the run
    time_s = np.asarray(result.meta.get("innovation_time_s", result.time_s[-len(innovations) :]))
    return time_s, innovations


def _recursive_residuals(result, innovations) -> str:
    outputs = list(result.meta.get("outputs", []))
    units = list(result.meta.get("output_units", [""] * len(outputs)))
    if innovations is None:
        return (
            "<p>This estimator keeps no innovations (the FTR fits each state equation in the "
            "frequency domain); see the σ of its least-squares fits.</p>"
        )
    time_s, values = innovations
    dt = float(np.median(np.diff(time_s))) if time_s.size > 1 else None
    text = residual_section(outputs, units, values, dt=dt, what="innovation")
    nis = result.nis[np.isfinite(result.nis)] if result.nis.size else result.nis
    if nis.size:
        text += (
            f"<p>Mean normalised innovation squared νᵀS⁻¹ν = {float(np.mean(nis)):.3g} over "
            f"{nis.size} samples (expected {len(outputs)}, the number of outputs, when the "
            "filter's noise model describes the data).</p>"
        )
    return text


def write_recursive_files(result, directory: str | Path) -> Path:
    """results.json, estimates.csv, parameter_histories.csv, innovations.csv (filters),
    figures/parameter_histories.png, figures/innovations.png and report.html of a
    ``flightid.recursive.RecursiveResult`` in ``directory``; returns the path of
    report.html."""
    from flightid.report.estimator_figures import innovations_figure, parameter_history_figure

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    write_results_json(directory, result.to_dict())
    rows = _recursive_rows(result)
    write_estimates_csv(rows, directory / "estimates.csv")
    columns, history = result.history_table()
    _write_csv(
        directory / "parameter_histories.csv",
        columns,
        ([f"{v:.10g}" for v in line] for line in history),
    )
    innovations = _recursive_innovations(result)
    outputs = list(result.meta.get("outputs", []))
    units = list(result.meta.get("output_units", [""] * len(outputs)))
    histories = _save(
        directory,
        "parameter_histories.png",
        parameter_history_figure(
            result.time_s,
            result.theta_history,
            result.std_history,
            result.parameter_names,
            result.units,
            result.values,
            f"{result.method}: parameter estimates ± σ (dashed: reported value)",
        ),
    )
    fits = [("Fit: parameter histories ± σ", image(histories, "parameter estimates ± σ"))]
    if innovations is not None:
        time_s, values = innovations
        _write_csv(
            directory / "innovations.csv",
            ["time_s", *outputs],
            (
                [f"{t:.10g}", *(f"{v:.10g}" for v in line)]
                for t, line in zip(time_s, values, strict=True)
            ),
        )
        figure = innovations_figure(
            time_s, values, outputs, units, f"{result.method}: innovations ν = z − ỹ"
        )
        fits.append(
            (
                "Fit: innovations",
                image(_save(directory, "innovations.png", figure), "innovations per output"),
            )
        )
    correlation = result.meta.get("parameter_correlation")
    title = result.meta.get("title", "") or "recursive estimate"
    status_word = "completed" if result.converged else "inconsistent"
    message = (
        f"one pass over {result.n_samples} samples; reported value = mean over the last "
        f"{result.n_report} history rows"
        + ("" if result.converged else "; " + "; ".join(result.warnings))
    )
    page = Page(
        title=title,
        provenance=provenance_rows(
            result.meta.get("file"),
            [m.get("name", "") for m in result.meta.get("maneuvers", [])],
            case_sha256=str(result.meta.get("sha256", "")),
            extra=[
                ("model", str(result.meta.get("model", ""))),
                ("estimator", f"recursive, {result.method} ({result.wall_time_s:.3g} s)"),
            ],
        ),
        ok=result.converged,
        status=_status(result.converged, status_word, message),
        estimates_html=estimates_section(rows, note=html.escape(result._std_note())),
        correlation_html=correlation_section(
            list(result.parameter_names),
            correlation,
            missing="This estimator keeps no parameter covariance matrix (σ per parameter "
            "only), so there is no correlation matrix.",
        ),
        residuals_heading="Innovation analysis",
        residuals_html=_recursive_residuals(result, innovations),
        fits=fits,
        summary_text=result.summary(),
    )
    return _write_page(directory, page)


# ------------------------------------------------------------------------------ design


def _design_rows(result) -> list[EstimateRow]:
    accuracy = result.best.accuracy
    units = {p.name: p.unit for p in result.problem.model.parameters}
    return [
        EstimateRow(
            name=name,
            unit=units.get(name, ""),
            value=float(accuracy.values[j]),
            std=float(accuracy.std[j]),
            std_cr=float(accuracy.std[j]),
            std_kind="predicted",
            initial=float(accuracy.values[j]),
            note="a-priori value",
        )
        for j, name in enumerate(accuracy.names)
    ]


def _design_noise(result, units: Mapping[str, str]) -> str:
    """The assumed noise and the predicted peak responses per output (a design has no
    residuals)."""
    accuracy, best = result.best.accuracy, result.best
    rows = []
    for j, name in enumerate(accuracy.output_names):
        limit = result.problem.limits.get(name)
        rows.append(
            [
                html.escape(name),
                html.escape(units.get(name, "")) or "—",
                f"{accuracy.noise_std[j]:.4g}",
                f"{best.response_peak.get(name, float('nan')):.4g}",
                "—" if limit is None else f"{limit:.4g}",
            ]
        )
    return (
        "<p>A design predicts; it has no residuals. The predicted σ assume white measurement "
        "noise of the σ below on each output.</p>"
        + table(
            ["output", "unit", "assumed noise σ [unit]", "peak |Δy| [unit]", "limit [unit]"], rows
        )
    )


def _write_design_csvs(result, directory: Path) -> None:
    best = result.best
    absolute = {
        spec.name: spec.trim + best.perturbations[:, j]
        for j, spec in enumerate(result.problem.inputs)
    }
    _write_csv(
        directory / "designed_input.csv",
        ["time_s", *absolute, *[f"delta_{n}" for n in absolute]],
        (
            [f"{t:.6f}"]
            + [f"{absolute[n][k]:.9g}" for n in absolute]
            + [f"{best.perturbations[k, j]:.9g}" for j in range(len(absolute))]
            for k, t in enumerate(best.time)
        ),
    )
    accuracy = best.accuracy
    header = ["name", "value", "predicted_std"]
    if result.reference is not None:
        header.append("reference_std")
    lines = []
    for j, name in enumerate(accuracy.names):
        line = [name, f"{accuracy.values[j]:.9g}", f"{accuracy.std[j]:.6g}"]
        if result.reference is not None:
            line.append(f"{result.reference[0].std_of(name):.6g}")
        lines.append(line)
    _write_csv(directory / "predicted_accuracy.csv", header, lines)


def write_design_files(
    result, directory: str | Path, units: Mapping[str, str] | None = None
) -> Path:
    """results.json, estimates.csv (std = std_cr = the predicted Cramér–Rao σ),
    designed_input.csv (time and trim + Δu per input, ready for a test card or an onboard
    excitation system), predicted_accuracy.csv, figures/designed_input.png,
    figures/predicted_sigma.png and report.html of a ``flightid.design.result.DesignResult``
    in ``directory``; ``units`` maps input and output names to their units (axis labels).
    Returns the path of report.html."""
    from flightid.report.estimator_figures import design_input_figure, predicted_sigma_figure

    units = dict(units or {})
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    write_results_json(directory, result.to_dict())
    rows = _design_rows(result)
    write_estimates_csv(rows, directory / "estimates.csv")
    _write_design_csvs(result, directory)
    problem, best = result.problem, result.best
    accuracy = best.accuracy
    signal = design_input_figure(
        best.time,
        best.perturbations,
        best.input_names,
        [units.get(n, "") for n in best.input_names],
        [s.amplitude for s in problem.inputs],
        accuracy.outputs,
        accuracy.output_names,
        [units.get(n, "") for n in accuracy.output_names],
        f"designed input ({problem.signal}, dotted: amplitude limit) and predicted response",
    )
    scale = np.maximum(np.abs(accuracy.values), accuracy.typical)
    reference = None if result.reference is None else 100 * result.reference[0].std / scale
    sigma = predicted_sigma_figure(
        accuracy.names,
        100 * accuracy.std / scale,
        reference,
        f"designed ({problem.signal})",
        "predicted Cramér–Rao σ relative to |θ|",
    )
    facts = result.summary().splitlines()[1].strip()
    page = Page(
        title=result.title or "input design",
        provenance=provenance_rows(
            result.case_file or None,
            [str(result.reference[1].get("name", ""))] if result.reference is not None else [],
            extra=[("design", facts)],
        ),
        ok=True,
        status=_status(
            True,
            "designed",
            f"{len(result.tried)} candidates, best "
            f"{problem.criterion} = {best.criterion_value:.6g}",
        ),
        estimates_html=estimates_section(
            rows,
            note="Predicted accuracy of the designed input: the Cramér–Rao σ the estimate "
            "would have from this input with the assumed noise, at the a-priori values.",
        ),
        correlation_html=correlation_section(list(accuracy.names), accuracy.correlation),
        residuals_heading="Assumed noise and predicted responses",
        residuals_html=_design_noise(result, units),
        fits=[
            (
                "Designed input and predicted response",
                image(
                    _save(directory, "designed_input.png", signal),
                    "designed input Δu and predicted response Δy against time",
                ),
            ),
            (
                "Predicted σ",
                image(_save(directory, "predicted_sigma.png", sigma), "predicted σ per parameter"),
            ),
        ],
        summary_text=result.summary(),
    )
    return _write_page(directory, page)


# ------------------------------------------------------------------------------ stages


def _stage_rows(entries: Mapping[str, dict], stage, results) -> list[EstimateRow]:
    rows = []
    for coefficient, entry in entries[stage.name]["coefficients"].items():
        kind = entry.get("std_kind") or results[coefficient].fit.std_kind
        for parameter in entry["parameters"]:
            name = (
                parameter["name"] if "term" in parameter else f"{coefficient}: {parameter['name']}"
            )
            rows.append(
                EstimateRow(
                    name=name,
                    unit=parameter.get("unit") or "",
                    value=float(parameter["value"]),
                    std=parameter.get("std"),
                    std_cr=parameter.get("std_cr", parameter.get("std")),
                    std_kind=kind,
                )
            )
    return rows


def _stage_correlations(entries, stage, results) -> str:
    parts = []
    for coefficient, result in results.items():
        fit = result.fit
        covariance = (
            fit.covariance_default if fit.covariance_default is not None else fit.covariance
        )
        names = [p["name"] for p in entries[stage.name]["coefficients"][coefficient]["parameters"]]
        if len(names) < 2:
            continue
        parts.append(f"<h3>{html.escape(coefficient)}</h3>")
        parts.append(correlation_section(names, correlation_from_covariance(covariance)))
    return "".join(parts) or "<p>Each fit has one parameter: no correlation.</p>"


def _stage_time(run, n: int) -> np.ndarray:
    """Time of each regression sample, s: k·dt within each maneuver, maneuvers end to end."""
    dt = float(run.dt or 1.0)
    index = run.maneuver_index if run.maneuver_index is not None else np.zeros(n, dtype=int)
    time_s = np.empty(n)
    offset = 0.0
    for m in np.unique(index):
        rows = np.flatnonzero(index == m)
        time_s[rows] = offset + dt * np.arange(rows.size)
        offset += dt * rows.size
    return time_s


def write_stages_files(
    run, directory: Path, figures: bool = True, page_name: str | None = None
) -> Path:
    """The regression stages' part of a staged run's folder: stage_estimates.csv (or
    estimates.csv when there is no output-error stage), stage_time_histories.csv,
    figures/stage_fit_<stage>.png, figures/whiteness_<stage>.png, a global-model stage's files
    (``flightid.report.globalmodel_reports``) and the page (``page_name``;
    default stages.html when an output-error stage writes report.html, else report.html).
    Returns the page's path."""
    from flightid.report.estimator_figures import coefficient_fit_figure
    from flightid.report.figures import png_bytes
    from flightid.report.whiteness_figures import whiteness_figure

    directory = Path(directory)
    alone = getattr(run, "output_error", None) is None
    page_name = page_name or ("report.html" if alone else STAGES_PAGE)
    entries = {e["name"]: e for e in run.stages_dict()}
    rows: list[EstimateRow] = []
    correlation, residuals, fits, lines = [], [], [], []
    for stage, results in run.regressions:
        stage_rows = _stage_rows(entries, stage, results)
        rows += stage_rows
        heading = f"<h3>Stage {stage.index}: {html.escape(stage.name)} ({stage.kind})</h3>"
        correlation.append(heading + _stage_correlations(entries, stage, results))
        names = list(results)
        fitted = np.column_stack([np.asarray(r.fit.fitted) for r in results.values()])
        residual = np.column_stack([np.asarray(r.fit.residuals) for r in results.values()])
        measured = fitted + residual
        time_s = _stage_time(run, fitted.shape[0])
        residuals.append(
            heading
            + residual_section(
                names,
                ["–"] * len(names),
                residual,
                maneuver_index=run.maneuver_index,
                dt=run.dt,
            )
        )
        for k in range(fitted.shape[0]):
            for j, name in enumerate(names):
                lines.append(
                    [
                        stage.name,
                        name,
                        f"{time_s[k]:.6g}",
                        f"{measured[k, j]:.10g}",
                        f"{fitted[k, j]:.10g}",
                        f"{residual[k, j]:.10g}",
                    ]
                )
        if not figures:
            continue
        title = f"stage {stage.name}: measured and fitted coefficients"
        fit_png = _save(
            directory,
            f"stage_fit_{stage.index}_{_safe(stage.name)}.png",
            coefficient_fit_figure(time_s, measured, fitted, names, title),
        )
        fits.append(
            (f"Fit: stage {stage.name}, measured and fitted coefficients", image(fit_png, title))
        )
        whiteness = _stage_whiteness(run, results)
        if whiteness is not None:
            name = f"whiteness_{stage.index}_{_safe(stage.name)}.png"
            data = png_bytes(
                whiteness_figure(whiteness, f"stage {stage.name}: residual autocorrelation")
            )
            (directory / "figures" / name).write_bytes(data)
            fits.append(
                (
                    f"Residual autocorrelation: stage {stage.name}",
                    image((name, data), "residual autocorrelation per coefficient"),
                )
            )
    for stage, model in getattr(run, "global_models", ()):
        from flightid.report import globalmodel_reports as global_report

        rows += global_report.global_model_rows(model)
        correlation.append(
            f"<h3>Stage {stage.index}: {html.escape(stage.name)} ({stage.kind})</h3>"
            + global_report.global_model_correlations(model)
        )
        fits += global_report.global_model_sections(stage, model, directory, figures)
    write_estimates_csv(rows, directory / ("estimates.csv" if alone else "stage_estimates.csv"))
    _write_csv(
        directory / "stage_time_histories.csv",
        ["stage", "coefficient", "time_s", "measured", "fitted", "residual"],
        lines,
    )
    case = run.case
    page = Page(
        title=f"{case.title}: " + ("regression stages" if run.regressions else "global model"),
        provenance=provenance_rows(
            case.path,
            [spec.file for spec in case.maneuvers],
            extra=[("data directory", str(run.data_dir))],
        ),
        ok=True,
        status=_status(
            True,
            "fitted",
            ", ".join(
                f"{count} {what}"
                for count, what in (
                    (len(run.regressions), "regression stage(s)"),
                    (len(getattr(run, "global_models", ())), "global model(s)"),
                )
                if count
            )
            + ("" if alone else "; the output-error stage's report is report.html"),
        ),
        estimates_html=estimates_section(
            rows,
            note="Regression σ assume white residuals (Cramér–Rao) unless the residuals are "
            "coloured, where the default σ is the coloured-residual one"
            + (" (see the residual analysis)." if run.regressions else "."),
        ),
        correlation_html="".join(correlation),
        residuals_heading="Residual analysis",
        residuals_html="".join(residuals),
        fits=fits,
        summary_text=run.summary(),
    )
    return _write_page(directory, page, page_name)


def _stage_whiteness(run, results):
    """Whiteness of every coefficient's residuals of one stage (``None``: too short)."""
    from flightid.accuracy.whiteness import WhitenessError, residual_whiteness

    names = tuple(results)
    residuals = np.column_stack([np.asarray(r.fit.residuals) for r in results.values()])
    try:
        return residual_whiteness(residuals, names, maneuver_index=run.maneuver_index, dt=run.dt)
    except WhitenessError:
        return None
