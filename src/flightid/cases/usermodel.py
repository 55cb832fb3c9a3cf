"""User models from Python files.

A model module defines, at module level::

    STATES = ("p", "r")                      # state names
    INPUTS = ("da", "dr", "beta")            # input channel names (looked up in the data)
    OUTPUTS = ("pdot", "rdot", "ay", "p", "r")
    PARAMETERS = {"Lp": -3.5, "Lr": 0.5}     # name → start value (order = θ's order),
                                             # or a list of names (start 0)
    def f(t, x, u, theta): ...               # dx/dt, 1-D array of len(STATES)
    def h(t, x, u, theta): ...               # y, 1-D array of len(OUTPUTS)

Lower-case names (``states``, ``inputs`` ...) are accepted too. Functions numba can compile
(plain arithmetic, ``math``, ``numpy`` arrays, module-level constants) run compiled.
The module is imported from its file (Python code the user wrote and chose to run); its
definitions are checked here and errors name the module and the missing or wrong item.
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

from flightid.cases.spec import CaseError

__all__ = ["UserModel", "load_user_model", "UserModelError"]


class UserModelError(CaseError):
    """A model module that cannot be imported or lacks a required definition."""


@dataclass(frozen=True)
class UserModel:
    """The definitions read from a model module."""

    path: Path
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    parameters: dict[str, float]
    f: Any
    h: Any
    module: ModuleType


def _get(module: ModuleType, name: str, path: Path) -> Any:
    for candidate in (name, name.lower()):
        if hasattr(module, candidate):
            return getattr(module, candidate)
    raise UserModelError(f"model.module {path.name}: missing the definition {name}")


def _names(value: Any, name: str, path: Path) -> tuple[str, ...]:
    if isinstance(value, str) or not isinstance(value, (list, tuple)):
        raise UserModelError(f"model.module {path.name}: {name} must be a list of names")
    for item in value:
        if not isinstance(item, str) or not item.isidentifier():
            raise UserModelError(f"model.module {path.name}: {name} holds {item!r}, not a name")
    return tuple(value)


def load_user_model(path: str | Path) -> UserModel:
    """Import a model module from a file and check its definitions."""
    path = Path(path).resolve()
    if not path.is_file():
        raise UserModelError(f"model.module: {path} does not exist")
    digest = hashlib.sha1(str(path).encode()).hexdigest()[:10]
    module_name = f"flightid_user_model_{path.stem}_{digest}"
    if module_name in sys.modules and getattr(sys.modules[module_name], "__file__", "") == str(
        path
    ):
        module = sys.modules[module_name]
    else:
        spec = importlib.util.spec_from_file_location(module_name, path)
        if spec is None or spec.loader is None:
            raise UserModelError(f"model.module: cannot import {path}")
        module = importlib.util.module_from_spec(spec)
        sys.modules[module_name] = module
        try:
            spec.loader.exec_module(module)
        except Exception as exc:
            del sys.modules[module_name]
            raise UserModelError(
                f"model.module {path.name}: importing it failed: {type(exc).__name__}: {exc}"
            ) from exc
    states = _names(_get(module, "STATES", path), "STATES", path)
    inputs = _names(_get(module, "INPUTS", path), "INPUTS", path)
    outputs = _names(_get(module, "OUTPUTS", path), "OUTPUTS", path)
    raw = _get(module, "PARAMETERS", path)
    if isinstance(raw, Mapping):
        parameters = {}
        for name, value in raw.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise UserModelError(
                    f"model.module {path.name}: PARAMETERS[{name!r}] must be a number, "
                    f"got {value!r}"
                )
            parameters[str(name)] = float(value)
    else:
        parameters = {name: 0.0 for name in _names(raw, "PARAMETERS", path)}
    f = _get(module, "f", path)
    h = _get(module, "h", path)
    for name, fn in (("f", f), ("h", h)):
        if not callable(fn):
            raise UserModelError(f"model.module {path.name}: {name} must be a function")
    return UserModel(path, states, inputs, outputs, parameters, f, h, module)
