"""Declared smoothing and differentiation of channels (flightid.data.preprocess)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from flightid.cases import CaseError, load_case
from flightid.cases.build import load_maneuvers, resolve_data_dir
from flightid.cli.main import main
from flightid.data.loaders import ChannelError, ChannelSpec, Table, to_flight_data
from flightid.data.preprocess import (
    PreprocessError,
    butter_smooth,
    ndiff8,
    savgol_derivative,
    savgol_smooth,
    smooth_mul_ts,
)

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "examples/csv_walkthrough"

# ------------------------------------------------------------------ direct formulas
# Independent transcriptions of CASES.md §0, sample by sample with 1-based k, the rules
# tested in the order written there (the first that applies wins).


def _direct_s(x: np.ndarray) -> np.ndarray:
    n = len(x)

    def X(k):  # 1-based
        return x[k - 1]

    out = []
    for k in range(1, n + 1):
        if k <= 3 or k >= n - 2:
            out.append(X(k))
        elif 4 <= k <= 8 or n - 7 <= k <= n - 3:
            out.append((7 * (X(k - 2) + X(k + 2)) + 24 * (X(k - 1) + X(k + 1)) + 34 * X(k)) / 96)
        else:  # 9 ≤ k ≤ N−8

            def sj(j, k=k):
                return X(k - j) + X(k + j)

            out.append(
                (
                    74 * X(k)
                    + 67 * sj(1)
                    + 46 * sj(2)
                    + 21 * sj(3)
                    + 3 * sj(4)
                    - 5 * sj(5)
                    - 6 * sj(6)
                    - 3 * sj(7)
                )
                / 320
            )
    return np.array(out)


C = [
    0.88888888887637,
    -0.31111111109862,
    0.11313131312500,
    -0.03535353535135,
    0.00870240870185,
    -0.00155400155390,
    0.00017760017759,
    -0.00000971250971,
]


def _direct_d(x: np.ndarray, dt: float) -> np.ndarray:
    n = len(x)

    def X(k):
        return x[k - 1]

    d = {}
    for k in range(3, n - 1):  # 3 ≤ k ≤ N−2
        if 10 <= k <= n - 9:
            d[k] = sum(C[j - 1] * (X(k + j) - X(k - j)) for j in range(1, 9)) / dt
        else:  # 3 ≤ k ≤ 9 or N−8 ≤ k ≤ N−2
            d[k] = (
                -0.08333333333333 * (X(k + 2) - X(k - 2)) + 0.66666666666667 * (X(k + 1) - X(k - 1))
            ) / dt
    d[1] = d[2] = d[3]
    d[n - 1] = d[n] = d[n - 2]
    return np.array([d[k] for k in range(1, n + 1)])


@pytest.mark.parametrize("n", [1, 2, 3, 5, 6, 8, 10, 11, 15, 16, 17, 18, 24, 101])
def test_smooth_mul_ts_matches_the_formula(n):
    x = np.random.default_rng(n).normal(size=n)
    assert np.allclose(smooth_mul_ts(x), _direct_s(x), rtol=0, atol=1e-14)


def test_smooth_mul_ts_edge_rules_explicitly():
    n = 40
    x = np.random.default_rng(7).normal(size=n)
    s = smooth_mul_ts(x)
    # k ≤ 3 and k ≥ N−2 untouched (1-based) → 0-based 0..2 and N−3..N−1
    assert np.array_equal(s[:3], x[:3])
    assert np.array_equal(s[-3:], x[-3:])
    # k = 4 and k = 8 (5-point rule), k = 9 (15-point rule)
    five = (7 * (x[1] + x[5]) + 24 * (x[2] + x[4]) + 34 * x[3]) / 96
    assert s[3] == pytest.approx(five, abs=1e-14)
    five8 = (7 * (x[5] + x[9]) + 24 * (x[6] + x[8]) + 34 * x[7]) / 96
    assert s[7] == pytest.approx(five8, abs=1e-14)
    w = [67, 46, 21, 3, -5, -6, -3]
    fifteen = (74 * x[8] + sum(wj * (x[8 - j] + x[8 + j]) for j, wj in enumerate(w, 1))) / 320
    assert s[8] == pytest.approx(fifteen, abs=1e-14)
    # weights sum to one: a constant passes unchanged (7·2 + 24·2 + 34 = 96; 74 + 2·123 = 320)
    assert np.allclose(smooth_mul_ts(np.full(n, 3.5)), 3.5, atol=1e-14)


@pytest.mark.parametrize("n", [5, 6, 9, 12, 18, 19, 20, 27, 80])
def test_ndiff8_matches_the_formula(n):
    x = np.random.default_rng(100 + n).normal(size=n)
    assert np.allclose(ndiff8(x, 0.04), _direct_d(x, 0.04), rtol=0, atol=1e-12)


def test_ndiff8_is_exact_for_a_cubic_and_accurate_for_a_sine():
    dt = 0.02
    t = np.arange(200) * dt
    # the 5- and 17-point central differences are exact for polynomials up to degree 4
    d = ndiff8(t**3 - 2 * t, dt)
    assert np.allclose(d[2:-2], 3 * t[2:-2] ** 2 - 2, atol=1e-8)
    d = ndiff8(np.sin(2 * t), dt)
    assert np.allclose(d[9:-9], 2 * np.cos(2 * t[9:-9]), atol=1e-9)
    assert d[0] == d[1] == d[2] and d[-1] == d[-2] == d[-3]


def test_ndiff8_needs_five_samples():
    with pytest.raises(PreprocessError, match="at least 5 samples, got 4"):
        ndiff8(np.zeros(4), 0.1)


def test_savgol_classic_weights_and_polynomials():
    x = np.random.default_rng(3).normal(size=30)
    s = savgol_smooth(x, 5, 2)
    # quadratic/cubic 5-point smoothing weights (−3, 12, 17, 12, −3)/35 (Savitzky & Golay 1964)
    assert s[10] == pytest.approx(np.dot([-3, 12, 17, 12, -3], x[8:13]) / 35, abs=1e-13)
    dt = 0.1
    t = np.arange(40) * dt
    quad = 1 + 2 * t - 0.5 * t**2
    assert np.allclose(savgol_smooth(quad, 7, 2), quad, atol=1e-12)  # ends included
    assert np.allclose(savgol_derivative(quad, dt, 7, 2), 2 - t, atol=1e-10)


def test_butterworth_is_zero_phase_low_pass():
    dt = 0.01
    t = np.arange(2000) * dt
    slow = np.sin(2 * np.pi * 0.2 * t)
    fast = np.sin(2 * np.pi * 20.0 * t)
    out = butter_smooth(slow + fast, dt, 4, 2.0)
    middle = slice(300, 1700)
    # gain at 0.2 Hz: |H|² = 1/(1 + (0.2/2)^8) per pass ≈ 1; at 20 Hz ≈ 1e-8: removed,
    # and no phase lag (filtfilt): the output lies on the slow sine itself
    assert np.max(np.abs(out[middle] - slow[middle])) < 1e-3


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: savgol_smooth(np.zeros(20), 6, 2), "odd window ≥ 3 samples, got 6"),
        (lambda: savgol_smooth(np.zeros(20), 5, 5), "order < window"),
        (lambda: savgol_smooth(np.zeros(20), 21, 2), "longer than the segment"),
        (lambda: savgol_derivative(np.zeros(20), 0.1, 5, 0), r"1 ≤ order"),
        (lambda: butter_smooth(np.zeros(200), 0.1, 2, 5.0), "Nyquist frequency 5 Hz"),
        (lambda: butter_smooth(np.zeros(200), 0.1, 2, 7.0), "Nyquist"),
        (lambda: butter_smooth(np.zeros(10), 0.1, 4, 1.0), "needs more than 15 samples"),
    ],
)
def test_bad_filter_settings_are_named_errors(call, message):
    with pytest.raises(PreprocessError, match=message):
        call()


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ({"column": 2, "smooth": "smoothMuLTS"}, "expected 'smoothMulTS'"),
        ({"column": 2, "smooth": {"savgol": [4, 2]}}, "odd window"),
        ({"column": 2, "smooth": {"savgol": [5]}}, r"\[window, order\]"),
        ({"column": 2, "smooth": {"lowess": [5, 2]}}, "expected one of"),
        ({"column": 2, "smooth": {"butter": [0, 2.0]}}, "order ≥ 1"),
        ({"column": 2, "derivative": "ndiff"}, "expected 'ndiff8'"),
        ({"column": 2, "derivative": {"butter": [2, 1.0]}}, "expected one of"),
        ({"column": 2, "derivative": {"savgol": [5, 0]}}, "1 ≤ order"),
    ],
)
def test_bad_spec_settings_are_named_errors(spec, message):
    with pytest.raises(PreprocessError, match=message) as info:
        ChannelSpec.from_value(spec, "outputs.z")
    assert "outputs.z." in str(info.value)


# ------------------------------------------------------------------ in channel specs

DT = 0.05


def _two_segment_table() -> Table:
    """Two recording segments in one file: 60 rows at 0.05 s, a 10 s gap, 50 more rows."""
    t = np.concatenate([np.arange(60) * DT, 13.0 + np.arange(50) * DT])
    rng = np.random.default_rng(11)
    x = np.concatenate([np.sin(t[:60]), 5 + np.cos(t[60:])]) + 0.01 * rng.normal(size=110)
    return Table(np.column_stack([t, x]), ("t", "x"), ("s", ""), "two segments")


@pytest.mark.parametrize(
    ("setting", "direct"),
    [
        ({"smooth": "smoothMulTS"}, _direct_s),
        ({"derivative": "ndiff8"}, lambda x: _direct_d(x, DT)),
        ({"smooth": "smoothMulTS", "derivative": "ndiff8"}, lambda x: _direct_d(_direct_s(x), DT)),
    ],
)
def test_steps_restart_at_each_segment(setting, direct):
    table = _two_segment_table()
    data = to_flight_data(table, outputs={"z": {"column": "x", **setting}}, gaps="join")
    x = table.data[:, 1]
    expected = np.concatenate([direct(x[:60]), direct(x[60:])])
    assert np.allclose(data.output("z"), expected, atol=1e-12)
    # filtering across the joint would differ right there
    assert not np.allclose(data.output("z")[55:65], direct(x)[55:65], atol=1e-6)


def test_order_unit_then_subtract_then_smooth_then_derivative():
    table = _two_segment_table()
    spec = {
        "column": "x",
        "unit": "deg",
        "scale": 2.0,
        "subtract": "first",
        "smooth": {"savgol": [7, 2]},
        "derivative": {"savgol": [9, 3]},
    }
    data = to_flight_data(table, outputs={"z": spec}, stop=3.0)
    x = (table.data[:61, 1] * 2.0) * np.pi / 180  # scale, then deg → rad (t ≤ 3 s: 60 rows)
    x = x[:60] - x[0]
    expected = savgol_derivative(savgol_smooth(x, 7, 2), DT, 9, 3)
    assert np.allclose(data.output("z"), expected, atol=1e-12)
    assert data.units["z"] == "rad/s"


def test_butter_cutoff_checked_against_the_data_rate():
    table = _two_segment_table()
    with pytest.raises(PreprocessError, match=r"outputs.z \(segment 1 of 2\).*Nyquist"):
        to_flight_data(
            table, outputs={"z": {"column": "x", "smooth": {"butter": [2, 10.0]}}}, gaps="join"
        )
    data = to_flight_data(
        table, outputs={"z": {"column": "x", "smooth": {"butter": [2, 2.0]}}}, gaps="join"
    )
    x = table.data[:, 1]
    expected = np.concatenate(
        [butter_smooth(x[:60], DT, 2, 2.0), butter_smooth(x[60:], DT, 2, 2.0)]
    )
    assert np.allclose(data.output("z"), expected, atol=1e-12)


def test_savgol_window_longer_than_a_segment_is_named():
    table = _two_segment_table()
    with pytest.raises(PreprocessError, match="segment 2 of 2.*longer than the segment"):
        to_flight_data(
            table, outputs={"z": {"column": "x", "smooth": {"savgol": [55, 2]}}}, gaps="join"
        )


def _walk_case(tmp_path: Path, outputs: str) -> Path:
    target = tmp_path / "walk"
    shutil.copytree(WALK, target)
    case = target / "my_case.toml"
    text = case.read_text()
    old = 'q = { column = "pitch_rate", unit = "deg/s", to = "rad/s" }'
    assert old in text
    case.write_text(text.replace(old, outputs))
    return case


def test_case_file_accepts_the_steps(tmp_path, capsys):
    case_path = _walk_case(
        tmp_path,
        'q = { column = "pitch_rate", unit = "deg/s", to = "rad/s", smooth = "smoothMulTS" }\n'
        'qdot = { column = "pitch_rate", unit = "deg/s", to = "rad/s", '
        'smooth = { savgol = [11, 3] }, derivative = "ndiff8" }',
    )
    assert main(["validate", str(case_path)]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "valid"
    case = load_case(case_path)
    (data,) = load_maneuvers(case, resolve_data_dir(case))
    table = np.loadtxt(case_path.parent / "my_flight.csv", delimiter=",", skiprows=1)
    q = table[:, 3] * np.pi / 180
    assert np.allclose(data.output("q"), _direct_s(q), atol=1e-12)
    assert np.allclose(data.output("qdot"), ndiff8(savgol_smooth(q, 11, 3), 0.02), atol=1e-9)
    assert data.units["qdot"] == "rad/s/s"


def test_case_file_refuses_bad_steps(tmp_path):
    case_path = _walk_case(
        tmp_path, 'q = { column = "pitch_rate", unit = "deg/s", smooth = { savgol = [10, 3] } }'
    )
    with pytest.raises(CaseError, match=r"data.outputs.q.smooth.savgol: expected an odd window"):
        load_case(case_path)
    assert main(["validate", str(case_path)]) != 0


def test_unknown_step_key_is_refused():
    with pytest.raises(ChannelError, match="unknown key"):
        ChannelSpec.from_value({"column": 2, "smoothing": "smoothMulTS"}, "outputs.z")
