"""Text summaries of estimation results."""

from __future__ import annotations

import numpy as np

__all__ = ["estimate_summary", "format_table"]


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


def estimate_summary(result) -> str:
    """Estimates, Cramér–Rao bounds, relative bounds, start values; cost and accounting."""
    rows = []
    for i, name in enumerate(result.names):
        value = result.values[i]
        if name in getattr(result, "at_bound", ()):
            rows.append([name, f"{value:.6g}", "-", "-", f"{result.initial[i]:.6g}", "at bound"])
        elif result.free[i]:
            std = result.std[i]
            relative = abs(std / value) * 100 if value != 0 and np.isfinite(std) else np.inf
            rows.append(
                [
                    name,
                    f"{value:.6g}",
                    f"{std:.3g}",
                    f"{relative:.2f}" if np.isfinite(relative) else "-",
                    f"{result.initial[i]:.6g}",
                    "",
                ]
            )
        else:
            rows.append([name, f"{value:.6g}", "-", "-", f"{result.initial[i]:.6g}", "fixed"])
    head = [
        f"flightid output-error estimate — {result.model.name}",
        f"solver {result.solver}, noise policy {result.noise_policy}, integration {result.method}",
        f"status: {result.status} — {result.message}",
        f"cost J = {result.cost:.6g}   iterations {result.iterations}   "
        f"equivalent evaluations {result.equivalent_evaluations} "
        f"(+{result.accuracy_evaluations} for the information matrix)   "
        f"wall time {result.wall_time_s:.3g} s",
        f"optimality: the next Gauss–Newton step is {result.optimality_sigma:.2g} σ long "
        "(central differences)",
        "",
    ]
    headers = ["parameter", "estimate", "CR bound", "rel. %", "start", ""]
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
    return "\n".join(head) + table + "\n\n" + noise
