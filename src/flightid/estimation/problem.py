"""The output-error problem: a model, its maneuvers, and the measured outputs.

Residuals and cost (RP-1153 §6):

    ν_i  = z_i − y_i(θ)                               (n_o residuals at sample i)
    J(θ) = Σ_i ν_iᵀ R⁻¹ ν_i                           [3.46]
    R̂    = diag( (1/N) Σ_i ν_i ν_iᵀ )                 [3.45]

The estimation works on the vector of *free* parameters in their own units; ``typical``
(from each parameter's ``scale``, or its start value) scales them for the linear algebra and
sets the floor of the relative convergence tests.

Multiple shooting (``flightid.model.unstable.with_multiple_shooting``): the simulator returns
continuity defects d beside the outputs; they enter as extra rows after the N data rows,
measured 0 and "simulated" −√w·d in the column of the output that weights the state, so the
cost and the Gauss–Newton step of every solver see J = Σ νᵀR⁻¹ν + Σ w d²/R_s unchanged in
form. ``n_data`` is N; R̂ comes from the data rows only.

Sample weights (``set_weights``): a weight w_ik ∈ [0, 1] per data sample and output scales
its residual and its sensitivities by √w_ik — ``run`` returns y' = y + (1 − √w)(z − y), so
z − y' = √w (z − y) and ∂y'/∂θ = √w ∂y/∂θ for every consumer of the outputs — so that
J = Σ_i Σ_k w_ik ν_ik² / R_kk and M = Σ_i G_iᵀ W_i R⁻¹ G_i; a zero weight removes the
measurement from the cost, the information matrix and R̂ = Σ_i w_ik ν_ik² / Σ_i w_ik, and
from N (``n_measurements``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from flightid.data.flightdata import FlightData
from flightid.errors import FlightIdError, InputError, ModelError, SimulationError
from flightid.model.binding import as_data_list
from flightid.model.statespace import StateSpaceModel
from flightid.simulation.simulator import SimulationBatch, Simulator

__all__ = ["OutputErrorProblem", "FiniteDifferences", "estimate_noise_covariance"]

# Outputs of the perturbed integrations held at once while differencing (bytes): the
# perturbations run in batches of this size and are differenced straight into G, so the
# sensitivities cost G plus about this much, never G plus all perturbed outputs (at N = 10⁵,
# 8 outputs: 2 trajectories of 6.4 MB per batch).
DIFFERENCE_BATCH_BYTES = 16 * 2**20


@dataclass(frozen=True)
class FiniteDifferences:
    """Finite-difference sensitivities at θ and how they were taken.

    Attributes:
        g: G (N, n_o, n_f), a view of an (n_f, N, n_o) array (each parameter's column
            contiguous).
        outputs: y(θ) (N, n_o).
        theta: the free parameters θ (n_f,).
        steps: the step δ_j of each parameter (signed; after any retries).
        central: central differences (else one-sided).
        plain: every δ_j is the positive relative step (no bound turned it, no diverging
            perturbation shortened it) and the problem has no bounds — forward differences
            that ``OutputErrorProblem.complete_central`` can complete.
    """

    g: np.ndarray
    outputs: np.ndarray
    theta: np.ndarray
    steps: np.ndarray
    central: bool
    plain: bool


def estimate_noise_covariance(residuals: np.ndarray, floor: np.ndarray | None = None) -> np.ndarray:
    """Diagonal of R̂ = (1/N) Σ ν_i ν_iᵀ [3.45], bounded below by ``floor``.

    Args:
        residuals: (N, n_o) residuals.
        floor: (n_o,) smallest admissible variances (keeps R̂ positive for noise-free data).
    Returns:
        (n_o,) variances in the outputs' units squared.
    """
    r_diag = np.mean(residuals**2, axis=0)
    if floor is not None:
        r_diag = np.maximum(r_diag, floor)
    return r_diag


class OutputErrorProblem:
    """Everything an optimizer needs: simulate, residuals, cost, sensitivities.

    Args:
        model: the state-space model; its free parameters are estimated.
        data: one ``FlightData`` or a list (maneuvers); each must have the model's output
            channels (as outputs) and input channels (as inputs or outputs).
        method: ``"rk4"`` or ``"euler"``.
        compiled: use the numba kernel.
        input_interpolation: the input between samples in the RK4 stages, ``"linear"``
            (default) or ``"zoh"`` (zero-order hold); see ``flightid.simulation.Simulator``.
    """

    def __init__(
        self,
        model: StateSpaceModel,
        data: FlightData | Sequence[FlightData],
        method: str = "rk4",
        compiled: bool = True,
        input_interpolation: str = "linear",
    ) -> None:
        self.model = model
        self.maneuvers = as_data_list(data)
        for i, maneuver in enumerate(self.maneuvers):
            missing = [n for n in model.outputs if n not in maneuver.output_names]
            if missing:
                raise InputError(
                    f"data[{i}] ({maneuver.name or 'unnamed'}): the model's outputs {missing} "
                    f"are not output channels of the data (outputs {list(maneuver.output_names)})"
                )
        self.simulator = Simulator(
            model,
            self.maneuvers,
            method=method,
            compiled=compiled,
            input_interpolation=input_interpolation,
        )
        self.input_interpolation = self.simulator.input_interpolation
        self.measured = np.concatenate(
            [np.column_stack([m.output(n) for n in model.outputs]) for m in self.maneuvers]
        )
        self.time = np.concatenate([m.time for m in self.maneuvers])
        self.maneuver_index = np.concatenate(
            [np.full(m.n_samples, i) for i, m in enumerate(self.maneuvers)]
        )
        parameters = model.parameters
        self.free_mask = parameters.free_mask
        if not self.free_mask.any():
            raise InputError("model.parameters: no parameter is free; nothing to estimate")
        self.free_index = np.flatnonzero(self.free_mask)
        self.theta_start_full = parameters.values
        self.free_names = parameters.free_names
        # Magnitude floor of each free parameter: its ``scale`` when given, else 1e-3. Relative
        # steps, perturbations and tests use max(|θ_j|, floor_j) at the *current* θ, so a start
        # value of 0 does not collapse them and one of 1e12 does not inflate them later.
        self.typical = np.array(
            [1e-3 if p.scale is None else float(p.scale) for p in parameters if p.free]
        )
        # Bounds of the free parameters (±inf when open); every solver keeps θ inside them.
        self.lower = np.array([p.lower for p in parameters if p.free], dtype=float)
        self.upper = np.array([p.upper for p in parameters if p.free], dtype=float)
        # Floor of R̂: 1e-12 of each output's variance about its mean (at least 1e-30), so that
        # noise-free data do not give a zero variance; documented in docs/method.md.
        spread = np.var(self.measured, axis=0)
        self.r_floor = np.maximum(1e-12 * spread, 1e-30)
        # data rows; multiple shooting appends one row per continuity defect (module docstring)
        self.n_data = int(self.measured.shape[0])
        n_defects = self.simulator.n_defects
        if n_defects:
            names = getattr(model, "shooting_outputs", ())
            n_states = len(model.states)
            # the defect of state s goes to the column of the output that weights it
            self._defect_columns = np.array(
                [model.outputs.index(names[c % n_states]) for c in range(n_defects)]
            )
            self._defect_scale = float(np.sqrt(model.shooting_weight))
            self.measured = np.vstack([self.measured, np.zeros((n_defects, self.n_outputs))])
        # √w per row and output (N + defect rows, n_o); None: every weight 1 (set_weights)
        self.root_weights: np.ndarray | None = None

    def set_weights(self, weights: np.ndarray | None) -> None:
        """Weights w ∈ [0, 1] of the data samples, (N,) or (N, n_o); None: all 1.

        A zero weight excludes a measurement from the cost, the sensitivities and R̂; a weight
        in (0, 1) down-weights it (module docstring). Every output keeps at least one sample
        of positive weight.
        """
        if weights is None:
            self.root_weights = None
            return
        w = np.asarray(weights, dtype=float)
        if w.ndim == 1 and w.shape[0] == self.n_data:
            w = np.repeat(w[:, None], self.n_outputs, axis=1)
        if w.shape != (self.n_data, self.n_outputs):
            raise InputError(
                f"weights: expected ({self.n_data},) or ({self.n_data}, {self.n_outputs}) "
                f"weights (samples × outputs), got shape {w.shape}"
            )
        if not np.all(np.isfinite(w)) or np.any(w < 0.0) or np.any(w > 1.0):
            raise InputError("weights: expected finite weights between 0 and 1")
        if np.any(np.all(w == 0.0, axis=0)):
            empty = [n for n, c in zip(self.model.outputs, w.T, strict=True) if not c.any()]
            raise InputError(f"weights: every sample of the outputs {empty} has weight 0")
        root = np.ones_like(self.measured)
        root[: self.n_data] = np.sqrt(w)
        self.root_weights = root

    @property
    def weights(self) -> np.ndarray | None:
        """The data rows' weights (N, n_o), or None when all are 1."""
        if self.root_weights is None:
            return None
        return self.root_weights[: self.n_data] ** 2

    @property
    def n_measurements(self) -> int:
        """Scalar measurements that enter the cost: N·n_o less those of weight 0."""
        if self.root_weights is None:
            return self.n_data * self.n_outputs
        return int(np.count_nonzero(self.root_weights[: self.n_data]))

    def _weighted(self, outputs: np.ndarray) -> np.ndarray:
        """y' = y + (1 − √w)·(z − y) of outputs (…, rows, n_o), in place: z − y' = √w·(z − y)
        and ∂y'/∂θ = √w·∂y/∂θ; a weight of 1 leaves y exactly, NaN (divergence) stays NaN."""
        outputs += (1.0 - self.root_weights) * (self.measured - outputs)
        return outputs

    def model_outputs(self, theta_free: np.ndarray) -> np.ndarray:
        """The model's own outputs y(θ) (N, n_o) at the data rows, without the weights."""
        full = self.full_theta(np.asarray(theta_free, dtype=float)[None, :])
        return self.simulator.run(full).outputs[0][: self.n_data]

    def check_enough_data(self) -> None:
        """Refuse a record with no more scalar measurements N·n_o than free parameters n_f:
        the residual variance s² = J(θ̂)/(N·n_o − n_f) [5.30], and with it every accuracy
        measure, needs N·n_o > n_f (an estimate on fewer is a fit through the points)."""
        measurements = self.n_measurements
        if measurements <= self.n_free:
            raise InputError(
                f"data: {self.n_data} samples × {self.n_outputs} outputs = {measurements} "
                f"scalar measurements for {self.n_free} free parameters; an estimate needs "
                "more measurements than free parameters (N·n_o > n_f): give a longer record "
                "or fix parameters"
            )

    # ------------------------------------------------------------------ sizes
    @property
    def n_free(self) -> int:
        return int(self.free_index.size)

    @property
    def n_samples(self) -> int:
        return int(self.measured.shape[0])

    @property
    def n_outputs(self) -> int:
        return int(self.measured.shape[1])

    @property
    def evaluations(self) -> int:
        """System integrations done so far (the paper's equivalent evaluations)."""
        return self.simulator.evaluations

    # ------------------------------------------------------------------ vectors
    @property
    def theta_start(self) -> np.ndarray:
        """Free parameters' start values."""
        return self.theta_start_full[self.free_index].copy()

    def full_theta(self, theta_free: np.ndarray) -> np.ndarray:
        """Full parameter vector(s) with the free entries replaced; accepts (n_f,) or (B, n_f)."""
        theta_free = np.asarray(theta_free, dtype=float)
        if theta_free.shape[-1] != self.n_free:
            raise InputError(
                f"theta_free: expected {self.n_free} free parameters {self.free_names}, "
                f"got shape {theta_free.shape}"
            )
        full = np.broadcast_to(
            self.theta_start_full, theta_free.shape[:-1] + self.theta_start_full.shape
        ).copy()
        full[..., self.free_index] = theta_free
        return full

    @property
    def bounded(self) -> bool:
        """True if any free parameter has a finite bound."""
        return bool(np.any(np.isfinite(self.lower)) or np.any(np.isfinite(self.upper)))

    def magnitude(self, theta_free: np.ndarray) -> np.ndarray:
        """max(|θ_j|, floor_j): the size relative steps and tests refer to."""
        return np.maximum(np.abs(np.asarray(theta_free, dtype=float)), self.typical)

    def project(self, theta_free: np.ndarray) -> np.ndarray:
        """θ clipped into [lower, upper] (the projection onto the box of bounds)."""
        return np.clip(theta_free, self.lower, self.upper)

    def at_bound(self, theta_free: np.ndarray, tolerance: float = 1e-10) -> np.ndarray:
        """(n_f,) mask of parameters lying on a bound (within ``tolerance`` relative)."""
        theta_free = np.asarray(theta_free, dtype=float)
        slack = tolerance * self.magnitude(theta_free)
        return (theta_free <= self.lower + slack) | (theta_free >= self.upper - slack)

    # ------------------------------------------------------------------ evaluations
    def run(self, theta_free_batch: np.ndarray) -> SimulationBatch:
        """Simulate a batch (B, n_f) of free-parameter vectors: B equivalent evaluations.

        An exception raised inside the user's f or h (after the start-value check passed,
        e.g. a domain error at parameter values the search reached) becomes a ``ModelError``
        naming the exception and the parameter values, never a bare traceback.
        """
        full = self.full_theta(np.atleast_2d(theta_free_batch))
        try:
            batch = self._with_defect_rows(self.simulator.run(full))
            if self.root_weights is not None:
                # the weighted outputs y' (module docstring): every consumer of the outputs —
                # cost, R̂, finite differences, response surfaces — sees the weighted problem
                self._weighted(batch.outputs)
            return batch
        except FlightIdError:
            raise
        except Exception as exc:
            values = ", ".join(
                f"{name} = {value:.6g}"
                for name, value in zip(self.model.parameters.names, full[0], strict=True)
            )
            raise ModelError(
                f"the model functions f/h raised {type(exc).__name__}: {exc} while simulating "
                f"at parameter values ({values}){' (first of the batch)' if len(full) > 1 else ''}"
            ) from exc

    def _with_defect_rows(self, batch: SimulationBatch) -> SimulationBatch:
        """The outputs with the multiple-shooting defect rows appended (none: unchanged)."""
        if batch.defects is None:
            return batch
        n_batch, n_defects = batch.defects.shape
        rows = np.zeros((n_batch, n_defects, self.n_outputs))
        # row c: −√w·d_c in the column of its state's output, so ν = z − y = √w·d_c
        rows[:, np.arange(n_defects), self._defect_columns] = -self._defect_scale * batch.defects
        outputs = np.concatenate([batch.outputs, rows], axis=1)
        return SimulationBatch(outputs, batch.diverged, batch.messages, batch.defects)

    def outputs(self, theta_free_batch: np.ndarray) -> np.ndarray:
        """Model outputs (B, N, n_o); NaN rows where a trajectory diverged."""
        return self.run(theta_free_batch).outputs

    def residuals(self, outputs: np.ndarray) -> np.ndarray:
        """ν = z − y for outputs of shape (N, n_o) or (B, N, n_o); with weights the outputs
        are the weighted y' of ``run``, so that ν = √w·(z − y)."""
        return self.measured - outputs

    def cost(self, outputs: np.ndarray, r_diag: np.ndarray) -> np.ndarray | float:
        """J = Σ_i ν_iᵀ R⁻¹ ν_i [3.46] for (N, n_o) or (B, N, n_o) outputs; inf if non-finite."""
        nu = self.residuals(outputs)
        # J = Σ_i Σ_k ν_ik² / R_kk
        cost = np.einsum("...ik,...ik,k->...", nu, nu, 1.0 / r_diag)
        return np.where(np.isfinite(cost), cost, np.inf)

    def noise_covariance(self, outputs: np.ndarray) -> np.ndarray:
        """R̂ diagonal [3.45] from the residuals of (N, n_o) outputs (data rows only)."""
        nu = self.residuals(outputs)[..., : self.n_data, :]
        if self.root_weights is None:
            return estimate_noise_covariance(nu, self.r_floor)
        # R̂_k = Σ_i w_ik ν_ik² / Σ_i w_ik
        total = np.sum(self.root_weights[: self.n_data] ** 2, axis=0)
        return np.maximum(np.sum(nu**2, axis=-2) / total, self.r_floor)

    def sensitivities(
        self,
        theta_free: np.ndarray,
        outputs: np.ndarray | None = None,
        relative_step: float = 1e-6,
        central: bool = False,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Output sensitivities G_i = ∂y_i/∂θ by finite differences.

        Forward differences cost n_f integrations (plus one if ``outputs`` at ``theta_free``
        is not given); central differences cost 2·n_f. Steps are
        ``relative_step · max(|θ_j|, typical_j)``. The perturbed integrations run in batches
        of at most ``DIFFERENCE_BATCH_BYTES`` of outputs, each differenced straight into G.

        Returns:
            (G of shape (N, n_o, n_f), outputs at theta_free of shape (N, n_o)).
        """
        differences = self.differences(theta_free, outputs, relative_step, central)
        return differences.g, differences.outputs

    @property
    def finite_differences(self) -> bool:
        """Whether ``sensitivities`` are this class's finite differences of ``run`` (a
        subclass with sensitivities of its own, e.g. analytic ones, says False)."""
        return type(self).sensitivities is OutputErrorProblem.sensitivities

    def differences(
        self,
        theta_free: np.ndarray,
        outputs: np.ndarray | None = None,
        relative_step: float = 1e-6,
        central: bool = False,
    ) -> FiniteDifferences:
        """``sensitivities`` with the record of how they were taken (``FiniteDifferences``)."""
        theta_free = np.asarray(theta_free, dtype=float)
        steps = relative_step * self.magnitude(theta_free)
        if self.bounded:
            # a parameter on (or within one step of) its upper bound is differenced downwards;
            # central differences there become one-sided below
            downwards = theta_free + steps > self.upper
            steps = np.where(downwards, -steps, steps)
            if central and np.any(downwards | (theta_free - np.abs(steps) < self.lower)):
                central = False
        if central:
            columns = self._central_columns(theta_free, steps)
            if columns is None:
                # near the edge of stability: one-sided differences, which retry smaller
                return self.differences(theta_free, outputs, relative_step, central=False)
            if outputs is None:
                outputs = self.outputs(theta_free[None, :])[0]
            plain = True
        else:
            if outputs is None:
                sim = self.run(theta_free[None, :])
                self._raise_if_diverged(sim, "sensitivities")
                outputs = sim.outputs[0]
            plain_steps = steps.copy()
            columns = self._forward_columns(theta_free, outputs, steps)
            plain = bool(np.array_equal(steps, plain_steps)) and not self.bounded
        return FiniteDifferences(
            np.moveaxis(columns, 0, -1), outputs, theta_free.copy(), steps, central, plain
        )

    def _batches(self, n_rows: int, trajectories_per_row: int = 1):
        """Slices of rows whose integrations fit ``DIFFERENCE_BATCH_BYTES`` of outputs."""
        trajectory = max(self.n_samples * self.n_outputs * 8 * trajectories_per_row, 1)
        per_batch = max(1, DIFFERENCE_BATCH_BYTES // trajectory)
        for start in range(0, n_rows, per_batch):
            yield slice(start, min(start + per_batch, n_rows))

    def _central_columns(self, theta_free: np.ndarray, steps: np.ndarray) -> np.ndarray | None:
        """(n_f, N, n_o): G_j = (y(θ + δ_j e_j) − y(θ − δ_j e_j)) / (2 δ_j); None if a
        perturbed integration diverges."""
        columns = np.empty((self.n_free, self.n_samples, self.n_outputs))
        eye = np.diag(steps)
        for rows in self._batches(self.n_free, 2):
            sim = self.run(np.vstack([theta_free + eye[rows], theta_free - eye[rows]]))
            if sim.diverged.any():
                return None
            count = rows.stop - rows.start
            plus, minus = sim.outputs[:count], sim.outputs[count:]
            # G_j = (y(θ + δ_j e_j) − y(θ − δ_j e_j)) / (2 δ_j)
            np.subtract(plus, minus, out=columns[rows])
            columns[rows] /= 2.0 * steps[rows, None, None]

        return columns

    def _forward_columns(
        self, theta_free: np.ndarray, outputs: np.ndarray, steps: np.ndarray
    ) -> np.ndarray:
        """(n_f, N, n_o): G_j = (y(θ + δ_j e_j) − y(θ)) / δ_j; ``steps`` is updated in place
        where a diverging perturbation was retried."""
        columns = np.empty((self.n_free, self.n_samples, self.n_outputs))
        diverged = np.zeros(self.n_free, dtype=bool)
        messages = [""] * self.n_free

        def perturb(rows: np.ndarray) -> None:
            for batch in self._batches(rows.size):
                chosen = rows[batch]
                sim = self.run(theta_free + np.diag(steps)[chosen])
                # y(θ + δ_j e_j) − y(θ), divided by δ_j below
                np.subtract(sim.outputs, outputs, out=sim.outputs)
                columns[chosen] = sim.outputs
                diverged[chosen] = sim.diverged
                for row, message in zip(chosen, sim.messages, strict=True):
                    messages[row] = message

        perturb(np.arange(self.n_free))
        # a perturbed simulation that diverges is retried the other way, then 10× and
        # 100× smaller (within the bounds), before the sensitivities are given up
        first_steps = steps.copy()
        for factor in (-1.0, 0.1, -0.1, 0.01, -0.01):
            bad = np.flatnonzero(diverged)
            if bad.size == 0:
                break
            retry = factor * first_steps[bad]
            moved = theta_free[bad] + retry
            inside = (moved >= self.lower[bad]) & (moved <= self.upper[bad])
            if not inside.any():
                continue
            bad, retry = bad[inside], retry[inside]
            steps[bad] = retry
            perturb(bad)
        if diverged.any():
            first = int(np.flatnonzero(diverged)[0])
            raise SimulationError(f"sensitivities: {messages[first]}")
        # G_j = (y(θ + δ_j e_j) − y(θ)) / δ_j
        columns /= steps[:, None, None]
        return columns

    def complete_central(self, forward: FiniteDifferences) -> FiniteDifferences | None:
        """Central differences from forward ones: n_f integrations instead of 2·n_f.

        With G⁺_j = (y(θ + δ_j e_j) − y(θ))/δ_j given, the backward quotients
        G⁻_j = (y(θ) − y(θ − δ_j e_j))/δ_j complete the central difference

            (G⁺_j + G⁻_j)/2 = (y(θ + δ_j e_j) − y(θ − δ_j e_j)) / (2 δ_j)

        (equal to rounding in the differences). ``forward.g`` is overwritten in place (no
        second G is allocated). Only for ``forward.plain`` differences (every δ_j the positive
        relative step, no bounds). Returns None if a backward integration diverges; the
        contents of ``forward.g`` are then undefined (partly completed) and must not be used.
        """
        if not forward.plain or forward.central:
            raise InputError("complete_central: needs plain forward differences")
        columns = np.moveaxis(forward.g, -1, 0)  # (n_f, N, n_o), the array differenced into
        theta, steps, outputs = forward.theta, forward.steps, forward.outputs
        eye = np.diag(steps)
        for rows in self._batches(self.n_free):
            sim = self.run(theta - eye[rows])
            if sim.diverged.any():
                return None
            minus = sim.outputs
            # G⁻_j δ_j = y(θ) − y(θ − δ_j e_j);  G_j = (G⁺_j + G⁻_j)/2
            np.subtract(outputs, minus, out=minus)
            minus /= steps[rows, None, None]

            columns[rows] += minus
            columns[rows] *= 0.5
        return FiniteDifferences(forward.g, outputs, theta, steps, True, True)

    def sensitivities_from_equations(
        self, theta_free: np.ndarray, relative_step: float = 1e-7
    ) -> tuple[np.ndarray, np.ndarray]:
        """G_i and outputs at ``theta_free`` from the integrated sensitivity equations
        (1 + n_s + n_f equivalent evaluations; see ``flightid.simulation.sensitivity``).

        Returns:
            (G of shape (N, n_o, n_f), outputs of shape (N, n_o)).
        """
        theta_free = np.asarray(theta_free, dtype=float)
        if self.simulator.n_defects:
            # multiple shooting: the defect rows have no sensitivity equations; differences
            return self.sensitivities(theta_free)
        steps = relative_step * self.magnitude(theta_free)
        outputs, g = self.simulator.run_with_sensitivities(
            self.full_theta(theta_free), self.free_index, steps, relative_step
        )
        if self.root_weights is not None:
            # the weighted outputs y' and their sensitivities √w·∂y/∂θ (module docstring)
            outputs = self._weighted(outputs)
            g = g * self.root_weights[:, :, None]
        return g, outputs

    @staticmethod
    def _raise_if_diverged(sim: SimulationBatch, what: str) -> None:
        if sim.diverged.any():
            first = int(np.flatnonzero(sim.diverged)[0])
            raise SimulationError(f"{what}: {sim.messages[first]}")
