"""Loaders: CSV, whitespace ASCII, MATLAB, DataFrame → FlightData; expressions; units; errors."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from flightid.data.loaders import (
    ChannelError,
    DataFileError,
    load_flight_data,
    parse_expression,
    read_table,
    table_from_dataframe,
    to_flight_data,
)
from flightid.data.units import UnitError, convert_factor
from flightid.errors import InputError

DATA = Path(os.environ.get("FLIGHTID_DATA", Path(__file__).resolve().parents[1] / "../shared/data"))
needs_data = pytest.mark.skipif(
    not (DATA / "fvsysid").is_dir(), reason=f"real flight data not found at {DATA}"
)

RNG = np.random.default_rng(20240601)
T = np.arange(50) * 0.1
A = RNG.normal(size=50)
B = RNG.normal(size=50)


def _write_ascii(path: Path, header: bool) -> Path:
    lines = []
    if header:
        lines += ["Data file: synthetic", "2 variables plus time", "", "T  A  B", "S DEG M/S", ""]
    lines += [f"{t:10.4f} {a:14.8f} {b:14.8f}" for t, a, b in zip(T, A, B, strict=True)]
    path.write_text("\n".join(lines) + "\n")
    return path


# ---------------------------------------------------------------- units


def test_unit_factors():
    # 1 deg = π/180 rad; 1 ft = 0.3048 m (exact, international foot); 1 g = 9.80665 m/s²
    assert convert_factor("deg", "rad") == pytest.approx(math.pi / 180)
    assert convert_factor("DEG/S**2", "rad/s^2") == pytest.approx(math.pi / 180)
    assert convert_factor("ft/sec", "m/s") == pytest.approx(0.3048)
    assert convert_factor("g", "m/s2") == pytest.approx(9.80665)
    # 1 lbf/ft² = 47.880259 Pa (NIST SP 811 appendix B)
    assert convert_factor("lbf/ft2", "Pa") == pytest.approx(47.880259, rel=1e-7)
    assert convert_factor("slug*ft^2", "kg*m^2") == pytest.approx(1.3558179, rel=1e-6)


def test_unit_mismatch_is_named_error():
    with pytest.raises(UnitError, match="different quantities"):
        convert_factor("deg", "m/s")
    with pytest.raises(UnitError, match="unknown unit"):
        convert_factor("furlong", "m")


# ---------------------------------------------------------------- expressions


def test_expression_parser_and_evaluation(tmp_path):
    path = _write_ascii(tmp_path / "x.asc", header=False)
    fd = load_flight_data(
        path,
        inputs={"d": {"expr": "($3 - $2) / 2", "unit": "deg", "to": "rad"}},
        outputs={"s": "-2*$2 + 0.5*($3+1)"},
    )
    assert np.allclose(fd.input("d"), (B - A) / 2 * math.pi / 180, atol=1e-8)
    assert np.allclose(fd.output("s"), -2 * A + 0.5 * (B + 1), atol=1e-7)
    assert parse_expression("-$1") == ("neg", ("col", 1))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("$2 +", "expected a number"),
        ("($2", r"expected '\)'"),
        ("$2 ; rm", "unexpected character"),
        ("__import__('os')", "unexpected character"),
    ],
)
def test_bad_expressions_are_named_errors(text, message):
    with pytest.raises(ChannelError, match=message):
        parse_expression(text)


# ---------------------------------------------------------------- formats


@pytest.mark.parametrize("header", [False, True])
def test_ascii_with_and_without_header(tmp_path, header):
    path = _write_ascii(tmp_path / "x.asc", header)
    table = read_table(path)
    assert table.data.shape == (50, 3)
    if header:
        assert table.names == ("T", "A", "B")
        assert table.units == ("S", "DEG", "M/S")
    column = "A" if header else 2
    fd = load_flight_data(path, inputs={"a": {"column": column, "unit": "deg", "to": "rad"}})
    assert np.allclose(fd.input("a"), np.deg2rad(A), atol=1e-9)
    assert fd.dt == pytest.approx(0.1)


def test_csv_header_units_and_offsets(tmp_path):
    path = tmp_path / "flight.csv"
    rows = ["time [s],alpha [deg],V (ft/s)"]
    rows += [f"{t},{a},{100 + b}" for t, a, b in zip(T, A, B, strict=True)]
    path.write_text("\n".join(rows) + "\n")
    table = read_table(path)
    assert table.names == ("time", "alpha", "V")
    assert table.units == ("s", "deg", "ft/s")
    fd = load_flight_data(
        path,
        time="time",
        inputs={"V": {"column": "V", "unit": "ft/s", "to": "m/s", "subtract": "first"}},
        outputs={"alpha": {"column": "alpha", "scale": 2.0, "offset": 1.0}},
        start=1.0,
        stop=3.0,
    )
    assert fd.n_samples == 21
    assert fd.input("V")[0] == 0.0
    # the header states deg: (2·α + 1) deg delivered in rad (the file's unit applies)
    assert np.allclose(fd.output("alpha"), np.deg2rad(2 * A[10:31] + 1))
    assert fd.units == {"V": "m/s", "alpha": "rad"}


def test_mat_sidpac_layout_and_plain_matrix(tmp_path):
    fdata = np.column_stack([T, A, B])
    varlab = np.array(["* time  (sec)  ", "* alpha (deg)  ", "  airspeed (ft/sec)"])
    scipy.io.savemat(tmp_path / "s.mat", {"fdata": fdata, "varlab": varlab, "sarea": 10.0})
    table = read_table(tmp_path / "s.mat")
    assert table.names == ("time", "alpha", "airspeed")
    assert table.units[1] == "deg"
    assert table.constants["sarea"] == 10.0
    scipy.io.savemat(tmp_path / "p.mat", {"flt": fdata})
    fd = load_flight_data(tmp_path / "p.mat", outputs={"b": 3})
    assert np.allclose(fd.output("b"), B)
    scipy.io.savemat(tmp_path / "v.mat", {"t": T[:, None], "alpha": A[:, None], "n": 3.0})
    table = read_table(tmp_path / "v.mat")
    assert table.names == ("t", "alpha")


def test_dataframe():
    pd = pytest.importorskip("pandas")
    frame = pd.DataFrame({"t": T, "a": A, "b": B})
    fd = to_flight_data(
        table_from_dataframe(frame), time="t", inputs={"a": "a"}, outputs={"b": "b"}
    )
    assert np.allclose(fd.output("b"), B)


# ---------------------------------------------------------------- errors


def test_missing_file(tmp_path):
    with pytest.raises(DataFileError, match="no such file"):
        read_table(tmp_path / "nope.asc")


def test_non_numeric_row_in_data(tmp_path):
    path = _write_ascii(tmp_path / "x.asc", header=False)
    path.write_text(path.read_text() + "1.0 abc 2.0\n")
    with pytest.raises(DataFileError, match="not numeric"):
        read_table(path)


def test_ragged_rows(tmp_path):
    path = tmp_path / "x.asc"
    path.write_text("0 1 2\n0.1 1 2\n0.2 1\n")
    with pytest.raises(DataFileError, match="has 2 numbers"):
        read_table(path)


def test_unknown_column_named(tmp_path):
    path = _write_ascii(tmp_path / "x.asc", header=True)
    with pytest.raises(ChannelError, match=r"outputs.z: no column named 'Z'.*\['T', 'A', 'B'\]"):
        load_flight_data(path, outputs={"z": "Z"})
    with pytest.raises(ChannelError, match="column 9 does not exist"):
        load_flight_data(path, outputs={"z": 9})
    with pytest.raises(ChannelError, match="unknown key"):
        load_flight_data(path, outputs={"z": {"col": 2}})


def test_nan_in_channel_named(tmp_path):
    path = tmp_path / "x.csv"
    path.write_text("t,a\n0,1\n0.1,nan\n0.2,3\n")
    with pytest.raises(ChannelError, match="outputs.a: 1 non-finite"):
        load_flight_data(path, time="t", outputs={"a": "a"})


def test_time_gap_named_and_join(tmp_path):
    path = tmp_path / "x.asc"
    t = np.r_[np.arange(5) * 0.1, 10 + np.arange(5) * 0.1]
    path.write_text("\n".join(f"{x} {i}" for i, x in enumerate(t)))
    with pytest.raises(InputError, match="gap"):
        load_flight_data(path, outputs={"a": 2})
    fd = load_flight_data(path, outputs={"a": 2}, gaps="join")
    assert fd.time[-1] == pytest.approx(0.9)


# ---------------------------------------------------------------- real data


@needs_data
def test_real_hfb320_with_and_without_header_agree():
    plain = read_table(DATA / "fvsysid/hfb320_1_10.asc")
    headed = read_table(DATA / "fvsysid/hfb320_1_10_withHeader.asc")
    assert plain.data.shape == (601, 20)  # README: 601 rows × 20 columns
    assert np.array_equal(plain.data, headed.data)
    assert headed.names[:3] == ("T", "DELV", "PDYN")


@needs_data
def test_real_attas_mat_and_asc_agree():
    mat = read_table(DATA / "fvsysid/fAttasAilRud1.mat")
    asc = read_table(DATA / "fvsysid/fAttasAilRud1.asc")
    assert mat.data.shape == (1502, 45)
    # the .asc copy re-stamps time from 0 s without the gap; the channels agree
    assert np.allclose(mat.data[:, 1:], asc.data[:, 1:], rtol=1e-5, atol=1e-6)
    fd = load_flight_data(
        DATA / "fvsysid/fAttasAilRud1.mat",
        gaps="join",
        inputs={"da": {"expr": "($29 - $28)/2", "unit": "deg", "to": "rad"}},
        outputs={"p": {"column": 7, "unit": "deg/s", "to": "rad/s"}},
    )
    assert fd.n_samples == 1502 and fd.dt == pytest.approx(0.04)


@needs_data
def test_real_twin_otter_sidpac_layout():
    table = read_table(DATA / "sidpac_twin_otter/totter_lon_020213f1_018.mat")
    assert table.data.shape == (401, 90)
    assert table.names[3] == "alpha" and table.units[3] == "deg"
    fd = load_flight_data(
        DATA / "sidpac_twin_otter/totter_lon_020213f1_018.mat",
        time="time",
        outputs={"az": {"column": "az", "unit": "g", "to": "m/s^2"}},
    )
    assert fd.dt == pytest.approx(0.02)
    assert -12 < fd.output("az").mean() < -8
