"""Private reader of SIDPAC-style MATLAB files (``fdata`` matrix + ``varlab`` labels).

Kept small and private to the regression package; ``flightid.data.loaders`` is the general
loader. Columns are 1-based in the SIDPAC documentation and in case files.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.io import loadmat

from flightid.errors import InputError


def read_fdata(path: str | Path) -> tuple[np.ndarray, list[str]]:
    """(fdata (N, k), labels) of a SIDPAC .mat file."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"data file: {str(path)!r} does not exist")
    try:
        content = loadmat(path)
    except Exception as exc:  # scipy raises several classes for bad files
        raise InputError(f"data file: cannot read {str(path)!r} as MATLAB: {exc}") from None
    if "fdata" not in content:
        raise InputError(
            f"data file: {str(path)!r} has no 'fdata' matrix; variables: "
            f"{sorted(k for k in content if not k.startswith('__'))}"
        )
    fdata = np.asarray(content["fdata"], dtype=float)
    labels = [str(x).strip() for x in np.ravel(content.get("varlab", []))]
    return fdata, labels


def column(fdata: np.ndarray, number: int, where: str) -> np.ndarray:
    """1-based column ``number`` of fdata."""
    if not isinstance(number, int) or isinstance(number, bool):
        raise InputError(f"{where}: expected a 1-based column number, got {number!r}")
    if not 1 <= number <= fdata.shape[1]:
        raise InputError(f"{where}: column {number} outside 1..{fdata.shape[1]}")
    return fdata[:, number - 1].copy()
