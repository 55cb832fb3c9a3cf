"""The test suite's own rules (docs/testing.md): deterministic Hypothesis, no catch-all raises."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from hypothesis import settings

TESTS = Path(__file__).resolve().parent


@pytest.mark.skipif(
    os.environ.get("HYPOTHESIS_PROFILE", "ci") != "ci", reason="an explicit exploration profile"
)
def test_hypothesis_runs_derandomised():
    # conftest.py loads the "ci" profile: the same examples on every run, no example database
    assert settings.default.derandomize is True
    assert settings.default.database is None


def test_no_catch_all_exception_checks():
    # pytest.raises(Exception) passes for any bug at all; tests name the error they expect
    pattern = re.compile(r"pytest\.raises\(\s*(Base)?Exception\s*[,)]")
    offenders = [
        f"{path.name}:{number}"
        for path in sorted(TESTS.glob("test_*.py"))
        if path.name != Path(__file__).name
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if pattern.search(line)
    ]
    assert offenders == []
