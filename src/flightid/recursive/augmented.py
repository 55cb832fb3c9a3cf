"""The augmented state x_a = (x, θ_free) of a flightid state-space model, for online estimation.

Recursive estimators treat the unknown parameters as states that do not change
(Jategaonkar, *Flight Vehicle System Identification*, 2nd ed., ch. 7):

    ẋ_a = f_a(x_a, u) = ( f(x, u, θ), 0 ),   θ = θ_fixed ∪ θ_free,  θ̇_free = 0
    y   = g(x_a, u)   = h(x, u, θ)

and propagate x_a over one sample interval by the classical fixed-step fourth-order
Runge–Kutta scheme (RK4), with the input at the half step taken as the mean of the two
neighbouring samples:

    ū = (u_k + u_{k+1})/2
    k1 = f(x_k, u_k)            k2 = f(x_k + (dt/2)·k1, ū)
    k3 = f(x_k + (dt/2)·k2, ū)  k4 = f(x_k + dt·k3, u_{k+1})
    x_{k+1} = x_k + (dt/6)·(k1 + 2k2 + 2k3 + k4)

The unscented filter with noise augmentation adds a process noise w to ẋ, held constant over
the step (f → f + w in every stage).

Everything here works on a *batch* of augmented states X (B × n): all sigma points of an
unscented filter, or all 2n perturbed states of a central-difference Jacobian, are evaluated
in one call of a numba kernel that loops over the rows and calls the model's compiled out-form
``f_out``/``h_out`` (``flightid.model.forms``). A model numba cannot compile runs the same
loop in plain Python (slower, same numbers).

Central-difference Jacobians, column j of the n augmented states:

    A[:, j] = (f_a(x_a + h_j e_j, u) − f_a(x_a − h_j e_j, u)) / (2 h_j)
    C[:, j] = (g(x_a + h_j e_j, u) − g(x_a − h_j e_j, u)) / (2 h_j)

with h_j an absolute step (EKF) or h_j = s·|x_a,j| (s if x_a,j = 0; EFRLS).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from flightid.errors import InputError, ModelError, describe
from flightid.model.statespace import StateSpaceModel

__all__ = ["AugmentedModel", "absolute_steps", "relative_steps"]


def _kernel_sources(f_out: Callable, h_out: Callable) -> tuple[Callable, Callable, Callable]:
    """The three batch loops (rates, RK4 step, outputs), closed over the out-form model
    functions. Each row b of X is one augmented state (x, θ_free)."""

    def rates(t, X, u, theta_template, free_index, n_x, out):
        n_batch = X.shape[0]
        n_free = free_index.shape[0]
        theta = theta_template.copy()
        x = np.empty(n_x)
        dx = np.empty(n_x)
        for b in range(n_batch):
            for j in range(n_free):
                theta[free_index[j]] = X[b, n_x + j]
            for i in range(n_x):
                x[i] = X[b, i]
            # ẋ = f(t, x, u, θ);  θ̇_free = 0
            f_out(t, x, u, theta, dx)
            for i in range(n_x):
                out[b, i] = dx[i]
            for j in range(n_free):
                out[b, n_x + j] = 0.0

    def rk4(t, dt, X, u0, u1, theta_template, free_index, n_x, W, out):
        n_batch = X.shape[0]
        n_free = free_index.shape[0]
        theta = theta_template.copy()
        x = np.empty(n_x)
        x_stage = np.empty(n_x)
        k1 = np.empty(n_x)
        k2 = np.empty(n_x)
        k3 = np.empty(n_x)
        k4 = np.empty(n_x)
        # ū = (u_k + u_{k+1})/2
        u_mid = 0.5 * (u0 + u1)
        half = 0.5 * dt
        sixth = dt / 6.0
        for b in range(n_batch):
            for j in range(n_free):
                theta[free_index[j]] = X[b, n_x + j]
                out[b, n_x + j] = X[b, n_x + j]
            for i in range(n_x):
                x[i] = X[b, i]
            # every stage: ẋ = f + w (w = 0 except in the noise-augmented UKF)
            f_out(t, x, u0, theta, k1)
            for i in range(n_x):
                k1[i] += W[b, i]
                x_stage[i] = x[i] + half * k1[i]
            f_out(t + half, x_stage, u_mid, theta, k2)
            for i in range(n_x):
                k2[i] += W[b, i]
                x_stage[i] = x[i] + half * k2[i]
            f_out(t + half, x_stage, u_mid, theta, k3)
            for i in range(n_x):
                k3[i] += W[b, i]
                x_stage[i] = x[i] + dt * k3[i]
            f_out(t + dt, x_stage, u1, theta, k4)
            for i in range(n_x):
                k4[i] += W[b, i]
                # x_{k+1} = x_k + (dt/6)·(k1 + 2k2 + 2k3 + k4)
                out[b, i] = x[i] + sixth * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])

    def outputs(t, X, u, theta_template, free_index, n_x, n_y, out):
        n_batch = X.shape[0]
        n_free = free_index.shape[0]
        theta = theta_template.copy()
        x = np.empty(n_x)
        y = np.empty(n_y)
        for b in range(n_batch):
            for j in range(n_free):
                theta[free_index[j]] = X[b, n_x + j]
            for i in range(n_x):
                x[i] = X[b, i]
            # y = h(t, x, u, θ)
            h_out(t, x, u, theta, y)
            for i in range(n_y):
                out[b, i] = y[i]

    return rates, rk4, outputs


def absolute_steps(x_a: np.ndarray, step: float | np.ndarray) -> np.ndarray:
    """Central-difference steps h_j = step (a number or one per augmented state)."""
    return np.broadcast_to(np.asarray(step, dtype=float), x_a.shape).copy()


def relative_steps(x_a: np.ndarray, step: float) -> np.ndarray:
    """Central-difference steps h_j = step·|x_a,j|, or step where x_a,j = 0."""
    # h_j = s·|x_j|  (s if x_j = 0)
    h = step * np.abs(x_a)
    h[h == 0.0] = step
    return h


def model_has_input_delays(model: StateSpaceModel) -> bool:
    """True if the model declares input delays."""
    return bool(model.input_delays)


def _check_recursive_model(model: StateSpaceModel) -> None:
    """``InputError`` for what the filters cannot take: per-maneuver parameters, output
    delays, an estimated (free) or negative input delay."""
    if model.maneuver_parameters:
        raise InputError(
            "model: per-maneuver parameters are not available in recursive estimation (one "
            f"continuous record); got {sorted(model.maneuver_parameters)}"
        )
    if model.output_delays:
        raise InputError(
            "model: output delays are not available in recursive estimation (the measurement "
            "at t would need the state at t − τ); delay the inputs instead (input_delays)"
        )
    for channel, name in model.input_delays.items():
        parameter = model.parameters[name]
        if parameter.free:
            raise InputError(
                f"model: the input delay {name!r} of {channel!r} is free; the recursive filters "
                f"take a fixed, known delay (set {name} = {{ value = ..., free = false }}, e.g. "
                "from output error or the frequency domain)"
            )
        if not (np.isfinite(parameter.value) and parameter.value >= 0.0):
            raise InputError(
                f"model: the input delay {name!r} of {channel!r} is {parameter.value} s; the "
                "recursive filters take a delay >= 0 (they cannot read inputs not yet fed)"
            )


class AugmentedModel:
    """A ``StateSpaceModel`` with its free parameters appended to the state.

    Args:
        model: the model (one maneuver's parameter layout: no per-maneuver parameters, no
            output delays; the recursive filters run one continuous record). Input delays
            must be fixed parameters ≥ 0: the filters feed the model u(t − τ)
            (``flightid.recursive.delay.InputDelayLine``).
        x0: initial state (len(model.states)), in the states' units.
        compiled: run the batch loops numba-compiled (falls back to Python, with the same
            numbers, when numba cannot compile the model functions).

    Attributes:
        n_x, n_free, n: number of states, free parameters, augmented states (n_x + n_free).
        names: augmented state names (states, then free parameter names).
        free_names: names of the free parameters (the order of x_a[n_x:]).
        x_a0: start of the augmented state (x0, θ_free start values).
    """

    def __init__(
        self, model: StateSpaceModel, x0: Sequence[float] | np.ndarray, compiled: bool = True
    ) -> None:
        if not isinstance(model, StateSpaceModel):
            raise InputError(f"model: expected a StateSpaceModel, got {describe(model)}")
        if not model.states:
            raise InputError(
                "model: recursive estimation needs a model with states (the augmented state "
                "x_a = (x, θ)); this one has none"
            )
        _check_recursive_model(model)
        from flightid.recursive.base import float_array

        if not isinstance(compiled, (bool, np.bool_)):
            raise InputError(f"compiled: expected True or False, got {describe(compiled)}")
        x0 = float_array(x0, "x0", f"{len(model.states)} initial states")
        if x0.shape != (len(model.states),):
            raise InputError(
                f"x0: expected {len(model.states)} initial states {list(model.states)}, "
                f"got {describe(x0)}"
            )
        if not np.all(np.isfinite(x0)):
            raise InputError(f"x0: expected finite initial states, got {x0.tolist()}")
        self.model = model
        self.n_x = len(model.states)
        self.n_y = len(model.outputs)
        self.n_u = len(model.inputs)
        mask = model.parameters.free_mask
        self.free_index = np.flatnonzero(mask).astype(np.int64)
        self.n_free = int(self.free_index.size)
        self.n = self.n_x + self.n_free
        self.theta_template = np.asarray(model.parameters.values, dtype=float).copy()
        self.free_names = [model.parameters.names[i] for i in self.free_index]
        self.free_units = [model.parameters[i].unit for i in self.free_index]
        self.names = [*model.states, *self.free_names]
        self.x_a0 = np.concatenate([x0, self.theta_template[self.free_index]])
        # fixed input delays τ (s) per input (0: not delayed)
        self.input_delays_s = np.zeros(self.n_u)
        for k, p in model.input_delay_maps():
            self.input_delays_s[k] = self.theta_template[p]
        self.compiled = False
        self._build(compiled)

    def input_delay_line(self):
        """A fresh ``InputDelayLine`` for the model's input delays, or None without any."""
        if not model_has_input_delays(self.model):
            return None
        from flightid.recursive.delay import InputDelayLine

        return InputDelayLine(self.input_delays_s, self.model.delay_convention)

    # ------------------------------------------------------------------ kernels

    def _build(self, compiled: bool) -> None:
        from flightid.model.forms import kernel_function

        if compiled:
            try:
                from flightid.model.kernel_cache import cached_njit

                sources = _kernel_sources(
                    kernel_function(self.model.f_out, True),
                    kernel_function(self.model.h_out, True),
                )
                self._rates, self._rk4, self._outputs = (cached_njit(s) for s in sources)
                self._probe()
                self.compiled = True
                return
            except Exception as exc:  # numba's compilation errors have many classes
                if not type(exc).__module__.startswith("numba"):
                    raise
        sources = _kernel_sources(
            kernel_function(self.model.f_out, False), kernel_function(self.model.h_out, False)
        )
        self._rates, self._rk4, self._outputs = sources
        self._probe()

    def _probe(self) -> None:
        """One evaluation at the start (compiles the loops; checks finite values)."""
        u = np.zeros(self.n_u)
        X = self.x_a0[None, :].copy()
        rates = self.rates(X, u, 0.0)
        outputs = self.outputs(X, u, 0.0)
        for name, values in (("f", rates), ("h", outputs)):
            if not np.all(np.isfinite(values)):
                raise ModelError(
                    f"{name}: non-finite values at the start state x_a0 = {self.x_a0.tolist()} "
                    f"with u = 0: {values.ravel().tolist()}"
                )

    # ------------------------------------------------------------------ batch evaluations

    def rates(self, X: np.ndarray, u: np.ndarray, t: float = 0.0) -> np.ndarray:
        """ẋ_a = (f(x, u, θ), 0) for every row of X (B × n); returns B × n."""
        X = np.ascontiguousarray(X, dtype=float)
        out = np.empty_like(X)
        self._rates(float(t), X, np.ascontiguousarray(u, dtype=float), self.theta_template,
                    self.free_index, self.n_x, out)  # fmt: skip
        return out

    def outputs(self, X: np.ndarray, u: np.ndarray, t: float = 0.0) -> np.ndarray:
        """y = h(x, u, θ) for every row of X (B × n); returns B × n_y."""
        X = np.ascontiguousarray(X, dtype=float)
        out = np.empty((X.shape[0], self.n_y))
        self._outputs(float(t), X, np.ascontiguousarray(u, dtype=float), self.theta_template,
                      self.free_index, self.n_x, self.n_y, out)  # fmt: skip
        return out

    def rk4(
        self,
        X: np.ndarray,
        u0: np.ndarray,
        u1: np.ndarray,
        dt: float,
        t: float = 0.0,
        w: np.ndarray | None = None,
    ) -> np.ndarray:
        """Every row of X (B × n) advanced by one RK4 step of ``dt`` s from ``t`` (inputs
        u_k = ``u0``, u_{k+1} = ``u1``); ``w`` (B × n_x) a process noise added to ẋ."""
        X = np.ascontiguousarray(X, dtype=float)
        W = np.zeros((X.shape[0], self.n_x)) if w is None else np.ascontiguousarray(w, dtype=float)
        out = np.empty_like(X)
        self._rk4(float(t), float(dt), X, np.ascontiguousarray(u0, dtype=float),
                  np.ascontiguousarray(u1, dtype=float), self.theta_template, self.free_index,
                  self.n_x, W, out)  # fmt: skip
        return out

    # ------------------------------------------------------------------ Jacobians

    def _perturbed(self, x_a: np.ndarray, h: np.ndarray) -> np.ndarray:
        """Rows x_a + h_j e_j (j = 0..n−1), then x_a − h_j e_j."""
        X = np.repeat(x_a[None, :], 2 * self.n, axis=0)
        idx = np.arange(self.n)
        X[idx, idx] += h
        X[self.n + idx, idx] -= h
        return X

    def state_jacobian(self, x_a: np.ndarray, u: np.ndarray, h: np.ndarray, t: float = 0.0):
        """A = ∂f_a/∂x_a (n × n) by central differences with steps ``h`` (n)."""
        F = self.rates(self._perturbed(x_a, h), u, t)
        # A[:, j] = (f_a(x + h_j e_j) − f_a(x − h_j e_j)) / (2 h_j)
        return ((F[: self.n] - F[self.n :]) / (2.0 * h[:, None])).T

    def output_jacobian(self, x_a: np.ndarray, u: np.ndarray, h: np.ndarray, t: float = 0.0):
        """C = ∂g/∂x_a (n_y × n) by central differences with steps ``h`` (n)."""
        Y = self.outputs(self._perturbed(x_a, h), u, t)
        # C[:, j] = (g(x + h_j e_j) − g(x − h_j e_j)) / (2 h_j)
        return ((Y[: self.n] - Y[self.n :]) / (2.0 * h[:, None])).T
