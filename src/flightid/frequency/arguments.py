"""Argument checks of the public frequency-domain functions: a wrong type, shape or range is
an ``InputError`` naming the argument, what was expected and what came, instead of the
ValueError / TypeError / IndexError numpy or Python would raise somewhere inside."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from flightid.errors import InputError, describe

__all__ = [
    "boolean_mask",
    "checked_callable",
    "finite_number",
    "flag",
    "name_list",
    "positive_integer",
    "real_array",
]


def real_array(value: Any, argument: str, what: str = "real numbers") -> np.ndarray:
    """``value`` as a float array; ``InputError`` for None, strings, booleans, complex
    values (their imaginary part would be dropped) and anything not numeric."""
    if value is None or isinstance(value, (str, bytes, bool, np.bool_)):
        raise InputError(f"{argument}: expected {what}, got {describe(value)}")
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):
        raise InputError(f"{argument}: expected {what}, got {describe(value)}") from None
    if np.iscomplexobj(raw):
        raise InputError(
            f"{argument}: expected {what}, got complex values (the imaginary part would be lost)"
        )
    if raw.dtype == bool or raw.dtype.kind in "USV":
        raise InputError(f"{argument}: expected {what}, got {describe(value)}")
    try:
        return np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{argument}: expected {what}, got {describe(value)}") from None


def finite_number(value: Any, argument: str, *, positive: bool = False) -> float:
    """A finite real number (> 0 with ``positive``)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number)):
        raise InputError(f"{argument}: expected a number, got {describe(value)}")
    if isinstance(value, (complex, np.complexfloating)):
        raise InputError(f"{argument}: expected a real number, got {value!r}")
    number = float(value)
    if not np.isfinite(number) or (positive and number <= 0.0):
        raise InputError(
            f"{argument}: expected a finite number{' > 0' if positive else ''}, got {value!r}"
        )
    return number


def positive_integer(value: Any, argument: str) -> int:
    """An integer ≥ 1 (not a bool, not 2.0)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise InputError(f"{argument}: expected a positive integer, got {describe(value)}")
    if value < 1:
        raise InputError(f"{argument}: expected a positive integer, got {value!r}")
    return int(value)


def flag(value: Any, argument: str) -> bool:
    """True or False only (not 0, 1 or "no")."""
    if not isinstance(value, (bool, np.bool_)):
        raise InputError(f"{argument}: expected True or False, got {describe(value)}")
    return bool(value)


def name_list(value: Any, argument: str) -> tuple[str, ...]:
    """A sequence of strings (not one string)."""
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise InputError(f"{argument}: expected a sequence of names, got {describe(value)}")
    if not all(isinstance(v, str) for v in value):
        raise InputError(f"{argument}: expected names (strings), got {list(value)!r}")
    return tuple(value)


def boolean_mask(value: Any, argument: str, size: int) -> np.ndarray:
    """A boolean mask over θ of ``size`` entries (a list of True/False or a bool array)."""
    mask = np.asarray(value) if not isinstance(value, str) else None
    if mask is None or mask.dtype != bool or mask.shape != (size,):
        raise InputError(
            f"{argument}: expected a mask of the shape of theta_start ({size},), True or False "
            f"per parameter (True: estimated), got {describe(value)}"
        )
    return mask


def checked_callable(value: Any, argument: str) -> Callable:
    """A callable (a function θ → LinearSystem, typically)."""
    if not callable(value):
        raise InputError(f"{argument}: expected a function, got {describe(value)}")
    return value
