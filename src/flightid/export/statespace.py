"""A linear model (``flightid.model.linearization.LinearModel``) as files other tools read:
JSON and NumPy ``.npz`` (``write_statespace``), MATLAB ``.mat`` (``write_mat``).

Every file holds the same content, in deviations from the operating point:

    dx/dt = A (x − x0) + B (u − u0) + f0,    y = C (x − x0) + D (u − u0) + y0

A, B, C, D; the names and units of the states, inputs and outputs; the operating point (x0,
u0, t0, f0 = f(x0, u0), y0 = h(x0, u0)) and how it was chosen; the covariance of vec(A, B,
C, D) (row-major blocks in that order; absent without one) and σ of every entry; the modes
with their σ; the notes (what the linear model leaves out). ``read_statespace`` reads a JSON
or NPZ file back into a ``LinearModel`` (the round trip is exact: floats are written with
all their digits).

MATLAB names (``write_mat``): ``A``, ``B``, ``C``, ``D``, ``A_std`` …, ``StateName``,
``InputName``, ``OutputName`` (cell arrays of char, as ``ss(A, B, C, D, 'StateName',
StateName, …)`` takes them), ``StateUnit``, ``InputUnit``, ``OutputUnit``, ``x0``, ``u0``,
``f0``, ``y0``, ``t0``, ``Covariance``, ``OperatingPoint``, ``Notes``, and per mode
``ModeName``, ``ModeEigenvalue`` (complex, 1/s), ``ModeEigenvalueStd`` (σ of real and
imaginary part), ``ModeNaturalFrequency`` (rad/s), ``ModeDampingRatio``,
``ModeTimeConstant``, ``ModeTimeToHalf``, ``ModeTimeToDouble`` (s), each with ``…Std``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from flightid.export.files import ExportError, write_exports
from flightid.model.linearization import LinearModel

__all__ = ["read_statespace", "statespace_paths", "write_mat", "write_statespace"]

FORMAT = "flightid-statespace"
FORMAT_VERSION = 1
_BLOCKS = ("A", "B", "C", "D")
_NAMES = ("states", "inputs", "outputs", "state_units", "input_units", "output_units")
# Mode attribute → MATLAB name (each also with "Std")
_MODE_FIELDS = (
    ("natural_frequency", "ModeNaturalFrequency"),
    ("damping_ratio", "ModeDampingRatio"),
    ("time_constant", "ModeTimeConstant"),
    ("time_to_half", "ModeTimeToHalf"),
    ("time_to_double", "ModeTimeToDouble"),
)


def _check_linear_model(linear: object) -> LinearModel:
    if not isinstance(linear, LinearModel):
        raise ExportError(
            "linear_model: expected a LinearModel (Estimate.linearize), got "
            f"{type(linear).__name__}"
        )
    return linear


def statespace_paths(path: str | Path) -> tuple[Path, Path]:
    """The JSON and NPZ file of ``write_statespace(…, path)``: ``path`` with the suffixes
    .json and .npz (a suffix .json or .npz given is replaced, any other kept: ``m.v1`` →
    ``m.v1.json``, ``m.v1.npz``)."""
    path = Path(path)
    stem = path.with_suffix("") if path.suffix in (".json", ".npz") else path
    return stem.with_name(stem.name + ".json"), stem.with_name(stem.name + ".npz")


def statespace_document(linear: LinearModel) -> dict:
    """The JSON document of ``write_statespace``."""
    linear = _check_linear_model(linear)
    entry = linear.to_dict()
    entry["covariance"] = None if linear.covariance is None else linear.covariance.tolist()
    return {"format": FORMAT, "format_version": FORMAT_VERSION, **entry}


def _npz_arrays(linear: LinearModel) -> dict[str, np.ndarray]:
    arrays: dict[str, np.ndarray] = {
        "format": np.array(FORMAT),
        "format_version": np.array(FORMAT_VERSION),
        "name": np.array(linear.name),
        "operating_point": np.array(linear.operating_point),
        "notes": np.array(list(linear.notes), dtype=str),
        "x0": np.asarray(linear.x0),
        "u0": np.asarray(linear.u0),
        "f0": np.asarray(linear.f0),
        "y0": np.asarray(linear.y0),
        "t0": np.array(float(linear.t0)),
        # the modes as their JSON entries (names, σ, participation)
        "modes_json": np.array(json.dumps(linear.modes().to_dict())),
    }
    for key in _NAMES:
        arrays[key] = np.array(list(getattr(linear, key)), dtype=str)
    for block in _BLOCKS:
        arrays[block] = np.asarray(getattr(linear, block))
        arrays[f"{block}_std"] = linear.block_std(block)
    if linear.covariance is not None:
        arrays["covariance"] = np.asarray(linear.covariance)
    return arrays


def write_statespace(
    linear_model: LinearModel, path: str | Path, *, overwrite: bool = False
) -> list[Path]:
    """Write ``linear_model`` as JSON and NPZ (``statespace_paths(path)``); returns both
    paths. Existing files are replaced only with ``overwrite`` and only when flightid
    exported them (``flightid.export.files``)."""
    from flightid.jsonout import dumps

    linear = _check_linear_model(linear_model)
    json_path, npz_path = statespace_paths(path)
    text = dumps(statespace_document(linear)) + "\n"
    arrays = _npz_arrays(linear)

    def write_npz(tmp: Path) -> None:
        with open(tmp, "wb") as stream:
            np.savez(stream, **arrays)

    return write_exports(
        {json_path: lambda tmp: tmp.write_text(text, encoding="utf-8"), npz_path: write_npz},
        overwrite,
    )


def _strings(value) -> tuple[str, ...]:
    return tuple(str(v) for v in np.asarray(value).ravel())


def read_statespace(path: str | Path) -> LinearModel:
    """The ``LinearModel`` in a JSON or NPZ file of ``write_statespace``."""
    path = Path(path)
    if path.suffix == ".npz":
        with np.load(path, allow_pickle=False) as data:
            if str(data["format"]) != FORMAT:
                raise ExportError(f"{path}: expected a {FORMAT} file, got {data['format']}")
            fields = {k: data[k] for k in data.files}
        covariance = fields.get("covariance")
        return LinearModel(
            *(fields[b] for b in _BLOCKS),
            **{key: _strings(fields[key]) for key in _NAMES},
            x0=fields["x0"],
            u0=fields["u0"],
            f0=fields["f0"],
            y0=fields["y0"],
            t0=float(fields["t0"]),
            covariance=covariance,
            operating_point=str(fields["operating_point"]),
            notes=_strings(fields["notes"]),
            name=str(fields["name"]),
        )
    document = json.loads(path.read_text(encoding="utf-8"))
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise ExportError(f"{path}: expected a {FORMAT} JSON document")
    point = document["operating_point"]
    shapes = {
        "A": (len(document["states"]), len(document["states"])),
        "B": (len(document["states"]), len(document["inputs"])),
        "C": (len(document["outputs"]), len(document["states"])),
        "D": (len(document["outputs"]), len(document["inputs"])),
    }
    return LinearModel(
        *(np.array(document[b], dtype=float).reshape(shapes[b]) for b in _BLOCKS),
        **{key: tuple(document[key]) for key in _NAMES},
        x0=np.array(point["x"], dtype=float),
        u0=np.array(point["u"], dtype=float),
        f0=np.array(point["f"], dtype=float),
        y0=np.array(point["y"], dtype=float),
        t0=float(point["t_s"]),
        covariance=None
        if document.get("covariance") is None
        else np.array(document["covariance"], dtype=float),
        operating_point=point["description"],
        notes=tuple(document.get("notes", ())),
        name=document["name"],
    )


def _cell(values) -> np.ndarray:
    """A MATLAB cell array (column) of char from a list of strings."""
    cell = np.empty((len(values), 1), dtype=object)
    for i, value in enumerate(values):
        cell[i, 0] = str(value)
    return cell


def mat_variables(linear: LinearModel) -> dict[str, object]:
    """The MATLAB variables of ``write_mat`` (module docstring)."""
    linear = _check_linear_model(linear)
    variables: dict[str, object] = {}
    for block in _BLOCKS:
        variables[block] = np.asarray(getattr(linear, block), dtype=float)
        variables[f"{block}_std"] = linear.block_std(block)
    for key, name in (("states", "State"), ("inputs", "Input"), ("outputs", "Output")):
        variables[f"{name}Name"] = _cell(getattr(linear, key))
        variables[f"{name}Unit"] = _cell(getattr(linear, f"{key[:-1]}_units"))
    for key in ("x0", "u0", "f0", "y0"):
        variables[key] = np.asarray(getattr(linear, key), dtype=float).reshape(-1, 1)
    variables["t0"] = float(linear.t0)
    variables["Covariance"] = (
        np.zeros((0, 0)) if linear.covariance is None else np.asarray(linear.covariance)
    )
    variables["OperatingPoint"] = linear.operating_point
    variables["Notes"] = _cell(linear.notes)
    variables["Name"] = linear.name
    modes = list(linear.modes())
    variables["ModeName"] = _cell([m.name for m in modes])
    variables["ModeEigenvalue"] = np.array([m.eigenvalue for m in modes], dtype=complex).reshape(
        -1, 1
    )
    variables["ModeEigenvalueStd"] = np.array(
        [m.eigenvalue_std for m in modes], dtype=float
    ).reshape(-1, 2)
    for attribute, name in _MODE_FIELDS:
        variables[name] = np.array([getattr(m, attribute) for m in modes]).reshape(-1, 1)
        variables[f"{name}Std"] = np.array([getattr(m, f"{attribute}_std") for m in modes]).reshape(
            -1, 1
        )
    return variables


def write_mat(linear_model: LinearModel, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write ``linear_model`` as a MATLAB .mat file (version 5, ``scipy.io.savemat``) with the
    variables of the module docstring; returns the path (``.mat`` appended when missing)."""
    from scipy.io import savemat

    variables = mat_variables(linear_model)
    path = Path(path)
    if path.suffix != ".mat":
        path = path.with_name(path.name + ".mat")

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as stream:
            savemat(stream, variables, oned_as="column")

    (written,) = write_exports({path: write}, overwrite)
    return written
