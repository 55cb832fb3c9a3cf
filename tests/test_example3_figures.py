"""Time-history figures from plain arrays and from Estimate-like objects."""

from types import SimpleNamespace

import matplotlib.image as mpimg
import numpy as np
import pytest

from flightid.errors import InputError
from flightid.report.figures import (
    plot_inputs,
    plot_measured_vs_predicted,
    plot_residuals,
)


def _fake_result(n_maneuvers=1):
    t = np.tile(np.arange(0.0, 5.0001, 0.05), n_maneuvers)
    predicted = np.column_stack([np.sin(t), np.cos(t)])
    rng = np.random.default_rng(0)
    return SimpleNamespace(
        time=t,
        output_names=("beta", "p"),
        predicted=predicted,
        measured=predicted + 0.05 * rng.standard_normal(predicted.shape),
        maneuver_index=np.repeat(np.arange(n_maneuvers), t.size // n_maneuvers),
    )


def test_measured_vs_predicted_from_estimate_like(tmp_path):
    path = plot_measured_vs_predicted(_fake_result(), tmp_path / "a" / "fit.png",
                                      labels={"beta": "β, rad"}, title="fit")  # fmt: skip
    image = mpimg.imread(path)
    assert image.ndim == 3
    # one panel per output stacked vertically: taller than a single panel
    assert image.shape[0] > 300


def test_several_maneuvers_get_columns(tmp_path):
    one = mpimg.imread(plot_measured_vs_predicted(_fake_result(1), tmp_path / "one.png"))
    two = mpimg.imread(plot_measured_vs_predicted(_fake_result(2), tmp_path / "two.png"))
    assert two.shape[1] > one.shape[1]


def test_arrays_inputs_and_residuals(tmp_path):
    result = _fake_result()
    path = plot_measured_vs_predicted(
        None, tmp_path / "arrays.png", time=result.time, measured=result.measured,
        predicted=result.predicted, names=["beta", "p"],
    )  # fmt: skip
    assert path.exists()
    assert plot_inputs(result.time, {"da": np.sign(np.sin(result.time))},
                       tmp_path / "in.png").exists()  # fmt: skip
    assert plot_residuals(result, tmp_path / "res.png").exists()


def test_figure_errors_are_named(tmp_path):
    result = _fake_result()
    with pytest.raises(InputError, match="Estimate-like"):
        plot_measured_vs_predicted(None, tmp_path / "x.png")
    with pytest.raises(InputError, match="columns but 3 channel names"):
        plot_measured_vs_predicted(result, tmp_path / "x.png", names=["a", "b", "c"])
    with pytest.raises(InputError, match="rows"):
        plot_inputs(result.time, np.zeros((3, 1)), tmp_path / "x.png", names=["da"])
    with pytest.raises(InputError, match="names"):
        plot_inputs(result.time, np.zeros((result.time.size, 1)), tmp_path / "x.png")
