"""A delay line for the recursive filters: the input a model sees, ũ(t_k) = u(t_k − τ), from
the samples fed so far.

A model with ``input_delays`` receives each delayed input at t − τ (τ ≥ 0, a fixed value in
s). Fed one sample at a time, the line keeps the few past samples the delay reaches back to
and returns, per input channel, the value of the model's ``delay_convention``, the same rule
the time-domain simulator applies to a whole record (``flightid.simulation.delayed_inputs``):

* ``"fractional"``: ũ_k = u(t_k − τ), linear between the two samples that bracket t_k − τ;
  before the first sample the first value is held;
* ``"two_sample"``: ũ_k = u_k + (τ/dt_k)·(u_{k−1} − u_k), dt_k = t_k − t_{k−1}; ũ_1 = u_1.

A negative delay would need inputs not yet fed and is refused.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from flightid.errors import InputError, describe

__all__ = ["InputDelayLine"]

CONVENTIONS = ("fractional", "two_sample")


class InputDelayLine:
    """Delays each input channel by its own fixed τ_k ≥ 0 (s), sample by sample.

    Args:
        delays_s: one delay per input (s), ≥ 0 and finite (0: the channel passes unchanged).
        convention: ``"fractional"`` or ``"two_sample"`` (module docstring).
    """

    def __init__(self, delays_s: Sequence[float] | np.ndarray, convention: str = "fractional"):
        from flightid.recursive.base import float_array

        delays = float_array(delays_s, "delays_s", "one delay (s) per input")
        if delays.ndim != 1:
            raise InputError(
                f"delays_s: expected one delay (s) per input, got {describe(delays_s)}"
            )
        if not np.all(np.isfinite(delays)) or np.any(delays < 0):
            raise InputError(
                f"delays_s: expected finite delays >= 0 s (a recursive filter cannot read "
                f"inputs not yet fed), got {delays.tolist()}"
            )
        if convention not in CONVENTIONS:
            raise InputError(
                f"delay_convention: expected one of {list(CONVENTIONS)}, got {convention!r}"
            )
        self.delays_s = delays
        self.convention = convention
        self.reset()

    def reset(self) -> None:
        """Forget the samples fed so far."""
        self._times: list[float] = []
        self._values: list[np.ndarray] = []

    def push(self, t: float, u: np.ndarray) -> np.ndarray:
        """Take the sample (t, u) (times increasing) and return ũ(t), one value per input."""
        u = np.asarray(u, dtype=float)
        if u.shape != self.delays_s.shape:
            raise InputError(f"u: expected {self.delays_s.size} inputs, got {describe(u)}")
        self._times.append(float(t))
        self._values.append(u.copy())
        if not np.any(self.delays_s):
            self._keep_from(len(self._times) - 1)
            return u.copy()
        if self.convention == "two_sample":
            return self._two_sample()
        return self._fractional()

    def _keep_from(self, index: int) -> None:
        del self._times[:index]
        del self._values[:index]

    def _two_sample(self) -> np.ndarray:
        self._keep_from(max(len(self._times) - 2, 0))
        if len(self._times) == 1:
            # ũ_1 = u_1
            return self._values[0].copy()
        (t0, t1), (u0, u1) = self._times, self._values
        # ũ_k = u_k + (τ/dt_k)·(u_{k−1} − u_k)
        return u1 + self.delays_s / (t1 - t0) * (u0 - u1)

    def _fractional(self) -> np.ndarray:
        times = np.asarray(self._times)
        values = np.asarray(self._values)
        # target times t_k − τ, the first sample's value held before it
        target = np.maximum(times[-1] - self.delays_s, times[0])
        # j: the last sample with t_j ≤ target (the last interval where target = t_k)
        j = np.clip(np.searchsorted(times, target, side="right") - 1, 0, max(times.size - 2, 0))
        out = np.empty(self.delays_s.size)
        for channel, (jc, tc) in enumerate(zip(j, target, strict=True)):
            if times.size == 1:
                out[channel] = values[0, channel]
                continue
            # u(t_k − τ) = u_j + w·(u_{j+1} − u_j),  w = (t_k − τ − t_j)/(t_{j+1} − t_j)
            w = (tc - times[jc]) / (times[jc + 1] - times[jc])
            out[channel] = values[jc, channel] + w * (values[jc + 1, channel] - values[jc, channel])
        # samples before the oldest bracket are never needed again
        self._keep_from(int(j.min()))
        return out
