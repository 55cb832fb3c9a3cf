"""Flying qualities: the modes of an identified airplane model against the MIL-F-8785C limits
for a stated airplane class and flight-phase category, with the level each criterion meets
at 95 % confidence.

Criteria (``LIMITS`` holds every number with its paragraph of MIL-F-8785C, 5 November 1980):

- short-period damping ratio ζ_sp (3.2.2.1.2), band per level;
- control anticipation parameter CAP = ω_sp² / (n/α) [1/(g·s²)] (3.2.2.1.1), band per level;
- Dutch-roll minimum ζ_d, ω_nd [rad/s] and ζ_d·ω_nd [rad/s] (3.3.1.1);
- roll-mode maximum time constant τ_R [s] (3.3.1.2);
- spiral minimum time to double amplitude T_2 [s] (3.3.1.3).

Verification of the limits: each number carries ``verified``. A number is verified where at
least one public reproduction of the specification's table, independent of this program and
read while writing it, states the same value, and none found states another. The others are
marked unverified (with why) and take no part in a verdict unless ``include_unverified`` is
asked for; a level none of whose limits is verified is not judged.

The level met at 95 % confidence (``CriterionResult.level``): with the value v, its σ (delta
method, from the modes) and z = 1.645 (one-sided 95 % normal quantile), a level holds when

    v − z σ ≥ minimum   and   v + z σ ≤ maximum      (each bound present)

— each bound is exceeded with probability ≤ 5 % under a normal error of v. The level reported
is the best (lowest-numbered) judged level that holds; levels are nested (Level 1 ⊂ Level 2 ⊂
Level 3), so a level holding implies the higher numbers hold. None when no judged level
holds: the criterion is not met at 95 % (``level_nominal``, the level of v alone, says where
the value lies). Without a σ (no covariance), the value alone decides and ``note`` says so.

The roll-mode and spiral criteria are judged on the real part of their eigenvalue, λ_r, whose
σ the delta method gives directly and which stays defined through neutral stability:

    τ_R ≤ τ_max  ⇔  λ_r ≤ −1/τ_max        T_2 ≥ T_min  ⇔  λ_r ≤ ln 2 / T_min

(a stable spiral, λ_r < 0, never doubles: it meets every level).

n/α, the load factor per angle of attack [g/rad], from a linear model with an angle of attack
state α and the airspeed V at the operating point (state ``V``, or ``speed_m_s``): with
Z_α = ∂α̇/∂α (A's entry),

    n/α ≈ −V Z_α / g

— Z_α ≈ −q̄ S C_Lα / (m V) plus the small thrust and gravity terms A holds, so n/α ≈
q̄ S C_Lα / (m g). CAP's σ then comes from the delta method over vec A (ω_sp and Z_α
correlated), with V held fixed. Given n/α instead (a number or (value, σ)), CAP's σ treats
ω_sp and n/α as independent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from flightid.errors import InputError, InputTypeError

__all__ = [
    "AIRPLANE_CLASSES",
    "CATEGORIES",
    "LIMITS",
    "CriterionResult",
    "FlyingQualities",
    "FlyingQualitiesError",
    "Limit",
    "flying_qualities",
    "limits_for",
    "load_factor_per_alpha",
]

STANDARD_GRAVITY = 9.80665  # m/s²
Z_95 = 1.6448536269514722  # one-sided 95 % quantile of the standard normal
AIRPLANE_CLASSES = ("I", "II", "II-C", "II-L", "III", "IV")
CATEGORIES = ("A", "B", "C")
LEVELS = (1, 2, 3)
_EVERY_CLASS = AIRPLANE_CLASSES
# the linear model's note when inputs are measured states (flightid.model.linearization)
MEASURED_STATES_NOTE = "are measured states"


class FlyingQualitiesError(InputError):
    """A class, category, criterion or input the flying-qualities check cannot use."""


@dataclass(frozen=True)
class Limit:
    """One level's bounds of one criterion for some classes and categories.

    ``minimum``/``maximum``: None where the level has no such bound. ``verified``: False
    where the number could not be checked against a public reproduction of the table
    (``why`` says what is known); such limits take no part in a verdict by default.
    """

    criterion: str
    classes: tuple[str, ...]
    categories: tuple[str, ...]
    level: int
    minimum: float | None
    maximum: float | None
    source: str
    verified: bool = True
    why: str = ""


_SP = "MIL-F-8785C 3.2.2.1.2"
_CAP = "MIL-F-8785C 3.2.2.1.1"
_DR = "MIL-F-8785C 3.3.1.1"
_ROLL = "MIL-F-8785C 3.3.1.2"
_SPIRAL = "MIL-F-8785C 3.3.1.3"
_C14 = ("I", "IV")
_C23 = ("II", "II-C", "II-L", "III")
_CAP_UNCHECKED = "no public reproduction of this figure's bound was found to check it against"
_SPIRAL_SPLIT = "reproductions disagree: 12 s (by category) and 20 s (by class)"
_CAP_B_MAX = "reproductions read the Category A figure's 3.6 and assume it for Category B"

#: Every limit used, with its source paragraph (module docstring: verification).
LIMITS: tuple[Limit, ...] = (
    # short-period damping ratio ζ_sp: band per level
    Limit("short_period_damping", _EVERY_CLASS, ("A", "C"), 1, 0.35, 1.30, _SP),
    Limit("short_period_damping", _EVERY_CLASS, ("A", "C"), 2, 0.25, 2.00, _SP),
    Limit("short_period_damping", _EVERY_CLASS, ("B",), 1, 0.30, 2.00, _SP),
    Limit("short_period_damping", _EVERY_CLASS, ("B",), 2, 0.20, 2.00, _SP),
    Limit("short_period_damping", _EVERY_CLASS, CATEGORIES, 3, 0.15, None, _SP),
    # CAP = ω_sp²/(n/α) [1/(g s²)]: read from the specification's figures
    Limit("cap", _EVERY_CLASS, ("A",), 1, 0.28, 3.6, _CAP),
    Limit("cap", _EVERY_CLASS, ("A",), 2, 0.16, 10.0, _CAP),
    Limit("cap", _EVERY_CLASS, ("B",), 1, 0.085, 3.6, _CAP, False, _CAP_B_MAX),
    Limit("cap", _EVERY_CLASS, ("B",), 2, 0.038, 10.0, _CAP, False, _CAP_UNCHECKED),
    Limit("cap", _EVERY_CLASS, ("C",), 1, 0.16, 3.6, _CAP, False, _CAP_UNCHECKED),
    Limit("cap", _EVERY_CLASS, ("C",), 2, 0.096, 10.0, _CAP, False, _CAP_UNCHECKED),
    Limit("cap", _EVERY_CLASS, CATEGORIES, 3, None, None, _CAP, False, _CAP_UNCHECKED),
    # Dutch roll: minimum ζ_d
    Limit("dutch_roll_damping", _EVERY_CLASS, ("A",), 1, 0.19, None, _DR),
    Limit("dutch_roll_damping", _EVERY_CLASS, ("B", "C"), 1, 0.08, None, _DR),
    Limit("dutch_roll_damping", _EVERY_CLASS, CATEGORIES, 2, 0.02, None, _DR),
    Limit(
        "dutch_roll_damping",
        _EVERY_CLASS,
        CATEGORIES,
        3,
        0.0,
        None,
        _DR,
        False,
        "reproductions disagree: 0 (MIL-F-8785C) and 0.02",
    ),  # fmt: skip
    # Dutch roll: minimum ζ_d ω_nd [rad/s]
    Limit("dutch_roll_damping_frequency", _EVERY_CLASS, ("A",), 1, 0.35, None, _DR),
    Limit("dutch_roll_damping_frequency", _EVERY_CLASS, ("B",), 1, 0.15, None, _DR),
    Limit("dutch_roll_damping_frequency", ("I", "II-C", "IV"), ("C",), 1, 0.15, None, _DR),
    Limit("dutch_roll_damping_frequency", ("II-L", "III"), ("C",), 1, 0.10, None, _DR),
    Limit("dutch_roll_damping_frequency", _EVERY_CLASS, CATEGORIES, 2, 0.05, None, _DR),
    Limit("dutch_roll_damping_frequency", _EVERY_CLASS, CATEGORIES, 3, None, None, _DR),
    # Dutch roll: minimum ω_nd [rad/s]
    Limit("dutch_roll_frequency", _C14, ("A",), 1, 1.0, None, _DR),
    Limit("dutch_roll_frequency", _C23, ("A",), 1, 0.4, None, _DR),
    Limit("dutch_roll_frequency", _EVERY_CLASS, ("B",), 1, 0.4, None, _DR),
    Limit("dutch_roll_frequency", ("I", "II-C", "IV"), ("C",), 1, 1.0, None, _DR),
    Limit("dutch_roll_frequency", ("II-L", "III"), ("C",), 1, 0.4, None, _DR),
    Limit("dutch_roll_frequency", _EVERY_CLASS, CATEGORIES, 2, 0.4, None, _DR),
    Limit("dutch_roll_frequency", _EVERY_CLASS, CATEGORIES, 3, 0.4, None, _DR),
    # roll mode: maximum time constant τ_R [s]
    Limit("roll_time_constant", _C14, ("A",), 1, None, 1.0, _ROLL),
    Limit("roll_time_constant", _C14, ("A",), 2, None, 1.4, _ROLL),
    Limit("roll_time_constant", _C23, ("A",), 1, None, 1.4, _ROLL),
    Limit("roll_time_constant", _C23, ("A",), 2, None, 3.0, _ROLL),
    Limit("roll_time_constant", _EVERY_CLASS, ("B",), 1, None, 1.4, _ROLL),
    Limit("roll_time_constant", _EVERY_CLASS, ("B",), 2, None, 3.0, _ROLL),
    Limit("roll_time_constant", ("I", "II-C", "IV"), ("C",), 1, None, 1.0, _ROLL),
    Limit("roll_time_constant", ("I", "II-C", "IV"), ("C",), 2, None, 1.4, _ROLL),
    Limit("roll_time_constant", ("II-L", "III"), ("C",), 1, None, 1.4, _ROLL),
    Limit("roll_time_constant", ("II-L", "III"), ("C",), 2, None, 3.0, _ROLL),
    Limit("roll_time_constant", _EVERY_CLASS, CATEGORIES, 3, None, 10.0, _ROLL),
    # spiral: minimum time to double amplitude T_2 [s]
    Limit("spiral_time_to_double", _C14, ("A",), 1, 12.0, None, _SPIRAL),
    Limit("spiral_time_to_double", _C23, ("A",), 1, 12.0, None, _SPIRAL, False, _SPIRAL_SPLIT),
    Limit(
        "spiral_time_to_double", _EVERY_CLASS, ("C",), 1, 12.0, None, _SPIRAL, False, _SPIRAL_SPLIT
    ),
    Limit("spiral_time_to_double", _EVERY_CLASS, ("B",), 1, 20.0, None, _SPIRAL),
    Limit(
        "spiral_time_to_double",
        _EVERY_CLASS,
        CATEGORIES,
        2,
        8.0,
        None,
        _SPIRAL,
        False,
        "reproductions disagree: 8 s (MIL-F-8785C) and 12 s",
    ),  # fmt: skip
    Limit("spiral_time_to_double", _EVERY_CLASS, CATEGORIES, 3, 4.0, None, _SPIRAL),
)

# criterion: (label, unit, mode it reads)
CRITERIA = {
    "short_period_damping": ("short-period damping ratio ζ_sp", "", "short period"),
    "cap": ("control anticipation parameter CAP", "1/(g s^2)", "short period"),
    "dutch_roll_damping": ("Dutch-roll damping ratio ζ_d", "", "Dutch roll"),
    "dutch_roll_frequency": ("Dutch-roll frequency ω_nd", "rad/s", "Dutch roll"),
    "dutch_roll_damping_frequency": ("Dutch-roll ζ_d ω_nd", "rad/s", "Dutch roll"),
    "roll_time_constant": ("roll-mode time constant τ_R", "s", "roll subsidence"),
    "spiral_time_to_double": ("spiral time to double T_2", "s", "spiral"),
}


def _check_class_category(airplane_class: str, category: str) -> tuple[str, str]:
    if not isinstance(airplane_class, str) or not isinstance(category, str):
        raise InputTypeError(
            f"airplane_class, category: expected strings such as 'IV', 'A', got "
            f"{type(airplane_class).__name__}, {type(category).__name__}"
        )
    cls, cat = airplane_class.strip().upper(), category.strip().upper()
    if cls not in AIRPLANE_CLASSES:
        raise FlyingQualitiesError(
            f"airplane_class: expected one of {list(AIRPLANE_CLASSES)}, got {airplane_class!r}"
        )
    if cat not in CATEGORIES:
        raise FlyingQualitiesError(
            f"category: expected one of {list(CATEGORIES)}, got {category!r}"
        )
    if cls == "II" and cat == "C":
        raise FlyingQualitiesError(
            "airplane_class: Category C limits differ for Class II carrier-based ('II-C') and "
            "land-based ('II-L') airplanes; expected 'II-C' or 'II-L', got 'II'"
        )
    return cls, cat


def limits_for(criterion: str, airplane_class: str, category: str) -> dict[int, Limit]:
    """{level: Limit} of ``criterion`` for the class and category (every level 1–3)."""
    if criterion not in CRITERIA:
        raise FlyingQualitiesError(
            f"criterion: expected one of {list(CRITERIA)}, got {criterion!r}"
        )
    cls, cat = _check_class_category(airplane_class, category)
    # a Class II-C/II-L airplane outside Category C uses the Class II rows and vice versa
    family = {cls, "II"} if cls.startswith("II") and cls != "III" else {cls}
    found = {}
    for limit in LIMITS:
        if limit.criterion == criterion and cat in limit.categories:
            if family & set(limit.classes):
                found[limit.level] = limit
    return found


@dataclass(frozen=True)
class CriterionResult:
    """One criterion: its value with σ, the limits of every level and the level met.

    ``level``: the best judged level that holds at 95 % (module docstring), None when none
    does or none could be judged; ``level_nominal``: the same for the value alone (σ = 0).
    """

    criterion: str
    label: str
    mode: str
    unit: str
    value: float
    std: float
    limits: dict[int, Limit]
    level: int | None
    level_nominal: int | None
    note: str = ""
    judged: bool = True  # False: every level's limits unverified (no verdict)

    def to_dict(self) -> dict:
        def num(v):
            return float(v) if v is not None and np.isfinite(v) else None

        return {
            "criterion": self.criterion,
            "label": self.label,
            "mode": self.mode,
            "unit": self.unit,
            "value": num(self.value),
            "std": num(self.std),
            "level": self.level,
            "level_nominal": self.level_nominal,
            "note": self.note,
            "judged": self.judged,
            "limits": {
                str(level): {
                    "minimum": limit.minimum,
                    "maximum": limit.maximum,
                    "source": limit.source,
                    "verified": limit.verified,
                    "why": limit.why,
                }
                for level, limit in sorted(self.limits.items())
            },
        }


@dataclass(frozen=True)
class FlyingQualities:
    """The criteria of one airplane class and flight-phase category (``flying_qualities``)."""

    airplane_class: str
    category: str
    criteria: tuple[CriterionResult, ...]
    include_unverified: bool = False
    notes: tuple[str, ...] = field(default=())

    def __getitem__(self, criterion: str) -> CriterionResult:
        for row in self.criteria:
            if row.criterion == criterion:
                return row
        raise FlyingQualitiesError(
            f"no criterion {criterion!r} judged; judged: {[r.criterion for r in self.criteria]}"
        )

    def rows(self) -> list[list[str]]:
        """One row per criterion: label, value ± σ [unit], Level 1/2/3 limits, level."""
        from flightid.numbers import format_with_sigma

        rows = []
        for row in self.criteria:
            value, sigma = format_with_sigma(row.value, row.std, missing="-")
            unit = f" {row.unit}" if row.unit else ""
            level = f"Level {row.level}" if row.level is not None else "not met at 95 %"
            if not row.judged:
                level = "not judged"
            limits = [_bounds_text(row.limits[lvl]) if lvl in row.limits else "-" for lvl in LEVELS]
            source = next(iter(row.limits.values())).source if row.limits else ""
            rows.append([row.label, f"{value} ± {sigma}{unit}", *limits, level, source])
        return rows

    def summary(self) -> str:
        """A table: criterion, value ± σ, the Level 1/2/3 limits, the level at 95 %."""
        from flightid.numbers import format_with_sigma

        lines = [
            f"flying qualities (MIL-F-8785C), Class {self.airplane_class}, Category "
            f"{self.category}; level at 95 % (value ∓ 1.645σ inside the limits)"
        ]
        for row in self.criteria:
            value, sigma = format_with_sigma(row.value, row.std, missing="-")
            limits = "; ".join(
                f"L{level} {_bounds_text(limit)}" for level, limit in sorted(row.limits.items())
            )
            level = f"Level {row.level}" if row.level is not None else "not met at 95 %"
            if not row.judged:
                level = "not judged"
            unit = f" {row.unit}" if row.unit else ""
            lines.append(f"  {row.label}: {value} ± {sigma}{unit}  [{limits}]  → {level}")
            if row.note:
                lines.append(f"      {row.note}")
        lines.extend(f"note: {n}" for n in self.notes)
        return "\n".join(lines)

    def to_dict(self) -> dict:
        return {
            "standard": "MIL-F-8785C",
            "class": self.airplane_class,
            "category": self.category,
            "confidence": 0.95,
            "include_unverified": self.include_unverified,
            "criteria": [row.to_dict() for row in self.criteria],
            "notes": list(self.notes),
        }


def _bounds_text(limit: Limit) -> str:
    if limit.minimum is None and limit.maximum is None:
        text = "no limit"
    elif limit.maximum is None:
        text = f"≥ {limit.minimum:g}"
    elif limit.minimum is None:
        text = f"≤ {limit.maximum:g}"
    else:
        text = f"{limit.minimum:g}–{limit.maximum:g}"
    return text + ("" if limit.verified else " (unverified)")


def _holds(value: float, sigma: float, low: float | None, high: float | None) -> bool:
    """v − zσ ≥ low and v + zσ ≤ high (each present); σ NaN counts as 0."""
    margin = Z_95 * sigma if np.isfinite(sigma) else 0.0
    if not np.isfinite(value):
        return False
    if low is not None and value - margin < low:
        return False
    return not (high is not None and value + margin > high)


def _judge(value, sigma, limits, include_unverified, transform=None):
    """(level at 95 %, level of the value alone, skipped levels)."""
    best, nominal, skipped = None, None, []
    for level in sorted(limits, reverse=True):
        limit = limits[level]
        if not (limit.verified or include_unverified):
            skipped.append(level)
            continue
        low, high = (limit.minimum, limit.maximum)
        if transform is not None:
            low, high = transform(low, high)
        if _holds(value, sigma, low, high):
            best = level
        if _holds(value, 0.0, low, high):
            nominal = level
    return best, nominal, sorted(skipped)


def _roll_bounds(low, high):
    # τ_R ≤ τ_max ⇔ λ_r ≤ −1/τ_max
    return None, (None if high is None else -1.0 / high)


def _spiral_bounds(low, high):
    # T_2 ≥ T_min ⇔ λ_r ≤ ln 2 / T_min
    return None, (None if low is None else math.log(2.0) / low)


def load_factor_per_alpha(linear, speed_m_s: float | None = None) -> float:
    """n/α ≈ −V Z_α / g [g/rad] from a linear model with an ``alpha`` state (module
    docstring); V from the ``V`` state at the operating point or ``speed_m_s``."""
    if "alpha" not in linear.states:
        raise FlyingQualitiesError(
            f"n/α: needs an 'alpha' state in the linear model, got states {list(linear.states)}; "
            "give n_alpha"
        )
    speed = _speed(linear, speed_m_s)
    k = list(linear.states).index("alpha")
    return -speed * float(linear.A[k, k]) / STANDARD_GRAVITY


def _speed(linear, speed_m_s):
    if speed_m_s is not None:
        speed = float(speed_m_s)
    elif "V" in linear.states:
        speed = float(linear.x0[list(linear.states).index("V")])
    else:
        raise FlyingQualitiesError(
            f"n/α: needs the airspeed: a 'V' state (states {list(linear.states)}) or speed_m_s"
        )
    if not (np.isfinite(speed) and speed > 0):
        raise FlyingQualitiesError(f"speed: expected a positive airspeed in m/s, got {speed}")
    return speed


def _cap_with_sigma(linear, speed_m_s, short_period) -> tuple[float, float]:
    """CAP and its σ by the delta method over vec A (central differences of CAP(A))."""
    k = list(linear.states).index("alpha")
    speed = _speed(linear, speed_m_s)
    target = short_period.eigenvalue

    def cap_of(a):
        values = np.linalg.eigvals(a)
        lam = values[np.argmin(np.abs(values - target))]
        # CAP = ω_sp² / (n/α),  n/α = −V Z_α/g
        return abs(lam) ** 2 / (-speed * a[k, k] / STANDARD_GRAVITY)

    a = np.array(linear.A, dtype=float)
    cap = cap_of(a)
    cov = linear.block_covariance("A")
    if cov is None:
        return cap, math.nan
    gradient = np.zeros(a.size)
    for j in range(a.size):
        step = 1e-6 * max(abs(a.flat[j]), 1.0)
        plus, minus = a.copy(), a.copy()
        plus.flat[j] += step
        minus.flat[j] -= step
        gradient[j] = (cap_of(plus) - cap_of(minus)) / (2.0 * step)
    return cap, math.sqrt(max(float(gradient @ cov @ gradient), 0.0))


def _cap_from_given(short_period, n_alpha) -> tuple[float, float]:
    if isinstance(n_alpha, (tuple, list)):
        if len(n_alpha) != 2:
            raise FlyingQualitiesError(f"n_alpha: expected a number or (value, σ), got {n_alpha}")
        value, sigma = float(n_alpha[0]), float(n_alpha[1])
    else:
        value, sigma = float(n_alpha), 0.0
    if not (np.isfinite(value) and value > 0):
        raise FlyingQualitiesError(f"n_alpha: expected a positive number in g/rad, got {value}")
    wn, s_wn = short_period.natural_frequency, short_period.natural_frequency_std
    cap = wn**2 / value
    # σ_CAP/CAP = √((2σ_ω/ω)² + (σ_nα/nα)²)  (ω_sp and n/α independent)
    return cap, cap * math.sqrt((2.0 * s_wn / wn) ** 2 + (sigma / value) ** 2)


def _mode_rows(modes) -> dict:
    """{criterion: (value, σ, transform)} from the named modes present."""
    rows = {}
    names = set(modes.names)
    if "short period" in names:
        sp = modes["short period"]
        rows["short_period_damping"] = (sp.damping_ratio, sp.damping_ratio_std, None)
    if "Dutch roll" in names:
        dr = modes["Dutch roll"]
        rows["dutch_roll_damping"] = (dr.damping_ratio, dr.damping_ratio_std, None)
        rows["dutch_roll_frequency"] = (dr.natural_frequency, dr.natural_frequency_std, None)
        # ζω_n = −Re λ
        rows["dutch_roll_damping_frequency"] = (-dr.eigenvalue.real, dr.eigenvalue_std[0], None)
    if "roll subsidence" in names:
        roll = modes["roll subsidence"]
        rows["roll_time_constant"] = (roll.eigenvalue.real, roll.eigenvalue_std[0], _roll_bounds)
    if "spiral" in names:
        spiral = modes["spiral"]
        rows["spiral_time_to_double"] = (
            spiral.eigenvalue.real,
            spiral.eigenvalue_std[0],
            _spiral_bounds,
        )
    return rows


def _displayed(criterion, value, sigma):
    """The value shown (τ_R, T_2 from λ_r; T_2 = inf for a stable spiral) and its σ."""
    if criterion == "roll_time_constant":
        # τ = −1/λ_r,  σ_τ = σ_λ/λ_r²
        return -1.0 / value, sigma / value**2
    if criterion == "spiral_time_to_double":
        if value <= 0:
            return math.inf, math.nan
        # T_2 = ln2/λ_r,  σ_T2 = ln2 σ_λ/λ_r²
        return math.log(2.0) / value, math.log(2.0) * sigma / value**2
    return value, sigma


def flying_qualities(
    modes,
    airplane_class: str,
    category: str,
    n_alpha: float | tuple[float, float] | None = None,
    *,
    speed_m_s: float | None = None,
    include_unverified: bool = False,
) -> FlyingQualities:
    """The MIL-F-8785C criteria of the named modes and the level each meets at 95 %.

    Args:
        modes: a ``Modes`` (``LinearModel.modes()``) or a ``LinearModel`` (then n/α, when
            not given, comes from its ``alpha`` state and the airspeed, and CAP's σ from the
            covariance of A).
        airplane_class: "I", "II", "II-C", "II-L", "III" or "IV" (MIL-F-8785C 1.3).
        category: flight-phase category "A", "B" or "C" (MIL-F-8785C 1.4).
        n_alpha: load factor per angle of attack [g/rad], a number or (value, σ).
        speed_m_s: the airspeed for n/α where the model has no ``V`` state.
        include_unverified: judge with the unverified limits too.

    Returns:
        ``FlyingQualities``: one ``CriterionResult`` per criterion whose mode is present.
    """
    cls, cat = _check_class_category(airplane_class, category)
    linear = None
    if hasattr(modes, "A") and hasattr(modes, "modes"):
        linear, modes = modes, modes.modes()
    if not hasattr(modes, "names"):
        raise InputTypeError(
            f"modes: expected a Modes or a LinearModel, got {type(modes).__name__}"
        )
    rows = _mode_rows(modes)
    notes = list(getattr(modes, "notes", ()))
    # a model holding measured states as inputs: its modes are not the free airplane's
    held = any(MEASURED_STATES_NOTE in n for n in notes)
    if "short period" in rows or "short period" in modes.names:
        cap = _cap(linear, modes, n_alpha, speed_m_s, notes)
        if cap is not None:
            rows["cap"] = (*cap, None)
    results = []
    for criterion, (value, sigma, transform) in rows.items():
        label, unit, mode = CRITERIA[criterion]
        limits = limits_for(criterion, cls, cat)
        level, nominal, skipped = _judge(value, sigma, limits, include_unverified, transform)
        note = []
        if held:
            level, skipped = None, sorted(limits)
            note.append("not judged: the model holds measured states as inputs (see notes)")
        if skipped and not held:
            note.append(f"Level {', '.join(map(str, skipped))} not judged: limit unverified")
        if not np.isfinite(sigma):
            note.append("no σ: the value alone decides")
        shown, shown_sigma = _displayed(criterion, value, sigma)
        results.append(
            CriterionResult(
                criterion, label, mode, unit, shown, shown_sigma, limits, level, nominal,
                "; ".join(note), len(skipped) < len(limits),
            )
        )  # fmt: skip
    order = list(CRITERIA)
    results.sort(key=lambda r: order.index(r.criterion))
    return FlyingQualities(cls, cat, tuple(results), include_unverified, tuple(notes))


def _cap(linear, modes, n_alpha, speed_m_s, notes) -> tuple[float, float] | None:
    """CAP with σ, or None (with a note) where n/α is not at hand."""
    short_period = modes["short period"]
    if n_alpha is not None:
        return _cap_from_given(short_period, n_alpha)
    if linear is None:
        notes.append("CAP not judged: give n_alpha (g/rad) or pass the LinearModel")
        return None
    try:
        n_per_alpha = load_factor_per_alpha(linear, speed_m_s)
    except FlyingQualitiesError as error:
        notes.append(f"CAP not judged: {error}")
        return None
    if not n_per_alpha > 0:
        notes.append(f"CAP not judged: n/α = {n_per_alpha:.4g} g/rad is not positive")
        return None
    return _cap_with_sigma(linear, speed_m_s, short_period)
