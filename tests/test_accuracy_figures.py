"""Accuracy figures render, and assess rejects bad arguments."""

from __future__ import annotations

import numpy as np
import pytest

from flightid.accuracy import assess, cost_slice, profile_curve, region_contour
from flightid.errors import InputError
from flightid.report.accuracy_figures import plot_profile, plot_region_slice
from test_accuracy_models import exp_estimate


def test_profile_and_slice_figures(tmp_path):
    result, data = exp_estimate(sigma=0.1)
    accuracy = assess(result, data, methods="profile", warn=False)
    contour = region_contour(result, data, accuracy)
    lo, hi = accuracy.ci_profile[2]
    curve = profile_curve(contour, accuracy.covariance, 2, np.linspace(lo, hi, 9))
    # at the profile limits the profile equals Δ (to the root-finding tolerance)
    assert curve.excess[0] == pytest.approx(accuracy.delta, rel=1e-3)
    assert curve.excess[-1] == pytest.approx(accuracy.delta, rel=1e-3)
    assert np.all(curve.excess[1:-1] < accuracy.delta)
    piece = cost_slice(contour, 1, 2, np.linspace(0.4, 1.2, 15), np.linspace(-0.2, 0.3, 11))
    assert piece.excess.shape == (15, 11) and piece.evaluations == 165
    for path in (
        plot_profile(curve, accuracy, tmp_path / "profile.png"),
        plot_region_slice(piece, accuracy, tmp_path / "slice.png"),
    ):
        assert path.stat().st_size > 10_000


@pytest.mark.parametrize(
    "kwargs",
    [
        {"methods": "bootstrap"},
        {"level": 95},
        {"kind": "joint"},
        {"budget": 0},
        {"parameters": ["nope"], "methods": "profile"},
    ],
)
def test_assess_rejects_bad_arguments(kwargs):
    result, data = exp_estimate(sigma=0.1)
    with pytest.raises(InputError):
        assess(result, data, warn=False, **kwargs)
