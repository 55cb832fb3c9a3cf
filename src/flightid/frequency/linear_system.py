"""A state-space model as matrices: ẋ = f_0 + A x + B u,  y = h_0 + C x + D u.

The frequency-domain estimators work with linear models. A ``StateSpaceModel`` whose f and
h are linear in the states and inputs (the ATTAS short-period and lateral models are) is put
in matrix form by evaluating it at x = 0, u = 0 and at unit vectors; because f and h are
affine, these differences are exact, not finite-difference approximations:

    f_0 = f(0, 0, θ),   A[:, i] = f(e_i, 0, θ) − f_0,   B[:, k] = f(0, e_k, θ) − f_0
    h_0 = h(0, 0, θ),   C[:, i] = h(e_i, 0, θ) − h_0,   D[:, k] = h(0, e_k, θ) − h_0

``linear_system`` then checks the affine form at a few random points and raises
``InputError`` if the model is not linear in x and u (a nonlinear model has to be
linearised about a trim point first). The constants f_0, h_0 hold bias-like parameters
(Z_0, M_0, state and output biases); a parameter that moves only f_0 or h_0 is invisible to a
frequency-domain fit on a band that excludes ω = 0 once the means are removed
(``bias_like_parameters``).

Time delays. A model's ``input_delays`` (the model sees u_k(t − τ_k)) and ``output_delays``
(the output y_j(t − τ_j)) are the factors e^{−jωτ} of the frequency domain:

    Y(ω) = diag(e^{−jωτ_y}) [C (jωI − A)⁻¹ B + D] diag(e^{−jωτ_u}) U(ω)

``LinearSystem`` carries the delays (s) at θ; ``transfer`` evaluates H(jω) with them. This is
the continuous delay, which the time-domain conventions (``delay_convention``) approximate
by interpolating between samples; on a finite record the transform of u(t − τ) differs
from e^{−jωτ}U(ω) by the τ seconds at each end of the record, a boundary effect of the size
of the boundary terms x(0), x(T) the estimators fit per maneuver.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from flightid.errors import InputError, describe
from flightid.frequency.arguments import real_array
from flightid.model.statespace import StateSpaceModel

__all__ = ["LinearSystem", "linear_system", "bias_like_parameters"]


@dataclass(frozen=True)
class LinearSystem:
    """Matrices of ẋ = f0 + A x + B u, y = h0 + C x + D u (SI units of the channels), with
    the input and output time delays τ_u (n_u,) and τ_y (n_y,) in s (zeros: no delay)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    f0: np.ndarray
    h0: np.ndarray
    input_delays_s: np.ndarray = field(default=None)  # type: ignore[assignment]
    output_delays_s: np.ndarray = field(default=None)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        for name, size in (
            ("input_delays_s", self.B.shape[1]),
            ("output_delays_s", self.C.shape[0]),
        ):
            value = getattr(self, name)
            delays = np.zeros(size) if value is None else np.asarray(value, dtype=float)
            if delays.shape != (size,) or not np.all(np.isfinite(delays)):
                raise InputError(f"{name}: expected {size} finite delays (s), got {value!r}")
            object.__setattr__(self, name, delays)

    @property
    def delayed(self) -> bool:
        """True if any input or output delay is non-zero."""
        return bool(np.any(self.input_delays_s) or np.any(self.output_delays_s))

    def input_phase(self, omega_rad_s: np.ndarray) -> np.ndarray:
        """e^{−jωτ_u} (K, n_u) at the frequencies ω (rad/s)."""
        return np.exp(-1j * np.asarray(omega_rad_s, float)[:, None] * self.input_delays_s[None, :])

    def output_phase(self, omega_rad_s: np.ndarray) -> np.ndarray:
        """e^{−jωτ_y} (K, n_y) at the frequencies ω (rad/s)."""
        return np.exp(-1j * np.asarray(omega_rad_s, float)[:, None] * self.output_delays_s[None, :])

    def transfer(self, frequencies_hz: np.ndarray) -> np.ndarray:
        """H(jω) = diag(e^{−jωτ_y}) [C (jωI − A)⁻¹ B + D] diag(e^{−jωτ_u}), (K, n_y, n_u)."""
        omega = 2.0 * np.pi * np.asarray(frequencies_hz, dtype=float).reshape(-1)
        eye = np.eye(self.A.shape[0])
        plain = np.array(
            [self.C @ np.linalg.solve(1j * w * eye - self.A, self.B) + self.D for w in omega]
        ).reshape(omega.size, self.C.shape[0], self.B.shape[1])
        return self.output_phase(omega)[:, :, None] * plain * self.input_phase(omega)[:, None, :]


def _call(fn, x: np.ndarray, u: np.ndarray, theta: np.ndarray, size: int) -> np.ndarray:
    value = np.asarray(fn(0.0, x, u, theta), dtype=float).reshape(-1)
    if value.shape[0] != size:
        raise InputError(
            f"model: a model function returned {value.shape[0]} values, expected {size}"
        )
    return value


def linear_system(model: StateSpaceModel, theta: np.ndarray | None = None) -> LinearSystem:
    """The model's matrices at the parameter vector ``theta`` (full vector; default: the
    model's values).

    Raises:
        InputError: the model has per-maneuver parameters, or f / h are not affine in
            (x, u) (checked at three seeded random points).
    """
    if not isinstance(model, StateSpaceModel):
        raise InputError(f"model: expected a StateSpaceModel, got {describe(model)}")
    if model.maneuver_parameters:
        raise InputError(
            "model: frequency-domain estimation takes one parameter set for all maneuvers; "
            f"got per-maneuver parameters {sorted(model.maneuver_parameters)}"
        )
    if model.f is None or not model.states:
        raise InputError("model: frequency-domain estimation needs a model with states (f)")
    theta = model.parameters.values if theta is None else real_array(theta, "theta", "numbers")
    if theta.shape != (len(model.parameters),) or not np.all(np.isfinite(theta)):
        raise InputError(
            f"theta: expected {len(model.parameters)} finite values (the full parameter vector "
            f"{model.parameters.names}), got {describe(theta)}"
        )
    theta_f = model.function_theta(theta)
    n_x, n_u, n_y = len(model.states), len(model.inputs), len(model.outputs)
    zx, zu = np.zeros(n_x), np.zeros(n_u)
    f0 = _call(model.f, zx, zu, theta_f, n_x)
    h0 = _call(model.h, zx, zu, theta_f, n_y)
    A = np.empty((n_x, n_x))
    C = np.empty((n_y, n_x))
    for i in range(n_x):
        e = np.zeros(n_x)
        e[i] = 1.0
        # A[:, i] = f(e_i, 0) − f_0
        A[:, i] = _call(model.f, e, zu, theta_f, n_x) - f0
        C[:, i] = _call(model.h, e, zu, theta_f, n_y) - h0
    B = np.empty((n_x, n_u))
    D = np.empty((n_y, n_u))
    for k in range(n_u):
        e = np.zeros(n_u)
        e[k] = 1.0
        # B[:, k] = f(0, e_k) − f_0
        B[:, k] = _call(model.f, zx, e, theta_f, n_x) - f0
        D[:, k] = _call(model.h, zx, e, theta_f, n_y) - h0
    rng = np.random.default_rng(20261126)
    for _ in range(3):
        x = rng.standard_normal(n_x)
        u = rng.standard_normal(n_u)
        f_lin = f0 + A @ x + B @ u
        h_lin = h0 + C @ x + D @ u
        f_true = _call(model.f, x, u, theta_f, n_x)
        h_true = _call(model.h, x, u, theta_f, n_y)
        scale = 1.0 + np.abs(f_true).max() + np.abs(h_true).max()
        gap = max(np.abs(f_true - f_lin).max(), np.abs(h_true - h_lin).max())
        if not np.isfinite(gap) or gap > 1e-8 * scale:
            raise InputError(
                "model: frequency-domain estimation needs f and h linear in the states and "
                f"inputs; at a random (x, u) they differ from their affine form by {gap:.3g} "
                "(linearise the model about a trim point first)"
            )
    # the delays τ (s) are parameters of the full vector θ, not of f and h
    input_delays = np.zeros(n_u)
    for k, p in model.input_delay_maps():
        input_delays[k] = theta[p]
    output_delays = np.zeros(n_y)
    for j, p in model.output_delay_maps():
        output_delays[j] = theta[p]
    return LinearSystem(A, B, C, D, f0, h0, input_delays, output_delays)


def bias_like_parameters(model: StateSpaceModel) -> list[str]:
    """Free parameters that move only f_0 or h_0 (not A, B, C, D nor a delay): biases,
    which a band excluding ω = 0 on mean-removed data cannot determine."""
    base = linear_system(model)
    theta = model.parameters.values.astype(float)
    names = []
    for j, name in enumerate(model.parameters.names):
        if not model.parameters.free_mask[j]:
            continue
        step = np.zeros_like(theta)
        step[j] = 1.0 + abs(theta[j])
        moved = linear_system(model, theta + step)
        same = all(
            np.allclose(getattr(moved, key), getattr(base, key), rtol=1e-12, atol=1e-12)
            for key in ("A", "B", "C", "D", "input_delays_s", "output_delays_s")
        )
        if same:
            names.append(name)
    return names
