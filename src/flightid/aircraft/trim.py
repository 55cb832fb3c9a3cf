"""Body states from flight variables, and steady straight level flight (trim) of a 6-DOF model.

Body velocity and direction cosines from V, α, β, Θ, Φ:

    u = V cos α cos β,  v = V sin β,  w = V sin α cos β
    l_xz = −sin Θ,  l_yz = sin Φ cos Θ,  l_zz = cos Φ cos Θ

Trim: find α, Θ, Φ and the free inputs (controls, thrust) so that du/dt = dv/dt = dw/dt =
dp/dt = dq/dt = dr/dt = 0 with p = q = r = 0 and a level flight path,
ḣ ∝ u l_xz + v l_yz + w l_zz = 0 (the velocity component along the local vertical),
solved by nonlinear least squares.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from flightid.errors import InputError
from flightid.model.statespace import StateSpaceModel

__all__ = ["body_state", "TrimPoint", "trim_level_flight"]


def body_state(
    V: float,
    alpha: float = 0.0,
    beta: float = 0.0,
    theta: float = 0.0,
    phi: float = 0.0,
    p: float = 0.0,
    q: float = 0.0,
    r: float = 0.0,
) -> np.ndarray:
    """Body state (u, v, w, p, q, r, l_xz, l_yz, l_zz) from V (m/s), angles (rad), rates."""
    return np.array(
        [
            V * np.cos(alpha) * np.cos(beta),
            V * np.sin(beta),
            V * np.sin(alpha) * np.cos(beta),
            p,
            q,
            r,
            -np.sin(theta),
            np.sin(phi) * np.cos(theta),
            np.cos(phi) * np.cos(theta),
        ]
    )


@dataclass(frozen=True)
class TrimPoint:
    """A steady straight level flight condition.

    Attributes:
        V: airspeed, m/s. alpha, beta, theta, phi: rad.
        inputs: {input name: trim value} for every input of the model.
        x: body state (u, v, w, p, q, r, l_xz, l_yz, l_zz).
        residual: largest |state derivative| left by the solver.
    """

    V: float
    alpha: float
    beta: float
    theta: float
    phi: float
    inputs: Mapping[str, float] = field(default_factory=dict)
    x: np.ndarray = field(default_factory=lambda: np.zeros(9))
    residual: float = 0.0

    def input_vector(self, names: Sequence[str]) -> np.ndarray:
        """Trim inputs in the order ``names``."""
        return np.array([self.inputs[n] for n in names], dtype=float)


def trim_level_flight(
    model: StateSpaceModel,
    V: float,
    *,
    beta: float = 0.0,
    fixed_inputs: Mapping[str, float] | None = None,
    guess: Mapping[str, float] | None = None,
    theta: np.ndarray | None = None,
    tol: float = 1e-10,
) -> TrimPoint:
    """Trim a 6-DOF model (``six_dof_model``) in steady straight level flight at speed V.

    Unknowns: α, Θ, Φ and every model input not in ``fixed_inputs``. ``guess`` may give start
    values for any unknown by name (``alpha``, ``theta``, ``phi`` or an input name).
    """
    if model.states != ("u", "v", "w", "p", "q", "r", "l_xz", "l_yz", "l_zz"):
        raise InputError(
            f"model: trim_level_flight needs a six_dof_model, got states {list(model.states)}"
        )
    fixed_inputs = dict(fixed_inputs or {})
    unknown_fixed = sorted(set(fixed_inputs) - set(model.inputs))
    if unknown_fixed:
        raise InputError(
            f"fixed_inputs: {unknown_fixed} are not inputs of the model {list(model.inputs)}"
        )
    free_inputs = [n for n in model.inputs if n not in fixed_inputs]
    names = ["alpha", "theta", "phi", *free_inputs]
    guess = dict(guess or {})
    start = np.array([guess.get(n, 0.05 if n in ("alpha", "theta") else 0.0) for n in names])
    theta_vec = model.parameters.values if theta is None else np.asarray(theta, dtype=float)

    def unpack(z):
        values = dict(zip(names, z, strict=True))
        u = np.array(
            [fixed_inputs[n] if n in fixed_inputs else values[n] for n in model.inputs],
            dtype=float,
        )
        x = body_state(V, values["alpha"], beta, values["theta"], values["phi"])
        return x, u

    def residual(z):
        x, u = unpack(z)
        d = np.asarray(model.f(0.0, x, u, theta_vec), dtype=float)
        # level flight: velocity along the local vertical u l_xz + v l_yz + w l_zz = 0
        climb = x[0] * x[6] + x[1] * x[7] + x[2] * x[8]
        return np.concatenate([d[:6], [climb]])

    solution = least_squares(residual, start, xtol=tol, ftol=tol, gtol=tol, x_scale="jac")
    x, u = unpack(solution.x)
    values = dict(zip(names, solution.x, strict=True))
    return TrimPoint(
        V=float(V),
        alpha=float(values["alpha"]),
        beta=float(beta),
        theta=float(values["theta"]),
        phi=float(values["phi"]),
        inputs={n: float(v) for n, v in zip(model.inputs, u, strict=True)},
        x=x,
        residual=float(np.max(np.abs(residual(solution.x)))),
    )
