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


# SIDPAC fdata layout (1-based columns), data README "sidpac_twin_otter".
_DEG = np.pi / 180.0
LONGITUDINAL_CHANNELS = {
    # name: (column, scale to the unit used: rad, rad/s, g, ft/s, lbf/ft²)
    "V": (2, 1.0),
    "alpha": (4, _DEG),
    "p": (5, _DEG),
    "q": (6, _DEG),
    "r": (7, _DEG),
    "phi": (8, _DEG),
    "theta": (9, _DEG),
    "ax": (11, 1.0),
    "az": (13, 1.0),
    "de": (14, _DEG),
    "qbar": (27, 1.0),
}
CONSTANT_COLUMNS = {
    "mass": 48,
    "Ix": 49,
    "Iy": 50,
    "Iz": 51,
    "Ixz": 52,
    "S": 77,
    "b": 78,
    "cbar": 79,
}


def longitudinal_flight_data(path: str | Path, name: str = ""):
    """(FlightData, constants) of a SIDPAC longitudinal maneuver.

    Outputs alpha (rad), q (rad/s), az (g); inputs V (ft/s), qbar (lbf/ft²), theta, phi
    (rad), ax (g), p, r (rad/s), de (rad). Constants: the means of the mass (slug), inertia
    (slug·ft²) and geometry (ft², ft) columns, plus g = 32.174 ft/s².
    """
    from flightid.data.flightdata import FlightData

    fdata, _ = read_fdata(path)
    ch = {k: s * column(fdata, c, k) for k, (c, s) in LONGITUDINAL_CHANNELS.items()}
    time = column(fdata, 1, "time")
    time = time - time[0]
    outputs = {k: ch[k] for k in ("alpha", "q", "az")}
    inputs = {k: ch[k] for k in ("V", "qbar", "theta", "phi", "ax", "p", "r", "de")}
    constants = {k: float(np.mean(column(fdata, c, k))) for k, c in CONSTANT_COLUMNS.items()}
    constants["g"] = 32.174
    data = FlightData(time, inputs, outputs, name=name or Path(path).stem, uniform_rtol=1e-4)
    return data, constants
