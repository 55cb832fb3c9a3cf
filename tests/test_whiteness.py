"""Residual whiteness (flightid.accuracy.whiteness): seeded white noise stays inside the
±1.96/√N band at about 95 % of the lags and passes Ljung–Box at about the nominal rate, an
AR(1) series is flagged; ρ(k) and Q against sums written here; maneuver boundaries; named
errors; the report and JSON carry it for output error and regression stages."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from flightid.accuracy.whiteness import WhitenessError, residual_whiteness
from flightid.cases import load_case, run_case
from flightid.cases.stages import case_signals, run_stages
from flightid.cli.main import main
from flightid.errors import InputError
from flightid.report.html import write_report


def _ar1(phi: float, n: int, seed: int) -> np.ndarray:
    e = np.random.default_rng(seed).normal(size=n)
    x = np.zeros(n)
    x[0] = e[0]
    for i in range(1, n):
        # x_i = φ x_{i−1} + e_i
        x[i] = phi * x[i - 1] + e[i]
    return x


def test_rho_and_ljung_box_equal_the_textbook_sums():
    x = _ar1(0.3, 500, seed=1)
    w = residual_whiteness(x, ["x"], max_lag=30, ljung_box_lags=10)
    # ρ(k) = Σ_{i} x_i x_{i+k} / Σ x_i²  (no de-meaning: residuals)
    rho = np.array([x[: 500 - k] @ x[k:] for k in range(31)]) / (x @ x)
    np.testing.assert_allclose(w.rho[:, 0], rho, rtol=1e-12)
    # Ljung & Box (1978): Q = N(N+2) Σ_{k=1..m} ρ_k²/(N−k) ~ χ²(m)
    q = 500 * 502 * np.sum(rho[1:11] ** 2 / (500 - np.arange(1, 11)))
    assert w.ljung_box[0] == pytest.approx(q, rel=1e-12)
    assert w.p_value[0] == pytest.approx(stats.chi2.sf(q, 10), rel=1e-10)
    assert w.band == pytest.approx(1.96 / np.sqrt(500))
    assert w.fraction_outside[0] == pytest.approx(np.mean(np.abs(rho[1:]) > w.band))


def test_white_noise_is_inside_the_band_about_95_percent_of_lags():
    # 40 seeded records × 3 outputs of N = 1000 white Gaussian samples, L = 100 lags
    fractions, rejected = [], []
    for seed in range(40):
        nu = np.random.default_rng(seed).normal(size=(1000, 3)) * [1.0, 0.01, 50.0]
        w = residual_whiteness(nu, ["a", "b", "c"], max_lag=100)
        fractions.append(w.fraction_outside)
        rejected.append(~w.white)
    # expected 5 % outside (slightly less: R̂(k) divides by N, shrinking ρ(k) by (N−k)/N)
    assert 0.03 < np.mean(fractions) < 0.06
    # Ljung–Box at the 5 % level rejects about 5 % of white records (6 of 120 expected)
    assert np.mean(rejected) < 0.12
    assert np.all(np.asarray(fractions) < 0.2)


def test_ar1_series_is_flagged():
    w = residual_whiteness(_ar1(0.7, 4000, seed=2)[:, None], ["ar1"], max_lag=50)
    # ρ(k) ≈ φ^k for an AR(1) series
    np.testing.assert_allclose(w.rho[1:4, 0], 0.7 ** np.arange(1, 4), atol=0.06)
    assert not w.white[0] and w.p_value[0] < 1e-10
    assert w.fraction_outside[0] > 0.15
    # a mildly coloured φ = 0.2 is still found by the portmanteau test
    assert not residual_whiteness(_ar1(0.2, 1000, seed=3), max_lag=50).white[0]


def test_lags_never_pair_samples_of_different_maneuvers():
    # two maneuvers of constant residual with opposite signs: within each the product is +1
    # at every lag, so ρ(k) = (N − 2k)/N; pairing across the boundary would lower it
    nu = np.r_[np.ones(100), -np.ones(100)]
    index = np.r_[np.zeros(100, int), np.ones(100, int)]
    w = residual_whiteness(nu, max_lag=10, maneuver_index=index)
    k = np.arange(11)
    np.testing.assert_allclose(w.rho[:, 0], (200 - 2 * k) / 200, rtol=1e-12)
    joined = residual_whiteness(nu, max_lag=10)
    assert joined.rho[5, 0] < w.rho[5, 0]
    assert w.n_maneuvers == 2
    # Ljung–Box with M = 2 maneuvers: N − M k products at lag k
    m = w.ljung_box_lags
    q = 200 * 202 * np.sum(w.rho[1 : m + 1, 0] ** 2 / (200 - 2 * np.arange(1, m + 1)))
    assert w.ljung_box[0] == pytest.approx(q, rel=1e-12)


def test_json_entry_and_summary():
    w = residual_whiteness(np.random.default_rng(4).normal(size=(400, 2)), ["p", "r"])
    entry = w.to_dict()
    assert entry["method"] == "ljung_box" and entry["max_lag"] == 100
    assert entry["ljung_box_lags"] == 20
    assert set(entry["outputs"]) == {"p", "r"}
    row = entry["outputs"]["r"]
    assert len(row["rho"]) == 101 and row["rho"][0] == pytest.approx(1.0)
    assert row["lags_outside"] == round(row["fraction_outside"] * 100)
    assert "Ljung–Box" in w.summary() and "p " in w.summary()


@pytest.mark.parametrize(
    ("args", "options", "match"),
    [
        (np.ones((2, 1)), {}, "N ≥ 3"),
        (np.full(10, np.nan), {}, "finite"),
        (np.ones((10, 2)), {"names": ["a"]}, "names: expected 2"),
        (np.ones(10), {"max_lag": 10}, "max_lag: expected 1 … 9"),
        (np.ones(10), {"max_lag": 4, "ljung_box_lags": 5}, "ljung_box_lags"),
        (np.ones(10), {"maneuver_index": np.zeros(9)}, "maneuver_index"),
        (np.ones(10), {"level": 1.5}, "level"),
    ],
)
def test_named_errors(args, options, match):
    with pytest.raises(WhitenessError, match=match) as info:
        residual_whiteness(args, **options)
    assert isinstance(info.value, InputError)


# ------------------------------------------------------------------ estimators and reports

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("FLIGHTID_DATA", ROOT / "../shared/data"))


def test_output_error_entry_carries_whiteness_and_white_noise_is_white(tmp_path):
    # the CSV walk-through: simulated short period with white measurement noise, correct
    # model — its output-error residuals are white (measured: p = 0.16 for α, 0.59 for q)
    run = run_case(load_case(ROOT / "examples/csv_walkthrough/my_case.toml"))
    entry = run.to_dict()["whiteness"]
    est = run.estimate
    expected = residual_whiteness(
        est.residuals, est.output_names, maneuver_index=est.maneuver_index
    )
    assert list(entry["outputs"]) == ["alpha", "q"]
    for j, name in enumerate(est.output_names):
        row = entry["outputs"][name]
        assert row["ljung_box_q"] == pytest.approx(expected.ljung_box[j], rel=1e-12)
        assert row["white"] and row["fraction_outside"] <= 0.1
    path = write_report(run, tmp_path / "out")
    page = path.read_text(encoding="utf-8")
    assert "Ljung–Box Q(20)" in page and "coloured</span>" not in page
    document = json.loads((tmp_path / "out" / "results.json").read_text(encoding="utf-8"))
    assert document["results"][0]["whiteness"]["outputs"]["q"]["white"] is True


@pytest.mark.skipif(not (DATA / "fvsysid").is_dir(), reason=f"data not found at {DATA}")
def test_regression_stage_whiteness_is_that_of_y_minus_x_theta(tmp_path, capsys):
    case = ROOT / "examples/cases/unstab_sp_equation_error_ls.toml"
    run = run_stages(load_case(case), DATA)
    entry = run.stages_dict()[0]["coefficients"]["qdot"]["whiteness"]
    # residuals by hand: q̇_m − X θ̂ with θ̂ from lstsq on the same signals
    signals = case_signals(load_case(case), DATA)
    X = np.column_stack([signals["w"], signals["q"], signals["de"]])
    y = signals["qdot"]
    nu = y - X @ np.linalg.lstsq(X, y, rcond=None)[0]
    expected = residual_whiteness(nu, ["qdot"])
    row = entry["outputs"]["qdot"]
    assert row["ljung_box_q"] == pytest.approx(expected.ljung_box[0], rel=1e-6)
    # ndiff8 turns the q noise into a residual with ρ(1) ≈ −0.44: coloured
    assert row["rho_1"] == pytest.approx(-0.437, abs=0.01) and row["white"] is False
    out = str(tmp_path / "out")
    assert main(["run", str(case), "--out", out, "--quiet", "--data-dir", str(DATA)]) == 0
    capsys.readouterr()
    # regression stages only: the stages' page is the folder's report.html
    page = (tmp_path / "out" / "report.html").read_text(encoding="utf-8")
    assert "Residual analysis" in page and "coloured</span>" in page
    assert "data:image/png;base64," in page
    assert (tmp_path / "out" / "figures" / "whiteness_0_regression.png").is_file()
