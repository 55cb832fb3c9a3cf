"""Run a case with a ``[frequency_domain]`` table: frequency-domain estimation.

    [frequency_domain]
    method = "output_error"      # or "equation_error"
    band_hz = [0.1, 1.5]         # frequencies of the fit, Hz (ω = 0 excluded)
    step_hz = 0.04               # spacing of the transform, Hz (1/T: independent points)
    detrend = "mean"             # "mean", "linear" or "none", before transforming
    boundary = true              # estimate x(0), x(T) of each maneuver (nuisance)
    constants = true             # estimate constant output offsets d per maneuver (nuisance;
                                 # also state offsets c when boundary = false)
    start = "case"               # output error: start at the case's values or at the
                                 # frequency-domain equation-error estimates
    max_noise_cycles = 30        # alternations of the S update and the fit
    tolerance = 1e-6             # relative change of S (or θ) that ends them
    input_quadrature = "linear"  # transform rules (flightid.frequency.fourier)
    output_quadrature = "trapezoid"

The model comes from ``[model]``, ``[parameters]``, ``[biases]`` as for the time-domain
case (``flightid.cases.build.build_model``) and is put in matrix form
(``flightid.frequency.linear_system``). Parameters that move only the constant terms (Z_0,
M_0, state and output biases) are not estimated: on mean-removed data, on a band that
excludes ω = 0, a constant is indistinguishable from the nuisance offsets; they are reported
with their start value, ``free: false``, ``estimated: false`` and the reason.
"""

from __future__ import annotations

import hashlib
import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from flightid.cases.checks import CaseError, _bool, _integer, _known, _number, _string, _table
from flightid.errors import InputError
from flightid.numbers import format_sigma, format_with_sigma
from flightid.results import ResultSurface, finite_or_none

__all__ = [
    "FrequencyPreparation",
    "FrequencyResult",
    "FrequencySettings",
    "frequency_settings",
    "prepare_frequency_case",
    "run_frequency_case",
]

_KEYS = {
    "method",
    "band_hz",
    "step_hz",
    "detrend",
    "boundary",
    "constants",
    "start",
    "max_noise_cycles",
    "tolerance",
    "input_quadrature",
    "output_quadrature",
}
_METHODS = ("output_error", "equation_error")
BIAS_REASON = (
    "not estimated: a constant term, invisible on mean-removed data on a band excluding "
    "ω = 0 (absorbed by the per-maneuver nuisance constants); held at its start value"
)


@dataclass(frozen=True)
class FrequencySettings:
    """The checked ``[frequency_domain]`` table."""

    method: str = "output_error"
    band_hz: tuple[float, float] = (0.1, 1.5)
    step_hz: float = 0.04
    detrend: str = "mean"
    boundary: bool = True
    constants: bool = True
    start: str = "case"
    max_noise_cycles: int = 30
    tolerance: float = 1e-6
    input_quadrature: str = "linear"
    output_quadrature: str = "trapezoid"


def frequency_settings(table: Any) -> FrequencySettings:
    """Check the ``[frequency_domain]`` table; ``CaseError`` names the key."""
    from flightid.frequency.fourier import QUADRATURES, TRENDS

    key = "frequency_domain"
    table = _table(table, key)
    _known(table, _KEYS, key)
    values: dict[str, Any] = {}
    if "method" in table:
        values["method"] = _string(table["method"], f"{key}.method", _METHODS)
    if "band_hz" in table:
        band = table["band_hz"]
        if not isinstance(band, list) or len(band) != 2:
            raise CaseError(f"{key}.band_hz: expected [low, high] in Hz, got {band!r}")
        lo, hi = (_number(v, f"{key}.band_hz") for v in band)
        if not 0.0 < lo < hi:
            raise CaseError(
                f"{key}.band_hz: expected 0 < low < high (Hz; ω = 0 is excluded), got {band!r}"
            )
        values["band_hz"] = (lo, hi)
    if "step_hz" in table:
        step = _number(table["step_hz"], f"{key}.step_hz")
        if step <= 0.0:
            raise CaseError(f"{key}.step_hz: expected a positive step in Hz, got {step!r}")
        values["step_hz"] = step
    if "detrend" in table:
        values["detrend"] = _string(table["detrend"], f"{key}.detrend", TRENDS)
    for name in ("boundary", "constants"):
        if name in table:
            values[name] = _bool(table[name], f"{key}.{name}")
    if "start" in table:
        values["start"] = _string(table["start"], f"{key}.start", ("case", "equation_error"))
    if "max_noise_cycles" in table:
        values["max_noise_cycles"] = _integer(
            table["max_noise_cycles"], f"{key}.max_noise_cycles", 1
        )
    if "tolerance" in table:
        tol = _number(table["tolerance"], f"{key}.tolerance")
        if not 0.0 < tol < 1.0:
            raise CaseError(f"{key}.tolerance: expected a number in (0, 1), got {tol!r}")
        values["tolerance"] = tol
    for name in ("input_quadrature", "output_quadrature"):
        if name in table:
            values[name] = _string(table[name], f"{key}.{name}", QUADRATURES)
    return FrequencySettings(**values)


@dataclass(frozen=True)
class FrequencyResult(ResultSurface):
    """A frequency-domain estimate with the common result surface."""

    title: str
    method: str
    settings: FrequencySettings
    names: tuple[str, ...]
    values: np.ndarray
    initial: np.ndarray
    std: np.ndarray  # reported σ: the coloured-residual one (NaN: fixed or not estimated)
    std_coloured: np.ndarray  # coloured-residual sandwich (= std)
    free: np.ndarray  # estimated here
    units: tuple[str, ...]
    not_estimated: dict[str, str]
    nuisance: tuple[tuple[str, float, float], ...]
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    frequencies_hz: np.ndarray
    spectra: tuple  # ManeuverSpectra per maneuver
    model_outputs: tuple[np.ndarray, ...]
    system: Any  # LinearSystem at the estimate
    S: np.ndarray | None
    cost: float | None
    converged: bool
    message: str
    noise_cycles: int
    iterations: int
    wall_time_s: float
    case_info: dict = field(default_factory=dict)
    maneuvers: tuple[dict, ...] = ()
    output_units: tuple[str, ...] = ()
    cost_history: tuple[float, ...] = ()
    evaluation_history: tuple[int, ...] = ()
    sample_interval_s: float = float("nan")
    # Cramér–Rao σ, corrected for grids finer than 1/T (empty: taken as std)
    std_cr: np.ndarray = field(default_factory=lambda: np.zeros(0))
    grid_factors: tuple[float, ...] = ()
    # correlation matrix of the estimated parameters (of the reported covariance), (n_free,
    # n_free); empty: not kept
    correlation: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    # the case's model (linear in x and u) and the covariances of the estimated parameters:
    # ``covariance`` the one behind the reported σ, P = diag(σ) ρ diag(σ) with ρ the
    # correlation of the coloured-residual sandwich (``correlation``), and the Cramér–Rao
    # ``covariance_cr``; None: equation error (one regression per state equation, no joint
    # covariance) or the model is not kept
    model: Any = None
    covariance: np.ndarray | None = None
    covariance_cr: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.std_cr.size == 0:
            object.__setattr__(self, "std_cr", np.asarray(self.std, dtype=float).copy())

    def cr_understatement(self) -> float:
        """max over the estimated parameters of std / std_cr: how many times the
        Cramér–Rao bounds understate the reported σ (NaN without estimates)."""
        ratio = self.std[self.free] / self.std_cr[self.free]
        ratio = ratio[np.isfinite(ratio)]
        return float(ratio.max()) if ratio.size else float("nan")

    def model_transfer(self, frequencies_hz: np.ndarray) -> np.ndarray:
        """H(jω) = diag(e^{−jωτ_y}) [C (jωI − A)⁻¹ B + D] diag(e^{−jωτ_u}) at the estimate,
        (F, n_y, n_u) (``LinearSystem.transfer``)."""
        return self.system.transfer(frequencies_hz)

    def equivalent_variances(self) -> np.ndarray:
        """Time-domain equivalent of the residual spectral covariance, R_j = S_jj/(Δt T)
        (T the mean record length), per output; NaN without S (equation error)."""
        if self.S is None:
            return np.full(len(self.outputs), np.nan)
        duration = float(np.mean([s.duration_s for s in self.spectra]))
        return np.real(np.diag(self.S)) / (self.sample_interval_s * duration)

    def model_response_has_signal(self, j: int, k: int) -> bool:
        """True if output j responds to input k in the model."""
        return bool(np.any(np.abs(self.model_transfer(self.frequencies_hz[:3])[:, j, k]) > 0))

    def transforms(self):
        """(frequencies, Z, U) per maneuver."""
        return [(s.frequencies_hz, s.outputs, s.inputs) for s in self.spectra]

    def output_transforms(self):
        """(frequencies, Z measured, Ŷ model) per maneuver."""
        return [
            (s.frequencies_hz, s.outputs, y)
            for s, y in zip(self.spectra, self.model_outputs, strict=True)
        ]

    # ---------------------------------------------------------------- the model in use
    @property
    def estimated_model(self):
        """The case's model at the estimate, free = the estimated parameters. The ones in
        ``not_estimated`` (constant terms, initial states: invisible on the band) keep their
        start values, so a time-domain prediction carries their start values too."""
        import warnings

        from flightid.simulation.prediction import (
            PredictionError,
            PredictionWarning,
            model_at_estimate,
        )

        if self.model is None:
            raise PredictionError("this frequency-domain result holds no model")
        if self.not_estimated:
            start = {n: float(v) for n, v in zip(self.names, self.initial, strict=True)}
            held = {n: start[n] for n in self.not_estimated}
            warnings.warn(
                f"the parameters {held} are not estimated in the frequency domain (invisible "
                f"on the band) and are held at their start values in the time-domain model",
                PredictionWarning,
                stacklevel=3,
            )
        estimated = [n for n, f in zip(self.names, self.free, strict=True) if f]
        return model_at_estimate(self.model, self.names, self.values, estimated)

    def _covariance_for(self, std: str) -> tuple[np.ndarray | None, str]:
        """(covariance behind ``std`` — "default": coloured-residual, "cr": Cramér–Rao —,
        why there is none)."""
        from flightid.results import check_method

        check_method(std, ("default", "cr"), "std")
        covariance = self.covariance if std == "default" else self.covariance_cr
        why = (
            "frequency-domain equation error gives one regression per state equation, no "
            "joint parameter covariance"
            if self.method == "equation_error"
            else "this frequency-domain result holds no parameter covariance"
        )
        return covariance, why

    def predict(self, data, x0=None, *, bands: bool = False, std: str = "default"):
        """The estimated model simulated in the time domain on ``data`` (a ``FlightData``:
        one ``Prediction``; a list: a tuple), with residuals and fit numbers
        (``flightid.simulation.prediction.predict_result``).

        Args:
            data: maneuvers with the model's inputs and outputs.
            x0: initial states (one value per state, ``{state: value}``, or a list per
                maneuver); states not given start at the data's channel of that name.
            bands: σ of the outputs from the parameter covariance (delta method);
                ``PredictionError`` for equation error, which has none.
            std: "default" (coloured-residual covariance, the reported σ) or "cr".
        """
        from flightid.simulation.prediction import predict_result

        covariance, why = self._covariance_for(std)
        return predict_result(
            self.estimated_model, data, x0, bands=bands, covariance=covariance, no_covariance=why
        )

    def simulate(self, inputs, x0=None) -> np.ndarray:
        """Outputs (N_total, n_o) of the estimated model driven by the inputs of ``inputs``
        (a ``FlightData`` or a list), from ``x0`` (as in ``predict``)."""
        from flightid.simulation.prediction import simulate_result

        return simulate_result(self.estimated_model, inputs, x0)

    def linearize(self, at=None, *, std: str = "default"):
        """The estimated model about ``at`` (None: its initial state, inputs 0 — exact, the
        model is linear; a ``FlightData``; or ``(x, u)``) with the covariance of A, B, C, D
        from the parameter covariance (``std`` as in ``predict``; none, with a note, for
        equation error); returns a ``LinearModel`` (``modes()``)."""
        from flightid.simulation.prediction import linearize_result

        covariance, why = self._covariance_for(std)
        units = dict(zip(self.outputs, self.output_units, strict=False))
        return linearize_result(
            self.estimated_model, at, covariance=covariance, no_covariance=why, units=units
        )

    # ---------------------------------------------------------------- surface
    def _frame_rows(self) -> list[dict]:
        return [
            {
                "name": n,
                "value": float(v),
                "std": float(s),
                "std_cr": float(r),
                "std_coloured": float(c),
                "free": bool(f),
                "unit": u,
                "initial": float(i),
            }
            for n, v, s, r, c, f, u, i in zip(
                self.names,
                self.values,
                self.std,
                self.std_cr,
                self.std_coloured,
                self.free,
                self.units,
                self.initial,
                strict=True,
            )
        ]

    def conf_int(self, level: float = 0.95) -> np.ndarray:
        """Normal intervals θ̂ ± z·σ (the reported, coloured-residual σ) of the estimated
        parameters, (n, 2)."""
        from flightid.results import t_intervals

        return t_intervals(self.values[self.free], self.std[self.free], level, 0, "normal")

    @property
    def conf_int_names(self) -> list[str]:
        return [n for n, f in zip(self.names, self.free, strict=True) if f]

    def summary(self) -> str:
        band = self.settings.band_hz
        lines = [
            f"{self.title}",
            f"frequency-domain {self.method.replace('_', ' ')}, band {band[0]:g}–{band[1]:g} Hz, "
            f"step {self.settings.step_hz:g} Hz, {self.frequencies_hz.size} frequencies × "
            f"{len(self.spectra)} maneuver(s)",
            f"status: {'converged' if self.converged else 'NOT CONVERGED'} ({self.message})",
            self.sigma_line(),
            "",
            f"{'parameter':<12}{'estimate':>14}{'std':>12}{'std (CR)':>12}{'start':>12}",
        ]
        for row in self._frame_rows():
            if row["free"]:
                cr = row["std_cr"]
                cr_text = f"{format_sigma(cr):>12}" if np.isfinite(cr) else f"{'—':>12}"
                # σ to two significant digits, the estimate to σ's decimal place
                value_text, std_text = format_with_sigma(row["value"], row["std"])
                lines.append(
                    f"{row['name']:<12}{value_text:>14}{std_text:>12}"
                    f"{cr_text}{row['initial']:>12.6g}"
                )
            else:
                lines.append(
                    f"{row['name']:<12}{row['value']:>14.6g}{'—':>12}{'—':>12}"
                    f"{row['initial']:>12.6g}   not estimated"
                )
        if self.not_estimated:
            lines += ["", "not estimated: " + ", ".join(self.not_estimated) + " — " + BIAS_REASON]
        if self.nuisance:
            lines += [
                "",
                f"nuisance (per maneuver, deviations from the mean): {len(self.nuisance)} values",
            ]
        return "\n".join(lines)

    def sigma_line(self) -> str:
        """One line: which σ ``std`` is and how far the Cramér–Rao bounds understate it."""
        ratio = self.cr_understatement()
        text = "std: coloured-residual σ (correlation across frequency measured from the residuals)"
        if np.isfinite(ratio) and ratio > 1.2:
            text += f"; the Cramér–Rao bounds (std (CR)) understate it by up to ×{ratio:.2g}"
        if self.grid_factors and max(self.grid_factors) > 1.0:
            text += (
                f"; grid finer than 1/T: std (CR) counts one independent frequency per "
                f"{max(self.grid_factors):.3g} grid points"
            )
        return text

    def to_dict(self) -> dict:
        """One results.json entry (``docs/schema/results.schema.json``)."""
        parameters = []
        for row in self._frame_rows():
            entry = {
                "name": row["name"],
                "value": finite_or_none(row["value"]),
                "std": finite_or_none(row["std"]) if row["free"] else None,
                "free": row["free"],
                "unit": row["unit"],
                "initial": finite_or_none(row["initial"]),
                "estimated": row["free"],
                "std_coloured": finite_or_none(row["std_coloured"]) if row["free"] else None,
                "std_cr": finite_or_none(row["std_cr"]) if row["free"] else None,
            }
            if row["name"] in self.not_estimated:
                entry["note"] = self.not_estimated[row["name"]]
            parameters.append(entry)
        r_equivalent = self.equivalent_variances()
        return {
            "method": f"frequency_{self.method}",
            "converged": bool(self.converged),
            "status": "converged" if self.converged else "max_iterations",
            "message": self.message,
            "cost": None if self.cost is None else finite_or_none(self.cost),
            "iterations": int(self.iterations),
            "equivalent_evaluations": int(self.iterations),
            "accuracy_evaluations": 2 * int(self.free.sum()) if self.S is not None else 0,
            "noise_cycles": int(self.noise_cycles),
            "noise_policy": "spectral covariance S from the residuals"
            if self.S is not None
            else "least squares (σ² per equation)",
            "integration": "none (frequency domain)",
            "wall_time_s": float(self.wall_time_s),
            "R": [finite_or_none(v) for v in r_equivalent],
            "outputs": list(self.outputs),
            "output_units": list(self.output_units) or [""] * len(self.outputs),
            "fit_rms": [finite_or_none(np.sqrt(v)) for v in r_equivalent],
            "cost_history": [finite_or_none(v) for v in self.cost_history],
            "evaluation_history": [int(v) for v in self.evaluation_history],
            "prediction": [],
            "parameters": parameters,
            "frequency_domain": {
                "band_hz": list(self.settings.band_hz),
                "step_hz": self.settings.step_hz,
                "n_frequencies": int(self.frequencies_hz.size),
                "detrend": self.settings.detrend,
                "boundary": self.settings.boundary,
                "constants": self.settings.constants,
                "input_quadrature": self.settings.input_quadrature,
                "output_quadrature": self.settings.output_quadrature,
                "not_estimated": dict(self.not_estimated),
                "nuisance": [
                    {"name": n, "value": finite_or_none(v), "std": finite_or_none(s)}
                    for n, v, s in self.nuisance
                ],
                "S_diagonal": (
                    None if self.S is None else [float(np.real(v)) for v in np.diag(self.S)]
                ),
                "std_note": "std = std_coloured: coloured-residual sandwich across frequency "
                "(flightid.frequency.uncertainty); std_cr: Cramér–Rao bound with the grid "
                "correction c = max(1, 1/(T·step_hz))",
                "grid_factors": [float(c) for c in self.grid_factors],
                "R_note": "R and fit_rms are time-domain equivalents of the spectral "
                "residual covariance, R_j = S_jj / (Δt T) (white noise of variance σ² has "
                "E|V(ω)|² = Δt T σ²); null for equation error",
            },
            "case": dict(self.case_info),
            "maneuvers": list(self.maneuvers),
        }

    def plot(self, path: str | Path | None = None, *, dpi: int = 120):
        """The Bode figure (``flightid.frequency.plots.bode_figure``); PNG at ``path``."""
        from flightid.frequency.plots import bode_figure

        figure = bode_figure(self)
        if path is not None:
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            figure.savefig(path, dpi=dpi)
        return figure


Progress = Callable[[str], None]


def _correlation(covariance, n_free: int) -> np.ndarray:
    """ρ_ij = P_ij / √(P_ii P_jj) of the estimated parameters; empty when the covariance
    is not the free parameters' (n_free × n_free)."""
    if covariance is None:
        return np.zeros((0, 0))
    matrix = np.asarray(covariance, dtype=float)
    if matrix.shape != (n_free, n_free):
        return np.zeros((0, 0))
    scale = np.sqrt(np.where(np.diag(matrix) > 0, np.diag(matrix), np.nan))
    return matrix / np.outer(scale, scale)


def _reported_covariance(coloured, std_free: np.ndarray) -> np.ndarray | None:
    """The covariance behind the reported σ: P = diag(σ) ρ diag(σ), ρ the correlation of the
    coloured-residual sandwich (the reported σ is the larger of its σ and the Cramér–Rao
    one, per parameter); None without a covariance."""
    if coloured is None:
        return None
    correlation = _correlation(coloured, std_free.size)
    # P_ij = σ_i ρ_ij σ_j
    return correlation * np.outer(std_free, std_free)


@dataclass(frozen=True)
class FrequencyPreparation:
    """Everything a frequency-domain run checks before it estimates (``validate`` stops
    here): the settings, the model and its matrix form, the maneuvers and their spectra,
    which parameters are estimated."""

    settings: FrequencySettings
    model: Any
    description: str
    maneuvers: tuple
    names: tuple[str, ...]
    free: np.ndarray
    not_estimated: dict[str, str]
    frequencies: np.ndarray
    spectra: tuple


def prepare_frequency_case(case, data_dir: str | Path | None = None) -> FrequencyPreparation:
    """Read and check everything a frequency-domain run needs before estimating: the
    ``[frequency_domain]`` table, the data, the model (linear in x and u), the band against
    each maneuver's Nyquist frequency, the number of equations against the unknowns, and
    for equation error the measured states and the parameters it can determine. Every
    failure is a ``CaseError`` naming the key."""
    from flightid.cases.build import base_model, build_model, load_maneuvers, resolve_data_dir
    from flightid.frequency.fourier import frequency_grid, maneuver_spectra
    from flightid.frequency.linear_system import bias_like_parameters, linear_system

    settings = frequency_settings(case.frequency_domain)
    directory = resolve_data_dir(case, data_dir)
    maneuvers = load_maneuvers(case, directory)
    base, description = base_model(case, directory)
    model, maneuvers = build_model(case, maneuvers, base=base)
    try:
        linear_system(model)
        bias_like = bias_like_parameters(model)
    except InputError as exc:
        raise CaseError(f"model: {exc}") from None
    x0_names = {
        p.name for p in model.parameters if p.name.startswith("x0_") and p.name not in bias_like
    }
    names = tuple(model.parameters.names)
    free_case = model.parameters.free_mask.copy()
    not_estimated = {n: BIAS_REASON for n in bias_like}
    for n in x0_names:
        if free_case[names.index(n)]:
            not_estimated[n] = (
                "not estimated: initial states enter as the per-maneuver boundary nuisance "
                "values x(0), x(T)"
            )
    free = np.array([f and n not in not_estimated for n, f in zip(names, free_case, strict=True)])
    if not free.any():
        raise CaseError("frequency_domain: the model has no free parameter the band can determine")
    try:
        frequencies = frequency_grid(settings.band_hz, settings.step_hz)
        spectra = []
        for m in maneuvers:
            inputs = np.column_stack([m.input(n) for n in model.inputs])
            outputs = np.column_stack([m.output(n) for n in model.outputs])
            spectra.append(
                maneuver_spectra(
                    m.time,
                    inputs,
                    outputs,
                    frequencies,
                    detrend=settings.detrend,
                    input_quadrature=settings.input_quadrature,
                    output_quadrature=settings.output_quadrature,
                    name=m.name,
                )
            )
    except InputError as exc:
        raise CaseError(f"frequency_domain: {exc}") from None
    _check_estimator(settings, model, free, spectra)
    return FrequencyPreparation(
        settings=settings,
        model=model,
        description=description,
        maneuvers=tuple(maneuvers),
        names=names,
        free=free,
        not_estimated=not_estimated,
        frequencies=frequencies,
        spectra=tuple(spectra),
    )


def _check_estimator(settings: FrequencySettings, model, free: np.ndarray, spectra) -> None:
    """The estimator's own checks that need no estimate: enough equations for the unknowns
    (output error) and, for equation error, measured states and every free parameter in
    some equation."""
    from flightid.frequency.equation_error import equation_error_structure
    from flightid.frequency.linear_system import linear_system
    from flightid.frequency.output_error import check_equation_count

    names = model.parameters.names
    theta0 = model.parameters.values.astype(float)
    try:
        if settings.method == "output_error":
            check_equation_count(
                spectra,
                int(free.sum()),
                len(model.states),
                len(model.outputs),
                boundary=settings.boundary,
                constants=settings.constants,
            )
        if settings.method == "equation_error" or settings.start == "equation_error":
            determined = equation_error_structure(
                lambda theta: linear_system(model, theta),
                theta0,
                free,
                tuple(model.states),
                tuple(model.outputs),
            )
    except InputError as exc:
        raise CaseError(f"frequency_domain: {exc}") from None
    if settings.method == "equation_error":
        undetermined = [n for n, f, e in zip(names, free, determined, strict=True) if f and not e]
        if undetermined:
            raise CaseError(
                f"frequency_domain.method: equation error determines no equation for "
                f'{undetermined}; use method = "output_error"'
            )


def run_frequency_case(
    case, data_dir: str | Path | None = None, progress: Progress | None = None
) -> FrequencyResult:
    """Run the case's frequency-domain estimation; ``CaseError`` for a malformed table or a
    model the frequency domain cannot take (``prepare_frequency_case``)."""
    from flightid.cases.build import maneuver_entry
    from flightid.frequency.equation_error import equation_error
    from flightid.frequency.linear_system import linear_system
    from flightid.frequency.output_error import model_response, output_error
    from flightid.frequency.uncertainty import grid_factors

    started = _time.perf_counter()
    case_file = Path(case.path) if case.path is not None else None
    case_sha256 = (
        hashlib.sha256(case_file.read_bytes()).hexdigest()
        if case_file is not None and case_file.is_file()
        else ""
    )
    prepared = prepare_frequency_case(case, data_dir)
    settings, model, description = prepared.settings, prepared.model, prepared.description
    maneuvers, names, free = prepared.maneuvers, prepared.names, prepared.free
    not_estimated, frequencies = prepared.not_estimated, prepared.frequencies
    spectra = list(prepared.spectra)
    if progress is not None:
        progress(
            f"frequency domain: {frequencies.size} frequencies in {settings.band_hz} Hz × "
            f"{len(spectra)} maneuver(s), {int(free.sum())} parameters, {settings.method}"
        )

    def system_of(theta):
        return linear_system(model, theta)

    theta0 = model.parameters.values.astype(float)
    states, outputs = tuple(model.states), tuple(model.outputs)
    try:
        if settings.method == "equation_error" or settings.start == "equation_error":
            ee = equation_error(
                system_of,
                theta0,
                free,
                spectra,
                states,
                outputs,
                boundary=settings.boundary,
                constants=settings.constants,
            )
        if settings.method == "equation_error":
            # (every free parameter is in some equation: prepare_frequency_case checked it)
            system = system_of(ee.theta)
            model_outputs = tuple(
                model_response(system, s, None, boundary=False, constants=False) for s in spectra
            )
            values, std, std_col, std_cr = ee.theta, ee.std, ee.std, ee.std_cr
            # one regression per state equation: no joint covariance of all parameters
            covariance = covariance_cr = None
            S = cost = None
            converged, message, cycles, iterations = True, "closed-form least squares", 0, 0
            nuisance: tuple = ()
            cost_history: tuple = ()
            evaluation_history: tuple = ()
        else:
            start = ee.theta if settings.start == "equation_error" else theta0
            fit = output_error(
                system_of,
                start,
                free,
                spectra,
                states,
                outputs,
                boundary=settings.boundary,
                constants=settings.constants,
                max_noise_cycles=settings.max_noise_cycles,
                tolerance=settings.tolerance,
                scales=np.maximum(np.abs(start), 0.01),
            )
            values, std, std_col, std_cr = fit.theta, fit.std, fit.std_coloured, fit.std_cr
            covariance, covariance_cr = fit.covariance_coloured, fit.covariance
            S, cost = fit.S, fit.cost
            converged, message = fit.converged, fit.message
            cycles, iterations = fit.noise_cycles, fit.iterations
            model_outputs = fit.model_outputs
            cost_history, evaluation_history = fit.cost_history, fit.evaluation_history
            nuisance = tuple(zip(fit.nuisance_names, fit.nuisance, fit.nuisance_std, strict=True))
            system = system_of(values)
    except InputError as exc:
        if isinstance(exc, CaseError):
            raise
        raise CaseError(f"frequency_domain: {exc}") from None
    result = FrequencyResult(
        title=case.title,
        method=settings.method,
        settings=settings,
        names=names,
        values=np.asarray(values, dtype=float),
        initial=theta0,
        std=np.where(free, std, np.nan),
        std_coloured=np.where(free, std_col, np.nan),
        std_cr=np.where(free, std_cr, np.nan),
        grid_factors=tuple(float(c) for c in grid_factors(spectra)),
        correlation=_correlation(covariance, int(free.sum())),
        free=free,
        units=tuple(p.unit for p in model.parameters),
        not_estimated=not_estimated,
        nuisance=nuisance,
        states=states,
        inputs=tuple(model.inputs),
        outputs=outputs,
        frequencies_hz=frequencies,
        spectra=tuple(spectra),
        model_outputs=tuple(model_outputs),
        system=system,
        S=S,
        cost=cost,
        converged=converged,
        message=message,
        noise_cycles=cycles,
        iterations=iterations,
        wall_time_s=_time.perf_counter() - started,
        case_info={
            "title": case.title,
            "file": str(case.path),
            "sha256": case_sha256,
            "model": description,
        },
        output_units=tuple(maneuvers[0].units.get(n, "") for n in outputs),
        cost_history=cost_history,
        evaluation_history=evaluation_history,
        sample_interval_s=float(np.mean([m.dt for m in maneuvers])),
        maneuvers=tuple(maneuver_entry(m) for m in maneuvers),
        model=model,
        covariance=_reported_covariance(covariance, std[free]),
        covariance_cr=covariance_cr,
    )
    if not np.all(np.isfinite(result.values[free])) or not np.all(np.isfinite(result.std[free])):
        raise CaseError(
            "frequency_domain: the estimate has non-finite values or bounds; the band does not "
            "determine every free parameter"
        )
    return result
