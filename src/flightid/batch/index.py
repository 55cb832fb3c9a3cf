"""``DIR/index.html``: one page linking every case's report, with its status.

A table with one line per case (name, flight-condition columns, status, iterations of the
outcome, the error of a failed case, a link to ``cases/<name>/report.html``) and the carpet
plots below it (links to ``plots/*.png``). The page uses relative links only, so the batch
folder can be moved or served as it is.
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from pathlib import Path
from typing import Any
from urllib.parse import quote

from flightid.batch.table import condition_columns

__all__ = ["write_index"]

_STYLE = (
    "body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}"
    "td,th{border:1px solid #ccc;padding:3px 8px;text-align:left}"
    ".failed{background:#fdd}.ok{background:#efe}img{max-width:45%;margin:4px}"
)


def write_index(
    records: Sequence[dict[str, Any]], out: Path, plots: Sequence[Path] = (), engine: str = ""
) -> Path:
    """Write ``out/index.html`` for the case records; returns its path."""
    conditions = condition_columns(records)
    head = ["case", *conditions, "status", "converged", "report", "error"]
    lines = []
    for r in records:
        name = r["case"]
        failed = r.get("status") == "failed"
        report = r.get("report")
        link = (
            f"<a href='cases/{quote(name)}/{quote(report)}'>report</a>"
            if report and not failed
            else "—"
        )
        cells = [html.escape(name)]
        cells += [html.escape(str(r.get("conditions", {}).get(c, ""))) for c in conditions]
        cells += [
            html.escape(str(r.get("status", ""))),
            "yes" if r.get("converged") else "no",
            link,
            html.escape(r.get("error") or ""),
        ]
        row = "".join(f"<td>{c}</td>" for c in cells)
        lines.append(f"<tr class='{'failed' if failed else 'ok'}'>{row}</tr>")
    n_failed = sum(r.get("status") == "failed" for r in records)
    figures = "".join(
        f"<a href='plots/{quote(p.name)}'><img alt='{html.escape(p.stem)}' "
        f"src='plots/{quote(p.name)}'></a>"
        for p in plots
    )
    page = (
        "<!DOCTYPE html><html><head><meta charset='utf-8'><title>flightid batch</title>"
        f"<style>{_STYLE}</style></head><body><h1>flightid batch</h1>"
        f"<p>{len(records)} case(s), {n_failed} failed"
        + (f"; engine: {html.escape(engine)}" if engine else "")
        + ". Table: <a href='estimates.csv'>estimates.csv</a>"
        + (
            " (<a href='estimates.parquet'>Parquet</a>)"
            if (out / "estimates.parquet").is_file()
            else ""
        )
        + ".</p>"
        "<table><tr>"
        + "".join(f"<th>{html.escape(h)}</th>" for h in head)
        + "</tr>"
        + "".join(lines)
        + "</table>"
        + (f"<h2>Carpet plots</h2>{figures}" if figures else "")
        + "</body></html>\n"
    )
    path = out / "index.html"
    tmp = out / ".index.html.tmp"
    tmp.write_text(page, encoding="utf-8")
    tmp.replace(path)
    return path
