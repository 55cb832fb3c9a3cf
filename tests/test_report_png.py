"""PNG output of the report figures: one Agg draw, the pixels ``savefig`` gives.

``flightid.report.figures.png_bytes`` / ``_save`` draw a figure once and write the canvas;
``Figure.savefig`` of a figure laid out by ``tight_layout`` draws it twice (a pre-draw for
its placeholder layout engine). Reference: matplotlib's own ``savefig`` of the same figure.
"""

from __future__ import annotations

import io

import numpy as np
import PIL.Image
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from flightid.report import figures


def _maneuver() -> Figure:
    rng = np.random.default_rng(3)
    n = 200
    z = rng.normal(size=(n, 3))
    return figures.maneuver_figure(
        np.arange(n) * 0.05,
        rng.normal(size=(n, 1)),
        ["de"],
        z,
        z + 0.1 * rng.normal(size=(n, 3)),
        ["alpha", "q", "az"],
        {"alpha": "rad", "q": "rad/s", "az": "m/s^2", "de": "rad"},
        "maneuver 1",
    )


def _pixels(png) -> np.ndarray:
    return np.asarray(PIL.Image.open(png).convert("RGBA"))


def _savefig(figure: Figure, dpi: int) -> np.ndarray:
    FigureCanvasAgg(figure)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi)
    buffer.seek(0)
    return _pixels(buffer)


def test_png_bytes_draws_once_the_pixels_of_savefig(monkeypatch):
    figure = _maneuver()
    draws = []
    original = Figure.draw

    def counted(self, renderer):
        draws.append(renderer)
        return original(self, renderer)

    monkeypatch.setattr(Figure, "draw", counted)
    png = figures.png_bytes(figure, dpi=96)
    assert len(draws) == 1
    monkeypatch.setattr(Figure, "draw", original)
    ours = _pixels(io.BytesIO(png))
    # figsize × dpi pixels, and the figure keeps its own dpi
    width, height = figure.get_size_inches()
    assert ours.shape == (round(height * 96), round(width * 96), 4)
    assert figure.dpi == 100
    np.testing.assert_array_equal(ours, _savefig(_maneuver(), 96))


def test_save_writes_the_pixels_of_savefig(tmp_path):
    path = figures._save(_maneuver(), tmp_path / "sub" / "fit.png", 120)
    np.testing.assert_array_equal(_pixels(path), _savefig(_maneuver(), 120))
