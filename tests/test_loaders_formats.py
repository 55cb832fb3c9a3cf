"""Loaders for formats behind optional extras: Parquet (pyarrow), MATLAB v7.3 (h5py).

Each test writes a small file with the package itself, reads it with ``read_table`` and maps
channels (units, expressions) with ``to_flight_data`` exactly as for CSV files.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from flightid.data.formats import Stream
from flightid.data.loaders import DataFileError, read_table, to_flight_data
from flightid.data.logwrite import write_dataflash, write_ulog
from flightid.data.timebase import TimeBaseError
from flightid.errors import FlightIdError
from flightid.results import MissingDependencyError

RNG = np.random.default_rng(20261123)
N = 40
T = np.arange(N) * 0.02
ALPHA_DEG = RNG.normal(size=N)
Q_DEGS = RNG.normal(size=N)
DE_L = RNG.normal(size=N)
DE_R = RNG.normal(size=N)


def _hide(monkeypatch, package: str) -> None:
    """Make ``import package`` (and its submodules) fail as if it were not installed: a
    ``None`` entry in ``sys.modules`` makes every import of that name raise ImportError."""
    for key in [k for k in sys.modules if k == package or k.startswith(package + ".")]:
        monkeypatch.delitem(sys.modules, key)
    for key in (package, f"{package}.parquet"):
        monkeypatch.setitem(sys.modules, key, None)


def _check_mapping(table) -> None:
    """Units and expressions flow through the channel mapping as for CSV."""
    fd = to_flight_data(
        table,
        time="t",
        inputs={"de": {"expr": "(de_r - de_l) / 2", "unit": "deg"}},
        outputs={
            "alpha": {"column": "alpha", "unit": "deg"},
            "q": {"column": "q", "unit": "deg/s"},
        },
    )
    # units are declared in the mapping, as for CSV: 1 deg = π/180 rad (definition)
    assert np.allclose(fd.output("alpha"), ALPHA_DEG * math.pi / 180)
    assert np.allclose(fd.output("q"), Q_DEGS * math.pi / 180)
    assert np.allclose(fd.input("de"), (DE_R - DE_L) / 2 * math.pi / 180)
    assert np.allclose(fd.time, T)


# ---------------------------------------------------------------- Parquet


def _write_parquet(path: Path) -> Path:
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    schema = pa.schema(
        [
            pa.field("t", pa.float64(), metadata={"unit": "s"}),
            pa.field("alpha", pa.float64(), metadata={"unit": "deg"}),
            pa.field("q [deg/s]", pa.float32()),
            pa.field("de_l", pa.float64()),
            pa.field("de_r", pa.float64()),
            pa.field("label", pa.string()),
            pa.field("n", pa.int32()),
        ]
    )
    table = pa.table(
        [
            T,
            ALPHA_DEG,
            Q_DEGS.astype(np.float32),
            DE_L,
            DE_R,
            [f"row{i}" for i in range(N)],
            np.arange(N, dtype=np.int32),
        ],
        schema=schema,
    )
    pq.write_table(table, path)
    return path


def test_parquet_columns_units_and_mapping(tmp_path):
    path = _write_parquet(tmp_path / "flight.parquet")
    table = read_table(path)
    # the string column is left out; units from field metadata or "name [unit]"
    assert table.names == ("t", "alpha", "q", "de_l", "de_r", "n")
    assert table.units == ("s", "deg", "deg/s", "", "", "")
    assert np.array_equal(table.column("n"), np.arange(N))
    # float32 column: equal to the float32-rounded values
    assert np.array_equal(table.column("q"), Q_DEGS.astype(np.float32).astype(float))
    _check_mapping(
        read_table(path, "parquet")  # explicit format, same result
    )


def test_parquet_nulls_are_nan_and_bad_files(tmp_path):
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    path = tmp_path / "gaps.pq"
    pq.write_table(pa.table({"t": [0.0, 1.0, 2.0], "x": [1.0, None, 3.0]}), path)
    x = read_table(path).column("x")
    assert x[0] == 1.0 and math.isnan(x[1]) and x[2] == 3.0

    only_text = tmp_path / "text.parquet"
    pq.write_table(pa.table({"s": ["a", "b", "c"]}), only_text)
    with pytest.raises(DataFileError, match="no numeric columns"):
        read_table(only_text)
    garbage = tmp_path / "garbage.parquet"
    garbage.write_bytes(b"not parquet at all")
    with pytest.raises(DataFileError, match="not a readable Parquet file"):
        read_table(garbage)


def test_parquet_missing_extra_is_named_error(tmp_path, monkeypatch):
    path = tmp_path / "x.parquet"
    path.write_bytes(b"PAR1")
    _hide(monkeypatch, "pyarrow")
    with pytest.raises(MissingDependencyError, match=r"flightid\[parquet\]") as info:
        read_table(path)
    assert isinstance(info.value, ImportError) and isinstance(info.value, FlightIdError)


# ---------------------------------------------------------------- MATLAB v7.3


def _write_mat73(path: Path, variables: dict) -> Path:
    """A MATLAB-v7.3-like file: HDF5 with a 512-byte user block holding MATLAB's text header;
    numeric arrays stored transposed (column-major) with a ``MATLAB_class`` attribute; char
    arrays as uint16 codes; cell arrays as object references under ``#refs#``."""
    h5py = pytest.importorskip("h5py")
    with h5py.File(path, "w", userblock_size=512) as f:
        refs = f.create_group("#refs#")
        for name, value in variables.items():
            if isinstance(value, list):  # cell array of strings (1 × k)
                ref_list = []
                for i, text in enumerate(value):
                    # a MATLAB 1 × L char row is stored as L × 1
                    codes = np.array([ord(c) for c in text], dtype=np.uint16)[:, None]
                    ds = refs.create_dataset(f"{name}{i}", data=codes)
                    ds.attrs["MATLAB_class"] = np.bytes_("char")
                    ref_list.append(ds.ref)
                ds = f.create_dataset(name, data=np.array(ref_list, dtype=h5py.ref_dtype)[:, None])
                ds.attrs["MATLAB_class"] = np.bytes_("cell")
            elif isinstance(value, str):  # char row
                ds = f.create_dataset(
                    name, data=np.array([ord(c) for c in value], dtype=np.uint16)[:, None]
                )
                ds.attrs["MATLAB_class"] = np.bytes_("char")
            elif isinstance(value, tuple):  # char matrix: rows of equal length
                rows = np.array([[ord(c) for c in row] for row in value], dtype=np.uint16)
                ds = f.create_dataset(name, data=rows.T)
                ds.attrs["MATLAB_class"] = np.bytes_("char")
            else:
                matrix = np.atleast_2d(np.asarray(value, dtype=float))
                ds = f.create_dataset(name, data=matrix.T)
                ds.attrs["MATLAB_class"] = np.bytes_("double")
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Nov 23 08:00:00 2026 HDF5"
    with open(path, "r+b") as f:
        f.write(header.ljust(116) + b"\x00" * 8 + b"\x00\x02IM")
    return path


def test_mat73_sidpac_fdata_varlab_transposed(tmp_path):
    fdata = np.column_stack([T, ALPHA_DEG, Q_DEGS, DE_L, DE_R])
    assert fdata.shape == (N, 5)
    # SIDPAC varlab: a char matrix, one padded row per column
    varlab = tuple(
        s.ljust(16)
        for s in ("time (sec)", "alpha (deg)", "* q (deg/s)", "de_l (deg)", "de_r (deg)")
    )
    path = _write_mat73(tmp_path / "f18.mat", {"fdata": fdata, "varlab": varlab, "sarea": 400.0})
    table = read_table(path)
    assert table.names == ("time", "alpha", "q", "de_l", "de_r")
    assert table.units == ("sec", "deg", "deg/s", "deg", "deg")
    assert np.array_equal(table.data, fdata)  # not transposed: rows are samples
    assert table.constants["sarea"] == 400.0
    fd = to_flight_data(
        table,
        time="time",
        inputs={"de": {"expr": "(de_r - de_l) / 2", "unit": "deg", "to": "deg"}},
        outputs={
            "alpha": {"column": "alpha", "unit": "deg"},
            "q": {"column": "q", "unit": "deg/s"},
        },
    )
    assert np.allclose(fd.input("de"), (DE_R - DE_L) / 2)
    # declared units: deg → rad, deg/s → rad/s; 1 deg = π/180 rad (definition)
    assert np.allclose(fd.output("alpha"), ALPHA_DEG * math.pi / 180)
    assert np.allclose(fd.output("q"), Q_DEGS * math.pi / 180)


def test_mat73_cell_varlab_named_vectors_and_variable(tmp_path):
    fdata = np.column_stack([T, ALPHA_DEG, Q_DEGS, DE_L, DE_R])
    labels = ["t (s)", "alpha (deg)", "q (deg/s)", "de_l (deg)", "de_r (deg)"]
    table = read_table(_write_mat73(tmp_path / "cell.mat", {"fdata": fdata, "varlab": labels}))
    assert table.names == ("t", "alpha", "q", "de_l", "de_r")
    _check_mapping(table)

    # named column vectors (N × 1 in MATLAB) of one length, a title string, a scalar
    vectors = {"t": T[:, None], "alpha": ALPHA_DEG[:, None], "q": Q_DEGS[:, None]}
    path = _write_mat73(tmp_path / "vec.mat", {**vectors, "title": "run 3", "mass": 1.5})
    table = read_table(path)
    assert set(table.names) == {"t", "alpha", "q"}
    assert np.array_equal(table.column("alpha"), ALPHA_DEG)
    assert table.constants == {"mass": 1.5}

    # two matrices: name one; an N × 3 matrix stays N × 3
    m1 = np.column_stack([T, ALPHA_DEG, Q_DEGS])
    path = _write_mat73(tmp_path / "two.mat", {"a": m1, "b": m1[:, :2]})
    with pytest.raises(DataFileError, match="several matrices"):
        read_table(path)
    assert np.array_equal(read_table(path, variable="a").data, m1)


def test_mat73_missing_extra_is_named_error(tmp_path, monkeypatch):
    pytest.importorskip("h5py")
    path = _write_mat73(tmp_path / "x.mat", {"x": np.eye(3)})
    _hide(monkeypatch, "h5py")
    with pytest.raises(MissingDependencyError, match=r"flightid\[hdf5\]"):
        read_table(path)


# ---------------------------------------------------------------- PX4 ULog


def _write_ulog(path: Path, topics: dict, parameters: dict[str, float]) -> Path:
    """A ULog file written by the package's writer (``flightid.data.logwrite.write_ulog``,
    through pyulog) from ``{topic: ([(type, field)], time µs, rows)}``; ``float[n] x``
    becomes the stream fields ``x_0 … x_{n−1}``. A key ``"name:k"`` is multi-instance k."""
    streams, field_types = [], {}
    for key, (fields, time_us, rows) in topics.items():
        names, kinds = [], {}
        for kind, name in fields:
            if kind.startswith("float["):
                size = int(kind[6:-1])
                names += [f"{name}_{i}" for i in range(size)]
            else:
                names.append(name)
                kinds[name] = kind
        columns = np.asarray(rows, dtype=float).T
        streams.append(
            Stream(key, np.asarray(time_us) * 1e-6, dict(zip(names, columns, strict=True)))
        )
        field_types[key] = kinds
    return write_ulog(path, streams, parameters, field_types=field_types)


def _ulog_topics():
    t_att = np.arange(30) * 20_000  # µs: 50 Hz from 0
    att = np.column_stack([RNG.normal(size=30), RNG.normal(size=30)])
    t_imu = 30_000 + np.arange(50) * 10_000  # µs: 100 Hz from 0.03 s to 0.52 s
    s = t_imu * 1e-6
    # linear in time, so linear interpolation reproduces the line exactly
    imu = np.column_stack([2 + 0.5 * s, -1 + 3 * s, 4 - s, 7 * s])
    return {
        "vehicle_attitude": ([("float", "roll"), ("double", "pitch")], t_att, att),
        "sensor_combined": ([("float[3]", "gyro_rad"), ("float", "acc")], t_imu, imu),
    }, (t_att, att)


def test_ulog_topics_keep_their_own_time_and_resample_on_purpose(tmp_path):
    pytest.importorskip("pyulog")
    topics, (t_att, att) = _ulog_topics()
    path = _write_ulog(tmp_path / "flight.ulg", topics, {"TEST_P": 1.5})
    table = read_table(path, variable="vehicle_attitude,sensor_combined")
    assert table.names == (
        "t",
        "vehicle_attitude.roll",
        "vehicle_attitude.pitch",
        "sensor_combined.gyro_rad_0",
        "sensor_combined.gyro_rad_1",
        "sensor_combined.gyro_rad_2",
        "sensor_combined.acc",
    )
    assert table.units[0] == "s" and table.constants == {"TEST_P": 1.5}
    # nothing interpolated: the rows are the union of both topics' stamps, each topic's
    # columns hold its own samples and NaN on the other topic's rows
    t_imu = topics["sensor_combined"][1]
    assert np.allclose(table.column("t"), np.union1d(t_att, t_imu) * 1e-6)
    assert [s.name for s in table.streams] == ["vehicle_attitude", "sensor_combined"]
    own = ~np.isnan(table.column("vehicle_attitude.pitch"))
    assert np.allclose(table.column("t")[own], t_att * 1e-6)
    assert np.array_equal(table.column("vehicle_attitude.pitch")[own], att[:, 1])
    assert np.allclose(table.column("vehicle_attitude.roll")[own], att[:, 0].astype(np.float32))
    spec = {
        "time": "t",
        "inputs": {"r": {"expr": "sensor_combined.gyro_rad_0 - 2", "unit": "rad/s"}},
        "outputs": {"theta": {"column": "vehicle_attitude.pitch", "unit": "rad", "to": "deg"}},
    }
    # two time bases and no declared resampling: refused, naming the rates
    with pytest.raises(
        TimeBaseError,
        match=r"time bases: vehicle_attitude \(50 Hz\), sensor_combined \(100 Hz\).*resample_hz",
    ):
        to_flight_data(table, **spec)
    fd = to_flight_data(table, resample_hz=50, **spec)
    # the grid k/50 s inside the span both topics cover (0.03..0.52 s): 0.04, 0.06, ..., 0.52
    s = np.arange(2, 27) / 50
    assert np.allclose(fd.time, s, rtol=0, atol=1e-12)
    # 1 rad = 180/π deg (definition); the 50 Hz topic is read at its own stamps
    assert np.allclose(fd.output("theta"), att[2:27, 1] * 180 / math.pi)
    # the 100 Hz topic is low-passed (zero phase) before it is read: a line passes unchanged
    assert np.allclose(fd.input("r"), 0.5 * s, atol=1e-5)
    assert any("sensor_combined" in n and "low-pass 20 Hz" in n for n in fd.notes)

    # one topic: plain field names, its own time base
    single = read_table(path, "ulog", variable="sensor_combined")
    assert single.names == ("t", "gyro_rad_0", "gyro_rad_1", "gyro_rad_2", "acc")
    assert single.n_rows == 50


def test_ulog_errors(tmp_path):
    pytest.importorskip("pyulog")
    topics, _ = _ulog_topics()
    path = _write_ulog(tmp_path / "flight.ulg", topics, {})
    with pytest.raises(DataFileError, match="several message streams.*sensor_combined"):
        read_table(path)
    with pytest.raises(DataFileError, match="no stream.*vehicle_gps"):
        read_table(path, variable="vehicle_attitude,vehicle_gps")
    bad = tmp_path / "bad.ulg"
    bad.write_bytes(b"not a ulog file at all")
    with pytest.raises(DataFileError, match="not a readable PX4 ULog"):
        read_table(bad)


def test_ulog_missing_extra_is_named_error(tmp_path, monkeypatch):
    path = tmp_path / "x.ulg"
    path.write_bytes(b"ULog")
    _hide(monkeypatch, "pyulog")
    with pytest.raises(MissingDependencyError, match=r"flightid\[px4\]"):
        read_table(path)


# ---------------------------------------------------------------- ArduPilot DataFlash


def _write_dataflash(path: Path):
    """A DataFlash log written by the package's writer (``flightid.data.logwrite.
    write_dataflash``, through pymavlink's packer): ATT at 50 Hz with Roll/Pitch in
    centidegrees ('c': int16 × 0.01), IMU instances 0 and 1 at 100 Hz; units in FMTU."""
    t_att = 1_000_000 + np.arange(25) * 20_000  # µs: 50 Hz from 1 s
    roll_cdeg = RNG.integers(-3000, 3000, size=25)  # centidegrees ('c': int16 × 0.01)
    yaw = RNG.normal(size=25)
    t_imu = 1_005_000 + np.arange(45) * 10_000  # µs: 100 Hz, 1.005 .. 1.445 s
    streams = [
        Stream(
            "ATT",
            t_att * 1e-6,
            {"Roll": roll_cdeg * 0.01, "Pitch": -roll_cdeg * 0.01, "Yaw": yaw},
            {"Roll": "deg", "Pitch": "deg", "Yaw": "deg"},
        )
    ]
    for instance in (0, 1):
        s = t_imu * 1e-6
        # linear in time, so linear interpolation reproduces the line exactly
        streams.append(
            Stream(
                f"IMU[{instance}]",
                s,
                {"GyrX": 0.5 * s + instance, "AccZ": 9.0 - s},
                {"GyrX": "rad/s", "AccZ": "m/s/s"},
            )
        )
    write_dataflash(path, streams, formats={"ATT": {"Roll": "c", "Pitch": "c"}})
    return t_att, roll_cdeg, yaw


def test_dataflash_types_instances_scales_units(tmp_path):
    pytest.importorskip("pymavlink")
    path = tmp_path / "00000042.BIN"
    t_att, roll_cdeg, yaw = _write_dataflash(path)
    table = read_table(path, variable="ATT,IMU[1]")
    assert table.names == ("t", "ATT.Roll", "ATT.Pitch", "ATT.Yaw", "IMU_1.GyrX", "IMU_1.AccZ")
    # units from the log's FMTU/UNIT messages
    assert table.units == ("s", "deg", "deg", "deg", "rad/s", "m/s/s")
    # each type keeps its own stamps (rows: their union)
    own = ~np.isnan(table.column("ATT.Roll"))
    assert np.allclose(table.column("t")[own], t_att * 1e-6)
    # 'c' fields are int16 centidegrees: value = integer × 0.01 (ArduPilot format table)
    assert np.allclose(table.column("ATT.Roll")[own], roll_cdeg * 0.01)
    assert np.allclose(table.column("ATT.Pitch")[own], -roll_cdeg * 0.01)
    spec = {
        "time": "t",
        "inputs": {"p": {"expr": "IMU_1.GyrX - 1", "unit": "rad/s"}},
        "outputs": {"phi": {"column": "ATT.Roll", "unit": "deg"}},
    }
    with pytest.raises(TimeBaseError, match=r"ATT \(50 Hz\), IMU\[1\] \(100 Hz\)"):
        to_flight_data(table, **spec)
    fd = to_flight_data(table, resample_hz=50, **spec)
    # the grid k/50 s inside the span both types cover, 1.005..1.445 s: 1.02, ..., 1.44 s
    s = np.arange(51, 73) / 50
    assert np.allclose(fd.time, s, rtol=0, atol=1e-12)
    keep = (t_att >= 1_005_000) & (t_att <= 1_445_000)
    # 1 deg = π/180 rad (definition)
    assert np.allclose(fd.output("phi"), roll_cdeg[keep] * 0.01 * math.pi / 180)
    assert np.allclose(fd.input("p"), 0.5 * s, atol=1e-5)

    imu0 = read_table(path, "dataflash", variable="IMU[0]")
    assert imu0.names == ("t", "GyrX", "AccZ") and imu0.n_rows == 45
    assert np.allclose(imu0.column("GyrX"), 0.5 * imu0.column("t"), atol=1e-6)


def test_dataflash_errors(tmp_path):
    pytest.importorskip("pymavlink")
    path = tmp_path / "log.bin"
    _write_dataflash(path)
    with pytest.raises(DataFileError, match=r"several message streams.*IMU\[1\]"):
        read_table(path)
    with pytest.raises(DataFileError, match=r"no stream.*IMU.*IMU\[0\]"):
        read_table(path, variable="ATT,IMU")
    # a type not in the log: the message lists every stream the log holds
    with pytest.raises(DataFileError, match=r"no stream.*GPS.*\['ATT', 'IMU\[0\]', 'IMU\[1\]'\]"):
        read_table(path, variable="ATT,GPS")
    bad = tmp_path / "bad.bin"
    bad.write_bytes(b"\x00\x01 not a log")
    with pytest.raises(DataFileError, match="not an ArduPilot DataFlash log"):
        read_table(bad)


def test_dataflash_missing_extra_is_named_error(tmp_path, monkeypatch):
    path = tmp_path / "x.bin"
    path.write_bytes(b"\xa3\x95\x80")
    _hide(monkeypatch, "pymavlink")
    with pytest.raises(MissingDependencyError, match=r"flightid\[ardupilot\]"):
        read_table(path)


def test_dataflash_text_log(tmp_path):
    pytest.importorskip("pymavlink")
    # the text form of a DataFlash log (as written by mavlogdump / Mission Planner): values
    # already scaled, one message per line
    path = tmp_path / "flight.log"
    path.write_text(
        "FMT, 128, 89, FMT, BBnNZ, Type,Length,Name,Format,Columns\n"
        "FMT, 10, 19, ATT, Qcf, TimeUS,Roll,Yaw\n"
        "ATT, 1000000, 12.5, 0.1\n"
        "ATT, 1020000, 13.5, 0.2\n"
        "ATT, 1040000, 14.5, 0.3\n"
    )
    table = read_table(path, "dataflash")  # .log is not picked by extension: name the format
    assert table.names == ("t", "Roll", "Yaw")
    assert np.allclose(table.data, [[1.0, 12.5, 0.1], [1.02, 13.5, 0.2], [1.04, 14.5, 0.3]])


def test_ulog_multi_instance(tmp_path):
    pytest.importorskip("pyulog")
    stamps = np.arange(20) * 10_000
    rows0, rows1 = RNG.normal(size=(20, 1)), RNG.normal(size=(20, 1))
    topics = {
        "sensor_gyro": ([("float", "x")], stamps, rows0),
        "sensor_gyro:1": ([("float", "x")], stamps + 5_000, rows1),
    }
    path = _write_ulog(tmp_path / "multi.ulg", topics, {})
    table = read_table(path, variable="sensor_gyro,sensor_gyro:1")
    assert table.names == ("t", "sensor_gyro.x", "sensor_gyro_1.x")
    assert table.n_rows == 40  # 0, 5, 10, ..., 195 ms: both instances' stamps
    fd = to_flight_data(
        table,
        time="t",
        outputs={"a": "sensor_gyro.x", "b": "sensor_gyro_1.x"},
        resample_hz=100,
    )
    # instance 1 covers 5..195 ms: the grid is 10, 20, ..., 190 ms; instance 0 (at 100 Hz,
    # not faster than the grid) is read at its own stamps, instance 1 halfway between its
    # samples
    assert np.allclose(fd.time, stamps[1:] * 1e-6, rtol=0, atol=1e-12)
    assert np.allclose(fd.output("a"), rows0[1:, 0].astype(np.float32))
    mid = (rows1[:-1, 0] + rows1[1:, 0]).astype(np.float32) / 2
    assert np.allclose(fd.output("b"), mid, atol=1e-6)
    assert read_table(path, variable="sensor_gyro:1").n_rows == 20


def test_mat73_plain_hdf5_without_user_block(tmp_path):
    h5py = pytest.importorskip("h5py")
    # an HDF5 file whose signature is at byte 0 (no MATLAB header), one stored matrix
    path = tmp_path / "plain.mat"
    matrix = np.column_stack([T, ALPHA_DEG])
    with h5py.File(path, "w") as f:
        f.create_dataset("m", data=matrix.T)
    assert np.array_equal(read_table(path).data, matrix)
