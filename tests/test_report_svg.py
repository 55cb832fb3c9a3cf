"""The output-error report's figures written as SVG from the arrays
(``flightid.report.svg_axes``, ``flightid.report.svg_figures``): well-formed XML whose
drawn points map back to the arrays, round ticks (matplotlib's MaxNLocator as the reference)
that cover the data, peaks kept by the envelope, names escaped; the case key
``[output] figure_format`` and ``flightid run --figure-format``; no matplotlib imported by
an ``--out`` run with SVG figures."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from flightid.report import svg_axes
from flightid.report.svg_figures import autocorrelation_svg, cost_history_svg, maneuver_svg

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "examples" / "csv_walkthrough" / "my_case.toml"
NS = "{http://www.w3.org/2000/svg}"
BLUE, RED, DARK = "#1f77b4", "#d62728", "#404040"


def _panels(svg_text: str) -> list[ET.Element]:
    """The nested <svg> elements of the panels (their data limits as attributes)."""
    root = ET.fromstring(svg_text)
    return [e for e in root.iter(f"{NS}svg") if e.get("data-xlim")]


def _inverse(panel: ET.Element, px: np.ndarray, py: np.ndarray):
    """Panel pixels → data (the module docstring's transform); one pixel in data units."""
    x0, x1 = map(float, panel.get("data-xlim").split())
    y0, y1 = map(float, panel.get("data-ylim").split())
    width, height = float(panel.get("width")), float(panel.get("height"))
    x = x0 + px * (x1 - x0) / width
    y = y1 - py * (y1 - y0) / height
    return x, y, (x1 - x0) / width, (y1 - y0) / height


def _polyline(panel: ET.Element, colour: str) -> np.ndarray:
    lines = [e for e in panel.iter(f"{NS}polyline") if e.get("stroke") == colour]
    points = " ".join(e.get("points") for e in lines)
    return np.array([p.split(",") for p in points.split()], dtype=float)


def _maneuver(n: int = 300, steps: bool = False, seed: int = 2):
    rng = np.random.default_rng(seed)
    time = 100.0 + np.arange(n) * 0.05
    inputs = np.round(rng.normal(size=(n, 1)), 1)
    measured = np.column_stack([np.cumsum(rng.normal(size=n)), 1e-3 * rng.normal(size=n)])
    predicted = measured + 0.1 * rng.normal(size=(n, 2))
    svg = maneuver_svg(
        time, inputs, ["de"], measured, predicted, ["alpha", "q"], {"alpha": "rad"}, "m1", steps
    )
    return svg, time, inputs, measured, predicted


# ------------------------------------------------------------------------------ figures


def test_maneuver_lines_and_markers_map_back_to_the_arrays():
    svg, time, inputs, measured, predicted = _maneuver()
    panels = _panels(svg)
    # the input, then per output its response and residual panel
    assert len(panels) == 1 + 2 * 2
    t = time - time[0]
    for j in range(2):
        response, residual = panels[1 + 2 * j], panels[2 + 2 * j]
        # the predicted line: every sample (300 < the panel's pixels), within a pixel
        xy = _polyline(response, BLUE)
        x, y, dx, dy = _inverse(response, xy[:, 0], xy[:, 1])
        assert np.all(np.abs(x - t) <= dx) and np.all(np.abs(y - predicted[:, j]) <= dy)
        # the measured '+' markers: one path, "M x-2.5 y h5 m-2.5 -2.5 v5" per sample
        (marks,) = [e for e in response.iter(f"{NS}path") if e.get("stroke") == DARK]
        starts = np.array(re.findall(r"M([-\d.]+) ([-\d.]+)h", marks.get("d")), dtype=float)
        x, y, dx, dy = _inverse(response, starts[:, 0] + 2.5, starts[:, 1])
        assert np.all(np.abs(x - t) <= dx) and np.all(np.abs(y - measured[:, j]) <= dy)
        xy = _polyline(residual, RED)
        x, y, dx, dy = _inverse(residual, xy[:, 0], xy[:, 1])
        assert np.all(np.abs(y - (measured[:, j] - predicted[:, j])) <= dy)


def test_zero_order_hold_inputs_are_drawn_as_held_steps():
    svg, time, inputs, *_ = _maneuver(n=50, steps=True)
    xy = _polyline(_panels(svg)[0], "black")
    x, y, dx, dy = _inverse(_panels(svg)[0], xy[:, 0], xy[:, 1])
    # steps-post: (t_i, u_i), (t_{i+1}, u_i), (t_{i+1}, u_{i+1}), ...
    assert xy.shape[0] == 2 * 50 - 1
    t = time - time[0]
    assert np.all(np.abs(x[0::2] - t) <= dx) and np.all(np.abs(y[0::2] - inputs[:, 0]) <= dy)
    assert np.all(np.abs(x[1::2] - t[1:]) <= dx)
    assert np.all(np.abs(y[1::2] - inputs[:-1, 0]) <= dy)


def test_a_spike_survives_the_envelope_of_a_dense_line():
    n = 40_000
    time = np.arange(n) * 0.01
    rng = np.random.default_rng(4)
    measured = rng.normal(size=(n, 1)) * 0.01
    predicted = np.zeros((n, 1))
    predicted[12_345, 0] = 3.0  # one sample high
    svg = maneuver_svg(time, None, [], measured, predicted, ["a"], {}, "spike")
    response = _panels(svg)[0]
    xy = _polyline(response, BLUE)
    # far fewer points than samples: at most two per pixel column
    assert xy.shape[0] <= 2 * np.ceil(float(response.get("width")))
    x, y, dx, dy = _inverse(response, xy[:, 0], xy[:, 1])
    peak = np.argmax(y)
    assert abs(y[peak] - 3.0) <= dy and abs(x[peak] - time[12_345]) <= dx


def test_envelope_keeps_each_pixel_columns_min_and_max():
    rng = np.random.default_rng(8)
    n, bins = 9001, 437
    values = np.cumsum(rng.normal(size=n))
    values[[5, 4000, 8999]] += [50.0, -70.0, 90.0]
    kept = svg_axes.envelope_indices(values, bins)
    edges = (np.arange(bins + 1) * n) // bins
    for b in range(bins):
        inside = kept[(kept >= edges[b]) & (kept < edges[b + 1])]
        column = values[edges[b] : edges[b + 1]]
        assert values[inside].min() == column.min() and values[inside].max() == column.max()
    assert {5, 4000, 8999} <= set(kept.tolist())
    # the matplotlib figures decimate with the very same function
    from flightid.report import figures

    assert figures.envelope_indices is svg_axes.envelope_indices


def test_names_are_escaped_and_the_xml_is_well_formed():
    name, unit, title = 'a<b & "c"', "m/s^2 <x>", "t&<'>"
    n = 40
    time = np.arange(n) * 0.1
    values = np.linspace(0, 1, n)[:, None]
    texts = []
    for svg in (
        maneuver_svg(time, values, [name], values, values, [name], {name: unit}, title),
        autocorrelation_svg(np.linspace(1, 0, 10)[:, None], 0.1, 0.1, [name], 3),
        cost_history_svg([5.0, 3.0, 2.0], [2], title, [1.0, 0.5, 0.4]),
    ):
        root = ET.fromstring(svg)  # raises on a bare < or &
        texts += ["".join(e.itertext()) for e in root.iter(f"{NS}text")]
        assert "<b" not in svg and "a<" not in svg
    assert title in texts and f"{name} [m/s² <x>]" in texts
    # ρ = 1 … 0 in 10 lags: lags 1-8 outside the band ±0.1
    assert f"{name}: 8 of 9 lags outside" in texts
    assert "correction lag L = 3" in texts and "R re-estimated" in texts


def test_autocorrelation_stems_and_band():
    rho = np.column_stack([0.9 ** np.arange(30), np.r_[1.0, np.zeros(29)]])
    svg = autocorrelation_svg(rho, 0.2, 0.5, ["x", "y"], lag_used=4)
    panels = _panels(svg)
    assert len(panels) == 2
    # one path of stems inside the band (blue) and one outside (red): M x base v height
    (red,) = [e for e in panels[0].iter(f"{NS}path") if e.get("stroke") == RED]
    stems = np.array(re.findall(r"M([-\d.]+) ([-\d.]+)v([-\d.]+)", red.get("d")), dtype=float)
    x, top, dx, dy = _inverse(panels[0], stems[:, 0], stems[:, 1] + stems[:, 2])
    outside = np.flatnonzero(np.abs(rho[:, 0]) > 0.2)[1:]  # lag 0 is not counted
    assert np.all(np.abs(x - 0.5 * outside) <= dx)
    assert np.all(np.abs(top - rho[outside, 0]) <= dy)
    texts = ["".join(e.itertext()) for e in ET.fromstring(svg).iter(f"{NS}text")]
    assert f"x: {outside.size} of 29 lags outside" in texts and "y: 0 of 29 lags outside" in texts


def test_cost_history_on_a_log_axis_with_the_noise_updates():
    costs = [1e4, 2e3, 1.5e3, 1.4e3, 900.0, 880.0]
    svg = cost_history_svg(costs, [4], "conv", [np.nan] * 6)
    (panel,) = _panels(svg)  # no ln det R panel without a finite entry
    assert panel.get("data-yscale") == "log"
    xy = _polyline(panel, BLUE)
    x, y, dx, dy = _inverse(panel, xy[:, 0], xy[:, 1])
    # y is log10 of the cost on a log axis; one line per stretch under one R
    assert np.allclose(x, [0, 1, 2, 3, 4, 5], atol=dx)
    assert np.allclose(y, np.log10(costs), atol=dy)
    assert len([e for e in panel.iter(f"{NS}polyline")]) == 2
    dashed = [e for e in panel.iter(f"{NS}path") if e.get("stroke-dasharray")]
    assert len(dashed) == 1
    px = float(re.match(r"M([-\d.]+)", dashed[0].get("d")).group(1))
    assert abs(_inverse(panel, np.array(px), np.array(0.0))[0] - 3.5) <= dx
    with_log_det = cost_history_svg(costs, [4], "conv", np.linspace(-3, -5, 6))
    assert len(_panels(with_log_det)) == 2


# ------------------------------------------------------------------------------ ticks


def test_ticks_are_matplotlibs_maxnlocator_ticks_and_cover_the_range():
    from matplotlib.ticker import MaxNLocator

    rng = np.random.default_rng(12)
    compared = 0
    for _ in range(400):
        centre = rng.normal() * 10.0 ** rng.integers(-4, 6)
        half = abs(rng.normal()) * 10.0 ** rng.integers(-5, 5) + 1e-300
        low, high = centre - half, centre + half
        for bins in (3, 4, 7):
            ticks = svg_axes.nice_ticks(low, high, bins)
            step = np.diff(ticks)
            assert ticks.size >= 2 and np.all(step > 0)
            assert ticks[0] >= low - 1e-9 * half and ticks[-1] <= high + 1e-9 * half
            # round: 1, 2, 2.5 or 5 × 10^k, and no end of the range farther than a step
            mantissa = step[0] / 10.0 ** np.floor(np.log10(step[0]))
            assert np.isclose(mantissa, [1, 2, 2.5, 5, 10]).any(), step[0]
            assert ticks[0] - low <= step[0] * (1 + 1e-9)
            assert high - ticks[-1] <= step[0] * (1 + 1e-9)
            reference = MaxNLocator(nbins=bins, steps=[1, 2, 2.5, 5, 10]).tick_values(low, high)
            slack = 1e-9 * (high - low)
            reference = reference[(reference >= low - slack) & (reference <= high + slack)]
            if reference.size >= 3:
                compared += 1
                assert np.allclose(ticks, reference, rtol=1e-9, atol=slack)
            else:
                # MaxNLocator left fewer than three inside: the next round step, ≤ 6 ticks
                assert 3 <= ticks.size <= 6 or ticks.size == reference.size
    assert compared > 500


@pytest.mark.parametrize(
    ("low", "high", "offset", "multiplier"),
    [
        (11000.2, 11003.7, 11000.0, 0),
        (1e-6, 5e-6, 0.0, -6),
        (-3e6, 7e6, 0.0, 6),
        (-0.021, 0.045, 0.0, 0),
    ],
)
def test_tick_labels_with_offset_and_multiplier_give_back_the_ticks(low, high, offset, multiplier):
    ticks = svg_axes.nice_ticks(low, high, 4)
    labels, text = svg_axes.tick_labels(ticks)
    values = np.array([float(t.replace("−", "-")) for t in labels])
    assert np.allclose(values * 10.0**multiplier + offset, ticks, rtol=1e-12, atol=1e-15)
    # short labels: the offset and the multiplier go to the axis' offset text
    assert max(len(t) for t in labels) <= 5
    if multiplier:
        assert text.startswith("×10")
    if offset:
        assert text.endswith(f"{offset:.6g}")
    assert "-" not in "".join(labels)  # minus signs as −


# ------------------------------------------------------------------------------ the run


def _env() -> dict[str, str]:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "src"), env.get("PYTHONPATH")]))
    return env


def test_an_out_run_with_svg_figures_imports_no_matplotlib(tmp_path):
    out = tmp_path / "out"
    script = (
        "import sys\n"
        "from flightid.cli.main import main\n"
        f"code = main(['run', {str(CASE)!r}, '--out', {str(out)!r}, '--quiet'])\n"
        "print(code, sorted(m for m in sys.modules if m.split('.')[0] == 'matplotlib'))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=_env(), timeout=300
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip().splitlines()[-1] == "0 []"
    names = sorted(p.name for p in (out / "figures").iterdir())
    assert names == ["autocorrelation.svg", "convergence.svg", "fit_1_my_flight.svg"]
    page = (out / "report.html").read_text(encoding="utf-8")
    for name in names:
        ET.fromstring((out / "figures" / name).read_text(encoding="utf-8"))
        assert (out / "figures" / name).read_text(encoding="utf-8") in page
    assert "src=" not in page


def test_figure_format_png_from_the_case_and_the_option_overrides_it(tmp_path):
    from flightid.cli.main import main

    case = tmp_path / "case.toml"
    text = CASE.read_text(encoding="utf-8")
    text = text.replace('data_dir = "."', f"data_dir = {str(CASE.parent)!r}")
    text = text.replace(
        'module = "short_period.py"', f"module = {str(CASE.parent / 'short_period.py')!r}"
    )
    case.write_text(text + '\n[output]\nfigure_format = "png"\n', encoding="utf-8")
    assert main(["run", str(case), "--out", str(tmp_path / "png"), "--quiet"]) == 0
    pngs = sorted((tmp_path / "png" / "figures").iterdir())
    assert [p.suffix for p in pngs] == [".png"] * 3
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)
    options = ["--figure-format", "svg", "--quiet"]
    assert main(["run", str(case), "--out", str(tmp_path / "svg"), *options]) == 0
    assert [p.suffix for p in (tmp_path / "svg" / "figures").iterdir()] == [".svg"] * 3


@pytest.mark.parametrize("given", ["jpeg", "SVG", 1])
def test_a_bad_figure_format_is_a_case_error_naming_the_key(tmp_path, given):
    from flightid.cases import load_case
    from flightid.cases.spec import CaseError

    case = tmp_path / "case.toml"
    value = f'"{given}"' if isinstance(given, str) else str(given)
    case.write_text(CASE.read_text(encoding="utf-8") + f"\n[output]\nfigure_format = {value}\n")
    with pytest.raises(CaseError, match=r"output\.figure_format: expected one of 'svg', 'png'"):
        load_case(case)
