"""How a data set expresses the measured accelerations: axis signs and unit.

The equations give the specific force along the body axes in g units [RP-1153 2.24–2.26]:

    a_x = X/(m g),  a_y = Y/(m g),  a_z = Z/(m g)

with (X, Y, Z) the aerodynamic plus thrust force (gravity excluded: an accelerometer does not
sense it). Body z points down, so in level flight Z ≈ −m g and a_z ≈ −1 g. Data sets differ
in sign convention and unit: many instruments and flight-test conventions record the normal
acceleration positive up (a_n = −a_z ≈ +1 g in level flight), and some record m/s² instead
of g. The model output is

    y_a = s_a · k · F_a/(m g),   s_a = ±1 per axis,   k = 1 (g units) or g (m/s²)

so the model matches the data instead of the data being converted by hand.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flightid.errors import InputError, InputTypeError, describe

__all__ = ["Accelerometer"]

_DIRECTIONS = {
    "ax": {"forward": 1.0, "aft": -1.0},
    "ay": {"right": 1.0, "left": -1.0},
    "az": {"down": 1.0, "up": -1.0},
}
_UNITS = ("g", "m/s^2")
_PRESETS = {
    # body axes, g units: a_z ≈ −1 g in level flight (the equations' own convention)
    "body": {},
    # normal acceleration positive up, g units: a_z ≈ +1 g in level flight
    "load_factor": {"az": "up"},
}


@dataclass(frozen=True)
class Accelerometer:
    """Sign and unit convention of the accelerometer outputs ax, ay, az.

    Attributes:
        unit: ``"g"`` (default, F/(m g)) or ``"m/s^2"`` (F/m).
        ax: positive ``"forward"`` (default) or ``"aft"``.
        ay: positive ``"right"`` (default, right wing) or ``"left"``.
        az: positive ``"down"`` (default, body z: a_z ≈ −1 g in level flight) or ``"up"``
            (the instrument / load-factor convention: a_z ≈ +1 g in level flight).
    """

    unit: str = "g"
    ax: str = "forward"
    ay: str = "right"
    az: str = "down"

    def __post_init__(self) -> None:
        if self.unit not in _UNITS:
            raise InputError(
                f"accelerometer.unit: expected one of {list(_UNITS)}, got {describe(self.unit)}"
            )
        for axis, choices in _DIRECTIONS.items():
            value = getattr(self, axis)
            if value not in choices:
                raise InputError(
                    f"accelerometer.{axis}: expected one of {list(choices)}, got {describe(value)}"
                )

    @classmethod
    def from_value(cls, value: Any) -> Accelerometer:
        """An ``Accelerometer`` from None (default), itself, a preset name (``"body"``,
        ``"load_factor"``) or a mapping of its fields (e.g. a case-file table)."""
        if value is None:
            return cls()
        if isinstance(value, Accelerometer):
            return value
        if isinstance(value, str):
            if value not in _PRESETS:
                raise InputError(
                    f"accelerometer: expected a preset {list(_PRESETS)}, a table of "
                    f"unit/ax/ay/az or an Accelerometer, got {value!r}"
                )
            return cls(**_PRESETS[value])
        if isinstance(value, Mapping):
            unknown = sorted(set(value) - {"unit", "ax", "ay", "az"})
            if unknown:
                raise InputError(
                    f"accelerometer.{unknown[0]}: unknown key; allowed: ['ax', 'ay', 'az', 'unit']"
                )
            return cls(**dict(value))
        raise InputTypeError(
            f"accelerometer: expected None, an Accelerometer, a preset name or a mapping, "
            f"got {describe(value)}"
        )

    def factors(self, g: float) -> np.ndarray:
        """(s_x k, s_y k, s_z k): multiply F/(m g) by these to get the recorded outputs."""
        # k = 1 for g units, k = g for m/s²
        k = 1.0 if self.unit == "g" else float(g)
        return np.array([_DIRECTIONS[axis][getattr(self, axis)] * k for axis in ("ax", "ay", "az")])
