"""User models from Python files.

A model module defines, at module level::

    STATES = ("p", "r")                      # state names
    INPUTS = ("da", "dr", "beta")            # input channel names (looked up in the data)
    OUTPUTS = ("pdot", "rdot", "ay", "p", "r")
    PARAMETERS = {"Lp": -3.5, "Lr": 0.5}     # name → start value (order = θ's order),
                                             # or a list of names (start 0)
    def f(t, x, u, theta): ...               # dx/dt, 1-D array of len(STATES)
    def h(t, x, u, theta): ...               # y, 1-D array of len(OUTPUTS)

A model without states (outputs that are algebraic functions of the inputs: regression by
output error) sets ``STATES = ()`` and may leave ``f`` out (or set ``f = None``).

Lower-case names (``states``, ``inputs`` ...) are accepted too. Functions numba can compile
(plain arithmetic, ``math``, ``numpy`` arrays, module-level constants) run compiled.
**Loading a model module executes it**: the file is imported as Python code (whatever it
does at import time runs with the user's rights), exactly as ``python model.py`` would. Its
definitions are checked here; errors are ``UserModelError`` (a ``CaseError`` and a
``ModelError``) naming the file, the line (for errors while importing it) and the missing or
wrong item. Whether ``f`` and ``h`` keep their contract on the data is checked by
``flightid.model.check_model``.
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
import traceback
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

from flightid.cases.spec import CaseError
from flightid.errors import ModelError

__all__ = ["UserModel", "load_user_model", "UserModelError"]


class UserModelError(CaseError, ModelError):
    """A model module that cannot be imported or lacks a required definition."""


def _import_failure(path: Path, exc: BaseException) -> UserModelError:
    """'model.module m.py line 3: SyntaxError: ... — `x = = 1`' for an error while importing.

    The line is the one of the model file where the error arose: the syntax error's own
    position, or the innermost traceback frame in the model file (an ``import`` of a missing
    package, a ``NameError`` at module level ...).
    """
    line, text = None, None
    if isinstance(exc, SyntaxError) and exc.filename and Path(exc.filename) == path:
        line, text = exc.lineno, exc.text
    else:
        for frame in traceback.extract_tb(exc.__traceback__):
            if frame.filename and Path(frame.filename) == path:
                line, text = frame.lineno, frame.line
    where = f" line {line}" if line is not None else ""
    code = f" — `{text.strip()}`" if text and text.strip() else ""
    message = exc.msg if isinstance(exc, SyntaxError) else str(exc)
    return UserModelError(
        f"model.module {path.name}{where}: importing it failed: "
        f"{type(exc).__name__}: {message}{code} ({path})"
    )


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


def _has(module: ModuleType, name: str) -> bool:
    return any(hasattr(module, candidate) for candidate in (name, name.lower()))


def _names(value: Any, name: str, path: Path) -> tuple[str, ...]:
    if isinstance(value, str) or not isinstance(value, (list, tuple)):
        raise UserModelError(f"model.module {path.name}: {name} must be a list of names")
    for item in value:
        if not isinstance(item, str) or not item.isidentifier():
            raise UserModelError(f"model.module {path.name}: {name} holds {item!r}, not a name")
    return tuple(value)


def import_model_module(path: str | Path) -> ModuleType:
    """Import a Python file as a module, once per process, registered in ``sys.modules``.

    The module's name is derived from the file's absolute path, so every caller that imports
    the same file gets the same module — flightid for ``[model] module``, and a model file
    that builds on another one::

        from pathlib import Path
        from flightid.cases.usermodel import import_model_module

        _base = import_model_module(Path(__file__).with_name("attas_short_period.py"))
        f, h = _base.f, _base.h

    Registered, because numba finds the module of a compiled function's globals by name when
    it loads the function's kernels from its disk cache: a module imported by path and not
    registered recompiles them in every process. Raises ``UserModelError`` if the file does
    not exist or its import fails (the message names the file and the error).
    """
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
        except (Exception, SystemExit) as exc:
            # SystemExit: a module that calls sys.exit() / exit() at import time
            del sys.modules[module_name]
            raise _import_failure(path, exc) from exc
    return module


def load_user_model(path: str | Path) -> UserModel:
    """Import a model module from a file (``import_model_module``) and check its
    definitions."""
    path = Path(path).resolve()
    module = import_model_module(path)
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
    # no states: f may be left out (None); StateSpaceModel puts the empty derivative there
    f = _get(module, "f", path) if states or _has(module, "f") else None
    h = _get(module, "h", path)
    for name, fn in (("f", f), ("h", h)):
        if fn is None and name == "f" and not states:
            continue
        if not callable(fn):
            raise UserModelError(f"model.module {path.name}: {name} must be a function")
    return UserModel(path, states, inputs, outputs, parameters, f, h, module)
