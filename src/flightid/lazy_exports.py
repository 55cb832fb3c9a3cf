"""A package's public names loaded on first use (PEP 562 module ``__getattr__``).

A package whose ``__init__`` imported every submodule would load numpy, scipy, numba or
matplotlib for a command that uses none of its names (``flightid --help``, ``flightid
validate``). Such a package keeps, instead, a table ``_LAZY_EXPORTS`` (public name → module
that defines it) and ends with::

    __getattr__, __dir__ = lazy_exports(__name__, _LAZY_EXPORTS)

A name is imported when it is first read and then kept in the package's namespace. Importing
a submodule that defines an export of the same name (``flightid.cases.load_run`` defines
``load_run``) binds the export, not the submodule, to the package's name — as an eager
``from .load_run import load_run`` did.
"""

from __future__ import annotations

import importlib
import sys
import types
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_exports"]

# the package global holding its table of public name → module
_TABLE = "_LAZY_EXPORTS"


class _LazyPackage(types.ModuleType):
    """A package with a lazy export table: a submodule bound under an export's name is
    replaced by the export (see the module docstring)."""

    def __setattr__(self, name: str, value: Any) -> None:
        exports = self.__dict__.get(_TABLE, {})
        if isinstance(value, types.ModuleType) and exports.get(name) == value.__name__:
            value = getattr(value, name)
        super().__setattr__(name, value)


def lazy_exports(
    package: str, exports: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module ``__getattr__`` and ``__dir__`` of ``package`` (its ``__name__``) for the
    table ``exports`` (public name → defining module, the package's ``_LAZY_EXPORTS``)."""
    module = sys.modules[package]
    module.__class__ = _LazyPackage

    def __getattr__(name: str) -> Any:
        """Import an export on first use and keep it in the package namespace."""
        module_name = exports.get(name)
        if module_name is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module_name), name)
        module.__dict__[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(module.__dict__) | set(exports))

    return __getattr__, __dir__
