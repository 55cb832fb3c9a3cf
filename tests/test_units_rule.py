"""The one channel unit rule (flightid.data.units.channel_conversion), in every case type.

A channel with ``unit`` alone is delivered in SI with angles in radians; ``to`` names another
delivered unit; an unknown unit is refused; value = (source · scale + offset) · factor.
Conversion factors are the exact legal definitions (sources in the comments), not earlier
output of flightid.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from flightid.cases import CaseError as RunCaseError
from flightid.cases import load_case as load_run_case
from flightid.cases.build import load_maneuvers
from flightid.cases.stages import case_signals
from flightid.data.loaders import ChannelError, ChannelSpec, read_table, to_flight_data
from flightid.data.units import UnitError, channel_conversion, parse_unit, si_label
from flightid.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "examples/csv_walkthrough"

DEG = math.pi / 180.0  # rad per degree (definition)
FT = 0.3048  # m per international foot (exact, 1959 agreement)
KT = 1852.0 / 3600.0  # m/s per knot (1 nmi = 1852 m exactly)
G0 = 9.80665  # m/s² standard gravity (ISO 80000-3, CGPM 1901)
LBF = 0.45359237 * G0  # N per pound-force (1 lbm = 0.45359237 kg exactly, times g0)


@pytest.mark.parametrize(
    ("unit", "factor", "delivered"),
    [
        ("deg", DEG, "rad"),
        ("deg/s", DEG, "rad/s"),
        ("DEG/S**2", DEG, "rad/s^2"),
        ("rad", 1.0, "rad"),
        ("ft", FT, "m"),
        ("ft/sec", FT, "m/s"),
        ("kt", KT, "m/s"),
        ("g", G0, "m/s^2"),
        ("lbf", LBF, "N"),
        ("lbf/ft^2", LBF / FT**2, "Pa"),
        ("slug*ft^2", LBF / FT * FT**2, "kg*m^2"),  # 1 slug = 1 lbf·s²/ft
        ("%", 0.01, "1"),
        ("min", 60.0, "s"),
    ],
)
def test_unit_alone_is_delivered_in_si_with_angles_in_radians(unit, factor, delivered):
    got_factor, got_unit = channel_conversion(unit)
    assert got_factor == pytest.approx(factor, rel=1e-12)
    assert got_unit == delivered


@pytest.mark.parametrize(
    ("unit", "to", "factor"),
    [
        ("deg", "deg", 1.0),
        ("g", "g", 1.0),
        ("deg/s", "rad/s", DEG),
        ("rad", "deg", 1.0 / DEG),
        ("m/s", "kt", 1.0 / KT),
        ("g", "ft/s^2", G0 / FT),
    ],
)
def test_to_names_the_delivered_unit(unit, to, factor):
    assert channel_conversion(unit, to) == (pytest.approx(factor, rel=1e-12), to)


def test_no_unit_means_values_as_recorded():
    assert channel_conversion("") == (1.0, "")


@pytest.mark.parametrize(
    "dimension", [(0, 0, 0, 1), (1, 0, -2, 0), (-1, 1, -2, 0), (1, 0, -1, 1), (0, 0, -1, 0)]
)
def test_si_label_parses_back_to_factor_one_and_the_same_dimension(dimension):
    assert parse_unit(si_label(dimension)) == (1.0, dimension)


@pytest.mark.parametrize(
    ("unit", "to", "match"),
    [
        ("furlong", "", r"unknown unit 'furlong'; known: \[.*'deg'.*'rad'"),
        ("degs", "", "unknown unit 'degs'"),
        ("kn", "", "ambiguous"),  # knots or kilonewtons
        ("", "rad", "give the source unit too"),
        ("deg", "m/s", "different quantities"),
        ("deg", "gon", "unknown unit 'gon'"),
    ],
)
def test_refused_units_are_named_unit_errors(unit, to, match):
    with pytest.raises(UnitError, match=match):
        channel_conversion(unit, to)


# ------------------------------------------------------------------ loaders (run case files)


@pytest.fixture()
def table(tmp_path):
    path = tmp_path / "flight.csv"
    t = np.arange(6) * 0.1
    source = np.array([1.0, -2.0, 3.5, 0.25, 10.0, -7.0])
    rows = "\n".join(f"{a},{b},{2 * b}" for a, b in zip(t, source, strict=True))
    path.write_text("time,a,b\n" + rows + "\n")
    return read_table(path), source


def test_channel_with_scale_offset_and_unit_together(table):
    """value = (source · scale + offset) · factor: scale and offset act in the source unit."""
    tab, source = table
    spec = ChannelSpec.from_value(
        {"column": "a", "scale": 2.0, "offset": 5.0, "unit": "deg"}, "inputs.x"
    )
    expected = (source * 2.0 + 5.0) * DEG
    np.testing.assert_allclose(spec.evaluate(tab, "inputs.x"), expected, rtol=1e-15)
    # the other order, source · scale · factor + offset, would differ by 5·(1 − π/180)
    assert not np.allclose(spec.evaluate(tab, "inputs.x"), source * 2.0 * DEG + 5.0)
    with_to = ChannelSpec.from_value(
        {"column": "a", "scale": 2.0, "offset": 5.0, "unit": "ft", "to": "m"}, "inputs.x"
    )
    np.testing.assert_allclose(
        with_to.evaluate(tab, "inputs.x"), (source * 2.0 + 5.0) * FT, rtol=1e-15
    )


def test_unit_alone_converts_in_flight_data_and_reports_the_si_unit(table):
    tab, source = table
    fd = to_flight_data(
        tab,
        time="time",
        inputs={"de": {"column": "a", "unit": "deg"}},
        outputs={
            "alpha": {"column": "a", "unit": "deg", "to": "deg"},
            "az": {"column": "b", "unit": "g"},
            "raw": "b",
        },
    )
    np.testing.assert_allclose(fd.channel("de"), source * DEG, rtol=1e-15)
    np.testing.assert_allclose(fd.output("alpha"), source, rtol=1e-15)
    np.testing.assert_allclose(fd.output("az"), 2 * source * G0, rtol=1e-15)
    np.testing.assert_allclose(fd.output("raw"), 2 * source, rtol=1e-15)
    assert fd.units["de"] == "rad" and fd.units["alpha"] == "deg" and fd.units["az"] == "m/s^2"


def test_unknown_unit_without_to_is_refused_by_the_channel_spec():
    with pytest.raises(ChannelError, match=r"outputs\.alpha: .*unknown unit 'furlong'; known:"):
        ChannelSpec.from_value({"column": 2, "unit": "furlong"}, "outputs.alpha")


def test_time_is_delivered_in_seconds(table):
    tab, _ = table
    fd = to_flight_data(tab, time={"column": "time", "unit": "min"}, outputs={"a": "a"})
    np.testing.assert_allclose(fd.time, np.arange(6) * 6.0, rtol=1e-12)  # 0.1 min = 6 s
    with pytest.raises(InputError, match="time: expected the time in s"):
        to_flight_data(tab, time={"column": "time", "unit": "s", "to": "min"}, outputs={"a": "a"})


# ------------------------------------------------------------------ `flightid run` case files


@pytest.fixture()
def walk(tmp_path) -> Path:
    target = tmp_path / "walk"
    shutil.copytree(WALK, target)
    return target


def _maneuver(case_path: Path):
    case = load_run_case(case_path)
    (maneuver,) = load_maneuvers(case, case_path.parent)
    return maneuver


def _csv_column(path: Path, name: str) -> np.ndarray:
    header = path.read_text().splitlines()[0].split(",")
    index = next(i for i, h in enumerate(header) if h.startswith(name))
    return np.loadtxt(path, delimiter=",", skiprows=1)[:, index]


def test_run_case_unit_deg_without_to_delivers_radians(walk):
    """The observed bug: `unit = "deg"` without `to` kept degrees in run case files."""
    case = walk / "my_case.toml"
    text = case.read_text()
    old = 'alpha = { column = "AOA", unit = "deg", to = "rad" }'
    assert old in text
    case.write_text(text.replace(old, 'alpha = { column = "AOA", unit = "deg" }'))
    maneuver = _maneuver(case)
    aoa_deg = _csv_column(walk / "my_flight.csv", "AOA")
    np.testing.assert_allclose(maneuver.output("alpha"), aoa_deg * DEG, rtol=1e-15)
    assert maneuver.units["alpha"] == "rad"
    # and `to = "deg"` keeps degrees
    case.write_text(text.replace(old, 'alpha = { column = "AOA", unit = "deg", to = "deg" }'))
    np.testing.assert_allclose(_maneuver(case).output("alpha"), aoa_deg, rtol=1e-15)


def test_run_case_unknown_unit_without_to_is_refused(walk):
    case = walk / "my_case.toml"
    text = case.read_text()
    case.write_text(text.replace('unit = "deg", to = "rad" }', 'unit = "dgr" }', 1))
    with pytest.raises(RunCaseError, match=r"data\.inputs\.de: .*unknown unit 'dgr'; known:"):
        load_run_case(case)


# ------------------------------------------------------------------ stepwise stages


def _regress_case(tmp_path: Path, signal_line: str, ml_output: str = "") -> Path:
    """A case with a stepwise stage over a small CSV (columns time, a, b)."""
    t = np.arange(40) * 0.05
    a = np.sin(t) * 5.0
    rows = "\n".join(f"{x},{y},{2 * y}" for x, y in zip(t, a, strict=True))
    (tmp_path / "f.csv").write_text("time,a,b\n" + rows + "\n")
    case = tmp_path / "case.toml"
    case.write_text(
        f'[data]\nfile = "f.csv"\ndata_dir = "."\nformat = "csv"\n'
        f"[data.inputs]\n{signal_line}\nCm = 3\n"
        '[[stages]]\nkind = "stepwise"\n[stages.coefficients.Cm]\ncandidates = ["alpha"]\n'
    )
    return case


def test_regress_signal_follows_the_same_rule(tmp_path):
    case = _regress_case(tmp_path, 'alpha = { column = 2, unit = "deg" }')
    a = np.sin(np.arange(40) * 0.05) * 5.0
    signals = case_signals(load_run_case(case))
    np.testing.assert_allclose(signals["alpha"], a * DEG, rtol=1e-12)
    # the run-case channel spec of the same line gives the same values
    spec = ChannelSpec.from_value({"column": 2, "unit": "deg"}, "outputs.alpha")
    np.testing.assert_allclose(
        spec.evaluate(read_table(tmp_path / "f.csv"), "x"), signals["alpha"], rtol=1e-15
    )


def test_regress_signal_to_keeps_degrees_and_other_units_convert(tmp_path):
    case = _regress_case(
        tmp_path,
        'alpha = { column = 2, unit = "deg", to = "deg" }\nrate = { column = 2, '
        'unit = "deg/s", scale = 2.0 }',
    )
    a = np.sin(np.arange(40) * 0.05) * 5.0
    signals = case_signals(load_run_case(case))
    np.testing.assert_allclose(signals["alpha"], a, rtol=1e-12)
    np.testing.assert_allclose(signals["rate"], 2.0 * a * DEG, rtol=1e-12)


def test_regress_unknown_unit_is_refused_with_the_known_ones(tmp_path):
    case = _regress_case(tmp_path, 'alpha = { column = 2, unit = "grad" }')
    with pytest.raises(RunCaseError, match=r"data\.inputs\.alpha: .*known: \[.*'deg'"):
        load_run_case(case)
