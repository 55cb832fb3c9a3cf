"""Model-based input design: choose band, timing and amplitudes for a criterion under limits.

A ``DesignProblem`` holds the model (parameters at their a-priori values, started in trim),
the designed inputs with their amplitude limits (peak |Δu| about the trim value), the inputs
held at constant values, the duration and sample interval, the noise assumed per output and
optional response limits (peak |Δy| of an output about its trim-input response). The design:

1. builds candidates — for a multisine the upper edge of the band scaled by factors
   c ∈ geomspace(c_min, 1) (the lower edge kept), for a step signal the pulse unit Δt over
   geomspace(0.5, 2) × the rule value (0.3/f_n, ``flightid.design.signals``), the inputs one
   after another from ``start_s`` with ``gap_s`` between them;
2. gives every candidate the largest amplitudes the limits allow: each input at its amplitude
   limit, then one common factor s ≤ 1 chosen so that every response stays within its limit
   (s = 1/r for the peak ratio r, exact for a linear model, then bisection-safe reductions
   until the simulated response complies);
3. predicts each candidate's Cramér–Rao bounds (``flightid.design.information``) and keeps
   the one with the smallest criterion (D-optimal, A-optimal, or the named parameters);
4. with several inputs held back by a response limit, raises each input's own amplitude
   factor s_j towards 1 as far as the limits allow, keeping the change where the criterion
   improves (an input whose response does not bind is not held back by another's).

Information grows with amplitude (∝ s² for a linear model), which is why amplitudes sit at
the tightest limit; the search is over band / timing on a grid of ``candidates`` values, and
over the amplitudes by the per-input refinement of step 4. The
returned input is checked once more against every limit before it is handed back (amplitude,
duration, response): a design that cannot meet them raises ``DesignError``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from flightid.data.flightdata import FlightData
from flightid.design.information import CRITERIA, PredictedAccuracy, predict_accuracy
from flightid.design.multisine import Multisine, design_multisine
from flightid.design.signals import (
    PULSE_PATTERNS,
    STEP_SIGNALS,
    natural_frequency_hz,
    pulse_sequence,
    pulse_width_s,
    sequence_length_s,
)
from flightid.errors import FlightIdError, InputError
from flightid.model.statespace import StateSpaceModel

__all__ = [
    "SIGNALS",
    "Candidate",
    "DesignError",
    "DesignProblem",
    "InputSpec",
    "design_input",
    "evaluate_input",
    "trim_state",
]

SIGNALS = ("multisine", *STEP_SIGNALS)
# rounding allowance of the limit checks (relative)
_LIMIT_TOLERANCE = 1e-9


class DesignError(FlightIdError, RuntimeError):
    """No input meets the design's limits (the message says which limit and by how much)."""


@dataclass(frozen=True)
class InputSpec:
    """A designed input: peak perturbation ``amplitude`` about ``trim`` (input units), the
    multisine band (Hz) or the step signal's pulse unit ``pulse_s`` (None: from f_n)."""

    name: str
    amplitude: float
    trim: float = 0.0
    band_hz: tuple[float, float] | None = None
    pulse_s: float | None = None

    def __post_init__(self) -> None:
        if not np.isfinite(self.amplitude) or self.amplitude <= 0:
            raise InputError(
                f"inputs.{self.name}.amplitude: expected a positive peak perturbation, got "
                f"{self.amplitude!r}"
            )
        if self.pulse_s is not None and not (np.isfinite(self.pulse_s) and self.pulse_s > 0):
            raise InputError(f"inputs.{self.name}.pulse_s: expected a positive time (s)")


@dataclass(frozen=True)
class DesignProblem:
    """Everything a design needs (module docstring). ``model`` starts in trim (its x0);
    ``held`` gives every model input that is not designed: a constant, or a series of one
    value per sample of ``time`` (e.g. measured longitudinal variables of a lateral model)."""

    model: StateSpaceModel
    inputs: tuple[InputSpec, ...]
    duration_s: float
    dt_s: float
    noise_std: Mapping[str, float]
    signal: str = "multisine"
    criterion: str = "d_optimal"
    parameters: tuple[str, ...] = ()
    held: Mapping[str, float | np.ndarray] = field(default_factory=dict)
    limits: Mapping[str, float] = field(default_factory=dict)
    band_hz: tuple[float, float] | None = None
    candidates: int = 6
    start_s: float = 1.0
    gap_s: float = 2.0
    method: str = "rk4"
    input_interpolation: str = "linear"

    def __post_init__(self) -> None:
        self._check_signal_and_times()
        self._check_inputs()
        self._check_held()
        self._check_limits()
        if (
            isinstance(self.candidates, bool)
            or not isinstance(self.candidates, int)
            or self.candidates < 1
        ):
            raise InputError(f"candidates: expected a positive integer, got {self.candidates!r}")
        self._check_timing()
        self._check_bands()
        self._check_parameters()

    def _check_signal_and_times(self) -> None:
        """A known signal and criterion (``"parameters"`` with names), positive
        ``duration_s`` and ``dt_s`` giving at least 10 samples."""
        if self.signal not in SIGNALS:
            raise InputError(f"signal: expected one of {list(SIGNALS)}, got {self.signal!r}")
        if self.criterion not in CRITERIA:
            raise InputError(f"criterion: expected one of {list(CRITERIA)}, got {self.criterion!r}")
        if self.criterion == "parameters" and not self.parameters:
            raise InputError('parameters: criterion "parameters" needs parameter names')
        for key in ("duration_s", "dt_s"):
            value = getattr(self, key)
            if not np.isfinite(value) or value <= 0:
                raise InputError(f"{key}: expected a positive time (s), got {value!r}")
        if self.dt_s * 10 > self.duration_s:
            raise InputError(
                f"dt_s: {self.dt_s} s gives fewer than 10 samples over duration_s = "
                f"{self.duration_s} s"
            )

    def _check_inputs(self) -> None:
        """At least one designed input, each an input of the model; every other model input
        held."""
        names = [s.name for s in self.inputs]
        if not names:
            raise InputError("inputs: expected at least one designed input")
        model_inputs = set(self.model.inputs)
        for name in names:
            if name not in model_inputs:
                raise InputError(
                    f"inputs.{name}: not an input of the model; inputs: {list(self.model.inputs)}"
                )
        missing = [n for n in self.model.inputs if n not in names and n not in self.held]
        if missing:
            raise InputError(
                f"inputs: the model inputs {missing} are neither designed nor held; give them "
                "an amplitude or a constant value"
            )

    def _check_held(self) -> None:
        """Each held input a finite constant or one finite value per sample of ``time``."""
        for name, value in self.held.items():
            shape = np.shape(value)
            if shape not in ((), (self.n_intervals + 1,)) or not np.all(np.isfinite(value)):
                raise InputError(
                    f"held.{name}: expected a finite constant or {self.n_intervals + 1} samples "
                    f"(one per sample of time), got shape {shape}"
                )

    def _check_limits(self) -> None:
        """Each limit a positive number on an output of the model."""
        for output, limit in self.limits.items():
            if output not in self.model.outputs:
                raise InputError(
                    f"limits.{output}: not an output of the model; outputs: "
                    f"{list(self.model.outputs)}"
                )
            if not np.isfinite(limit) or limit <= 0:
                raise InputError(f"limits.{output}: expected a positive limit, got {limit!r}")

    def _check_parameters(self) -> None:
        """The ``parameters`` criterion's names are free parameters of the model."""
        for parameter in self.parameters:
            if parameter not in self.model.parameters.free_names:
                raise InputError(
                    f"parameters: {parameter!r} is not a free parameter; free: "
                    f"{self.model.parameters.free_names}"
                )

    def _check_timing(self) -> None:
        """``start_s`` and ``gap_s``: finite and ≥ 0 (a pulse before t = 0 would be cut off
        without a word); a step signal's first pulse starts inside ``duration_s``."""
        for key in ("start_s", "gap_s"):
            value = getattr(self, key)
            if isinstance(value, bool) or not np.isfinite(value) or value < 0:
                raise InputError(f"{key}: expected a time ≥ 0 s, got {value!r}")
        if self.signal in STEP_SIGNALS and self.start_s >= self.duration_s:
            raise InputError(
                f"start_s: the first pulse starts at {self.start_s:g} s, at or after the end of "
                f"the input (duration_s = {self.duration_s:g} s)"
            )

    def _check_bands(self) -> None:
        """Every multisine band (``band_hz`` and each input's) below the Nyquist frequency
        f_N = 1/(2 Δt) of ``dt_s``: a harmonic at or above it cannot be sampled."""
        # f_N = 1 / (2 Δt)
        nyquist_hz = 0.5 / self.dt_s
        bands = [("band_hz", self.band_hz)] + [
            (f"inputs.{s.name}.band_hz", s.band_hz) for s in self.inputs
        ]
        for key, band in bands:
            if band is None:
                continue
            if len(band) != 2 or not 0 <= band[0] < band[1] or not np.isfinite(band[1]):
                raise InputError(
                    f"{key}: expected [low, high] with 0 ≤ low < high (Hz), got {band!r}"
                )
            if band[1] >= nyquist_hz:
                raise InputError(
                    f"{key}: the band reaches {band[1]:g} Hz, at or above the Nyquist frequency "
                    f"{nyquist_hz:g} Hz of dt_s = {self.dt_s:g} s; lower the band's upper edge "
                    f"below {nyquist_hz:g} Hz or shorten dt_s"
                )

    @property
    def n_intervals(self) -> int:
        """n = ⌊T/Δt⌋ sample intervals (the input never outlasts ``duration_s``)."""
        return int(np.floor(self.duration_s / self.dt_s + 1e-9))

    @property
    def period_s(self) -> float:
        """n·Δt ≤ T: the length actually sampled, and a multisine's period."""
        return self.n_intervals * self.dt_s

    @property
    def time(self) -> np.ndarray:
        """Sample times 0, Δt, …, n·Δt (s)."""
        return np.arange(self.n_intervals + 1) * self.dt_s

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.inputs)

    @property
    def amplitudes(self) -> np.ndarray:
        return np.array([s.amplitude for s in self.inputs])

    def flight_data(self, perturbations: np.ndarray, name: str = "designed input") -> FlightData:
        """The maneuver the model flies: designed inputs = trim + Δu, held inputs as given."""
        t = self.time
        channels = {n: np.broadcast_to(np.asarray(v, float), t.shape) for n, v in self.held.items()}
        for j, spec in enumerate(self.inputs):
            channels[spec.name] = spec.trim + perturbations[:, j]
        return FlightData(t, {n: channels[n] for n in self.model.inputs}, name=name)


@dataclass(frozen=True)
class Candidate:
    """One evaluated input: Δu (N, m) about trim, its settings and its predicted accuracy."""

    signal: str
    time: np.ndarray
    perturbations: np.ndarray
    input_names: tuple[str, ...]
    amplitude_factors: tuple[float, ...]  # s_j ≤ 1 per input: Δu_j peak = s_j × its limit
    setting: dict  # band_hz per input (multisine) or pulse_s and start_s per input (steps)
    accuracy: PredictedAccuracy
    criterion_value: float
    response_peak: dict  # output → peak |Δy| about the trim-input response
    multisine: Multisine | None = None

    @property
    def peak_amplitudes(self) -> np.ndarray:
        """max_k |Δu_j,k| per input."""
        return np.max(np.abs(self.perturbations), axis=0)


def trim_state(model: StateSpaceModel, inputs: Mapping[str, float]) -> np.ndarray:
    """x with f(0, x, u_trim, θ) = 0, from the model's x0 (scipy.optimize.root, hybr).

    Raises ``InputError`` when no equilibrium is found (residual above 1e-9·(1 + |f(x0)|))."""
    from scipy.optimize import root

    u = np.array([float(inputs[n]) for n in model.inputs])
    theta = model.function_theta(model.parameters.values)
    x0 = model.initial_state()

    def rates(x: np.ndarray) -> np.ndarray:
        return np.asarray(model.f(0.0, x, u, theta), dtype=float)

    solution = root(rates, x0, method="hybr")
    residual = float(np.max(np.abs(rates(solution.x)))) if solution.x.size else 0.0
    if not np.all(np.isfinite(solution.x)) or residual > 1e-9 * (1 + np.max(np.abs(rates(x0)))):
        raise InputError(
            f"trim: no equilibrium f(x, u_trim) = 0 found from x0 = {x0.tolist()} (largest "
            f"|ẋ| left {residual:.3g}); give the initial state instead (design.trim = false)"
        )
    return solution.x


def _outputs(problem: DesignProblem, perturbations: np.ndarray) -> np.ndarray:
    from flightid.simulation import simulate

    return simulate(
        problem.model,
        problem.flight_data(perturbations),
        method=problem.method,
        input_interpolation=problem.input_interpolation,
    )


def _response_peaks(problem: DesignProblem, perturbations: np.ndarray, base: np.ndarray) -> dict:
    """output → max_k |y_k(Δu) − y_k(0)|."""
    y = _outputs(problem, perturbations)
    return {
        o: float(np.max(np.abs(y[:, i] - base[:, i]))) for i, o in enumerate(problem.model.outputs)
    }


def _limit_ratio(problem: DesignProblem, peaks: Mapping[str, float]) -> float:
    """max over limited outputs of peak |Δy| / limit (0 without limits)."""
    return max((peaks[o] / limit for o, limit in problem.limits.items()), default=0.0)


def _within_limits(problem: DesignProblem, perturbations: np.ndarray, base: np.ndarray):
    """(the largest common factor s ≤ 1 that keeps every response within its limit, peaks)."""
    peaks = _response_peaks(problem, perturbations, base)
    ratio = _limit_ratio(problem, peaks)
    if ratio <= 1.0:
        return 1.0, peaks
    factor = 1.0
    for _ in range(40):
        # Δy ∝ s for a linear model: s ← s / r, with a 0.1 % margin against rounding
        factor *= 0.999 / ratio
        peaks = _response_peaks(problem, factor * perturbations, base)
        ratio = _limit_ratio(problem, peaks)
        if ratio <= 1.0:
            return factor, peaks
    raise DesignError(
        f"limits: no amplitude keeps the response within its limits (peak/limit still "
        f"{ratio:.3g} at {factor:.3g} × the amplitude limits)"
    )


def evaluate_input(
    problem: DesignProblem,
    perturbations: np.ndarray,
    signal: str = "given",
    setting: dict | None = None,
    multisine: Multisine | None = None,
    scale_to_limits: bool = False,
    factors: tuple[float, ...] | None = None,
) -> Candidate:
    """Predicted accuracy and response of the input Δu (N, m) about trim (no limit scaling
    unless ``scale_to_limits``; ``factors`` records the amplitude factors Δu was made with)."""
    perturbations = np.asarray(perturbations, dtype=float)
    expected = (problem.time.size, len(problem.inputs))
    if perturbations.shape != expected:
        raise InputError(f"perturbations: expected shape {expected}, got {perturbations.shape}")
    base = _outputs(problem, np.zeros(expected))
    factor = 1.0
    if scale_to_limits:
        factor, peaks = _within_limits(problem, perturbations, base)
        perturbations = factor * perturbations
    else:
        peaks = _response_peaks(problem, perturbations, base)
    accuracy = predict_accuracy(
        problem.model,
        problem.flight_data(perturbations),
        problem.noise_std,
        method=problem.method,
        input_interpolation=problem.input_interpolation,
    )
    return Candidate(
        signal,
        problem.time,
        perturbations,
        problem.names,
        tuple(float(f) * factor for f in (factors or (1.0,) * len(problem.inputs))),
        dict(setting or {}),
        accuracy,
        accuracy.criterion(problem.criterion, problem.parameters),
        peaks,
        multisine.with_amplitudes(multisine.amplitudes) if multisine is not None else None,
    )


def _input_bands(problem: DesignProblem) -> list[tuple[float, float]]:
    bands = []
    for spec in problem.inputs:
        band = spec.band_hz or problem.band_hz
        if band is None:
            raise InputError(
                f"inputs.{spec.name}.band_hz: a multisine needs a frequency band (design.band_hz "
                "or per input)"
            )
        bands.append((float(band[0]), float(band[1])))
    return bands


def _multisine_candidates(problem: DesignProblem):
    """(setting, Δu, multisine) for each scaled band (module docstring, step 1)."""
    bands = _input_bands(problem)
    common = len(set(bands)) == 1
    period = problem.period_s
    m = len(problem.inputs)
    # the narrowest band still needs ≥ 3 harmonics per input: c_min from that
    widths = [hi - lo for lo, hi in bands]
    c_min = min(1.0, max((3 * m if common else 3) / period / w for w in widths))
    factors = np.geomspace(c_min, 1.0, problem.candidates) if problem.candidates > 1 else [1.0]
    seen = set()
    for c in factors:
        scaled = [(lo, lo + c * (hi - lo)) for lo, hi in bands]
        try:
            multisine = design_multisine(
                problem.names,
                period,
                scaled[0] if common else scaled,
                problem.amplitudes.tolist(),
            )
        except InputError:
            continue
        key = tuple(tuple(k.tolist()) for k in multisine.harmonics)
        if key in seen:
            continue
        seen.add(key)
        setting = {
            spec.name: {"band_hz": [float(f[0]), float(f[-1])], "harmonics": int(f.size)}
            for spec, f in zip(
                problem.inputs, [multisine.frequencies_hz(n) for n in problem.names], strict=True
            )
        }
        yield setting, multisine.signals(problem.time), multisine


def _pulse_units(problem: DesignProblem, spec: InputSpec) -> float:
    if spec.pulse_s is not None:
        return float(spec.pulse_s)
    # held series enter with their first sample (the flight condition the pulses start from)
    held = {n: float(np.ravel(v)[0]) for n, v in problem.held.items()}
    trim_inputs = {**held, **{s.name: s.trim for s in problem.inputs}}
    theta = problem.model.function_theta(problem.model.parameters.values)
    f_n = natural_frequency_hz(
        problem.model.f,
        problem.model.initial_state(),
        np.array([trim_inputs[n] for n in problem.model.inputs]),
        theta,
    )
    return pulse_width_s(problem.signal, f_n)


def _step_candidates(problem: DesignProblem):
    """(setting, Δu, None) for each pulse-unit factor (module docstring, step 1)."""
    widths, signs = PULSE_PATTERNS[problem.signal]
    rule = [_pulse_units(problem, spec) for spec in problem.inputs]
    factors = np.geomspace(0.5, 2.0, problem.candidates) if problem.candidates > 1 else [1.0]
    t = problem.time
    for c in factors:
        start = problem.start_s
        columns, setting = [], {}
        for spec, dt in zip(problem.inputs, rule, strict=True):
            pulse = c * dt
            length = sequence_length_s(problem.signal, pulse)
            columns.append(pulse_sequence(t, start, pulse, widths, signs, spec.amplitude))
            setting[spec.name] = {"pulse_s": float(pulse), "start_s": float(start)}
            start += length + problem.gap_s
        # the last sequence must end (and the response have time to show) inside T
        if start - problem.gap_s > problem.period_s - problem.dt_s:
            continue
        yield setting, np.column_stack(columns), None


def _shortest_steps(problem: DesignProblem) -> str:
    """What the shortest step candidate needs (for the message when none fits)."""
    shortest = min(np.geomspace(0.5, 2.0, problem.candidates)) if problem.candidates > 1 else 1.0
    lengths = [
        sequence_length_s(problem.signal, shortest * _pulse_units(problem, spec))
        for spec in problem.inputs
    ]
    needed = problem.start_s + sum(lengths) + problem.gap_s * (len(lengths) - 1)
    return (
        f"the shortest {problem.signal} candidate needs {needed:.4g} s (start_s "
        f"{problem.start_s:g} + sequences {[round(v, 3) for v in lengths]} + gaps); lengthen "
        "duration_s or give a shorter pulse_s"
    )


def _check_limits(problem: DesignProblem, candidate: Candidate) -> None:
    """The returned input obeys every limit (amplitude, duration, response) or DesignError."""
    peaks = candidate.peak_amplitudes
    for spec, peak in zip(problem.inputs, peaks, strict=True):
        if peak > spec.amplitude * (1 + _LIMIT_TOLERANCE):
            raise DesignError(
                f"inputs.{spec.name}.amplitude: the designed input reaches {peak:.6g}, above the "
                f"limit {spec.amplitude:.6g}"
            )
    if candidate.time[-1] > problem.duration_s * (1 + _LIMIT_TOLERANCE):
        raise DesignError(
            f"duration_s: the designed input lasts {candidate.time[-1]:.6g} s, longer than "
            f"{problem.duration_s:.6g} s"
        )
    for output, limit in problem.limits.items():
        if candidate.response_peak[output] > limit * (1 + _LIMIT_TOLERANCE):
            raise DesignError(
                f"limits.{output}: the designed input moves {output} by "
                f"{candidate.response_peak[output]:.6g}, above the limit {limit:.6g}"
            )


def design_input(problem: DesignProblem, progress=None) -> tuple[Candidate, list[Candidate]]:
    """The best candidate for the problem's criterion, and every feasible candidate tried
    (module docstring). Raises ``DesignError`` when no candidate can be evaluated."""
    source = _multisine_candidates if problem.signal == "multisine" else _step_candidates
    tried: list[Candidate] = []
    reasons: list[str] = []
    for setting, perturbations, multisine in source(problem):
        try:
            candidate = evaluate_input(
                problem, perturbations, problem.signal, setting, multisine, scale_to_limits=True
            )
        except (InputError, DesignError) as exc:
            reasons.append(f"{setting}: {exc}")
            continue
        if multisine is not None:
            candidate = Candidate(
                **{
                    **candidate.__dict__,
                    "multisine": multisine.with_amplitudes(candidate.peak_amplitudes),
                }
            )
        tried.append(candidate)
        if progress is not None:
            progress(
                f"candidate {len(tried)}: {setting} amplitude × "
                f"{candidate.amplitude_factors[0]:.3g}, "
                f"{problem.criterion} = {candidate.criterion_value:.6g}"
            )
    if not tried:
        if reasons:
            raise DesignError(f"design: no feasible input ({'; '.join(reasons[:3])})")
        raise DesignError(
            f"duration_s: no candidate fits in {problem.duration_s:g} s; {_shortest_steps(problem)}"
        )
    best = min(tried, key=lambda c: c.criterion_value)
    best = _raise_amplitudes(problem, best, progress)
    _check_limits(problem, best)
    return best, tried


def _feasible(problem: DesignProblem, perturbations: np.ndarray, base: np.ndarray) -> bool:
    return _limit_ratio(problem, _response_peaks(problem, perturbations, base)) <= 1.0


def _raise_amplitudes(problem: DesignProblem, candidate: Candidate, progress=None) -> Candidate:
    """Step 4: with several inputs and a common factor s < 1, raise each input's own factor
    s_j towards 1 (bisection, 10 halvings, on the simulated response limits) and keep the
    change where the criterion improves — an input whose response is not the binding one
    need not be held back by another's."""
    factors = np.array(candidate.amplitude_factors)
    if len(problem.inputs) < 2 or not problem.limits or np.all(factors >= 1.0):
        return candidate
    # Δu at every input's amplitude limit
    unit = candidate.perturbations / factors[None, :]
    base = _outputs(problem, np.zeros_like(unit))
    best = candidate
    for j in range(len(problem.inputs)):
        trial = factors.copy()
        trial[j] = 1.0
        if not _feasible(problem, unit * trial, base):
            low, high = factors[j], 1.0
            for _ in range(10):
                trial[j] = 0.5 * (low + high)
                if _feasible(problem, unit * trial, base):
                    low = trial[j]
                else:
                    high = trial[j]
            trial[j] = low
        if trial[j] <= factors[j] * (1 + 1e-3):
            continue
        multisine = (
            candidate.multisine.with_amplitudes(trial * problem.amplitudes)
            if candidate.multisine is not None
            else None
        )
        raised = evaluate_input(
            problem, unit * trial, candidate.signal, candidate.setting, multisine,
            factors=tuple(trial),
        )  # fmt: skip
        if raised.criterion_value < best.criterion_value:
            if progress is not None:
                progress(
                    f"amplitude of {problem.inputs[j].name} raised to {trial[j]:.3g} × its "
                    f"limit: {problem.criterion} = {raised.criterion_value:.6g}"
                )
            best, factors = raised, trial
    return best


def named_std(candidate: Candidate) -> dict[str, float]:
    """parameter name → predicted σ."""
    return {
        n: float(s) for n, s in zip(candidate.accuracy.names, candidate.accuracy.std, strict=True)
    }
