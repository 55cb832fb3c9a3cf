"""One figure per result, for the results' ``plot()`` (``flightid.results.ResultSurface``).

Each function returns a matplotlib ``Figure`` drawn with the object interface on an Agg
canvas (no pyplot, no global backend change); the caller saves or shows it.

    Estimate            measured and predicted outputs against time (left) and residuals
                        ν = z − y (right), one row per output, units on the axes
    AccuracyResult      every held interval of each free parameter, in standard errors
                        about θ̂: (limit − θ̂_j)/(s·σ_j), one row per parameter
    LeastSquaresResult  response z = fitted + residual and the fit against sample number,
                        and the residuals
    StepwiseResult      R² and PSE of the model left by each step, the selected step marked
"""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from flightid.errors import InputTypeError, describe

__all__ = [
    "accuracy_figure",
    "estimate_figure",
    "figure_of",
    "least_squares_figure",
    "stepwise_figure",
]


def _label(name: str, unit: str) -> str:
    return f"{name} [{unit}]" if unit else name


def _figure(width: float, height: float) -> Figure:
    figure = Figure(figsize=(width, height))
    FigureCanvasAgg(figure)
    return figure


def estimate_figure(estimate) -> Figure:
    """Measured vs predicted outputs and residuals of an ``Estimate`` (maneuvers one after
    the other on the time axis, separated by gaps)."""
    names = list(estimate.output_names)
    units = estimate.output_unit_map
    figure = _figure(10.0, 1.8 * len(names) + 0.8)
    axes = figure.subplots(len(names), 2, sharex=True, squeeze=False)
    index = np.asarray(estimate.maneuver_index)
    for j, name in enumerate(names):
        fit, residual = axes[j, 0], axes[j, 1]
        for k in np.unique(index):
            rows = index == k
            t = estimate.time[rows]
            first = k == index[0]
            fit.plot(
                t,
                estimate.measured[rows, j],
                color="0.45",
                lw=1.0,
                label="measured" if first else None,
            )
            fit.plot(
                t,
                estimate.predicted[rows, j],
                color="tab:red",
                lw=1.0,
                label="model" if first else None,
            )
            residual.plot(t, estimate.residuals[rows, j], color="tab:blue", lw=0.8)
        residual.axhline(0.0, color="k", lw=0.5)
        fit.set_ylabel(_label(name, units.get(name, "")), fontsize=8)
        residual.set_ylabel(_label(f"ν {name}", units.get(name, "")), fontsize=8)
        for ax in (fit, residual):
            ax.tick_params(labelsize=7)
            ax.grid(True, linewidth=0.4, alpha=0.5)
    axes[0, 0].set_title("measured vs model", fontsize=9)
    axes[0, 1].set_title("residual", fontsize=9)
    axes[0, 0].legend(fontsize=7, loc="best")
    for ax in axes[-1]:
        ax.set_xlabel("time [s]", fontsize=8)
    figure.suptitle(f"{estimate.model.name}: {estimate.solver}, {estimate.status}", fontsize=10)
    figure.tight_layout()
    return figure


def accuracy_figure(accuracy) -> Figure:
    """Every held interval of each free parameter in standard errors about θ̂."""
    names = list(accuracy.names)
    methods = list(accuracy.methods)
    figure = _figure(7.5, 0.5 * len(names) * max(len(methods), 1) * 0.35 + 1.6)
    ax = figure.subplots()
    scale = np.where(
        np.isfinite(accuracy.std_scaled) & (accuracy.std_scaled > 0), accuracy.std_scaled, 1.0
    )
    for m, method in enumerate(methods):
        table = accuracy.conf_int(method=method)
        # position (limit − θ̂_j)/(s·σ_j): the CR interval reads ±t, the others compare with it
        lower = (table[:, 0] - accuracy.center) / scale
        upper = (table[:, 1] - accuracy.center) / scale
        y = np.arange(len(names)) + (m - (len(methods) - 1) / 2) * 0.8 / max(len(methods), 1)
        finite = np.isfinite(lower) & np.isfinite(upper)
        ax.hlines(y[finite], lower[finite], upper[finite], lw=2.5, color=f"C{m}", label=method)
    ax.axvline(0.0, color="k", lw=0.6)
    ax.set_yticks(range(len(names)), names, fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("(limit − θ̂) / (s·σ), standard errors", fontsize=8)
    ax.set_title(
        f"{accuracy.kind} {accuracy.level:g} intervals ({accuracy.distribution})", fontsize=9
    )
    ax.legend(fontsize=7, loc="best")
    ax.grid(True, axis="x", linewidth=0.4, alpha=0.5)
    figure.tight_layout()
    return figure


def least_squares_figure(fit, title: str = "least-squares fit") -> Figure:
    """Response and fit against sample number, and the residuals."""
    figure = _figure(8.0, 4.5)
    top, bottom = figure.subplots(2, 1, sharex=True)
    n = np.arange(fit.n_samples)
    top.plot(n, fit.fitted + fit.residuals, color="0.45", lw=1.0, label="response z")
    top.plot(n, fit.fitted, color="tab:red", lw=1.0, label="fit Xθ̂")
    top.legend(fontsize=7, loc="best")
    top.set_title(f"{title}: R² = {fit.r2:.4f}", fontsize=9)
    bottom.plot(n, fit.residuals, color="tab:blue", lw=0.8)
    bottom.axhline(0.0, color="k", lw=0.5)
    bottom.set_ylabel("residual", fontsize=8)
    bottom.set_xlabel("sample", fontsize=8)
    for ax in (top, bottom):
        ax.tick_params(labelsize=7)
        ax.grid(True, linewidth=0.4, alpha=0.5)
    figure.tight_layout()
    return figure


def stepwise_figure(result) -> Figure:
    """R² and PSE of the model after each step; the selected model's step marked."""
    figure = _figure(7.5, 4.5)
    top, bottom = figure.subplots(2, 1, sharex=True)
    numbers = [s.number for s in result.steps]
    top.plot(numbers, [s.r2 for s in result.steps], "o-", color="tab:blue")
    bottom.plot(numbers, [s.pse for s in result.steps], "o-", color="tab:red")
    selected = set(result.selected)
    for s in result.steps:
        if set(s.terms) == selected:
            bottom.axvline(s.number, color="k", lw=0.6, ls="--")
    top.set_ylabel("R²", fontsize=8)
    bottom.set_ylabel("PSE", fontsize=8)
    bottom.set_xlabel("step", fontsize=8)
    top.set_title(
        f"stepwise regression for {result.response}: {', '.join(result.selected)}", fontsize=9
    )
    for ax in (top, bottom):
        ax.tick_params(labelsize=7)
        ax.grid(True, linewidth=0.4, alpha=0.5)
    figure.tight_layout()
    return figure


def figure_of(result) -> Figure:
    """The figure of any flightid result (dispatch on its type)."""
    from flightid.accuracy.result import AccuracyResult
    from flightid.estimation.result import Estimate
    from flightid.regression.least_squares import LeastSquaresResult
    from flightid.regression.stepwise import StepwiseResult

    if isinstance(result, Estimate):
        return estimate_figure(result)
    if isinstance(result, AccuracyResult):
        return accuracy_figure(result)
    if isinstance(result, StepwiseResult):
        return stepwise_figure(result)
    if isinstance(result, LeastSquaresResult):
        return least_squares_figure(result)
    raise InputTypeError(
        "result: expected an Estimate, AccuracyResult, LeastSquaresResult or StepwiseResult, "
        f"got {describe(result)}"
    )
