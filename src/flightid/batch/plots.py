"""Carpet plots of a batch: each derivative against a flight-condition column, ±σ bars.

One PNG per parameter, ``DIR/plots/<parameter>_vs_<column>.png``: the estimates of the cases
that finished (``status`` not ``failed``) at the case's value of the chosen column, with error
bars of ±σ, the default σ (the coloured-residual σ where the residuals are coloured, the
Cramér–Rao bound where they are white) as a wide grey bar and the Cramér–Rao σ as a narrow
capped bar inside it. An
engineer reads the envelope from them: a derivative should vary smoothly with the flight
condition; a point off the trend with a small σ is worth a look. Rendered with matplotlib's
Agg backend (no display needed).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from flightid.batch.plan import BatchError

__all__ = ["carpet_plots"]


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.\-]", "_", name)


def carpet_plots(
    rows: Sequence[dict[str, Any]], column: str, out: Path, dpi: int = 96
) -> list[Path]:
    """Write the carpet plots of ``rows`` (``flightid.batch.table.table_rows``) against
    ``column`` into ``out/plots/``; returns the files.

    Raises:
        BatchError: ``column`` is no numeric flight-condition column of the table.
    """
    ok = [r for r in rows if r.get("status") != "failed" and r.get("parameter")]
    if not any(column in r for r in rows):
        names = sorted({k for r in rows for k in r})
        raise BatchError(f"--plot-against {column!r}: no such column in the table ({names})")
    points: dict[str, list[tuple[float, float, float | None, float | None, str]]] = {}
    for r in ok:
        x, value = r.get(column), r.get("value")
        if isinstance(x, bool) or not isinstance(x, (int, float)) or value is None:
            continue
        points.setdefault(r["parameter"], []).append(
            (float(x), float(value), r.get("std"), r.get("std_cr"), r.get("unit") or "")
        )
    if not points:
        raise BatchError(f"--plot-against {column!r}: no finished case has a number in this column")
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    directory = out / "plots"
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for name, pts in points.items():
        pts.sort()
        xs = [p[0] for p in pts]
        ys = [p[1] for p in pts]
        sd = [p[2] if p[2] is not None else 0.0 for p in pts]
        # a record without the Cramér–Rao σ apart: its default σ is the Cramér–Rao σ
        cr = [p[3] if p[3] is not None else (p[2] or 0.0) for p in pts]
        fig = Figure(figsize=(5.0, 3.4))
        ax = fig.add_subplot()
        ax.errorbar(xs, ys, yerr=sd, fmt="none", ecolor="0.65", elinewidth=4, label="±σ (default)")
        ax.errorbar(xs, ys, yerr=cr, fmt="o", capsize=3, label="estimate ±σ (Cramér–Rao)")
        unit = pts[0][4]
        ax.set_xlabel(column)
        ax.set_ylabel(f"{name} ({unit})" if unit else name)
        ax.set_title(f"{name} against {column}")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        path = directory / f"{_safe(name)}_vs_{_safe(column)}.png"
        fig.savefig(path, dpi=dpi)
        written.append(path)
    return written
