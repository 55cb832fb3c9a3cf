"""Named model parameters: value, free/fixed, scale and bounds.

The estimation works on the vector of *free* parameter values; fixed parameters keep their
values and are passed to the model functions unchanged. ``scale`` is the typical magnitude of
a parameter: it sets the floor of the relative-change convergence test (so that a parameter
whose true value is 0 can still converge) and the size of the first finite-difference and
MNRES perturbations.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from flightid.errors import InputError, InputTypeError, describe

__all__ = ["Parameter", "Parameters"]


def _check_name(name: object, argument: str) -> str:
    if not isinstance(name, str) or not name.isidentifier():
        raise InputError(
            f"{argument}: expected a parameter name that is a Python identifier "
            f"(letters, digits, underscore), got {describe(name)}"
        )
    return name


def _real(value: object, argument: str, *, infinite: bool = False) -> float:
    """``value`` as a float: a real number (Python or numpy, or a 0-d real array); bools,
    strings, complex numbers and other objects are an ``InputTypeError``; NaN, and ±inf
    unless ``infinite``, an ``InputError``."""
    real = isinstance(value, numbers.Real) or (
        isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf"
    )
    if isinstance(value, (bool, np.bool_)) or not real:
        raise InputTypeError(f"{argument}: expected a real number, got {describe(value)}")
    number = float(value)
    if math.isnan(number) or (math.isinf(number) and not infinite):
        raise InputError(
            f"{argument}: expected a {'number (not NaN)' if infinite else 'finite number'}, "
            f"got {number}"
        )
    return number


@dataclass(frozen=True)
class Parameter:
    """One model parameter.

    Attributes:
        name: identifier, e.g. ``"Cl_beta"``.
        value: current (start) value, in the parameter's own unit.
        free: True if the parameter is estimated, False if held fixed.
        scale: typical magnitude (> 0), in the parameter's unit; when None, ``typical`` is
            ``max(|value|, 1e-3)``.
        lower, upper: optional bounds used by the search methods (not by the Newton steps).
        unit: free text, for reports.
    """

    name: str
    value: float
    free: bool = True
    scale: float | None = None
    lower: float = -math.inf
    upper: float = math.inf
    unit: str = ""

    def __post_init__(self) -> None:
        _check_name(self.name, "Parameter.name")
        where = f"Parameter {self.name!r}"
        value = _real(self.value, f"{where}: value")
        object.__setattr__(self, "value", value)
        if not isinstance(self.free, (bool, np.bool_)):
            raise InputTypeError(f"{where}: free must be True or False, got {describe(self.free)}")
        object.__setattr__(self, "free", bool(self.free))
        if self.scale is not None:
            scale = _real(self.scale, f"{where}: scale")
            if scale <= 0:
                raise InputError(
                    f"{where}: scale must be a positive finite number, got {self.scale!r}"
                )
            object.__setattr__(self, "scale", scale)
        for bound in ("lower", "upper"):
            object.__setattr__(
                self, bound, _real(getattr(self, bound), f"{where}: {bound}", infinite=True)
            )
        if not isinstance(self.unit, str):
            raise InputTypeError(f"{where}: unit must be a string, got {describe(self.unit)}")
        if not self.lower <= value <= self.upper:
            raise InputError(
                f"Parameter {self.name!r}: value {value} lies outside its bounds "
                f"[{self.lower}, {self.upper}]"
            )

    @property
    def typical(self) -> float:
        """Typical magnitude: ``scale`` if given, else ``max(|value|, 1e-3)``."""
        if self.scale is not None:
            return float(self.scale)
        return max(abs(self.value), 1e-3)


class Parameters(Sequence[Parameter]):
    """An ordered, immutable collection of named parameters.

    Build it from ``Parameter`` objects, from ``(name, value)`` pairs or from a mapping
    ``{name: value}``. ``with_values`` returns a copy with new values.
    """

    def __init__(self, items: Iterable[Parameter | tuple] | Mapping[str, float]) -> None:
        if isinstance(items, Parameters):
            params = list(items)
        elif isinstance(items, Mapping):
            params = [Parameter(name, value) for name, value in items.items()]
        elif isinstance(items, (str, bytes)) or not isinstance(items, Iterable):
            raise InputTypeError(
                "parameters: expected Parameter objects, (name, value) tuples or a mapping "
                f"{{name: value}}, got {describe(items)}"
            )
        else:
            params = []
            for item in items:
                if isinstance(item, Parameter):
                    params.append(item)
                elif isinstance(item, tuple):
                    params.append(Parameter(*item))
                else:
                    raise InputTypeError(
                        f"parameters: expected Parameter objects or (name, value) tuples, "
                        f"got {describe(item)}"
                    )
        names = [p.name for p in params]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise InputError(f"parameters: names must be unique, repeated: {duplicates}")
        self._items: tuple[Parameter, ...] = tuple(params)
        self._index = {p.name: i for i, p in enumerate(params)}

    # Sequence protocol -------------------------------------------------------------
    def __len__(self) -> int:
        return len(self._items)

    def __getitem__(self, key):  # type: ignore[override]
        if isinstance(key, str):
            try:
                return self._items[self._index[key]]
            except KeyError:
                raise KeyError(
                    f"no parameter named {key!r}; known parameters: {list(self._index)}"
                ) from None
        return self._items[key]

    def __iter__(self) -> Iterator[Parameter]:
        return iter(self._items)

    def __contains__(self, name: object) -> bool:
        return name in self._index

    def __repr__(self) -> str:
        inner = ", ".join(f"{p.name}={p.value:g}{'' if p.free else ' (fixed)'}" for p in self)
        return f"Parameters({inner})"

    # Views ---------------------------------------------------------------------------
    @property
    def names(self) -> list[str]:
        return [p.name for p in self._items]

    def index(self, name: str) -> int:  # type: ignore[override]
        """Position of parameter ``name`` in the full vector."""
        if name not in self._index:
            raise KeyError(f"no parameter named {name!r}; known parameters: {list(self._index)}")
        return self._index[name]

    @property
    def values(self) -> np.ndarray:
        """Full parameter vector (free and fixed), float64."""
        return np.array([p.value for p in self._items], dtype=float)

    @property
    def free_mask(self) -> np.ndarray:
        return np.array([p.free for p in self._items], dtype=bool)

    @property
    def free_names(self) -> list[str]:
        return [p.name for p in self._items if p.free]

    @property
    def typical(self) -> np.ndarray:
        return np.array([p.typical for p in self._items], dtype=float)

    # Copies --------------------------------------------------------------------------
    def with_values(self, values: Mapping[str, float] | np.ndarray) -> Parameters:
        """Copy with new values, from a full vector or a ``{name: value}`` mapping."""
        if isinstance(values, Mapping):
            unknown = sorted(set(values) - set(self._index))
            if unknown:
                raise InputError(f"values: unknown parameter names {unknown}; known: {self.names}")
            return Parameters(
                replace(p, value=float(values[p.name])) if p.name in values else p for p in self
            )
        vector = np.asarray(values, dtype=float)
        if vector.shape != (len(self),):
            raise InputError(
                f"values: expected a vector of length {len(self)}, got shape {vector.shape}"
            )
        return Parameters(replace(p, value=float(v)) for p, v in zip(self, vector, strict=True))

    def with_free(self, names: Iterable[str], free: bool = True) -> Parameters:
        """Copy with the named parameters set free (or fixed when ``free=False``)."""
        chosen = set(names)
        unknown = sorted(chosen - set(self._index))
        if unknown:
            raise InputError(f"names: unknown parameter names {unknown}; known: {self.names}")
        return Parameters(replace(p, free=free) if p.name in chosen else p for p in self)

    def __add__(self, other: Parameters) -> Parameters:
        return Parameters(list(self) + list(other))
