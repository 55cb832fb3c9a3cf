"""One report layout and one folder layout for every estimator.

Each estimator's folder holds results.json, estimates.csv (the output-error run's columns),
a time-history CSV, figures/*.png and report.html; each report.html has, in this order,
the provenance (case file and its SHA-256), a one-line status, the estimates with both σ,
the correlation matrix, the residual or innovation analysis, the estimator's fits and the
file list, and no <pre> summary as its main content. The rounding that follows σ is
checked against hand-written numbers.
"""

from __future__ import annotations

import csv
import hashlib
import json
import re
from pathlib import Path

import numpy as np
import pytest

from data_paths import DATA, needs_data
from flightid.numbers import format_with_sigma
from flightid.report.page import (
    EstimateRow,
    estimates_section,
    format_interval,
)

ROOT = Path(__file__).resolve().parents[1]
# the columns of the output-error run's estimates.csv (flightid.report.html.write_csv)
OUTPUT_ERROR_COLUMNS = [
    "name", "unit", "value", "std", "std_cr", "std_kind", "relative_percent", "lower", "upper",
    "initial", "free", "role",
]  # fmt: skip


# ------------------------------------------------------------------------------ helpers


def _headings(page: str) -> list[str]:
    return re.findall(r"<h2>(.*?)</h2>", page)


def _check_page(directory: Path, residual_heading: str, fit_words: list[str]) -> str:
    """The folder's common files and the page's common sections, in order."""
    for name in ("results.json", "estimates.csv", "report.html"):
        assert (directory / name).stat().st_size > 0, name
    assert list((directory / "figures").glob("*.png")), "no figures"
    json.loads((directory / "results.json").read_text(encoding="utf-8"))
    with open(directory / "estimates.csv", newline="", encoding="utf-8") as stream:
        assert next(csv.reader(stream)) == OUTPUT_ERROR_COLUMNS
    page = (directory / "report.html").read_text(encoding="utf-8")
    headings = _headings(page)
    # provenance and status come before the first section
    head = page[: page.index("<h2>")]
    assert "case file SHA-256" in head and "data files" in head and "flightid" in head
    assert re.search(r"<p class='status (ok|bad)'>[^<]+</p>", head)
    assert headings[:3] == ["Estimates", "Correlation matrix [–]", residual_heading]
    assert headings[-1] == "Files"
    fits = " ".join(headings[3:-1])
    for word in fit_words:
        assert word in fits, (word, headings)
    # both σ columns, and which is the default
    assert "<th>σ (default)</th><th>Cramér–Rao σ</th><th>default σ is</th>" in page
    # a <pre> only inside the collapsed text summary at the end
    assert page.count("<pre>") == page.count("<details><summary>Text summary")
    assert page.index("<details>") > page.index("<h2>Files</h2>")
    # every file of the folder is linked
    for path in directory.rglob("*"):
        if path.is_file() and not path.name.startswith("."):
            assert f"href='{path.relative_to(directory).as_posix()}'" in page, path
    return page


# ------------------------------------------------------------------------------ numbers


def test_value_follows_sigma_to_two_significant_digits():
    # hand-written: σ 0.00033 has 2 significant digits at 5 decimals; the value follows
    assert format_with_sigma(4.00022, 0.00033) == ("4.00022", "0.00033")
    assert format_with_sigma(-1.513, 0.0339) == ("-1.513", "0.034")
    # σ that rounds up to the next decade: 0.000996 → 0.0010, 4 decimals
    assert format_with_sigma(2.0, 0.000996) == ("2.0000", "0.0010")
    # σ ≥ 100: rounding to tens
    assert format_with_sigma(1234.5, 123.0) == ("1230", "120")
    # no σ: 6 significant digits
    assert format_with_sigma(0.123456789, None) == ("0.123457", "—")
    assert format_with_sigma(0.123456789, float("nan")) == ("0.123457", "—")
    # a value that rounds to zero shows no minus sign
    assert format_with_sigma(-0.00001, 0.004) == ("0.0000", "0.0040")


def test_interval_ends_at_the_decimal_place_of_sigma():
    half = 1.959963984540054 * 0.00033  # z_0.975 · σ
    assert format_interval(4.00022 - half, 4.00022 + half, 0.00033) == "[3.99957, 4.00087]"
    assert format_interval(-1.58, -1.45, 0.034) == "[-1.580, -1.450]"
    assert format_interval(None, 1.0, 0.1) == "—"


def test_estimates_table_shows_both_sigma_and_the_interval():
    rows = [EstimateRow("Ma", "1/s", 4.00022, 0.00033, 0.00021, "coloured", initial=3.5)]
    page = estimates_section(rows)
    cells = re.findall(r"<td>(.*?)</td>", page)
    assert cells[:8] == [
        "Ma", "1/s", "4.00022", "0.00033", "0.00021", "coloured-residual", "0.0082",
        "[3.99957, 4.00087]",
    ]  # fmt: skip


# ------------------------------------------------------------------------------ design


def _short_period():
    from flightid.model import StateSpaceModel

    def f(t, x, u, p):
        # α̇ = Z_α α + (1 + Z_q) q + Z_δe δe;  q̇ = M_α α + M_q q + M_δe δe
        return np.array(
            [p[0] * x[0] + (1 + p[1]) * x[1] + p[2] * u[0], p[3] * x[0] + p[4] * x[1] + p[5] * u[0]]
        )

    def h(t, x, u, p):
        return np.array([x[0], x[1]])

    names = ("Za", "Zq", "Zde", "Ma", "Mq", "Mde")
    numbers = (-0.48, 0.10, -0.68, -4.9, -2.0, -7.2)
    return StateSpaceModel(
        ("alpha", "q"), ("de",), ("alpha", "q"), f, h, dict(zip(names, numbers, strict=True)),
        x0=(0.0, 0.0),
    )  # fmt: skip


def test_design_folder_and_page(tmp_path):
    from flightid.design.optimize import DesignProblem, InputSpec, design_input
    from flightid.design.result import DesignResult
    from flightid.report.estimator_reports import write_design_files

    problem = DesignProblem(
        _short_period(), (InputSpec("de", 0.03, -0.02, (0.1, 1.5)),), 8.0, 0.05,
        {"alpha": 0.002, "q": 0.003}, candidates=1,
    )  # fmt: skip
    best, tried = design_input(problem)
    case_file = tmp_path / "design.toml"
    case_file.write_text("title = 'x'\n", encoding="utf-8")
    result = DesignResult(problem, best, tuple(tried), title="design", case_file=str(case_file))
    out = tmp_path / "out"
    write_design_files(result, out, {"de": "rad", "alpha": "rad", "q": "rad/s"})
    page = _check_page(out, "Assumed noise and predicted responses", ["Designed input", "σ"])
    assert hashlib.sha256(case_file.read_bytes()).hexdigest() in page
    assert "<table class='correlation'>" in page
    assert (out / "designed_input.csv").is_file() and (out / "predicted_accuracy.csv").is_file()
    # estimates.csv: std = std_cr = the predicted σ
    with open(out / "estimates.csv", newline="", encoding="utf-8") as stream:
        rows = {r["name"]: r for r in csv.DictReader(stream)}
    for name, sigma in zip(best.accuracy.names, best.accuracy.std, strict=True):
        assert float(rows[name]["std"]) == pytest.approx(sigma, rel=1e-12)
        assert float(rows[name]["std_cr"]) == pytest.approx(sigma, rel=1e-12)


# ------------------------------------------------------------------------------ recursive


def _recursive_result(meta_extra: dict):
    from flightid.recursive.result import RecursiveResult

    rng = np.random.default_rng(7)
    n = 200
    time_s = 0.02 * np.arange(n)
    truth = np.array([-1.5, -3.0])
    settle = np.exp(-time_s / 0.5)[:, None]
    theta = truth + settle * np.array([0.5, -0.8]) + 1e-4 * rng.standard_normal((n, 2))
    std = 0.01 + 0.2 * settle * np.ones((n, 2))
    meta = {
        "title": "simulated",
        "file": "",
        "outputs": ["q", "az"],
        "output_units": ["rad/s", "m/s^2"],
        "maneuvers": [{"name": "sim", "samples": n, "dt": 0.02}],
        **meta_extra,
    }
    return RecursiveResult(
        method="ekf", parameter_names=("Mq", "Ma"), time_s=time_s,
        samples=np.arange(1, n + 1), theta_history=theta, std_history=std,
        state_names=("q",), state_history=np.zeros((n, 1)), report="last_10",
        units=("1/s", "1/s^2"), initial=(-1.0, -2.2), n_samples=n,
        nis=np.full(n, 2.0), warnings=(), wall_time_s=0.1, meta=meta,
    )  # fmt: skip


def test_recursive_folder_and_page(tmp_path):
    from flightid.report.estimator_reports import write_recursive_files

    rng = np.random.default_rng(3)
    innovations = rng.standard_normal((199, 2)) * [0.01, 0.1]
    correlation = np.array([[1.0, -0.95], [-0.95, 1.0]])
    result = _recursive_result(
        {
            "innovations": innovations,
            "innovation_time_s": 0.02 * np.arange(1, 200),
            "parameter_correlation": correlation,
        }
    )
    write_recursive_files(result, tmp_path)
    page = _check_page(tmp_path, "Innovation analysis", ["parameter histories", "innovations"])
    # the strong correlation is flagged, the white innovations pass the test
    assert "Mq–Ma (-0.950)" in page and "<table class='correlation'>" in page
    assert "coloured</span>" not in page
    with open(tmp_path / "innovations.csv", newline="", encoding="utf-8") as stream:
        rows = list(csv.reader(stream))
    assert rows[0] == ["time_s", "q", "az"] and len(rows) == 200
    assert float(rows[1][2]) == pytest.approx(innovations[0, 1], rel=1e-9)
    # innovation RMS per output, by hand
    rms = np.sqrt(np.mean(innovations**2, axis=0))
    assert f"<td>{rms[1]:.4g}</td>" in page
    assert (tmp_path / "parameter_histories.csv").is_file()


def test_recursive_without_covariance_says_so(tmp_path):
    from flightid.report.estimator_reports import write_recursive_files

    write_recursive_files(_recursive_result({}), tmp_path)
    page = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert "keeps no parameter covariance matrix" in page and "keeps no innovations" in page
    assert not (tmp_path / "innovations.csv").exists()


@needs_data("fvsysid")
def test_shipped_recursive_case_keeps_innovations_correlation_and_case_digest(tmp_path):
    from flightid.cases import load_case
    from flightid.cases.recursive_case import run_recursive_case
    from flightid.report.estimator_reports import write_recursive_files

    case_file = ROOT / "examples/cases/unstab_sp_recursive_ekf.toml"
    result = run_recursive_case(load_case(case_file), DATA)
    write_recursive_files(result, tmp_path)
    page = _check_page(tmp_path, "Innovation analysis", ["parameter histories", "innovations"])
    assert hashlib.sha256(case_file.read_bytes()).hexdigest() in page
    assert "<table class='correlation'>" in page
    corr = np.asarray(result.meta["parameter_correlation"])
    np.testing.assert_allclose(np.diag(corr), 1.0, rtol=1e-12)
    np.testing.assert_allclose(corr, corr.T, atol=1e-12)


# ------------------------------------------------------------------------------ frequency


@needs_data("fvsysid")
def test_frequency_domain_folder_and_page(tmp_path):
    from flightid.cases import load_case
    from flightid.cases.frequency_case import run_frequency_case
    from flightid.report.estimator_reports import write_frequency_files

    case_file = ROOT / "examples/cases/attas_short_period_frequency_domain.toml"
    result = run_frequency_case(load_case(case_file), DATA)
    write_frequency_files(result, tmp_path)
    page = _check_page(
        tmp_path, "Residual analysis (frequency domain)", ["Bode", "output transforms"]
    )
    assert hashlib.sha256(case_file.read_bytes()).hexdigest() in page
    assert "<table class='correlation'>" in page and (tmp_path / "frequency_spectra.csv").is_file()
    # the correlation is that of the reported σ: its diagonal is 1, symmetric
    np.testing.assert_allclose(np.diag(result.correlation), 1.0, rtol=1e-12)
    assert result.correlation.shape == (int(result.free.sum()),) * 2
    # the parameters not estimated are listed, without σ
    with open(tmp_path / "estimates.csv", newline="", encoding="utf-8") as stream:
        rows = {r["name"]: r for r in csv.DictReader(stream)}
    assert rows["M0"]["std"] == "" and rows["M0"]["free"] == "False"
    assert float(rows["Ma"]["std"]) > float(rows["Ma"]["std_cr"]) > 0


# ------------------------------------------------------------------------------ stages


@needs_data("fvsysid")
def test_regression_stages_alone_write_the_common_folder(tmp_path, capsys):
    from flightid.cases import load_case
    from flightid.cases.stages import case_signals
    from flightid.cli.main import main

    case_file = ROOT / "examples/cases/unstab_sp_equation_error_ls.toml"
    out = tmp_path / "out"
    assert main(["run", str(case_file), "--out", str(out), "--quiet", "--data-dir", str(DATA)]) == 0
    capsys.readouterr()
    page = _check_page(out, "Residual analysis", ["measured and fitted coefficients"])
    assert "<table class='correlation'>" in page
    # measured coefficient in the time-history CSV = the case's signal; fitted = X θ̂ by lstsq
    signals = case_signals(load_case(case_file), DATA)
    X = np.column_stack([signals["w"], signals["q"], signals["de"]])
    y = signals["qdot"]
    fitted = X @ np.linalg.lstsq(X, y, rcond=None)[0]
    with open(out / "stage_time_histories.csv", newline="", encoding="utf-8") as stream:
        rows = [r for r in csv.DictReader(stream) if r["coefficient"] == "qdot"]
    np.testing.assert_allclose([float(r["measured"]) for r in rows], y, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose([float(r["fitted"]) for r in rows], fitted, rtol=1e-6, atol=1e-9)


def test_frequency_domain_folder_on_simulated_data(tmp_path):
    from flightid.cases import load_case
    from flightid.cases.frequency_case import run_frequency_case
    from flightid.report.estimator_reports import write_frequency_files
    from test_frequency_delays import write_case

    case_file = write_case(tmp_path)
    result = run_frequency_case(load_case(case_file))
    out = tmp_path / "out"
    write_frequency_files(result, out)
    page = _check_page(out, "Residual analysis (frequency domain)", ["Bode", "output transforms"])
    assert hashlib.sha256(case_file.read_bytes()).hexdigest() in page
    # the 2 × 2 correlation of wn and zeta: ρ = P12/√(P11 P22) of the reported covariance
    assert result.correlation.shape == (2, 2)
    rho = result.correlation[0, 1]
    assert -1.0 < rho < 1.0 and result.correlation[1, 0] == pytest.approx(rho)
    assert f"<td>{rho:.2g}</td>" in page
    with open(out / "estimates.csv", newline="", encoding="utf-8") as stream:
        rows = {r["name"]: r for r in csv.DictReader(stream)}
    for name, std in zip(result.names, result.std, strict=True):
        assert float(rows[name]["std"]) == pytest.approx(std, rel=1e-12)
        assert rows[name]["std_kind"] == "coloured"


_REGRESSION_CASE = """title = "simulated regression"
[data]
data_dir = "."
file = "sim.csv"
time = "t"
[data.inputs]
w = { column = "w", unit = "m/s" }
q = { column = "q", unit = "rad/s" }
de = { column = "de", unit = "rad" }
qdot = { column = "qdot", unit = "rad/s^2" }
[data.outputs]
az = { column = "az", unit = "m/s^2" }
[[stages]]
kind = "regression"
method = "ols"
[stages.coefficients.az]
response = "az"
terms = ["w", "q", "de"]
parameters = ["Zw", "Zq", "Zde"]
[stages.coefficients.qdot]
response = "qdot"
terms = ["w", "q", "de"]
parameters = ["Mw", "Mq", "Mde"]
"""


def test_regression_stages_folder_on_simulated_data(tmp_path, capsys):
    from flightid.cli.main import main

    rng = np.random.default_rng(11)
    t = 0.02 * np.arange(600)
    w, q, de = (np.sin(2 * np.pi * f * t + k) for k, f in enumerate((0.3, 0.7, 1.1)))
    X = np.column_stack([w, q, de])
    az = X @ [-1.5, 0.3, -5.0] + 0.01 * rng.standard_normal(t.size)
    qdot = X @ [0.2, -3.0, -12.0] + 0.02 * rng.standard_normal(t.size)
    np.savetxt(tmp_path / "sim.csv", np.column_stack([t, w, q, de, qdot, az]), delimiter=",",
               header="t,w,q,de,qdot,az", comments="")  # fmt: skip
    (tmp_path / "case.toml").write_text(_REGRESSION_CASE, encoding="utf-8")
    out = tmp_path / "out"
    assert main(["run", str(tmp_path / "case.toml"), "--out", str(out), "--quiet"]) == 0
    capsys.readouterr()
    page = _check_page(out, "Residual analysis", ["measured and fitted coefficients"])
    assert page.count("<table class='correlation'>") == 2  # one per coefficient
    # fitted = X θ̂ by lstsq, residual = measured − fitted (independent of the stage code)
    theta = np.linalg.lstsq(X, qdot, rcond=None)[0]
    with open(out / "stage_time_histories.csv", newline="", encoding="utf-8") as stream:
        rows = [r for r in csv.DictReader(stream) if r["coefficient"] == "qdot"]
    np.testing.assert_allclose([float(r["measured"]) for r in rows], qdot, atol=1e-9)
    np.testing.assert_allclose([float(r["fitted"]) for r in rows], X @ theta, atol=1e-8)
    with open(out / "estimates.csv", newline="", encoding="utf-8") as stream:
        estimates = {r["name"]: r for r in csv.DictReader(stream)}
    np.testing.assert_allclose(
        [float(estimates[n]["value"]) for n in ("Mw", "Mq", "Mde")], theta, rtol=1e-9
    )
