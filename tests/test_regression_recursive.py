"""Recursive least squares (growing and constant window) against batch fits."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from flightid.errors import InputError
from flightid.regression import RecursiveLeastSquares, SlidingWindowLeastSquares


def _batch(X, Y):
    return np.linalg.lstsq(X, Y, rcond=None)[0]


def _rel(a, b):
    return np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)


def _data(seed=0, n=300, p=4, ny=1):
    rng = np.random.default_rng(seed)
    X = np.column_stack([np.ones(n), rng.normal(size=(n, p - 1))])
    Y = X @ rng.normal(size=(p, ny)) + 0.1 * rng.normal(size=(n, ny))
    return X, (Y[:, 0] if ny == 1 else Y)


def test_growing_window_agrees_with_batch_at_every_row():
    X, y = _data()
    rls = RecursiveLeastSquares(X[:10], y[:10])
    worst = 0.0
    for k in range(10, X.shape[0]):
        est = rls.update(X[k], y[k])
        worst = max(worst, _rel(est, _batch(X[: k + 1], y[: k + 1])))
    assert worst < 1e-10
    np.testing.assert_allclose(rls.P, np.linalg.inv(X.T @ X), rtol=1e-9)


def test_constant_window_agrees_with_batch_over_the_window():
    X, Y = _data(1, n=400, p=5, ny=3)  # several responses at once (as in MNRES surfaces)
    w = 40
    swls = SlidingWindowLeastSquares(X[:w], Y[:w])
    worst = 0.0
    for k in range(w, X.shape[0]):
        est = swls.update(X[k], Y[k])
        worst = max(worst, _rel(est, _batch(X[k + 1 - w : k + 1], Y[k + 1 - w : k + 1])))
    assert worst < 1e-10
    Xw, Yw = swls.window()
    np.testing.assert_array_equal(Xw, X[-w:])
    assert swls.size == w
    np.testing.assert_allclose(swls.P, np.linalg.inv(Xw.T @ Xw), rtol=1e-9)


def test_errors():
    X, y = _data()
    with pytest.raises(InputError, match="at least n_p = 4 rows"):
        RecursiveLeastSquares(X[:3], y[:3])
    rls = SlidingWindowLeastSquares(X[:6], y[:6])
    with pytest.raises(InputError, match="rows of 4 regressors"):
        rls.update(X[6, :3], y[6])
    # a window of identical rows cannot determine the parameters
    same = SlidingWindowLeastSquares(X[:4], y[:4])
    with pytest.raises(InputError, match="singular"):
        for _ in range(4):
            same.update(np.array([1.0, 0.0, 0.0, 0.0]), 0.0)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_params=st.integers(1, 5),
    window_extra=st.integers(0, 20),
    n_updates=st.integers(1, 60),
    log_scales=st.lists(st.floats(-2, 2), min_size=5, max_size=5),
    offset=st.floats(-5, 5),
)
def test_property_recursive_equals_batch(
    seed, n_params, window_extra, n_updates, log_scales, offset
):
    # Random regressors with column scales 1e-2…1e2 and an offset (correlated columns);
    # both recursive forms must match batch fits over the same rows, component by component.
    rng = np.random.default_rng(seed)
    window = n_params + 2 + window_extra
    n = window + n_updates
    X = (rng.normal(size=(n, n_params)) + offset) * 10.0 ** np.array(log_scales[:n_params])
    y = X @ rng.normal(size=n_params) + rng.normal(size=n)
    conds = [np.linalg.cond(X[k : k + window]) for k in range(n - window + 1)]
    assume(max(conds) < 1e6)
    swls = SlidingWindowLeastSquares(X[:window], y[:window])
    rls = RecursiveLeastSquares(X[:window], y[:window])
    for k in range(window, n):
        sw = swls.update(X[k], y[k])
        gr = rls.update(X[k], y[k])
        ref_sw = _batch(X[k + 1 - window : k + 1], y[k + 1 - window : k + 1])
        ref_gr = _batch(X[: k + 1], y[: k + 1])
        assert _rel(sw, ref_sw) < 1e-10
        assert _rel(gr, ref_gr) < 1e-10
