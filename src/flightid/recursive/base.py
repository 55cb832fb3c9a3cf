"""What every recursive estimator shares: checked settings, the sample-by-sample ``feed``
contract, covariance checks and the divergence error.

An estimator is fed one sample at a time, ``feed(t, u, z)`` (time in s, inputs and measured
outputs in the model's order and units). The first sample only corrects the start values;
every later one first predicts from the previous sample (the sample interval is the
difference of the two times), then corrects. After each call ``theta`` and ``theta_std``
hold the current parameter estimates and their standard deviations.

Filter health (house rule: a wrong answer must not look like a right one):

* a non-finite state or covariance raises ``RecursiveDivergenceError`` naming the sample;
* the covariance is kept symmetric, (P + Pᵀ)/2; an eigenvalue below −1e-9·max|λ| (lost
  positive semi-definiteness) is recorded as a warning with the sample number;
* the normalised innovation squared ε_k = ν_kᵀ S_k⁻¹ ν_k is recorded; an ε above the
  χ²(n_y) quantile 1 − 1e-6 is an innovation far outside its covariance (counted, and the
  result warns when they exceed 5 % of the samples);
* the mean ε̄ of the N recorded ε is n_y for a filter whose noise model describes the data
  (E[ε] = n_y, ε ~ χ²(n_y)); its statistical band n_y ± 3√(2 n_y / N) is too narrow for real
  data, whose noise model is never exact, so the result warns when ε̄ lies a factor 10 or
  more outside n_y: ε̄ > 10 n_y (the filter's S far too small: its σ are optimistic) or
  ε̄ < n_y / 10 (S far too large: e.g. an absurd process noise Q lets the states follow
  the measurements, the parameters stop learning and their σ say nothing about the data).
  Any of these warnings turns the result's status to ``inconsistent``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from flightid.errors import FlightIdError, InputError, describe

__all__ = [
    "NIS_FACTOR",
    "RecursiveDivergenceError",
    "RecursiveEstimatorBase",
    "diagonal_matrix",
    "float_array",
    "symmetric_sqrt",
]


# a mean normalised innovation squared this factor above or below n_y is inconsistent
NIS_FACTOR = 10.0


class RecursiveDivergenceError(FlightIdError, ArithmeticError):
    """A recursive filter produced a non-finite state or covariance (it diverged)."""

    def __init__(self, message: str, *, sample: int | None = None) -> None:
        super().__init__(message)
        self.sample = sample


def float_array(value: object, argument: str, what: str = "numbers") -> np.ndarray:
    """``value`` as a float array, or ``InputError`` naming ``argument`` for strings,
    None, booleans and anything numpy cannot read as real numbers."""
    if value is None or isinstance(value, (str, bytes, bool, np.bool_)):
        raise InputError(f"{argument}: expected {what}, got {describe(value)}")
    if isinstance(value, (complex, np.complexfloating)) or np.iscomplexobj(value):
        raise InputError(f"{argument}: expected real {what}, got complex {describe(value)}")
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{argument}: expected {what}, got {describe(value)}") from None
    if np.asarray(value).dtype == bool:
        raise InputError(f"{argument}: expected {what}, got booleans {describe(value)}")
    return array


def diagonal_matrix(
    value: float | Sequence[float], n: int, argument: str, *, positive: bool = False
) -> np.ndarray:
    """``value``·I (a number) or diag(value) (a list of n numbers), all ≥ 0 (> 0 with
    ``positive``) and finite."""
    array = float_array(value, argument, f"a number or a list of {n} numbers")
    if array.ndim > 1 or (array.ndim == 1 and array.size != n):
        raise InputError(
            f"{argument}: expected a number or a list of {n} numbers, got {describe(value)}"
        )
    if not np.all(np.isfinite(array)) or np.any(array < 0):
        raise InputError(f"{argument}: expected finite values >= 0, got {np.ravel(array).tolist()}")
    if positive and np.any(array == 0):
        raise InputError(
            f"{argument}: expected values > 0 (a zero variance makes the filter's gain "
            f"singular), got {np.ravel(array).tolist()}"
        )
    return np.diag(np.broadcast_to(array, (n,)).astype(float))


def symmetric_sqrt(P: np.ndarray) -> np.ndarray:
    """The symmetric principal square root S of a symmetric PSD matrix, S·S = P.

    For symmetric P = V Λ Vᵀ (eigendecomposition) the principal root is V Λ^½ Vᵀ, which is
    what scipy.linalg.sqrtm returns for such a matrix, at a fraction of the cost; round-off
    negative eigenvalues (≥ −1e-9·max|λ|) are taken as 0.
    """
    from scipy import linalg

    eigenvalues, vectors = linalg.eigh(P)
    floor = -1e-9 * max(float(np.max(np.abs(eigenvalues))), 1e-300)
    if eigenvalues[0] < floor:
        raise RecursiveDivergenceError(
            f"covariance: not positive semi-definite (smallest eigenvalue {eigenvalues[0]:.3g}, "
            f"largest {eigenvalues[-1]:.3g}); the square root for the sigma points does not exist"
        )
    # √P = V diag(√λ) Vᵀ
    return (vectors * np.sqrt(np.clip(eigenvalues, 0.0, None))) @ vectors.T


def _check_series(value: np.ndarray, n: int, argument: str) -> np.ndarray:
    array = float_array(value, argument, f"{n} values")
    if array.shape != (n,):
        raise InputError(f"{argument}: expected {n} values, got {describe(value)}")
    if not np.all(np.isfinite(array)):
        raise InputError(f"{argument}: expected finite values, got {array.tolist()}")
    return array


class RecursiveEstimatorBase:
    """Sample bookkeeping shared by the estimators (``feed`` calls ``_first`` / ``_step``).

    Subclasses set ``n_inputs``, ``n_outputs``, ``parameter_names`` and implement
    ``_first(t, u, z)`` and ``_step(t_prev, t, u_prev, u, z)``, and the properties
    ``theta``/``theta_std`` (current parameter estimates and standard deviations).
    """

    method = "base"
    n_inputs: int
    n_outputs: int
    parameter_names: list[str]

    def reset(self) -> None:
        self.k = 0  # samples fed so far
        self._t_prev: float | None = None
        self._u_prev: np.ndarray | None = None
        self.warnings: list[str] = []
        self.nis: list[float] = []  # ε_k = νᵀ S⁻¹ ν per corrected sample
        self.innovations: list[np.ndarray] = []  # ν_k = z_k − ỹ_k per corrected sample
        self.covariance_warnings = 0

    def feed(self, t: float, u: Sequence[float], z: Sequence[float]) -> None:
        """Process one sample: time ``t`` (s), inputs ``u``, measured outputs ``z``."""
        u = _check_series(u, self.n_inputs, "u")
        z = _check_series(z, self.n_outputs, "z")
        if isinstance(t, (bool, np.bool_)) or not isinstance(t, (int, float, np.number)):
            raise InputError(f"t: expected a time in s (a number), got {describe(t)}")
        t = float(t)
        if not np.isfinite(t):
            raise InputError(f"t: expected a finite time, got {t}")
        if self._t_prev is not None and not t > self._t_prev:
            raise InputError(
                f"t: sample {self.k + 1} at {t} s does not follow the previous one at "
                f"{self._t_prev} s (times must increase)"
            )
        u = self._model_input(t, u)
        self.k += 1
        self._t_current = t
        try:
            # overflow / invalid values are caught below and by _checked as divergence
            with np.errstate(over="ignore", invalid="ignore"):
                if self.k == 1:
                    self._first(t, u, z)
                else:
                    self._step(self._t_prev, t, self._u_prev, u, z)
        except FlightIdError:
            raise
        except (np.linalg.LinAlgError, ValueError, FloatingPointError) as exc:
            # a singular or non-finite innovation covariance, inf/NaN reaching LAPACK
            raise RecursiveDivergenceError(
                f"{self.method}: the filter diverged at sample {self.k} (t = {t} s): "
                f"{type(exc).__name__}: {exc}",
                sample=self.k,
            ) from None
        self._t_prev, self._u_prev = t, u

    def _model_input(self, t: float, u: np.ndarray) -> np.ndarray:
        """The inputs the estimator works with at time ``t`` for the fed inputs ``u`` (the
        fed ones; a filter whose model delays inputs returns the delayed ones)."""
        return u

    # helpers for the state-space filters -------------------------------------------

    def _checked(self, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x, (P + Pᵀ)/2) after the finiteness and PSD checks of the module docstring."""
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(P))):
            raise RecursiveDivergenceError(
                f"{self.method}: the filter diverged at sample {self.k} (t = {self._t_now} s): "
                "non-finite state or covariance",
                sample=self.k,
            )
        P = 0.5 * (P + P.T)
        eigenvalues = np.linalg.eigvalsh(P)
        if eigenvalues[0] < -1e-9 * max(float(np.max(np.abs(eigenvalues))), 1e-300):
            self.covariance_warnings += 1
            if self.covariance_warnings == 1:
                self.warnings.append(
                    f"covariance not positive semi-definite first at sample {self.k} "
                    f"(smallest eigenvalue {eigenvalues[0]:.3g})"
                )
        return x, P

    def _innovation(self, nu: np.ndarray, S: np.ndarray | None) -> None:
        """Record ν and ε = νᵀ S⁻¹ ν of this sample (ε only where S is an innovation
        covariance)."""
        self.innovations.append(nu)
        if S is None:
            return
        try:
            # ε_k = ν_kᵀ S_k⁻¹ ν_k
            eps = float(nu @ np.linalg.solve(S, nu))
        except np.linalg.LinAlgError:
            eps = float("inf")
        self.nis.append(eps)

    @property
    def _t_now(self) -> float | None:
        return getattr(self, "_t_current", None)

    def health_warnings(self) -> list[str]:
        """The warnings collected so far, plus the innovation test over all samples."""
        from scipy import stats

        warnings = list(self.warnings)
        if self.nis:
            limit = float(stats.chi2.ppf(1.0 - 1e-6, self.n_outputs))
            outside = int(np.sum(~(np.asarray(self.nis) <= limit)))
            if outside > 0.05 * len(self.nis):
                warnings.append(
                    f"{outside} of {len(self.nis)} innovations lie far outside their covariance "
                    f"(ν'S⁻¹ν > {limit:.1f}, the χ²({self.n_outputs}) 1−1e-6 quantile): the "
                    "filter's noise model does not describe the data"
                )
            warnings += self._mean_nis_warning()
        return warnings

    def _mean_nis_warning(self) -> list[str]:
        """The warning for a mean ε̄ a factor ``NIS_FACTOR`` or more away from n_y (module
        docstring); empty when inside."""
        values = np.asarray(self.nis, dtype=float)
        values = values[np.isfinite(values)]
        if not values.size:
            return []
        # ε̄ = (1/N) Σ ε_k, expected n_y
        mean = float(np.mean(values))
        n_y = self.n_outputs
        low, high = n_y / NIS_FACTOR, n_y * NIS_FACTOR
        if low <= mean <= high:
            return []
        if mean < low:
            why = (
                "far below: the predicted innovation covariance S is much larger than the "
                "innovations (process noise q_states or r0 far too large?); the parameter σ "
                "do not describe the data"
            )
        else:
            why = (
                "far above: the innovations are much larger than their covariance S "
                "(q_states or r0 too small, or a model error); the σ are optimistic"
            )
        return [
            f"inconsistent filter: mean normalised innovation squared ν'S⁻¹ν = {mean:.3g} "
            f"over {values.size} samples, expected {n_y} (χ²({n_y}); accepted "
            f"{low:.3g}–{high:.3g}), {why}"
        ]
