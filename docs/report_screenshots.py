"""Render the top of each estimator's report.html to the PNG figures of the case guide.

Runs the shipped cases (their flight data must be present), renders each report.html with
headless Chromium at 1200 × 1600 pixels and writes ``docs/figures/report*.png``:

    python docs/report_screenshots.py            # needs chromium on the PATH and the data

The cases run from the repository root with relative paths, so the pages show
``examples/cases/...`` as the case file.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures"

# (figure, command after `flightid`, page in the result folder)
SHOTS = (
    ("report.png", ["run", "examples/cases/twin_otter_longitudinal.toml"], "report.html"),
    (
        "report_frequency.png",
        ["run", "examples/cases/attas_short_period_frequency_domain.toml"],
        "report.html",
    ),
    (
        "report_recursive.png",
        ["run", "examples/cases/attas_short_period_recursive_ekf.toml"],
        "report.html",
    ),
    ("report_design.png", ["design", "examples/cases/short_period_design.toml"], "report.html"),
    ("report_stepwise.png", ["run", "examples/cases/twin_otter_stepwise.toml"], "stages.html"),
)


def _browser() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if shutil.which(name):
            return name
    raise SystemExit("report_screenshots: needs chromium (or chromium-browser) on the PATH")


def _shrink(path: Path) -> None:
    """Halve the PNG's colour depth to a palette (a page of text and plots stays readable)."""
    try:
        from PIL import Image
    except ImportError:
        return
    image = Image.open(path).convert("RGB")
    image.quantize(colors=128).save(path, optimize=True)


def main() -> int:
    browser = _browser()
    with tempfile.TemporaryDirectory() as scratch:
        for figure, command, page in SHOTS:
            out = Path(scratch) / figure.removesuffix(".png")
            subprocess.run(
                [sys.executable, "-m", "flightid.cli.main", *command, "--out", str(out)],
                cwd=ROOT,
                check=True,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            target = FIGURES / figure
            subprocess.run(
                [
                    browser, "--headless", "--no-sandbox", "--hide-scrollbars",
                    f"--screenshot={target}", "--window-size=1200,1600",
                    (out / page).as_uri(),
                ],
                check=True,
                capture_output=True,
            )  # fmt: skip
            _shrink(target)
            print(f"{target.relative_to(ROOT)}: {target.stat().st_size // 1024} KB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
