"""Modes of a linear model: eigenvalues of A with natural frequency, damping, time constant,
time to half or double amplitude — each with its σ — and, for airplane models, the mode names.

For an eigenvalue λ = σ + iω of A (one row per complex pair, ω > 0; one per real root):

    ω_n = |λ|  [rad/s],   ζ = −σ/ω_n             (oscillatory modes)
    τ   = −1/σ [s]                                (real modes; negative when unstable)
    t_½ = ln 2/(−σ) [s]  (σ < 0),   t_2 = ln 2/σ [s]  (σ > 0)

σ of each (delta method): with the right and left eigenvectors v, w of λ (A v = λ v,
wᴴ A = λ wᴴ), the first-order change of λ is

    dλ = wᴴ dA v / (wᴴ v),   i.e.   ∂λ/∂A_ij = w̄_i v_j / (wᴴ v),

so every quantity q(λ) has the gradient g = ∂q/∂vec A (chain rule through Re λ, Im λ) and
Var q ≈ gᵀ Cov(vec A) g, with Cov(vec A) from ``LinearModel.covariance``.

Which states take part in a mode: the participation factors p_i = |w̄_i v_i| / Σ_j |w̄_j v_j|
(independent of the states' units).

Names of airplane modes (states named as flightid's airplane models name them): a mode
belongs to the longitudinal axis when most of its participation lies in u, w, V, alpha, q,
theta, to the lateral axis when it lies in v, beta, p, r, phi, psi.
  - longitudinal, oscillatory, by ω_n descending: the first is the "short period", the second
    the "phugoid" (only when a speed state u or V is among the states);
  - lateral, oscillatory: the one of highest ω_n is the "Dutch roll";
  - lateral, real: the one with the largest roll-rate (p) participation, where p is its
    dominant state, is the "roll subsidence"; of the other real lateral modes the slowest
    (smallest |λ|) is the "spiral" when the bank angle is a state: phi, or l_yz = sin Φ cos Θ
    of the direction-cosine attitude of flightid's lateral and 6-DOF airplane models;
  - an eigenvalue with |λ| ≤ 1e-9·max(1, max |λ|) is "neutral";
  - every other mode, and every mode of a model without airplane states, is "mode k" (k its
    row in the table, modes ordered by |λ| descending).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from scipy.linalg import eig

from flightid.errors import InputError

__all__ = ["Mode", "Modes", "ModeError", "modes_of"]

LONGITUDINAL_STATES = ("u", "w", "V", "alpha", "q", "theta")
LATERAL_STATES = ("v", "beta", "p", "r", "phi", "psi")
SPEED_STATES = ("u", "V")
# states that carry the bank angle: Φ itself, or l_yz = sin Φ cos Θ (direction cosines)
BANK_STATES = ("phi", "l_yz")
NEUTRAL_TOLERANCE = 1e-9
LN2 = math.log(2.0)
# the quantities of a mode with σ: (attribute, heading, unit)
QUANTITIES = (
    ("natural_frequency", "omega_n", "rad/s"),
    ("damping_ratio", "zeta", ""),
    ("time_constant", "tau", "s"),
    ("time_to_half", "t_half", "s"),
    ("time_to_double", "t_double", "s"),
)


class ModeError(InputError):
    """A mode asked for that the table does not hold."""


@dataclass(frozen=True)
class Mode:
    """One mode: an eigenvalue (a complex pair as its member with Im λ > 0) and its numbers.

    Quantities that do not apply are NaN: ω_n and ζ for a real mode, τ for an oscillatory one,
    t_½ for an unstable mode, t_2 for a stable one. Each ``*_std`` is its σ (NaN without a
    covariance). ``participation``: {state: p_i} (module docstring).
    """

    name: str
    eigenvalue: complex
    eigenvalue_std: tuple[float, float]  # σ of (Re λ, Im λ), 1/s
    natural_frequency: float
    natural_frequency_std: float
    damping_ratio: float
    damping_ratio_std: float
    time_constant: float
    time_constant_std: float
    time_to_half: float
    time_to_half_std: float
    time_to_double: float
    time_to_double_std: float
    participation: dict

    @property
    def oscillatory(self) -> bool:
        return self.eigenvalue.imag > 0.0

    @property
    def stable(self) -> bool:
        return self.eigenvalue.real < 0.0

    @property
    def dominant_state(self) -> str:
        return _dominant(self.participation)

    def to_dict(self) -> dict:
        entry: dict = {
            "name": self.name,
            "eigenvalue_real_1_per_s": _num(self.eigenvalue.real),
            "eigenvalue_imag_rad_per_s": _num(self.eigenvalue.imag),
            "eigenvalue_real_std_1_per_s": _num(self.eigenvalue_std[0]),
            "eigenvalue_imag_std_rad_per_s": _num(self.eigenvalue_std[1]),
            "oscillatory": self.oscillatory,
            "stable": self.stable,
        }
        for attribute, key, unit in QUANTITIES:
            suffix = {"rad/s": "_rad_per_s", "s": "_s", "": ""}[unit]
            entry[f"{key}{suffix}"] = _num(getattr(self, attribute))
            entry[f"{key}_std{suffix}"] = _num(getattr(self, f"{attribute}_std"))
        entry["participation"] = {k: float(v) for k, v in self.participation.items()}
        return entry


def _num(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


@dataclass(frozen=True)
class Modes:
    """The modes of a linear model, by |λ| descending (``modes_of``)."""

    modes: tuple[Mode, ...]
    states: tuple[str, ...]
    notes: tuple[str, ...] = ()  # the linear model's notes (what its A leaves out)

    def __iter__(self) -> Iterator[Mode]:
        return iter(self.modes)

    def __len__(self) -> int:
        return len(self.modes)

    def __getitem__(self, key: int | str) -> Mode:
        """The mode at a row number or of a name ("short period", "mode 2", ...)."""
        if isinstance(key, str):
            for mode in self.modes:
                if mode.name == key:
                    return mode
            raise ModeError(f"no mode named {key!r}; modes: {[m.name for m in self.modes]}")
        return self.modes[key]

    @property
    def names(self) -> list[str]:
        return [m.name for m in self.modes]

    def summary(self) -> str:
        """A table: eigenvalue, ω_n, ζ, τ, t_½, t_2, each ± σ, and the dominant state."""
        head = (
            f"{'mode':<16}{'eigenvalue [1/s]':>28}{'omega_n [rad/s]':>22}{'zeta':>20}"
            f"{'tau [s]':>20}{'t_half [s]':>20}{'t_double [s]':>20}  dominant"
        )
        lines = ["modes (± 1σ)", head]
        for mode in self.modes:
            lam = mode.eigenvalue
            text = f"{lam.real:.4g}" + (f" ± {lam.imag:.4g}i" if mode.oscillatory else "")
            cells = [f"{mode.name:<16}{text:>28}"]
            for attribute, _, _ in QUANTITIES:
                value = getattr(mode, attribute)
                sigma = getattr(mode, f"{attribute}_std")
                cell = "" if np.isnan(value) else f"{value:.4g}"
                if cell and np.isfinite(sigma):
                    cell += f" ±{sigma:.2g}"
                cells.append(f"{cell:>{22 if attribute == 'natural_frequency' else 20}}")
            cells.append(f"  {mode.dominant_state}")
            lines.append("".join(cells))
        lines.extend(f"note: {n}" for n in self.notes)
        return "\n".join(lines)

    def to_dict(self) -> list[dict]:
        return [m.to_dict() for m in self.modes]


def _quantity_gradients(lam: complex, g: np.ndarray) -> dict[str, tuple[float, np.ndarray]]:
    """(value, ∂value/∂vec A) of every quantity of the module docstring, from λ and its
    complex gradient g = ∂λ/∂vec A; NaN where a quantity does not apply."""
    s, w = lam.real, lam.imag
    g_re, g_im = g.real, g.imag
    nan = (math.nan, np.full(g.shape, np.nan))
    out = {k: nan for k, _, _ in QUANTITIES}
    if w > 0.0:
        wn = math.hypot(s, w)
        # ∂ω_n = (σ ∂σ + ω ∂ω)/ω_n
        g_wn = (s * g_re + w * g_im) / wn
        out["natural_frequency"] = (wn, g_wn)
        # ζ = −σ/ω_n:  ∂ζ = −∂σ/ω_n + σ ∂ω_n/ω_n²
        out["damping_ratio"] = (-s / wn, -g_re / wn + s * g_wn / wn**2)
    elif s != 0.0:
        # τ = −1/σ:  ∂τ = ∂σ/σ²
        out["time_constant"] = (-1.0 / s, g_re / s**2)
    if s < 0.0:
        # t_½ = −ln2/σ:  ∂t_½ = ln2 ∂σ/σ²
        out["time_to_half"] = (-LN2 / s, LN2 * g_re / s**2)
    elif s > 0.0:
        # t_2 = ln2/σ:  ∂t_2 = −ln2 ∂σ/σ²
        out["time_to_double"] = (LN2 / s, -LN2 * g_re / s**2)
    return out


def _std(gradient: np.ndarray, covariance: np.ndarray | None) -> float:
    """√(gᵀ C g); NaN without a covariance or with an undefined gradient."""
    if covariance is None or not np.all(np.isfinite(gradient)):
        return math.nan
    return math.sqrt(max(float(gradient @ covariance @ gradient), 0.0))


def _eigen(a: np.ndarray) -> list[tuple[complex, np.ndarray, np.ndarray]]:
    """(λ, ∂λ/∂vec A (complex, row-major), participation) for each real λ and each λ with
    Im λ > 0, ordered by |λ| descending."""
    values, left, right = eig(a, left=True, right=True)
    n = a.shape[0]
    tiny = 1e-12 * max(1.0, float(np.max(np.abs(values)))) if n else 0.0
    rows = []
    for k, lam in enumerate(values):
        if lam.imag < -tiny:
            continue
        lam = complex(lam.real, lam.imag if lam.imag > tiny else 0.0)
        v, w = right[:, k], left[:, k]
        if lam.imag == 0.0:
            v, w = v.real, w.real
        scale = np.vdot(w, v)  # wᴴ v
        with np.errstate(divide="ignore", invalid="ignore"):
            # ∂λ/∂A_ij = w̄_i v_j / (wᴴ v)
            gradient = np.outer(np.conj(w), v).ravel() / scale
        if abs(scale) < 1e-12 * np.linalg.norm(w) * np.linalg.norm(v):
            gradient = np.full(n * n, np.nan + 0j)
        weights = np.abs(np.conj(w) * v)
        participation = weights / weights.sum() if weights.sum() > 0 else weights
        rows.append((lam, gradient, participation))
    rows.sort(key=lambda r: -abs(r[0]))
    return rows


def _axis(participation: dict[str, float]) -> str:
    longitudinal = sum(participation.get(s, 0.0) for s in LONGITUDINAL_STATES)
    lateral = sum(participation.get(s, 0.0) for s in LATERAL_STATES)
    if longitudinal == 0.0 and lateral == 0.0:
        return ""
    return "longitudinal" if longitudinal >= lateral else "lateral"


def _dominant(participation: dict[str, float]) -> str:
    return max(participation, key=participation.get) if participation else ""


def _name_longitudinal(names, eigenvalues, chosen, states) -> None:
    """Oscillatory longitudinal modes by ω_n descending: short period, then phugoid (when a
    speed state is among the states)."""
    oscillatory = [k for k in chosen if eigenvalues[k].imag > 0]
    if oscillatory:
        names[oscillatory[0]] = "short period"
    if len(oscillatory) > 1 and any(s in states for s in SPEED_STATES):
        names[oscillatory[1]] = "phugoid"


def _name_lateral(names, eigenvalues, participations, chosen, states) -> None:
    """Dutch roll (fastest oscillatory), roll subsidence (real, p dominant, most p), spiral
    (the slowest other real mode, when a bank-angle state phi or l_yz is a state)."""
    oscillatory = [k for k in chosen if eigenvalues[k].imag > 0]
    if oscillatory:
        names[oscillatory[0]] = "Dutch roll"
    real = [k for k in chosen if eigenvalues[k].imag == 0]
    roll = [k for k in real if _dominant(participations[k]) == "p"]
    if roll:
        picked = max(roll, key=lambda k: participations[k]["p"])
        names[picked] = "roll subsidence"
        real.remove(picked)
    if real and any(s in states for s in BANK_STATES):
        names[min(real, key=lambda k: abs(eigenvalues[k]))] = "spiral"


def mode_names(
    eigenvalues: list[complex], participations: list[dict[str, float]], states: tuple[str, ...]
) -> list[str]:
    """The name of each mode by the rules of the module docstring (modes by |λ| descending)."""
    names = [f"mode {k + 1}" for k in range(len(eigenvalues))]
    top = max([1.0, *(abs(lam) for lam in eigenvalues)])
    axes = [_axis(p) for p in participations]
    for k, lam in enumerate(eigenvalues):
        if abs(lam) <= NEUTRAL_TOLERANCE * top:
            names[k] = "neutral"
    moving = [k for k in range(len(eigenvalues)) if names[k] != "neutral"]
    _name_longitudinal(names, eigenvalues, [k for k in moving if axes[k] == "longitudinal"], states)
    _name_lateral(
        names, eigenvalues, participations, [k for k in moving if axes[k] == "lateral"], states
    )
    return names


def modes_of(linear) -> Modes:
    """The ``Modes`` of a ``LinearModel`` (module docstring); σ from its covariance."""
    a = np.asarray(linear.A, dtype=float)
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise ModeError(f"A: expected a square matrix, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ModeError("A: has non-finite entries; no modes can be given")
    cov_a = linear.block_covariance("A")
    rows = _eigen(a)
    participations = [
        dict(zip(linear.states, (float(v) for v in p), strict=True)) for _, _, p in rows
    ]
    names = mode_names([r[0] for r in rows], participations, tuple(linear.states))
    modes = []
    for (lam, gradient, _), name, share in zip(rows, names, participations, strict=True):
        quantities = _quantity_gradients(lam, gradient)
        numbers = {}
        for attribute, (value, g) in quantities.items():
            numbers[attribute] = value
            numbers[f"{attribute}_std"] = math.nan if math.isnan(value) else _std(g, cov_a)
        sigma_re = _std(gradient.real, cov_a)
        sigma_im = _std(gradient.imag, cov_a) if lam.imag > 0 else 0.0
        if cov_a is None:
            sigma_im = math.nan
        modes.append(Mode(name, lam, (sigma_re, sigma_im), participation=share, **numbers))
    return Modes(tuple(modes), tuple(linear.states), tuple(linear.notes))
