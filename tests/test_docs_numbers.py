"""The guides' measured numbers are the scripts' output (docs/docs_numbers.py).

Each guide quotes its measured numbers between ``<!-- numbers: NAME -->`` and
``<!-- /numbers -->``; the script that measures them (``docs/<guide>_numbers.py``) records
its last output in ``docs/numbers/<script>.txt``. Tolerances: counts exactly, other numbers
to one unit of the last digit the page prints (or the ``rel=`` the marker states), table
columns of wall times not at all (they depend on the machine; the page shows the command
that prints them).

Here, without running anything expensive: every region of every guide is in a record and
agrees with it, and every record's regions are on their guide. Where a script's numbers
come from a run of a few seconds, that run is repeated against the page (skipped without
the flight data).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from data_paths import DATA, needs_data

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _load(name: str):
    if str(DOCS) not in sys.path:
        sys.path.insert(0, str(DOCS))  # the scripts import their helpers from beside them
    spec = importlib.util.spec_from_file_location(name, DOCS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


numbers = _load("docs_numbers")
RECORDS = sorted((DOCS / "numbers").glob("*.txt"))


@pytest.mark.parametrize("record", RECORDS, ids=lambda path: path.stem)
def test_each_guide_quotes_its_scripts_last_output(record: Path) -> None:
    output = record.read_text(encoding="utf-8")
    page = numbers.guide_of(output)
    problems = numbers.compare(page.read_text(encoding="utf-8"), output)
    assert not problems, "\n".join(problems)


def test_every_region_of_the_guides_has_a_record() -> None:
    recorded = set()
    for record in RECORDS:
        recorded |= set(numbers.regions(record.read_text(encoding="utf-8")))
    quoted = {}
    for page in sorted(DOCS.glob("*.md")):
        for name in numbers.regions(page.read_text(encoding="utf-8")):
            quoted[name] = page.name
    assert RECORDS and quoted
    missing = {name: page for name, page in quoted.items() if name not in recorded}
    assert not missing, f"regions no script records: {missing}"


PAGE = """Some prose.
<!-- numbers: demo rel=0.01 -->
| case | passes | wall (s) | Zw |
|---|---|---|---|
| 3a | 18 | 0.30 | −1.3085 ± 3.2·10⁻² |

12 of 15 within 2σ
<!-- /numbers -->
More prose: 7 parameters.
"""


def _printed(zw: str = "-1.3085 ± 0.032", passes: str = "18", wall: str = "9.99") -> str:
    return (
        "<!-- numbers: demo -->\n| case | passes | wall (s) | Zw |\n|---|---|---|---|\n"
        f"| 3a | {passes} | {wall} | {zw} |\n\n12 of 15 within 2σ\n<!-- /numbers -->\n"
    )


def test_numbers_are_read_as_the_page_prints_them() -> None:
    assert numbers.value("−1.2·10⁻⁸") == pytest.approx(-1.2e-8)
    assert numbers.value("4.0×10⁵") == pytest.approx(4.0e5)
    assert numbers.value("3.5e-07") == pytest.approx(3.5e-7)
    # a digit inside a name is not a number
    assert numbers.NUMBER.findall("Cm0 of 3a is −0.5, Zδe 1e-3") == ["−0.5", "1e-3"]


def test_agreement_within_the_tolerance_and_wall_times_ignored() -> None:
    assert numbers.compare(PAGE, _printed()) == []
    # the marker's rel=0.01: 1 % off agrees, 2 % does not
    assert numbers.compare(PAGE, _printed(zw="-1.3200 ± 0.032")) == []
    assert len(numbers.compare(PAGE, _printed(zw="-1.3400 ± 0.032"))) == 1


def test_a_row_of_wall_times_is_not_compared() -> None:
    page = (
        "<!-- numbers: x -->\n| parameter | ekf |\n|---|---|\n| Lp | −2.07 |\n| wall (s) | 0.46 |\n"
    )
    page += "<!-- /numbers -->"
    assert numbers.compare(page, page.replace("0.46", "3.10")) == []
    assert len(numbers.compare(page, page.replace("−2.07", "−2.10"))) == 1


def test_a_changed_count_word_or_line_is_caught() -> None:
    assert len(numbers.compare(PAGE, _printed(passes="19"))) == 1
    assert len(numbers.compare(PAGE, _printed().replace("12 of 15", "11 of 15"))) == 1
    assert len(numbers.compare(PAGE, _printed().replace("within", "beyond"))) == 1
    assert numbers.compare(PAGE, _printed().replace("demo", "other")) == [
        "other: not quoted on the page"
    ]


def test_without_a_stated_tolerance_one_unit_of_the_last_digit() -> None:
    page = "<!-- numbers: x -->\nZw = 0.2148\n<!-- /numbers -->"
    assert numbers.compare(page, page.replace("0.2148", "0.21489")) == []
    assert len(numbers.compare(page, page.replace("0.2148", "0.2150"))) == 1


def test_write_replaces_only_the_regions() -> None:
    written = numbers.write(PAGE, _printed(zw="-1.4 ± 0.1"))
    assert written.startswith("Some prose.\n<!-- numbers: demo rel=0.01 -->\n")
    assert "| 3a | 18 | 9.99 | -1.4 ± 0.1 |" in written
    assert written.endswith("<!-- /numbers -->\nMore prose: 7 parameters.\n")


@needs_data("fvsysid/unStabAC_sim.asc")
def test_unstable_least_squares_rows_are_what_the_cases_give_today() -> None:
    """The 3g/3h rows of docs/unstable.md against a fresh run of the two least-squares case
    files (about 5 s; the other rows integrate and are checked through the record)."""
    unstable = _load("unstable_numbers")
    case_numbers = _load("case_numbers")
    fresh = case_numbers.table(unstable.COMPARISON_HEADING, unstable.least_squares_rows(str(DATA)))
    page = numbers.regions((DOCS / "unstable.md").read_text(encoding="utf-8"))
    quoted_lines = page["unstable-comparison"][0].splitlines()
    quoted = "\n".join(
        quoted_lines[:2] + [line for line in quoted_lines if line[:5] in {"| 3g ", "| 3h "}]
    )
    assert quoted.count("\n") == 3
    problems = numbers.differences(quoted, fresh)
    assert not problems, "\n".join(problems)


@needs_data("fvsysid/unStabAC_sim.asc")
def test_regression_least_squares_table_is_what_the_cases_give_today() -> None:
    """docs/regression.md's OLS/TLS table against a fresh run of both case files (≈ 5 s)."""
    regression = _load("regression_numbers")
    page = numbers.regions((DOCS / "regression.md").read_text(encoding="utf-8"))
    problems = numbers.differences(
        page["regression-unstable-ls"][0], regression.least_squares(str(DATA))
    )
    assert not problems, "\n".join(problems)


def test_method_paper_examples_table_is_what_flightid_paper_prints_today() -> None:
    """docs/method.md's examples 1 and 2 table against fresh runs (≈ 4 s, no data needed)."""
    method = _load("method_numbers")
    page = numbers.regions((DOCS / "method.md").read_text(encoding="utf-8"))
    problems = numbers.differences(page["method-paper-examples"][0], method.table())
    assert not problems, "\n".join(problems)


def test_data_resampling_example_is_what_flightid_says_today() -> None:
    """docs/data.md's roll.csv example (refusals, segments, notes, errors) against a fresh
    run of docs/data_numbers.py (≈ 1 s, a seeded file it writes itself)."""
    data = _load("data_numbers")
    page = numbers.regions((DOCS / "data.md").read_text(encoding="utf-8"))
    problems = numbers.differences(page["data-resampling"][0], data.resampling())
    assert not problems, "\n".join(problems)


def test_inspect_example_is_what_flightid_inspect_prints_today() -> None:
    """docs/inspect.md's two outputs against a fresh run of docs/inspect_numbers.py on the
    seeded log it writes (a few seconds, no data needed)."""
    pytest.importorskip("pyulog")
    inspect = _load("inspect_numbers")
    page = numbers.regions((DOCS / "inspect.md").read_text(encoding="utf-8"))
    report, lines = inspect.example()
    problems = numbers.differences(page["inspect-report"][0], report)
    problems += numbers.differences(page["inspect-case-lines"][0], lines)
    assert not problems, "\n".join(problems)


def test_frequency_delay_example_is_what_the_fits_give_today() -> None:
    """docs/frequency.md's rate-loop table (free, held and no delay) against fresh fits of
    the scipy-simulated record (≈ 2 s, no data needed; the 20-seed line via the record)."""
    frequency = _load("frequency_numbers")
    quoted = numbers.regions((DOCS / "frequency.md").read_text(encoding="utf-8"))
    table = quoted["frequency-delay-example"][0].split("\n\n")[0]
    problems = numbers.differences(table, frequency.delay_table())
    assert not problems, "\n".join(problems)


def test_recursive_delay_example_is_what_the_filters_give_today() -> None:
    """docs/recursive.md's EKF/UKF table and FTR line on the delayed rate loop and roll mode
    against fresh runs (≈ 5 s, no data needed)."""
    recursive = _load("recursive_numbers")
    quoted = numbers.regions((DOCS / "recursive.md").read_text(encoding="utf-8"))
    fresh = f"{recursive.delay_table()}\n\n{recursive.ftr_delay()}"
    problems = numbers.differences(quoted["recursive-delay"][0], fresh)
    assert not problems, "\n".join(problems)


def test_aircraft_example3_table_is_what_flightid_paper_prints_today() -> None:
    """docs/aircraft.md's RP-1153 example 3 results against fresh runs (≈ 8 s: seven
    simulated estimations, no data needed)."""
    aircraft = _load("aircraft_numbers")
    quoted = numbers.regions((DOCS / "aircraft.md").read_text(encoding="utf-8"))
    problems = numbers.differences(quoted["aircraft-example3"][0], aircraft.example3_table())
    assert not problems, "\n".join(problems)


@needs_data("sidpac_f18harv")
def test_compat_f18_table_is_what_the_cases_give_today() -> None:
    """docs/compat.md's F-18 HARV reconstruction against SIDPAC's stored results, from fresh
    runs of both case files (≈ 10 s)."""
    compat = _load("compat_numbers")
    quoted = numbers.regions((DOCS / "compat.md").read_text(encoding="utf-8"))
    fresh = compat.against_sidpac(str(DATA))
    problems = numbers.differences(quoted["compat-f18-against-sidpac"][0], fresh)
    assert not problems, "\n".join(problems)


def test_every_numbers_script_has_a_record() -> None:
    scripts = sorted(DOCS.glob("*_numbers.py")) + [ROOT / "bench" / "benchmarks_numbers.py"]
    scripts = [s for s in scripts if s.name not in {"case_numbers.py", "docs_numbers.py"}]
    # a script re-run against its page by a test of its own needs no record
    tested = {"fly_numbers.py": "test_fly_numbers.py",
              "flying_qualities_numbers.py": "test_flying_qualities.py",
              "fly_cases_numbers.py": "test_fly_cases.py"}  # fmt: skip
    for script, test in tested.items():
        assert script in (ROOT / "tests" / test).read_text(encoding="utf-8"), (script, test)
    scripts = [s for s in scripts if s.name not in tested]
    missing = [s.name for s in scripts if not (DOCS / "numbers" / f"{s.stem}.txt").is_file()]
    assert len(scripts) >= 10 and not missing, f"scripts without a record: {missing}"
