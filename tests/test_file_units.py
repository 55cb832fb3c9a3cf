"""Units stated by the file: applied where the case declares none, checked where it does.

A CSV header ``q [deg/s]``, a SIDPAC ``varlab`` label, a DataFlash FMTU unit, Parquet field
metadata and an HDF5 attribute all state a column's unit. A channel that declares no unit
takes it (and is delivered in SI with angles in rad, or in ``to``); a declared unit that means
another unit is a ``FileUnitError`` naming both; ``ignore_file_unit = true`` overrides.
Conversion factors are the published definitions, written out here, not flightid's output.
"""

from __future__ import annotations

import math
import shutil
import struct
from pathlib import Path

import numpy as np
import pytest

from flightid.cases import CaseError, load_case
from flightid.cases.build import load_maneuvers
from flightid.data.loaders import (
    ChannelError,
    ChannelSpec,
    FileUnitError,
    Table,
    read_table,
    to_flight_data,
)
from flightid.data.units import channel_conversion, same_unit

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "examples/csv_walkthrough"

# published definitions
DEG = math.pi / 180.0  # rad per degree
FT = 0.3048  # m per international foot (exact, 1959)
INCH = 0.0254  # m per inch (exact)
MILE = 1609.344  # m per statute mile (exact)
KT = 1852.0 / 3600.0  # m/s per knot (1 nmi = 1852 m exactly)
G0 = 9.80665  # m/s², standard gravity (CGPM 1901)
LBF = 4.4482216152605  # N per pound-force (NIST SP 811)
SLUG = 14.59390294  # kg per slug (NIST SP 811, 10 digits)

RNG = np.random.default_rng(2024)
N = 51
T = np.arange(N) * 0.02
SIGNAL = RNG.normal(size=N)


@pytest.mark.parametrize(
    ("unit", "factor", "delivered"),
    [
        ("cm", 0.01, "m"),
        ("mm", 0.001, "m"),
        ("mi", MILE, "m"),
        ("knots", KT, "m/s"),
        ("mph", MILE / 3600.0, "m/s"),
        ("slug·ft²", SLUG * FT**2, "kg*m^2"),
        ("slug ft2", SLUG * FT**2, "kg*m^2"),
        ("kg·m²", 1.0, "kg*m^2"),
        ("mbar", 100.0, "Pa"),
        ("inHg", 3386.389, "Pa"),
        ("cdeg", 0.01 * DEG, "rad"),
        ("cdeg/s", 0.01 * DEG, "rad/s"),
        ("µs", 1e-6, "s"),
        ("us", 1e-6, "s"),
        ("ms", 1e-3, "s"),
        ("g0", G0, "m/s^2"),
        ("rpm", 2 * math.pi / 60.0, "rad/s"),
        ("s⁻¹", 1.0, "1/s"),
        ("1e-07 deglatitude", 1e-7 * DEG, "rad"),  # pymavlink's label for int32 × 10⁻⁷ deg
    ],
)
def test_common_units_are_known_by_their_definitions(unit, factor, delivered):
    got, label = channel_conversion(unit)
    # the 10-digit slug is rounded: 1e-9 relative
    assert got == pytest.approx(factor, rel=1e-9)
    assert label == delivered


@pytest.mark.parametrize(
    ("unit", "factor"),
    [
        ("in", INCH),
        ("ft", FT),
        ("kt", KT),
        ("km/h", 1000.0 / 3600.0),
        ("lbf", LBF),
        ("lb", LBF),
        ("psf", LBF / FT**2),
        ("slug*ft^2", SLUG * FT**2),
        ("hPa", 100.0),
        ("Pa", 1.0),
    ],
)
def test_units_known_before_keep_their_definitions(unit, factor):
    """A guard (these were known already): the exact slug of the new table still agrees
    with the published 10-digit value."""
    assert channel_conversion(unit)[0] == pytest.approx(factor, rel=1e-9)


def test_same_unit_reads_spellings_alike():
    assert same_unit("deg/sec", "deg/s") and same_unit("slug ft2", "slug·ft²")
    assert not same_unit("deg/s", "rad/s") and not same_unit("ft", "m")


def _csv(path: Path, header: list[str], columns: list[np.ndarray]) -> Path:
    rows = [",".join(header)]
    rows += [",".join(f"{v:.17g}" for v in row) for row in np.column_stack(columns)]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.fixture()
def flight(tmp_path) -> Path:
    return _csv(
        tmp_path / "flight.csv",
        ["time [s]", "AOA [deg]", "pitch_rate [deg/s]", "V [kt]", "temp [degC]", "n [instance]"],
        [T, SIGNAL, 2 * SIGNAL, 100 + SIGNAL, 15 + SIGNAL, np.ones(N)],
    )


def test_header_unit_applies_when_the_case_gives_none(flight):
    table = read_table(flight)
    fd = to_flight_data(
        table, time="time", inputs={"V": "V"}, outputs={"alpha": "AOA", "q": "pitch_rate"}
    )
    np.testing.assert_allclose(fd.output("alpha"), SIGNAL * DEG, rtol=1e-13)
    np.testing.assert_allclose(fd.output("q"), 2 * SIGNAL * DEG, rtol=1e-13)
    np.testing.assert_allclose(fd.input("V"), (100 + SIGNAL) * KT, rtol=1e-13)
    assert fd.units == {"V": "m/s", "alpha": "rad", "q": "rad/s"}


def test_to_alone_converts_from_the_file_unit(flight):
    fd = to_flight_data(
        read_table(flight), time="time", outputs={"alpha": {"column": "AOA", "to": "deg"}}
    )
    np.testing.assert_allclose(fd.output("alpha"), SIGNAL, rtol=1e-13)
    assert fd.units == {"alpha": "deg"}


def test_contradicting_case_unit_is_a_named_error_naming_both(flight):
    with pytest.raises(FileUnitError, match=r"outputs\.q: .*unit = 'rad/s'.*'deg/s'.*pitch_rate"):
        to_flight_data(
            read_table(flight),
            time="time",
            outputs={"q": {"column": "pitch_rate", "unit": "rad/s"}},
        )


def test_same_unit_spelled_otherwise_is_accepted(flight):
    """A guard: the check does not refuse a declared unit the file spells otherwise."""
    fd = to_flight_data(
        read_table(flight),
        time="time",
        outputs={"q": {"column": "pitch_rate", "unit": "DEG/SEC", "to": "deg/s"}},
    )
    np.testing.assert_allclose(fd.output("q"), 2 * SIGNAL, rtol=1e-13)


def test_ignore_file_unit_lets_the_case_unit_override(flight):
    fd = to_flight_data(
        read_table(flight),
        time="time",
        outputs={
            "q": {"column": "pitch_rate", "unit": "rad/s", "ignore_file_unit": True},
            "raw": {"column": "AOA", "ignore_file_unit": True},
        },
    )
    np.testing.assert_allclose(fd.output("q"), 2 * SIGNAL, rtol=1e-15)
    np.testing.assert_allclose(fd.output("raw"), SIGNAL, rtol=1e-15)
    assert fd.units == {"q": "rad/s", "raw": ""}


def test_unreadable_file_unit_needs_a_declared_unit_or_the_override(flight):
    table = read_table(flight)
    with pytest.raises(FileUnitError, match=r"outputs\.T: .*'degC'.*cannot read"):
        to_flight_data(table, time="time", outputs={"T": "temp"})
    # labels that mean "no unit" (ArduPilot's instance) are not units
    fd = to_flight_data(table, time="time", outputs={"n": "n"})
    assert fd.units == {"n": ""}


def test_expressions_take_the_unit_of_a_sum_of_like_columns(tmp_path):
    path = _csv(
        tmp_path / "surfaces.csv",
        ["t [s]", "de_l [deg]", "de_r [deg]", "V [m/s]"],
        [T, SIGNAL, -SIGNAL + 1, 50 + SIGNAL],
    )
    table = read_table(path)
    fd = to_flight_data(table, time="t", inputs={"da": "($3 - $2) / 2", "nde": "-de_l"})
    # δa = (δ_r − δ_l)/2 in deg, delivered in rad
    np.testing.assert_allclose(fd.input("da"), (1 - 2 * SIGNAL) / 2 * DEG, rtol=1e-12)
    np.testing.assert_allclose(fd.input("nde"), -SIGNAL * DEG, rtol=1e-12)
    assert fd.units == {"da": "rad", "nde": "rad"}
    for expr in ("sin(de_l)", "de_l + V", "de_l * de_r"):
        with pytest.raises(FileUnitError, match=r"inputs\.x: the expression .*declare the unit"):
            to_flight_data(table, time="t", inputs={"x": expr})
    # the unit of a non-linear expression's result, declared, is taken as given
    fd = to_flight_data(table, time="t", inputs={"x": {"expr": "V * V", "unit": "m^2/s^2"}})
    np.testing.assert_allclose(fd.input("x"), (50 + SIGNAL) ** 2, rtol=1e-12)
    with pytest.raises(FileUnitError, match=r"unit = 'rad'.*'deg'"):
        to_flight_data(table, time="t", inputs={"x": {"expr": "2 * de_l", "unit": "rad"}})


def test_time_column_in_milliseconds_is_delivered_in_seconds(tmp_path):
    path = _csv(tmp_path / "ms.csv", ["time [ms]", "q [rad/s]"], [T * 1000.0, SIGNAL])
    fd = to_flight_data(read_table(path), time="time", outputs={"q": "q"})
    np.testing.assert_allclose(fd.time, T, rtol=1e-12)
    assert fd.dt == pytest.approx(0.02)


def test_signals_carry_the_file_unit(flight):
    fd = to_flight_data(
        read_table(flight),
        time="time",
        signals={"a_s": "AOA"},
        outputs={"alpha": "a_s"},
    )
    np.testing.assert_allclose(fd.output("alpha"), SIGNAL * DEG, rtol=1e-13)
    assert fd.units == {"alpha": "rad"}


def test_table_units_of_any_reader_apply(tmp_path):
    # a Table built by any reader: the units tuple is what counts
    table = Table(np.column_stack([T, SIGNAL]), ("t", "h"), ("s", "ft"), "memory")
    fd = to_flight_data(table, time="t", outputs={"h": "h"})
    np.testing.assert_allclose(fd.output("h"), SIGNAL * FT, rtol=1e-13)


def test_sidpac_varlab_units_apply(tmp_path):
    sio = pytest.importorskip("scipy.io")
    path = tmp_path / "sidpac.mat"
    varlab = np.array(["time (sec)", "alpha (deg)", "qbar (lbf/ft2)"], dtype=object)
    sio.savemat(path, {"fdata": np.column_stack([T, SIGNAL, 80 + SIGNAL]), "varlab": varlab})
    fd = to_flight_data(read_table(path), time="time", outputs={"alpha": "alpha", "qbar": "qbar"})
    np.testing.assert_allclose(fd.output("alpha"), SIGNAL * DEG, rtol=1e-13)
    np.testing.assert_allclose(fd.output("qbar"), (80 + SIGNAL) * LBF / FT**2, rtol=1e-12)


def test_parquet_unit_metadata_applies(tmp_path):
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    schema = pa.schema(
        [pa.field("t", pa.float64()), pa.field("p", pa.float64(), metadata={"unit": "deg/s"})]
    )
    path = tmp_path / "rates.parquet"
    pq.write_table(pa.table([T, SIGNAL], schema=schema), path)
    fd = to_flight_data(read_table(path), time="t", outputs={"p": "p"})
    np.testing.assert_allclose(fd.output("p"), SIGNAL * DEG, rtol=1e-13)
    with pytest.raises(FileUnitError, match="'rad/s'.*'deg/s'"):
        to_flight_data(read_table(path), time="t", outputs={"p": {"column": "p", "unit": "rad/s"}})


def test_hdf5_unit_attribute_of_a_struct_field_applies(tmp_path):
    h5py = pytest.importorskip("h5py")
    path = tmp_path / "v73.mat"
    with h5py.File(path, "w") as f:
        group = f.create_group("man")
        group.attrs["MATLAB_class"] = np.bytes_("struct")
        for name, values, unit in (("time", T, "s"), ("p", SIGNAL, "deg/s")):
            ds = group.create_dataset(name, data=values[:, None].T)  # MATLAB N × 1, stored 1 × N
            ds.attrs["MATLAB_class"] = np.bytes_("double")
            ds.attrs["units"] = np.bytes_(unit)
    fd = to_flight_data(read_table(path, variable="man"), time="time", outputs={"p": "p"})
    np.testing.assert_allclose(fd.output("p"), SIGNAL * DEG, rtol=1e-13)


def _df_message(msg_type: int, payload: bytes) -> bytes:
    # DataFlash message: 0xA3 0x95, type byte, payload (ArduPilot LogStructure.h)
    return bytes([0xA3, 0x95, msg_type]) + payload


def _df_fmt(msg_type: int, name: str, fmt: str, columns: str) -> bytes:
    sizes = {"Q": 8, "B": 1, "b": 1, "f": 4, "d": 8, "n": 4, "N": 16, "Z": 64}
    length = 3 + sum(sizes[c] for c in fmt)
    payload = struct.pack(
        "<BB4s16s64s", msg_type, length, name.encode(), fmt.encode(), columns.encode()
    )
    return _df_message(0x80, payload)


def test_dataflash_fmtu_units_apply(tmp_path):
    pytest.importorskip("pymavlink")
    out = bytearray()
    out += _df_fmt(0x80, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns")
    out += _df_fmt(0x81, "UNIT", "QbZ", "TimeUS,Id,Label")
    out += _df_fmt(0x83, "FMTU", "QBNN", "TimeUS,FmtType,UnitIds,MultIds")
    out += _df_fmt(10, "ATT", "Qff", "TimeUS,Roll,GyrX")
    for ident, label in (("s", "s"), ("d", "deg"), ("k", "deg/s")):
        out += _df_message(0x81, struct.pack("<Qb64s", 0, ord(ident), label.encode()))
    out += _df_message(0x83, struct.pack("<QB16s16s", 0, 10, b"sdk", b"F--"))
    roll = np.round(SIGNAL, 3).astype(np.float32)
    for k in range(N):
        out += _df_message(10, struct.pack("<Qff", 1_000_000 + 20_000 * k, roll[k], 2 * roll[k]))
    path = tmp_path / "log.bin"
    path.write_bytes(bytes(out))
    table = read_table(path, variable="ATT")
    fd = to_flight_data(table, time="t", outputs={"phi": "Roll", "p": "GyrX"})
    np.testing.assert_allclose(fd.output("phi"), roll.astype(float) * DEG, rtol=1e-12)
    np.testing.assert_allclose(fd.output("p"), 2 * roll.astype(float) * DEG, rtol=1e-12)
    assert fd.units == {"phi": "rad", "p": "rad/s"}


def test_channel_spec_checks_the_new_key():
    with pytest.raises(ChannelError, match=r"ignore_file_unit: expected true or false"):
        ChannelSpec.from_value({"column": 1, "ignore_file_unit": "yes"}, "outputs.x")
    with pytest.raises(ChannelError, match=r"outputs\.x\.to: .*unknown unit"):
        ChannelSpec.from_value({"column": 1, "to": "furlong"}, "outputs.x")


def test_case_file_with_contradicting_unit_is_refused(tmp_path):
    """The CSV walk-through with a case unit that contradicts the header."""
    target = tmp_path / "walk"
    shutil.copytree(WALK, target)
    case_path = target / "my_case.toml"
    text = case_path.read_text()
    old = 'q = { column = "pitch_rate", unit = "deg/s", to = "rad/s" }'
    assert old in text
    case_path.write_text(text.replace(old, 'q = { column = "pitch_rate", unit = "rad/s" }'))
    case = load_case(case_path)
    with pytest.raises(CaseError, match=r"outputs\.q: the channel declares unit = 'rad/s'.*deg/s"):
        load_maneuvers(case, target)
    # the header's unit alone gives the same maneuver as the walk-through's declared units
    case_path.write_text(
        text.replace(old, 'q = "pitch_rate"').replace(
            'alpha = { column = "AOA", unit = "deg", to = "rad" }', 'alpha = "AOA"'
        )
    )
    implied = load_maneuvers(load_case(case_path), target)[0]
    case_path.write_text(text)
    declared = load_maneuvers(load_case(case_path), target)[0]
    np.testing.assert_allclose(implied.output("q"), declared.output("q"), rtol=1e-15)
    np.testing.assert_allclose(implied.output("alpha"), declared.output("alpha"), rtol=1e-15)
