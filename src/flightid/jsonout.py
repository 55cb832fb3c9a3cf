"""Strict JSON for every document flightid writes (results.json, ``--json`` output), in the
shared core so that every result can write its own JSON.

JSON (RFC 8259) has no NaN or infinity; Python's ``json`` writes them as ``NaN`` /
``Infinity`` unless told not to, and such files are rejected by strict readers. Here every
non-finite number becomes ``null`` and the reason is kept beside the data: the top-level
object gains a key ``"nonfinite"`` mapping the JSON Pointer (RFC 6901) of each such value to
what it was::

    {"results": [{..., "prediction": [{"r2": [0.97, null]}]}],
     "nonfinite": {"/results/0/prediction/0/r2/1": "NaN"}}

The key is only present when something was replaced. Documents are then written with
``allow_nan=False``, so a non-finite number that slips past the conversion is an error,
not an invalid file. numpy scalars and arrays are converted to plain Python values.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["NONFINITE_KEY", "strict", "dumps"]

NONFINITE_KEY = "nonfinite"


def _pointer_part(key: object) -> str:
    # RFC 6901: "~" is written "~0" and "/" is written "~1"
    return str(key).replace("~", "~0").replace("/", "~1")


def _label(value: float) -> str:
    if math.isnan(value):
        return "NaN"
    return "inf" if value > 0 else "-inf"


def _convert(value: Any, path: str, found: dict[str, str]) -> Any:
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        number = float(value)
        if math.isfinite(number):
            return number
        found[path or "/"] = _label(number)
        return None
    if isinstance(value, (str, type(None))):
        return value
    if isinstance(value, Mapping):
        return {str(k): _convert(v, f"{path}/{_pointer_part(k)}", found) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return [_convert(v, f"{path}/{i}", found) for i, v in enumerate(value)]
    raise TypeError(f"JSON output: cannot write a {type(value).__name__} at {path or '/'}")


def strict(document: Any) -> Any:
    """``document`` with plain Python values only and every NaN / ±inf replaced by None.

    When ``document`` is a mapping and something was replaced, the result carries
    ``"nonfinite": {pointer: "NaN" | "inf" | "-inf"}`` (see the module docstring).
    """
    found: dict[str, str] = {}
    result = _convert(document, "", found)
    if found and isinstance(result, dict):
        result[NONFINITE_KEY] = found
    return result


def dumps(document: Any, indent: int | None = 2) -> str:
    """Strict JSON text of ``document`` (``strict`` first, then ``allow_nan=False``)."""
    return json.dumps(strict(document), indent=indent, allow_nan=False)
