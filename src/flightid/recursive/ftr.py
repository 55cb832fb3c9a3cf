"""Recursive Fourier-transform regression (FTR; Morelli's frequency-domain equation error,
Jategaonkar, *Flight Vehicle System Identification*, 2nd ed., ch. 7.6; FVSysID's ``ftr_mod``).

The measured state signals x (the outputs taken as states) and the inputs u obey, in the
frequency domain, the linear state equation without constant terms

    jω X(ω) = A X(ω) + B U(ω).

Signals are de-meaned by the mean of their first ``n_mean`` (10) samples, x̄_k = x_k − x_mean.
The finite Fourier transform at the chosen frequencies ω = 2πf is kept recursively, one term
per sample (sample 1 excluded, phase reference t_1 = 0, as in FVSysID's ``ftr_mod``):

    X(ω) += x̄_k e^{−jω t_k},   U(ω) += ū_k e^{−jω t_k},   k = 2, 3, …,   t_k = (k−1)·dt

Every ``update_every`` samples (k mod M = 0) each state equation i is solved by least squares
over the n_f frequencies with real parts (Θ = [X U], n_f × n_p, n_p = n_x + n_u):

    θ_i = Re(ΘᴴΘ)⁻¹ Re(Θᴴ jωX_i)                         (row i of [A B])
    σ_i² = Σ_ω |jωX_i − Θθ_i|² / (2 n_f − n_p)
    std_i = sqrt(diag(σ_i² Re(ΘᴴΘ)⁻¹))

This is ordinary least squares on the real-stacked equations [Re; Im] (2 n_f rows, n_p real
unknowns, Re(ΘᴴΘ) = ΘᵣᵀΘᵣ): each real component of a circular complex residual of variance s
has variance s/2, which σ_i² estimates with 2 n_f − n_p degrees of freedom, as the
frequency-domain equation error does (``flightid.frequency.equation_error``). Dividing by
n_f − n_p instead would estimate s, not s/2, and make every σ about √2 too large. The σ is
the Cramér–Rao-type one of white, equal residuals at independent frequencies (space the
frequencies by at least 1/T of the record); the equation-error residual carries jω times
the measurement noise, so it is conservative where that noise dominates (measured in
docs/recursive.md).

An update whose Re(ΘᴴΘ) is singular (condition number ≥ 1e12: no excitation yet) is
skipped and counted (``skipped_updates``); the estimate stays that of the last update.

A coefficient may be reported with a known part removed (``offsets``): for the short period
A_12 = 1 + Z_q, so Z_q = A_12 − 1 with the std of A_12.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from flightid.errors import FlightIdError, InputError, describe
from flightid.recursive.base import RecursiveEstimatorBase

__all__ = ["FourierTransformRegression", "NoEstimateYetError", "frequency_grid_hz"]


# Re(ΘᴴΘ) with a larger condition number is taken as singular (update skipped)
MAX_CONDITION = 1e12


class NoEstimateYetError(FlightIdError, LookupError):
    """The FTR has not reached its first update (no estimate exists yet)."""


def frequency_grid_hz(start: float, stop: float, step: float) -> np.ndarray:
    """start, start + step, … ≤ stop (Hz), as MATLAB's start:step:stop."""
    for name, value in (("start", start), ("stop", stop), ("step", step)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
            raise InputError(f"frequencies_hz.{name}: expected a finite number, got {value!r}")
    if step <= 0 or start <= 0 or stop < start:
        raise InputError(
            f"frequencies_hz: expected 0 < start <= stop and step > 0, got start={start}, "
            f"stop={stop}, step={step}"
        )
    count = int(np.floor((stop - start) / step + 1e-9)) + 1
    return start + step * np.arange(count)


def _checked_delays(value, n_inputs: int) -> np.ndarray:
    """``input_delays_s`` as n_inputs finite delays ≥ 0 (s); zeros for None."""
    if value is None:
        return np.zeros(n_inputs)
    from flightid.recursive.base import float_array

    delays = float_array(value, "input_delays_s", f"{n_inputs} delays (s)")
    if delays.shape != (n_inputs,):
        raise InputError(
            f"input_delays_s: expected {n_inputs} delays (s), one per input, got {describe(value)}"
        )
    if not np.all(np.isfinite(delays)) or np.any(delays < 0):
        raise InputError(f"input_delays_s: expected finite delays >= 0 s, got {delays.tolist()}")
    return delays


def _checked_sizes(n_states: object, n_inputs: object) -> None:
    """n_states ≥ 1 and n_inputs ≥ 0, both integers."""
    for name, value in (("n_states", n_states), ("n_inputs", n_inputs)):
        if isinstance(value, bool) or not isinstance(value, int) or value < (name == "n_states"):
            raise InputError(f"{name}: expected a non-negative integer, got {value!r}")


def _checked_frequencies(frequencies_hz: object, n_p: int) -> np.ndarray:
    """``frequencies_hz`` as more than n_p positive finite frequencies (Hz)."""
    from flightid.recursive.base import float_array

    freq = float_array(frequencies_hz, "frequencies_hz", "frequencies (Hz)")
    if freq.ndim != 1 or freq.size <= n_p or not np.all(np.isfinite(freq)) or np.any(freq <= 0):
        raise InputError(
            f"frequencies_hz: expected more than {n_p} positive frequencies, got "
            f"{describe(frequencies_hz)}"
        )
    return freq


def _positive_integer(value: object, name: str) -> int:
    """``value`` as an integer ≥ 1 (a bool is no integer here)."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise InputError(f"{name}: expected a positive integer, got {value!r}")
    return value


def _default_parameter_names(n_states: int, n_inputs: int) -> list[list[str]]:
    """Row i: "A<i>1" … "A<i><n_x>", "B<i>1" … "B<i><n_u>"."""
    return [
        [f"A{i + 1}{j + 1}" for j in range(n_states)]
        + [f"B{i + 1}{j + 1}" for j in range(n_inputs)]
        for i in range(n_states)
    ]


def _checked_parameter_names(parameter_names: object, n_states: int, n_p: int) -> list[str]:
    """n_states rows of n_p unique names, flattened row by row."""
    if (
        isinstance(parameter_names, str)
        or not isinstance(parameter_names, Sequence)
        or not all(
            isinstance(row, Sequence) and not isinstance(row, str) for row in parameter_names
        )
    ):
        raise InputError(
            f"parameter_names: expected {n_states} rows of {n_p} names, got "
            f"{describe(parameter_names)}"
        )
    rows = [list(row) for row in parameter_names]
    if len(rows) != n_states or any(len(row) != n_p for row in rows):
        raise InputError(f"parameter_names: expected {n_states} rows of {n_p} names, got {rows!r}")
    names = [name for row in rows for name in row]
    if len(set(names)) != len(names) or not all(isinstance(n, str) for n in names):
        raise InputError(f"parameter_names: expected unique names, got {names}")
    return names


def _checked_offsets(offsets: object, names: Sequence[str]) -> dict:
    """``offsets`` as {parameter name: finite number}; {} for None."""
    if offsets is not None and not isinstance(offsets, Mapping):
        raise InputError(f"offsets: expected a mapping name → number, got {describe(offsets)}")
    offsets = dict(offsets or {})
    unknown = [name for name in offsets if name not in names]
    if unknown:
        raise InputError(f"offsets: {unknown} are not parameter names {names}")
    for name, value in offsets.items():
        if (
            isinstance(value, (bool, np.bool_))
            or not isinstance(value, (int, float, np.number))
            or not np.isfinite(value)
        ):
            raise InputError(f"offsets[{name!r}]: expected a finite number, got {value!r}")
    return offsets


class FourierTransformRegression(RecursiveEstimatorBase):
    """Recursive FTR for n_x measured states and n_u inputs.

    ``feed(t, u, z)``: ``u`` the n_u inputs, ``z`` the n_x measured states.

    Args:
        n_states: number of state signals (the measured outputs taken as states).
        n_inputs: number of input signals.
        frequencies_hz: the analysis frequencies f (Hz), more than n_x + n_u of them.
        update_every: samples between least-squares updates (M; updates at k mod M = 0).
        parameter_names: n_x rows of n_x + n_u names (row i: A_i1…A_in_x, B_i1…B_in_u);
            default "A11", …, "B11", ….
        offsets: name → known part subtracted from that coefficient before reporting.
        n_mean: samples whose mean is removed from every signal (10).
        input_delays_s: a fixed delay τ ≥ 0 (s) per input (default none): the inputs are
            regressed as ũ(t) = u(t − τ), linear between samples, the first sample held
            before it (``flightid.recursive.delay.InputDelayLine``, "fractional").
    """

    method = "ftr"

    def __init__(
        self,
        n_states: int,
        n_inputs: int,
        frequencies_hz: Sequence[float] | np.ndarray,
        update_every: int,
        parameter_names: Sequence[Sequence[str]] | None = None,
        offsets: Mapping[str, float] | None = None,
        n_mean: int = 10,
        input_delays_s: Sequence[float] | np.ndarray | None = None,
    ) -> None:
        _checked_sizes(n_states, n_inputs)
        n_p = n_states + n_inputs
        freq = _checked_frequencies(frequencies_hz, n_p)
        update_every = _positive_integer(update_every, "update_every")
        n_mean = _positive_integer(n_mean, "n_mean")
        if parameter_names is None:
            parameter_names = _default_parameter_names(n_states, n_inputs)
        names = _checked_parameter_names(parameter_names, n_states, n_p)
        offsets = _checked_offsets(offsets, names)
        self.n_states, self.n_inputs, self.n_outputs = n_states, n_inputs, n_states
        self.frequencies_hz = freq
        # ω = 2πf (rad/s)
        self.omega = 2.0 * np.pi * freq
        self.update_every = update_every
        self.n_mean = n_mean
        self.parameter_names = names
        self.offsets = np.array([float(offsets.get(name, 0.0)) for name in names])
        self.input_delays_s = _checked_delays(input_delays_s, n_inputs)
        self.reset()

    def reset(self) -> None:
        super().reset()
        from flightid.recursive.delay import InputDelayLine

        self._delay_line = (
            InputDelayLine(self.input_delays_s) if np.any(self.input_delays_s) else None
        )
        n_f = self.omega.size
        self.X = np.zeros((n_f, self.n_states), dtype=complex)
        self.U = np.zeros((n_f, self.n_inputs), dtype=complex)
        self._buffer: list[tuple[float, np.ndarray, np.ndarray]] = []
        self._t1: float | None = None
        self._mean_x: np.ndarray | None = None
        self._mean_u: np.ndarray | None = None
        self._theta: np.ndarray | None = None
        self._std: np.ndarray | None = None
        self.updates: list[tuple[int, float, np.ndarray, np.ndarray]] = []
        self.skipped_updates = 0  # updates without information (Re(ΘᴴΘ) singular)

    def _model_input(self, t: float, u: np.ndarray) -> np.ndarray:
        """ũ(t) = u(t − τ) for the fixed input delays; the fed inputs without any."""
        return u if self._delay_line is None else self._delay_line.push(t, u)

    # ---------------------------------------------------------------- transform

    def _accumulate(self, k: int, t: float, u: np.ndarray, z: np.ndarray) -> None:
        if k == 1:  # sample 1 is not part of the transform (as in ftr_mod)
            return
        # e^{−jω t_k}, t_k measured from the first sample
        phase = np.exp(-1j * self.omega * (t - self._t1))
        # X(ω) += x̄_k e^{−jω t_k},  U(ω) += ū_k e^{−jω t_k}
        self.X += phase[:, None] * (z - self._mean_x)[None, :]
        self.U += phase[:, None] * (u - self._mean_u)[None, :]

    def _feed_sample(self, t: float, u: np.ndarray, z: np.ndarray) -> None:
        if self.k == 1:
            self._t1 = t
        if self._mean_x is None:
            self._buffer.append((t, u, z))
            if len(self._buffer) < self.n_mean:
                return
            # de-meaning by the first n_mean samples
            self._mean_x = np.mean([b[2] for b in self._buffer], axis=0)
            self._mean_u = np.mean([b[1] for b in self._buffer], axis=0)
            for i, (tb, ub, zb) in enumerate(self._buffer):
                self._accumulate(i + 1, tb, ub, zb)
            self._buffer = []
        else:
            self._accumulate(self.k, t, u, z)
        if self.k % self.update_every == 0 and self._mean_x is not None:
            self._update(t)

    def _first(self, t, u, z) -> None:
        self._feed_sample(t, u, z)

    def _step(self, t_prev, t, u_prev, u, z) -> None:
        self._feed_sample(t, u, z)

    # ---------------------------------------------------------------- regression

    def regression(self) -> tuple[np.ndarray, np.ndarray]:
        """(θ, std) of the transforms so far: n_x rows of n_x + n_u values each, before the
        offsets are removed."""
        theta_all = np.empty((self.n_states, self.n_states + self.n_inputs))
        std_all = np.empty_like(theta_all)
        Theta = np.hstack([self.X, self.U])
        n_f, n_p = Theta.shape
        # Re(ΘᴴΘ) and its inverse
        information = np.real(Theta.conj().T @ Theta)
        if not np.linalg.cond(information) < MAX_CONDITION:
            raise np.linalg.LinAlgError(
                f"ftr: Re(ΘᴴΘ) is singular at sample {self.k} (condition number ≥ "
                f"{MAX_CONDITION:.0e}): the signals carry no information at the frequencies yet"
            )
        covariance = np.linalg.inv(information)
        for i in range(self.n_states):
            # response jω X_i
            response = 1j * self.omega * self.X[:, i]
            # θ_i = Re(ΘᴴΘ)⁻¹ Re(Θᴴ jωX_i)
            theta = covariance @ np.real(Theta.conj().T @ response)
            # σ_i² = Σ |jωX_i − Θθ_i|² / (2 n_f − n_p)
            sigma2 = float(np.sum(np.abs(response - Theta @ theta) ** 2)) / (2 * n_f - n_p)
            theta_all[i] = theta
            # std_i = sqrt(diag(σ_i² Re(ΘᴴΘ)⁻¹))
            std_all[i] = np.sqrt(np.clip(sigma2 * np.diag(covariance), 0.0, None))
        return theta_all, std_all

    def _update(self, t: float) -> None:
        try:
            theta, std = self.regression()
        except np.linalg.LinAlgError:
            # nothing to regress on yet (e.g. before the input starts): no estimate here
            self.skipped_updates += 1
            return
        theta = theta.ravel() - self.offsets
        std = std.ravel()
        if not (np.all(np.isfinite(theta)) and np.all(np.isfinite(std))):
            from flightid.recursive.base import RecursiveDivergenceError

            raise RecursiveDivergenceError(
                f"ftr: non-finite estimates at sample {self.k} (t = {t} s)", sample=self.k
            )
        self._theta, self._std = theta, std
        self.updates.append((self.k, t, theta.copy(), std.copy()))

    def _last_update(self, values: np.ndarray | None) -> np.ndarray:
        """A copy of ``values`` of the last update, or ``NoEstimateYetError`` before the
        first one."""
        if values is None:
            raise NoEstimateYetError(
                f"ftr: no estimate yet; the first update comes at sample {self.update_every} "
                f"({self.k} fed)"
            )
        return values.copy()

    @property
    def theta(self) -> np.ndarray:
        """Estimates of the last update (offsets removed)."""
        return self._last_update(self._theta)

    @property
    def theta_std(self) -> np.ndarray:
        """Standard deviations of the last update."""
        return self._last_update(self._std)
