"""Predicted Cramér–Rao bounds and correlations of a candidate input, before it is flown.

For output error with measurement noise covariance R (diagonal, assumed), the information
matrix of the free parameters at θ [RP-1153 4.6; Jategaonkar, *Flight Vehicle System
Identification*, §4.10]

    M = Σ_k G_kᵀ R⁻¹ G_k,        G_k = ∂y_k/∂θ (n_o × n_f),

depends on the input through the simulated sensitivities G only, not on measured data. So a
candidate input, the model with its a-priori parameter values and an assumed noise level give
the accuracy to expect: the Cramér–Rao lower bounds

    C = M⁻¹,   σ_j = √C_jj,   ρ_ij = C_ij / (σ_i σ_j).

G comes from the sensitivity equations integrated alongside the states, and M from
``flightid.estimation.gauss_newton.information_matrix``, the function the output-error
estimator forms its Cramér–Rao bounds with at convergence (there from central-difference G),
so the prediction and the estimator's own bounds are the same formula.

Criteria (smaller is better), with s_j = max(|θ_j|, typical_j) making them unit-free:

    D-optimal:   −log det M               (volume of the confidence ellipsoid; unit-free up to
                                           a constant, so s_j is not needed)
    A-optimal:   Σ_j C_jj / s_j²           (sum of squared relative bounds)
    parameters:  Σ_{j named} C_jj / s_j²   (the relative bounds of the named parameters)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from flightid.data.flightdata import FlightData
from flightid.errors import InputError, SimulationError
from flightid.model.statespace import StateSpaceModel

__all__ = ["CRITERIA", "PredictedAccuracy", "criterion_value", "predict_accuracy"]

CRITERIA = ("d_optimal", "a_optimal", "parameters")


@dataclass(frozen=True)
class PredictedAccuracy:
    """The accuracy a candidate input is predicted to give.

    ``names``/``values``/``typical``: the free parameters, their a-priori values and magnitude
    floors; ``information`` M (n_f × n_f); ``covariance`` M⁻¹; ``outputs`` the simulated
    response (N, n_o) with ``output_names``; ``noise_std`` the assumed σ per output.
    """

    names: tuple[str, ...]
    values: np.ndarray
    typical: np.ndarray
    information: np.ndarray
    covariance: np.ndarray
    outputs: np.ndarray
    output_names: tuple[str, ...]
    noise_std: np.ndarray

    @property
    def std(self) -> np.ndarray:
        """Predicted Cramér–Rao bounds σ_j = √(M⁻¹)_jj, in the parameters' units."""
        return np.sqrt(np.diag(self.covariance))

    @property
    def correlation(self) -> np.ndarray:
        """ρ_ij = C_ij / (σ_i σ_j)."""
        s = self.std
        return self.covariance / np.outer(s, s)

    def std_of(self, name: str) -> float:
        """The predicted σ of parameter ``name``."""
        if name not in self.names:
            raise InputError(f"name: {name!r} is not a free parameter; free: {list(self.names)}")
        return float(self.std[self.names.index(name)])

    def criterion(self, criterion: str, parameters: Sequence[str] = ()) -> float:
        """The design criterion's value (module docstring); smaller is better."""
        return criterion_value(self, criterion, parameters)


def criterion_value(
    accuracy: PredictedAccuracy, criterion: str, parameters: Sequence[str] = ()
) -> float:
    """−log det M (``d_optimal``), Σ C_jj/s_j² (``a_optimal``), or that sum over the named
    ``parameters`` (``parameters``)."""
    if criterion not in CRITERIA:
        raise InputError(f"criterion: expected one of {list(CRITERIA)}, got {criterion!r}")
    if criterion == "d_optimal":
        sign, logdet = np.linalg.slogdet(accuracy.information)
        # −log det M
        return float(-logdet) if sign > 0 else float("inf")
    scale = np.maximum(np.abs(accuracy.values), accuracy.typical)
    relative = np.diag(accuracy.covariance) / scale**2
    if criterion == "a_optimal":
        # Σ_j C_jj / s_j²
        return float(np.sum(relative))
    if not parameters:
        raise InputError('parameters: criterion "parameters" needs the names of the parameters')
    unknown = [p for p in parameters if p not in accuracy.names]
    if unknown:
        raise InputError(
            f"parameters: {unknown} are not free parameters of the model; free: "
            f"{list(accuracy.names)}"
        )
    index = [accuracy.names.index(p) for p in parameters]
    # Σ_{j named} C_jj / s_j²
    return float(np.sum(relative[index]))


def _noise_vector(model: StateSpaceModel, noise_std: Mapping[str, float] | Sequence[float]):
    if isinstance(noise_std, Mapping):
        missing = [o for o in model.outputs if o not in noise_std]
        extra = [o for o in noise_std if o not in model.outputs]
        if missing or extra:
            raise InputError(
                f"noise_std: expected one σ per model output {list(model.outputs)}; missing "
                f"{missing}, not outputs {extra}"
            )
        values = [noise_std[o] for o in model.outputs]
    else:
        values = list(noise_std)
        if len(values) != len(model.outputs):
            raise InputError(
                f"noise_std: expected {len(model.outputs)} values (outputs "
                f"{list(model.outputs)}), got {len(values)}"
            )
    sigma = np.asarray(values, dtype=float)
    for o, s in zip(model.outputs, sigma, strict=True):
        if not np.isfinite(s) or s <= 0:
            raise InputError(
                f"noise_std.{o}: expected a positive σ in the output's units, got {s!r}"
            )
    return sigma


def _with_placeholder_outputs(model: StateSpaceModel, data: FlightData) -> FlightData:
    """The maneuver with zero output channels where it has none: the sensitivities need only
    the inputs, but the output-error problem checks that outputs exist."""
    if all(o in data.output_names for o in model.outputs):
        return data
    inputs = {n: data.input(n) for n in data.input_names}
    outputs = {o: np.zeros(data.n_samples) for o in model.outputs}
    return FlightData(data.time, inputs, outputs, name=data.name)


def predict_accuracy(
    model: StateSpaceModel,
    data: FlightData | Sequence[FlightData],
    noise_std: Mapping[str, float] | Sequence[float],
    *,
    method: str = "rk4",
    input_interpolation: str = "linear",
    compiled: bool = True,
) -> PredictedAccuracy:
    """Predicted Cramér–Rao bounds of ``model``'s free parameters for the inputs of ``data``
    (one maneuver or several), with measurement noise σ ``noise_std`` per output.

    Raises ``InputError`` when the input leaves parameters undetermined (M singular; the
    message names them) and ``SimulationError`` when the simulation diverges.
    """
    from flightid.estimation.gauss_newton import information_matrix, undetermined_parameters
    from flightid.estimation.problem import OutputErrorProblem

    sigma = _noise_vector(model, noise_std)
    maneuvers = [data] if isinstance(data, FlightData) else list(data)
    maneuvers = [_with_placeholder_outputs(model, m) for m in maneuvers]
    problem = OutputErrorProblem(
        model, maneuvers, method=method, compiled=compiled, input_interpolation=input_interpolation
    )
    theta = problem.theta_start
    g, outputs = problem.sensitivities_from_equations(theta)
    if not np.all(np.isfinite(g)):
        raise SimulationError("predicted accuracy: the sensitivities are not finite")
    # M = Σ_k G_kᵀ R⁻¹ G_k, R = diag(σ²)
    m = information_matrix(g, sigma**2)
    _, undetermined = undetermined_parameters(m)
    names = tuple(problem.free_names)
    if undetermined:
        raise InputError(
            "input: it leaves the parameters "
            f"{[names[j] for j in undetermined]} undetermined (the information matrix is "
            "singular); excite the inputs and states they multiply"
        )
    # C = M⁻¹ (symmetrised against rounding)
    covariance = np.linalg.inv(m)
    covariance = 0.5 * (covariance + covariance.T)
    if np.any(np.diag(covariance) <= 0) or not np.all(np.isfinite(covariance)):
        raise InputError("input: the information matrix is numerically singular; no bounds")
    return PredictedAccuracy(
        names,
        np.asarray(theta, dtype=float),
        np.asarray(problem.typical, dtype=float),
        m,
        covariance,
        outputs,
        tuple(model.outputs),
        sigma,
    )
