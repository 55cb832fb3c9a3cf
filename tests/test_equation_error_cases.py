"""The unstable-aircraft equation-error cases (CASES.md §3g, §3h): two regressions without
intercept on unStabAC_sim.asc, solved by OLS and by TLS, run through ``flightid run --json``
and compared with closed forms written here (np.linalg.lstsq, an SVD of [X y], the Q15 σ
formula and the §0 ndiff8 differentiator). Each runs in about a second. Skipped without
../shared/data."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from flightid.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("FLIGHTID_DATA", ROOT / "../shared/data"))
FILE = DATA / "fvsysid" / "unStabAC_sim.asc"
pytestmark = pytest.mark.skipif(not FILE.is_file(), reason=f"data not found at {FILE}")

NAMES = {"az": ["Zw", "Zq", "Zδe"], "qdot": ["Mw", "Mq", "Mδe"]}
DT = 0.05  # s (CASES.md §3)
# CASES.md §0, ndiff_Filter08 coefficients
C8 = [
    0.88888888887637,
    -0.31111111109862,
    0.11313131312500,
    -0.03535353535135,
    0.00870240870185,
    -0.00155400155390,
    0.00017760017759,
    -0.00000971250971,
]


def _ndiff8(x: np.ndarray, dt: float) -> np.ndarray:
    """D(x) of CASES.md §0, written from the formula with 1-based k as there."""
    n = x.shape[0]
    d = np.zeros(n)
    X = lambda k: x[k - 1]  # noqa: E731  (1-based)
    for k in range(3, n - 1):
        if 10 <= k <= n - 9:
            d[k - 1] = sum(C8[j - 1] * (X(k + j) - X(k - j)) for j in range(1, 9)) / dt
        else:
            d[k - 1] = (
                -0.08333333333333 * (X(k + 2) - X(k - 2)) + 0.66666666666667 * (X(k + 1) - X(k - 1))
            ) / dt
    d[0] = d[1] = d[2]
    d[n - 2] = d[n - 1] = d[n - 3]
    return d


@pytest.fixture(scope="module")
def regressions():
    """(X, {response: y}) from the file: cols 3 w, 4 q, 5 δe, 6 a_z; q̇_m = D(q)."""
    table = np.loadtxt(FILE)
    assert table.shape == (251, 6)
    X = table[:, 2:5]
    return X, {"az": table[:, 5], "qdot": _ndiff8(table[:, 3], DT)}


def _run(name: str, capsys) -> dict:
    case = str(ROOT / "examples/cases" / f"{name}.toml")
    code = main(["run", case, "--json", "--quiet", "--data-dir", str(DATA)])
    assert code == 0
    document = json.loads(capsys.readouterr().out)
    assert document["results"] == []
    (stage,) = document["stages"]
    assert stage["kind"] == "regression"
    return stage["coefficients"]


def _q15_std(X: np.ndarray, y: np.ndarray, theta: np.ndarray) -> np.ndarray:
    # CASES.md Q15: √diag(s²(XᵀX)⁻¹), s² = Σ res²/(N − 3)
    res = y - X @ theta
    s2 = res @ res / (X.shape[0] - 3)
    return np.sqrt(np.diag(s2 * np.linalg.inv(X.T @ X)))


def _check(coefficients: dict, expected: dict) -> None:
    assert list(coefficients) == ["az", "qdot"]
    for response, names in NAMES.items():
        rows = coefficients[response]["parameters"]
        assert [r["name"] for r in rows] == names
        assert [r["term"] for r in rows] == ["w", "q", "de"]
        theta, std = expected[response]
        np.testing.assert_allclose([r["value"] for r in rows], theta, rtol=1e-9)
        # the classical σ √diag(s²(XᵀX)⁻¹) (std_cr; std is the coloured-residual σ when the
        # residuals are coloured)
        np.testing.assert_allclose([r["std_cr"] for r in rows], std, rtol=1e-6)


def test_ls_case_is_ordinary_least_squares_without_intercept(regressions, capsys):
    X, ys = regressions
    expected = {}
    for response, y in ys.items():
        theta = np.linalg.lstsq(X, y, rcond=None)[0]
        expected[response] = (theta, _q15_std(X, y, theta))
    coefficients = _run("unstab_sp_equation_error_ls", capsys)
    _check(coefficients, expected)
    assert coefficients["az"]["method"] == "ols"
    # the simulated a_z is exactly linear in w, q, δe: Zq comes out at its simulation value
    # (the fixed −1.4768 of §3a–3f)
    assert coefficients["az"]["parameters"][1]["value"] == pytest.approx(-1.4768, abs=1e-5)


def test_tls_case_is_the_svd_of_the_composite_matrix(regressions, capsys):
    X, ys = regressions
    expected = {}
    for response, y in ys.items():
        # [X y] = U Σ Vᵀ; θ = −v_1..3 / v_4 with v the last right singular vector
        v = np.linalg.svd(np.column_stack([X, y]))[2][-1]
        theta = -v[:3] / v[3]
        expected[response] = (theta, _q15_std(X, y, theta))
    coefficients = _run("unstab_sp_equation_error_tls", capsys)
    _check(coefficients, expected)
    entry = coefficients["qdot"]
    assert entry["method"] == "tls" and entry["covariance"] == "ols"
    assert all(r["std_eiv"] > 0 for r in entry["parameters"])
    # TLS is not OLS here (so the rtol 1e-9 check above tells them apart): on the q̇_m
    # regression they differ by ≈ 3e-5 relative (Mδe −12.70591 vs −12.70556), well below σ
    ols = np.linalg.lstsq(X, ys["qdot"], rcond=None)[0]
    assert np.max(np.abs(expected["qdot"][0] / ols - 1)) > 1e-5
    assert np.all(np.abs(expected["qdot"][0] - ols) < expected["qdot"][1])


def _variant(tmp_path: Path, old: str, new: str) -> Path:
    text = (ROOT / "examples/cases/unstab_sp_equation_error_tls.toml").read_text("utf-8")
    assert old in text
    path = tmp_path / "case.toml"
    path.write_text(
        text.replace(old, new).replace("[data]\n", f"[data]\ndata_dir = '{DATA}'\n", 1),
        encoding="utf-8",
    )
    return path


def test_covariance_eiv_reports_the_sandwich_sigma(tmp_path, capsys):
    path = _variant(tmp_path, 'method = "tls"', 'method = "tls"\ncovariance = "eiv"')
    assert main(["run", str(path), "--json", "--quiet"]) == 0
    entry = json.loads(capsys.readouterr().out)["stages"][0]["coefficients"]["qdot"]
    assert entry["covariance"] == "eiv"
    for row in entry["parameters"]:
        assert row["std"] == pytest.approx(row["std_eiv"]) and row["std"] != row["std_ols"]


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ('method = "tls"', 'method = "wls"', "stages\\[0\\].method: expected one of"),
        ('method = "tls"', 'method = "ols"\ncovariance = "eiv"', 'is for method = "tls"'),
        ('["Mw", "Mq", "Mδe"]', '["Mw", "Mq"]', "coefficients.qdot.parameters: expected a list"),
        ('["Mw", "Mq", "Mδe"]', '["Mw", "Mw", "Mq"]', "expected distinct names"),
        ('method = "tls"', 'method = "tls"\nf_enter = 4', "f_enter"),
    ],
)
def test_stage_option_errors_name_the_key(tmp_path, capsys, old, new, message):
    from flightid.cases import load_case
    from flightid.cases.checks import CaseError
    from flightid.cases.stages import run_stages

    with pytest.raises(CaseError, match=message):
        run_stages(load_case(_variant(tmp_path, old, new)), DATA)
