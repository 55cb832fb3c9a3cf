"""Streaming use of the recursive estimators: feed one sample or a block, read the current
estimates and their standard deviations at any time, and turn the run into a result.

    from flightid.recursive import AugmentedModel, ExtendedKalmanFilter, RecursiveEstimator

    augmented = AugmentedModel(model, x0)
    online = RecursiveEstimator(ExtendedKalmanFilter(augmented, p0=10.0,
                                                     q_states=[1e-7, 1e-7], r0=[4e-7, 8e-7]))
    for t, u, z in samples:                 # as they arrive
        online.feed(t, u, z)
        print(online.estimates, online.std)  # name → value, name → σ
    online.feed_block(T, U, Z)              # or a block of rows at once
    result = online.result()                # RecursiveResult (histories, final values)

Feeding the samples one by one, in blocks of any size, or all at once gives the same
numbers: every path calls the estimator's ``feed`` once per sample, in order. ``feed_block``
runs BLAS on one thread (the matrices are small); a caller feeding single samples in a loop
may do the same with ``threadpoolctl.threadpool_limits(1)``.
"""

from __future__ import annotations

import time as _time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from flightid.errors import InputError, describe
from flightid.recursive.base import RecursiveEstimatorBase

__all__ = ["RecursiveEstimator", "run_recursive"]


class RecursiveEstimator:
    """Wraps an estimator (EKF, UKF, UKF_aug, EFRLS or FTR) for sample-by-sample use and
    records the parameter histories (``record=False`` keeps only the current values)."""

    def __init__(self, estimator: RecursiveEstimatorBase, record: bool = True) -> None:
        if not isinstance(estimator, RecursiveEstimatorBase):
            raise InputError(
                f"estimator: expected a recursive estimator (EKF, UKF, EFRLS, FTR), got "
                f"{describe(estimator)}"
            )
        self.estimator = estimator
        self.record = record
        self._times: list[float] = []
        self._samples: list[int] = []
        self._theta: list[np.ndarray] = []
        self._std: list[np.ndarray] = []
        self._states: list[np.ndarray] = []
        self._updates_seen = 0
        self.wall_time_s = 0.0

    @property
    def method(self) -> str:
        return self.estimator.method

    @property
    def parameter_names(self) -> list[str]:
        return list(self.estimator.parameter_names)

    @property
    def n_samples(self) -> int:
        """Samples fed so far."""
        return self.estimator.k

    @property
    def estimates(self) -> dict[str, float]:
        """Current parameter estimates, name → value."""
        return dict(zip(self.parameter_names, self.estimator.theta.tolist(), strict=True))

    @property
    def std(self) -> dict[str, float]:
        """Current standard deviations, name → σ."""
        return dict(zip(self.parameter_names, self.estimator.theta_std.tolist(), strict=True))

    def feed(self, t: float, u: Sequence[float], z: Sequence[float]) -> None:
        """One sample: time ``t`` (s), inputs ``u``, measurements ``z``."""
        start = _time.perf_counter()
        self.estimator.feed(t, u, z)
        self.wall_time_s += _time.perf_counter() - start
        if self.record:
            self._keep(t)

    def feed_block(self, t: np.ndarray, u: np.ndarray, z: np.ndarray) -> None:
        """Rows of samples: times ``t`` (N), inputs ``u`` (N × n_u), measurements ``z``
        (N × n_z)."""
        from flightid.recursive.base import float_array

        t = float_array(t, "t", "sample times (s)").reshape(-1)
        u = float_array(u, "u", "input samples")
        z = float_array(z, "z", "measurement samples")
        n = t.size
        if u.ndim == 1 and self.estimator.n_inputs == 1:
            u = u[:, None]
        if z.ndim == 1 and self.estimator.n_outputs == 1:
            z = z[:, None]
        if u.shape != (n, self.estimator.n_inputs):
            raise InputError(
                f"u: expected ({n}, {self.estimator.n_inputs}) inputs, got {describe(u)}"
            )
        if z.shape != (n, self.estimator.n_outputs):
            raise InputError(
                f"z: expected ({n}, {self.estimator.n_outputs}) measurements, got {describe(z)}"
            )
        from flightid.estimation.gauss_newton import one_blas_thread

        # the matrices are small (n ≈ 10–20): threaded BLAS only waits for busy cores
        # (scipy.linalg.expm of 10 × 10: 1 ms threaded on the 2-core machine, 55 µs on one)
        with one_blas_thread():
            for k in range(n):
                self.feed(t[k], u[k], z[k])

    def _keep(self, t: float) -> None:
        est = self.estimator
        updates = getattr(est, "updates", None)
        if updates is not None:  # FTR: one history row per update
            for sample, t_update, theta, std in updates[self._updates_seen :]:
                self._times.append(t_update)
                self._samples.append(sample)
                self._theta.append(theta)
                self._std.append(std)
            self._updates_seen = len(updates)
            return
        self._times.append(t)
        self._samples.append(est.k)
        self._theta.append(est.theta)
        self._std.append(est.theta_std)
        self._states.append(est.states)

    def result(
        self,
        report: str = "last_10",
        *,
        units: Sequence[str] | None = None,
        initial: Sequence[float] | None = None,
        settings: Mapping[str, Any] | None = None,
        meta: Mapping[str, Any] | None = None,
    ):
        """The run so far as a ``RecursiveResult`` (needs ``record=True``).

        Args:
            report: the reported value: ``"last_N"`` (mean over the last N history rows:
                samples, or FTR updates) or ``"final"`` (the last row).
            units: per parameter, for the tables.
            initial: start value per parameter (None for the FTR).
            settings: the estimator's settings, kept in the result.
            meta: case information (title, file, model, outputs, output_units, R0,
                maneuvers) for the results.json entry.
        """
        from flightid.recursive.result import RecursiveResult

        if not self.record:
            raise InputError("result: the estimator was created with record=False (no history)")
        if not self._theta:
            raise InputError(
                f"result: no estimate recorded yet ({self.n_samples} samples fed"
                + (
                    f"; the FTR updates every {self.estimator.update_every} samples)"
                    if self.method == "ftr"
                    else ")"
                )
            )
        est = self.estimator
        augmented = getattr(est, "augmented", None)
        state_names = list(augmented.model.states) if augmented is not None else []
        covariance = None
        if augmented is not None and self.method != "efrls":
            # the parameter block of the last filter covariance P̂ (after the n_x states)
            covariance = np.array(est.P[augmented.n_x :, augmented.n_x :], dtype=float)
        return RecursiveResult(
            method=self.method,
            parameter_names=tuple(self.parameter_names),
            time_s=np.asarray(self._times),
            samples=np.asarray(self._samples, dtype=int),
            theta_history=np.vstack(self._theta),
            std_history=np.vstack(self._std),
            state_names=tuple(state_names),
            state_history=np.vstack(self._states) if self._states else np.empty((0, 0)),
            report=report,
            units=tuple(units) if units is not None else ("",) * len(self.parameter_names),
            initial=None if initial is None else tuple(float(v) for v in initial),
            n_samples=self.n_samples,
            nis=np.asarray(est.nis, dtype=float),
            warnings=tuple(est.health_warnings()),
            wall_time_s=self.wall_time_s,
            settings=dict(settings or {}),
            meta=dict(meta or {}),
            model=None if augmented is None else augmented.model,
            covariance=covariance,
        )


def run_recursive(
    estimator: RecursiveEstimatorBase,
    t: np.ndarray,
    u: np.ndarray,
    z: np.ndarray,
    report: str = "last_10",
    **result_options: Any,
):
    """Feed a whole record (``RecursiveEstimator.feed_block``) and return its result."""
    online = RecursiveEstimator(estimator)
    online.feed_block(t, u, z)
    return online.result(report, **result_options)
