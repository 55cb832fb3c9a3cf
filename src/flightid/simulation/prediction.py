"""Prediction with a model at given parameter values: outputs, residuals, fit numbers and,
on request, output bands from the parameter covariance.

Fit numbers per output o over the N samples of one maneuver:

    RMS error   e_o = √( (1/N) Σ_i (z_io − y_io)² )
    R²_o        = 1 − Σ_i (z_io − y_io)² / Σ_i (z_io − z̄_o)²

Prediction bands (delta method): with the output sensitivities S_k = ∂y_k/∂θ (n_o × n_f, the
free parameters, central differences of whole simulations) and the covariance P of the free
estimates,

    Var y_k,o ≈ (S_k P S_kᵀ)_oo

— the spread of the model output that the parameter uncertainty alone causes (measurement
noise is not in it); exact to first order in the parameter deviations.

Initial states of a predicted maneuver (``initial_states``): the values given, else the first
sample of the data's channel named like the state, else the model's own initial state (when
it is one specification for every maneuver); anything else is refused with the state named.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from flightid.data.flightdata import FlightData
from flightid.errors import FlightIdWarning, InputError, SimulationError
from flightid.model.binding import as_data_list
from flightid.model.statespace import StateSpaceModel
from flightid.simulation.simulator import Simulator

__all__ = [
    "Prediction",
    "PredictionError",
    "PredictionWarning",
    "initial_states",
    "linearize_result",
    "model_at_estimate",
    "output_sensitivities",
    "output_std",
    "predict_maneuvers",
    "predict_result",
    "prediction_model",
    "simulate_result",
]

# relative step of the central differences of the outputs in θ: δ_j = 1e-5·max(|θ_j|, typ_j)
SENSITIVITY_STEP = 1e-5
# perturbed outputs held at once while differencing (bytes)
BATCH_BYTES = 16 * 2**20


class PredictionError(InputError):
    """A prediction that cannot be made as asked (initial state unknown, data unsuitable)."""


class PredictionWarning(FlightIdWarning):
    """A prediction made with parameters the estimation did not determine (held at their
    start values)."""


@dataclass(frozen=True)
class Prediction:
    """Measured and predicted outputs of one maneuver, with fit numbers.

    Attributes:
        name: maneuver name.
        time: (N,) s.
        measured, predicted: (N, n_o) in the outputs' units.
        output_names: the n_o outputs.
        rms: RMS error per output (outputs' units).
        r2: R² per output (1 − residual sum of squares / spread about the mean).
        inputs, input_names, units: the maneuver's inputs (N, n_u) and channel units, for
            figures.
        predicted_std: (N, n_o) σ of the predicted outputs from the parameter covariance
            (delta method, module docstring), or None when no band was asked for.
    """

    name: str
    time: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    output_names: tuple[str, ...]
    rms: np.ndarray
    r2: np.ndarray
    inputs: np.ndarray | None = None
    input_names: tuple[str, ...] = ()
    units: dict = field(default_factory=dict)
    predicted_std: np.ndarray | None = None

    @classmethod
    def from_outputs(
        cls,
        name: str,
        time: np.ndarray,
        measured: np.ndarray,
        predicted: np.ndarray,
        output_names: Sequence[str],
    ) -> Prediction:
        """The prediction of one maneuver with its RMS error and R² per output.

        Args:
            name: maneuver name.
            time: (N,) s.
            measured: (N, n_o) measured outputs, in the outputs' units.
            predicted: (N, n_o) model outputs, in the outputs' units.
            output_names: the n_o outputs.
        """
        residual = measured - predicted
        # RMS error e_o = √((1/N) Σ_i (z_io − y_io)²)
        rms = np.sqrt(np.mean(residual**2, axis=0))
        # R²_o = 1 − Σ_i (z_io − y_io)² / Σ_i (z_io − z̄_o)²
        total = np.sum((measured - measured.mean(axis=0)) ** 2, axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            r2 = 1.0 - np.sum(residual**2, axis=0) / total
        return cls(name, time, measured, predicted, tuple(output_names), rms, r2)

    @classmethod
    def of_maneuver(
        cls,
        maneuver: FlightData,
        predicted: np.ndarray,
        output_names: Sequence[str],
        predicted_std: np.ndarray | None = None,
    ) -> Prediction:
        """``from_outputs`` on a maneuver's measured outputs, keeping its inputs and channel
        units for the report's figures (and the outputs' σ when given, (N, n_o))."""
        measured = np.column_stack([maneuver.output(n) for n in output_names])
        prediction = cls.from_outputs(
            maneuver.name, maneuver.time, measured, predicted, output_names
        )
        return replace(
            prediction,
            inputs=np.asarray(maneuver.inputs) if maneuver.input_names else None,
            input_names=tuple(maneuver.input_names),
            units=dict(maneuver.units),
            predicted_std=predicted_std,
        )

    @property
    def residuals(self) -> np.ndarray:
        """z − y (N, n_o), in the outputs' units."""
        return self.measured - self.predicted

    def band(self, level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) (N, n_o): y ± z_{(1+c)/2}·σ_y, the two-sided normal band at level c.

        Raises ``PredictionError`` when the prediction has no σ (made without bands)."""
        if self.predicted_std is None:
            raise PredictionError("band: this prediction has no output σ; predict with bands=True")
        if not 0.0 < level < 1.0:
            raise PredictionError(f"level: expected a number in (0, 1), got {level!r}")
        from scipy.stats import norm

        # half width z_{(1+c)/2}·σ_y
        half = norm.ppf(0.5 + 0.5 * level) * self.predicted_std
        return self.predicted - half, self.predicted + half

    def summary(self) -> str:
        """One line per output: RMS error, R² (and the mean band σ when present)."""
        lines = [f"prediction {self.name or '(unnamed)'}: {self.time.shape[0]} samples"]
        for o, name in enumerate(self.output_names):
            unit = self.units.get(name, "") or ""
            line = f"  {name:<12} RMS {self.rms[o]:.4g} {unit}".rstrip()
            line += f"   R² {self.r2[o]:.4f}"
            if self.predicted_std is not None:
                line += f"   mean σ_y {np.mean(self.predicted_std[:, o]):.3g}"
            lines.append(line)
        return "\n".join(lines)

    def to_dict(self) -> dict:
        entry = {
            "maneuver": self.name,
            "samples": int(self.time.shape[0]),
            "outputs": list(self.output_names),
            "rms_error": [float(v) for v in self.rms],
            "r2": [float(v) for v in self.r2],
        }
        if self.predicted_std is not None:
            # the band's size per output: RMS over the samples of σ_y
            entry["predicted_std_rms"] = [
                float(v) for v in np.sqrt(np.mean(self.predicted_std**2, axis=0))
            ]
        return entry


def _state_values(
    spec: Sequence[float] | Mapping[str, float] | np.ndarray, states: Sequence[str], where: str
) -> dict[str, float]:
    """{state: value} from a sequence (one value per state) or a mapping by state name."""
    if isinstance(spec, Mapping):
        unknown = [k for k in spec if k not in states]
        if unknown:
            raise PredictionError(f"{where}: {unknown} are not states of the model {list(states)}")
        items = dict(spec)
    else:
        values = np.asarray(spec, dtype=float).ravel()
        if values.size != len(states):
            raise PredictionError(
                f"{where}: expected {len(states)} values (one per state {list(states)}), "
                f"got {values.size}"
            )
        items = dict(zip(states, values, strict=True))
    out = {}
    for state, value in items.items():
        number = float(value)
        if not np.isfinite(number):
            raise PredictionError(f"{where}[{state!r}]: must be finite, got {value!r}")
        out[state] = number
    return out


def _per_maneuver_spec(x0: object) -> bool:
    """True for a list of initial-state specifications (one per maneuver), False for one."""
    if isinstance(x0, np.ndarray):
        return x0.ndim == 2
    return (
        isinstance(x0, (list, tuple))
        and len(x0) > 0
        and all(isinstance(e, (Mapping, list, tuple, np.ndarray)) for e in x0)
    )


def initial_states(
    model: StateSpaceModel,
    maneuvers: Sequence[FlightData],
    x0: Sequence | Mapping | np.ndarray | None = None,
) -> list[np.ndarray]:
    """x0 (n_s,) of each maneuver (module docstring): given values (one specification for
    all maneuvers, or a list with one per maneuver), else the first sample of the data's
    channel of the state's name, else the model's initial state at its parameter values (only
    when the model gives one specification for every maneuver)."""
    states = model.states
    per_maneuver = _per_maneuver_spec(x0)
    if per_maneuver and len(x0) != len(maneuvers):
        raise PredictionError(
            f"x0: {len(x0)} initial-state specifications for {len(maneuvers)} maneuvers; give "
            f"one for all or one per maneuver"
        )
    own = None if model.per_maneuver_x0 else model.initial_state()
    result = []
    for k, maneuver in enumerate(maneuvers):
        spec = x0[k] if per_maneuver else x0
        given = {} if spec is None else _state_values(spec, states, "x0")
        values = np.empty(len(states))
        for s, state in enumerate(states):
            if state in given:
                values[s] = given[state]
            elif state in maneuver.input_names or state in maneuver.output_names:
                values[s] = float(maneuver.channel(state)[0])
            elif own is not None:
                values[s] = own[s]
            else:
                raise PredictionError(
                    f"x0: the initial state {state!r} of maneuver {k} "
                    f"({maneuver.name or 'unnamed'}) is not given, the data has no channel "
                    f"{state!r}, and the model's initial states are per estimation maneuver; "
                    f"give x0"
                )
        if not np.all(np.isfinite(values)):
            bad = [s for s, v in zip(states, values, strict=True) if not np.isfinite(v)]
            raise PredictionError(f"x0: the initial states {bad} are not finite (first samples)")
        result.append(values)
    return result


def prediction_model(
    model: StateSpaceModel,
    maneuvers: Sequence[FlightData],
    x0: Sequence | Mapping | np.ndarray | None = None,
) -> StateSpaceModel:
    """The model with fixed numeric initial states for ``maneuvers`` (``initial_states``),
    integrated from them over each whole maneuver (without the multiple-shooting intervals of
    the estimation; a stabilizing gain stays and needs the measured outputs).

    Raises ``PredictionError`` for a model with parameters per estimation maneuver unless
    the maneuvers are as many (then maneuver k takes the k-th copies)."""
    n_per = model.n_parameter_maneuvers
    if n_per and n_per != len(maneuvers):
        raise PredictionError(
            f"data: the model has parameters per estimation maneuver "
            f"{list(model.maneuver_parameters)} ({n_per} maneuvers); a prediction needs as many "
            f"maneuvers, got {len(maneuvers)}"
        )
    starts = initial_states(model, maneuvers, x0)
    spec = tuple(tuple(float(v) for v in s) for s in starts)
    fixed = replace(model, x0=spec if len(spec) > 1 else spec[0])
    if getattr(fixed, "shooting", None) is not None:
        # the shooting intervals belong to the estimation maneuvers: a prediction is one
        # integration of each maneuver from its initial state
        fixed = replace(fixed, shooting=None)
    return fixed


def output_sensitivities(
    simulator: Simulator, theta: np.ndarray, free_index: np.ndarray, typical: np.ndarray
) -> np.ndarray:
    """S = ∂y/∂θ_free (N, n_o, n_f) by central differences of whole simulations,
    δ_j = SENSITIVITY_STEP·max(|θ_j|, typical_j), run in batches of at most
    ``BATCH_BYTES`` of perturbed outputs; raises ``SimulationError`` if a perturbed simulation
    diverges."""
    theta = np.asarray(theta, dtype=float)
    steps = SENSITIVITY_STEP * np.maximum(np.abs(theta[free_index]), typical)
    n_out = len(simulator.model.outputs)
    sensitivities = np.empty((simulator.n_samples, n_out, free_index.size))
    trajectory = max(2 * simulator.n_samples * n_out * 8, 1)
    per_batch = max(1, BATCH_BYTES // trajectory)
    for first in range(0, free_index.size, per_batch):
        chosen = np.arange(first, min(first + per_batch, free_index.size))
        n = chosen.size
        rows = np.repeat(theta[None, :], 2 * n, axis=0)
        rows[np.arange(n), free_index[chosen]] += steps[chosen]
        rows[n + np.arange(n), free_index[chosen]] -= steps[chosen]
        batch = simulator.run(rows)
        if batch.diverged.any():
            bad = int(np.flatnonzero(batch.diverged)[0])
            raise SimulationError(f"output sensitivities: {batch.messages[bad]}")
        # S_j = (y(θ + δ_j e_j) − y(θ − δ_j e_j)) / (2 δ_j)
        columns = (batch.outputs[:n] - batch.outputs[n:]) / (2.0 * steps[chosen, None, None])
        sensitivities[:, :, chosen] = np.moveaxis(columns, 0, -1)
    return sensitivities


def output_std(sensitivities: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """σ_y (N, n_o) = √diag(S_k P S_kᵀ) for sensitivities (N, n_o, n_f) and P (n_f, n_f)."""
    # Var y_k,o = Σ_ab S_k,o,a P_ab S_k,o,b
    variance = np.einsum("koa,ab,kob->ko", sensitivities, covariance, sensitivities)
    return np.sqrt(np.maximum(variance, 0.0))


def _check_covariance(covariance: np.ndarray, n_free: int) -> np.ndarray:
    p = np.asarray(covariance, dtype=float)
    if p.shape != (n_free, n_free):
        raise PredictionError(
            f"covariance: expected ({n_free}, {n_free}) over the free parameters, got {p.shape}"
        )
    if not np.all(np.isfinite(p)):
        raise PredictionError(
            "covariance: has non-finite entries (an undetermined parameter); no band can be given"
        )
    return p


def predict_maneuvers(
    model: StateSpaceModel,
    data: FlightData | Sequence[FlightData],
    x0: Sequence | Mapping | np.ndarray | None = None,
    *,
    method: str = "rk4",
    input_interpolation: str = "linear",
    covariance: np.ndarray | None = None,
) -> list[Prediction]:
    """One ``Prediction`` per maneuver of ``data``, simulated with ``model`` at its parameter
    values from the initial states of ``initial_states``.

    Args:
        model: the model at the values to predict with.
        data: maneuvers carrying the model's inputs and outputs.
        x0: initial states (``initial_states``).
        method, input_interpolation: integration, as in ``Simulator``.
        covariance: P of the free parameters (n_f, n_f): with it each prediction carries
            ``predicted_std`` (delta method, module docstring); None: no band.
    """
    maneuvers = as_data_list(data)
    for k, maneuver in enumerate(maneuvers):
        missing = [n for n in model.outputs if n not in maneuver.output_names]
        if missing:
            raise PredictionError(
                f"data[{k}] ({maneuver.name or 'unnamed'}): the model's outputs {missing} "
                f"are not output channels of the data (outputs "
                f"{list(maneuver.output_names)}); use simulate for inputs alone"
            )
    fixed = prediction_model(model, maneuvers, x0)
    simulator = Simulator(fixed, maneuvers, method=method, input_interpolation=input_interpolation)
    theta = fixed.parameters.values
    outputs = simulator.outputs(theta)
    std = None
    if covariance is not None:
        free_index = np.flatnonzero(fixed.parameters.free_mask)
        p = _check_covariance(covariance, free_index.size)
        typical = np.array([1e-3 if q.scale is None else q.scale for q in fixed.parameters])
        s = output_sensitivities(simulator, theta, free_index, typical[free_index])
        std = output_std(s, p)
    predictions = []
    start = 0
    for maneuver in maneuvers:
        stop = start + maneuver.n_samples
        band = None if std is None else std[start:stop]
        predictions.append(
            Prediction.of_maneuver(maneuver, outputs[start:stop], model.outputs, band)
        )
        start = stop
    return predictions


# ---------------------------------------------------------------------- results' model calls
# Every result that holds a model (time-domain, frequency-domain and recursive estimates)
# answers predict / simulate / linearize through these three functions, with the model at its
# estimated values (free mask = the parameters the covariance is over).


def model_at_estimate(
    model: StateSpaceModel,
    names: Sequence[str],
    values: Sequence[float] | np.ndarray,
    estimated: Sequence[str],
) -> StateSpaceModel:
    """``model`` with the parameters ``names`` at ``values`` and exactly those named in
    ``estimated`` free (the order of a covariance over the free parameters is the model's
    parameter order). Parameters not named keep their values."""
    parameters = model.parameters
    unknown = [n for n in (*names, *estimated) if n not in parameters]
    if unknown:
        raise PredictionError(
            f"names: {unknown} are not parameters of the model {parameters.names}"
        )
    valued = parameters.with_values(dict(zip(names, np.asarray(values, dtype=float), strict=True)))
    fixed = valued.with_free(valued.names, free=False)
    return model.with_parameters(fixed.with_free(estimated, free=True))


def predict_result(
    model: StateSpaceModel,
    data: FlightData | Sequence[FlightData],
    x0: Sequence | Mapping | np.ndarray | None = None,
    *,
    bands: bool = False,
    covariance: np.ndarray | None = None,
    no_covariance: str = "",
    method: str = "rk4",
    input_interpolation: str = "linear",
) -> Prediction | tuple[Prediction, ...]:
    """A result's ``predict``: one ``Prediction`` for a ``FlightData``, a tuple of them for a
    list (``predict_maneuvers``).

    Args:
        model: the model at the estimated values, free = the parameters of ``covariance``.
        data, x0: as ``predict_maneuvers``.
        bands: give ``Prediction.predicted_std`` from ``covariance`` (delta method).
        covariance: P of the free parameters, or None when the result has none.
        no_covariance: why the result has no covariance (the message of the
            ``PredictionError`` that ``bands=True`` then raises).
    """
    if bands and covariance is None:
        raise PredictionError(
            f"bands: no prediction band can be given: {no_covariance or 'no parameter covariance'}"
        )
    predictions = predict_maneuvers(
        model,
        data,
        x0,
        method=method,
        input_interpolation=input_interpolation,
        covariance=covariance if bands else None,
    )
    return predictions[0] if isinstance(data, FlightData) else tuple(predictions)


def simulate_result(
    model: StateSpaceModel,
    inputs: FlightData | Sequence[FlightData],
    x0: Sequence | Mapping | np.ndarray | None = None,
    *,
    method: str = "rk4",
    input_interpolation: str = "linear",
) -> np.ndarray:
    """A result's ``simulate``: outputs (N_total, n_o) of ``model`` driven by the inputs of
    ``inputs`` (outputs not needed) from the initial states of ``initial_states``."""
    from flightid.simulation.simulator import simulate

    maneuvers = as_data_list(inputs)
    fixed = prediction_model(model, maneuvers, x0)
    return simulate(fixed, maneuvers, method=method, input_interpolation=input_interpolation)


def _operating_point(model: StateSpaceModel, at, units: dict) -> tuple:
    """(x, u, units, description) of ``at``: None, a ``FlightData`` or (x, u)."""
    from flightid.model.linearization import LinearizationError

    if at is None:
        x = model.initial_state(model.parameters.values, 0)
        u = np.zeros(len(model.inputs))
        return x, u, units, "initial state of the first estimation maneuver, inputs 0"
    if isinstance(at, FlightData):
        (x,) = initial_states(model, [at], None)
        u = np.array([float(np.mean(at.channel(n))) for n in model.inputs])
        point = f"initial state and mean inputs of maneuver {at.name or '(unnamed)'}"
        return x, u, {**units, **dict(at.units)}, point
    if isinstance(at, (tuple, list)) and len(at) == 2:
        return at[0], at[1], units, "given"
    raise LinearizationError(f"at: expected None, a FlightData or (x, u), got {type(at).__name__}")


def linearize_result(
    model: StateSpaceModel,
    at=None,
    *,
    covariance: np.ndarray | None = None,
    no_covariance: str = "",
    units: Mapping[str, str] | None = None,
):
    """A result's ``linearize``: the ``LinearModel`` of ``model`` about an operating point,
    with Cov vec(A, B, C, D) from ``covariance`` (``flightid.model.linearization``).

    Args:
        model: the model at the estimated values, free = the parameters of ``covariance``.
        at: None — the initial state of the first estimation maneuver, inputs 0 (exact for a
            model linear in x and u); a ``FlightData`` — its initial state (as ``predict``
            starts it) and the mean of each input; or ``(x, u)``.
        covariance: P of the free parameters; None: the entries come without σ and
            ``notes`` says why (``no_covariance``). Non-finite entries (undetermined
            parameters) likewise, naming them.
        units: ``{channel: unit}``.
    """
    from flightid.model.linearization import linearize

    x, u, units, point = _operating_point(model, at, dict(units or {}))
    notes: tuple[str, ...] = ()
    if covariance is None:
        notes = (f"no σ of the entries: {no_covariance or 'no parameter covariance'}",)
    elif not np.all(np.isfinite(covariance)):
        diagonal = np.diag(np.asarray(covariance, dtype=float))
        free_names = model.parameters.free_names
        undetermined = [n for n, v in zip(free_names, diagonal, strict=True) if not np.isfinite(v)]
        covariance = None
        notes = (f"no σ of the entries: the parameters {undetermined} are undetermined",)
    return linearize(
        model,
        x,
        u,
        covariance=covariance,
        units=units,
        operating_point=point,
        name=model.name,
        notes=notes,
    )
