"""Where a case file's data files live.

Order, most specific first: the command line (``--data-dir``), the case's own ``data_dir``
(relative to the case file), the environment variable ``FLIGHTID_DATA``, else
``DEFAULT_DATA_DIR``: a folder ``shared/data`` three levels above the case file's folder.
For the cases under ``examples/cases/`` that is a folder ``shared/data`` beside the
checkout; they give no ``data_dir``, so that ``FLIGHTID_DATA`` can point them to wherever
the data files are. A case that keeps its data beside itself (``data_dir = "."``) is
not redirected by ``FLIGHTID_DATA``.
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
    if given is None and os.environ.get("FLIGHTID_DATA"):
        return Path(os.environ["FLIGHTID_DATA"])
    path = Path(DEFAULT_DATA_DIR if given is None else given)
    return path if path.is_absolute() else (case_directory / path).resolve()
