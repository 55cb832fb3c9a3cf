"""Options for unstable airplanes: stabilized output error, eigenvalue transformation and
multiple shooting (docs/unstable.md; Jategaonkar, *Flight Vehicle System Identification*,
2nd ed., ch. 9).

An unstable model cannot be simulated open-loop over a long record: small parameter or
state errors grow like e^(λt), λ > 0, the outputs leave the data and the Gauss–Newton
linearisation fails. Each option here keeps the simulated trajectory near the data.

``with_stabilizing_gain(model, S)`` — stabilized output error (FVSysID test case TC09): at
every sample, after y_k = h(x_k, u_k), the state is corrected x_k ← x_k + S (z_k − y_k) (S:
n_s × n_o, constant); the residual z_k − y_k keeps the output y_k computed before the
correction. The correction runs in every simulation, perturbed or not, and in the
sensitivity equations (``flightid.simulation.feedback``).

``with_eigenvalue_shift(model, σ)`` and ``exponentially_weighted(maneuvers, σ)`` — eigenvalue
transformation (FVSysID test case TC10): for a linear model ẋ = A x + B u, y = C x + D u, the
weighted signals x' = e^(−σt) x, u' = e^(−σt) u, y' = e^(−σt) y obey exactly

    ẋ' = (A − σI) x' + B u',   y' = C x' + D u'

so the eigenvalues move left by σ and the model is integrated stable for σ > max Re λ(A),
while its parameters (A, B, C, D) are unchanged: they are estimated from the weighted data
and reported as they are. For a model that is *not* linear and homogeneous in (x, u) (a
constant term, a bias, a product of states) the identity fails — ẋ' = e^(−σt) f(e^(σt)x',
e^(σt)u') − σx' has no shift-free form — so ``with_eigenvalue_shift`` checks homogeneity
numerically (f(2x, 2u) = 2f(x, u), h likewise, at random x, u) and refuses other models with
``NotLinearError``.

``with_multiple_shooting(model, maneuvers, intervals)`` — multiple shooting (no reference tool
has it): each maneuver is cut into intervals; interval m > 1 starts from its own initial
states, new free parameters ``ms<m>_<state>`` (start: the measured channel named like the
state at the interval's first sample, else 0). Continuity x_end(interval m − 1) = x0(m) is
enforced by weighted defect residuals: the defect d of state s counts in the cost as
``shooting_weight`` samples of the residual of the output named like s,

    J = Σ_k ν_kᵀ R⁻¹ ν_k + Σ_boundaries Σ_s w · d_s² / R_s,

so a defect of one noise standard deviation costs as much as w samples; with w = 10⁶ the
defects at the optimum are ~10⁻³ of the noise level and the estimates those of ordinary
output error, while far from the optimum each interval's error grows only over its own
length. The weights (1, 10³, 10⁶) are used in turn by default (a continuation, each stage
started from the one before; ``flightid.estimation.shooting``): a single large weight from
the start ties the intervals together at once and can land where open-loop output error
lands. ``flightid.estimation.problem.OutputErrorProblem`` appends the defect rows; R is
estimated from the data rows only.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields

import numpy as np

from flightid.data.flightdata import FlightData
from flightid.errors import InputError
from flightid.model.parameters import Parameter, Parameters
from flightid.model.statespace import StateSpaceModel

__all__ = [
    "UnstableModel",
    "NotLinearError",
    "with_stabilizing_gain",
    "gain_matrix",
    "with_eigenvalue_shift",
    "exponentially_weighted",
    "check_linear_homogeneous",
    "with_multiple_shooting",
    "shooting_starts",
    "DEFAULT_SHOOTING_WEIGHT",
    "DEFAULT_SHOOTING_WEIGHTS",
]

# defect weights: a continuity defect of one noise σ costs as much as this many samples; the
# estimation runs with each in turn, each from the estimates of the one before (continuation)
DEFAULT_SHOOTING_WEIGHTS = (1.0, 1e3, 1e6)
DEFAULT_SHOOTING_WEIGHT = DEFAULT_SHOOTING_WEIGHTS[-1]


class NotLinearError(InputError):
    """The eigenvalue transformation was asked for a model that is not linear and homogeneous
    in the states and inputs."""


@dataclass(frozen=True, eq=False)
class UnstableModel(StateSpaceModel):
    """A ``StateSpaceModel`` with a stabilizing gain and/or multiple-shooting intervals.

    Args (beyond ``StateSpaceModel``'s):
        stabilizing_gain: S (n_s × n_o): x_k ← x_k + S (z_k − y_k) at every sample; None: no
            correction.
        shooting: per maneuver, the intervals after the first: ((first sample, (parameter
            name per state)), ...); None: one interval per maneuver.
        shooting_outputs: per state, the output whose noise variance weights its defect.
        shooting_weight: w, the defects' weight in samples (module docstring).
        shooting_schedule: smaller weights to estimate with first, in order, each stage
            starting from the estimates of the one before (continuation; run by
            ``flightid.estimation.shooting.estimate_multiple_shooting``).
    """

    stabilizing_gain: np.ndarray | None = None
    shooting: tuple | None = None
    shooting_outputs: tuple[str, ...] = ()
    shooting_weight: float = DEFAULT_SHOOTING_WEIGHT
    shooting_schedule: tuple[float, ...] = ()


def _as_unstable(model: StateSpaceModel, **changes) -> UnstableModel:
    values = {f.name: getattr(model, f.name) for f in fields(StateSpaceModel)}
    if isinstance(model, UnstableModel):
        values.update(
            {f.name: getattr(model, f.name) for f in fields(UnstableModel) if f.name not in values}
        )
    values.update(changes)
    return UnstableModel(**values)


def gain_matrix(
    model: StateSpaceModel, gain: np.ndarray | Sequence | Mapping[str, Mapping[str, float]]
) -> np.ndarray:
    """S (n_s × n_o) from a matrix, or from ``{state: {output: gain}}`` (others 0)."""
    n_s, n_o = len(model.states), len(model.outputs)
    if isinstance(gain, Mapping):
        matrix = np.zeros((n_s, n_o))
        for state, row in gain.items():
            if state not in model.states:
                raise InputError(
                    f"stabilizing_gain.{state}: not a state of the model; states "
                    f"{list(model.states)}"
                )
            if not isinstance(row, Mapping):
                raise InputError(
                    f"stabilizing_gain.{state}: expected a table {{output = gain}}, got {row!r}"
                )
            for output, value in row.items():
                if output not in model.outputs:
                    raise InputError(
                        f"stabilizing_gain.{state}.{output}: not an output of the model; "
                        f"outputs {list(model.outputs)}"
                    )
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise InputError(
                        f"stabilizing_gain.{state}.{output}: expected a number, got {value!r}"
                    )
                matrix[model.states.index(state), model.outputs.index(output)] = float(value)
        return matrix
    matrix = np.asarray(gain, dtype=float)
    if matrix.shape != (n_s, n_o) or not np.all(np.isfinite(matrix)):
        raise InputError(
            f"stabilizing_gain: expected a finite {n_s} × {n_o} matrix (states "
            f"{list(model.states)} × outputs {list(model.outputs)}), got shape {matrix.shape}"
        )
    return matrix


def with_stabilizing_gain(
    model: StateSpaceModel, gain: np.ndarray | Sequence | Mapping[str, Mapping[str, float]]
) -> UnstableModel:
    """The model with the state correction x_k ← x_k + S (z_k − y_k) at every sample."""
    if model.output_delays:
        raise InputError(
            "stabilizing_gain: not available with output delays (the correction uses the "
            "undelayed output of h)"
        )
    return _as_unstable(model, stabilizing_gain=gain_matrix(model, gain))


def check_linear_homogeneous(
    model: StateSpaceModel, theta: np.ndarray | None = None, seed: int = 0
) -> None:
    """``NotLinearError`` unless f and h are linear and homogeneous in (x, u) at θ:
    f(a x1 + b x2, a u1 + b u2) = a f(x1, u1) + b f(x2, u2), h likewise, checked at random
    points (seeded) with relative tolerance 1e-7."""
    theta = model.function_theta(theta, 0) if theta is None else theta
    rng = np.random.default_rng(seed)
    n_s, n_u = len(model.states), len(model.inputs)
    x1, x2 = rng.normal(size=n_s), rng.normal(size=n_s)
    u1, u2 = rng.normal(size=n_u), rng.normal(size=n_u)
    a, b = 1.7, -0.6
    for name, fn in (("f", model.f), ("h", model.h)):
        fn = getattr(fn, "py_func", fn)
        left = np.asarray(fn(0.3, a * x1 + b * x2, a * u1 + b * u2, theta), dtype=float)
        right = a * np.asarray(fn(0.3, x1, u1, theta), dtype=float) + b * np.asarray(
            fn(0.3, x2, u2, theta), dtype=float
        )
        scale = max(float(np.max(np.abs(right), initial=0.0)), 1.0)
        if not np.allclose(left, right, rtol=1e-7, atol=1e-7 * scale):
            raise NotLinearError(
                f"eigenvalue_shift: the transformation x' = e^(−σt)x, ẋ' = f(x', u') − σx' is "
                f"exact only for a model linear and homogeneous in the states and inputs; "
                f"{name}(a·x1 + b·x2, a·u1 + b·u2) differs from a·{name}(x1, u1) + "
                f"b·{name}(x2, u2) by up to {float(np.max(np.abs(left - right))):.3g} (a bias, "
                f"a constant or a nonlinear term?)"
            )


def with_eigenvalue_shift(
    model: StateSpaceModel, sigma: float, check: bool = True
) -> StateSpaceModel:
    """The model with every eigenvalue moved by −σ: ẋ' = f(t, x', u', θ) − σ x', y' = h.

    Exact (for data weighted by ``exponentially_weighted``) only for models linear and
    homogeneous in (x, u); ``check`` refuses others (``NotLinearError``).
    """
    if isinstance(sigma, bool) or not isinstance(sigma, (int, float)) or not np.isfinite(sigma):
        raise InputError(f"eigenvalue_shift: expected a finite number σ (1/s), got {sigma!r}")
    if not model.has_states:
        raise InputError("eigenvalue_shift: the model has no states to shift")
    if check:
        check_linear_homogeneous(model)
    sigma = float(sigma)
    f = model.f
    failure = None
    if hasattr(f, "py_func"):
        f_inner = f
    else:
        from flightid.model.compilation import try_compiled

        try:
            # compiled through the digest-keyed disk cache (an uncached njit here was
            # compiled again by every process, and with it every kernel calling it)
            from flightid.model.kernel_cache import compiled_function

            f_inner = compiled_function(f)
            # an error the compiled f raises at these values (a division by a parameter)
            # is not a compilation failure
            failure = try_compiled(
                f_inner,
                0.0,
                np.zeros(len(model.states)),
                np.zeros(len(model.inputs)),
                model.function_theta(None, 0),
            )
        except Exception as exc:  # numba typing errors have many classes: run in Python
            failure = exc
        if failure is not None:
            f_inner = getattr(f, "py_func", f)

    def f_shifted(t, x, u, theta):
        dx = f_inner(t, x, u, theta)
        out = np.empty(x.shape[0])
        for i in range(x.shape[0]):
            # ẋ'_i = f_i(x', u') − σ x'_i
            out[i] = dx[i] - sigma * x[i]
        return out

    if failure is not None:
        # the simulator's fall-back to Python names the user's line from this error
        f_shifted.compile_failure = failure
    from dataclasses import replace

    return replace(model, f=f_shifted)


def exponentially_weighted(
    maneuvers: FlightData | Sequence[FlightData], sigma: float
) -> list[FlightData]:
    """Every input and output channel multiplied by e^(−σ t_k), t_k = t − t_0 per maneuver
    (s; so t_k = (k − 1)·Δt for k = 1..N, uniform sampling Δt)."""
    items = [maneuvers] if isinstance(maneuvers, FlightData) else list(maneuvers)
    out = []
    for m in items:
        # w_k = e^(−σ (t_k − t_0))
        weight = np.exp(-float(sigma) * (m.time - m.time[0]))[:, None]
        out.append(
            FlightData(
                m.time,
                m.inputs * weight,
                m.outputs * weight,
                input_names=m.input_names,
                output_names=m.output_names,
                units=m.units,
                name=m.name,
                notes=m.notes,
            )
        )
    return out


def shooting_starts(n_samples: int, intervals: int) -> list[int]:
    """First samples of intervals 2 … ``intervals`` of a maneuver of ``n_samples``, as equal
    as the samples allow: s_m = round((m − 1)·(N − 1)/M)."""
    if isinstance(intervals, bool) or not isinstance(intervals, int) or intervals < 1:
        raise InputError(f"shooting_intervals: expected a whole number ≥ 1, got {intervals!r}")
    if intervals > (n_samples - 1) // 2:
        raise InputError(
            f"shooting_intervals: {intervals} intervals in a maneuver of {n_samples} samples "
            f"leave fewer than 2 samples per interval"
        )
    return [int(round(m * (n_samples - 1) / intervals)) for m in range(1, intervals)]


def with_multiple_shooting(
    model: StateSpaceModel,
    maneuvers: FlightData | Sequence[FlightData],
    intervals: int,
    weight: float | Sequence[float] = DEFAULT_SHOOTING_WEIGHTS,
) -> UnstableModel:
    """The model with every maneuver cut into ``intervals`` shooting intervals.

    New free parameters ``ms<m>_<state>`` (m = 2 … intervals; with several maneuvers
    ``ms<m>_<state>_<maneuver>``) hold each interval's initial states, started at the
    measured channel named like the state (else 0). The defect of state s is weighted with
    the noise variance of the output named s; a state without such an output is refused.

    ``weight``: w, or an increasing sequence of weights — a continuation: the estimation runs
    with each in turn from the estimates of the one before (``estimate_multiple_shooting``),
    the last one giving the result. A small first weight lets each interval follow its own
    data, so the start is not the open-loop simulation's; the large last one closes the gaps.
    """
    items = [maneuvers] if isinstance(maneuvers, FlightData) else list(maneuvers)
    weights = [weight] if isinstance(weight, (int, float)) else list(weight)
    if (
        not weights
        or any(isinstance(w, bool) or not isinstance(w, (int, float)) or not w > 0 for w in weights)
        or any(b <= a for a, b in zip(weights, weights[1:], strict=False))
    ):
        raise InputError(
            f"shooting_weight: expected a positive number or an increasing list of them, "
            f"got {weight!r}"
        )
    if not model.has_states:
        raise InputError("shooting_intervals: the model has no states to shoot")
    unobserved = [s for s in model.states if s not in model.outputs]
    if unobserved:
        raise InputError(
            f"shooting_intervals: the continuity defect of each state is weighted with the "
            f"noise of the output of the same name; the states {unobserved} have none "
            f"(outputs {list(model.outputs)})"
        )
    new: list[Parameter] = []
    spec = []
    for i, m in enumerate(items):
        entries = []
        for number, start in enumerate(shooting_starts(m.n_samples, intervals), start=2):
            suffix = f"_{i + 1}" if len(items) > 1 else ""
            names = tuple(f"ms{number}_{s}{suffix}" for s in model.states)
            for state, name in zip(model.states, names, strict=True):
                try:
                    value = float(m.channel(state)[start])
                except KeyError:
                    value = 0.0
                new.append(Parameter(name, value))
            entries.append((start, names))
        spec.append(tuple(entries))
    clash = [p.name for p in new if p.name in model.parameters]
    if clash:
        raise InputError(f"shooting_intervals: parameter names already taken: {clash}")
    parameters = Parameters([*model.parameters, *new])
    function_parameters = model.function_parameters
    return _as_unstable(
        model,
        parameters=parameters,
        function_parameters=function_parameters,
        shooting=tuple(spec),
        shooting_outputs=tuple(model.states),
        shooting_weight=float(weights[-1]),
        shooting_schedule=tuple(float(w) for w in weights[:-1]),
    )
