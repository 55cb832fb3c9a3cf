"""The modes (and, for a stated airplane class and flight-phase category, the flying
qualities) of an estimate, as the text summary, results.json and the report show them.

Operating point: a run linearizes at the initial state and the mean inputs of its first
estimation maneuver (``Estimate.linearize(at=maneuver)``). ``Estimate.summary()``, which has
no data, shows modes only for a model linear in its states and inputs — there A, B, C, D are
the same at every point, so the initial state with inputs 0 gives the modes exactly; for a
nonlinear model it says where to find them instead of showing the modes of an arbitrary
point. Linearity is tested by linearizing at a second point (every state and input moved by
0.5·max(|value|, 1)) and comparing the matrices (relative 1e-6).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flightid.export.flying_qualities import FlyingQualities, flying_qualities

__all__ = [
    "ModalAnalysis",
    "linear_in_states_and_inputs",
    "modal_analysis",
    "mode_rows",
    "modes_text",
    "summary_block",
]

LINEARITY_TOLERANCE = 1e-6


@dataclass(frozen=True)
class ModalAnalysis:
    """A linear model of an estimate, its modes and (when asked) its flying qualities."""

    linear: Any  # flightid.model.linearization.LinearModel
    modes: Any  # flightid.model.modes.Modes
    flying_qualities: FlyingQualities | None = None

    def summary(self) -> str:
        lines = [modes_text(self.modes, self.linear.operating_point)]
        if self.flying_qualities is not None:
            # the linear model's notes stand under the modes already
            shown = {f"note: {n}" for n in self.modes.notes}
            quality = self.flying_qualities.summary().splitlines()
            lines += ["", *(line for line in quality if line not in shown)]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """results.json's ``modes`` entry (docs/schema/results.schema.json)."""
        linear = self.linear
        return {
            "operating_point": {
                "description": linear.operating_point,
                "states": list(linear.states),
                "x": [float(v) for v in linear.x0],
                "inputs": list(linear.inputs),
                "u": [float(v) for v in linear.u0],
            },
            "modes": self.modes.to_dict(),
            "notes": list(self.modes.notes),
            "flying_qualities": None
            if self.flying_qualities is None
            else self.flying_qualities.to_dict(),
        }


def _cell(value: float, sigma: float) -> str:
    from flightid.numbers import format_with_sigma

    if not math.isfinite(value):
        return "-"
    text, sigma_text = format_with_sigma(value, sigma, missing="")
    return f"{text} ± {sigma_text}" if sigma_text else text


def _table(headers: list[str], rows: list[list[str]]) -> str:
    """Fixed-width columns: the first left-aligned, the others right-aligned."""
    widths = [max(len(r[i]) for r in [headers, *rows]) for i in range(len(headers))]

    def line(cells: list[str]) -> str:
        pairs = enumerate(zip(cells, widths, strict=True))
        return "  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in pairs)

    return "\n".join([line(headers), "  ".join("-" * w for w in widths), *map(line, rows)])


def modes_text(modes, operating_point: str = "") -> str:
    """The modes as a table: ω_n and ζ (oscillatory modes) or τ (real ones) and the time to
    half or double amplitude, each ± 1σ at σ's decimal place."""
    rows = mode_rows(modes)
    head = "modes (± 1σ)" + (f" at {operating_point}" if operating_point else "")
    table = _table(MODE_HEADERS, rows)
    notes = [f"note: {n}" for n in modes.notes]
    return "\n".join([head, table, *notes])


MODE_HEADERS = ["mode", "ω_n [rad/s]", "ζ [–]", "τ [s]", "time to half/double [s]"]


def mode_rows(modes) -> list[list[str]]:
    """One row per mode: name, ω_n, ζ, τ, time to half (t½) or double (t2), each ± 1σ."""
    rows = []
    for mode in modes:
        halving = math.isfinite(mode.time_to_half)
        time = (mode.time_to_half, mode.time_to_half_std) if halving else (
            mode.time_to_double, mode.time_to_double_std)  # fmt: skip
        rows.append(
            [
                mode.name,
                _cell(mode.natural_frequency, mode.natural_frequency_std),
                _cell(mode.damping_ratio, mode.damping_ratio_std),
                _cell(mode.time_constant, mode.time_constant_std),
                ("t½ " if halving else "t2 ") + _cell(*time) if math.isfinite(time[0]) else "-",
            ]
        )
    return rows


def linear_in_states_and_inputs(estimate) -> bool:
    """Whether the estimated model's A, B, C, D are the same at the initial state with
    inputs 0 and at a second point (module docstring)."""
    from flightid.model.linearization import linearize

    model = estimate.model
    x = np.asarray(model.initial_state(np.asarray(estimate.values, dtype=float), 0), float)
    u = np.zeros(len(model.inputs))
    first = linearize(model, x, u)
    second = linearize(model, x + 0.5 * np.maximum(np.abs(x), 1.0), u + 0.5)
    for block in ("A", "B", "C", "D"):
        a, b = getattr(first, block), getattr(second, block)
        scale = max(float(np.max(np.abs(a), initial=0.0)), 1e-12)
        if not np.allclose(a, b, rtol=LINEARITY_TOLERANCE, atol=LINEARITY_TOLERANCE * scale):
            return False
    return True


def modal_analysis(estimate, at=None, settings: Mapping[str, Any] | None = None) -> ModalAnalysis:
    """The linear model of ``estimate`` at ``at`` (as ``Estimate.linearize``), its modes and,
    with ``settings`` (the case's ``[flying_qualities]``: class, category, optional speed
    [m/s], n_alpha [g/rad], include_unverified), the flying qualities."""
    linear = estimate.linearize(at=at)
    modes = linear.modes()
    quality = None
    if settings:
        quality = flying_qualities(
            linear,
            str(settings["class"]),
            str(settings["category"]),
            n_alpha=settings.get("n_alpha"),
            speed_m_s=settings.get("speed"),
            include_unverified=bool(settings.get("include_unverified", False)),
        )
    return ModalAnalysis(linear, modes, quality)


def summary_block(estimate) -> str:
    """The modes block of ``Estimate.summary()`` (module docstring), or "" for a model
    without states."""
    if not estimate.model.states:
        return ""
    try:
        if not linear_in_states_and_inputs(estimate):
            return (
                "modes: not shown here: the model is nonlinear in its states or inputs, so "
                "they depend on the operating point (Estimate.linearize(at=data).modes(); a "
                "case run's results.json and report give them at its first maneuver)"
            )
        analysis = modal_analysis(estimate)
    except (ValueError, TypeError, ArithmeticError) as error:
        # a summary never fails for its modes: say why they are missing
        return f"modes: not computed ({error})"
    return modes_text(analysis.modes, "the initial state, inputs 0 (the model is linear)")
