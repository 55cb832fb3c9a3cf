"""Log writers (``flightid.data.logwrite``) and the example logs (``flightid.examples.logs``).

Round trips: streams written with ``write_ulog`` / ``write_dataflash`` and read back with
``ulog_streams`` / ``dataflash_streams`` are the same streams (names, stamps, values in the
log's types, DataFlash units through FMTU). The files are also checked with the libraries'
own readers (pyulog's ``ULog``, pymavlink's ``DFReader``) and against the byte layout of the
format specifications. The example logs are checked against an independent simulation
(scipy.signal.lsim of the stated transfer functions, fed the logged command) and identified
from test-side resampled segments with the shipped model modules and case settings.
"""

from __future__ import annotations

import math
import shutil
import struct
import tomllib
from pathlib import Path

import numpy as np
import pytest

from flightid.data.formats import Stream, dataflash_streams, ulog_streams
from flightid.data.logwrite import LogWriteError, write_dataflash, write_ulog
from flightid.errors import InputTypeError

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "logs"
RNG = np.random.default_rng(20261127)


def _ulog_input() -> tuple[list[Stream], dict]:
    # jittering stamps, whole µs as logs store them (the reader gives back µs × 10⁻⁶)
    t = (1_500_000 + np.cumsum(RNG.integers(4000, 5601, size=30))) * 1e-6
    streams = [
        Stream(
            "vehicle_angular_velocity",
            t,
            {"xyz_0": RNG.normal(size=30), "xyz_1": RNG.normal(size=30), "xyz_2": t},
        ),
        Stream("vehicle_status", t[::5], {"nav_state": np.array([2.0, 2, 10, 10, 15, 2])}),
        Stream("sensor_gyro", t[1:], {"x": RNG.normal(size=29)}),
        Stream("sensor_gyro:1", t[:-1], {"x": RNG.normal(size=29)}),
        Stream("estimator", t[:4], {"v_0": [1.0, 2, 3, 4], "count": [1.0, 2, 3, 4]}),
    ]
    field_types = {"vehicle_status": {"nav_state": "uint8_t"}, "estimator": {"v_0": "double"}}
    field_types["estimator"]["count"] = "int32_t"
    return streams, field_types


def test_ulog_round_trip_and_pyulog_reads_it(tmp_path):
    pyulog = pytest.importorskip("pyulog")
    streams, field_types = _ulog_input()
    path = write_ulog(
        tmp_path / "log.ulg",
        streams,
        {"MC_ROLL_P": 6.5, "SYS_AUTOSTART": 4001},
        field_types=field_types,
        dropouts=[(1.6, 0.0307)],
        info={"sys_name": "PX4"},
    )
    back, constants = ulog_streams(path)
    assert constants == {"MC_ROLL_P": 6.5, "SYS_AUTOSTART": 4001.0}
    by_name = {s.name: s for s in back}
    assert set(by_name) == {s.name for s in streams}
    for stream in streams:
        got = by_name[stream.name]
        assert np.array_equal(got.time_s, stream.time_s)
        assert list(got.fields) == list(stream.fields)
        for name, values in stream.fields.items():
            kind = field_types.get(stream.name, {}).get(name, "float")
            # stored as float32 unless the stream says otherwise
            expected = np.asarray(values, float)
            if kind == "float":
                expected = expected.astype(np.float32).astype(float)
            assert np.array_equal(got.fields[name], expected), (stream.name, name)

    log = pyulog.ULog(str(path))
    topics = {(d.name, d.multi_id) for d in log.data_list}
    assert topics == {
        ("vehicle_angular_velocity", 0),
        ("vehicle_status", 0),
        ("sensor_gyro", 0),
        ("sensor_gyro", 1),
        ("estimator", 0),
    }
    status = log.get_dataset("vehicle_status")
    assert status.data["nav_state"].dtype == np.uint8
    assert "xyz[2]" in log.get_dataset("vehicle_angular_velocity").data  # one float[3] field
    # a dropout message holds its duration (ms) only: it is read at the stamp before it
    (dropout,) = log.dropouts
    assert dropout.duration == 31 and 1_594_400 <= dropout.timestamp <= 1_600_000
    assert log.msg_info_dict["sys_name"] == "PX4"
    # file header (ULog specification): "ULog" 0x01 0x12 0x35, version byte, start µs
    head = path.read_bytes()[:16]
    assert head[:7] == b"ULog\x01\x12\x35" and head[7] == 1
    assert struct.unpack("<Q", head[8:])[0] == round(streams[0].time_s[0] * 1e6)


def test_ulog_writer_refuses_what_it_cannot_store(tmp_path):
    pytest.importorskip("pyulog")
    t = np.array([0.0, 0.01, 0.02])
    bad = [
        ([Stream("a", t, {"x": [1.0, 2.5, 3.0]})], {"a": {"x": "uint8_t"}}, "integers"),
        ([Stream("a", t, {"x": [1.0, 300.0, 3.0]})], {"a": {"x": "uint8_t"}}, "sample 1"),
        ([Stream("a", t[::-1], {"x": t})], {}, "increase"),
        ([Stream("a", t + 1e-7 * np.arange(3) - 0.0, {"x": t})], {}, None),  # fine
        ([Stream("a", np.array([0.0, 0.0000004]), {"x": [1.0, 2]})], {}, "1 µs"),
        ([Stream("a", t, {"x": t[:2]})], {}, "one value per time stamp"),
        ([Stream("a b", t, {"x": t})], {}, "topic name"),
        ([Stream("a", t, {"timestamp": t})], {}, "not a ULog field name"),
        ([Stream("a", t, {"x": t})], {"a": {"x": "float16"}}, "unknown"),
        ([Stream("a", t, {"x": t}), Stream("a:1", t, {"y": t})], {}, "same fields"),
    ]
    for streams, types_, message in bad:
        if message is None:
            write_ulog(tmp_path / "ok.ulg", streams, field_types=types_)
            continue
        with pytest.raises(LogWriteError, match=message):
            write_ulog(tmp_path / "x.ulg", streams, field_types=types_)
    with pytest.raises(InputTypeError, match="int .*or a float"):
        write_ulog(tmp_path / "x.ulg", [Stream("a", t, {"x": t})], {"P": "1"})
    with pytest.raises(InputTypeError, match="Stream"):
        write_ulog(tmp_path / "x.ulg", [("a", t, {"x": t})])


def _dataflash_input() -> list[Stream]:
    t = (2_000_000 + np.cumsum(RNG.integers(2200, 2801, size=40))) * 1e-6
    imu = {"GyrX": RNG.normal(size=40), "AccZ": -9.81 + RNG.normal(size=40)}
    imu_units = {"GyrX": "rad/s", "AccZ": "m/s/s"}
    t_att = t[::4]
    return [
        Stream("IMU[0]", t, imu, imu_units),
        Stream("IMU[1]", t, {k: v + 1 for k, v in imu.items()}, imu_units),
        Stream(
            "ATT",
            t_att,
            {"Roll": np.round(RNG.normal(size=10) * 20, 2), "Yaw": np.round(t_att * 10, 2)},
            {"Roll": "deg", "Yaw": "degheading"},
        ),
        Stream("RCOU", t_att, {"C1": 1500.0 + np.arange(10)}, {"C1": "us"}),
        Stream("MODE", t[:2], {"Mode": [5.0, 0.0], "ModeNum": [5.0, 0.0], "Rsn": [1.0, 1]}),
        Stream("XKF", t[:3], {"Odd": [1.0, 2, 3]}, {"Odd": "furlong/fortnight"}),
    ]


DF_FORMATS = {
    "ATT": {"Roll": "c", "Yaw": "C"},
    "RCOU": {"C1": "H"},
    "MODE": {"Mode": "M", "ModeNum": "B", "Rsn": "B"},
}


def test_dataflash_round_trip_units_and_dfreader_reads_every_message(tmp_path):
    dfreader = pytest.importorskip("pymavlink.DFReader")
    streams = _dataflash_input()
    path = write_dataflash(
        tmp_path / "log.bin", streams, formats=DF_FORMATS, parameters={"SERVO1_TRIM": 1500}
    )
    back = {s.name: s for s in dataflash_streams(path)}
    assert set(back) == {s.name for s in streams} | {"PARM"}
    for stream in streams:
        got = back[stream.name]
        assert np.array_equal(got.time_s, stream.time_s)
        assert list(got.fields) == list(stream.fields)
        for name, values in stream.fields.items():
            expected = np.asarray(values, float)
            if DF_FORMATS.get(stream.name, {}).get(name, "f") == "f":
                expected = expected.astype(np.float32).astype(float)
            # scaled types ('c' = int16 × 0.01) return the multiples written
            assert np.allclose(got.fields[name], expected, rtol=0, atol=1e-9), (stream, name)
        # units through FMTU/UNIT: ArduPilot's ids where the label is theirs, else a new id
        assert got.units == {f: stream.units.get(f, "") for f in stream.fields}
    assert back["PARM"].fields["Value"].tolist() == [1500.0]

    # pymavlink's reader: every message, in time order; FMT/UNIT/MULT/FMTU first
    log = dfreader.DFReader_binary(str(path), zero_time_base=True)
    names = []
    while (message := log.recv_msg()) is not None:
        names.append(message.get_type())
    data_count = sum(s.time_s.size for s in streams)
    assert len([n for n in names if n not in ("FMT", "UNIT", "MULT", "FMTU", "PARM")]) == (
        data_count
    )
    assert names.count("FMTU") == 5  # one per data type (IMU instances share theirs)
    # message layout (ArduPilot LogStructure.h): 0xA3 0x95, type 128 = FMT, length 89
    raw = path.read_bytes()
    assert raw[:3] == b"\xa3\x95\x80" and raw[4] == 89


def test_dataflash_writer_refuses_what_it_cannot_store(tmp_path):
    pytest.importorskip("pymavlink")
    t = np.array([0.0, 0.02, 0.04])
    bad = [
        (Stream("ATT", t, {"Roll": [0.0, 0.005, 1.0]}), {"ATT": {"Roll": "c"}}, "multiples"),
        (Stream("RCOU", t, {"C1": [1500.0, -1.0, 1.0]}), {"RCOU": {"C1": "H"}}, "sample 1"),
        (Stream("TOOLONG", t, {"A": t}), {}, "1–4 capital"),
        (Stream("ATT", t, {"TimeUS": t}), {}, "not a DataFlash column name"),
        (Stream("ATT", t, {"A": t}), {"ATT": {"A": "Z"}}, "not numeric"),
        (Stream("ATT", t, {f"F{i}": t for i in range(16)}), {}, "at most 16 fields"),
        (Stream("ATT", t[::-1], {"A": t}), {}, "increase"),
        (Stream("MODE", t, {"Mode": [1.0, 2, 3], "ModeNum": [1.0, 2, 4]}), {}, "ModeNum"),
    ]
    for stream, formats, message in bad:
        with pytest.raises(LogWriteError, match=message):
            write_dataflash(tmp_path / "x.bin", [stream], formats=formats)
    with pytest.raises(LogWriteError, match="same fields"):
        write_dataflash(
            tmp_path / "x.bin",
            [Stream("IMU[0]", t, {"A": t}), Stream("IMU[1]", t, {"B": t})],
        )
    assert not (tmp_path / "x.bin").exists()  # nothing written when refused


# ---------------------------------------------------------------- the example logs


@pytest.fixture(scope="module")
def example_logs(tmp_path_factory):
    pytest.importorskip("pyulog")
    pytest.importorskip("pymavlink")
    from flightid.examples.logs import write_example_logs

    return write_example_logs(tmp_path_factory.mktemp("example_logs"))


def test_examples_are_deterministic_and_small(example_logs, tmp_path):
    from flightid.examples.logs import write_fixedwing_dataflash, write_multirotor_ulog

    multirotor, fixedwing = example_logs["multirotor"], example_logs["fixedwing"]
    again = write_multirotor_ulog(tmp_path / "a.ulg")
    assert again.path.read_bytes() == multirotor.path.read_bytes()
    assert write_fixedwing_dataflash(tmp_path / "a.bin").path.read_bytes() == (
        fixedwing.path.read_bytes()
    )
    other = write_multirotor_ulog(tmp_path / "b.ulg", seed=43)
    assert other.path.read_bytes() != multirotor.path.read_bytes()
    assert other.dropouts != multirotor.dropouts
    for log in (multirotor, fixedwing):
        assert 100_000 < log.path.stat().st_size < 1_000_000
    assert multirotor.parameters == {"omega_n": 42.0, "zeta": 0.6, "tau": 0.025}
    assert fixedwing.parameters == {"Lp": -4.0, "Lda": 30.0}
    assert [m for m, _, _ in multirotor.modes] == ["POSCTL", "ACRO", "POSCTL"]
    assert [m for m, _, _ in fixedwing.modes] == ["FBWA", "MANUAL", "FBWA"]


def _gaps(time_s: np.ndarray, longer_than_s: float) -> np.ndarray:
    steps = np.diff(time_s)
    return time_s[:-1][steps > longer_than_s]


def test_multirotor_log_streams_jitter_dropouts_and_modes(example_logs):
    log = example_logs["multirotor"]
    streams, constants = ulog_streams(log.path)
    by_name = {s.name: s for s in streams}
    assert set(by_name) == {
        "vehicle_angular_velocity",
        "vehicle_rates_setpoint",
        "vehicle_attitude",
        "vehicle_status",
    }
    assert constants["MC_ROLL_P"] == 6.5
    gyro = by_name["vehicle_angular_velocity"].time_s
    steps = np.diff(gyro)
    # jitter 4.0–5.6 ms outside the drop-outs; each drop-out a gap of 28–40 ms
    normal = steps[steps < 0.02]
    assert normal.min() >= 0.004 - 1e-9 and normal.max() <= 0.0056 + 1e-9
    assert np.std(normal) > 3e-4  # jittering, not uniform
    gaps = _gaps(gyro, 0.02)
    assert len(gaps) == len(log.dropouts) == 3
    for (start, duration), gap_at in zip(log.dropouts, gaps, strict=True):
        assert gap_at < start < gap_at + 0.0056 and 0.028 <= duration <= 0.034
    assert 200 < log.rates_hz["vehicle_angular_velocity"] < 215
    assert 100 < log.rates_hz["vehicle_attitude"] < 108
    # nav_state: POSCTL (2) → ACRO (10) → POSCTL at the truth's mode times
    status = by_name["vehicle_status"]
    nav = status.fields["nav_state"]
    changes = status.time_s[1:][np.diff(nav) != 0]
    assert nav[0] == 2 and set(nav) == {2.0, 10.0}
    assert np.allclose(changes, [log.modes[1][1], log.modes[2][1]])
    # the attitude quaternion is a unit quaternion
    q = np.column_stack([by_name["vehicle_attitude"].fields[f"q_{i}"] for i in range(4)])
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-6)


def test_fixedwing_log_streams_units_and_modes(example_logs):
    log = example_logs["fixedwing"]
    by_name = {s.name: s for s in dataflash_streams(log.path)}
    assert {"IMU[0]", "ATT", "RCOU", "MODE", "PARM"} <= set(by_name)
    assert by_name["IMU[0]"].units["GyrX"] == "rad/s"
    assert by_name["ATT"].units["Roll"] == "deg" and by_name["RCOU"].units["C1"] == "us"
    imu = by_name["IMU[0]"].time_s
    assert len(_gaps(imu, 0.02)) == 3 and 395 < log.rates_hz["IMU[0]"] < 405
    c1 = by_name["RCOU"].fields["C1"]
    assert np.array_equal(c1, np.round(c1)) and 1000 <= c1.min() and c1.max() <= 2000
    roll = by_name["ATT"].fields["Roll"]
    assert np.allclose(roll * 100, np.round(roll * 100), atol=1e-6)  # centidegrees
    mode = by_name["MODE"]
    assert mode.fields["ModeNum"].tolist() == [5.0, 0.0, 5.0]  # FBWA, MANUAL, FBWA
    assert by_name["VER"].fields["BU"].tolist() == [3.0]  # ArduPlane: names the modes
    assert np.allclose(mode.time_s[1:], [log.modes[1][1], log.modes[2][1]])


def _away_from_dropouts(time_s, dropouts, margin_s=0.3):
    keep = np.ones(time_s.size, dtype=bool)
    for start, duration in dropouts:
        keep &= ~((time_s > start - margin_s) & (time_s < start + duration + margin_s))
    return keep


def test_examples_match_an_independent_simulation_of_their_truth(example_logs):
    """The logged outputs minus scipy.signal.lsim of the stated transfer function, fed the
    logged command (linear between its samples, as the truth is defined), leave only the
    stated noise: RMS within 10 % of the noise σ."""
    signal = pytest.importorskip("scipy.signal")
    log = example_logs["multirotor"]
    wn, zeta, tau = (log.parameters[k] for k in ("omega_n", "zeta", "tau"))
    gyro, setpoint = ulog_streams(log.path, "vehicle_angular_velocity,vehicle_rates_setpoint")[0]
    t = np.arange(setpoint.time_s[0], setpoint.time_s[-1], 5e-4)
    u = np.interp(t - tau, setpoint.time_s, setpoint.fields["roll"])
    # p/p_cmd = ω_n² / (s² + 2ζω_n s + ω_n²), the input delayed by τ
    _, p, _ = signal.lsim(([wn**2], [1.0, 2 * zeta * wn, wn**2]), u, t - t[0])
    keep = _away_from_dropouts(gyro.time_s, log.dropouts) & (gyro.time_s > t[0] + 1.0)
    residual = gyro.fields["xyz_0"][keep] - np.interp(gyro.time_s[keep], t, p)
    assert abs(np.std(residual) / log.noise_std["p"] - 1) < 0.1
    assert abs(np.mean(residual)) < 5 * log.noise_std["p"] / math.sqrt(residual.size)

    log = example_logs["fixedwing"]
    imu, rcou = dataflash_streams(log.path, "IMU[0],RCOU")
    t = np.arange(rcou.time_s[0], rcou.time_s[-1], 5e-4)
    # δa = (C1 − 1500 µs) · 0.05 deg/µs
    da = np.interp(t, rcou.time_s, (rcou.fields["C1"] - 1500) * 0.05 * math.pi / 180)
    # p/δa = L_δa / (s − L_p)
    _, p, _ = signal.lsim(([log.parameters["Lda"]], [1.0, -log.parameters["Lp"]]), da, t - t[0])
    keep = _away_from_dropouts(imu.time_s, log.dropouts) & (imu.time_s > t[0] + 2.0)
    residual = imu.fields["GyrX"][keep] - np.interp(imu.time_s[keep], t, p)
    assert abs(np.std(residual) / log.noise_std["p"] - 1) < 0.1


# ---------------------------------------------------------------- the example cases


def _segments(lo, hi, dropouts, margin_s=0.02):
    """[lo, hi] cut at the drop-outs: the pieces with uniformly resampled data."""
    edges = [lo]
    for start, duration in dropouts:
        if lo < start < hi:
            edges += [start - margin_s, start + duration + margin_s]
    edges.append(hi)
    return list(zip(edges[::2], edges[1::2], strict=True))


def _resampled_case(tmp_path, case_name, columns, hz, log) -> Path:
    """The shipped case with its [data] replaced by CSV segments, resampled here by linear
    interpolation at ``hz`` between the drop-outs, over the case's flight-mode interval as
    the log's writer states it (``ExampleLog.modes``)."""
    case_text = (EXAMPLES / case_name).read_text()
    (maneuver,) = tomllib.loads(case_text)["data"]["maneuvers"]
    (lo, hi) = [(a, b) for m, a, b in log.modes if m.lower() == maneuver["mode"].lower()][0]
    files = []
    for k, (a, b) in enumerate(_segments(lo, hi, log.dropouts)):
        t = np.arange(math.ceil(a * hz), math.floor(b * hz) + 1) / hz
        table = [t] + [np.interp(t, ts, values) for ts, values in columns.values()]
        name = f"segment_{k}.csv"
        np.savetxt(
            tmp_path / name,
            np.column_stack(table),
            delimiter=",",
            header="t," + ",".join(columns),
            comments="",
        )
        files.append(name)
    for module in EXAMPLES.glob("*.py"):
        shutil.copy(module, tmp_path / module.name)
    rest = case_text[case_text.index("[data.inputs]") :]
    head = f'title = "{case_name}, resampled segments"\n[data]\ndata_dir = "."\n'
    head += f'files = {files}\ntime = "t"\n'
    path = tmp_path / case_name
    path.write_text(head + rest)
    return path


def _assert_recovered(run, truth: dict[str, float], names: dict[str, str]):
    estimate = run.estimate
    assert estimate.status == "converged"
    for truth_name, name in names.items():
        value, sigma = estimate.value(name), estimate.stddev(name)
        assert abs(value - truth[truth_name]) < 3 * sigma, (name, value, sigma)
        assert sigma < 0.01 * abs(truth[truth_name])


def test_fixedwing_case_recovers_the_truth_from_resampled_segments(example_logs, tmp_path):
    from flightid.cases import run_case

    log = example_logs["fixedwing"]
    imu, att, rcou = dataflash_streams(log.path, "IMU[0],ATT,RCOU")
    columns = {
        "IMU_0.GyrX": (imu.time_s, imu.fields["GyrX"]),
        "ATT.Roll": (att.time_s, att.fields["Roll"]),
        "RCOU.C1": (rcou.time_s, rcou.fields["C1"]),
    }
    case = _resampled_case(tmp_path, "fixedwing_roll.toml", columns, 100, log)
    run = run_case(case)
    assert len(run.maneuvers) == 4  # MANUAL, cut at the three drop-outs inside it
    _assert_recovered(run, log.parameters, {"Lp": "Lp", "Lda": "Lda"})


def test_multirotor_case_recovers_the_truth_from_resampled_segments(example_logs, tmp_path):
    from flightid.cases import run_case

    log = example_logs["multirotor"]
    gyro, setpoint = ulog_streams(log.path, "vehicle_angular_velocity,vehicle_rates_setpoint")[0]
    columns = {
        "vehicle_angular_velocity.xyz_0": (gyro.time_s, gyro.fields["xyz_0"]),
        "vehicle_rates_setpoint.roll": (setpoint.time_s, setpoint.fields["roll"]),
    }
    case = _resampled_case(tmp_path, "multirotor_roll_rate.toml", columns, 200, log)
    run = run_case(case)
    assert len(run.maneuvers) == 2
    _assert_recovered(run, log.parameters, {"omega_n": "wn", "zeta": "zeta", "tau": "tau"})


@pytest.mark.parametrize("case_name", ["multirotor_roll_rate.toml", "fixedwing_roll.toml"])
def test_shipped_case_files_run_on_the_logs(example_logs, tmp_path, case_name):
    """The shipped case files as they are, with the logs beside them: they declare
    ``resample_hz``; where the case reader does not know that key yet, skip (naming it)."""
    from flightid.cases import CaseError, load_case, run_case

    for item in [*EXAMPLES.glob("*.py"), *EXAMPLES.glob("*.toml")]:
        shutil.copy(item, tmp_path / item.name)
    for log in example_logs.values():
        shutil.copy(log.path, tmp_path / log.path.name)
    try:
        load_case(tmp_path / case_name)
    except CaseError as exc:
        if "resample_hz: unknown key" in str(exc):
            pytest.skip("[data] resample_hz is not known to the case reader yet")
        raise
    log = example_logs["multirotor" if case_name.startswith("multi") else "fixedwing"]
    names = (
        {"omega_n": "wn", "zeta": "zeta", "tau": "tau"}
        if case_name.startswith("multi")
        else {"Lp": "Lp", "Lda": "Lda"}
    )
    _assert_recovered(run_case(tmp_path / case_name), log.parameters, names)


# ---------------------------------------------------------------- flightid example-logs


def test_cli_example_logs_writes_refuses_and_overwrites_only_its_files(tmp_path, capsys):
    pytest.importorskip("pyulog")
    pytest.importorskip("pymavlink")
    from flightid.cli.main import main

    folder = tmp_path / "logs"
    assert main(["example-logs", "--out", str(folder)]) == 0
    out = capsys.readouterr().out
    assert "omega_n = 42" in out and "Lp = -4" in out and "drop-outs" in out
    assert sorted(p.name for p in folder.iterdir()) == [
        "fixedwing_roll.bin",
        "multirotor_roll_rate.ulg",
    ]
    first = (folder / "multirotor_roll_rate.ulg").read_bytes()
    (folder / "notes.txt").write_text("mine")
    assert main(["example-logs", "--out", str(folder)]) == 1
    assert "already exist" in capsys.readouterr().err
    # --overwrite replaces the two logs (same bytes) and nothing else
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    (folder / "fixedwing_roll.bin").unlink()
    (folder / "fixedwing_roll.bin").symlink_to(victim)
    assert main(["example-logs", "--out", str(folder), "--overwrite"]) == 0
    assert (folder / "multirotor_roll_rate.ulg").read_bytes() == first
    assert (folder / "notes.txt").read_text() == "mine" and victim.read_text() == "keep"
    assert not (folder / "fixedwing_roll.bin").is_symlink()
    assert main(["example-logs", "--out", ""]) == 1
    assert "empty" in capsys.readouterr().err


def test_writers_replace_a_file_only_with_overwrite_and_never_through_a_link(tmp_path):
    pytest.importorskip("pyulog")
    pytest.importorskip("pymavlink")
    t = np.array([0.0, 0.01, 0.02])
    stream = Stream("ATT", t, {"A": t}, {"A": "deg"})
    for write, name in ((write_ulog, "log.ulg"), (write_dataflash, "log.bin")):
        path = tmp_path / name
        path.write_text("the user's file")
        with pytest.raises(LogWriteError, match="already exists"):
            write(path, [stream])
        assert path.read_text() == "the user's file"
        write(path, [stream], overwrite=True)
        assert path.read_bytes()[:2] in (b"UL", b"\xa3\x95")
        victim = tmp_path / f"victim_{name}"
        victim.write_text("keep")
        path.unlink()
        path.symlink_to(victim)
        with pytest.raises(LogWriteError, match="already exists"):
            write(path, [stream])
        write(path, [stream], overwrite=True)
        assert victim.read_text() == "keep" and not path.is_symlink()
