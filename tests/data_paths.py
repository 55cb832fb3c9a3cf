"""Where the tests find the real flight data, and the mark that skips a test without them.

The data directory is ``$FLIGHTID_DATA`` if set, else ``../shared/data`` beside the checkout
(the shipped cases' default, ``flightid.data.location``). A fresh clone has no such folder:
tests that read the real records skip there, naming what they missed, instead of failing.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("FLIGHTID_DATA", ROOT / ".." / "shared" / "data")).resolve()


def data_present(*relative: str) -> bool:
    """Whether every file or folder ``relative`` (to the data directory) exists."""
    return all((DATA / r).exists() for r in relative)


def needs_data(*relative: str) -> pytest.MarkDecorator:
    """Skip unless the data files or folders ``relative`` exist (default: ``fvsysid``)."""
    relative = relative or ("fvsysid",)
    missing = [r for r in relative if not (DATA / r).exists()]
    return pytest.mark.skipif(
        bool(missing),
        reason=f"flight data {missing} not found in {DATA} (set FLIGHTID_DATA)",
    )
