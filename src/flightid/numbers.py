"""Numbers printed with as many digits as their uncertainty supports.

An estimate θ̂ ± σ is written with σ rounded to two significant digits and θ̂ (and any
interval bound around it) rounded to the same decimal place: 4.00022 ± 0.00033 reads
``4.00022 ± 0.00033`` and its interval ``[3.99957, 4.00087]``, not ``[4, 4.001]``.

Numbers between 10⁻⁴ and 10⁶ in magnitude are written in fixed point, the others in
scientific notation (each number with its own exponent, the mantissa cut at σ's decimal
place). Where σ carries no scale — zero, NaN (a fixed parameter) or infinite (an
undetermined one) — the value is written to six significant digits (``VALUE_DIGITS``) and
σ as ``0``, the ``missing`` text or ``inf``.

These helpers depend on nothing in flightid, so that every estimator's text summary and
report page can use them.
"""

from __future__ import annotations

import math

__all__ = [
    "SIGMA_DIGITS",
    "VALUE_DIGITS",
    "format_at_sigma",
    "format_interval",
    "format_sigma",
    "format_with_sigma",
    "sigma_decimal_place",
]

#: significant digits of σ
SIGMA_DIGITS = 2
#: significant digits of a value whose σ carries no scale (0, NaN, inf)
VALUE_DIGITS = 6
# fixed point for magnitudes in [FIXED_LOW, FIXED_HIGH), scientific notation outside
FIXED_LOW = 1e-4
FIXED_HIGH = 1e6


def _finite_positive(sigma: float) -> bool:
    return math.isfinite(sigma) and sigma > 0


def _nonfinite(value: float) -> str:
    """``nan``, ``inf`` or ``-inf``."""
    if math.isnan(value):
        return "nan"
    return "inf" if value > 0 else "-inf"


def sigma_decimal_place(sigma: float, digits: int = SIGMA_DIGITS) -> int | None:
    """Decimal exponent q of σ's last significant digit (σ rounded to ``digits`` digits):
    0.00033 → −5, 0.000996 → −4 (σ rounds to 0.0010), 1234 → 2; None for σ ≤ 0, NaN, inf."""
    sigma = float(sigma)
    if not _finite_positive(sigma):
        return None
    # σ rounded to `digits` significant digits first: rounding may carry into a new decade
    rounded = float(f"{sigma:.{digits - 1}e}")
    return math.floor(math.log10(rounded)) - (digits - 1)


def _at_place(x: float, place: int) -> str:
    """x rounded to 10^place, fixed point or scientific (module docstring)."""
    if not math.isfinite(x):
        return _nonfinite(x)
    rounded = round(x, -place)
    if rounded == 0:
        return "0" if place >= 0 else f"{0.0:.{-place}f}"
    magnitude = abs(rounded)
    if FIXED_LOW <= magnitude < FIXED_HIGH:
        return f"{rounded:.{max(-place, 0)}f}"
    exponent = math.floor(math.log10(magnitude))
    # mantissa digits after the point down to 10^place
    return f"{rounded:.{max(exponent - place, 0)}e}"


def format_sigma(sigma: float, digits: int = SIGMA_DIGITS, missing: str = "—") -> str:
    """σ to ``digits`` significant digits (``0.00033``, ``1.2e+04``); ``0`` for σ = 0,
    ``inf`` for an infinite σ, ``missing`` for NaN or None."""
    if sigma is None or (isinstance(sigma, float) and math.isnan(sigma)):
        return missing
    sigma = float(sigma)
    if math.isnan(sigma):
        return missing
    if sigma == 0:
        return "0"
    if not math.isfinite(sigma):
        return _nonfinite(sigma)
    place = sigma_decimal_place(abs(sigma), digits)
    return _at_place(sigma, place)


def format_at_sigma(x: float, sigma: float, digits: int = SIGMA_DIGITS) -> str:
    """x (a value or an interval bound) rounded to the decimal place of σ's last
    significant digit; to ``VALUE_DIGITS`` significant digits when σ has no scale."""
    if x is None:
        return "—"
    x = float(x)
    if not math.isfinite(x):
        return _nonfinite(x)
    place = None if sigma is None else sigma_decimal_place(float(sigma), digits)
    if place is None:
        return f"{x:.{VALUE_DIGITS}g}"
    return _at_place(x, place)


def format_with_sigma(
    value: float, sigma: float, digits: int = SIGMA_DIGITS, missing: str = "—"
) -> tuple[str, str]:
    """(value text, σ text): σ to ``digits`` significant digits, the value to the same
    decimal place — ``format_with_sigma(4.00022, 0.00033)`` → ``("4.00022", "0.00033")``."""
    return format_at_sigma(value, sigma, digits), format_sigma(sigma, digits, missing)


def format_interval(lower: float, upper: float, sigma: float, digits: int = SIGMA_DIGITS) -> str:
    """``[lower, upper]`` with both bounds at σ's decimal place (``format_at_sigma``); an
    open side prints as ``-inf`` / ``inf``."""
    return f"[{format_at_sigma(lower, sigma, digits)}, {format_at_sigma(upper, sigma, digits)}]"
