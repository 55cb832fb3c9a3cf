"""Table models of an aerodynamic coefficient: sums of tensor-product tables on breakpoints.

A table component covers one to three explanatory variables (JSBSim's row / column / table
limit). Its basis is the tensor product of one-dimensional bases on the breakpoints b_0 < … <
b_{K−1} of each variable:

- degree 1: hat functions (piecewise-linear B-splines). φ_k(x) is 1 at b_k, 0 at the other
  breakpoints and linear in between, so the coefficients *are* the table values and the
  model is exactly what JSBSim's linear ``<table>`` interpolates;
- degree 3: clamped cubic B-splines on the knots (b_0 ×4, b_1 … b_{K−2}, b_{K−1} ×4),
  K + 2 functions per axis (``scipy.interpolate.BSpline.design_matrix``); the table values
  are the spline sampled on the breakpoints.

Outside its breakpoints a variable is held at the nearest edge (x clipped to [b_0, b_{K−1}]),
which is how JSBSim's tables behave: the model holds its edge value and does not extrapolate.

A component may be multiplied by a signal (``times = "qhat"``: the C_Lq(α)·q̂ form), and a
model is the sum of its components:

    C(x) = Σ_c s_c(x) Σ_j θ_cj Φ_cj(x)          Φ_cj = φ_j1(x_1) φ_j2(x_2) φ_j3(x_3)

with s_c the ``times`` signal (1 without one).

Identifiability. The basis functions of every component sum to one (a partition of unity),
so two components multiplied by the same signal share one direction: the constant (times that
signal). The rule: among the components with the same ``times`` (None counting as one group),
every component but the first loses its first basis function (the one at the first
breakpoint of each of its variables), i.e. its value there is fixed to 0 and the other
values are relative to it. Two components of one group that share a variable overlap in
more than a constant and are rejected (``TableError``).

Fit (``fit_table_model``). With smoothing λ = 0 the basis functions whose data weight
w_j = Σ_i Φ_j(x_i) (the number of samples near the breakpoint, weighted by the hat value,
without the ``times`` signal) is below ``min_weight`` are not determined by the data: they
are dropped (their values NaN, flagged ``dropped``; the model evaluates to NaN where they
act) and the others are fitted by ``flightid.regression.least_squares`` with the
coloured-residual σ by maneuver. With λ > 0 every basis function is kept and the cost gains
λ‖D θ‖², D the second divided differences of the values along each axis of each component
(scaled by the mean breakpoint spacing², so on evenly spaced breakpoints a row is
θ_{k−1} − 2θ_k + θ_{k+1}, and a function linear along the axis costs nothing): cells without
data are filled smoothly and flagged ``filled``.

The smoothed fit does not go through ``least_squares`` with the pseudo-rows √λ D θ = 0
appended: it would count them as samples (N, N − n_p), put their residuals into s² and into
the residual autocorrelation of the coloured σ. Instead (``PenalisedLeastSquaresResult``):

    θ̂ = A⁻¹ Bᵀ z,   A = BᵀB + λ DᵀD               (QR of the stacked [B; √λ D])
    residuals ν = z − B θ̂ over the N data rows only
    edf = tr(A⁻¹ BᵀB)                              effective number of parameters
    s² = ‖ν‖² / (N − edf)
    Cov_cr(θ̂) = s² A⁻¹ BᵀB A⁻¹                     (θ̂ is linear in z: Cov = A⁻¹ Bᵀ Cov(z) B A⁻¹)
    Cov_col(θ̂) = A⁻¹ [Σ_i Σ_j b_i R̂_ν(i − j) b_jᵀ] A⁻¹ · N/(N − edf)   when ν is coloured

These are the variance of the smoothed estimate for the given λ; they leave out the bias the
smoothing adds where the true table has curvature (none where it is linear along each axis).
PSE = RSS/N + σ²_max·edf/N.
"""

from __future__ import annotations

import dataclasses
import math
import types
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from flightid.coloured import COLOURED, CRAMER_RAO, automatic_lag, coloured_covariance
from flightid.errors import InputError, describe
from flightid.globalmodel.variables import check_series
from flightid.regression.least_squares import (
    LeastSquaresError,
    LeastSquaresResult,
    least_squares,
)

__all__ = [
    "BreakpointChoice",
    "PenalisedLeastSquaresResult",
    "TableComponent",
    "TableError",
    "TableFit",
    "auto_breakpoints",
    "choose_breakpoints",
    "cubic_bspline_functions",
    "fit_table_model",
    "hat_functions",
    "table_basis",
]

#: most variables of one table (JSBSim's row, column and table breakpoints)
MAX_TABLE_VARIABLES = 3
#: degrees of the one-dimensional bases: hat functions and cubic B-splines
DEGREES = (1, 3)


class TableError(InputError):
    """A table model's input is malformed: breakpoints, variables, signals, components that
    are not identifiable together, or a table the data (and smoothing) cannot determine."""


# --------------------------------------------------------------------------- components


def _breakpoint_array(name: str, values: Any) -> np.ndarray:
    """Breakpoints of ``name`` as a read-only float array: 1-D, ≥ 2 finite, strictly
    increasing (else ``TableError``)."""
    try:
        array = np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise TableError(
            f"breakpoints[{name!r}]: expected a sequence of numbers, got {describe(values)}"
        ) from None
    if array.ndim != 1 or array.size < 2:
        raise TableError(
            f"breakpoints[{name!r}]: expected at least 2 breakpoints in a 1-D sequence, got "
            f"{describe(values)}"
        )
    if not np.all(np.isfinite(array)):
        raise TableError(f"breakpoints[{name!r}]: expected finite numbers, got {array.tolist()}")
    if not np.all(np.diff(array) > 0):
        raise TableError(
            f"breakpoints[{name!r}]: expected strictly increasing values, got {array.tolist()}"
        )
    array.flags.writeable = False
    return array


@dataclass(frozen=True, eq=False)
class TableComponent:
    """One table of a table model: 1–3 variables, their breakpoints, an optional signal the
    table is multiplied by, and the degree of the one-dimensional bases.

    Attributes:
        variables: names of the table's variables (signals), 1 to 3, distinct.
        breakpoints: {variable: strictly increasing breakpoints (≥ 2), in the variable's
            unit}; keys beyond ``variables`` are ignored (one map may serve every component).
        times: name of a signal the table is multiplied by (``"qhat"``), or None.
        degree: 1 (hat functions: the coefficients are the table values) or 3 (cubic
            B-splines).
    """

    variables: tuple[str, ...]
    breakpoints: Mapping[str, np.ndarray]
    times: str | None = None
    degree: int = 1

    def __post_init__(self) -> None:
        variables = self.variables
        if isinstance(variables, str):
            variables = (variables,)
        if not isinstance(variables, Sequence) or not all(
            isinstance(v, str) and v for v in variables
        ):
            raise TableError(
                f"variables: expected 1 to {MAX_TABLE_VARIABLES} signal names, got "
                f"{describe(self.variables)}"
            )
        variables = tuple(variables)
        if not 1 <= len(variables) <= MAX_TABLE_VARIABLES:
            raise TableError(
                f"variables: expected 1 to {MAX_TABLE_VARIABLES} variables per table (JSBSim's "
                f"row, column and table), got {len(variables)}: {list(variables)}"
            )
        if len(set(variables)) != len(variables):
            raise TableError(f"variables: expected distinct names, got {list(variables)}")
        if not isinstance(self.breakpoints, Mapping):
            raise TableError(
                f"breakpoints: expected a mapping {{variable: breakpoints}}, got "
                f"{describe(self.breakpoints)}"
            )
        missing = [v for v in variables if v not in self.breakpoints]
        if missing:
            raise TableError(
                f"breakpoints: expected breakpoints for every variable {list(variables)}, "
                f"missing {missing}"
            )
        breakpoints = {v: _breakpoint_array(v, self.breakpoints[v]) for v in variables}
        if self.times is not None and not (isinstance(self.times, str) and self.times):
            raise TableError(f"times: expected a signal name or None, got {describe(self.times)}")
        if isinstance(self.degree, bool) or self.degree not in DEGREES:
            raise TableError(f"degree: expected 1 or 3, got {self.degree!r}")
        object.__setattr__(self, "variables", variables)
        object.__setattr__(self, "breakpoints", types.MappingProxyType(breakpoints))
        object.__setattr__(self, "degree", int(self.degree))

    @property
    def label(self) -> str:
        """``"alpha:de"``, or ``"qhat*alpha"`` for a table multiplied by ``qhat``."""
        name = ":".join(self.variables)
        return name if self.times is None else f"{self.times}*{name}"

    @property
    def grid_shape(self) -> tuple[int, ...]:
        """Number of breakpoints of each variable: the shape of the table values."""
        return tuple(self.breakpoints[v].size for v in self.variables)

    @property
    def basis_shape(self) -> tuple[int, ...]:
        """Number of basis functions along each variable (K, or K + 2 for degree 3)."""
        extra = 0 if self.degree == 1 else 2
        return tuple(k + extra for k in self.grid_shape)

    def nodes(self, variable: str) -> np.ndarray:
        """Where each basis function along ``variable`` sits: the breakpoints (degree 1) or
        the Greville abscissae ξ_j = (t_{j+1} + t_{j+2} + t_{j+3})/3 of the cubic knots,
        at which a linear function's B-spline coefficients equal its values."""
        b = self.breakpoints[variable]
        if self.degree == 1:
            return b
        t = _cubic_knots(b)
        # ξ_j = (t_{j+1} + t_{j+2} + t_{j+3}) / 3
        return (t[1:-3] + t[2:-2] + t[3:-1]) / 3.0

    def to_dict(self) -> dict:
        """{"by", "breakpoints", "times", "degree"} with plain lists."""
        return {
            "by": list(self.variables),
            "breakpoints": {v: self.breakpoints[v].tolist() for v in self.variables},
            "times": self.times,
            "degree": self.degree,
        }

    @classmethod
    def from_dict(cls, data: Mapping) -> TableComponent:
        """The component ``to_dict`` wrote."""
        if not isinstance(data, Mapping) or "by" not in data or "breakpoints" not in data:
            raise TableError(
                f"component: expected a mapping with 'by' and 'breakpoints', got {describe(data)}"
            )
        return cls(
            tuple(data["by"]),
            data["breakpoints"],
            times=data.get("times"),
            degree=data.get("degree", 1),
        )


# ------------------------------------------------------------------------- 1-D bases


def _series(name: str, values: Any, length: int | None = None) -> np.ndarray:
    """A finite 1-D float series (of ``length`` samples when given), else ``TableError``."""
    return check_series(values, name, length, error=TableError, scalar=False)


def hat_functions(x: Any, breakpoints: Any) -> np.ndarray:
    """Piecewise-linear B-splines (hat functions) on the breakpoints at the points x.

    φ_k(x) = (x − b_{k−1})/(b_k − b_{k−1}) on [b_{k−1}, b_k], (b_{k+1} − x)/(b_{k+1} − b_k)
    on [b_k, b_{k+1}], 0 elsewhere; at each x at most two are non-zero and they sum to 1.
    Outside [b_0, b_{K−1}] x is held at the nearest edge (JSBSim's tables), so the row is
    that of the edge breakpoint.

    Args:
        x: points (N,), the variable's unit.
        breakpoints: strictly increasing (K ≥ 2,), same unit.

    Returns:
        (N, K) array.
    """
    b = _breakpoint_array("breakpoints", breakpoints)
    x = np.clip(_series("x", x), b[0], b[-1])
    k = b.size
    # interval j with b_j ≤ x ≤ b_{j+1}
    j = np.clip(np.searchsorted(b, x, side="right") - 1, 0, k - 2)
    # t = (x − b_j) / (b_{j+1} − b_j)
    t = (x - b[j]) / (b[j + 1] - b[j])
    rows = np.arange(x.size)
    out = np.zeros((x.size, k))
    out[rows, j] = 1.0 - t
    out[rows, j + 1] += t
    return out


def _cubic_knots(b: np.ndarray) -> np.ndarray:
    """Clamped cubic knots: b_0 four times, the interior breakpoints, b_{K−1} four times."""
    return np.concatenate([np.repeat(b[0], 3), b, np.repeat(b[-1], 3)])


def cubic_bspline_functions(x: Any, breakpoints: Any) -> np.ndarray:
    """Clamped cubic B-splines with the breakpoints as knots, at the points x: (N, K + 2).

    The knots are (b_0 ×4, b_1 … b_{K−2}, b_{K−1} ×4) (``scipy.interpolate.BSpline``); the
    functions are non-negative and sum to 1. x outside [b_0, b_{K−1}] is held at the edge.
    """
    from scipy.interpolate import BSpline

    b = _breakpoint_array("breakpoints", breakpoints)
    x = np.clip(_series("x", x), b[0], b[-1])
    return BSpline.design_matrix(x, _cubic_knots(b), 3).toarray()


def _axis_basis(component: TableComponent, variable: str, x: np.ndarray) -> np.ndarray:
    if component.degree == 1:
        return hat_functions(x, component.breakpoints[variable])
    return cubic_bspline_functions(x, component.breakpoints[variable])


# ----------------------------------------------------------------------- tensor bases


def _check_signals(
    signals: Mapping[str, Any], names: Sequence[str], length: int | None = None
) -> dict[str, np.ndarray]:
    """The named signals as finite 1-D arrays of one length (``TableError`` naming the key)."""
    if not isinstance(signals, Mapping):
        raise TableError(f"signals: expected a mapping {{name: series}}, got {describe(signals)}")
    missing = [n for n in names if n not in signals]
    if missing:
        raise TableError(
            f"signals: expected the table signals {list(dict.fromkeys(names))}, missing "
            f"{missing}; got {sorted(signals)}"
        )
    out: dict[str, np.ndarray] = {}
    for name in dict.fromkeys(names):
        out[name] = _series(f"signals[{name!r}]", signals[name], length)
        length = out[name].size
    return out


def _signal_names(components: Sequence[TableComponent]) -> list[str]:
    names: list[str] = []
    for component in components:
        names += list(component.variables)
        if component.times is not None:
            names.append(component.times)
    return names


def _checked_components(components: Any) -> tuple[TableComponent, ...]:
    """The components as a tuple, checked to be identifiable together (module docstring)."""
    if isinstance(components, TableComponent):
        components = (components,)
    if not isinstance(components, Sequence) or not components:
        raise TableError(
            f"components: expected one or more TableComponent, got {describe(components)}"
        )
    components = tuple(components)
    for i, component in enumerate(components):
        if not isinstance(component, TableComponent):
            raise TableError(
                f"components[{i}]: expected a TableComponent, got {type(component).__name__}"
            )
    for i, first in enumerate(components):
        for j in range(i + 1, len(components)):
            second = components[j]
            shared = sorted(set(first.variables) & set(second.variables))
            if first.times == second.times and shared:
                raise TableError(
                    f"components[{i}] ({first.label}) and components[{j}] ({second.label}): "
                    f"expected tables multiplied by the same signal to have no variable in "
                    f"common, got {shared} in both (their sum is not identifiable)"
                )
    return components


def _raw_component_basis(component: TableComponent, signals: Mapping[str, np.ndarray]):
    """Tensor product Φ_j(x_i) of the component's axis bases, without ``times``: (N, n_c),
    flat index in C order over ``basis_shape``."""
    basis = None
    for variable in component.variables:
        axis = _axis_basis(component, variable, signals[variable])
        # Φ_(j…,k)(x_i) = Φ_(j…)(x_i) φ_k(x_i)
        basis = axis if basis is None else (basis[:, :, None] * axis[:, None, :])
        basis = basis.reshape(axis.shape[0], -1)
    return basis


def _fixed_first(components: Sequence[TableComponent]) -> list[bool]:
    """Whether each component loses its first basis function (not first of its group)."""
    seen: set[str | None] = set()
    out = []
    for component in components:
        out.append(component.times in seen)
        seen.add(component.times)
    return out


def _component_labels(component: TableComponent) -> list[str]:
    return [
        f"{component.label}[{','.join(str(i) for i in index)}]"
        for index in np.ndindex(*component.basis_shape)
    ]


def table_basis(
    components: Sequence[TableComponent] | TableComponent, signals: Mapping[str, Any]
) -> tuple[np.ndarray, tuple[str, ...]]:
    """The regressor columns of a table model and their labels.

    Each component contributes the tensor product of its variables' bases (flat index in C
    order over its ``basis_shape``), multiplied by its ``times`` signal. Rule (module
    docstring): among components with the same ``times`` every component but the first drops
    its first basis function (value fixed to 0 at the first breakpoint of each variable),
    since each component's functions sum to 1 and the sum would otherwise be unidentifiable.

    Args:
        components: the components of the model, in order.
        signals: {name: series (N,)} holding every variable and ``times`` signal.

    Returns:
        (B (N, n_p), labels ``"alpha:de[i,j]"`` / ``"qhat*alpha[i]"``).
    """
    components = _checked_components(components)
    data = _check_signals(signals, _signal_names(components))
    columns, labels = [], []
    for component, fixed in zip(components, _fixed_first(components), strict=True):
        basis = _raw_component_basis(component, data)
        names = _component_labels(component)
        if component.times is not None:
            basis = basis * data[component.times][:, None]
        if fixed:
            basis, names = basis[:, 1:], names[1:]
        columns.append(basis)
        labels += names
    return np.hstack(columns), tuple(labels)


# ------------------------------------------------------------------------- smoothing


def _second_differences(nodes: np.ndarray) -> np.ndarray:
    """(K − 2, K) second divided differences at the nodes, scaled by the mean spacing²:

    h̄² · 2 [θ_{k−1}/(h₁(h₁+h₂)) − θ_k/(h₁h₂) + θ_{k+1}/(h₂(h₁+h₂))],  h₁ = x_k − x_{k−1},
    h₂ = x_{k+1} − x_k; zero for a linear function, θ_{k−1} − 2θ_k + θ_{k+1} when even.
    """
    k = nodes.size
    if k < 3:
        return np.zeros((0, k))
    h = np.diff(nodes)
    mean2 = float(np.mean(h)) ** 2
    h1, h2 = h[:-1], h[1:]
    rows = np.arange(k - 2)
    out = np.zeros((k - 2, k))
    out[rows, rows] = 2.0 * mean2 / (h1 * (h1 + h2))
    out[rows, rows + 1] = -2.0 * mean2 / (h1 * h2)
    out[rows, rows + 2] = 2.0 * mean2 / (h2 * (h1 + h2))
    return out


def _component_penalty(component: TableComponent) -> np.ndarray:
    """Second differences along each axis of the component's coefficient grid: (m, n_c)."""
    shape = component.basis_shape
    blocks = []
    for axis, variable in enumerate(component.variables):
        # D_axis = I ⊗ … ⊗ D₁ ⊗ … ⊗ I   (D₁ on this axis, identities on the others)
        matrix = np.ones((1, 1))
        for other, size in enumerate(shape):
            factor = (
                _second_differences(component.nodes(variable)) if other == axis else np.eye(size)
            )
            matrix = np.kron(matrix, factor)
        blocks.append(matrix)
    return np.vstack(blocks)


# ------------------------------------------------------------------- smoothed result


@dataclass(frozen=True, eq=False)
class PenalisedLeastSquaresResult(LeastSquaresResult):
    """A ``LeastSquaresResult`` of the smoothed fit θ̂ = argmin ‖z − Bθ‖² + λ‖Dθ‖².

    Every statistic is over the N data rows only (module docstring): ``dof`` is N − edf
    (a real number), ``s2`` = RSS/(N − edf), ``pse`` = RSS/N + σ²_max·edf/N, the covariances
    the sandwich A⁻¹ BᵀB A⁻¹ s² (classical) and its coloured form. ``vif`` is NaN (the
    penalty, not the columns alone, determines the estimates).

    Attributes:
        effective_parameters: edf = tr(A⁻¹ BᵀB), A = BᵀB + λDᵀD (≤ n_p).
        smoothing: λ, in the response's unit squared per unit second difference squared.
    """

    effective_parameters: float = float("nan")
    smoothing: float = 0.0

    @property
    def dof(self) -> float:  # type: ignore[override]
        """Residual degrees of freedom N − edf."""
        return self.n_samples - self.effective_parameters

    @property
    def pse(self) -> float:
        """Predicted squared error RSS/N + σ²_max·edf/N."""
        return (self.rss + self.sigma2_max * self.effective_parameters) / self.n_samples

    @property
    def f_overall(self) -> float:
        """((TSS − RSS)/(edf − k0)) / s²."""
        k0 = 1 if self.has_constant else 0
        n_reg = self.effective_parameters - k0
        if n_reg <= 0 or self.dof <= 0 or self.s2 == 0:
            return float("nan")
        return ((self.tss - self.rss) / n_reg) / self.s2

    def summary(self) -> str:
        """Text table of the smoothed fit (estimates, default σ and classical σ)."""
        lines = [
            "Smoothed least-squares table fit",
            "=" * 64,
            f"N = {self.n_samples}   n_p = {self.n_parameters}   edf = "
            f"{self.effective_parameters:.4g}   λ = {self.smoothing:.4g}",
            f"s² = {self.s2:.6g}   R² = {self.r2:.6f}   PSE = {self.pse:.6g}",
            f"std err: {self.std_kind} (lag {self.coloured_lag})",
            "-" * 64,
            f"{'term':<24s}{'estimate':>14s}{'std err':>13s}{'std_cr':>13s}",
        ]
        for j, name in enumerate(self.names):
            lines.append(
                f"{name:<24s}{self.estimates[j]:>14.6g}{self.std[j]:>13.3g}{self.std_cr[j]:>13.3g}"
            )
        lines.append("=" * 64)
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """``LeastSquaresResult.to_dict`` plus ``effective_parameters``, ``smoothing``,
        ``dof``."""
        out = super().to_dict()
        out.update(
            effective_parameters=float(self.effective_parameters),
            smoothing=float(self.smoothing),
            dof=float(self.dof),
        )
        return out


def _readonly(array: Any) -> np.ndarray:
    out = np.array(array, dtype=float)
    out.flags.writeable = False
    return out


def _smoothed_fit(
    B: np.ndarray,
    z: np.ndarray,
    D: np.ndarray,
    smoothing: float,
    names: tuple[str, ...],
    *,
    has_constant: bool,
    sigma2_max: float | None,
    units: Mapping[str, str],
    maneuver_index: np.ndarray | None,
) -> PenalisedLeastSquaresResult:
    """θ̂, the statistics over the data rows and the (coloured) sandwich σ of the smoothed fit
    (module docstring)."""
    n, p = B.shape
    stacked = np.vstack([B, math.sqrt(smoothing) * D])
    norms = np.linalg.norm(stacked, axis=0)
    if np.any(norms == 0):
        empty = [names[j] for j in np.flatnonzero(norms == 0)]
        raise TableError(
            f"table: basis functions {empty} have neither data nor smoothing rows (an axis with "
            f"2 breakpoints cannot be filled); add data or breakpoints"
        )
    # unit-length columns: the rank test and the condition number do not depend on units
    Q, R = np.linalg.qr(stacked / norms)
    singular = np.linalg.svd(R, compute_uv=False)
    condition = float(singular[0] / singular[-1]) if singular[-1] > 0 else float("inf")
    if singular[-1] < 1e-12 * singular[0]:
        raise TableError(
            f"table: the data and the smoothing do not determine the table values (condition "
            f"number {condition:.3g}); add data, breakpoints or smoothing"
        )
    # θ̂ = A⁻¹ Bᵀ z from the stacked system [B; √λ D] θ = [z; 0]
    rhs = np.concatenate([z, np.zeros(D.shape[0])])
    theta = np.linalg.solve(R, Q.T @ rhs) / norms
    # A⁻¹ = N⁻¹ R⁻¹ R⁻ᵀ N⁻¹, N = diag(norms)
    r_inv = np.linalg.solve(R, np.eye(p))
    a_inv = (r_inv @ r_inv.T) / np.outer(norms, norms)
    btb = B.T @ B
    # edf = tr(A⁻¹ BᵀB)
    edf = float(np.sum(a_inv * btb))
    if n - edf <= 0:
        raise TableError(
            f"table: expected more samples than effective parameters, got N = {n} and edf = "
            f"{edf:.4g}"
        )
    fitted = B @ theta
    residuals = z - fitted
    rss = float(residuals @ residuals)
    s2 = rss / (n - edf)
    # Cov_cr(θ̂) = s² A⁻¹ BᵀB A⁻¹
    covariance = s2 * (a_inv @ btb @ a_inv)
    covariance = 0.5 * (covariance + covariance.T)
    std_cr = np.sqrt(np.diag(covariance))
    lag = automatic_lag(residuals[:, None], maneuver_index) if n >= 3 else 0
    if lag > 0:
        sandwich, _ = coloured_covariance(
            B[:, None, :], residuals[:, None], np.ones(1), a_inv, lag, maneuver_index
        )
        # R̂_ν(0) divides by N: × N/(N − edf), as s² does
        default = sandwich * (n / (n - edf))
        kind = COLOURED
    else:
        default, kind = covariance, CRAMER_RAO
    # TSS about the mean when the tables hold the constant (an untimed component)
    tss = float(np.sum((z - z.mean()) ** 2)) if has_constant else float(z @ z)
    if sigma2_max is None:
        # σ²_max = mean((z − z̄)²), as least_squares
        sigma2_max = float(np.mean((z - z.mean()) ** 2))
    return PenalisedLeastSquaresResult(
        names=names,
        estimates=_readonly(theta),
        std=_readonly(np.sqrt(np.diag(default))),
        std_cr=_readonly(std_cr),
        covariance=_readonly(covariance),
        covariance_default=_readonly(default),
        std_kind=kind,
        residuals_white=lag == 0,
        coloured_lag=int(lag),
        residuals=_readonly(residuals),
        fitted=_readonly(fitted),
        rss=rss,
        tss=tss,
        n_samples=n,
        n_parameters=p,
        has_constant=has_constant,
        sigma2_max=float(sigma2_max),
        condition_number=condition,
        vif=_readonly(np.full(p, np.nan)),
        units=tuple(units.get(name, "") for name in names) if units else (),
        effective_parameters=edf,
        smoothing=float(smoothing),
    )


# --------------------------------------------------------------------------- the fit


def _nested(array: np.ndarray) -> Any:
    """Nested lists with None for NaN (strict JSON)."""
    if array.dtype == bool:
        return array.tolist()
    return np.where(np.isnan(array), None, array.astype(object)).tolist()


def _from_nested(name: str, values: Any, shape: tuple[int, ...], dtype=float) -> np.ndarray:
    try:
        array = np.array(values if dtype is bool else _none_to_nan(values), dtype=dtype).reshape(
            shape
        )
    except (TypeError, ValueError):
        raise TableError(
            f"{name}: expected nested lists of shape {shape}, got {describe(values)}"
        ) from None
    array.flags.writeable = False
    return array


def _none_to_nan(values: Any) -> Any:
    if isinstance(values, list):
        return [_none_to_nan(v) for v in values]
    return float("nan") if values is None else values


@dataclass(frozen=True, eq=False)
class TableFit:
    """A fitted table model: its tables, their values and σ, and how they were determined.

    Attributes:
        components: the tables, in order (``TableComponent``).
        coefficients: per component, θ on its ``basis_shape`` grid: NaN where dropped (no
            data, λ = 0), 0 at the first function of a component that is not the first of
            its ``times`` group (the identifiability rule).
        values: per component, the table on its breakpoint grid (``grid_shape``); equal to
            ``coefficients`` for degree 1, the spline sampled on the breakpoints for degree 3;
            NaN where a dropped function acts.
        value_std: per component, the default σ of each value (coloured where the residuals
            are), 0 at a fixed first value, NaN where dropped.
        filled: per component, values not determined by the data (data weight below
            ``min_weight``) but by the smoothing (λ > 0).
        dropped: per component, values left undetermined (λ = 0): NaN.
        names: the fitted parameters (columns of ``regressors``), e.g. ``"alpha:de[2,3]"``.
        estimates: θ̂ of the parameters (n_p,).
        covariance: their default covariance (n_p, n_p) (the one behind ``value_std``).
        dof: residual degrees of freedom (N − n_p; N − edf with smoothing).
        s2: residual variance RSS/dof, the response's unit squared.
        smoothing: λ (0: none).
        min_weight: the data weight below which a basis function counts as without data.
        fit: the least-squares result of the fit (``PenalisedLeastSquaresResult`` with
            smoothing); None for a table read back with ``from_dict``.
    """

    components: tuple[TableComponent, ...]
    coefficients: tuple[np.ndarray, ...]
    values: tuple[np.ndarray, ...]
    value_std: tuple[np.ndarray, ...]
    filled: tuple[np.ndarray, ...]
    dropped: tuple[np.ndarray, ...]
    names: tuple[str, ...]
    estimates: np.ndarray
    covariance: np.ndarray
    dof: float
    s2: float
    smoothing: float = 0.0
    min_weight: float = 1.0
    fit: LeastSquaresResult | None = field(default=None, repr=False)

    @property
    def n_parameters(self) -> int:
        return len(self.names)

    def _active(self, signals: Mapping[str, Any]):
        """Per component: raw basis (N, n_c), times (N,) or None; and data signals."""
        data = _check_signals(signals, _signal_names(self.components))
        out = []
        for component in self.components:
            raw = _raw_component_basis(component, data)
            times = None if component.times is None else data[component.times]
            out.append((raw, times))
        return out

    def _undetermined(self, bases) -> np.ndarray:
        """Rows where a dropped basis function acts."""
        rows = np.zeros(bases[0][0].shape[0], dtype=bool)
        for (raw, _), coefficients in zip(bases, self.coefficients, strict=True):
            missing = np.isnan(coefficients.ravel())
            if missing.any():
                rows |= np.any(raw[:, missing] != 0, axis=1)
        return rows

    def evaluate(self, signals: Mapping[str, Any]) -> np.ndarray:
        """The modelled coefficient at the points (N,): Σ_c s_c Σ_j θ_cj Φ_cj (variables held
        at the table edges outside the breakpoints); NaN where a dropped value acts."""
        bases = self._active(signals)
        total = np.zeros(bases[0][0].shape[0])
        for (raw, times), coefficients in zip(bases, self.coefficients, strict=True):
            part = raw @ np.nan_to_num(coefficients.ravel(), nan=0.0)
            total += part if times is None else part * times
        total[self._undetermined(bases)] = np.nan
        return total

    def regressors(self, signals: Mapping[str, Any]) -> np.ndarray:
        """The rows x(points) of the fitted parameters (N, n_p), columns as ``names``, so
        that ``evaluate = regressors @ estimates`` and Var(ŷ) = x Cov xᵀ; NaN rows where a
        dropped value acts."""
        bases = self._active(signals)
        columns = []
        for (raw, times), coefficients, fixed in zip(
            bases, self.coefficients, _fixed_first(self.components), strict=True
        ):
            free = ~np.isnan(coefficients.ravel())
            if fixed:
                free[0] = False
            part = raw[:, free]
            columns.append(part if times is None else part * times[:, None])
        X = np.hstack(columns)
        X[self._undetermined(bases)] = np.nan
        return X

    def cell_flags(self, signals: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
        """(empty, filled), each (N,) bool: the points where a dropped value acts (the model
        is NaN there) and those whose cell touches a value filled by the smoothing (its hat
        function on the breakpoint grid is non-zero there, for either degree)."""
        bases = self._active(signals)
        empty = self._undetermined(bases)
        data = _check_signals(signals, _signal_names(self.components))
        filled = np.zeros(empty.shape, dtype=bool)
        for component, mask in zip(self.components, self.filled, strict=True):
            if mask.any():
                linear = TableComponent(component.variables, component.breakpoints)
                hats = _raw_component_basis(linear, data)
                filled |= np.any(hats[:, mask.ravel()] != 0, axis=1)
        return empty, filled & ~empty

    def to_dict(self) -> dict:
        """Plain lists and numbers (NaN as None: strict JSON); ``from_dict`` reads it back."""
        return {
            "tables": [
                {
                    **component.to_dict(),
                    "coefficients": _nested(self.coefficients[c]),
                    "values": _nested(self.values[c]),
                    "value_std": _nested(self.value_std[c]),
                    "filled": _nested(self.filled[c]),
                    "dropped": _nested(self.dropped[c]),
                }
                for c, component in enumerate(self.components)
            ],
            "parameters": list(self.names),
            "estimates": _nested(np.asarray(self.estimates)),
            "covariance": _nested(np.asarray(self.covariance)),
            "dof": float(self.dof),
            "s2": float(self.s2) if np.isfinite(self.s2) else None,
            "smoothing": float(self.smoothing),
            "min_weight": float(self.min_weight),
        }

    @classmethod
    def from_dict(cls, data: Mapping) -> TableFit:
        """The table model ``to_dict`` wrote (without the ``fit`` statistics object)."""
        required = ("tables", "parameters", "estimates", "covariance", "dof", "s2")
        if not isinstance(data, Mapping) or any(key not in data for key in required):
            raise TableError(f"table model: expected a mapping with keys {list(required)}")
        components = _checked_components(
            [TableComponent.from_dict(entry) for entry in data["tables"]]
        )
        tables = data["tables"]
        per = {key: [] for key in ("coefficients", "values", "value_std", "filled", "dropped")}
        for c, (component, entry) in enumerate(zip(components, tables, strict=True)):
            for key in per:
                shape = component.basis_shape if key == "coefficients" else component.grid_shape
                dtype = bool if key in ("filled", "dropped") else float
                per[key].append(_from_nested(f"tables[{c}].{key}", entry.get(key), shape, dtype))
        names = tuple(data["parameters"])
        n_p = len(names)
        free = sum(
            int(np.sum(~np.isnan(coefficients))) - int(fixed)
            for coefficients, fixed in zip(
                per["coefficients"], _fixed_first(components), strict=True
            )
        )
        if free != n_p:
            raise TableError(
                f"parameters: expected one name per fitted table coefficient ({free}), got {n_p}"
            )
        s2 = data["s2"]
        return cls(
            components=components,
            **{key: tuple(arrays) for key, arrays in per.items()},
            names=names,
            estimates=_from_nested("estimates", data["estimates"], (n_p,)),
            covariance=_from_nested("covariance", data["covariance"], (n_p, n_p)),
            dof=float(data["dof"]),
            s2=float("nan") if s2 is None else float(s2),
            smoothing=float(data.get("smoothing", 0.0)),
            min_weight=float(data.get("min_weight", 1.0)),
        )


def _check_fit_options(
    smoothing: float, min_weight: float, first: str = "smoothing"
) -> tuple[float, float]:
    """Both options as floats: non-negative finite numbers (else ``TableError``); ``first``
    is the first one's name."""
    for name, value in ((first, smoothing), ("min_weight", min_weight)):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise TableError(f"{name}: expected a non-negative number, got {describe(value)}")
        if not (math.isfinite(value) and value >= 0):
            raise TableError(f"{name}: expected a non-negative finite number, got {value!r}")
    return float(smoothing), float(min_weight)


def _component_units(
    components: Sequence[TableComponent], names: Sequence[str], units: Mapping[str, str] | None
) -> dict[str, str]:
    """{parameter: unit} from {component label: unit of its values}."""
    if not units:
        return {}
    labels = [c.label for c in components]
    unknown = sorted(set(units) - set(labels))
    if unknown:
        raise TableError(f"units: expected component labels from {labels}, got {unknown}")
    return {
        name: str(units[name.rpartition("[")[0]])
        for name in names
        if name.rpartition("[")[0] in units
    }


def fit_table_model(
    z: Any,
    components: Sequence[TableComponent] | TableComponent,
    signals: Mapping[str, Any],
    *,
    smoothing: float = 0.0,
    min_weight: float = 1.0,
    maneuver_index: Any = None,
    units: Mapping[str, str] | None = None,
    sigma2_max: float | None = None,
) -> TableFit:
    """Fit a sum of tables to a response (module docstring: basis, identifiability, fit).

    Args:
        z: the response (N,), e.g. a force or moment coefficient.
        components: the tables (``TableComponent``), in order.
        signals: {name: series (N,)} with every variable and ``times`` signal.
        smoothing: λ ≥ 0. 0: basis functions with data weight below ``min_weight`` are
            dropped (values NaN, flagged ``dropped``). λ > 0: every value is kept; the cost
            gains λ‖Dθ‖² (second differences along each axis), which fills values without
            data (flagged ``filled``).
        min_weight: data weight Σ_i Φ_j(x_i) below which a value has no data.
        maneuver_index: (N,) maneuver of each sample (the coloured σ never pairs samples of
            different maneuvers).
        units: {component label (``"alpha:de"``, ``"qhat*alpha"``): unit of its values}.
        sigma2_max: σ²_max of PSE (default: the variance of z).

    Returns:
        ``TableFit``.
    """
    components = _checked_components(components)
    smoothing, min_weight = _check_fit_options(smoothing, min_weight)
    if sigma2_max is not None:
        _check_fit_options(sigma2_max, 0.0, "sigma2_max")
    data = _check_signals(signals, _signal_names(components))
    n = next(iter(data.values())).size
    z = _series("z", z, n)
    B_full, labels_full, weights, penalty, fixed = _design(components, data)
    keep = ~fixed
    without_data = (weights < min_weight) & keep
    if smoothing == 0.0:
        keep &= ~without_data
    names = tuple(labels_full[j] for j in np.flatnonzero(keep))
    if not names:
        raise TableError(
            f"table: no basis function has a data weight ≥ min_weight = {min_weight}; the data "
            f"lie outside every table"
        )
    has_constant = any(c.times is None for c in components)
    unit_map = _component_units(components, names, units)
    if maneuver_index is not None:
        maneuver_index = np.asarray(maneuver_index)
        if maneuver_index.shape != (n,):
            raise TableError(
                f"maneuver_index: expected one entry per sample ({n}), got shape "
                f"{maneuver_index.shape}"
            )
    B = B_full[:, keep]
    if smoothing > 0.0:
        D = penalty[:, keep]
        D = D[np.any(D != 0, axis=1)]
        fit = _smoothed_fit(
            B, z, D, smoothing, names, has_constant=has_constant, sigma2_max=sigma2_max,
            units=unit_map, maneuver_index=maneuver_index,
        )  # fmt: skip
    else:
        fit = _plain_fit(B, z, names, has_constant, sigma2_max, unit_map, maneuver_index)
    return _table_fit(components, fit, keep, without_data, smoothing, min_weight)


def _design(components: tuple[TableComponent, ...], data: Mapping[str, np.ndarray]):
    """Every basis column (N, n_all) with times, labels, data weights, the block-diagonal
    penalty (m, n_all), and the mask of fixed first functions."""
    columns, labels, weights, penalties, fixed = [], [], [], [], []
    for component, first_fixed in zip(components, _fixed_first(components), strict=True):
        raw = _raw_component_basis(component, data)
        # w_j = Σ_i Φ_j(x_i)
        weights.append(raw.sum(axis=0))
        if component.times is not None:
            raw = raw * data[component.times][:, None]
        columns.append(raw)
        labels += _component_labels(component)
        penalties.append(_component_penalty(component))
        mask = np.zeros(raw.shape[1], dtype=bool)
        mask[0] = first_fixed
        fixed.append(mask)
    n_all = sum(c.shape[1] for c in columns)
    penalty = np.zeros((sum(p.shape[0] for p in penalties), n_all))
    row = col = 0
    for block in penalties:
        penalty[row : row + block.shape[0], col : col + block.shape[1]] = block
        row, col = row + block.shape[0], col + block.shape[1]
    return (
        np.hstack(columns),
        labels,
        np.concatenate(weights),
        penalty,
        np.concatenate(fixed),
    )


def _plain_fit(B, z, names, has_constant, sigma2_max, units, maneuver_index):
    """``least_squares`` on the kept columns; R² about the mean when the tables hold the
    constant (the hat functions sum to 1, though no single column is constant)."""
    try:
        fit = least_squares(
            B, z, names, sigma2_max=sigma2_max, units=units or None,
            maneuver_index=maneuver_index,
        )  # fmt: skip
    except LeastSquaresError as error:
        raise TableError(
            f"table: the data do not determine the table values ({error}); add data, remove "
            f"breakpoints or fill empty cells with smoothing > 0"
        ) from error
    if has_constant and not fit.has_constant:
        # TSS = Σ (z − z̄)²
        fit = dataclasses.replace(fit, has_constant=True, tss=float(np.sum((z - z.mean()) ** 2)))
    return fit


def _table_fit(components, fit, keep, without_data, smoothing, min_weight) -> TableFit:
    """Scatter θ̂ and its covariance back onto each component's grids."""
    n_all = keep.size
    # fixed first functions stay 0, dropped ones become NaN
    theta_all = np.zeros(n_all)
    cov_all = np.zeros((n_all, n_all))
    kept = np.flatnonzero(keep)
    theta_all[kept] = fit.estimates
    cov_all[np.ix_(kept, kept)] = fit.covariance_default
    dropped_all = without_data & ~keep
    theta_all[dropped_all] = np.nan
    coefficients, values, value_std, filled, dropped = [], [], [], [], []
    start = 0
    for component in components:
        size = int(np.prod(component.basis_shape))
        part = slice(start, start + size)
        start += size
        theta = theta_all[part]
        coefficients.append(_readonly(theta.reshape(component.basis_shape)))
        # values at the breakpoints: v = E θ, E the basis at the breakpoint grid
        E = _grid_basis(component)
        lost = np.any(E[:, dropped_all[part]] != 0, axis=1)
        value = E @ np.nan_to_num(theta, nan=0.0)
        value[lost] = np.nan
        # Cov(v) = E Cov(θ) Eᵀ
        variance = np.einsum("gi,ij,gj->g", E, cov_all[part, part], E)
        std = np.sqrt(np.maximum(variance, 0.0))
        std[lost] = np.nan
        shape = component.grid_shape
        values.append(_readonly(value.reshape(shape)))
        value_std.append(_readonly(std.reshape(shape)))
        smoothed = np.any(E[:, (without_data & keep)[part]] != 0, axis=1)
        filled.append(_readonly_bool(smoothed.reshape(shape)))
        dropped.append(_readonly_bool(lost.reshape(shape)))
    return TableFit(
        components=tuple(components),
        coefficients=tuple(coefficients),
        values=tuple(values),
        value_std=tuple(value_std),
        filled=tuple(filled),
        dropped=tuple(dropped),
        names=tuple(fit.names),
        estimates=fit.estimates,
        covariance=fit.covariance_default,
        dof=float(fit.dof),
        s2=float(fit.s2),
        smoothing=smoothing,
        min_weight=min_weight,
        fit=fit,
    )


def _readonly_bool(array: np.ndarray) -> np.ndarray:
    out = np.array(array, dtype=bool)
    out.flags.writeable = False
    return out


def _grid_basis(component: TableComponent) -> np.ndarray:
    """The component's basis at every breakpoint-grid point (n_grid, n_c), C order."""
    mesh = np.meshgrid(*(component.breakpoints[v] for v in component.variables), indexing="ij")
    points = {v: m.ravel() for v, m in zip(component.variables, mesh, strict=True)}
    return _raw_component_basis(component, points)


# ------------------------------------------------------------------------ breakpoints


def auto_breakpoints(x: Any, n: int) -> np.ndarray:
    """n breakpoints at the data quantiles of x, rounded, unique (possibly fewer than n).

    The quantiles at 0, 1/(n−1), …, 1 are rounded to two significant digits of the mean
    spacing (max − min)/(n − 1); the first is rounded down and the last up, so every sample
    lies inside the table; coinciding values are merged.

    Args:
        x: samples of the variable (N,).
        n: number of breakpoints wanted, ≥ 2.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
        raise TableError(f"n: expected an integer number of breakpoints ≥ 2, got {n!r}")
    x = _series("x", x)
    low, high = (float(x.min()), float(x.max())) if x.size else (0.0, 0.0)
    if not high > low:
        raise TableError(
            f"x: expected samples spread over an interval to place breakpoints, got "
            f"{x.size} samples in [{low}, {high}]"
        )
    quantiles = np.quantile(x, np.linspace(0.0, 1.0, int(n)))
    spacing = (high - low) / (int(n) - 1)
    # two significant digits of the spacing: a resolution of 10^(floor(log10 spacing) − 1)
    decimals = 1 - math.floor(math.log10(spacing))
    resolution = 10.0 ** (-decimals)
    rounded = np.round(quantiles, decimals)
    first = math.floor(low / resolution) * resolution
    last = math.ceil(high / resolution) * resolution
    # the multiplication can land one ulp inside the data: step out by one resolution then
    first = first if first <= low else first - resolution
    last = last if last >= high else last + resolution
    rounded[0], rounded[-1] = round(first, decimals), round(last, decimals)
    rounded = np.clip(rounded, rounded[0], rounded[-1])
    return np.unique(rounded)


@dataclass(frozen=True, eq=False)
class BreakpointChoice:
    """Breakpoints of one variable chosen by the predicted squared error.

    Attributes:
        variable: the variable.
        breakpoints: the chosen breakpoints.
        counts: the breakpoint counts tried.
        pse: PSE of the fit with each count (inf where that fit failed: ``errors``).
        errors: {count: the failure's message} for the counts whose fit failed.
    """

    variable: str
    breakpoints: np.ndarray
    counts: tuple[int, ...]
    pse: tuple[float, ...]
    errors: Mapping[int, str] = field(default_factory=dict)


def choose_breakpoints(
    z: Any,
    variable: str,
    signals: Mapping[str, Any],
    counts: Sequence[int] = range(3, 13),
    *,
    others: Sequence[TableComponent] = (),
    times: str | None = None,
    degree: int = 1,
    smoothing: float = 0.0,
    min_weight: float = 1.0,
    maneuver_index: Any = None,
    sigma2_max: float | None = None,
) -> BreakpointChoice:
    """The count of ``auto_breakpoints`` for ``variable`` with the least PSE.

    For each count n the model ``others + [TableComponent((variable,), auto_breakpoints(x,
    n), times, degree)]`` is fitted (``fit_table_model``) and its PSE = RSS/N + σ²_max n_p/N
    (edf for n_p with smoothing) compared, with one σ²_max for all counts (default: the
    variance of z), so more breakpoints must pay for themselves in fit error.

    Args:
        z: the response (N,).
        variable: the variable whose breakpoints are chosen.
        signals: {name: series} with every variable and ``times`` signal.
        counts: breakpoint counts to try (each ≥ 2).
        others: further tables fitted with it (fixed breakpoints).
        times: the new table's multiplying signal (``TableComponent``).
        degree: the new table's degree (``TableComponent``).
        smoothing: as ``fit_table_model``.
        min_weight: as ``fit_table_model``.
        maneuver_index: as ``fit_table_model``.
        sigma2_max: σ²_max of PSE.
    """
    counts = tuple(int(c) for c in counts)
    if not counts:
        raise TableError("counts: expected at least one breakpoint count, got none")
    data = _check_signals(signals, [variable])
    z = _series("z", z, data[variable].size)
    if sigma2_max is None:
        # σ²_max = mean((z − z̄)²): the same for every count
        sigma2_max = float(np.mean((z - z.mean()) ** 2))
    pse, errors, candidates = [], {}, []
    for count in counts:
        breakpoints = auto_breakpoints(data[variable], count)
        candidates.append(breakpoints)
        component = TableComponent((variable,), {variable: breakpoints}, times, degree)
        try:
            fit = fit_table_model(
                z, [*others, component], signals, smoothing=smoothing,
                min_weight=min_weight, maneuver_index=maneuver_index, sigma2_max=sigma2_max,
            )  # fmt: skip
        except TableError as error:
            errors[count] = str(error)
            pse.append(float("inf"))
            continue
        pse.append(float(fit.fit.pse))
    if not np.isfinite(pse).any():
        raise TableError(
            f"choose_breakpoints: no breakpoint count of {list(counts)} for {variable!r} gave a "
            f"fit: {errors}"
        )
    best = int(np.argmin(pse))
    return BreakpointChoice(variable, candidates[best], counts, tuple(pse), errors)
