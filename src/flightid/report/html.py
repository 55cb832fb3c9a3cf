"""HTML report of a case run: estimates with bounds, fits, residuals, convergence, correlation.

``write_report(run, out_dir)`` writes (all at once, see ``flightid.report.folder``)

    out_dir/results.json     {"results": [entry]} (the JSON contract, see flightid.cli.run;
                             strict JSON, see flightid.report.jsonout)
    out_dir/estimates.csv    name, value, CR bound, interval, start, free (and, with an
                             accuracy assessment, the profile and search limits)
    out_dir/figures/*.png    measured vs predicted and residuals per maneuver, prediction
                             maneuvers, convergence history, correlation matrix
    out_dir/report.html      everything above on one page, and the accuracy assessment when
                             the run has one (CR, profile and search intervals, N_φ)

Intervals: θ̂_j ± k·z_{(1+c)/2}·σ_j with σ_j the Cramér–Rao bound, c the confidence level and
k the ``bound_factor`` of the case (1 by default; flight-test practice often uses 3–5 because
CR bounds of real data are optimistic). The report only reads results.
"""

from __future__ import annotations

import csv
import html
from pathlib import Path

import numpy as np

__all__ = ["write_report", "write_files", "interval_half_widths"]


def interval_half_widths(std: np.ndarray, confidence: float, bound_factor: float) -> np.ndarray:
    """k·z·σ: half widths of the individual intervals (normal quantile z at (1+c)/2)."""
    from scipy.stats import norm

    z = float(norm.ppf(0.5 * (1.0 + confidence)))
    return bound_factor * z * np.asarray(std, dtype=float)


# ------------------------------------------------------------------------------ figures


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _fit_figure(path: Path, title: str, time, measured, predicted, names, units) -> None:
    plt = _plt()
    n = len(names)
    fig, axes = plt.subplots(n, 2, figsize=(11, 1.8 * n + 0.8), sharex=True, squeeze=False)
    for j, name in enumerate(names):
        ax = axes[j, 0]
        ax.plot(time, measured[:, j], color="0.45", lw=1.0, label="measured")
        ax.plot(time, predicted[:, j], color="tab:red", lw=1.0, label="model")
        unit = units.get(name, "")
        ax.set_ylabel(f"{name}" + (f" [{unit}]" if unit else ""), fontsize=8)
        ax.tick_params(labelsize=7)
        res = axes[j, 1]
        res.plot(time, measured[:, j] - predicted[:, j], color="tab:blue", lw=0.8)
        res.axhline(0.0, color="k", lw=0.5)
        res.tick_params(labelsize=7)
        if j == 0:
            ax.set_title("measured vs model", fontsize=9)
            res.set_title("residual", fontsize=9)
            ax.legend(fontsize=7, loc="best")
    axes[-1, 0].set_xlabel("time [s]", fontsize=8)
    axes[-1, 1].set_xlabel("time [s]", fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _convergence_figure(path: Path, estimate) -> None:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 3.2))
    costs = np.asarray(estimate.cost_history, dtype=float)
    evaluations = np.asarray(estimate.evaluation_history, dtype=float)
    x = evaluations if evaluations.size == costs.size else np.arange(costs.size)
    ax.semilogy(x, costs, "o-", ms=3)
    ax.set_xlabel("equivalent evaluations" if evaluations.size == costs.size else "pass")
    ax.set_ylabel("cost J")
    ax.set_title(f"convergence ({estimate.solver}, {estimate.status})", fontsize=9)
    ax.grid(True, which="both", lw=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _correlation_figure(path: Path, estimate) -> None:
    plt = _plt()
    corr = np.asarray(estimate.correlation, dtype=float)
    names = estimate.free_names
    size = max(4.0, 0.35 * len(names) + 2)
    fig, ax = plt.subplots(figsize=(size + 1, size))
    image = ax.imshow(corr, vmin=-1, vmax=1, cmap="RdBu_r")
    ax.set_xticks(range(len(names)), names, rotation=90, fontsize=7)
    ax.set_yticks(range(len(names)), names, fontsize=7)
    fig.colorbar(image, ax=ax, shrink=0.8)
    ax.set_title("correlation of the estimates", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name) or "maneuver"


def write_figures(run, directory: Path) -> dict[str, list[str]]:
    """Write the PNG figures; returns {kind: [relative paths]}."""
    directory.mkdir(parents=True, exist_ok=True)
    est = run.estimate
    names = list(est.output_names)
    units = {}
    for m in run.maneuvers:
        units.update(m.units)
    figures: dict[str, list[str]] = {"fits": [], "prediction": [], "other": []}
    for k, maneuver in enumerate(run.maneuvers):
        rows = est.maneuver_index == k
        path = directory / f"fit_{k + 1}_{_safe(maneuver.name)}.png"
        _fit_figure(
            path,
            f"{run.case.title} — maneuver {maneuver.name}",
            est.time[rows],
            est.measured[rows],
            est.predicted[rows],
            names,
            units,
        )
        figures["fits"].append(f"figures/{path.name}")
    for p in run.predictions:
        path = directory / f"prediction_{_safe(p.name)}.png"
        _fit_figure(
            path,
            f"prediction on {p.name}",
            p.time,
            p.measured,
            p.predicted,
            list(p.output_names),
            units,
        )
        figures["prediction"].append(f"figures/{path.name}")
    _convergence_figure(directory / "convergence.png", est)
    figures["other"].append("figures/convergence.png")
    if len(est.free_names) > 1:
        _correlation_figure(directory / "correlation.png", est)
        figures["other"].append("figures/correlation.png")
    return figures


# ------------------------------------------------------------------------------ tables


def _estimate_rows(run) -> list[dict]:
    est = run.estimate
    confidence = float(run.case.accuracy.get("confidence", 0.95))
    factor = float(run.case.accuracy.get("bound_factor", 1.0))
    half = interval_half_widths(np.where(est.free, est.std, 0.0), confidence, factor)
    rows = []
    for i, name in enumerate(est.names):
        free = bool(est.free[i])
        value, std = float(est.values[i]), float(est.std[i])
        rows.append(
            {
                "name": name,
                "value": value,
                "cr_bound": std if free else None,
                "relative_percent": 100 * std / abs(value) if free and value != 0 else None,
                "lower": value - half[i] if free else None,
                "upper": value + half[i] if free else None,
                "initial": float(est.initial[i]),
                "free": free,
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


def _table(headers: list[str], rows: list[list[str]], classes: list[str] | None = None) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = []
    for i, row in enumerate(rows):
        cls = f' class="{classes[i]}"' if classes and classes[i] else ""
        body.append(f"<tr{cls}>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em; max-width: 1200px; color: #222; }
table { border-collapse: collapse; margin: 0.6em 0 1.2em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 3px 8px; text-align: right; }
th { background: #f0f0f0; } td:first-child { text-align: left; font-family: monospace; }
tr.fixed td { color: #888; } td.high { background: #fbd5d5; }
.ok { color: #176117; } .bad { color: #a11; } img { max-width: 100%; border: 1px solid #ddd; }
"""


def render_html(run, figures: dict[str, list[str]]) -> str:
    est = run.estimate
    case = run.case
    confidence = float(case.accuracy.get("confidence", 0.95))
    factor = float(case.accuracy.get("bound_factor", 1.0))
    threshold = float(case.accuracy.get("correlation_warning", 0.9))
    parts = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'>",
        f"<title>{html.escape(case.title)}</title><style>{_STYLE}</style></head><body>",
        f"<h1>{html.escape(case.title)}</h1>",
    ]
    if case.description:
        parts.append(f"<p>{html.escape(case.description)}</p>")
    status_class = "ok" if est.converged else "bad"
    parts.append(
        f"<p class='{status_class}'><b>{html.escape(est.status)}</b>: "
        f"{html.escape(est.message)}</p>"
    )
    summary = [
        ["case file", html.escape(str(case.path))],
        ["model", html.escape(run.model_description)],
        [
            "maneuvers",
            html.escape(", ".join(f"{m.name} ({m.n_samples} × {m.dt:g} s)" for m in run.maneuvers)),
        ],
        ["solver / noise / integration", f"{est.solver} / {est.noise_policy} / {est.method}"],
        ["cost J", _fmt(est.cost)],
        ["iterations", str(est.iterations)],
        [
            "equivalent evaluations",
            f"{est.equivalent_evaluations} (+{est.accuracy_evaluations} for the information "
            "matrix)",
        ],
        ["wall time", f"{est.wall_time_s:.2f} s"],
    ]
    parts.append("<h2>Run</h2>" + _table(["item", "value"], summary))

    rows, classes = [], []
    for row in _estimate_rows(run):
        rows.append(
            [
                html.escape(row["name"]),
                _fmt(row["value"]),
                _fmt(row["cr_bound"], 3),
                _fmt(row["relative_percent"], 3),
                _fmt(row["lower"]),
                _fmt(row["upper"]),
                _fmt(row["initial"]),
                "free" if row["free"] else "fixed",
            ]
        )
        classes.append("" if row["free"] else "fixed")
    interval = f"{100 * confidence:g} % interval" + (f" (×{factor:g})" if factor != 1 else "")
    parts.append(
        "<h2>Estimates</h2>"
        + _table(
            [
                "parameter",
                "estimate",
                "CR bound σ",
                "σ/|θ| %",
                f"{interval} low",
                "high",
                "start",
                "",
            ],
            rows,
            classes,
        )
    )
    if getattr(run, "accuracy", None) is not None:
        parts.append(_accuracy_section(run))
    noise_rows = [
        [html.escape(n), _fmt(r, 4), _fmt(e, 4)]
        for n, r, e in zip(est.output_names, est.r_diag, est.fit_error(), strict=True)
    ]
    parts.append("<h2>Outputs</h2>" + _table(["output", "R (variance)", "fit RMS"], noise_rows))
    if run.predictions:
        parts.append("<h2>Prediction check</h2>")
        for k, p in enumerate(run.predictions):
            pr = [
                [html.escape(n), _fmt(e, 4), _fmt(r, 4)]
                for n, e, r in zip(p.output_names, p.rms, p.r2, strict=True)
            ]
            parts.append(
                f"<p>maneuver <b>{html.escape(p.name)}</b> (not used for estimation)</p>"
                + _table(["output", "RMS error", "R²"], pr)
            )
            parts.extend(f"<p><img src='{f}'></p>" for f in figures["prediction"][k : k + 1])
    parts.append("<h2>Measured vs model and residuals</h2>")
    parts.extend(f"<p><img src='{f}'></p>" for f in figures["fits"])
    parts.append("<h2>Convergence</h2>")
    parts.append(
        _table(["pass", "cost J"], [[str(i), _fmt(c)] for i, c in enumerate(est.cost_history)])
    )
    if "figures/convergence.png" in figures["other"]:
        parts.append("<p><img src='figures/convergence.png' style='max-width:600px'></p>")
    corr = np.asarray(est.correlation, dtype=float)
    if corr.size > 1:
        names = est.free_names
        crow = []
        for i, name in enumerate(names):
            cells = [html.escape(name)]
            for j in range(len(names)):
                v = corr[i, j]
                high = i != j and np.isfinite(v) and abs(v) > threshold
                text = _fmt(v, 2)
                cells.append(f"<span class='high'>{text}</span>" if high else text)
            crow.append(cells)
        high_pairs = [
            f"{names[i]}–{names[j]} ({corr[i, j]:.3f})"
            for i in range(len(names))
            for j in range(i + 1, len(names))
            if np.isfinite(corr[i, j]) and abs(corr[i, j]) > threshold
        ]
        parts.append("<h2>Correlation matrix</h2>")
        if high_pairs:
            parts.append(
                f"<p class='bad'>|correlation| above {threshold:g}: "
                f"{html.escape(', '.join(high_pairs))}</p>"
            )
        parts.append(_table([""] + [html.escape(n) for n in names], crow))
        if "figures/correlation.png" in figures["other"]:
            parts.append("<p><img src='figures/correlation.png' style='max-width:700px'></p>")
    parts.append("</body></html>")
    return "\n".join(parts)


def _interval(pair) -> str:
    """ "[lower, upper]"; an open side (no limit found) shows as ∓∞, an unknown one as —."""
    lower, upper = (float(v) for v in pair)
    low = "−∞" if lower == -np.inf else _fmt(lower) if np.isfinite(lower) else "—"
    high = "+∞" if upper == np.inf else _fmt(upper) if np.isfinite(upper) else "—"
    return f"[{low}, {high}]"


def _accuracy_section(run) -> str:
    """Estimate, CR, profile and search intervals of every free parameter, with N_φ."""
    acc = run.accuracy
    ran = [m for m in ("profile", "search") if getattr(acc, m) is not None]
    headers = ["parameter", "estimate", "s·σ", "CR interval"]
    headers += [f"{m} interval" for m in ran]
    rows = []
    for j, name in enumerate(acc.names):
        row = [html.escape(name), _fmt(acc.center[j]), _fmt(acc.std_scaled[j], 3)]
        row.append(_interval(acc.ci_cr[j]))
        row += [_interval(getattr(acc, f"ci_{m}")[j]) for m in ran]
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


def write_files(run, directory: Path) -> Path:
    """Write results.json, estimates.csv, figures and report.html into ``directory`` (which
    exists); returns the HTML path. ``write_report`` calls this on a temporary folder.

    results.json is strict JSON (``flightid.report.jsonout``: NaN / ±inf become null, listed
    under ``"nonfinite"``). ``[output] figures = false`` skips the PNG figures, ``report =
    false`` the HTML page.
    """
    from flightid.report.jsonout import dumps

    directory = Path(directory)
    (directory / "results.json").write_text(
        dumps({"results": [run.to_dict()]}) + "\n", encoding="utf-8"
    )
    write_csv(run, directory / "estimates.csv")
    figures = (
        write_figures(run, directory / "figures")
        if run.case.output.get("figures", True)
        else {"fits": [], "prediction": [], "other": []}
    )
    path = directory / "report.html"
    if run.case.output.get("report", True):
        path.write_text(render_html(run, figures), encoding="utf-8")
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
