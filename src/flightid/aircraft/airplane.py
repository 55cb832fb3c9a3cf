"""Airplane definition: mass, inertia, reference geometry, air density, thrust line, engine.

All quantities in SI units (see ``flightid.aircraft.units`` for conversions from ft, slug,
slug·ft², lbf and degrees). Body axes: x forward, y right wing, z down; the XZ plane is a plane
of symmetry, so I_xy = I_yz = 0 and only the product of inertia I_xz appears (RP-1153 §2.A).

A longitudinal-only airplane gives mass, I_y, S and c̄ (and ρ); I_x, I_z, I_xz and the span b
may then be left out. The models that need them (6-DOF, lateral, terms in p̂ r̂ β̇) raise an
``AirplaneDataError`` naming what is missing (``Airplane.require``).

Thrust: magnitude T (N) from an input channel, along a line inclined σ_T above the body x
axis, acting at the point (x_T, z_T) (m, body axes, from the centre of gravity; z down):

    X_T = T cos σ_T,   Z_T = −T sin σ_T,   M_T = l_T T,   l_T = z_T cos σ_T + x_T sin σ_T

or with the moment arm l_T given directly (``thrust_arm``; l_T < 0: thrust line above the
c.g., nose-down moment).

Engine (propeller or fan), optional: the rotor's angular momentum h_E = s I_p Ω about body x
(kg·m²/s; s = ``rotation`` = +1 for a rotor turning right-handed about +x, i.e. clockwise seen
from behind) adds the gyroscopic moments −ω × h_E = (0, −r h_E, q h_E); the propeller (shaft)
torque Q (N·m, ≥ 0, from an input channel) acts on the airframe as the rolling moment −s Q.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from flightid.aircraft.units import G0, isa_density
from flightid.errors import InputError, describe

__all__ = ["Airplane", "AirplaneDataError"]


class AirplaneDataError(InputError):
    """A model needs an airplane quantity (I_x, I_z, b, …) that the Airplane leaves out."""


_REQUIRED = ("mass", "Iy", "S", "cbar")


@dataclass(frozen=True)
class Airplane:
    """Mass properties and reference geometry of a rigid airplane.

    Attributes:
        mass: m, kg.
        Ix, Iy, Iz: moments of inertia about the body axes, kg·m² (I_x and I_z may be None
            for a longitudinal-only airplane, both or neither).
        Ixz: product of inertia, kg·m² (positive with the usual NASA sign convention,
            I_xz = ∫ x z dm); 0 by default.
        S: wing reference area, m².
        b: wing span, m (None for a longitudinal-only airplane).
        cbar: mean aerodynamic chord c̄, m.
        density: air density ρ, kg/m³; ``None`` means use ``altitude`` with the ISA model.
        altitude: altitude for the ISA density, m (used only when ``density`` is None).
        thrust_input: name of the input channel holding the thrust magnitude T (N), or None
            when thrust is folded into the aerodynamic coefficients.
        thrust_inclination: σ_T (α_T), angle of the thrust line above the body x axis, rad.
        thrust_x, thrust_z: point of the thrust line, m from the c.g. along body x (forward)
            and z (down): M_T = T (z_T cos σ_T + x_T sin σ_T).
        thrust_arm: l_T, m: pitching moment per newton of thrust, M_T = l_T T, given instead
            of thrust_x/thrust_z (then they must be 0).
        engine_momentum: engine rotor angular momentum magnitude I_p Ω, kg·m²/s (constant).
        engine_momentum_input: input channel of I_p Ω (kg·m²/s), instead of the constant.
        propeller_torque_input: input channel of the propeller shaft torque Q, N·m.
        rotation: s = +1 (rotor right-handed about +x: clockwise seen from behind) or −1.
        g: acceleration of gravity, m/s².
        name: label.
    """

    mass: float | None = None
    Ix: float | None = None
    Iy: float | None = None
    Iz: float | None = None
    Ixz: float = 0.0
    S: float | None = None
    b: float | None = None
    cbar: float | None = None
    density: float | None = None
    altitude: float = 0.0
    thrust_input: str | None = None
    thrust_inclination: float = 0.0
    g: float = G0
    name: str = "airplane"
    thrust_x: float = 0.0
    thrust_z: float = 0.0
    thrust_arm: float | None = None
    engine_momentum: float = 0.0
    engine_momentum_input: str | None = None
    propeller_torque_input: str | None = None
    rotation: int = 1

    def __post_init__(self) -> None:
        self._check_sizes()
        self._check_offsets()
        self._check_thrust_arm()
        self._check_density()
        self._check_channel_names()
        self._check_engine_and_rotation()

    def _check_sizes(self) -> None:
        """mass, inertias, reference sizes and g: positive finite numbers (floats); Ix and Iz
        both or neither."""
        for field in ("mass", "Ix", "Iy", "Iz", "S", "b", "cbar", "g"):
            value = getattr(self, field)
            if value is None and field not in _REQUIRED and field != "g":
                continue
            if value is None:
                raise AirplaneDataError(
                    f"Airplane.{field}: missing; every model needs {list(_REQUIRED)} (SI units)"
                )
            if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise InputError(
                    f"Airplane.{field}: expected a positive finite number (SI units), "
                    f"got {describe(value)}"
                )
            object.__setattr__(self, field, float(value))
        if (self.Ix is None) != (self.Iz is None):
            raise AirplaneDataError(
                f"Airplane.Ix, Iz: give both or neither (a longitudinal-only airplane), got "
                f"Ix={self.Ix}, Iz={self.Iz}"
            )

    def _check_offsets(self) -> None:
        """Ixz, the thrust point, engine momentum and thrust inclination: finite numbers
        (floats); Γ = Ix·Iz − Ixz² positive."""
        for field in ("Ixz", "thrust_x", "thrust_z", "engine_momentum", "thrust_inclination"):
            value = getattr(self, field)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise InputError(
                    f"Airplane.{field}: expected a finite number, got {describe(value)}"
                )
            object.__setattr__(self, field, float(value))
        if self.Ix is not None and self.Ix * self.Iz - self.Ixz**2 <= 0:
            raise InputError(
                f"Airplane.Ixz: Γ = Ix·Iz − Ixz² must be positive, got Ix={self.Ix}, "
                f"Iz={self.Iz}, Ixz={self.Ixz}"
            )

    def _check_thrust_arm(self) -> None:
        """thrust_arm: None or a finite number (float), and then no thrust point."""
        if self.thrust_arm is not None:
            if not isinstance(self.thrust_arm, (int, float)) or not math.isfinite(self.thrust_arm):
                raise InputError(
                    f"Airplane.thrust_arm: expected a finite number (m) or None, "
                    f"got {describe(self.thrust_arm)}"
                )
            if self.thrust_x != 0.0 or self.thrust_z != 0.0:
                raise InputError(
                    "Airplane.thrust_arm: give the thrust moment arm l_T or the thrust point "
                    f"(thrust_x, thrust_z), not both; got l_T={self.thrust_arm}, "
                    f"x_T={self.thrust_x}, z_T={self.thrust_z}"
                )
            object.__setattr__(self, "thrust_arm", float(self.thrust_arm))

    def _check_density(self) -> None:
        """density: None or a finite number ≥ 0 kg/m³."""
        if self.density is not None and not (
            isinstance(self.density, (int, float)) and math.isfinite(self.density)
        ):
            raise InputError(
                f"Airplane.density: expected a finite number ≥ 0 (kg/m³) or None, "
                f"got {describe(self.density)}"
            )
        if self.density is not None and self.density < 0:
            raise InputError(f"Airplane.density: must be ≥ 0 kg/m³, got {self.density}")

    def _check_channel_names(self) -> None:
        """Input channel fields: None or a channel name."""
        for field in ("thrust_input", "engine_momentum_input", "propeller_torque_input"):
            value = getattr(self, field)
            if value is not None and (not isinstance(value, str) or not value.isidentifier()):
                raise InputError(
                    f"Airplane.{field}: expected an input channel name or None, "
                    f"got {describe(value)}"
                )

    def _check_engine_and_rotation(self) -> None:
        """Engine momentum as a constant or a channel, not both; rotation ±1."""
        if self.engine_momentum_input is not None and self.engine_momentum != 0.0:
            raise InputError(
                "Airplane.engine_momentum: give the engine angular momentum as a constant or "
                f"as an input channel, not both; got {self.engine_momentum} and "
                f"{self.engine_momentum_input!r}"
            )
        if self.rotation not in (1, -1) or isinstance(self.rotation, bool):
            raise InputError(f"Airplane.rotation: expected +1 or −1, got {describe(self.rotation)}")

    @property
    def rho(self) -> float:
        """Air density used by the equations, kg/m³."""
        return float(self.density) if self.density is not None else isa_density(self.altitude)

    @property
    def gamma(self) -> float:
        """Γ = I_x I_z − I_xz², kg²·m⁴ (RP-1153 2.10)."""
        self.require(("Ix", "Iz"), "Γ = Ix·Iz − Ixz²")
        return self.Ix * self.Iz - self.Ixz**2

    @property
    def weight(self) -> float:
        """m g, N."""
        return self.mass * self.g

    @property
    def thrust_moment_arm(self) -> float:
        """l_T, m: M_T = l_T T with l_T = z_T cos σ_T + x_T sin σ_T (or ``thrust_arm``)."""
        if self.thrust_arm is not None:
            return self.thrust_arm
        # M_T = z_T X_T − x_T Z_T = T (z_T cos σ_T + x_T sin σ_T)
        return self.thrust_z * math.cos(self.thrust_inclination) + self.thrust_x * math.sin(
            self.thrust_inclination
        )

    @property
    def longitudinal_only(self) -> bool:
        """True when I_x, I_z or b is left out (only longitudinal models can use it)."""
        return self.Ix is None or self.b is None

    def require(self, fields: Iterable[str], purpose: str) -> None:
        """Raise ``AirplaneDataError`` naming the ``fields`` that are None and the
        ``purpose`` that needs them."""
        missing = [f for f in fields if getattr(self, f) is None]
        if missing:
            raise AirplaneDataError(
                f"airplane: {purpose} needs {missing}, which the airplane "
                f"{self.name!r} leaves out; give them (SI units) in the Airplane"
            )
