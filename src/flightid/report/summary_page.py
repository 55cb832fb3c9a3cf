"""results.json and report.html for the results that have no output-error report of their
own: recursive estimation (``flightid.recursive``), frequency-domain estimation
(``flightid.frequency``) and input design (``flightid.design``).

One page that stands alone, like the output-error report (``flightid.report.html``): the
title, when and by which flightid it was written, the result's text summary (the same text
``flightid run`` prints), every figure embedded as a base64 PNG, and links to the data files
written beside it (results.json, CSV).
"""

from __future__ import annotations

import base64
import html
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path

__all__ = ["write_results_json", "write_summary_page"]

_STYLE = (
    "body{font-family:sans-serif;max-width:72em;margin:2em auto;padding:0 1em}"
    "pre{background:#f6f6f6;padding:1em;overflow-x:auto}"
    "img{max-width:100%;border:1px solid #ddd;margin:0.5em 0}"
)


def write_results_json(directory: str | Path, entry: dict) -> Path:
    """Write ``directory/results.json`` — the layout-1 document
    (``flightid.results.results_document``) with the one ``entry``, strict JSON
    (``flightid.jsonout``), UTF-8 — and return its path."""
    from flightid.jsonout import dumps
    from flightid.results import results_document

    path = Path(directory) / "results.json"
    path.write_text(dumps(results_document([entry])) + "\n", encoding="utf-8")
    return path


def write_summary_page(
    directory: str | Path,
    summary: str,
    figures: Sequence[str | Path] = (),
    files: Sequence[str | Path] = (),
    title: str | None = None,
) -> Path:
    """Write ``directory/report.html`` and return its path.

    Args:
        directory: the result folder (exists).
        summary: the result's text summary, shown as it is printed.
        figures: PNG files to embed, in order (missing ones are skipped, not an error: a
            result may have drawn fewer figures).
        files: data files to link, relative to ``directory`` or absolute inside it.
        title: the page's heading; default the summary's first line (its title line).
    """
    from flightid._version import __version__

    directory = Path(directory)
    if title is None:
        title = summary.splitlines()[0] if summary else "flightid result"
    written = datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        f"<p>Written {written} by flightid {html.escape(__version__)}.</p>",
        "<h2>Summary</h2>",
        f"<pre>{html.escape(summary)}</pre>",
    ]
    images = [Path(f) for f in figures]
    images = [f if f.is_absolute() else directory / f for f in images]
    images = [f for f in images if f.is_file()]
    if images:
        parts.append("<h2>Figures</h2>")
        for figure in images:
            data = base64.b64encode(figure.read_bytes()).decode("ascii")
            parts.append(
                f'<p><img src="data:image/png;base64,{data}" alt="{html.escape(figure.stem)}"></p>'
            )
    links = [Path(f) for f in files]
    links = [f.relative_to(directory) if f.is_absolute() else f for f in links]
    if links:
        parts.append("<h2>Files</h2><ul>")
        for link in links:
            name = html.escape(link.as_posix())
            parts.append(f'<li><a href="{name}">{name}</a></li>')
        parts.append("</ul>")
    parts.append("</body></html>")
    path = directory / "report.html"
    path.write_text("\n".join(parts) + "\n", encoding="utf-8")
    return path
