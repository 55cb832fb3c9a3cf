"""The carpet plots of the global-model guide: the JSBSim F-16 study's models of C_L, C_D
and C_m against α at four Mach numbers, with the interval of the coefficient itself, the
simulator's truth and the data flown near each Mach number.

    PYTHONPATH=src python docs/globalmodel_carpets.py     # runs the study (≈ 20 s, jsbsim)

Writes ``docs/figures/globalmodel_carpet_{CL,CD,Cm}.svg`` (drawn by
``flightid.report.svg_axes``, as the report's figures are). The study
(``bench/globalmodel_jsbsim.py --carpets``) gives, on its grid, the model's value, its
intervals, the support flag and the truth; the figures show the global-residual-variance
model.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from flightid.report import svg_axes as ax  # noqa: E402
from flightid.report.svg_axes import Panel, PanelText  # noqa: E402

MACHS = (0.4, 0.6, 0.8, 1.0)
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728")
# data shown with a curve: samples within this Mach of it
DATA_MACH = 0.025


def carpet(carpets: dict, coefficient: str) -> str:
    """One coefficient's carpet as SVG text."""
    alpha = np.asarray(carpets["alpha_deg"], dtype=float)
    machs = np.asarray(carpets["Mach"], dtype=float)
    model = carpets["coefficients"]["global"][coefficient]
    data = carpets["data"]
    rows = [int(np.argmin(np.abs(machs - m))) for m in MACHS]
    # the axis spans the truth and the model inside its support (the extrapolation is clipped)
    inside = ~np.asarray(model["outside"], dtype=bool)[rows]
    shown = np.concatenate(
        [
            np.asarray(model["truth"], dtype=float)[rows].ravel(),
            np.asarray(model["value"], dtype=float)[rows][inside],
        ]
    )
    scale = ax.y_scale(shown[np.isfinite(shown)], 5)
    width, height, top = 7.6 * ax.PX_PER_IN, 3.8 * ax.PX_PER_IN, 64.0
    left = ax.y_label_margin([scale])
    ticks = ax.nice_ticks(float(alpha[0]), float(alpha[-1]), 8)
    labels, _ = ax.tick_labels(ticks)
    panel = Panel(left, top, width - left - 20.0, height, float(alpha[0]), float(alpha[-1]), scale)
    data_alpha = np.asarray(data["alpha_deg"], dtype=float)
    data_mach = np.asarray(data["Mach"], dtype=float)
    data_value = np.asarray(data[coefficient], dtype=float)
    entries = []
    for colour, mach, row in zip(COLOURS, MACHS, rows, strict=True):
        value = np.asarray(model["value"][row], dtype=float)
        outside = np.asarray(model["outside"][row], dtype=bool)
        low = np.where(outside, np.nan, np.asarray(model["function_lower"][row], dtype=float))
        high = np.where(outside, np.nan, np.asarray(model["function_upper"][row], dtype=float))
        ax.band_between(panel, alpha, low, high, colour, 0.25)
        near = np.abs(data_mach - mach) <= DATA_MACH
        ax.markers(panel, data_alpha[near], data_value[near], "#9a9a9a", 4.0)
        ax.polyline(panel, alpha, np.where(outside, np.nan, value), colour, 1.6)
        dashed = outside | np.roll(outside, 1) | np.roll(outside, -1)
        ax.polyline(panel, alpha, np.where(dashed, value, np.nan), colour, 1.2, dash="5 3")
        # the truth: a thin dotted line of the curve's colour
        truth = np.asarray(model["truth"][row], dtype=float)
        ax.polyline(panel, alpha, truth, colour, 1.0, dash="1.5 1.5")
        entries.append(("line", colour, f"Mach {mach:g}"))
    entries.append(("dash", "#404040", "JSBSim truth (dotted)"))
    text = PanelText(f"{coefficient} [–]", "", "alpha [deg]", True, tuple(entries))
    title = (
        f"F-16 (JSBSim): global model of {coefficient}, shaded: 95 % interval of the coefficient"
    )
    notes = (
        "dashed: outside the data's support; grey +: data within Mach ±0.025 of a curve;",
        "elevator at the trim schedule, q̂ = 0, leading-edge flap as the flight controls set it",
    )
    body = [
        f"<text x='{left:.1f}' y='20' font-size='{ax.TITLE_PX}'>{ax.escape(title)}</text>",
        ax.render_panel(panel, ticks, labels, text),
    ]
    for k, note in enumerate(notes):
        body.append(
            f"<text x='{left:.1f}' y='{top + height + 48.0 + 14.0 * k:.1f}' "
            f"font-size='{ax.TICK_PX}'>{ax.escape(note)}</text>"
        )
    return ax.document(width, top + height + 76.0, body)


def main() -> int:
    with tempfile.TemporaryDirectory() as scratch:
        path = Path(scratch) / "carpets.json"
        subprocess.run(
            [sys.executable, str(ROOT / "bench" / "globalmodel_jsbsim.py"), "--carpets", str(path)],
            check=False,  # the study exits 1 on a FAIL line; its carpets are written anyway
            stdout=subprocess.DEVNULL,
            env={**os.environ, "PYTHONPATH": str(ROOT / "src")},
        )
        carpets = json.loads(path.read_text(encoding="utf-8"))
    for coefficient in ("CL", "CD", "Cm"):
        target = ROOT / "docs" / "figures" / f"globalmodel_carpet_{coefficient}.svg"
        target.write_text(carpet(carpets, coefficient), encoding="utf-8")
        print(f"{target.relative_to(ROOT)}: {target.stat().st_size // 1024} KB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
