"""Airplane definition: mass, inertia, reference geometry, air density and thrust line.

All quantities in SI units (see ``flightid.aircraft.units`` for conversions from ft, slug,
slug·ft², lbf and degrees). Body axes: x forward, y right wing, z down; the XZ plane is a plane
of symmetry, so I_xy = I_yz = 0 and only the product of inertia I_xz appears (RP-1153 §2.A).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from flightid.aircraft.units import G0, isa_density
from flightid.errors import InputError, describe

__all__ = ["Airplane"]


@dataclass(frozen=True)
class Airplane:
    """Mass properties and reference geometry of a rigid airplane.

    Attributes:
        mass: m, kg.
        Ix, Iy, Iz: moments of inertia about the body axes, kg·m².
        Ixz: product of inertia, kg·m² (positive with the usual NASA sign convention,
            I_xz = ∫ x z dm).
        S: wing reference area, m².
        b: wing span, m.
        cbar: mean aerodynamic chord c̄, m.
        density: air density ρ, kg/m³; ``None`` means use ``altitude`` with the ISA model.
        altitude: altitude for the ISA density, m (used only when ``density`` is None).
        thrust_input: name of the input channel holding the thrust magnitude T (N), or None
            when thrust is folded into the aerodynamic coefficients.
        thrust_inclination: α_T, angle of the thrust line above the body x axis, rad.
        g: acceleration of gravity, m/s².
        name: label.
    """

    mass: float
    Ix: float
    Iy: float
    Iz: float
    Ixz: float
    S: float
    b: float
    cbar: float
    density: float | None = None
    altitude: float = 0.0
    thrust_input: str | None = None
    thrust_inclination: float = 0.0
    g: float = G0
    name: str = "airplane"

    def __post_init__(self) -> None:
        for field in ("mass", "Ix", "Iy", "Iz", "S", "b", "cbar", "g"):
            value = getattr(self, field)
            if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise InputError(
                    f"Airplane.{field}: expected a positive finite number (SI units), "
                    f"got {describe(value)}"
                )
            object.__setattr__(self, field, float(value))
        if not isinstance(self.Ixz, (int, float)) or not math.isfinite(self.Ixz):
            raise InputError(f"Airplane.Ixz: expected a finite number, got {describe(self.Ixz)}")
        object.__setattr__(self, "Ixz", float(self.Ixz))
        if self.Ix * self.Iz - self.Ixz**2 <= 0:
            raise InputError(
                f"Airplane.Ixz: Γ = Ix·Iz − Ixz² must be positive, got Ix={self.Ix}, "
                f"Iz={self.Iz}, Ixz={self.Ixz}"
            )
        if self.density is not None and not (
            isinstance(self.density, (int, float)) and math.isfinite(self.density)
        ):
            raise InputError(
                f"Airplane.density: expected a finite number ≥ 0 (kg/m³) or None, "
                f"got {describe(self.density)}"
            )
        if self.density is not None and self.density < 0:
            raise InputError(f"Airplane.density: must be ≥ 0 kg/m³, got {self.density}")
        if self.thrust_input is not None and (
            not isinstance(self.thrust_input, str) or not self.thrust_input.isidentifier()
        ):
            raise InputError(
                f"Airplane.thrust_input: expected an input channel name or None, "
                f"got {describe(self.thrust_input)}"
            )

    @property
    def rho(self) -> float:
        """Air density used by the equations, kg/m³."""
        return float(self.density) if self.density is not None else isa_density(self.altitude)

    @property
    def gamma(self) -> float:
        """Γ = I_x I_z − I_xz², kg²·m⁴ (RP-1153 2.10)."""
        return self.Ix * self.Iz - self.Ixz**2

    @property
    def weight(self) -> float:
        """m g, N."""
        return self.mass * self.g
