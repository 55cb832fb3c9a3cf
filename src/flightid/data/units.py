"""Unit conversion for flight-data channels: factors to SI, checked by dimension.

A unit is written the way data files write it: ``"deg"``, ``"deg/s"``, ``"DEG/S**2"``,
``"ft/sec"``, ``"lbf/ft2"``, ``"slug*ft^2"``, ``"g"``. It is parsed (no ``eval``) into a
factor to SI and a dimension vector over (length, mass, time, angle, force-free):

    value_SI = factor · value

Angles are a dimension of their own here (rad and deg) so that a conversion "deg → m/s" is
refused. ``convert_factor("deg", "rad")`` returns the multiplier from one unit to another:

    value_to = value_from · factor_from / factor_to

The standard acceleration of gravity g = 9.80665 m/s² (ISO 80000-3) is the unit ``g``.

The channel rule (one meaning of ``unit`` in every case file and loader)
-------------------------------------------------------------------------
A data channel declares the unit its source is recorded in (``unit``) and optionally the unit
it is delivered in (``to``). ``channel_conversion(unit, to)`` is the only place that decides:

* ``unit`` and ``to``: the values are converted from ``unit`` to ``to`` (same dimension).
* ``unit`` only: the values are delivered in **SI, angles in radians** — the coherent SI unit
  of the same dimension (``si_label``): deg → rad, deg/s → rad/s, deg/s² → rad/s², ft → m,
  ft/s and kt → m/s, g → m/s², lbf → N, lbf/ft² → Pa, slug·ft² → kg·m², % → 1 (a fraction).
  Accelerations given in ``g`` therefore arrive in m/s²; write ``to = "g"`` for a model
  whose outputs are in g (as the RP-1153 equations are).
* neither: the values are used as recorded (no unit declared, none shown in reports).
* ``to`` without ``unit``: refused (``UnitError``).

Where the data file states a column's unit, ``flightid.data.loaders.ChannelSpec`` puts it in
``unit`` before this rule is applied (a declared unit must then mean the same unit,
``same_unit``).

An unknown unit label is always refused with ``UnitError``, whose message lists the known
names. The order of operations on a channel is fixed: value = (source · scale + offset),
then multiplied by the conversion factor of this rule (scale and offset act in the source
unit).
"""

from __future__ import annotations

import math
import re

from flightid.errors import InputError

__all__ = [
    "UnitError",
    "parse_unit",
    "convert_factor",
    "si_label",
    "channel_conversion",
    "known_units",
    "same_unit",
    "G0",
]

G0 = 9.80665  # m/s², standard gravity (ISO 80000-3)

# Dimension vector order: length, mass, time, angle.
_L, _M, _T, _A = (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1)
_ONE = (0, 0, 0, 0)
_FORCE = (1, 1, -2, 0)

# base unit → (factor to SI, dimension); the factors are the published definitions:
# 1 ft = 0.3048 m, 1 in = 0.0254 m, 1 mi = 1609.344 m, 1 nmi = 1852 m (exact); 1 lbm =
# 0.45359237 kg (exact); 1 lbf = 1 lbm · g0; 1 slug = 1 lbf·s²/ft; 1 mph = 0.44704 m/s (exact);
# 1 bar = 10⁵ Pa; 1 inHg (conventional) = 3386.389 Pa; 1 psf = 1 lbf/ft²; 1 psi = 1 lbf/in²
_SPEED = (1, 0, -1, 0)
_PRESSURE = (-1, 1, -2, 0)
_BASE: dict[str, tuple[float, tuple[int, ...]]] = {
    "1": (1.0, _ONE),
    "-": (1.0, _ONE),
    "rad": (1.0, _A),
    "mrad": (1e-3, _A),
    "deg": (math.pi / 180.0, _A),
    "cdeg": (math.pi / 18000.0, _A),  # centidegree (ArduPilot)
    "m": (1.0, _L),
    "km": (1000.0, _L),
    "dm": (0.1, _L),
    "cm": (0.01, _L),
    "mm": (0.001, _L),
    "ft": (0.3048, _L),
    "in": (0.0254, _L),
    "mi": (1609.344, _L),
    "nmi": (1852.0, _L),
    "s": (1.0, _T),
    "sec": (1.0, _T),
    "ms": (1e-3, _T),
    "us": (1e-6, _T),
    "min": (60.0, _T),
    "h": (3600.0, _T),
    "hr": (3600.0, _T),
    "hz": (1.0, (0, 0, -1, 0)),
    "rpm": (2.0 * math.pi / 60.0, (0, 0, -1, 1)),  # revolutions per minute: 2π rad / 60 s
    "kg": (1.0, _M),
    "gram": (1e-3, _M),
    "slug": (0.45359237 * 9.80665 / 0.3048, _M),  # lbf·s²/ft = 14.5939029372... kg
    "lbm": (0.45359237, _M),
    "n": (1.0, _FORCE),
    "kilonewton": (1000.0, _FORCE),
    "lbf": (4.4482216152605, _FORCE),
    "lb": (4.4482216152605, _FORCE),
    "pa": (1.0, _PRESSURE),
    "hpa": (100.0, _PRESSURE),
    "kpa": (1000.0, _PRESSURE),
    "mbar": (100.0, _PRESSURE),
    "bar": (1e5, _PRESSURE),
    "inhg": (3386.389, _PRESSURE),
    "psf": (47.880258980336, _PRESSURE),
    "psi": (6894.7572931684, _PRESSURE),
    "g": (G0, (1, 0, -2, 0)),
    "kt": (1852.0 / 3600.0, _SPEED),
    "kts": (1852.0 / 3600.0, _SPEED),
    "knot": (1852.0 / 3600.0, _SPEED),
    "kmh": (1.0 / 3.6, _SPEED),
    "kph": (1.0 / 3.6, _SPEED),
    "mph": (0.44704, _SPEED),
    "percent": (0.01, _ONE),
    "%": (0.01, _ONE),
    "ppm": (1e-6, _ONE),
}
_ALIASES = {
    "degree": "deg",
    "degrees": "deg",
    "radian": "rad",
    "radians": "rad",
    "meter": "m",
    "metre": "m",
    "feet": "ft",
    "foot": "ft",
    "inch": "in",
    "knots": "knot",
    "second": "s",
    "seconds": "s",
    "usec": "us",
    "msec": "ms",
    "gn": "g",
    "prozent": "percent",
    # ArduPilot's angle units: degrees of heading, latitude, longitude
    "degheading": "deg",
    "deglatitude": "deg",
    "deglongitude": "deg",
}
# Labels with two common meanings once case is ignored: refused, with the unambiguous names.
_AMBIGUOUS = {"kn": "knots ('kt') or kilonewtons ('kilonewton')"}

# Written forms brought to the grammar before parsing: micro signs → "u", middle dots → "*",
# superscript powers → "^n", standard gravity "g0" → "g".
_MICRO = str.maketrans({"µ": "u", "μ": "u", "·": "*", "⋅": "*", "×": "*"})
_SUPERSCRIPT = re.compile(r"[⁻]?[⁰¹²³⁴⁵⁶⁷⁸⁹]+")
_SUPERSCRIPT_DIGITS = str.maketrans("⁻⁰¹²³⁴⁵⁶⁷⁸⁹", "-0123456789")
_G0 = re.compile(r"(?<![a-z])g0(?![0-9])")
# a leading multiplier written by some logs: "0.01 m", "1e-07 deg" (number, space, unit)
_MULTIPLIER = re.compile(r"\s*([0-9]*\.?[0-9]+(?:e[-+]?[0-9]+)?)\s+(?=[a-z%])")

_TOKEN = re.compile(r"\s*(?:(?P<name>[A-Za-z%][A-Za-z]*|1|-)(?P<power>(?:\^|\*\*)?-?\d+)?)\s*")


# the largest power of one unit name (m^3, s^-2 are typical; huge ones only overflow)
MAX_UNIT_POWER = 12


class UnitError(InputError):
    """A unit that cannot be parsed, or a conversion between different dimensions."""


def parse_unit(text: str) -> tuple[float, tuple[int, ...]]:
    """(factor to SI, dimension) of a unit string such as ``"deg/s^2"`` or ``"lbf/ft2"``.

    Grammar: ``unit := part (("*" | "/" | ".") part)*``, ``part := NAME [["^" | "**"] INT]``;
    everything after the first ``/`` divides (``"m/s/s"`` is m·s⁻²). Case is ignored.
    """
    if not isinstance(text, str) or not text.strip():
        raise UnitError(f"unit: expected a unit such as 'deg' or 'm/s', got {text!r}")
    source = _normalised(text)
    factor, dimension = 1.0, [0, 0, 0, 0]
    multiplier = _MULTIPLIER.match(source)
    if multiplier:
        factor = float(multiplier.group(1))
        if not (math.isfinite(factor) and factor > 0):
            raise UnitError(f"unit {text!r}: the multiplier must be a positive number")
    sign = 1
    position = multiplier.end() if multiplier else 0
    expect_part = True
    while position < len(source):
        if expect_part:
            match = _TOKEN.match(source, position)
            if not match or not match.group("name"):
                raise UnitError(f"unit {text!r}: cannot read a unit name at position {position}")
            name = _ALIASES.get(match.group("name"), match.group("name"))
            power_text = (match.group("power") or "1").lstrip("^*")
            digits = power_text.lstrip("-").lstrip("0") or "0"
            if len(digits) > 2 or int(digits) > MAX_UNIT_POWER:
                raise UnitError(
                    f"unit {text[:40]!r}: the power {power_text[:20]} is out of range; at most "
                    f"{MAX_UNIT_POWER} either way"
                )
            power = int(power_text)
            if power == 0:
                raise UnitError(f"unit {text!r}: a power of 0 ({match.group(0).strip()!r})")
            if name in _AMBIGUOUS:
                raise UnitError(f"unit {text!r}: {name!r} is ambiguous; write {_AMBIGUOUS[name]}")
            if name not in _BASE:
                raise UnitError(
                    f"unit {text!r}: unknown unit {name!r}; known: {known_units()} "
                    "(with *, / and powers)"
                )
            base_factor, base_dim = _BASE[name]
            factor *= base_factor ** (sign * power)
            for k in range(4):
                dimension[k] += sign * power * base_dim[k]
            position = match.end()
            expect_part = False
        else:
            char = source[position]
            if char in "*.":
                position += 1
            elif char == "/":
                sign = -1
                position += 1
            elif char.isspace():
                position += 1
                continue
            elif source[position - 1].isspace():
                expect_part = True  # a space between two unit names multiplies: "slug ft2"
                continue
            else:
                raise UnitError(f"unit {text!r}: unexpected {char!r} at position {position}")
            expect_part = True
    if expect_part:
        raise UnitError(f"unit {text!r}: ends with an operator")
    return factor, tuple(dimension)


def _normalised(text: str) -> str:
    """``text`` in the grammar's form: lower case, micro signs as ``u``, middle dots as
    ``*``, superscript powers as ``^n`` (``slug·ft²`` → ``slug*ft^2``), ``g0`` as ``g``."""
    source = text.strip().translate(_MICRO)
    source = _SUPERSCRIPT.sub(lambda m: "^" + m.group(0).translate(_SUPERSCRIPT_DIGITS), source)
    return _G0.sub("g", source.lower())


def same_unit(first: str, second: str) -> bool:
    """True when two unit labels mean the same unit (same dimension, factors equal to
    10⁻⁹ relative): ``"deg/sec"`` and ``"deg/s"``, ``"slug*ft^2"`` and ``"slug ft2"``."""
    f_first, d_first = parse_unit(first)
    f_second, d_second = parse_unit(second)
    return d_first == d_second and abs(f_first - f_second) <= 1e-9 * max(f_first, f_second)


def convert_factor(from_unit: str, to_unit: str) -> float:
    """Multiplier taking values in ``from_unit`` to ``to_unit`` (same dimension required)."""
    f_from, d_from = parse_unit(from_unit)
    f_to, d_to = parse_unit(to_unit)
    if d_from != d_to:
        raise UnitError(
            f"unit conversion {from_unit!r} → {to_unit!r}: the units measure different "
            f"quantities (dimensions L,M,T,angle {d_from} vs {d_to})"
        )
    # value_to = value_from · factor_from / factor_to
    return f_from / f_to


def known_units() -> list[str]:
    """The unit names ``parse_unit`` accepts (combined with ``*``, ``/`` and powers)."""
    return sorted({*_BASE, *_ALIASES})


# Named coherent SI units of common dimensions (L, M, T, angle); others are composed.
_SI_NAMES: dict[tuple[int, ...], str] = {
    _ONE: "1",
    _A: "rad",
    (0, 0, -1, 1): "rad/s",
    (0, 0, -2, 1): "rad/s^2",
    _L: "m",
    (2, 0, 0, 0): "m^2",
    (3, 0, 0, 0): "m^3",
    (1, 0, -1, 0): "m/s",
    (1, 0, -2, 0): "m/s^2",
    _T: "s",
    _M: "kg",
    _FORCE: "N",
    (2, 1, -2, 0): "N*m",
    (-1, 1, -2, 0): "Pa",
    (2, 1, 0, 0): "kg*m^2",
    (-3, 1, 0, 0): "kg/m^3",
}
_SI_BASE_NAMES = ("m", "kg", "s", "rad")


def si_label(dimension: tuple[int, ...]) -> str:
    """The coherent SI unit (angles in rad) of a dimension vector (L, M, T, angle).

    Common dimensions have their usual name (N, Pa, m/s^2, rad/s); others are written as
    products of m, kg, s and rad, e.g. ``"m*rad/s"``. ``parse_unit(si_label(d))`` is
    (1.0, d).
    """
    if dimension in _SI_NAMES:
        return _SI_NAMES[dimension]
    up = [
        name if p == 1 else f"{name}^{p}"
        for name, p in zip(_SI_BASE_NAMES, dimension, strict=True)
        if p > 0
    ]
    down = [
        name if p == -1 else f"{name}^{-p}"
        for name, p in zip(_SI_BASE_NAMES, dimension, strict=True)
        if p < 0
    ]
    return "*".join(up or ["1"]) + "".join(f"/{part}" for part in down)


def channel_conversion(unit: str, to: str = "") -> tuple[float, str]:
    """The channel rule (module docstring): (factor, delivered unit) for a channel whose
    source is in ``unit`` and that is asked for in ``to``.

        value_delivered = factor · (source · scale + offset)

    ``unit`` only → SI with angles in rad; ``unit`` and ``to`` → ``to``; neither →
    (1.0, ""). Raises ``UnitError`` for an unknown unit, for ``to`` without ``unit`` and for
    units of different dimensions.
    """
    for key, text in (("unit", unit), ("to", to)):
        if not isinstance(text, str):
            raise UnitError(f"{key}: expected a unit such as 'deg' or 'm/s', got {text!r}")
    unit, to = unit.strip(), to.strip()
    if not unit:
        if to:
            raise UnitError(f"to = {to!r}: give the source unit too ('unit')")
        return 1.0, ""
    if to:
        return convert_factor(unit, to), to
    factor, dimension = parse_unit(unit)
    # value_SI = factor_to_SI · value
    return factor, si_label(dimension)
