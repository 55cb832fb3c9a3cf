"""The HTML report: stands alone, names its provenance, and shows the diagnostics it promises
(units, Theil U, residual autocorrelation, coloured-residual σ, cost history with the R
re-estimations, det R, prediction check, optimality)."""

from __future__ import annotations

import base64
import dataclasses
import hashlib
import re
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from flightid import __version__
from flightid.accuracy import assess
from flightid.cases import load_case, run_case
from flightid.cases.run import Prediction
from flightid.data import FlightData
from flightid.errors import InputError
from flightid.estimation import estimate
from flightid.report import diagnostics
from flightid.report.diagnostics import (
    ColouredSigma,
    coloured_sigma,
    log_det_r,
    residual_autocorrelation,
    theil_u,
)
from flightid.report.html import render_figures, render_html, write_report

ROOT = Path(__file__).resolve().parents[1]
WALK_CASE = ROOT / "examples/csv_walkthrough/my_case.toml"


@pytest.fixture(scope="module")
def walk_run():
    """The CSV walk-through case run once (short-period, 501 samples, MAX noise policy)."""
    return run_case(load_case(WALK_CASE))


@pytest.fixture(scope="module")
def walk_page(walk_run, tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "out"
    path = write_report(walk_run, out)
    return path, path.read_text(encoding="utf-8")


# ------------------------------------------------------------------ the numbers


def test_theil_u_closed_forms():
    rng = np.random.default_rng(1)
    z = rng.normal(size=(200, 2)) + 3.0
    # y = z: no residual, U = 0
    assert np.allclose(theil_u(z, z), 0.0)
    # y = c·z (c > 0): U = |1 − c|·rms z / ((1 + c)·rms z) = |1 − c| / (1 + c)
    assert np.allclose(theil_u(z, 0.5 * z), 0.5 / 1.5)
    # y = −z: U = 2 rms z / (2 rms z) = 1, the worst value
    assert np.allclose(theil_u(z, -z), 1.0)
    with pytest.raises(InputError, match="one shape"):
        theil_u(z, z[:10])


def test_residual_autocorrelation_of_an_ar1_sequence():
    # AR(1) ν_k = φ ν_{k−1} + e_k has ρ(k) = φ^k (closed form); N = 20000, seed 3
    rng = np.random.default_rng(3)
    phi, n = 0.8, 20_000
    e = rng.normal(size=n)
    nu = np.empty(n)
    nu[0] = e[0]
    for k in range(1, n):
        nu[k] = phi * nu[k - 1] + e[k]
    rho, band = residual_autocorrelation(np.column_stack([nu, e]), 5)
    assert band == pytest.approx(1.96 / np.sqrt(n))
    assert np.allclose(rho[:, 0], phi ** np.arange(6), atol=0.03)
    # the white column stays inside the band (its 5 lags, 95 % each: expected 0.25 outside)
    assert np.all(np.abs(rho[1:, 1]) < 2 * band) and rho[0, 1] == 1.0


def test_log_det_r():
    det, log_det = log_det_r(np.array([2.0, 0.5, 4.0]))
    assert det == pytest.approx(4.0) and log_det == pytest.approx(np.log(4.0))


def test_noise_update_passes_mark_the_first_cost_under_the_new_r(walk_run):
    est = walk_run.estimate
    passes = est.noise_update_passes
    assert len(passes) == est.noise_cycles >= 1
    n_data = est.n_data
    for p in passes:
        if p < len(est.cost_history):
            # MAX: R = R̂ from the residuals at θ, so J(θ) = Σ νᵀR̂⁻¹ν = N·n_o at that θ
            assert est.cost_history[p] == pytest.approx(n_data, rel=0.01)
            # the cost before the update was under the old R: far from N·n_o here
            assert abs(est.cost_history[p - 1] - n_data) > 0.1 * n_data
    assert est.to_dict()["noise_update_passes"] == list(passes)


def test_max_policy_records_ln_det_r_and_the_cost_at_fixed_r_per_pass(walk_run):
    """MAX policy (J = Σ νᵀR⁻¹ν, R re-estimated between Gauss–Newton passes): the final cost
    is N·n_o whatever the fit; ln det R̂ per pass shows the convergence instead."""
    est = walk_run.estimate
    n_passes = len(est.cost_history)
    history = np.asarray(est.log_det_r_history)
    assert history.shape == (n_passes,) and len(est.r_history) == n_passes
    # at R = R̂ of the residuals themselves J = Σ_k N R̂_k / R̂_k = N·n_o (here 501·2 = 1002)
    assert est.cost == pytest.approx(est.n_data, rel=1e-12)
    assert est.cost_history[0] == pytest.approx(est.n_data, rel=1e-12)
    # ln det R̂ does not jump at R updates: non-increasing from the first update on
    first = est.noise_update_passes[0]
    assert np.all(np.diff(history[first - 1 :]) <= 1e-9 * np.abs(history[-1]))
    assert history[-1] < history[0] - 1.0  # and it fell on the way
    # the last entry by hand: R̂_k = mean ν_k², ln det R̂ = Σ ln R̂_k, the final R's
    r_hat = np.mean(est.residuals**2, axis=0)
    assert history[-1] == pytest.approx(np.sum(np.log(r_hat)), rel=1e-9)
    assert history[-1] == pytest.approx(est.log_det_r, rel=1e-9)
    # the cost at fixed R of the last pass by hand: Σ_i Σ_k ν_ik² / R_k, R the one in force
    r_fixed = np.asarray(est.r_history[-1])
    assert est.cost_history[-1] == pytest.approx(np.sum(est.residuals**2 / r_fixed), rel=1e-9)
    # the last pass ran under the R before the final update: its cost is not N·n_o
    assert not np.allclose(r_fixed, est.r_diag, rtol=1e-6, atol=0.0)
    document = est.to_dict()
    assert document["log_det_r_history"] == pytest.approx(list(history))
    assert document["log_det_r"] == pytest.approx(est.log_det_r)
    assert document["r_history"][-1] == pytest.approx(list(r_fixed))


def test_convergence_section_shows_ln_det_r_and_the_cost_at_fixed_r(walk_run, walk_page):
    _, page = walk_page
    est = walk_run.estimate
    assert "<th>ln det R̂ [–]</th>" in page and "<th>cost J at fixed R [–]</th>" in page
    assert "ln det R̂ per pass (top) and cost J at fixed R (bottom)" in page
    last = len(est.cost_history) - 1
    row = re.search(rf"<tr><td>{last}</td>(.*?)</tr>", page).group(1)
    assert f"<td>{est.log_det_r_history[-1]:.8g}</td>" in row
    assert f"<td>{est.cost_history[-1]:.6g}</td>" in row


def _coloured_estimate(walk_run):
    """The walk-through model estimated on its data plus low-pass (AR(1), φ = 0.97, seed 11)
    noise: residuals strongly coloured."""
    data = walk_run.maneuvers[0]
    rng = np.random.default_rng(11)
    noise = np.zeros_like(data.outputs)
    for k in range(1, noise.shape[0]):
        noise[k] = 0.97 * noise[k - 1] + rng.normal(size=noise.shape[1])
    noise *= np.array([3e-4, 1e-3])  # rad, rad/s
    coloured = FlightData(
        data.time,
        inputs=dict(zip(data.input_names, data.inputs.T, strict=True)),
        outputs=dict(zip(data.output_names, (data.outputs + noise).T, strict=True)),
        units=data.units,
        name="coloured",
    )
    result = estimate(
        walk_run.model, coloured, noise="max", input_interpolation="zoh", compiled=False
    )
    return result, coloured


@pytest.fixture(scope="module")
def coloured(walk_run):
    return _coloured_estimate(walk_run)


def test_coloured_sigma_agrees_with_the_accuracy_assessment(coloured):
    est, data = coloured
    default = coloured_sigma(est)
    accuracy = assess(est, data, methods="cr", polish=False, compiled=False, warn=False)
    # the report's default (no assessment run) and flightid.accuracy give the same numbers
    assert default.lag == accuracy.coloured_lag > 0
    assert np.allclose(default.std_coloured, accuracy.std_coloured, rtol=1e-10)
    assert np.allclose(default.std_cr, accuracy.std_scaled, rtol=1e-10)
    assert default.understated and default.worst[1] > diagnostics.COLOURED_RATIO_WARNING


def test_warning_only_when_coloured_and_understated():
    base = dict(names=("a", "b"), std_cr=np.ones(2), std_coloured=np.ones(2), s2=1.0)
    assert not ColouredSigma(ratio=np.array([1.0, 1.2]), lag=3, **base).understated
    assert not ColouredSigma(ratio=np.array([1.0, 2.0]), lag=0, **base).understated
    worried = ColouredSigma(ratio=np.array([1.0, 2.0]), lag=3, **base)
    assert worried.understated and worried.worst == ("b", 2.0)


# ------------------------------------------------------------------ the page


def test_page_stands_alone(walk_page):
    path, page = walk_page
    # the SVG figures (the default) are inline: the page holds each file's text
    figures = sorted((path.parent / "figures").glob("*"))
    assert [f.suffix for f in figures] == [".svg"] * 3  # one maneuver, autocorrelation, cost
    for figure in figures:
        assert figure.read_text(encoding="utf-8") in page, figure.name
    assert page.count("<svg xmlns=") == 3 and page.count("</svg>") == page.count("<svg")
    assert re.findall(r"src=['\"]([^'\"]*)['\"]", page) == []
    assert "<link" not in page and "<script" not in page
    # the only links are to the files of the result folder itself, by relative name
    hrefs = re.findall(r"href=['\"]([^'\"]*)['\"]", page)
    assert hrefs and all((path.parent / h).is_file() for h in hrefs)
    assert not any("://" in h or h.startswith("/") for h in hrefs)
    # the figures are also kept as files beside it
    assert (path.parent / "figures" / "convergence.svg").is_file()


def test_png_figures_are_embedded_as_base64_images(walk_run, tmp_path):
    case = dataclasses.replace(
        walk_run.case, output={**walk_run.case.output, "figure_format": "png"}
    )
    path = write_report(dataclasses.replace(walk_run, case=case), tmp_path / "out")
    page = path.read_text(encoding="utf-8")
    sources = re.findall(r"src=['\"]([^'\"]*)['\"]", page)
    assert len(sources) == 3  # one maneuver, autocorrelation, cost history
    for source in sources:
        assert source.startswith("data:image/png;base64,")
        png = base64.b64decode(source.split(",", 1)[1])
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in (path.parent / "figures").iterdir()) == [
        "autocorrelation.png",
        "convergence.png",
        "fit_1_my_flight.png",
    ]
    assert "<svg" not in page


def test_page_provenance(walk_page):
    _, page = walk_page
    digest = hashlib.sha256(WALK_CASE.read_bytes()).hexdigest()
    assert f"flightid {__version__}" in page
    assert digest in page and str(WALK_CASE) in page
    stamp = re.search(r"(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d) UTC", page)
    made = datetime.strptime(stamp.group(1), "%Y-%m-%d %H:%M:%S").replace(tzinfo=UTC)
    assert abs((datetime.now(UTC) - made).total_seconds()) < 3600


def test_page_numbers_and_units(walk_run, walk_page):
    _, page = walk_page
    est = walk_run.estimate
    # units of the outputs (FlightData.units from the case's channel `to`)
    assert "<td>rad</td>" in page and "<td>rad/s</td>" in page
    # Theil U per output, computed here from its definition
    z, y = est.measured, est.predicted
    for j in range(2):
        u = np.sqrt(np.mean((z[:, j] - y[:, j]) ** 2)) / (
            np.sqrt(np.mean(z[:, j] ** 2)) + np.sqrt(np.mean(y[:, j] ** 2))
        )
        assert f"<td>{u:.3g}</td>" in page
    # det R and ln det R of the final R
    assert f"{np.prod(est.r_diag):.6g}" in page and f"{np.sum(np.log(est.r_diag)):.8g}" in page
    assert "[rad² · (rad/s)²]" in page
    # the ±1.96/√N band, the optimality and the R re-estimations in the cost table
    assert f"±{1.96 / np.sqrt(est.time.shape[0]):.3g}" in page
    assert f"{est.optimality_sigma:.3g}" in page
    first = est.noise_update_passes[0]
    assert re.search(rf"<tr><td>{first}</td>.*?R re-estimated before this pass", page)
    # white residuals in this case: no warning, and the coloured σ column is there anyway
    assert "coloured σ" in page and "understate" not in page


def test_page_warns_on_coloured_residuals_and_shows_the_prediction(walk_run, coloured):
    est, data = coloured
    held = walk_run.maneuvers[0]
    prediction = Prediction.from_outputs(
        "held-out", held.time, held.outputs, est.predicted, est.output_names
    )
    prediction = dataclasses.replace(
        prediction, inputs=held.inputs, input_names=held.input_names, units=dict(held.units)
    )
    run = dataclasses.replace(walk_run, estimate=est, maneuvers=(data,), predictions=(prediction,))
    page = render_html(run, render_figures(run, dpi=40))
    worst, ratio = coloured_sigma(est).worst
    assert f"understate the uncertainty by up to ×{ratio:.2g}" in page
    assert f"<code>{worst}</code>" in page
    # both columns are kept; the default one (the σ every other output reports) is labelled
    assert est.std_kind == "coloured"
    assert "<th>coloured σ (default)</th>" in page and "<th>CR σ</th>" in page
    assert "σ reported by default" in page
    assert "Prediction check on held-out maneuvers" in page
    rms = np.sqrt(np.mean((held.outputs - est.predicted) ** 2, axis=0))
    assert all(f"<td>{e:.4g}</td>" in page for e in rms)
    # fit, prediction, autocorrelation, cost: inline SVG (the default figure format)
    assert page.count("<svg xmlns=") == 4 and "data:image/png" not in page
    png_page = render_html(run, render_figures(run, dpi=40, figure_format="png"))
    assert png_page.count("data:image/png;base64,") == 4 and "<svg" not in png_page


def test_estimates_show_the_digits_their_sigma_supports(walk_run):
    """1234.56789 ± 0.00012: σ to two significant digits, the estimate and its 95 % interval
    to σ's decimal place (10⁻⁵) in the text summary and the page — six significant digits
    (1234.57) would hide what σ resolves."""
    est = walk_run.estimate
    i = int(np.flatnonzero(est.free)[0])
    values, std = np.array(est.values), np.array(est.std)
    values[i], std[i] = 1234.56789, 0.00012
    changed = dataclasses.replace(est, values=values, std=std, std_cr=std)
    name = est.names[i]
    (row,) = [line for line in changed.summary().splitlines() if line.startswith(f"{name} ")]
    assert " 1234.56789 " in row and " 0.00012 " in row
    run = dataclasses.replace(walk_run, estimate=changed, accuracy=None)
    page = render_html(run, None)
    # z₀.₉₇₅·σ = 1.959964·0.00012 = 0.000235: [1234.567655, 1234.568125] to 10⁻⁵
    row = re.search(rf"<tr><td>{name}</td>(.*?)</tr>", page).group(1)
    assert "<td>1234.56789</td>" in row and "<td>0.00012</td>" in row
    assert "<td>1234.56765</td>" in row and "<td>1234.56813</td>" in row


def test_output_error_estimates_csv_has_the_columns_of_every_estimator(walk_page):
    """estimates.csv of an output-error run has the columns every other estimator's folder
    writes (flightid.report.page.CSV_COLUMNS), in that order."""
    import csv

    from flightid.report.page import CSV_COLUMNS

    path, _ = walk_page
    with (path.parent / "estimates.csv").open(encoding="utf-8") as stream:
        assert next(csv.reader(stream)) == list(CSV_COLUMNS)


def test_page_splits_the_evaluations(walk_run, walk_page):
    # the evaluations to the optimum, confirming it and for the bounds, each named
    _, page = walk_page
    est = walk_run.estimate
    assert est.evaluations_to_optimum + est.confirmation_evaluations == (est.equivalent_evaluations)
    assert (
        f"{est.total_evaluations}: {est.evaluations_to_optimum} to the optimum, "
        f"{est.confirmation_evaluations} confirming it, {est.accuracy_evaluations} for the "
        "information matrix"
    ) in page
