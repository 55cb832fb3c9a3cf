"""The walk-through of docs/logs.md end to end: `flightid example-logs` → `flightid inspect
--case-lines` → `flightid run` of both example cases → report.html; the estimates against
the truth the example logs were simulated from, and the numbers the page quotes against
this run (docs/logs_walkthrough.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _walkthrough_module():
    spec = importlib.util.spec_from_file_location(
        "logs_walkthrough", ROOT / "docs" / "logs_walkthrough.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    pytest.importorskip("pyulog")
    pytest.importorskip("pymavlink")
    module = _walkthrough_module()
    return module, module.run_walkthrough(tmp_path_factory.mktemp("walkthrough"))


def test_walkthrough_runs_and_recovers_the_simulated_truth(walk):
    from flightid.examples.logs import write_fixedwing_dataflash, write_multirotor_ulog

    module, result = walk
    folder = result["folder"]
    for out in ("out_multirotor_roll_rate", "out_fixedwing_roll"):
        assert (folder / out / "report.html").stat().st_size > 10_000
    for out in ("inspect_multirotor", "inspect_fixedwing"):
        assert (folder / out / "overview.png").is_file()
    # the case lines `inspect --case-lines` printed are TOML with the maneuvers flown
    import tomllib

    lines = tomllib.loads(result["blocks"]["case_lines_multirotor"])["data"]["maneuvers"]
    assert [m["name"] for m in lines][:4] == ["sweep_1", "doublet_1", "doublet_2", "doublet_3"]
    assert lines[4]["name"] == "pulse_1"  # the return to level on leaving Acro
    # truth: what the example writers return (the parameters the logs were simulated with);
    # written again here with the default seeds, in their own folder
    truths = {
        module.MULTIROTOR_CASE: (
            write_multirotor_ulog(folder / "truth.ulg").parameters,
            module.MULTIROTOR_PARAMETERS,
        ),
        module.FIXEDWING_CASE: (
            write_fixedwing_dataflash(folder / "truth.bin").parameters,
            module.FIXEDWING_PARAMETERS,
        ),
    }
    for case, (truth, names) in truths.items():
        results = result["results"][case]
        assert results["status"] == "converged", case
        by_name = {p["name"]: p for p in results["parameters"]}
        for name, (truth_key, _) in names.items():
            value, sigma = by_name[name]["value"], by_name[name]["std"]
            assert abs(value - truth[truth_key]) < 3 * sigma, (case, name, value, sigma)
            assert 0 < sigma < 0.01 * abs(truth[truth_key])
    # the maneuvers were selected by flight mode: the Acro and MANUAL intervals
    multirotor = result["results"][module.MULTIROTOR_CASE]["maneuvers"]
    assert "2 segment(s): 29.4..35.33 s" in " ".join(multirotor[0]["time_base"])
    fixedwing = result["results"][module.FIXEDWING_CASE]["maneuvers"]
    assert "1 segment(s): 51..79 s" in " ".join(fixedwing[0]["time_base"])


def test_the_page_quotes_this_run(walk):
    """Every block docs/logs.md quotes agrees with this run to the digits it prints (wall
    times not compared), and no placeholder is left."""
    module, result = walk
    text = (ROOT / "docs" / "logs.md").read_text(encoding="utf-8")
    assert "TODO" not in text
    assert module.compare(text, result["blocks"]) == []
    assert (ROOT / "docs" / "figures" / "inspect_multirotor.png").stat().st_size < 150_000


def test_comparison_catches_a_changed_number_and_ignores_wall_time():
    module = _walkthrough_module()
    page = (
        "<!-- walkthrough: estimates -->\n| multirotor | ω_n | 42 | 41.9869 | 0.022 | -0.60 |\n\n"
        "<!-- walkthrough: runs -->\n| fixed wing | `flightid run x.toml` | 6 | 1.02 s |\n"
    )
    fresh = {
        "estimates": "| multirotor | ω_n | 42 | 41.98694 | 0.0218 | -0.601 |",
        "runs": "| fixed wing | `flightid run x.toml` | 6 | 3.50 s |",
    }
    assert module.compare(page, fresh) == []
    fresh["estimates"] = "| multirotor | ω_n | 42 | 41.9889 | 0.022 | -0.60 |"
    assert len(module.compare(page, fresh)) == 1
    fresh["runs"] = "| fixed wing | `flightid run x.toml` | 7 | 1.02 s |"
    assert len(module.compare(page, fresh)) == 2
    assert module.compare(page, {"estimates": fresh["estimates"]})[0].startswith("runs")
