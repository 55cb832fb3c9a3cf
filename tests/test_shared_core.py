"""The shared core (``flightid.results``, ``flightid.jsonout``, ``flightid.parallel``) serves
the layers above it without importing them: the report's renderers are handed in by the
``flightid`` package, and the accuracy methods run their tasks without the batch layer."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import flightid.results as results
from flightid.results import RendererMissingError, set_renderers
from test_accuracy_models import exp_estimate

ROOT = Path(__file__).resolve().parents[1]


def _python(code: str) -> str:
    """stdout of ``code`` run in a fresh interpreter on this checkout's sources."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + str(ROOT / "tests")}
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_import_flightid_loads_neither_numpy_nor_the_report():
    # the package hands the renderers to flightid.results when it is imported, and stays light
    loaded = _python(
        "import sys, flightid\n"
        "heavy = ('numpy', 'scipy', 'matplotlib', 'numba', 'flightid.report')\n"
        "print(sorted(m for m in heavy if m in sys.modules))"
    )
    assert loaded == "[]"


@pytest.fixture
def renderers():
    """Restore the package's renderers after a test replaces them."""
    saved = results._summary_renderer, results._figure_renderer
    yield
    results._summary_renderer, results._figure_renderer = saved


def test_summary_and_plot_draw_with_the_renderers_handed_in(renderers, tmp_path):
    from matplotlib.figure import Figure

    estimate, _ = exp_estimate()
    drawn = Figure()
    seen = []

    def figure(result):
        seen.append(result)
        return drawn

    set_renderers(summary=lambda result: f"summary of {type(result).__name__}", figure=figure)
    assert estimate.summary() == "summary of Estimate"
    assert estimate.plot(tmp_path / "fig.png") is drawn
    assert seen == [estimate] and (tmp_path / "fig.png").stat().st_size > 0


def test_without_renderers_summary_and_plot_are_a_named_error(renderers):
    estimate, _ = exp_estimate()
    results._summary_renderer = results._figure_renderer = None
    with pytest.raises(RendererMissingError, match=r"Estimate\.summary\(\): no report renderer"):
        estimate.summary()
    with pytest.raises(RendererMissingError, match=r"Estimate\.plot\(\): no report renderer"):
        estimate.plot()


def test_the_package_hands_in_the_report_renderers():
    from flightid.report.result_figures import estimate_figure
    from flightid.report.text import estimate_summary

    estimate, _ = exp_estimate()
    # the same text as the report's own function, called directly
    assert estimate.summary() == estimate_summary(estimate)
    assert len(estimate.plot().axes) == len(estimate_figure(estimate).axes)


def test_profile_limits_run_without_the_batch_layer():
    # the accuracy methods' tasks go through flightid.parallel; the batch layer (Dask engine,
    # case files) is not imported for a serial run
    out = _python(
        "import sys, warnings\n"
        "warnings.simplefilter('ignore')\n"
        "from test_accuracy_models import exp_estimate\n"
        "from flightid.accuracy import assess\n"
        "estimate, data = exp_estimate()\n"
        "accuracy = assess(estimate, data, methods=('cr', 'profile'), warn=False)\n"
        "import numpy as np\n"
        "print(bool(np.all(np.isfinite(accuracy.ci_profile))),"
        " sorted(m for m in sys.modules if m.startswith('flightid.batch')))"
    )
    assert out == "True []"
