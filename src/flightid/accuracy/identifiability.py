"""Combinations of parameters that the data barely determine, and their honest intervals.

When two derivatives act on the outputs almost alike (Mq and Mα̇ in a short period flown at
one speed: α̇ ≈ q), the data fix one combination of them well and the other hardly at all.
Each σ alone is then the projection of a long, thin likelihood region, and the quadratic
approximation behind it can fail badly; a pair with |ρ| = 0.9996 reported with its σ at face
value looks like two determined numbers and is not.

The normalised information matrix says which combinations these are. With M the information
matrix of the free parameters and d_j = √M_jj (1/d_j is θ_j's σ if it alone were free),

    M̃ = D⁻¹ M D⁻¹,   D = diag(d),   M̃ v_i = λ_i v_i   (λ_1 ≤ … ≤ λ_n, M̃_jj = 1)

the combination Σ_j v_ij d_j θ_j (parameters in units of 1/d_j) has variance 1/λ_i: the
eigenvector of the smallest λ is the combination the data determine least, and the condition
λ_max/λ_i says how much worse than the best. ``weak_combinations`` names

* every pair with |ρ_jk| ≥ ``correlation_threshold`` (ρ from C = M⁻¹), with the eigenvector
  that makes it so (the one of largest (v_ij² + v_ik²)/λ_i) restricted to the pair: the
  combination along it is not determined, the one across it is;
* every other direction with condition λ_max/λ_i ≥ ``condition_threshold``, with its
  components of |v_ij| ≥ 0.2.

``check_identifiability`` adds, for the parameters named, the profile-likelihood interval
(``profile``), which follows the region itself, beside the Cramér–Rao and coloured-residual
σ, and Beale's N_φ (``nonlinearity``) of the fit.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from flightid.errors import FlightIdError, FlightIdWarning, InputError

__all__ = [
    "CONDITION_THRESHOLD",
    "CORRELATION_THRESHOLD",
    "WARN_CORRELATION",
    "IdentifiabilityReport",
    "IdentifiabilityWarning",
    "ProfiledParameter",
    "WeakCombination",
    "check_identifiability",
    "weak_combinations",
]

# |ρ| from which a pair is named (σ at face value overstate what the data tell apart)
CORRELATION_THRESHOLD = 0.99
# λ_max/λ_i of the normalised information matrix from which a direction is named
CONDITION_THRESHOLD = 1e4
# a weak pair is a terminal warning when |ρ| reaches this, or when the profile interval of one
# of its parameters departs from the quadratic one; below it (and for directions named by
# their condition alone) the finding is in the results and the report only: the Cramér–Rao σ
# already carries a correlation, and the profile says whether it can be taken at face value
WARN_CORRELATION = 0.999
# a component of an eigenvector smaller than this is left out of the named combination
COMPONENT_FLOOR = 0.2
# profile half-widths outside [1/1.1, 1.1] × the quadratic ones: the approximation fails
QUADRATIC_TOLERANCE = 0.1


class IdentifiabilityWarning(FlightIdWarning):
    """Parameters the data barely tell apart; ``flightid`` prints it as
    ``flightid: warning: <message>``."""


@dataclass(frozen=True)
class WeakCombination:
    """A combination of free parameters that the data barely determine.

    Attributes:
        names: the parameters in it.
        undetermined: coefficients of the combination the data do not determine (on the
            parameters scaled by their σ alone, 1/√M_jj), unit length.
        determined: for a pair, the coefficients of the combination across it (determined);
            empty otherwise.
        condition: λ_max/λ of the normalised information matrix along ``undetermined``.
        correlations: the pairs with |ρ| over the threshold, (name, name, ρ) each (empty for a
            direction named by its condition alone).
    """

    names: tuple[str, ...]
    undetermined: tuple[float, ...]
    determined: tuple[float, ...] = ()
    condition: float = float("nan")
    correlations: tuple[tuple[str, str, float], ...] = ()

    def describe(self) -> str:
        undetermined = _combination(self.names, self.undetermined)
        tail = f"(condition {self.condition:.1e}; parameters scaled by their σ alone)"
        if not self.correlations:
            return f"the combination {undetermined} is barely determined by the data {tail}"
        listed = ", ".join(self.names[:-1]) + f" and {self.names[-1]}"
        if len(self.correlations) == 1:
            rhos = f"ρ = {_rho_text(self.correlations[0][2])}"
        else:
            rhos = ", ".join(f"ρ({a}, {b}) = {_rho_text(r)}" for a, b, r in self.correlations)
        if self.determined:
            verdict = (
                f"the combination {_combination(self.names, self.determined)} is determined, "
                f"{undetermined} is not"
            )
        else:
            verdict = f"the combination {undetermined} is not determined"
        return f"{listed} are barely told apart by the data: {rhos}; {verdict} {tail}"

    def to_dict(self) -> dict:
        return {
            "names": list(self.names),
            "undetermined": list(self.undetermined),
            "determined": list(self.determined),
            "condition": self.condition,
            "correlations": [{"names": [a, b], "rho": r} for a, b, r in self.correlations],
        }


@dataclass(frozen=True)
class ProfiledParameter:
    """A parameter of a weak combination: its quadratic and profile-likelihood intervals.

    Attributes:
        name: the parameter.
        value: its estimate.
        std_cr: Cramér–Rao σ.
        std_coloured: coloured-residual σ (NaN when not computed).
        ci_cr: quadratic interval at the level (lower, upper).
        ci_profile: profile-likelihood interval at the level (±inf where open).
        std_profile: the profile interval's half-width in σ units of the quadratic one,
            σ_cr·(upper − lower)/(ci_cr upper − ci_cr lower) (inf where open).
    """

    name: str
    value: float
    std_cr: float
    std_coloured: float
    ci_cr: tuple[float, float]
    ci_profile: tuple[float, float]
    std_profile: float

    @property
    def quadratic_fails(self) -> bool:
        """The profile interval is not the quadratic one within ``QUADRATIC_TOLERANCE`` (width
        or either side)."""
        lower = (self.value - self.ci_profile[0]) / max(self.value - self.ci_cr[0], 1e-300)
        upper = (self.ci_profile[1] - self.value) / max(self.ci_cr[1] - self.value, 1e-300)
        limit = 1.0 + QUADRATIC_TOLERANCE
        return not all(1.0 / limit <= side <= limit for side in (lower, upper))

    def describe(self, level: float) -> str:
        verdict = (
            "the quadratic approximation fails"
            if self.quadratic_fails
            else "the profile agrees with the quadratic approximation"
        )
        coloured = f", coloured σ {self.std_coloured:.4g}" if np.isfinite(self.std_coloured) else ""
        return (
            f"{self.name} = {self.value:.6g}: profile-likelihood {level:.0%} interval "
            f"[{self.ci_profile[0]:.6g}, {self.ci_profile[1]:.6g}] (as σ: "
            f"{self.std_profile:.4g}) beside Cramér–Rao σ {self.std_cr:.4g}{coloured}, {verdict}"
        )

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "value": self.value,
            "std_cr": self.std_cr,
            "std_coloured": _finite_or_none(self.std_coloured),
            "ci_cr": [float(v) for v in self.ci_cr],
            "ci_profile": [_finite_or_none(v) for v in self.ci_profile],
            "std_profile": _finite_or_none(self.std_profile),
            "quadratic_fails": self.quadratic_fails,
        }


@dataclass(frozen=True)
class IdentifiabilityReport:
    """The weak combinations of an estimate and the profile intervals of their parameters."""

    combinations: tuple[WeakCombination, ...]
    profiled: tuple[ProfiledParameter, ...] = ()
    level: float = 0.95
    n_phi: float = float("nan")  # Beale's nonlinearity measure of the fit (NaN: not computed)
    notes: tuple[str, ...] = field(default=())

    def messages(self) -> list[str]:
        """One line per combination, with the profile intervals of its parameters."""
        return self._lines(self.combinations) + list(self.notes)

    def serious(self, combination: WeakCombination) -> bool:
        """Whether a combination is a terminal warning: a pair with |ρ| ≥ ``WARN_CORRELATION``
        or a parameter whose profile interval departs from the quadratic one."""
        if not combination.correlations:
            return False
        if max(abs(r) for _, _, r in combination.correlations) >= WARN_CORRELATION:
            return True
        return any(p.quadratic_fails for p in self.profiled if p.name in combination.names)

    def warning_messages(self) -> list[str]:
        """The lines worth a terminal warning (``serious``); the rest are in ``messages``."""
        return self._lines(tuple(c for c in self.combinations if self.serious(c)))

    def _lines(self, combinations) -> list[str]:
        lines = []
        for combination in combinations:
            members = [p for p in self.profiled if p.name in combination.names]
            line = combination.describe()
            if members:
                line += "; " + "; ".join(p.describe(self.level) for p in members)
                if np.isfinite(self.n_phi):
                    line += f" (Beale's N_phi of the fit {self.n_phi:.3g})"
            lines.append(line)
        return lines

    def to_dict(self) -> dict:
        return {
            "combinations": [c.to_dict() for c in self.combinations],
            "profiled": [p.to_dict() for p in self.profiled],
            "level": self.level,
            "N_phi": _finite_or_none(self.n_phi),
            "notes": list(self.notes),
        }


def _rho_text(rho: float) -> str:
    """ρ with enough decimals that it does not round to ±1 (at least 4): '−0.99997'."""
    gap = max(1.0 - abs(rho), 1e-15)
    digits = max(4, int(np.ceil(-np.log10(gap))) + 1)
    return f"{rho:+.{digits}f}"


def _finite_or_none(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def _combination(names: Sequence[str], coefficients: Sequence[float]) -> str:
    """'0.71·Mq − 0.70·Malphadot'."""
    text = ""
    for name, c in zip(names, coefficients, strict=True):
        sign = "−" if c < 0 else "+"
        text += (f"{'-' if c < 0 else ''}" if not text else f" {sign} ") + f"{abs(c):.2f}·{name}"
    return text


def _oriented(vector: np.ndarray) -> np.ndarray:
    """Unit vector along ``vector`` with its first component positive."""
    vector = vector / np.linalg.norm(vector)
    return -vector if vector[0] < 0 else vector


def weak_combinations(
    names: Sequence[str],
    information_matrix: np.ndarray,
    correlation_threshold: float = CORRELATION_THRESHOLD,
    condition_threshold: float = CONDITION_THRESHOLD,
) -> list[WeakCombination]:
    """The pairs and directions the data barely determine (module docstring).

    Args:
        names: the free parameters.
        information_matrix: M (n_f × n_f) at the estimate.
        correlation_threshold: |ρ| from which a pair is named.
        condition_threshold: λ_max/λ from which a wider direction is named.
    """
    m = np.asarray(information_matrix, dtype=float)
    names = tuple(names)
    if m.shape != (len(names), len(names)) or not np.all(np.isfinite(m)):
        raise InputError(
            f"information_matrix: expected a finite {len(names)} × {len(names)} matrix for "
            f"{list(names)}, got shape {m.shape}"
        )
    d = np.sqrt(np.maximum(np.diag(m), 0.0))
    if np.any(d == 0.0):
        # parameters without information are named as undetermined by the estimation itself
        return []
    # M̃ = D⁻¹ M D⁻¹
    normalised = m / np.outer(d, d)
    eigenvalues, vectors = np.linalg.eigh(normalised)
    eigenvalues = np.maximum(eigenvalues, eigenvalues[-1] * 1e-300)
    condition = eigenvalues[-1] / eigenvalues
    # ρ = C_jk/√(C_jj C_kk) with C = M̃⁻¹ (the scaling by D cancels)
    inverse = vectors @ np.diag(1.0 / eigenvalues) @ vectors.T
    scale = np.sqrt(np.diag(inverse))
    rho = inverse / np.outer(scale, scale)
    # each pair with |ρ| over the threshold goes to the eigenvector that carries its variance:
    # the one of largest (v_ij² + v_ik²)/λ_i
    pairs: dict[int, list[tuple[int, int]]] = {}
    for j in range(len(names)):
        for k in range(j + 1, len(names)):
            if abs(rho[j, k]) >= correlation_threshold:
                share = (vectors[j] ** 2 + vectors[k] ** 2) / eigenvalues
                pairs.setdefault(int(np.argmax(share)), []).append((j, k))
    found = [
        _correlated_group(names, vectors[:, i], float(condition[i]), rho, members)
        for i, members in sorted(pairs.items())
    ]
    for i in np.flatnonzero(condition >= condition_threshold):
        if int(i) in pairs:
            continue
        members = np.flatnonzero(np.abs(vectors[:, i]) >= COMPONENT_FLOOR)
        weak = _oriented(vectors[members, i])
        found.append(
            WeakCombination(
                tuple(names[j] for j in members),
                tuple(float(v) for v in weak),
                condition=float(condition[i]),
            )
        )
    return found


def _correlated_group(
    names: tuple[str, ...],
    vector: np.ndarray,
    condition: float,
    rho: np.ndarray,
    pairs: list[tuple[int, int]],
) -> WeakCombination:
    """The parameters of ``pairs`` (all sharing the weak eigenvector ``vector``) as one
    combination: the eigenvector restricted to them; for a single pair also the determined
    combination across it."""
    members = sorted({j for pair in pairs for j in pair})
    # members that hardly take part in the weak direction (correlated with it only because
    # their own σ is small) are left out; at least the pair of largest |ρ| stays
    size = np.abs(vector[members])
    kept = [j for j, v in zip(members, size, strict=True) if v >= COMPONENT_FLOOR * size.max()]
    if len(kept) < 2:
        kept = list(max(pairs, key=lambda pair: abs(rho[pair])))
    members = kept
    pairs = [pair for pair in pairs if pair[0] in members and pair[1] in members]
    weak = _oriented(vector[members])
    strong = _oriented(np.array([-weak[1], weak[0]])) if len(members) == 2 else np.array([])
    return WeakCombination(
        tuple(names[j] for j in members),
        tuple(float(v) for v in weak),
        tuple(float(v) for v in strong),
        condition,
        tuple((names[j], names[k], float(rho[j, k])) for j, k in pairs),
    )


def check_identifiability(
    estimate,
    data=None,
    *,
    accuracy=None,
    level: float = 0.95,
    correlation_threshold: float = CORRELATION_THRESHOLD,
    condition_threshold: float = CONDITION_THRESHOLD,
    warn: bool = True,
    compiled: bool = True,
) -> IdentifiabilityReport:
    """The weak combinations of an output-error ``estimate`` and, for their parameters, the
    profile-likelihood intervals beside the quadratic ones.

    Args:
        estimate: an ``Estimate``.
        data: the data it came from (maneuvers, or an ``OutputErrorProblem``); needed for the
            profile intervals unless ``accuracy`` already has them. None: no profile.
        accuracy: an ``AccuracyResult`` of the estimate whose profile intervals (when it has
            them for the parameters) and coloured σ are used instead of a new assessment.
        level: confidence level of the intervals (that of ``accuracy`` when given).
        correlation_threshold, condition_threshold: see ``weak_combinations``.
        warn: issue the serious findings (``IdentifiabilityReport.warning_messages``) as
            ``IdentifiabilityWarning``; every finding is in the report.
        compiled: numba kernels for the profile's simulations.
    """
    names = tuple(estimate.free_names)
    combinations = tuple(
        weak_combinations(
            names, estimate.information_matrix, correlation_threshold, condition_threshold
        )
    )
    # profiles for the parameters of correlated pairs (a direction named by its condition
    # alone spreads over many parameters: its finding stands without a profile of each)
    involved = [n for n in names if any(n in c.names for c in combinations if c.correlations)]
    report = IdentifiabilityReport(combinations, level=level)
    if involved and (data is not None or _has_profile(accuracy, names, involved)):
        try:
            report = _with_profiles(
                estimate, data, accuracy, involved, combinations, level, compiled
            )
        except FlightIdError as exc:
            # the combinations stand; the profile is what could not be had
            note = f"profile intervals of {involved} not computed: {exc}"
            report = IdentifiabilityReport(combinations, level=level, notes=(note,))
    if warn:
        for message in report.warning_messages():
            warnings.warn(message, IdentifiabilityWarning, stacklevel=2)
    return report


def _has_profile(accuracy, names: tuple[str, ...], involved: list[str]) -> bool:
    if accuracy is None or accuracy.profile is None:
        return False
    intervals = accuracy.profile.intervals
    return all(not np.any(np.isnan(intervals[names.index(n)])) for n in involved)


def _with_profiles(estimate, data, accuracy, involved, combinations, level, compiled):
    """The report with ``ProfiledParameter`` entries, from ``accuracy`` or a new assessment
    of the ``involved`` parameters (Cramér–Rao, Beale's N_φ, profile)."""
    names = tuple(estimate.free_names)
    if not _has_profile(accuracy, names, involved):
        from flightid.accuracy.assess import assess

        accuracy = assess(
            estimate,
            data,
            level=level if accuracy is None else accuracy.level,
            methods=("cr", "profile"),
            parameters=involved,
            warn=False,
            compiled=compiled,
        )
    profiled = []
    for name in involved:
        j = names.index(name)
        lower, upper = (float(v) for v in accuracy.profile.intervals[j])
        cr_lower, cr_upper = (float(v) for v in accuracy.ci_cr[j])
        std_cr = float(accuracy.std_scaled[j])
        # σ_profile = σ_cr · (profile width)/(quadratic width)
        std_profile = std_cr * (upper - lower) / (cr_upper - cr_lower)
        profiled.append(
            ProfiledParameter(
                name,
                float(accuracy.center[j]),
                std_cr,
                float(accuracy.std_coloured[j]),
                (cr_lower, cr_upper),
                (lower, upper),
                float(std_profile),
            )
        )
    return IdentifiabilityReport(
        combinations, tuple(profiled), float(accuracy.level), float(accuracy.nonlinearity.n_phi)
    )
