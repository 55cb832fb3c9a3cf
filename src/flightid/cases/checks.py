"""Checks shared by the case-file sections: each raises ``CaseError`` naming the key."""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Mapping
from typing import Any

from flightid.errors import InputError

__all__ = ["CaseError"]


class CaseError(InputError):
    """A malformed case file; the message starts with the offending key."""


def _table(value: Any, key: str) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise CaseError(f"{key}: expected a table ([{key}] or {{...}}), got {type(value).__name__}")
    return value


def _known(table: Mapping[str, Any], allowed: set[str], key: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        where = f"[{key}]" if key else "the top level"
        raise CaseError(
            f"{key + '.' if key else ''}{unknown[0]}: unknown key in {where}; "
            f"allowed keys: {sorted(allowed)}"
        )


def _number(value: Any, key: str, *, infinite: bool = False) -> float:
    """A TOML integer or float; NaN never, ±inf only where ``infinite`` (bounds, limits)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CaseError(f"{key}: expected a number, got {value!r}")
    number = float(value)
    if math.isnan(number) or (math.isinf(number) and not infinite):
        what = "a number (not NaN)" if infinite else "a finite number"
        raise CaseError(f"{key}: expected {what}, got {value!r}")
    return number


def _integer(value: Any, key: str, smallest: int | None = None) -> int:
    """A TOML integer (not 2.5, 3.0 or "3"), at least ``smallest``."""
    what = {None: "an integer", 0: "a non-negative integer", 1: "a positive integer"}.get(
        smallest, f"an integer ≥ {smallest}"
    )
    if isinstance(value, bool) or not isinstance(value, int):
        raise CaseError(f"{key}: expected {what}, got {value!r}")
    if smallest is not None and value < smallest:
        raise CaseError(f"{key}: expected {what}, got {value!r}")
    return value


def _bool(value: Any, key: str) -> bool:
    """TOML true / false only ("no", 0 and "false" are errors, not truthy values)."""
    if not isinstance(value, bool):
        raise CaseError(f"{key}: expected true or false, got {value!r}")
    return value


def _string(value: Any, key: str, choices: tuple[str, ...] | None = None) -> str:
    if not isinstance(value, str):
        raise CaseError(f"{key}: expected a string, got {value!r}")
    if choices is not None and value not in choices:
        raise CaseError(f"{key}: expected one of {list(choices)}, got {value!r}")
    return value


def _optional_string(value: Any, key: str) -> str | None:
    return None if value is None else _string(value, key)


def _names(value: Any, key: str) -> list[str]:
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise CaseError(f"{key}: expected a list of names (strings), got {value!r}")
    return value


def _typed(value: Any, hint: Any, key: str) -> None:
    """Check ``value`` against a dataclass field's type (bool, int, float, str, X | None)."""
    arguments = [a for a in typing.get_args(hint) if a is not type(None)]
    if typing.get_origin(hint) in (typing.Union, types.UnionType) and len(arguments) == 1:
        hint = arguments[0]  # TOML has no null: X | None means X here
    if hint is bool:
        _bool(value, key)
    elif hint is int:
        _integer(value, key)
    elif hint is float:
        _number(value, key, infinite=True)
    elif hint is str:
        _string(value, key)


def _settings(table: Mapping[str, Any], cls: type, key: str) -> None:
    """The keys of ``table`` are fields of the dataclass ``cls``, each of its type."""
    try:
        hints = typing.get_type_hints(cls)
    except Exception:  # an annotation that cannot be resolved: leave the check to cls
        hints = {}
    fields = {f.name: hints.get(f.name) for f in dataclasses.fields(cls) if f.init}
    for name, value in table.items():
        if name not in fields:
            raise CaseError(
                f"{key}.{name}: not a setting of {cls.__name__}; its settings: {sorted(fields)}"
            )
        _typed(value, fields[name], f"{key}.{name}")
