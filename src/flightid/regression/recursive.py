"""Recursive least squares: the growing window and the constant-size window of RP-1153.

Both keep the estimate S (n_p, n_y) of Y ≈ X S for one or several response columns Y, so the
same code serves a single coefficient (n_y = 1) and the surface fits of MNRES (many columns).

Growing window (rows are only added). With P = (XᵀX)⁻¹ and a new row a (1 × n_p) with
response y (1 × n_y), the matrix-inversion lemma gives

    k       = P aᵀ / (1 + a P aᵀ)                      gain
    S_{k+1} = S_k + k (y − a S_k)
    P_{k+1} = P_k − k a P_k

Constant-size window [3.9–3.10]. A new row a enters and the oldest row a° leaves:

    P_{k+1} = (P_k⁻¹ + aᵀa − a°ᵀa°)⁻¹                                        [3.9]
    S_{k+1} = S_k − P_{k+1} [ a°ᵀ y° − aᵀ y + (aᵀa − a°ᵀa°) S_k ]             [3.10]

(from A_{k+1} S_{k+1} = Xᵀ_{k+1} Y_{k+1} = A_k S_k + aᵀy − a°ᵀy° with A = P⁻¹). We carry
the information matrix A = P⁻¹ itself, update it by the rank-two change and solve with it
(a Cholesky factorisation per update) rather than propagating P by two rank-one lemmas,
which keeps the round-off from growing along long windows. Both forms are started from an
exact batch fit over the first rows, so they agree with batch fits over the same rows to
round-off (tested to 1e-10 relative).
"""

from __future__ import annotations

from collections import deque

import numpy as np
from scipy import linalg

from flightid.errors import InputError, describe

__all__ = ["RecursiveLeastSquares", "SlidingWindowLeastSquares"]


def _rows(X: np.ndarray, Y: np.ndarray, argument: str) -> tuple[np.ndarray, np.ndarray, bool]:
    """(X as (N, n_p), Y as (N, n_y), whether Y was one-dimensional)."""
    X = np.asarray(X, dtype=float)
    Y = np.asarray(Y, dtype=float)
    if X.ndim == 1:
        X = X[None, :]
    if X.ndim != 2:
        raise InputError(f"{argument}: expected rows of regressors (N, n_p), got {describe(X)}")
    vector = Y.ndim <= 1
    if Y.ndim == 0:
        Y = Y.reshape(1, 1)
    elif Y.ndim == 1:
        Y = Y[:, None] if X.shape[0] == Y.shape[0] else Y[None, :]
    if Y.shape[0] != X.shape[0]:
        raise InputError(
            f"{argument}: expected as many responses as regressor rows ({X.shape[0]}), "
            f"got {describe(Y)}"
        )
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(Y))):
        raise InputError(f"{argument}: values must be finite")
    return X, Y, vector


def _batch(X: np.ndarray, Y: np.ndarray, argument: str) -> tuple[np.ndarray, np.ndarray]:
    """(S, A = XᵀX) from a full-rank batch of rows, solved by QR."""
    n, p = X.shape
    if n < p:
        raise InputError(
            f"{argument}: the first batch needs at least n_p = {p} rows to be identifiable, got {n}"
        )
    Q, R = np.linalg.qr(X)
    d = np.abs(np.diag(R))
    if d.min() <= 1e-12 * d.max():
        raise InputError(f"{argument}: the first batch of rows is rank deficient")
    S = linalg.solve_triangular(R, Q.T @ Y)
    return S, X.T @ X


def _matching_rows(a, y, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Rows of ``a`` and ``y`` checked against an estimator of ``shape`` (regressors,
    responses)."""
    A_rows, Y_rows, _ = _rows(a, y, "a, y")
    if A_rows.shape[1] != shape[0] or Y_rows.shape[1] != shape[1]:
        raise InputError(
            f"a, y: expected rows of {shape[0]} regressors and "
            f"{shape[1]} responses, got {A_rows.shape} and {Y_rows.shape}"
        )
    return A_rows, Y_rows


class RecursiveLeastSquares:
    """Growing-window recursive least squares.

    Args:
        X0: regressors of a first batch of rows (N0 ≥ n_p, full rank) fitted exactly to
            start from.
        Y0: the dependent variable of those rows.
    """

    def __init__(self, X0: np.ndarray, Y0: np.ndarray) -> None:
        X0, Y0, self._vector = _rows(X0, Y0, "X0, Y0")
        self._S, A = _batch(X0, Y0, "X0")
        # P = (XᵀX)⁻¹
        self._P = linalg.cho_solve(linalg.cho_factor(A), np.eye(A.shape[0]))
        self.n_rows = X0.shape[0]

    @property
    def estimate(self) -> np.ndarray:
        """Current S (n_p,) or (n_p, n_y)."""
        return self._S[:, 0].copy() if self._vector else self._S.copy()

    @property
    def P(self) -> np.ndarray:
        """Current (XᵀX)⁻¹."""
        return self._P.copy()

    def update(self, a: np.ndarray, y: np.ndarray | float) -> np.ndarray:
        """Add one row (or several, one after the other) and return the new estimate."""
        A_rows, Y_rows = _matching_rows(a, y, self._S.shape)
        for row, resp in zip(A_rows, Y_rows, strict=True):
            Pa = self._P @ row
            # k = P aᵀ / (1 + a P aᵀ)
            k = Pa / (1.0 + row @ Pa)
            # S ← S + k (y − a S)
            self._S = self._S + np.outer(k, resp - row @ self._S)
            # P ← P − k a P   (symmetrised)
            self._P = self._P - np.outer(k, Pa)
            self._P = 0.5 * (self._P + self._P.T)
            self.n_rows += 1
        return self.estimate


class SlidingWindowLeastSquares:
    """Constant-size-window recursive least squares, [3.9–3.10].

    Args:
        X0: regressors of the first window (its length is the window size; full rank).
        Y0: the dependent variable of the first window.
    """

    def __init__(self, X0: np.ndarray, Y0: np.ndarray) -> None:
        X0, Y0, self._vector = _rows(X0, Y0, "X0, Y0")
        self._S, self._A = _batch(X0, Y0, "X0")
        self._window: deque[tuple[np.ndarray, np.ndarray]] = deque(
            (x.copy(), y.copy()) for x, y in zip(X0, Y0, strict=True)
        )

    @property
    def size(self) -> int:
        """Number of rows in the window."""
        return len(self._window)

    @property
    def estimate(self) -> np.ndarray:
        """Current S (n_p,) or (n_p, n_y)."""
        return self._S[:, 0].copy() if self._vector else self._S.copy()

    @property
    def P(self) -> np.ndarray:
        """Current P = (XᵀX)⁻¹ over the window."""
        return linalg.cho_solve(linalg.cho_factor(self._A), np.eye(self._A.shape[0]))

    def window(self) -> tuple[np.ndarray, np.ndarray]:
        """The rows (X, Y) now in the window, oldest first."""
        X = np.array([x for x, _ in self._window])
        Y = np.array([y for _, y in self._window])
        return X, (Y[:, 0] if self._vector else Y)

    def update(self, a: np.ndarray, y: np.ndarray | float) -> np.ndarray:
        """Add row ``a`` with response ``y``, drop the oldest row; return the new estimate."""
        A_rows, Y_rows = _matching_rows(a, y, self._S.shape)
        for row, resp in zip(A_rows, Y_rows, strict=True):
            old_row, old_resp = self._window.popleft()
            # aᵀa − a°ᵀa°
            change = np.outer(row, row) - np.outer(old_row, old_row)
            # P_{k+1}⁻¹ = P_k⁻¹ + aᵀa − a°ᵀa°                                    [3.9]
            self._A = self._A + change
            factor = self._cholesky()
            # S_{k+1} = S_k − P_{k+1}[a°ᵀy° − aᵀy + (aᵀa − a°ᵀa°) S_k]            [3.10]
            bracket = np.outer(old_row, old_resp) - np.outer(row, resp) + change @ self._S
            self._S = self._S - linalg.cho_solve(factor, bracket)
            self._window.append((row.copy(), resp.copy()))
        return self.estimate

    def _cholesky(self):
        try:
            return linalg.cho_factor(self._A)
        except linalg.LinAlgError:
            raise InputError(
                "a: after this update the rows in the window no longer determine all "
                "parameters (XᵀX is singular)"
            ) from None
