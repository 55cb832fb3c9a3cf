"""HTML page of the regression stages of a case (``flightid.cases.stages.StagesRun``).

``write_stages_files(run, directory)`` writes ``stages.html`` (one self-contained page, figures
embedded as base64 PNG) and ``figures/whiteness_<stage>.png``: per regression or stepwise
stage, per coefficient the method (OLS / TLS / stepwise), R², s², the estimates with their
standard errors (TLS: both the OLS-formula σ and the errors-in-variables σ), and the residual
whiteness — ρ(1), lags outside ±1.96/√N, Ljung–Box Q and p (``flightid.accuracy.whiteness``)
— with the autocorrelation figure. The standard errors of a regression assume white
residuals; the page says so in plain words when a response's residuals are coloured.
The output-error stage, when there is one, has its own report.html beside it.
"""

from __future__ import annotations

import html
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from flightid.accuracy.whiteness import Whiteness, WhitenessError, residual_whiteness
from flightid.report.html import _STYLE, _fmt, _img, _table

__all__ = ["STAGES_PAGE", "render_stages_html", "stage_whiteness", "write_stages_files"]

STAGES_PAGE = "stages.html"


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name) or "stage"


def stage_whiteness(run, results) -> Whiteness | None:
    """Whiteness of every coefficient's residuals of one stage, one column each (the numbers
    per column equal ``StagesRun.whiteness`` of that coefficient)."""
    names = tuple(results)
    residuals = np.column_stack([np.asarray(r.fit.residuals) for r in results.values()])
    try:
        return residual_whiteness(residuals, names, maneuver_index=run.maneuver_index, dt=run.dt)
    except WhitenessError:
        return None


def _parameter_rows(entry: dict) -> tuple[list[str], list[list[str]]]:
    tls = entry.get("method") == "tls"
    headers = ["parameter", "term", "estimate", "std"]
    if tls:
        headers += ["std (OLS formula)", "std (errors in variables)"]
    headers.append("|t|")
    rows = []
    for row in entry["parameters"]:
        std = row.get("std")
        t = abs(row["value"] / std) if std else None
        cells = [html.escape(row["name"]), html.escape(row.get("term", row["name"]))]
        cells += [_fmt(row["value"]), _fmt(std, 4)]
        if tls:
            cells += [_fmt(row.get("std_ols"), 4), _fmt(row.get("std_eiv"), 4)]
        cells.append(_fmt(t, 4))
        rows.append(cells)
    return headers, rows


def _method(stage, entry: dict) -> str:
    if stage.kind == "stepwise":
        return "modified stepwise regression (OLS on the selected terms)"
    if entry.get("method") == "tls":
        return (
            "total least squares (SVD of [X z]); std: "
            + ("errors-in-variables sandwich" if entry.get("covariance") == "eiv" else "OLS")
            + " formula at the TLS estimates"
        )
    return "ordinary least squares"


def _whiteness_rows(whiteness: Whiteness) -> list[list[str]]:
    rows = []
    for j, name in enumerate(whiteness.names):
        outside = int(np.sum(np.abs(whiteness.rho[1:, j]) > whiteness.band))
        verdict = "white" if whiteness.white[j] else "<span class='bad'>coloured</span>"
        rows.append(
            [
                html.escape(name),
                _fmt(float(whiteness.rho[1, j]), 3),
                f"{outside} of {whiteness.max_lag}",
                _fmt(float(whiteness.ljung_box[j]), 4),
                _fmt(float(whiteness.p_value[j]), 3),
                verdict,
            ]
        )
    return rows


def render_stages_html(run, figures: dict[int, tuple[str, bytes]] | None = None) -> str:
    """The page as one HTML string; ``figures`` maps a stage index to its (file, PNG)."""
    from flightid._version import __version__

    case = run.case
    entries = {e["name"]: e for e in run.stages_dict()}
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        "<meta name='generator' content='flightid'>",
        f"<title>{html.escape(case.title)}: regression stages</title><style>{_STYLE}</style>",
        "</head><body>",
        f"<h1>{html.escape(case.title)}: regression stages</h1>",
        _table(
            ["", ""],
            [
                ["produced by", f"flightid {html.escape(__version__)}"],
                ["generated (UTC)", datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S UTC")],
                ["case file", f"<code>{html.escape(str(case.path))}</code>"],
                ["data directory", f"<code>{html.escape(str(run.data_dir))}</code>"],
            ],
            table_class="facts",
        ),
    ]
    for stage, results in run.regressions:
        entry = entries[stage.name]
        parts.append(f"<h2>Stage {stage.index}: {html.escape(stage.name)} ({stage.kind})</h2>")
        for name, coefficient in entry["coefficients"].items():
            headers, rows = _parameter_rows(coefficient)
            parts.append(
                f"<h3>{html.escape(name)}</h3><p>{html.escape(_method(stage, coefficient))}; "
                f"R² = {_fmt(coefficient['r2'], 6)}, s² = {_fmt(coefficient['s2'], 4)}</p>"
            )
            parts.append(_table(headers, rows))
        whiteness = stage_whiteness(run, results)
        if whiteness is None:
            continue
        parts.append("<h3>Residual whiteness</h3>")
        parts.append(
            _table(
                [
                    "response",
                    "ρ(1) [–]",
                    f"lags outside ±1.96/√N = ±{whiteness.band:.3g}",
                    f"Ljung–Box Q({whiteness.ljung_box_lags})",
                    "p",
                    "",
                ],
                _whiteness_rows(whiteness),
            )
        )
        coloured = [n for n, w in zip(whiteness.names, whiteness.white, strict=True) if not w]
        if coloured:
            parts.append(
                "<div class='note'>The residuals of "
                + html.escape(", ".join(coloured))
                + " are coloured (Ljung–Box p < "
                + f"{1 - whiteness.level:.2g}): the standard errors above assume white "
                "residuals and are optimistic for them.</div>"
            )
        if figures and stage.index in figures:
            parts.append(
                _img(figures[stage.index], f"stage {stage.name}: residual autocorrelation")
            )
    parts.append(
        "<p class='small'>ρ(k) = R̂(k)/R̂(0), R̂(k) = (1/N) Σ ν_i ν_{i+k} within each maneuver; "
        "Ljung–Box Q = N(N+2) Σ_{k=1..m} ρ(k)²/(N − M k), χ²(m) for white residuals "
        "(<code>flightid.accuracy.whiteness</code>).</p>"
    )
    parts.append("</body></html>")
    return "\n".join(p for p in parts if p)


def write_stages_files(run, directory: Path, figures: bool = True) -> Path:
    """Write ``stages.html`` and ``figures/whiteness_<stage>.png`` into ``directory`` (which
    exists); returns the page's path."""
    from flightid.report.figures import png_bytes
    from flightid.report.whiteness_figures import whiteness_figure

    directory = Path(directory)
    rendered: dict[int, tuple[str, bytes]] = {}
    if figures:
        for stage, results in run.regressions:
            whiteness = stage_whiteness(run, results)
            if whiteness is None:
                continue
            title = f"stage {stage.name}: residual autocorrelation"
            name = f"whiteness_{stage.index}_{_safe(stage.name)}.png"
            rendered[stage.index] = (name, png_bytes(whiteness_figure(whiteness, title)))
        if rendered:
            (directory / "figures").mkdir(parents=True, exist_ok=True)
            for name, data in rendered.values():
                (directory / "figures" / name).write_bytes(data)
    path = directory / STAGES_PAGE
    path.write_text(render_stages_html(run, rendered), encoding="utf-8")
    return path
