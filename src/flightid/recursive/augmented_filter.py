"""The base of the filters on an augmented state x_a = (x, θ_free) (``AugmentedModel``): the
extended and unscented Kalman filters and extended-forgetting RLS share its estimate ``x``,
covariance ``P``, input delays and parameter read-out."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from flightid.errors import InputError, describe
from flightid.recursive.augmented import AugmentedModel
from flightid.recursive.base import RecursiveEstimatorBase, diagonal_matrix

__all__ = ["AugmentedFilter"]


class AugmentedFilter(RecursiveEstimatorBase):
    """A filter on the augmented state x_a = (x, θ_free) of an ``AugmentedModel``: holds the
    current estimate ``x`` (n) and covariance ``P`` (n × n)."""

    def __init__(self, augmented, p0: float | Sequence[float]) -> None:
        if not isinstance(augmented, AugmentedModel):
            raise InputError(f"augmented: expected an AugmentedModel, got {describe(augmented)}")
        self.augmented = augmented
        self.n_inputs = augmented.n_u
        self.n_outputs = augmented.n_y
        self.parameter_names = list(augmented.free_names)
        self.P0 = diagonal_matrix(p0, augmented.n, "p0")
        self.reset()

    def _additive_noise(self, q_states, r0) -> tuple[np.ndarray, np.ndarray]:
        """Q = diag(Q_states, 0, …, 0) (n × n; the parameters get no process noise) and R0
        (n_y × n_y), from numbers (× I) or diagonal values."""
        n_x, n = self.augmented.n_x, self.augmented.n
        Q = np.zeros((n, n))
        Q[:n_x, :n_x] = diagonal_matrix(q_states, n_x, "q_states")
        return Q, diagonal_matrix(r0, self.augmented.n_y, "r0", positive=True)

    def reset(self) -> None:
        super().reset()
        self.x = self.augmented.x_a0.copy()
        self.P = self.P0.copy()
        self._delay_line = self.augmented.input_delay_line()

    def _model_input(self, t: float, u: np.ndarray) -> np.ndarray:
        """ũ(t) = u(t − τ) for the model's fixed input delays (``InputDelayLine``); the fed
        inputs where the model delays none."""
        if self._delay_line is None:
            return u
        return self._delay_line.push(t, u)

    @property
    def theta(self) -> np.ndarray:
        """Current estimates of the free parameters."""
        return self.x[self.augmented.n_x :].copy()

    @property
    def theta_std(self) -> np.ndarray:
        """sqrt(diag P) over the parameter part."""
        return np.sqrt(np.clip(np.diag(self.P)[self.augmented.n_x :], 0.0, None))

    @property
    def states(self) -> np.ndarray:
        """Current estimates of the model states."""
        return self.x[: self.augmented.n_x].copy()
