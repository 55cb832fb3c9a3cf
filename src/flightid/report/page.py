"""The pieces of every flightid report page, and the page they make.

Every estimator's ``report.html`` (output error: ``flightid.report.html``; frequency
domain, recursive, input design and regression stages: ``flightid.report.estimator_reports``)
is built from these pieces, so that a reader finds the same things in the same place:

1. header and provenance: title, flightid version, time written (UTC), case file and the
   SHA-256 of its bytes, data files;
2. status: one line;
3. estimates: value, unit, default σ and Cramér–Rao σ side by side (and which of the two is
   the default), σ/|θ|, the interval, the start value; numbers rounded to follow σ;
4. correlation matrix of the estimates;
5. residual (or innovation) analysis: RMS and whiteness per output;
6. the fits the estimator has (figures);
7. the files of the result folder;
8. the text summary, collapsed.

Rounding that follows σ: σ is shown to 2 significant digits and the value to the same
decimal place (4.00022 ± 0.00033); an interval's ends, themselves uncertain by about σ, to
one decimal place less ([3.9996, 4.0009]).
"""

from __future__ import annotations

import base64
import csv
import hashlib
import html
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from flightid.numbers import format_interval as interval_at_sigma
from flightid.numbers import format_sigma, format_with_sigma

__all__ = [
    "STYLE",
    "EstimateRow",
    "Page",
    "correlation_from_covariance",
    "correlation_section",
    "estimate_csv_rows",
    "estimates_section",
    "file_sha256",
    "files_section",
    "image",
    "provenance_rows",
    "render_page",
    "residual_section",
    "table",
    "write_estimates_csv",
]

STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1180px; color: #222;
       padding: 0 1em; }
h1 { margin-bottom: 0.2em; } h2 { border-bottom: 1px solid #ccc; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.6em 0 1.2em; font-size: 0.88em; }
th, td { border: 1px solid #ccc; padding: 3px 8px; text-align: right; }
th { background: #f0f0f0; } td:first-child { text-align: left; font-family: monospace; }
table.facts td, table.facts th { text-align: left; }
table.facts td:first-child { font-family: inherit; }
tr.fixed td { color: #888; } .high { background: #fbd5d5; }
.ok { color: #176117; } .bad { color: #a11; }
.warning { border: 2px solid #c33; background: #fff1f0; padding: 0.6em 1em; margin: 1em 0; }
.note { border: 1px solid #cb3; background: #fffbe6; padding: 0.5em 1em; margin: 1em 0; }
figure { margin: 0.5em 0 1.2em; } figcaption { font-size: 0.85em; color: #555; }
img { border: 1px solid #ddd; } code { font-size: 0.95em; }
.small { font-size: 0.85em; color: #555; }
details pre { background: #f6f6f6; padding: 1em; overflow-x: auto; }
"""

# the CSV columns of every estimator's estimates.csv (those of the output-error run)
CSV_COLUMNS = (
    "name",
    "unit",
    "value",
    "std",
    "std_cr",
    "std_kind",
    "relative_percent",
    "lower",
    "upper",
    "initial",
    "free",
    "role",
)

# what the page calls each kind of default σ
SIGMA_KINDS = {
    "cramer_rao": "Cramér–Rao",
    "coloured": "coloured-residual",
    "filter": "filter covariance",
    "least_squares": "least squares",
    "predicted": "predicted Cramér–Rao",
}


# ------------------------------------------------------------------------------ numbers


def _finite(value) -> bool:
    return value is not None and not isinstance(value, bool) and np.isfinite(float(value))


def format_interval(lower: float | None, upper: float | None, sigma: float | None) -> str:
    """ "[lower, upper]" at σ's decimal place (``flightid.numbers.format_interval``); "—"
    without the ends."""
    if not (_finite(lower) and _finite(upper)):
        return "—"
    return interval_at_sigma(lower, upper, sigma)


def _g(value, digits: int = 4) -> str:
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "—"
    return f"{float(value):.{digits}g}"


# ------------------------------------------------------------------------------ html pieces


def table(
    headers: list[str],
    rows: list[list[str]],
    classes: list[str] | None = None,
    table_class: str = "",
) -> str:
    """An HTML table; ``headers`` are escaped, cells are HTML already."""
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    thead = f"<thead><tr>{head}</tr></thead>" if any(headers) else ""
    body = []
    for i, row in enumerate(rows):
        cls = f' class="{classes[i]}"' if classes and classes[i] else ""
        body.append(f"<tr{cls}>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>")
    attribute = f" class='{table_class}'" if table_class else ""
    return f"<table{attribute}>{thead}<tbody>{''.join(body)}</tbody></table>"


def image(figure: tuple[str, bytes] | None, alt: str, width: str = "100%") -> str:
    """The figure embedded in the page, which then needs no other file: an SVG figure
    (a file name ending in ``.svg``, its UTF-8 text one ``<svg>`` element) inline, labelled
    by ``alt``; a PNG as an <img> with a base64 data URI."""
    if figure is None:
        return ""
    if figure[0].lower().endswith(".svg"):
        svg = figure[1].decode("utf-8")
        return (
            f"<figure style='max-width:{width}' role='img' aria-label='{html.escape(alt)}'>"
            f"{svg}<figcaption>{html.escape(alt)}</figcaption></figure>"
        )
    data = base64.b64encode(figure[1]).decode("ascii")
    return (
        f"<figure><img alt='{html.escape(alt)}' style='max-width:{width}' "
        f"src='data:image/png;base64,{data}'><figcaption>{html.escape(alt)}</figcaption></figure>"
    )


def file_sha256(path: str | Path) -> str:
    """SHA-256 of a file's bytes (hex); "" when it cannot be read."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return ""


def utc_now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S UTC")


def provenance_rows(
    case_file: str | Path | None,
    data_files: Sequence[str] = (),
    *,
    case_sha256: str = "",
    generated_utc: str | None = None,
    extra: Sequence[tuple[str, str]] = (),
) -> list[list[str]]:
    """The provenance table: flightid version, time written, case file and its SHA-256
    (``case_sha256``, else of the file as it is now), data files, and ``extra`` (label, text)."""
    from flightid._version import __version__

    digest = case_sha256 or (file_sha256(case_file) if case_file else "")
    rows = [
        ["produced by", f"flightid {html.escape(__version__)}"],
        ["generated (UTC)", html.escape(generated_utc or utc_now())],
        ["case file", f"<code>{html.escape(str(case_file or '—'))}</code>"],
        [
            "case file SHA-256",
            f"<code>{html.escape(digest or '— (the case was not read from a file)')}</code>",
        ],
        [
            "data files",
            ", ".join(f"<code>{html.escape(str(f))}</code>" for f in data_files) or "—",
        ],
    ]
    rows += [[html.escape(label), html.escape(text)] for label, text in extra]
    return rows


# ------------------------------------------------------------------------------ estimates


@dataclass(frozen=True)
class EstimateRow:
    """One parameter of the estimates table and of estimates.csv.

    ``std`` is the default σ (the one intervals use), of kind ``std_kind`` (a key of
    ``SIGMA_KINDS``); ``std_cr`` the Cramér–Rao σ (NaN/None where the estimator has none).
    """

    name: str
    unit: str
    value: float
    std: float | None
    std_cr: float | None
    std_kind: str
    initial: float | None = None
    free: bool = True
    note: str = ""
    # free, fixed, solved (from a constraint) or at_bound, as the output-error report says
    role: str | None = None


def _interval_half_width(std: float, confidence: float) -> float:
    from statistics import NormalDist

    # z_{(1+c)/2}·σ: z the two-sided normal quantile
    return NormalDist().inv_cdf(0.5 * (1.0 + confidence)) * std


def estimate_csv_rows(rows: Sequence[EstimateRow], confidence: float = 0.95) -> list[dict]:
    """The rows of estimates.csv (``CSV_COLUMNS``, the output-error run's columns): the
    interval θ̂ ± z_{(1+c)/2}·σ with σ the default σ."""
    out = []
    for row in rows:
        std = float(row.std) if row.free and _finite(row.std) else None
        half = _interval_half_width(std, confidence) if std is not None else None
        value = float(row.value)
        out.append(
            {
                "name": row.name,
                "unit": row.unit,
                "value": value,
                "std": std,
                "std_cr": float(row.std_cr) if row.free and _finite(row.std_cr) else None,
                "std_kind": row.std_kind if row.free else None,
                "relative_percent": 100 * std / abs(value) if std is not None and value else None,
                "lower": value - half if half is not None else None,
                "upper": value + half if half is not None else None,
                "initial": None if row.initial is None else float(row.initial),
                "free": bool(row.free),
                "role": row.role or ("free" if row.free else "fixed"),
            }
        )
    return out


def write_estimates_csv(
    rows: Sequence[EstimateRow], path: str | Path, confidence: float = 0.95
) -> Path:
    """Write estimates.csv (``CSV_COLUMNS``; empty cells where there is no number)."""
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(CSV_COLUMNS))
        writer.writeheader()
        for row in estimate_csv_rows(rows, confidence):
            writer.writerow({k: ("" if v is None else v) for k, v in row.items()})
    return path


def estimates_section(rows: Sequence[EstimateRow], confidence: float = 0.95, note: str = "") -> str:
    """The estimates table: value and both σ (default and Cramér–Rao), which one is the
    default, σ/|θ|, the interval, the start value and whether the parameter was estimated."""
    computed = estimate_csv_rows(rows, confidence)
    cells, classes = [], []
    for row, numbers in zip(rows, computed, strict=True):
        value, std = format_with_sigma(row.value, numbers["std"])
        kind = SIGMA_KINDS.get(row.std_kind, row.std_kind) if row.free else "—"
        status = row.note or ("estimated" if row.free else "fixed")
        cells.append(
            [
                html.escape(row.name),
                html.escape(row.unit) if row.unit else "—",
                value,
                std,
                format_sigma(numbers["std_cr"]),
                html.escape(kind),
                _g(numbers["relative_percent"], 2),
                format_interval(numbers["lower"], numbers["upper"], numbers["std"]),
                _g(row.initial, 6),
                html.escape(status),
            ]
        )
        classes.append("" if row.free else "fixed")
    headers = [
        "parameter",
        "unit",
        "estimate",
        "σ (default)",
        "Cramér–Rao σ",
        "default σ is",
        "σ/|θ| %",
        f"{100 * confidence:g} % interval",
        "start",
        "",
    ]
    text = (
        "<p class='small'>σ (default): the σ the interval uses and results.json, "
        "estimates.csv and the terminal report as <code>std</code>; Cramér–Rao σ: "
        "<code>std_cr</code>. σ is shown to 2 significant digits and the estimate to the "
        "same decimal place; interval θ̂ ± z·σ with z the normal quantile.</p>"
    )
    if note:
        text += f"<div class='note'>{note}</div>"
    return table(headers, cells, classes) + text


# ------------------------------------------------------------------------------ correlation


def correlation_from_covariance(covariance) -> np.ndarray:
    """ρ_ij = P_ij / √(P_ii P_jj) (NaN where a variance is not positive)."""
    matrix = np.asarray(covariance, dtype=float)
    scale = np.sqrt(np.where(np.diag(matrix) > 0, np.diag(matrix), np.nan))
    return matrix / np.outer(scale, scale)


def correlation_section(
    names: Sequence[str], matrix, threshold: float = 0.9, missing: str = ""
) -> str:
    """The correlation matrix of the estimates (|ρ| above ``threshold`` marked); ``missing``
    says why there is none when ``matrix`` is None or empty."""
    if matrix is None or np.asarray(matrix).size == 0:
        return f"<p>{html.escape(missing or 'No correlation matrix for this result.')}</p>"
    corr = np.asarray(matrix, dtype=float)
    rows = []
    for i, name in enumerate(names):
        cells = [html.escape(name)]
        for j in range(len(names)):
            v = corr[i, j]
            text = _g(v, 2) if np.isfinite(v) else "—"
            high = i != j and np.isfinite(v) and abs(v) > threshold
            cells.append(f"<span class='high'>{text}</span>" if high else text)
        rows.append(cells)
    pairs = [
        f"{names[i]}–{names[j]} ({corr[i, j]:.3f})"
        for i in range(len(names))
        for j in range(i + 1, len(names))
        if np.isfinite(corr[i, j]) and abs(corr[i, j]) > threshold
    ]
    text = ""
    if pairs:
        text = (
            f"<p class='bad'>|correlation| above {threshold:g}: {html.escape(', '.join(pairs))}</p>"
        )
    return text + table(["", *names], rows, table_class="correlation")


# ------------------------------------------------------------------------------ residuals


def residual_section(
    names: Sequence[str],
    units: Sequence[str],
    residuals,
    *,
    maneuver_index=None,
    dt: float | None = None,
    what: str = "residual",
    lag_unit: str = "samples",
) -> str:
    """RMS and whiteness (ρ(1), lags outside ±1.96/√N, Ljung–Box Q and p) per output of
    ``residuals`` (N, n_o) (``flightid.accuracy.whiteness``)."""
    from flightid.accuracy.whiteness import WhitenessError, residual_whiteness

    residuals = np.asarray(residuals, dtype=float)
    if residuals.ndim == 1:
        residuals = residuals[:, None]
    rms = np.sqrt(np.mean(residuals**2, axis=0))
    try:
        whiteness = residual_whiteness(
            residuals, tuple(names), maneuver_index=maneuver_index, dt=dt
        )
    except WhitenessError:
        whiteness = None
    rows = []
    for j, name in enumerate(names):
        cells = [html.escape(name), html.escape(units[j]) if units[j] else "—", _g(rms[j])]
        if whiteness is None:
            cells += ["—", "—", "—", "—"]
        else:
            outside = int(np.sum(np.abs(whiteness.rho[1:, j]) > whiteness.band))
            verdict = "white" if whiteness.white[j] else "<span class='bad'>coloured</span>"
            cells += [
                _g(float(whiteness.rho[1, j]), 3),
                f"{outside} of {whiteness.rho.shape[0] - 1}",
                f"{_g(float(whiteness.ljung_box[j]))} (p = {_g(float(whiteness.p_value[j]), 2)})",
                verdict,
            ]
        rows.append(cells)
    band = f" = ±{whiteness.band:.3g}" if whiteness is not None else ""
    lags = str(whiteness.ljung_box_lags) if whiteness is not None else "m"
    headers = [
        "output",
        "unit",
        f"{what} RMS [unit]",
        "ρ(1) [–]",
        f"lags ({lag_unit}) outside ±1.96/√N{band}",
        f"Ljung–Box Q({lags})",
        "",
    ]
    return table(headers, rows) + (
        f"<p class='small'>ρ(k): normalised {what} autocorrelation; Ljung–Box "
        "Q = N(N+2) Σ_{k=1..m} ρ(k)²/(N − M k), χ²(m) for white "
        f"{what}s, “coloured” when p < 0.05 (<code>flightid.accuracy.whiteness</code>).</p>"
    )


# ------------------------------------------------------------------------------ the page


def files_section(directory: str | Path, also: Sequence[str] = ("report.html",)) -> str:
    """A list of links to every file in the result folder (and ``also``, written after)."""
    directory = Path(directory)
    names = sorted(
        p.relative_to(directory).as_posix()
        for p in directory.rglob("*")
        if p.is_file() and not p.name.startswith(".")
    )
    names += [n for n in also if n not in names]
    items = "".join(
        f"<li><a href='{html.escape(n)}'>{html.escape(n)}</a></li>" for n in sorted(names)
    )
    return f"<ul class='files'>{items}</ul>"


@dataclass
class Page:
    """The content of a report page, section by section (module docstring, in this order).

    Each ``*_html`` is an HTML fragment; ``fits`` is (heading, fragment) per fit section.
    """

    title: str
    provenance: list[list[str]]
    ok: bool
    status: str
    estimates_html: str
    correlation_html: str
    residuals_heading: str
    residuals_html: str
    fits: list[tuple[str, str]] = field(default_factory=list)
    files_html: str = ""
    summary_text: str = ""
    description: str = ""
    run_facts: list[list[str]] = field(default_factory=list)


def render_page(page: Page) -> str:
    """The page as one self-contained HTML string."""
    title = html.escape(page.title)
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        "<meta name='viewport' content='width=device-width, initial-scale=1'>",
        "<meta name='generator' content='flightid'>",
        f"<title>{title}</title><style>{STYLE}</style></head><body>",
        f"<h1>{title}</h1>",
    ]
    if page.description:
        parts.append(f"<p>{html.escape(page.description)}</p>")
    parts.append(table(["", ""], page.provenance, table_class="facts provenance"))
    status_class = "ok" if page.ok else "bad"
    parts.append(f"<p class='status {status_class}'>{html.escape(page.status)}</p>")
    if page.run_facts:
        parts.append("<h2>Run</h2>" + table(["item", "value"], page.run_facts, table_class="facts"))
    parts.append("<h2>Estimates</h2>" + page.estimates_html)
    parts.append("<h2>Correlation matrix [–]</h2>" + page.correlation_html)
    if page.residuals_html:  # a section without content is left out
        parts.append(f"<h2>{html.escape(page.residuals_heading)}</h2>" + page.residuals_html)
    for heading, fragment in page.fits:
        parts.append(f"<h2>{html.escape(heading)}</h2>" + fragment)
    parts.append("<h2>Files</h2>" + page.files_html)
    if page.summary_text:
        parts.append(
            "<details><summary>Text summary (as printed by flightid)</summary>"
            f"<pre>{html.escape(page.summary_text)}</pre></details>"
        )
    parts.append("</body></html>")
    return "\n".join(parts)
