"""The explanatory space of a global model: its variables, their scales and their box.

Two coordinate systems are used over the same variables x_1 … x_m (signal units):

    scaled (the modelling functions):   u_k = x_k / h_k,          h_k = max_i |x_k(i)|
    support (distances between points): v_k = (x_k − c_k) / r_k,  c_k = (max + min)/2,
                                                                  r_k = (max − min)/2

Scaling without centring keeps a monomial in u the same monomial in x, so a model found in
scaled variables reads in raw units after a diagonal rescaling of its parameters. The support
coordinates put every variable on [−1, 1] over the data, so that a distance weighs a radian of
α and a unit of Mach by their ranges, not by their units.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from flightid.errors import InputError, describe

__all__ = ["GlobalModelError", "Normalisation", "points_matrix", "check_series"]


class GlobalModelError(InputError):
    """A global-model set-up or prediction input is malformed; the message names the key,
    what was expected and what came."""


def check_series(
    values: object,
    key: str,
    n_samples: int | None = None,
    *,
    error: type[Exception] = GlobalModelError,
    scalar: bool = True,
) -> np.ndarray:
    """``values`` as a finite float series (N,), of ``n_samples`` entries when given; a
    scalar is a series of one entry where ``scalar`` is true.

    Raises:
        error (GlobalModelError by default): not one-dimensional, wrong length, or
            non-finite entries, naming ``key``.
    """
    try:
        series = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise error(f"{key}: expected a series of numbers, got {describe(values)}") from None
    if series.ndim == 0 and scalar:
        series = series[None]
    if series.ndim != 1:
        raise error(f"{key}: expected a one-dimensional series, got {describe(values)}")
    if n_samples is not None and series.shape[0] != n_samples:
        raise error(
            f"{key}: expected {n_samples} samples, got {series.shape[0]} (as the other series)"
        )
    bad = np.flatnonzero(~np.isfinite(series))
    if bad.size:
        raise error(
            f"{key}: expected finite values, got {series[bad[0]]} at sample {int(bad[0])} "
            f"({bad.size} non-finite in all)"
        )
    return series


def points_matrix(points: Mapping[str, object], names: Sequence[str]) -> np.ndarray:
    """The points (n, m) as a matrix, one column per variable of ``names`` (signal units).

    A scalar stands for a constant over the points (``{"alpha": grid, "Mach": 0.6}``).

    Raises:
        GlobalModelError: ``points`` is not a mapping, a variable is missing, series of
            different lengths, or non-finite values, naming the variable.
    """
    if not isinstance(points, Mapping):
        raise GlobalModelError(
            f"points: expected a mapping {{variable: values}}, got {describe(points)}"
        )
    missing = [name for name in names if name not in points]
    if missing:
        raise GlobalModelError(
            f"points: expected every model variable {list(names)}, missing {missing}"
        )
    arrays = {name: np.asarray(points[name], dtype=float) for name in names}
    lengths = {a.size for a in arrays.values() if a.ndim > 0}
    if len(lengths) > 1:
        sizes = {name: int(a.size) for name, a in arrays.items()}
        raise GlobalModelError(f"points: expected series of one length, got {sizes}")
    n = lengths.pop() if lengths else 1
    columns = []
    for name, array in arrays.items():
        column = np.full(n, float(array)) if array.ndim == 0 else array.ravel()
        columns.append(check_series(column, f"points[{name!r}]", n))
    return np.column_stack(columns)


@dataclass(frozen=True)
class Normalisation:
    """Scales and box of the explanatory variables (module docstring).

    Attributes:
        names: the variables, in model order.
        scale: h_k = max |x_k| over the data (1 where the variable is identically 0), signal
            units.
        low, high: the data's minimum and maximum of each variable, signal units.
        units: unit of each variable (``""`` where unknown).
    """

    names: tuple[str, ...]
    scale: np.ndarray
    low: np.ndarray
    high: np.ndarray
    units: tuple[str, ...]

    @classmethod
    def from_data(
        cls, signals: Mapping[str, np.ndarray], names: Sequence[str], units=None
    ) -> Normalisation:
        """Scales and box of the variables ``names`` over ``signals`` (finite series)."""
        units = dict(units or {})
        matrix = np.column_stack([np.asarray(signals[name], dtype=float) for name in names])
        # h_k = max_i |x_k(i)|
        scale = np.max(np.abs(matrix), axis=0)
        scale[scale == 0] = 1.0
        return cls(
            names=tuple(names),
            scale=scale,
            low=matrix.min(axis=0),
            high=matrix.max(axis=0),
            units=tuple(str(units.get(name, "")) for name in names),
        )

    def to_unit(self, X: np.ndarray) -> np.ndarray:
        """Scaled variables u = x / h (n, m)."""
        # u_k = x_k / h_k
        return np.asarray(X, dtype=float) / self.scale

    def support_coordinates(self, X: np.ndarray) -> np.ndarray:
        """Support coordinates v = (x − c)/r (n, m): the data box is [−1, 1]^m."""
        centre = 0.5 * (self.high + self.low)
        half = 0.5 * (self.high - self.low)
        half = np.where(half > 0, half, 1.0)
        # v_k = (x_k − c_k) / r_k
        return (np.asarray(X, dtype=float) - centre) / half

    def to_dict(self) -> list[dict]:
        """One entry per variable: name, unit, low, high, scale."""
        return [
            {
                "name": name,
                "unit": self.units[k],
                "low": float(self.low[k]),
                "high": float(self.high[k]),
                "scale": float(self.scale[k]),
            }
            for k, name in enumerate(self.names)
        ]

    @classmethod
    def from_dict(cls, entries: Sequence[Mapping]) -> Normalisation:
        """The normalisation ``to_dict`` wrote."""
        return cls(
            names=tuple(str(e["name"]) for e in entries),
            scale=np.array([float(e["scale"]) for e in entries]),
            low=np.array([float(e["low"]) for e in entries]),
            high=np.array([float(e["high"]) for e in entries]),
            units=tuple(str(e.get("unit", "")) for e in entries),
        )
