"""The user docs are a manual: no references to files users do not have, no development history.

Users get docs/*.md and README.md, not the development notes (CASES.md, METHOD.md), not the
shared folder beside the development checkout, and not the issue tracker's numbering or the
dates and commits at which a number was measured. Each pattern below names one such
reference; a page that uses one fails with the file, the line and the text.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = sorted((ROOT / "docs").glob("*.md")) + sorted((ROOT / "docs" / "api").glob("*.md"))
PAGES.append(ROOT / "README.md")

# What a user cannot follow, each with why (case-sensitive: docs/cases.md is a user page).
FORBIDDEN = {
    r"\bCASES\.md\b": "a development note users do not have",
    r"\bMETHOD\.md\b": "a development note users do not have",
    r"\.\./shared\b": "a path into the development machine's shared folder",
    r"shared/data/README": "the shared data folder's notes, which users do not have",
    r"(?i)\bissues? ?#?\d+": "an issue number (development history)",
    r"(?i)\bsessions?\b": "a development session (development history)",
    r"\b20\d\d-[01]\d-[0-3]\d\b": "a date of development",
    r"\bcommit [0-9a-f]{7,40}\b": "a development commit",
    r"\b\d\d:\d\d UTC\b": "a time of day of development",
}


def offending_lines(text: str) -> list[tuple[int, str, str]]:
    """(line number, matched text, reason) for each forbidden reference in text."""
    found = []
    for number, line in enumerate(text.splitlines(), start=1):
        for pattern, reason in FORBIDDEN.items():
            for match in re.finditer(pattern, line):
                found.append((number, match.group(0), reason))
    return found


@pytest.mark.parametrize("page", PAGES, ids=lambda page: str(page.relative_to(ROOT)))
def test_page_has_no_reference_users_cannot_follow(page: Path) -> None:
    found = offending_lines(page.read_text(encoding="utf-8"))
    assert not found, "\n".join(f"{page.name}:{n}: {text!r} — {why}" for n, text, why in found)


@pytest.mark.parametrize(
    "line",
    [
        "see CASES.md §6",
        "the model of METHOD.md",
        "else `../../../shared/data` relative to the case file",
        "as ../shared/data/README.md says",
        "the trust region of issue 13",
        "(Issue #14)",
        "the second session's table",
        "measured 2026-11-23 on the machine",
        "re-measured at commit ebbf382",
        "as it stood at 09:45 UTC",
    ],
)
def test_each_forbidden_reference_is_caught(line: str) -> None:
    assert offending_lines(line), line


@pytest.mark.parametrize(
    "line",
    [
        "a folder `shared/data` beside your checkout",
        "FVSysID test case TC22 (Jategaonkar 2015)",
        "CASES of the reference program",
        "the regression value is flightid's own output at commit <hash>",
        "see [case files](cases.md) and docs/method.md",
    ],
)
def test_ordinary_prose_passes(line: str) -> None:
    assert not offending_lines(line), line


def test_every_guide_in_the_nav_is_linked_from_the_home_page() -> None:
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    guides = set(re.findall(r":\s*([a-z_]+\.md)\s*$", nav, flags=re.MULTILINE)) - {"index.md"}
    home = (ROOT / "docs" / "index.md").read_text(encoding="utf-8")
    missing = sorted(guide for guide in guides if f"]({guide}" not in home)
    assert guides and not missing, f"docs/index.md does not link {missing}"


def test_every_api_page_is_in_the_nav_and_the_api_index() -> None:
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    api_index = (ROOT / "docs" / "api" / "index.md").read_text(encoding="utf-8")
    for page in sorted((ROOT / "docs" / "api").glob("*.md")):
        if page.name == "index.md":
            continue
        assert f"api/{page.name}" in nav, f"mkdocs.yml nav lacks api/{page.name}"
        assert f"]({page.name})" in api_index, f"docs/api/index.md lacks {page.name}"


def test_every_python_name_on_the_sidpac_fvsysid_page_exists() -> None:
    import importlib

    page = (ROOT / "docs" / "from_sidpac_fvsysid.md").read_text(encoding="utf-8")
    names = set(re.findall(r"`(flightid(?:\.[A-Za-z_]\w*)+)", page))
    assert len(names) >= 15, names
    missing = []
    for name in sorted(names):
        parts = name.split(".")
        for split in range(len(parts), 0, -1):
            try:
                target = importlib.import_module(".".join(parts[:split]))
            except ImportError:
                continue
            try:
                for attribute in parts[split:]:
                    target = getattr(target, attribute)
            except AttributeError:
                missing.append(name)
            break
        else:
            missing.append(name)
    assert not missing, f"not in flightid: {missing}"


@pytest.mark.slow
def test_standard_case_tables_in_cases_md_match_what_the_script_prints() -> None:
    import os
    import subprocess
    import sys

    data_dir = Path(os.environ.get("FLIGHTID_DATA", ROOT.parent / "shared" / "data"))
    if not (data_dir / "fvsysid" / "hfb320_1_10.asc").is_file():
        pytest.skip(f"the FVSysID/SIDPAC data are not in {data_dir}")
    script = ROOT / "docs" / "standard_cases.py"
    done = subprocess.run(
        [sys.executable, str(script), "--data-dir", str(data_dir), "--check"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stdout + done.stderr


# The API reference renders the docstrings of src/flightid, and comments are read by users of
# the source: neither may cite the development notes, the shared folder or an issue number.
SOURCE_FORBIDDEN = {
    r"\bCASES\.md\b": "a development note users do not have",
    r"\bMETHOD\.md\b|\bMETHOD §": "a development note users do not have",
    r"\.\./shared/": "a path into the development machine's shared folder",
    r"(?i)\bissues? ?#?\d+": "an issue number (development history)",
}
# The default data folder is product behaviour: its constant may spell the path.
SOURCE_ALLOWED_LINE = "DEFAULT_DATA_DIR"
SOURCE_ROOT = ROOT / "src" / "flightid"


def docstring_and_comment_lines(source: str) -> list[tuple[int, str]]:
    """(line number, text) of every docstring line (module, class, function) and comment."""
    import ast
    import io
    import tokenize

    lines = []
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if not isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        if ast.get_docstring(node, clean=False) is None:
            continue
        first = node.body[0].value
        for offset, text in enumerate(first.value.splitlines()):
            lines.append((first.lineno + offset, text))
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT:
            lines.append((token.start[0], token.string))
    return lines


def source_offences(source: str) -> list[tuple[int, str, str]]:
    """(line number, matched text, reason) for each forbidden reference in a docstring or
    comment of source; a line of the source that names DEFAULT_DATA_DIR is exempt."""
    source_lines = source.splitlines()
    found = []
    for number, text in docstring_and_comment_lines(source):
        if SOURCE_ALLOWED_LINE in source_lines[number - 1]:
            continue
        for pattern, reason in SOURCE_FORBIDDEN.items():
            for match in re.finditer(pattern, text):
                found.append((number, match.group(0), reason))
    return found


def test_no_docstring_or_comment_cites_what_users_do_not_have() -> None:
    modules = sorted(SOURCE_ROOT.rglob("*.py"))
    assert len(modules) > 50, modules
    found = []
    for module in modules:
        for number, text, why in source_offences(module.read_text(encoding="utf-8")):
            where = module.relative_to(ROOT)
            found.append(f"{where}:{number}: {text!r} — {why}")
    assert not found, "\n".join(found)


@pytest.mark.parametrize(
    "source",
    [
        '"""Filter error (CASES.md §1b)."""\n',
        'class A:\n    """As METHOD.md §3 says."""\n',
        'def f():\n    """Scaled by importance\n    (METHOD §7)."""\n',
        "async def g():\n    '''The secant form (issue 14).'''\n",
        "x = 1  # data in ../shared/data\n",
        "def h():\n    # measured, Issue #14\n    return 1\n",
    ],
)
def test_each_forbidden_source_reference_is_caught(source: str) -> None:
    assert source_offences(source), source


@pytest.mark.parametrize(
    "source",
    [
        'DEFAULT_DATA_DIR = "../../../shared/data"  # ../shared/ beside the checkout\n',
        '"""A folder shared/data three levels above the case file\'s folder."""\n',
        'def f():\n    """FVSysID test case TC09 (Jategaonkar ch. 9); issue the warnings."""\n',
        'x = "CASES.md"  # a string, not a docstring or comment\n',
    ],
)
def test_ordinary_source_text_passes(source: str) -> None:
    assert not source_offences(source), source
