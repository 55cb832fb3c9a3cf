"""docs/fly.md quotes the numbers of its example as docs/fly_numbers.py measures them (the
CSV walk-through case run, a prediction on a new doublet, the linear model and its modes,
every export format), and the comparison catches a changed number."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _numbers_module():
    spec = importlib.util.spec_from_file_location("fly_numbers", ROOT / "docs" / "fly_numbers.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    module = _numbers_module()
    return module, module.run_example(tmp_path_factory.mktemp("fly"))


def test_the_page_quotes_this_run(measured):
    module, blocks = measured
    text = (ROOT / "docs" / "fly.md").read_text(encoding="utf-8")
    assert set(module.quoted_blocks(text)) == set(blocks)
    assert module.compare(text, blocks) == []


def test_the_example_recovers_the_true_short_period_within_two_sigma(measured):
    module, _ = measured
    from flightid.cases import load_run  # noqa: F401  (the API the page shows)

    omega, zeta = module._true_mode()
    # closed form of the true A = [[Za, 1 + Zq], [Ma, Mq]]: ω_n² = det A, 2ζω_n = −trace A
    za, zq, _, ma, mq, _ = module.TRUE.values()
    assert omega**2 == pytest.approx(za * mq - (1 + zq) * ma, rel=1e-12)
    assert 2 * zeta * omega == pytest.approx(-(za + mq), rel=1e-12)
    rows = {
        line.split("|")[1].strip(): line.split("|")[2:5] for line in _rows(measured[1]["modes"])
    }
    for label in ("ω_n (rad/s)", "ζ"):
        estimate, sigma, truth = (float(c) for c in rows[label])
        assert abs(estimate - truth) < 2 * sigma


def _rows(table: str) -> list[str]:
    return [line for line in table.splitlines()[2:] if line.startswith("|")]


def test_comparison_catches_a_changed_number():
    module = _numbers_module()
    page = "<!-- fly: modes -->\n| ζ | 0.4887 | 0.0006 | 0.4897 |\n"
    assert module.compare(page, {"modes": "| ζ | 0.48874 | 0.00061 | 0.48971 |"}) == []
    assert len(module.compare(page, {"modes": "| ζ | 0.4899 | 0.0006 | 0.4897 |"})) == 1
    assert module.compare(page, {"other": "x"})[0].startswith("other")
