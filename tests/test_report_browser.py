"""report.html in a real headless browser (Chromium): it renders to a screenshot, every
embedded figure decodes, the tables are in the DOM, and the page logs nothing to the console.

Chromium prints every console message (console.log / error, uncaught exceptions) to stderr
as ``...:CONSOLE...`` lines with ``--enable-logging=stderr --v=0``; the report has no script,
so any such line is an error. The figures are inline SVG elements (the default) or
base64 PNG images; both are counted as figures shown. A page that does log one is checked
first, so that a Chromium whose log format changed cannot pass silently. Skipped where no
Chromium binary is found (Debian: ``apt-get install chromium``).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from flightid.cases import load_case, run_case
from flightid.report.html import write_report

ROOT = Path(__file__).resolve().parents[1]
WALK_CASE = ROOT / "examples/csv_walkthrough/my_case.toml"
BROWSER = next(
    (
        found
        for name in ("chromium", "chromium-browser", "google-chrome", "chrome")
        if (found := shutil.which(name))
    ),
    None,
)
pytestmark = pytest.mark.skipif(
    BROWSER is None, reason="no Chromium binary on PATH (Debian: apt-get install chromium)"
)
WIDTH, HEIGHT = 1280, 4000

# appended to a copy of the page: reports, through the console, how many images decoded
_IMAGE_CHECK = """<script>
window.addEventListener("load", () => {
  const images = Array.from(document.images);
  const figures = Array.from(document.querySelectorAll("figure > svg"));
  const decoded = images.filter((i) => i.complete && i.naturalWidth > 0).length
    + figures.filter((f) => f.getBoundingClientRect().width > 0).length;
  console.log(`flightid-check images=${images.length + figures.length} decoded=${decoded}`);
});
</script>"""


def _chromium(*arguments: str) -> subprocess.CompletedProcess:
    command = [
        BROWSER,
        "--headless",
        "--no-sandbox",  # root in containers
        "--disable-gpu",
        "--hide-scrollbars",
        "--enable-logging=stderr",
        "--v=0",
        *arguments,
    ]
    return subprocess.run(command, capture_output=True, text=True, timeout=120, check=False)


def _console(stderr: str) -> list[str]:
    """Console lines of a Chromium log: ``[...:INFO:CONSOLE(1)] "message", source: ...``."""
    return [line for line in stderr.splitlines() if re.search(r":CONSOLE\b", line)]


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("browser") / "out"
    return write_report(run_case(load_case(WALK_CASE)), out)


def test_console_errors_are_seen(tmp_path):
    # the detector itself: a page with an uncaught error must show up
    page = tmp_path / "bad.html"
    page.write_text("<!DOCTYPE html><p>x</p><script>throw new Error('boom-1153')</script>")
    run = _chromium("--dump-dom", page.as_uri())
    assert any("Uncaught Error: boom-1153" in line for line in _console(run.stderr)), run.stderr


def test_report_renders_without_console_errors(report, tmp_path):
    shot = tmp_path / "report.png"
    run = _chromium(f"--screenshot={shot}", f"--window-size={WIDTH},{HEIGHT}", report.as_uri())
    assert run.returncode == 0, run.stderr
    assert _console(run.stderr) == [], run.stderr
    import matplotlib.image as mpimg

    image = mpimg.imread(shot)
    assert image.shape[:2] == (HEIGHT, WIDTH)
    # not blank: the top of the page (title, tables, figures) has dark and light pixels
    top = image[:1500, :, :3].mean(axis=2)
    assert top.min() < 0.2 and top.max() > 0.9 and np.mean(top < 0.5) > 0.005


def test_report_dom_tables_and_decoded_figures(report, tmp_path):
    page = tmp_path / "report.html"
    page.write_text(
        report.read_text(encoding="utf-8").replace("</body>", _IMAGE_CHECK + "</body>"),
        encoding="utf-8",
    )
    run = _chromium("--virtual-time-budget=5000", "--dump-dom", page.as_uri())
    assert run.returncode == 0, run.stderr
    lines = _console(run.stderr)
    check = [line for line in lines if "flightid-check" in line]
    assert len(check) == 1 and len(lines) == 1, run.stderr
    images, decoded = map(int, re.search(r"images=(\d+) decoded=(\d+)", check[0]).groups())
    assert images == decoded >= 3
    dom = run.stdout
    for heading in (
        "Estimates",
        "Residual analysis: noise, fit, whiteness",
        "Fit: inputs, measured and predicted outputs, residuals",
        "Convergence",
    ):
        assert f"<h2>{heading}</h2>" in dom
    assert dom.count("<table") >= 6 and "coloured σ" in dom and "Theil U [–]" in dom
