"""``GlobalModelSettings(method="table")``: a global model whose coefficients are sums of
tables, fitted by ``fit_global_model``, predicted with intervals and support, saved and
reloaded, reported, and run from a case file.

References: the truth is a piecewise-linear function on the breakpoint grid, evaluated by
``scipy.interpolate.RegularGridInterpolator`` (linear, the same function the hat basis
spans); the interval coverage is a seeded Monte Carlo over white-noise realisations.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

from flightid.globalmodel import GlobalModel, GlobalModelSettings, fit_global_model
from flightid.globalmodel.variables import GlobalModelError

ALPHA = np.array([-0.1, 0.0, 0.1, 0.2])
DE = np.array([-0.2, 0.0, 0.2])
VALUES = np.array([[0.1, 0.3, 0.2], [0.5, 0.8, 0.6], [0.9, 1.0, 1.3], [0.7, 1.1, 1.6]])
TRUTH = RegularGridInterpolator((ALPHA, DE), VALUES)
SETTINGS = GlobalModelSettings(
    method="table",
    tables=[{"by": ["alpha", "de"]}],
    breakpoints={"alpha": ALPHA.tolist(), "de": DE.tolist()},
)


def _sweep(n: int, phase: float = 0.0):
    """α over [−0.1, 0.2] and δe over [−0.2, 0.2], slow and fast sines (one maneuver)."""
    t = np.arange(n)
    alpha = 0.05 + 0.15 * np.sin(t / 37.0 + phase)
    de = 0.2 * np.sin(t / 11.0 + 1.0 + phase)
    return alpha, de


def _fit(n=2000, sigma=0.05, seed=1, settings=SETTINGS, phase=0.0):
    rng = np.random.default_rng(seed)
    alpha, de = _sweep(n, phase)
    z = TRUTH(np.column_stack([alpha, de])) + sigma * rng.standard_normal(n)
    return fit_global_model({"alpha": alpha, "de": de, "CL": z}, ["CL"], ["alpha", "de"],
                            settings=settings)  # fmt: skip


def test_a_piecewise_linear_truth_is_recovered_at_the_breakpoints_within_3_sigma():
    coefficient = _fit()["CL"]
    tables = coefficient.tables
    assert tables is not None and coefficient.method == "table"
    z_scores = (tables.values[0] - VALUES) / tables.value_std[0]
    assert np.all(np.abs(z_scores) < 3.0), z_scores
    # the terms are the basis labels; the parameters carry the coefficient's name
    assert coefficient.terms[5] == "alpha:de[1,2]"
    assert coefficient.parameters[5] == "CL_alpha:de[1,2]"
    # predict between breakpoints is the bilinear interpolation of the fitted values
    points = {"alpha": [0.03, 0.17], "de": [-0.05, 0.11]}
    fitted = RegularGridInterpolator((ALPHA, DE), tables.values[0])
    expected = fitted(np.column_stack([points["alpha"], points["de"]]))
    np.testing.assert_allclose(coefficient.predict(points).value, expected, atol=1e-12)


def test_the_mean_band_covers_the_truth_at_held_out_points_at_its_level():
    """White noise, 200 seeds: the 95 % band of the mean covers the truth at held-out points
    in 92–98 % of the cases."""
    held = {"alpha": np.array([-0.05, 0.03, 0.12, 0.18]), "de": np.array([0.1, -0.13, 0.05, 0.0])}
    truth = TRUTH(np.column_stack([held["alpha"], held["de"]]))
    covered = []
    for seed in range(200):
        prediction = _fit(n=400, sigma=0.05, seed=seed)["CL"].predict(held)
        band = prediction.mean_interval()
        covered.append((band[:, 0] <= truth) & (truth <= band[:, 1]))
    rate = float(np.mean(covered))
    print(f"coverage of the 95 % mean band: {rate:.4f}")
    assert 0.92 <= rate <= 0.98, rate


def test_a_reloaded_model_predicts_identically():
    model = _fit(n=600)
    reloaded = GlobalModel.from_dict(json.loads(model.to_json()))
    points = {"alpha": [-0.3, 0.0, 0.07, 0.25], "de": [0.0, 0.3, -0.1, 0.1]}
    before, after = model.predict(points)["CL"], reloaded.predict(points)["CL"]
    for name in ("value", "lower", "upper", "function_lower", "function_upper",
                 "distance_ratio", "leverage_ratio"):  # fmt: skip
        np.testing.assert_array_equal(getattr(before, name), getattr(after, name))
    assert before.reason == after.reason
    np.testing.assert_array_equal(reloaded["CL"].tables.values[0], model["CL"].tables.values[0])
    assert "table alpha:de" in reloaded.summary()


def _with_an_empty_cell(smoothing: float):
    """Data avoid the cell α > 0.1, δe > 0 (the value at α = 0.2, δe = 0.2 has no data)."""
    settings = GlobalModelSettings(
        method="table",
        tables=[{"by": ["alpha", "de"]}],
        breakpoints={"alpha": ALPHA.tolist(), "de": DE.tolist()},
        smoothing=smoothing,
    )
    alpha, de = _sweep(3000)
    keep = ~((alpha > 0.1) & (de > 0.0))
    rng = np.random.default_rng(5)
    z = TRUTH(np.column_stack([alpha, de])) + 0.02 * rng.standard_normal(alpha.size)
    signals = {"alpha": alpha[keep], "de": de[keep], "CL": z[keep]}
    return fit_global_model(signals, ["CL"], ["alpha", "de"], settings=settings)["CL"]


def test_a_point_where_a_value_has_no_data_is_nan_and_flagged_empty_cell():
    coefficient = _with_an_empty_cell(0.0)
    assert coefficient.tables.dropped[0][3, 2]
    prediction = coefficient.predict({"alpha": [0.15, 0.0], "de": [0.1, 0.0]})
    assert np.isnan(prediction.value[0]) and np.isnan(prediction.upper[0])
    assert prediction.outside[0] and "empty-cell" in prediction.reason[0]
    assert np.isfinite(prediction.value[1]) and not prediction.outside[1]


def test_a_point_on_a_value_filled_by_smoothing_is_flagged_filled():
    coefficient = _with_an_empty_cell(1e-3)
    assert coefficient.tables.filled[0][3, 2] and not coefficient.tables.dropped[0].any()
    prediction = coefficient.predict({"alpha": [0.15, 0.0], "de": [0.1, 0.0]})
    assert np.isfinite(prediction.value[0])
    assert prediction.outside[0] and "filled" in prediction.reason[0]
    assert not prediction.outside[1]


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"method": "table"}, "tables: expected a non-empty list"),
        ({"method": "table", "tables": [{"by": ["alpha"]}]}, "missing ['alpha']"),
        (
            {
                "method": "table",
                "tables": [{"by": "alpha", "degree": 2}],
                "breakpoints": {"alpha": "auto"},
            },
            "tables[0].degree: expected 1 or 3",
        ),  # fmt: skip
        ({"method": "table", "tables": [{"by": ["a", "b", "c", "d"]}]}, "tables[0].by"),
        ({"method": "table", "tables": [{"by": "a", "rows": 1}]}, "unknown keys ['rows']"),
        ({"method": "table", "tables": [{"by": "a"}], "breakpoints": {"a": "many"}}, "'auto'"),
        ({"method": "table", "tables": [{"by": "a"}], "breakpoints": {"a": [1, 0]}}, "increasing"),
        ({"method": "table", "smoothing": -1.0}, "smoothing"),
        ({"tables": [{"by": "a"}]}, "only with method = 'table'"),
    ],
)
def test_table_settings_are_checked(options, message):
    with pytest.raises(GlobalModelError) as raised:
        GlobalModelSettings(**options)
    assert message in str(raised.value)


def test_a_table_variable_that_is_not_a_model_variable_is_named():
    settings = GlobalModelSettings(
        method="table", tables=[{"by": ["alpha"], "times": "qhat"}], breakpoints={"alpha": "auto"}
    )
    with pytest.raises(GlobalModelError, match=r"got \['qhat'\]"):
        _fit(n=300, settings=settings)


def test_auto_breakpoints_with_a_count_and_by_pse():
    counted = GlobalModelSettings(
        method="table", tables=[{"by": ["alpha", "de"]}],
        breakpoints={"alpha": "auto", "de": DE.tolist()}, breakpoint_count=5,
    )  # fmt: skip
    table = _fit(n=1500, settings=counted)["CL"].tables
    assert table.components[0].grid_shape == (5, 3)
    chosen = GlobalModelSettings(
        method="table", tables=[{"by": ["alpha"]}, {"by": ["de"]}],
        breakpoints={"alpha": "auto", "de": "auto"},
    )  # fmt: skip
    coefficient = _fit(n=1500, settings=chosen)["CL"]
    shapes = [c.grid_shape[0] for c in coefficient.tables.components]
    assert all(3 <= k <= 12 for k in shapes)


def test_the_carpet_and_the_table_section_draw_for_a_table_model():
    from flightid.report.globalmodel_reports import _terms_table, carpet_svg

    coefficient = _with_an_empty_cell(0.0)
    svg = carpet_svg(coefficient, "alpha", "de")
    assert svg.startswith("<svg") and "polyline" in svg
    section = _terms_table(coefficient)
    assert "Table <code>alpha:de</code>" in section and "no data" in section


# ------------------------------------------------------------------------ case file
HEAD = """
title = "table model test"
[data]
files = ["m1.csv", "m2.csv"]
data_dir = "."
format = "csv"
time = "time"
[data.inputs]
alpha = "alpha"
de = "de"
[data.outputs]
CL = "CL"

[[stages]]
kind = "global_model"
name = "tables"
variables = ["alpha", "de"]
method = "table"
tables = [{ by = ["alpha", "de"] }]
breakpoints = { alpha = [-0.1, 0.0, 0.1, 0.2], de = [-0.2, 0.0, 0.2] }
[stages.coefficients.CL]
response = "CL"
"""


def test_a_case_with_method_table_runs_through_flightid_run_json(tmp_path: Path, capsys):
    from flightid.cli.main import main
    from flightid.globalmodel import load_global_model

    rng = np.random.default_rng(7)
    for k, name in enumerate(("m1", "m2")):
        alpha, de = _sweep(800, phase=float(k))
        cl = TRUTH(np.column_stack([alpha, de])) + 0.01 * rng.standard_normal(alpha.size)
        time = np.arange(alpha.size) * 0.05
        rows = "\n".join(
            ",".join(f"{v:.17g}" for v in row) for row in zip(time, alpha, de, cl, strict=True)
        )
        (tmp_path / f"{name}.csv").write_text("time,alpha,de,CL\n" + rows + "\n")
    case = tmp_path / "case.toml"
    case.write_text(HEAD)
    out = tmp_path / "out"
    assert main(["run", str(case), "--json", "--quiet", "--out", str(out)]) == 0
    document = json.loads(capsys.readouterr().out)
    assert "tables" in json.dumps(document)
    jsonschema = pytest.importorskip("jsonschema")
    root = Path(__file__).resolve().parents[1]
    schema = json.loads((root / "docs" / "schema" / "results.schema.json").read_text())
    jsonschema.validate(document, schema)
    model = load_global_model(out / "global_model.json")
    tables = model["CL"].tables
    assert model["CL"].method == "table" and tables.components[0].grid_shape == (4, 3)
    assert np.all(np.abs(tables.values[0] - VALUES) < 3.0 * tables.value_std[0] + 1e-12)
    # the page lists the table and draws its carpet
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "Table <code>alpha:de</code>" in page
    assert (out / "figures" / "carpet_CL.svg").read_text().startswith("<svg")
