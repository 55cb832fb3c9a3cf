"""SI conversion helpers and a standard atmosphere.

flightid works in SI units throughout: m, kg, s, N, rad. Data published in U.S. customary units
convert with the factors below (exact by definition of the international foot and pound):

    length      1 ft        = 0.3048 m
    mass        1 slug      = 14.593902937 kg      (1 lbf·s²/ft)
    force       1 lbf       = 4.4482216152605 N
    inertia     1 slug·ft²  = 1.3558179483 kg·m²
    area        1 ft²       = 0.09290304 m²
    angle       1 deg       = π/180 rad
    density     1 slug/ft³  = 515.378818 kg/m³

The atmosphere is the ICAO/ISA troposphere (valid below 11 km):

    T = T0 − L·h,   p = p0 (T/T0)^(g0/(R L)),   ρ = p / (R T)
"""

from __future__ import annotations

import math

import numpy as np

from flightid.data.units import G0
from flightid.errors import InputError

__all__ = [
    "G0",
    "FT",
    "SLUG",
    "LBF",
    "SLUG_FT2",
    "FT2",
    "DEG",
    "SLUG_PER_FT3",
    "ft",
    "ft2",
    "slug",
    "lbf",
    "slug_ft2",
    "deg",
    "lb_weight_to_kg",
    "isa_density",
]

# G0: standard gravity, m/s² (the one constant of flightid.data.units)
FT = 0.3048  # m per ft
FT2 = FT * FT  # m² per ft²
LBF = 4.4482216152605  # N per lbf
SLUG = LBF / FT  # kg per slug (lbf·s²/ft) = 14.5939 kg
SLUG_FT2 = SLUG * FT2  # kg·m² per slug·ft² = 1.35582 kg·m²
SLUG_PER_FT3 = SLUG / FT**3  # kg/m³ per slug/ft³
DEG = math.pi / 180.0  # rad per degree


def _scaled(value, factor: float):
    """value · factor: a float for a scalar, a float array for an array."""
    return np.asarray(value, dtype=float) * factor if np.ndim(value) else float(value) * factor


def ft(value):
    """Feet → metres."""
    return _scaled(value, FT)


def ft2(value):
    """Square feet → square metres."""
    return _scaled(value, FT2)


def slug(value):
    """Slugs → kilograms."""
    return _scaled(value, SLUG)


def lbf(value):
    """Pounds force → newtons."""
    return _scaled(value, LBF)


def slug_ft2(value):
    """Moments of inertia, slug·ft² → kg·m²."""
    return _scaled(value, SLUG_FT2)


def deg(value):
    """Degrees → radians."""
    return _scaled(value, DEG)


def lb_weight_to_kg(weight_lb: float) -> float:
    """Weight in pounds (lbf at standard gravity) → mass in kg (1 lb = 0.45359237 kg)."""
    return float(weight_lb) * 0.45359237


# ISA sea-level values and tropospheric lapse rate (ICAO Doc 7488).
_T0 = 288.15  # K
_P0 = 101325.0  # Pa
_LAPSE = 0.0065  # K/m
_R_AIR = 287.05287  # J/(kg·K)


def isa_density(altitude_m: float) -> float:
    """Air density ρ (kg/m³) of the ISA troposphere at geopotential altitude h (m), 0 ≤ h ≤ 11 km.

    ρ(0) = 1.225 kg/m³.
    """
    h = float(altitude_m)
    if not (-500.0 <= h <= 11000.0):
        raise InputError(
            f"altitude_m: the ISA troposphere model covers -500 to 11000 m, got {altitude_m!r}"
        )
    # T = T0 − L h
    temperature = _T0 - _LAPSE * h
    # p = p0 (T/T0)^(g0/(R L))
    pressure = _P0 * (temperature / _T0) ** (G0 / (_R_AIR * _LAPSE))
    # ρ = p/(R T)
    return pressure / (_R_AIR * temperature)
