"""The files users have load as they are, or are refused with a named error before reading.

MATLAB structs (v5 and v7.3) are read by name with their fields as columns; byte-order marks
are dropped; duplicate column names, cells such as ``1_000``, non-regular paths (fifo,
device, directory) and files larger than the available memory are refused with a
``DataFileError``/``ChannelError`` that says what came.
"""

from __future__ import annotations

import codecs
import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from flightid.data import loaders
from flightid.data.loaders import (
    ChannelError,
    DataFileError,
    FileTooLargeError,
    read_table,
    to_flight_data,
)

RNG = np.random.default_rng(7)
N = 40
T = np.arange(N) * 0.05
P = RNG.normal(size=N)
DA = RNG.normal(size=N)
GYR = RNG.normal(size=N)
ACC = RNG.normal(size=(N, 3))


# ---------------------------------------------------------------- MATLAB v5 structs


@pytest.fixture()
def v5_structs(tmp_path) -> Path:
    sio = pytest.importorskip("scipy.io")
    path = tmp_path / "maneuvers.mat"
    ail_1 = {
        "time": T,
        "p": P[:, None],  # a column vector
        "delta_a": DA,  # a row vector
        "mass": 2.5,
        "note": "first aileron doublet",
        "IMU": {"GyrX": GYR, "Acc": ACC},
        "gps_alt": np.arange(5.0),  # another rate: not a column
    }
    sio.savemat(path, {"ail_1": ail_1, "ail_2": {"time": T, "p": -P}, "flight": {"ail_1": ail_1}})
    return path


def test_v5_struct_fields_are_columns_by_name(v5_structs):
    table = read_table(v5_structs, variable="ail_1")
    assert table.names == (
        "time",
        "p",
        "delta_a",
        "IMU.GyrX",
        "IMU.Acc_1",
        "IMU.Acc_2",
        "IMU.Acc_3",
    )
    assert table.constants == {"mass": 2.5}
    np.testing.assert_array_equal(table.column("p"), P)
    np.testing.assert_array_equal(table.column("IMU.Acc_2"), ACC[:, 1])
    fd = to_flight_data(
        table,
        time="time",
        inputs={"da": "delta_a"},
        outputs={"p": "p", "r": "IMU.GyrX - 0.5 * p"},
    )
    np.testing.assert_array_equal(fd.input("da"), DA)
    np.testing.assert_allclose(fd.output("r"), GYR - 0.5 * P, rtol=1e-15)
    other = read_table(v5_structs, variable="ail_2")
    np.testing.assert_array_equal(other.column("p"), -P)


def test_v5_file_without_matrix_or_vectors_is_refused(tmp_path):
    from scipy.io import savemat

    path = tmp_path / "scalars.mat"
    savemat(str(path), {"mass": 1.5, "title": "run 3"})
    with pytest.raises(DataFileError, match=r"scalars.mat: no numeric matrix or vectors found$"):
        read_table(path)


def test_v5_nested_struct_by_dotted_name(v5_structs):
    table = read_table(v5_structs, variable="flight.ail_1")
    np.testing.assert_array_equal(table.column("delta_a"), DA)
    imu = read_table(v5_structs, variable="ail_1.IMU")
    assert imu.names == ("GyrX", "Acc_1", "Acc_2", "Acc_3")


def test_v5_struct_errors_name_what_the_file_holds(v5_structs):
    with pytest.raises(DataFileError, match=r"structs \['ail_1', 'ail_2', 'flight'\].*variable"):
        read_table(v5_structs)
    with pytest.raises(DataFileError, match=r"no numeric variable or struct 'ail_3'.*structs"):
        read_table(v5_structs, variable="ail_3")
    with pytest.raises(DataFileError, match=r"'ail_1' has no field 'q'; fields: \['time'"):
        read_table(v5_structs, variable="ail_1.q")
    table = read_table(v5_structs, variable="ail_1")
    with pytest.raises(ChannelError, match=r"'gps_alt' .* is not a column: a 1 × 5 field"):
        table.column("gps_alt")


def test_v5_struct_array_is_refused(tmp_path):
    sio = pytest.importorskip("scipy.io")
    path = tmp_path / "array.mat"
    records = np.zeros((1, 2), dtype=[("time", object), ("p", object)])
    for k in range(2):
        records[0, k]["time"] = T
        records[0, k]["p"] = P
    sio.savemat(path, {"man": records})
    with pytest.raises(DataFileError, match=r"'man' is a 1 × 2 struct array; .*one struct"):
        read_table(path, variable="man")


# ---------------------------------------------------------------- MATLAB v7.3 structs


def _write_mat73_struct(path: Path) -> Path:
    """A MATLAB-v7.3-like file: HDF5 with a 512-byte user block; a struct is a group with
    MATLAB_class "struct"; numeric fields are stored transposed (column-major)."""
    h5py = pytest.importorskip("h5py")
    with h5py.File(path, "w", userblock_size=512) as f:
        man = f.create_group("ail_1")
        man.attrs["MATLAB_class"] = np.bytes_("struct")
        for name, value in (("time", T[:, None]), ("p", P[:, None]), ("mass", [[2.5]])):
            ds = man.create_dataset(name, data=np.asarray(value, dtype=float).T)
            ds.attrs["MATLAB_class"] = np.bytes_("double")
        imu = man.create_group("IMU")
        imu.attrs["MATLAB_class"] = np.bytes_("struct")
        ds = imu.create_dataset("GyrX", data=GYR[:, None].T)
        ds.attrs["MATLAB_class"] = np.bytes_("double")
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Nov 23 08:00:00 2026 HDF5"
    with open(path, "r+b") as f:
        f.write(header.ljust(116) + b"\x00" * 8 + b"\x00\x02IM")
    return path


def test_v73_struct_fields_are_columns_by_name(tmp_path):
    path = _write_mat73_struct(tmp_path / "v73.mat")
    table = read_table(path, variable="ail_1")
    assert set(table.names) == {"time", "p", "IMU.GyrX"}
    assert table.constants == {"mass": 2.5}
    np.testing.assert_array_equal(table.column("p"), P)
    np.testing.assert_array_equal(table.column("IMU.GyrX"), GYR)
    np.testing.assert_array_equal(read_table(path, variable="ail_1.IMU").column("GyrX"), GYR)
    with pytest.raises(DataFileError, match=r"structs \['ail_1'\]"):
        read_table(path)


# ---------------------------------------------------------------- text files


def _rows() -> list[str]:
    return [f"{t:.2f},{p:.6f},{d:.6f}" for t, p, d in zip(T, P, DA, strict=True)]


def test_utf8_bom_does_not_change_the_first_column_name(tmp_path):
    path = tmp_path / "excel.csv"
    text = "\n".join(["time,p,delta_a", *_rows()]) + "\n"
    path.write_bytes(codecs.BOM_UTF8 + text.encode("utf-8"))
    table = read_table(path)
    assert table.names == ("time", "p", "delta_a")
    np.testing.assert_allclose(
        to_flight_data(table, time="time", outputs={"p": "p"}).time, T, atol=1e-12
    )


def test_utf16_bom_text_is_read(tmp_path):
    # Excel's "Unicode text": UTF-16 with a byte-order mark, tab-separated
    path = tmp_path / "excel.csv"
    text = "\r\n".join(["time\tp\tdelta_a", *(r.replace(",", "\t") for r in _rows())])
    path.write_bytes(codecs.BOM_UTF16_LE + text.encode("utf-16-le"))
    table = read_table(path)
    assert table.names == ("time", "p", "delta_a")
    np.testing.assert_allclose(table.column("p"), np.round(P, 6), atol=1e-12)


def test_duplicate_column_names_are_refused_naming_them(tmp_path):
    path = tmp_path / "dup.csv"
    rows = [f"{t:.2f},{p:.6f},{-p:.6f}" for t, p in zip(T, P, strict=True)]
    path.write_text("\n".join(["time,p,p", *rows]) + "\n")
    table = read_table(path)
    with pytest.raises(ChannelError, match=r"outputs\.p: .*2 columns named 'p': columns \[2, 3\]"):
        to_flight_data(table, time="time", outputs={"p": "p"})
    # by number, each one can be used
    fd = to_flight_data(table, time="time", outputs={"p": 3})
    np.testing.assert_allclose(fd.output("p"), -np.round(P, 6), atol=1e-12)


@pytest.mark.parametrize("cell", ["1_000", "١٢"])
def test_cells_python_reads_but_files_do_not_write_are_refused(tmp_path, cell):
    path = tmp_path / "odd.csv"
    rows = _rows()
    rows[4] = f"0.20,{cell},0.5"
    path.write_text("\n".join(["time,p,delta_a", *rows]) + "\n")
    with pytest.raises(DataFileError, match=rf"row 6 .*column 2 \('p'\), '{cell}' is not a number"):
        read_table(path)
    ascii_path = tmp_path / "odd.asc"
    ascii_path.write_text("\n".join(r.replace(",", " ") for r in rows) + "\n")
    with pytest.raises(DataFileError, match=rf"line 5 .*column 2, '{cell}' is not a number"):
        read_table(ascii_path)


# ---------------------------------------------------------------- paths that are no files


def test_fifo_is_refused_before_reading(tmp_path):
    path = tmp_path / "flight.csv"
    os.mkfifo(path)
    done = threading.Event()

    def writer() -> None:
        # stands in for a program that writes the pipe, so that a reader that opens it
        # (instead of refusing it) gets an empty file rather than hanging the test
        deadline = time.monotonic() + 10.0
        while not done.is_set() and time.monotonic() < deadline:
            try:
                fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)
            except OSError:
                time.sleep(0.01)
                continue
            os.close(fd)
            return

    thread = threading.Thread(target=writer, daemon=True)
    thread.start()
    try:
        with pytest.raises(DataFileError, match=r"is a fifo \(named pipe\), expected a regular"):
            read_table(path)
    finally:
        done.set()
        thread.join(timeout=11)


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero")
def test_device_and_directory_are_refused(tmp_path):
    with pytest.raises(DataFileError, match=r"/dev/zero: is a device, expected a regular"):
        read_table("/dev/zero", "csv")
    with pytest.raises(DataFileError, match=r"is a directory"):
        read_table(tmp_path, "mat")


def test_file_larger_than_available_memory_is_refused(tmp_path, monkeypatch):
    path = tmp_path / "big.csv"
    path.write_text("\n".join(["time,p,delta_a", *_rows()]) + "\n")
    size = path.stat().st_size
    monkeypatch.setattr(loaders, "available_memory_bytes", lambda: size)  # bytes
    with pytest.raises(FileTooLargeError, match=r"big.csv: .*needs about .* is available"):
        read_table(path)
    monkeypatch.setattr(loaders, "available_memory_bytes", lambda: 1000 * size)
    assert read_table(path).n_rows == N


def test_memory_error_while_reading_is_named(tmp_path, monkeypatch):
    path = tmp_path / "flight.csv"
    path.write_text("\n".join(["time,p,delta_a", *_rows()]) + "\n")

    def exhausted(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(loaders, "read_csv", exhausted)
    with pytest.raises(FileTooLargeError, match=r"ran out of memory while reading it"):
        read_table(path)


def test_available_memory_is_a_positive_byte_count():
    available = loaders.available_memory_bytes()
    assert available is None or (isinstance(available, int) and available > 0)
