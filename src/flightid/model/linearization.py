"""Linear state-space model of a ``StateSpaceModel`` about an operating point, with the
covariance of its entries.

    dx/dt ≈ A (x − x̄) + B (u − ū) + f(x̄, ū),    y ≈ C (x − x̄) + D (u − ū) + h(x̄, ū)

    A = ∂f/∂x,  B = ∂f/∂u,  C = ∂h/∂x,  D = ∂h/∂u     at (x̄, ū, θ), t = t̄

The Jacobians are central differences of the model's f and h, step
δ = 1e-6·max(|v|, 1) per state or input v — exact to rounding for a model linear in x and u.

Covariance of the entries (delta method): with e(θ) = vec(A, B, C, D) (row-major A, then B, C,
D) and J = ∂e/∂θ_free by central differences in θ (step max(1e-4·max(|θ_j|, typical_j),
0.1·σ_j), σ_j = √P_jj),

    Cov e ≈ J P Jᵀ

for the covariance P of the free estimates; the operating point is held fixed (the
covariance is that of the Jacobians at the given point). Time delays of the model are not in
A, B, C, D (``notes`` lists them).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from flightid.errors import InputError
from flightid.model.statespace import StateSpaceModel
from flightid.results import MissingDependencyError

__all__ = ["LinearModel", "LinearizationError", "linearize"]

# relative steps: of the states and inputs in the Jacobians, of θ in the covariance
STATE_STEP = 1e-6
PARAMETER_STEP = 1e-4
_BLOCKS = ("A", "B", "C", "D")


class LinearizationError(InputError):
    """A linearization that cannot be made as asked (operating point, covariance)."""


@dataclass(frozen=True, eq=False)
class LinearModel:
    """dx/dt = A x + B u, y = C x + D u in deviations from the operating point.

    Attributes:
        A, B, C, D: (n_s, n_s), (n_s, n_u), (n_o, n_s), (n_o, n_u).
        states, inputs, outputs: names.
        state_units, input_units, output_units: units (``""`` where unknown).
        x0, u0: the operating point (states, inputs) in their units; ``t0`` its time (s).
        f0, y0: f(x0, u0) (zero in a trim) and h(x0, u0).
        covariance: Cov vec(A, B, C, D) (row-major blocks in that order), or None.
        operating_point: how the point was chosen, in words.
        notes: what the linear model leaves out (time delays), one line each.
        name: label.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    x0: np.ndarray
    u0: np.ndarray
    f0: np.ndarray
    y0: np.ndarray
    t0: float = 0.0
    covariance: np.ndarray | None = None
    state_units: tuple[str, ...] = ()
    input_units: tuple[str, ...] = ()
    output_units: tuple[str, ...] = ()
    operating_point: str = ""
    notes: tuple[str, ...] = ()
    name: str = "linear model"

    def __post_init__(self) -> None:
        for name in ("A", "B", "C", "D", "x0", "u0", "f0", "y0", "covariance"):
            value = getattr(self, name)
            if value is None:
                continue
            array = np.array(value, dtype=float)
            array.flags.writeable = False
            object.__setattr__(self, name, array)
        for name, size in (
            ("state_units", len(self.states)),
            ("input_units", len(self.inputs)),
            ("output_units", len(self.outputs)),
        ):
            units = tuple(getattr(self, name)) or ("",) * size
            if len(units) != size:
                raise LinearizationError(f"{name}: expected {size} units, got {len(units)}")
            object.__setattr__(self, name, units)

    # ------------------------------------------------------------------ entries
    @property
    def shapes(self) -> dict[str, tuple[int, int]]:
        n_s, n_u, n_o = len(self.states), len(self.inputs), len(self.outputs)
        return {"A": (n_s, n_s), "B": (n_s, n_u), "C": (n_o, n_s), "D": (n_o, n_u)}

    def entry_slices(self) -> dict[str, slice]:
        """Where each block lies in vec(A, B, C, D) (the rows of ``covariance``)."""
        slices, start = {}, 0
        for block, (rows, cols) in self.shapes.items():
            slices[block] = slice(start, start + rows * cols)
            start += rows * cols
        return slices

    def block_std(self, block: str) -> np.ndarray:
        """σ of every entry of ``block`` ("A", "B", "C" or "D"), its shape; NaN without a
        covariance."""
        if block not in _BLOCKS:
            raise LinearizationError(f"block: expected one of {list(_BLOCKS)}, got {block!r}")
        shape = self.shapes[block]
        if self.covariance is None:
            return np.full(shape, np.nan)
        part = np.diag(self.covariance)[self.entry_slices()[block]]
        return np.sqrt(np.maximum(part, 0.0)).reshape(shape)

    def block_covariance(self, block: str) -> np.ndarray | None:
        """Cov vec(block) (row-major), or None without a covariance."""
        if self.covariance is None:
            return None
        part = self.entry_slices()[block]
        return self.covariance[part, part]

    # ------------------------------------------------------------------ conversions
    def modes(self):
        """The modes of A with σ (``flightid.model.modes.modes_of``)."""
        from flightid.model.modes import modes_of

        return modes_of(self)

    def to_scipy(self):
        """``scipy.signal.StateSpace(A, B, C, D)`` (continuous time)."""
        from scipy.signal import StateSpace

        return StateSpace(np.array(self.A), np.array(self.B), np.array(self.C), np.array(self.D))

    def to_control(self):
        """``control.StateSpace`` with the state, input and output names (python-control,
        the optional extra ``flightid[control]``); ``MissingDependencyError`` without it."""
        try:
            import control
        except ImportError:
            raise MissingDependencyError(
                "to_control: needs python-control, which is not installed; install it with "
                "pip install 'flightid[control]' (or pip install control)"
            ) from None
        return control.ss(
            np.array(self.A),
            np.array(self.B),
            np.array(self.C),
            np.array(self.D),
            states=list(self.states),
            inputs=list(self.inputs),
            outputs=list(self.outputs),
            name=self.name,
        )

    # ------------------------------------------------------------------ reports
    def summary(self) -> str:
        """The matrices with σ of every entry (where it is not 0), the operating point and
        the modes."""
        lines = [f"{self.name}: {len(self.states)} states, {len(self.inputs)} inputs, "]
        lines[0] += f"{len(self.outputs)} outputs"
        if self.operating_point:
            lines.append(f"operating point: {self.operating_point}")
        point = ", ".join(
            f"{n} = {v:.6g} {u}".rstrip()
            for n, v, u in zip(
                (*self.states, *self.inputs),
                (*self.x0, *self.u0),
                (*self.state_units, *self.input_units),
                strict=True,
            )
        )
        lines.append(f"  {point}")
        rows = {"A": self.states, "B": self.states, "C": self.outputs, "D": self.outputs}
        cols = {"A": self.states, "B": self.inputs, "C": self.states, "D": self.inputs}
        for block in _BLOCKS:
            matrix, sigma = getattr(self, block), self.block_std(block)
            if matrix.size == 0:
                continue
            lines.append(f"{block} (rows {list(rows[block])}, columns {list(cols[block])}):")
            for i, row in enumerate(rows[block]):
                cells = [
                    f"{matrix[i, j]:11.4g}" + (f" ±{sigma[i, j]:.2g}" if sigma[i, j] > 0 else "")
                    for j in range(matrix.shape[1])
                ]
                lines.append(f"  {row:<8}" + "  ".join(cells))
        lines.append("")
        # the modes' table ends with the notes (what A leaves out)
        lines.append(self.modes().summary())
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready entry: matrices, their σ, names, units, operating point, modes."""
        entry: dict = {
            "name": self.name,
            "states": list(self.states),
            "inputs": list(self.inputs),
            "outputs": list(self.outputs),
            "state_units": list(self.state_units),
            "input_units": list(self.input_units),
            "output_units": list(self.output_units),
            "operating_point": {
                "description": self.operating_point,
                "t_s": float(self.t0),
                "x": [float(v) for v in self.x0],
                "u": [float(v) for v in self.u0],
                "f": [float(v) for v in self.f0],
                "y": [float(v) for v in self.y0],
            },
            "notes": list(self.notes),
        }
        for block in _BLOCKS:
            entry[block] = np.asarray(getattr(self, block)).tolist()
            sigma = self.block_std(block)
            entry[f"{block}_std"] = None if self.covariance is None else sigma.tolist()
        entry["modes"] = self.modes().to_dict()
        return entry

    def __repr__(self) -> str:
        return (
            f"LinearModel({self.name}: states={list(self.states)}, inputs={list(self.inputs)}, "
            f"outputs={list(self.outputs)})"
        )


def _as_vector(
    value: Sequence[float] | Mapping[str, float] | np.ndarray | None,
    names: Sequence[str],
    what: str,
) -> np.ndarray:
    if value is None:
        return np.zeros(len(names))
    if isinstance(value, Mapping):
        unknown = [k for k in value if k not in names]
        missing = [n for n in names if n not in value]
        if unknown or missing:
            raise LinearizationError(
                f"{what}: expected one value per name {list(names)}; unknown {unknown}, "
                f"missing {missing}"
            )
        vector = np.array([float(value[n]) for n in names])
    else:
        vector = np.asarray(value, dtype=float).ravel()
        if vector.size != len(names):
            raise LinearizationError(
                f"{what}: expected {len(names)} values (one per {list(names)}), got {vector.size}"
            )
    if not np.all(np.isfinite(vector)):
        raise LinearizationError(f"{what}: values must be finite, got {vector.tolist()}")
    return vector


def _jacobians(
    model: StateSpaceModel, t: float, x: np.ndarray, u: np.ndarray, theta_f: np.ndarray
) -> tuple[np.ndarray, ...]:
    """(A, B, C, D) by central differences of f and h at (t, x, u) for the θ f and h read."""
    n_s = x.size
    point = np.concatenate([x, u])
    steps = STATE_STEP * np.maximum(np.abs(point), 1.0)

    def both(z: np.ndarray) -> np.ndarray:
        xs, us = z[:n_s], z[n_s:]
        dx = np.asarray(model.f(t, xs, us, theta_f), dtype=float) if n_s else np.zeros(0)
        return np.concatenate([dx, np.asarray(model.h(t, xs, us, theta_f), dtype=float)])

    columns = []
    for j in range(point.size):
        plus, minus = point.copy(), point.copy()
        plus[j] += steps[j]
        minus[j] -= steps[j]
        # ∂(f, h)/∂z_j = ((f, h)(z + δ_j e_j) − (f, h)(z − δ_j e_j)) / (2 δ_j)
        columns.append((both(plus) - both(minus)) / (2.0 * steps[j]))
    n_rows = n_s + len(model.outputs)
    jac = np.column_stack(columns) if columns else np.zeros((n_rows, 0))
    return jac[:n_s, :n_s], jac[:n_s, n_s:], jac[n_s:, :n_s], jac[n_s:, n_s:]


def _entries(model, t, x, u, theta, maneuver) -> np.ndarray:
    blocks = _jacobians(model, t, x, u, model.function_theta(theta, maneuver))
    return np.concatenate([b.ravel() for b in blocks])


def _entry_covariance(
    model: StateSpaceModel,
    t: float,
    x: np.ndarray,
    u: np.ndarray,
    maneuver: int,
    covariance: np.ndarray,
) -> np.ndarray:
    """Cov vec(A, B, C, D) = J P Jᵀ, J = ∂vec/∂θ_free by central differences in θ."""
    parameters = model.parameters
    theta = parameters.values
    free_index = np.flatnonzero(parameters.free_mask)
    p = np.asarray(covariance, dtype=float)
    if p.shape != (free_index.size, free_index.size):
        raise LinearizationError(
            f"covariance: expected ({free_index.size}, {free_index.size}) over the free "
            f"parameters {parameters.free_names}, got {p.shape}"
        )
    if not np.all(np.isfinite(p)):
        raise LinearizationError(
            "covariance: has non-finite entries (an undetermined parameter); the entries' "
            "covariance cannot be given"
        )
    typical = np.array([1e-3 if q.scale is None else q.scale for q in parameters])
    sigma = np.sqrt(np.maximum(np.diag(p), 0.0))
    columns = []
    for k, j in enumerate(free_index):
        # δ_j = max(1e-4·max(|θ_j|, typical_j), 0.1·σ_j): on the scale of the uncertainty
        # where that is larger, so that rounding in the inner differences stays small
        step = max(PARAMETER_STEP * max(abs(theta[j]), typical[j]), 0.1 * sigma[k])
        plus, minus = theta.copy(), theta.copy()
        plus[j] += step
        minus[j] -= step
        # J_j = (e(θ + δ e_j) − e(θ − δ e_j)) / (2δ)
        columns.append(
            (_entries(model, t, x, u, plus, maneuver) - _entries(model, t, x, u, minus, maneuver))
            / (2.0 * step)
        )
    jac = np.column_stack(columns)
    # Cov e = J P Jᵀ
    return jac @ p @ jac.T


def _delay_notes(model: StateSpaceModel) -> tuple[str, ...]:
    notes = []
    for kind, delays in (("output", model.output_delays), ("input", model.input_delays)):
        for channel, parameter in (delays or {}).items():
            value = model.parameters[parameter].value
            notes.append(
                f"{kind} {channel!r} delayed by {parameter} = {value:.4g} s: not in A, B, C, D"
            )
    return tuple(notes)


def _measured_state_notes(model: StateSpaceModel) -> tuple[str, ...]:
    """A note when inputs are measured states (an airplane state name, or a state's name with
    ``_m``): then A holds the dynamics of the other states with those held as inputs — its
    modes are not those of the free airplane."""
    from flightid.model.modes import LATERAL_STATES, LONGITUDINAL_STATES

    airplane = set(LONGITUDINAL_STATES) | set(LATERAL_STATES)
    measured = [
        n
        for n in model.inputs
        if n in airplane or n in model.states or (n.endswith("_m") and n[:-2] in model.states)
    ]
    if not measured:
        return ()
    return (
        f"inputs {measured} are measured states: A holds the dynamics of {list(model.states)} "
        f"with them held as inputs; its modes are not those of the free airplane",
    )


def _maneuver_notes(model: StateSpaceModel, maneuver: int) -> tuple[str, ...]:
    if not model.maneuver_parameters:
        return ()
    return (
        f"parameters per maneuver {list(model.maneuver_parameters)}: those of maneuver "
        f"{maneuver + 1}",
    )


def linearize(
    model: StateSpaceModel,
    x: Sequence[float] | Mapping[str, float] | np.ndarray,
    u: Sequence[float] | Mapping[str, float] | np.ndarray | None = None,
    *,
    t: float = 0.0,
    covariance: np.ndarray | None = None,
    maneuver: int = 0,
    units: Mapping[str, str] | None = None,
    operating_point: str = "",
    name: str = "",
    notes: Sequence[str] = (),
) -> LinearModel:
    """The linear model of ``model`` at its parameter values about (x, u) (module docstring).

    Args:
        model: the model (its parameter values are used).
        x: the operating point's states (one value per state, or ``{state: value}``).
        u: its inputs (likewise); None: all 0.
        t: the time passed to f and h (s).
        covariance: P of the free parameters: with it ``LinearModel.covariance`` holds
            Cov vec(A, B, C, D); None: no covariance.
        maneuver: for a model with parameters per maneuver, whose copies to use (0-based).
        units: ``{channel: unit}`` for the states, inputs and outputs.
        operating_point: how the point was chosen, in words (for reports).
        name: label (default: the model's name).
        notes: further lines for ``LinearModel.notes``.
    Raises:
        LinearizationError: a point of the wrong size or not finite, a covariance of the
            wrong shape or with non-finite entries.
    """
    xv = _as_vector(x, model.states, "x")
    uv = _as_vector(u, model.inputs, "u")
    t = float(t)
    theta = model.parameters.values
    theta_f = model.function_theta(theta, maneuver)
    blocks = _jacobians(model, t, xv, uv, theta_f)
    f0 = np.asarray(model.f(t, xv, uv, theta_f), dtype=float) if model.states else np.zeros(0)
    y0 = np.asarray(model.h(t, xv, uv, theta_f), dtype=float)
    cov = None if covariance is None else _entry_covariance(model, t, xv, uv, maneuver, covariance)
    units = dict(units or {})
    return LinearModel(
        *blocks,
        states=model.states,
        inputs=model.inputs,
        outputs=model.outputs,
        x0=xv,
        u0=uv,
        f0=f0,
        y0=y0,
        t0=t,
        covariance=cov,
        state_units=tuple(units.get(n, "") or "" for n in model.states),
        input_units=tuple(units.get(n, "") or "" for n in model.inputs),
        output_units=tuple(units.get(n, "") or "" for n in model.outputs),
        operating_point=operating_point,
        notes=_delay_notes(model)
        + _measured_state_notes(model)
        + _maneuver_notes(model, maneuver)
        + tuple(notes),
        name=name or model.name,
    )
