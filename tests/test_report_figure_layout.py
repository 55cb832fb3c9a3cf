"""The report's figures (``flightid.report.figures``: maneuver, autocorrelation, cost
history) laid out without ``tight_layout``: every panel and series is there, and after the
draw no two texts (tick labels, axis labels, titles, offset texts, the figure title) overlap,
no text lies on a panel other than its own, every text lies inside the figure — what
``tight_layout`` guaranteed, checked on the drawn text boxes (matplotlib's own measure).
Drawing creates few tick objects (the figures' drawing time went mostly to them)."""

from __future__ import annotations

import io

import numpy as np
import PIL.Image
import pytest
from matplotlib import axis as mpl_axis
from matplotlib.backends.backend_agg import FigureCanvasAgg

from flightid.report import figures

OUTPUTS = ["V", "alpha", "theta", "q", "qdot", "ax", "h"]
UNITS = {"V": "m/s", "alpha": "rad", "q": "rad/s", "h": "m", "de": "rad", "F": "N"}


def _maneuver(n_outputs: int = 7, seed: int = 4):
    """A maneuver whose channels span the tick labels' hard cases: an offset (+1.16e4),
    a ×10⁻⁴ scale, long negative labels, a large altitude."""
    rng = np.random.default_rng(seed)
    n = 601
    time = 1234.5 + 0.1 * np.arange(n)
    scales = [110.0, 0.1, 1e-4, -0.025, 0.1, 1.0, 3048.0][:n_outputs]
    measured = np.column_stack(
        [s + abs(s) * 0.05 * np.cumsum(rng.normal(size=n)) / 10 for s in scales]
    )
    predicted = measured + 0.01 * np.abs(measured).mean(axis=0) * rng.normal(size=measured.shape)
    inputs = np.column_stack([0.02 * np.sign(np.sin(0.3 * time)), 11600 + rng.normal(size=n)])
    return figures.maneuver_figure(
        time,
        inputs,
        ["de", "F"],
        measured,
        predicted,
        OUTPUTS[:n_outputs],
        UNITS,
        "maneuver m1 (estimation)",
        dpi=96,
    )


def _autocorrelation(n_outputs: int = 7):
    rng = np.random.default_rng(5)
    lags = 120
    rho = np.exp(-np.arange(lags)[:, None] / rng.uniform(3, 40, n_outputs))
    rho -= 0.4 * np.sin(np.arange(lags)[:, None] / 7.0)
    rho[0] = 1.0
    return figures.autocorrelation_figure(rho, 0.08, 0.04, OUTPUTS[:n_outputs], lag_used=90)


def _cost(with_log_det: bool):
    costs = [4200.0, 1300.0, 1100.0, 1040.0, 1030.0, 4100.0, 4095.0, 4090.0]
    log_det = [-41.0, -52.0, -53.0, -53.6, -53.7, -54.0, -54.05, -54.06] if with_log_det else ()
    return figures.cost_history_figure(costs, (5,), "convergence (mnres, noise max)", log_det)


def _drawn(figure, dpi: float = 96.0):
    figure.set_dpi(dpi)
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    return canvas.get_renderer()


def _shown_ticks(axis):
    low, high = sorted(axis.get_view_interval())
    slack = 1e-9 * (high - low)
    ticks = axis.get_major_ticks() + axis.get_minor_ticks()
    return [t for t in ticks if low - slack <= t.get_loc() <= high + slack]


def _texts(figure):
    """(owner axes or None, name, Text) of every shown text outside the panels' insides."""
    texts = [(None, "suptitle", figure._suptitle)] if figure._suptitle else []
    for ax in figure.axes:
        if not ax.get_visible():
            continue
        for which, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            for tick in _shown_ticks(axis):
                for label in (tick.label1, tick.label2):
                    if label.get_visible() and label.get_text():
                        texts.append((ax, f"{which} tick {label.get_text()!r}", label))
            if axis.label.get_text():
                texts.append((ax, f"{which} label", axis.label))
            if axis.offsetText.get_visible() and axis.offsetText.get_text():
                texts.append((ax, f"{which} offset", axis.offsetText))
        for title in (ax.title, ax._left_title, ax._right_title):
            if title.get_text():
                texts.append((ax, "title", title))
    return texts


def _check_layout(figure):
    renderer = _drawn(figure)
    width, height = figure.bbox.width, figure.bbox.height
    texts = [(ax, name, t, t.get_window_extent(renderer)) for ax, name, t in _texts(figure)]
    panels = [ax for ax in figure.axes if ax.get_visible()]
    assert texts
    for _, name, text, box in texts:
        where = f"{name} {text.get_text()!r}"
        # inside the figure (a pixel of rounding)
        assert box.x0 >= -1 and box.y0 >= -1, where
        assert box.x1 <= width + 1 and box.y1 <= height + 1, where
        # on no panel (its own included: these texts sit around the panels)
        for panel in panels:
            inner = panel.get_window_extent(renderer).padded(-1.0)
            assert not box.overlaps(inner), f"{where} lies on a panel"
    for k, (_, name_a, a, box_a) in enumerate(texts):
        for _, name_b, b, box_b in texts[k + 1 :]:
            overlap = box_a.overlaps(box_b.padded(-0.5))
            assert not overlap, f"{name_a} {a.get_text()!r} overlaps {name_b} {b.get_text()!r}"
    return renderer


@pytest.mark.parametrize("n_outputs", [1, 3, 7])
def test_maneuver_figure_shows_every_panel_and_series_without_overlaps(n_outputs):
    figure = _maneuver(n_outputs)
    _check_layout(figure)
    axes = figure.axes
    # 2 input panels, then per output its panel and its residual panel
    assert len(axes) == 2 + 2 * n_outputs
    assert [ax.get_ylabel() for ax in axes[:2]] == ["de [rad]", "F [N]"]
    for j, name in enumerate(OUTPUTS[:n_outputs]):
        output, residual = axes[2 + 2 * j], axes[3 + 2 * j]
        assert [line.get_label() for line in output.get_lines()][:2] == [
            "measured z",
            "predicted y",
        ]
        assert output.get_ylabel() == figures.axis_label(name, UNITS.get(name))
        # the residual and the zero line
        assert len(residual.get_lines()) == 2
        assert residual.get_ylabel().startswith("z − y")
    assert axes[0].get_title(loc="left") == "inputs"
    assert axes[2].get_title(loc="left") == "outputs: measured vs predicted"
    assert axes[3].get_title(loc="left") == "residuals"
    assert axes[2].get_legend() is not None
    # the time axis labelled under the bottom row, with its tick labels there only
    assert axes[-2].get_xlabel().startswith("t − t₀ [s]") and axes[-1].get_xlabel()
    for ax in axes:
        labels = [t.label1.get_text() for t in _shown_ticks(ax.xaxis) if t.label1.get_visible()]
        assert bool(labels) == (ax in axes[-2:]), ax.get_ylabel()
        # the same time span in every panel
        assert ax.get_xlim() == axes[0].get_xlim()
    assert figure._suptitle.get_text() == "maneuver m1 (estimation)"


@pytest.mark.parametrize("n_outputs", [1, 2, 4, 7])
def test_autocorrelation_figure_shows_every_output_without_overlaps(n_outputs):
    figure = _autocorrelation(n_outputs)
    _check_layout(figure)
    assert len(figure.axes) == n_outputs
    for ax, name in zip(figure.axes, OUTPUTS, strict=False):
        assert ax.get_title().startswith(f"{name}: ")
        # the lags inside and outside the band, the zero line and the correction lag; the band
        lines = ax.get_lines()
        assert len(lines) == 4 and len(ax.patches) == 1
        stems = sum(np.count_nonzero(np.isfinite(line.get_ydata())) for line in lines[:2])
        assert stems == 2 * 120
        assert lines[3].get_label() == "correction lag L = 90"
    # the lag axis labelled under the lowest panel of each column
    columns = min(n_outputs, 3)
    labelled = [ax.get_xlabel() == "lag [s]" for ax in figure.axes]
    assert labelled == [j + columns >= n_outputs for j in range(n_outputs)]
    assert figure.axes[0].get_legend() is not None


@pytest.mark.parametrize("with_log_det", [False, True])
def test_cost_history_figure_shows_every_pass_without_overlaps(with_log_det):
    figure = _cost(with_log_det)
    _check_layout(figure)
    assert len(figure.axes) == (2 if with_log_det else 1)
    cost_axes = figure.axes[-1]
    assert cost_axes.get_yscale() == "log"
    # two stretches under one R each, and the R re-estimation line
    assert len(cost_axes.get_lines()) == 3
    points = sum(len(line.get_xdata()) for line in cost_axes.get_lines()[:2])
    assert points == 8
    assert "cost J" in cost_axes.get_ylabel() and cost_axes.get_xlabel() == "pass [–]"
    if with_log_det:
        assert figure.axes[0].get_ylabel().startswith("ln det")


def test_drawing_a_maneuver_figure_creates_few_tick_objects(monkeypatch):
    # a 7-output maneuver (16 panels) drew 457 ticks laid out by tight_layout; the inner
    # panels' time ticks are now grid lines in one collection, the y axes have few ticks
    created = []
    original = mpl_axis.Tick.__init__

    def counted(self, *args, **kwargs):
        created.append(type(self).__name__)
        original(self, *args, **kwargs)

    monkeypatch.setattr(mpl_axis.Tick, "__init__", counted)
    figure = _maneuver(7)
    png = figures.png_bytes(figure, 96)
    assert len(figure.axes) == 16
    assert len(created) <= 10 * 16, len(created)
    image = PIL.Image.open(io.BytesIO(png))
    width, height = figure.get_size_inches()
    assert abs(image.size[0] - width * 96) < 1 and abs(image.size[1] - height * 96) < 1


def test_figures_drawn_here_leave_the_heap_out_of_collections_then_hand_it_back(monkeypatch):
    import gc

    from flightid.report import drawing

    seen = []

    def job_seen(job):
        seen.append(gc.get_freeze_count())
        return b"png"

    monkeypatch.setattr(drawing, "draw_job", job_seen)
    job = drawing.FigureJob("cost_history_figure", ([3.0, 2.0],), {}, 40.0, 1.0)
    assert gc.get_freeze_count() == 0
    assert drawing.draw([job, job]) == [b"png", b"png"]
    # frozen while drawing, everything handed back to the collector afterwards
    assert len(seen) == 2 and min(seen) > 0
    assert gc.get_freeze_count() == 0
