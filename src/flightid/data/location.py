"""Where a case file's data files live.

Order: the command line (``--data-dir``), the environment variable ``FLIGHTID_DATA``, the
case's own ``data_dir`` (relative to the case file), else ``../../../shared/data`` relative to
the case file — the shared data beside a checkout, for the cases under ``examples/cases/``.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["DEFAULT_DATA_DIR", "data_directory"]

DEFAULT_DATA_DIR = "../../../shared/data"


def data_directory(
    case_directory: Path, given: str | None = None, override: str | Path | None = None
) -> Path:
    """The data directory of a case in ``case_directory`` (see the module docstring)."""
    if override is not None:
        return Path(override)
    if os.environ.get("FLIGHTID_DATA"):
        return Path(os.environ["FLIGHTID_DATA"])
    path = Path(DEFAULT_DATA_DIR if given is None else given)
    return path if path.is_absolute() else (case_directory / path).resolve()
