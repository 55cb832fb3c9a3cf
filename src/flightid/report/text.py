"""Text summaries of estimation and accuracy results."""

from __future__ import annotations

import numpy as np

from flightid.errors import InputTypeError, describe
from flightid.numbers import format_at_sigma, format_interval, format_sigma, format_with_sigma

__all__ = [
    "accuracy_summary",
    "estimate_summary",
    "format_table",
    "sigma_note",
    "sigma_range",
    "summary_of",
]


def format_table(headers: list[str], rows: list[list[str]]) -> str:
    """A plain fixed-width table; first column left-aligned, the others right-aligned."""
    widths = [max(len(str(r[i])) for r in [headers, *rows]) for i in range(len(headers))]

    def line(cells):
        return "  ".join(
            str(c).ljust(w) if i == 0 else str(c).rjust(w)
            for i, (c, w) in enumerate(zip(cells, widths, strict=True))
        )

    rule = "  ".join("-" * w for w in widths)
    return "\n".join([line(headers), rule, *(line(r) for r in rows)])


def sigma_range(result) -> tuple[float, float] | None:
    """(smallest, largest) finite std / std_cr over the free parameters, or None."""
    ratio = np.asarray(getattr(result, "sigma_ratio", ()), dtype=float)
    ratio = ratio[np.isfinite(ratio)]
    if ratio.size == 0:
        return None
    return float(ratio.min()), float(ratio.max())


# std/std_cr from which the note adds that the coloured σ itself may be optimistic: the
# measured airplane-in-turbulence study (bench/sigma_coverage.py, airplane_turbulence) had
# std/std_cr of about 3 and a coloured σ still up to 2.5× below the spread
STRONGLY_COLOURED = 2.0


def sigma_note(result) -> str | None:
    """One line saying that (and by how much) the Cramér–Rao bounds understate the σ, for a
    result whose default σ is the coloured-residual σ; None when the residuals are white."""
    if getattr(result, "std_kind", "cramer_rao") != "coloured":
        return None
    band = 1.96 / np.sqrt(max(int(np.shape(result.residuals)[0]), 1))
    text = (
        f"residuals are coloured (autocorrelated to lag L = {result.coloured_lag} samples, "
        f"white-noise band ±{band:.2g}); σ shown are the coloured-residual σ"
    )
    span = sigma_range(result)
    if span is not None:
        low, high = span
        times = f"{low:.2g}×" if f"{low:.2g}" == f"{high:.2g}" else f"{low:.2g}–{high:.2g}×"
        text += f", {times} the Cramér–Rao bounds (std_cr)"
        if high >= STRONGLY_COLOURED:
            text += (
                "; residuals this coloured come from turbulence or a model term the model "
                "lacks, where even the coloured σ can be too small (in a simulated airplane "
                "in turbulence up to 2.5×: docs/accuracy.md, Measured coverage): model the "
                "turbulence (filter error method) or the missing term"
            )
    return text


def _parameter_rows(result, coloured: bool) -> list[list[str]]:
    """One row per parameter: name, estimate, σ, rel. %, [CR σ], start, remark."""
    rows = []
    for i, name in enumerate(result.names):
        value = result.values[i]
        extra = ["-"] if coloured else []
        if name in getattr(result, "at_bound", ()):
            rows.append(
                [name, f"{value:.6g}", "-", "-", *extra, f"{result.initial[i]:.6g}", "at bound"]
            )
        elif result.free[i]:
            std = result.std[i]
            relative = abs(std / value) * 100 if value != 0 and np.isfinite(std) else np.inf
            cr = [format_sigma(result.std_cr[i], missing="-")] if coloured else []
            # σ to two significant digits, the estimate to σ's decimal place
            value_text, std_text = format_with_sigma(value, std, missing="-")
            rows.append(
                [
                    name,
                    value_text,
                    std_text,
                    f"{relative:.2g}" if np.isfinite(relative) else "-",
                    *cr,
                    f"{result.initial[i]:.6g}",
                    # a value solved from a constraint (filter error: diag(KC)_i = 1)
                    "solved" if name in getattr(result, "solved", ()) else "",
                ]
            )
        else:
            rows.append(
                [name, f"{value:.6g}", "-", "-", *extra, f"{result.initial[i]:.6g}", "fixed"]
            )
    return rows


def _without_status(message: str, status: str) -> str:
    """The message without a leading "<status>:" (the line names the status already)."""
    prefix = f"{status}:"
    return message[len(prefix) :].strip() if message.startswith(prefix) else message


def _log_det_text(result) -> str:
    """``   ln det R = …`` where R was estimated (the likelihood's measure then: J under
    R = R̂ is about N·n_o whatever the fit), else nothing."""
    if getattr(result, "noise_policy", "fixed") == "fixed":
        return ""
    log_det = float(np.sum(np.log(np.asarray(result.r_diag, dtype=float))))
    return f"   ln det R = {log_det:.6g}"


def estimate_summary(result) -> str:
    """A header naming the method (output error, filter error); estimates, default σ (and
    Cramér–Rao bounds beside it when the residuals are coloured), relative σ, start values,
    "solved" for values solved from a constraint; cost and accounting."""
    coloured = getattr(result, "std_kind", "cramer_rao") == "coloured"
    rows = _parameter_rows(result, coloured)
    if coloured:
        sigma_line = (
            f"σ: coloured-residual σ (residual autocorrelation to lag L = "
            f"{result.coloured_lag} samples); CR σ: the Cramér–Rao bounds (std_cr), which "
            "assume white residuals"
        )
    else:
        sigma_line = "σ: Cramér–Rao bounds (the residuals are white at lag 1)"
    # "output-error", "filter-error": the method that produced the estimate
    estimator = getattr(result, "estimator", "output_error").replace("_", "-")
    head = [
        f"flightid {estimator} estimate — {result.model.name}",
        f"solver {result.solver}, noise policy {result.noise_policy}, integration {result.method}",
        f"status: {result.status} — {_without_status(result.message, result.status)}",
        f"cost J = {result.cost:.6g}{_log_det_text(result)}   iterations {result.iterations}   "
        f"equivalent evaluations {result.evaluations_text()}   "
        f"wall time {result.wall_time_s:.3g} s",
        f"optimality: the next Gauss–Newton step is {result.optimality_sigma:.2g} σ long "
        "(central differences)",
        sigma_line,
        "",
    ]
    headers = ["parameter", "estimate", "σ", "rel. %", *(["CR σ"] if coloured else []), "start", ""]
    # units (Parameter.unit, the outputs' channel units) in a column when any is known
    units = tuple(getattr(result, "parameter_units", ()))
    if any(units):
        headers.insert(1, "unit")
        rows = [[row[0], unit, *row[1:]] for row, unit in zip(rows, units, strict=True)]
    table = format_table(headers, rows)
    output_units = dict(getattr(result, "output_unit_map", {}))
    show = any(output_units.values())
    noise_rows = [
        [n, *([output_units.get(n, "")] if show else []), f"{r:.4g}", f"{e:.4g}"]
        for n, r, e in zip(result.output_names, result.r_diag, result.fit_error(), strict=True)
    ]
    noise = format_table(
        ["output", *(["unit"] if show else []), "R (variance)", "fit RMS"], noise_rows
    )
    text = "\n".join(head) + table + "\n\n" + noise
    # the modes of a model linear in its states and inputs (flightid.export.modal)
    from flightid.export.modal import summary_block

    modes = summary_block(result)
    return text + ("\n\n" + modes if modes else "")


def accuracy_summary(result) -> str:
    """The intervals of an ``AccuracyResult`` beside each other: estimate, s·σ, coloured σ,
    the Cramér–Rao, Beale (and, when run, profile and search) intervals; Δ, s², N_φ and the
    evaluations above and below the table."""

    units = result.unit_map
    show_units = any(units.values())
    headers = ["parameter", *(["unit"] if show_units else [])]
    headers += ["estimate", "s·σ (CR)", "σ coloured", f"CR {result.level:g}"]
    headers += ["CR Beale"]
    if result.profile is not None:
        headers.append("profile")
    if result.search is not None:
        headers.append("search")
    rows = []
    for j, name in enumerate(result.names):
        # σ to two significant digits; estimate and bounds to the decimal place of the
        # smaller σ (the finer one the table shows)
        sigmas = [s for s in (result.std_scaled[j], result.std_coloured[j]) if np.isfinite(s)]
        place = min(sigmas) if sigmas else float("nan")

        def cell(pair, place=place) -> str:
            return format_interval(pair[0], pair[1], place)

        row = [
            name,
            *([units[name]] if show_units else []),
            format_at_sigma(result.center[j], place),
            format_sigma(result.std_scaled[j]),
            format_sigma(result.std_coloured[j]),
            cell(result.ci_cr[j]),
            cell(result.ci_cr_beale[j]),
        ]
        if result.profile is not None:
            row.append(cell(result.profile.intervals[j]))
        if result.search is not None:
            row.append(cell(result.search.intervals[j]))
        rows.append(row)
    lines = [
        f"{result.kind} {result.level:g} intervals ({result.distribution}); s² = {result.s2:.4g}, "
        f"Δ = {result.delta:.4g}, Beale Δ = {result.delta_beale:.4g}, "
        f"N_φ = {result.nonlinearity.n_phi:.3g}, coloured-residual lag L = {result.coloured_lag}",
        format_table(headers, rows),
        "evaluations: " + ", ".join(f"{k} {v}" for k, v in result.evaluations.items()),
    ]
    lines += [f"warning: {w}" for w in result.warnings]
    return "\n".join(lines)


def summary_of(result) -> str:
    """The text summary of an ``Estimate`` or an ``AccuracyResult`` (their ``summary()``)."""
    from flightid.accuracy.result import AccuracyResult
    from flightid.estimation.result import Estimate

    if isinstance(result, Estimate):
        return estimate_summary(result)
    if isinstance(result, AccuracyResult):
        return accuracy_summary(result)
    raise InputTypeError(
        f"result: expected an Estimate or an AccuracyResult, got {describe(result)}"
    )
