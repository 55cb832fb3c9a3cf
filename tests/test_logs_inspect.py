"""Finding the maneuvers in a log: stream timing, flight modes and SysID runs, excitation
segments, built-in signals (quaternion → Euler), selection by mode, `flightid inspect`."""

from __future__ import annotations

import math
import tomllib
from types import SimpleNamespace

import numpy as np
import pytest

from flightid.cli.main import main
from flightid.data.formats import Stream
from flightid.data.loaders import ChannelError, _finish_table, to_flight_data
from flightid.data.signals import quaternion_to_euler
from flightid.logs.caselines import case_lines
from flightid.logs.excitation import detect_excitation
from flightid.logs.modes import (
    ModeInterval,
    ModeSelectionError,
    mode_intervals,
    select_mode,
    sysid_runs,
)
from flightid.logs.streams import summarize_stream
from log_writers import jittered_stamps_us, write_dataflash, write_ulog

RNG = np.random.default_rng(20240611)


# ---------------------------------------------------------------- synthetic inputs


def _square(t, t0, pattern, pulse_s, amplitude):
    """Pulses (multiple of pulse_s, sign) from t0: doublet [(1, 1), (1, -1)], 3-2-1-1 ..."""
    out = np.zeros_like(t)
    edge = t0
    for multiple, sign in pattern:
        on = (t >= edge) & (t < edge + multiple * pulse_s)
        out[on] = sign * amplitude
        edge += multiple * pulse_s
    return out


def _chirp(t, t0, duration, f0, f1, amplitude):
    tau = t - t0
    on = (tau >= 0) & (tau < duration)
    # linear sweep: phase = 2π (f0 τ + (f1 − f0) τ² / (2T))
    phase = 2 * np.pi * (f0 * tau + (f1 - f0) * tau**2 / (2 * duration))
    return np.where(on, amplitude * np.sin(phase), 0.0)


def _multisine(t, t0, duration, freqs, amplitude):
    tau = t - t0
    on = (tau >= 0) & (tau < duration)
    phases = RNG.uniform(0, 2 * np.pi, len(freqs))
    total = sum(np.sin(2 * np.pi * f * tau + p) for f, p in zip(freqs, phases, strict=True))
    return np.where(on, amplitude * total, 0.0)


def _test_input(t):
    """Trim 0.1 plus a doublet at 5 s, a 3-2-1-1 at 15 s, a released step at 30 s, a
    0.3 → 6 Hz sweep at 45 s and a 0.5 .. 3.1 Hz multisine at 75 s; noise σ = 0.005."""
    x = 0.1 + _square(t, 5.0, [(1, 1), (1, -1)], 0.8, 0.3)
    x += _square(t, 15.0, [(3, 1), (2, -1), (1, 1), (1, -1)], 0.6, 0.2)
    x += _square(t, 30.0, [(1, 1)], 4.0, 0.25)
    x += _chirp(t, 45.0, 20.0, 0.3, 6.0, 0.2)
    x += _multisine(t, 75.0, 15.0, (0.5, 1.1, 1.7, 2.3, 3.1), 0.08)
    return x + RNG.normal(0.0, 0.005, t.size)


def test_detect_kinds_spans_and_bands_on_uneven_stamps():
    t = np.arange(0.0, 100.0, 0.01)
    x = _test_input(t)
    stamps = t + RNG.uniform(-0.002, 0.002, t.size)  # jittered, as logs store them
    found = detect_excitation(stamps, x, "u", "rad")
    expected = [
        ("doublet", 5.0, 6.6),
        ("3-2-1-1", 15.0, 19.2),
        ("step", 30.0, 34.0),
        ("sweep", 45.0, 65.0),
        ("multisine", 75.0, 90.0),
    ]
    assert [s.kind for s in found] == [k for k, _, _ in expected]
    for segment, (kind, start, stop) in zip(found, expected, strict=True):
        # a sweep from phase 0 at 0.3 Hz reaches 10 % of its peak after
        # asin(0.1) / (2π · 0.3 Hz) = 0.053 s: the start is where the input is 10 % out
        assert segment.start_s == pytest.approx(start, abs=0.1 if kind == "sweep" else 0.03)
        assert segment.stop_s == pytest.approx(stop, abs=0.03)
        assert segment.channel == "u" and segment.unit == "rad"
        assert segment.level == pytest.approx(0.1, abs=0.003)
    doublet, _, step, sweep, multisine = found
    # the sweep's band is the 0.3 .. 6 Hz it was made with (within 25 % at the low end,
    # where the first zero crossings are half a period of a fast-changing frequency apart)
    assert sweep.band_hz[0] == pytest.approx(0.3, rel=0.25)
    assert sweep.band_hz[1] == pytest.approx(6.0, rel=0.15)
    # the multisine's energy lies between its lowest and highest component
    assert 0.4 <= multisine.band_hz[0] <= 0.6 and 2.9 <= multisine.band_hz[1] <= 3.3
    assert doublet.amplitude == pytest.approx(0.3, abs=0.02)
    assert step.amplitude == pytest.approx(0.25, abs=0.02)
    # ratio = 20 log10(RMS / σ): a ±0.3 doublet over σ = 0.005 is 20 log10(60) = 35.6 dB;
    # the quiet level comes from interpolated, jittered samples: within 3 dB
    assert doublet.ratio_db == pytest.approx(20 * math.log10(0.3 / 0.005), abs=3.0)


def test_quiet_and_constant_channels_have_no_segment():
    t = np.arange(0.0, 60.0, 0.005)
    assert detect_excitation(t, 3.0 + RNG.normal(0.0, 0.01, t.size)) == []
    assert detect_excitation(t, np.full(t.size, 2.0)) == []
    assert detect_excitation(t[:5], np.arange(5.0)) == []


def test_step_held_to_the_end_stops_max_hold_after_its_edge():
    t = np.arange(0.0, 40.0, 0.01)
    x = np.where(t >= 20.0, 0.5, 0.0) + RNG.normal(0.0, 0.004, t.size)
    (step,) = detect_excitation(t, x, max_hold_s=5.0)
    assert step.kind == "step"
    assert step.start_s == pytest.approx(20.0, abs=0.02)
    assert step.stop_s == pytest.approx(25.0, abs=0.3)


def test_single_smooth_pulse_is_a_pulse_not_a_multisine():
    """A controller's return to level at a mode change: the rate command jumps to −1.8 and
    decays back to the hold level (time constant 0.08 s) — one excursion of one sign, not a
    multi-frequency input; a doublet and a multisine in the same record keep their kinds."""
    t = np.arange(0.0, 30.0, 0.005)
    tau = t - 20.0
    # return to level: x = −1.8 e^(−τ/0.08) for τ ≥ 0
    x = np.where(tau >= 0, -1.8 * np.exp(-np.clip(tau, 0, None) / 0.08), 0.0)
    x += _square(t, 5.0, [(1, 1), (1, -1)], 0.1, 1.2)
    x += _multisine(t, 10.0, 6.0, (0.7, 1.3, 2.1, 2.9), 0.3)
    # a smooth one-signed bump: half a sine period of 0.6 s
    bump = (t >= 25.0) & (t < 25.6)
    x[bump] += 0.9 * np.sin(np.pi * (t[bump] - 25.0) / 0.6)
    x += RNG.normal(0.0, 0.008, t.size)
    found = detect_excitation(t, x, "vehicle_rates_setpoint.roll", "rad/s")
    assert [s.kind for s in found] == ["doublet", "multisine", "pulse", "pulse"]
    pulse = found[2]
    assert pulse.start_s == pytest.approx(20.0, abs=0.01)
    assert pulse.amplitude == pytest.approx(1.8, abs=0.05)
    assert found[3].start_s == pytest.approx(25.0, abs=0.1)


# ---------------------------------------------------------------- streams and modes


def test_stream_summary_rate_jitter_and_dropout():
    t = np.r_[np.arange(0, 200) * 0.005, 0.995 + 0.0336 + np.arange(0, 100) * 0.005]
    summary = summarize_stream(Stream("gyro", t, {"x": np.zeros(t.size)}, {"x": "rad/s"}))
    assert summary.samples == 300
    assert summary.rate_hz == pytest.approx(200.0)
    assert summary.max_interval_s == pytest.approx(0.0336)
    assert summary.dropouts == 1
    assert summary.jitter_s < 1e-9
    assert summary.fields == {"x": "rad/s"}


def test_px4_modes_and_selection():
    t = np.arange(0.0, 40.0, 0.5)
    # Position (2) until 10 s, Stabilized (15) until 20 s, Position, Stabilized from 30 s
    nav = np.select([t < 10, t < 20, t < 30], [2, 15, 2], 15).astype(float)
    status = Stream("vehicle_status", t, {"nav_state": nav})
    modes = mode_intervals([status], end_s=41.0)
    assert [(m.name, m.start_s, m.stop_s) for m in modes] == [
        ("Position", 0.0, 10.0),
        ("Stabilized", 10.0, 20.0),
        ("Position", 20.0, 30.0),
        ("Stabilized", 30.0, 41.0),
    ]
    # the PX4 constant's name selects it too, without regard to case
    assert select_mode(modes, "stab", 2).start_s == 30.0
    with pytest.raises(ModeSelectionError, match=r"occurs 2 times.*mode_index"):
        select_mode(modes, "Stabilized")
    with pytest.raises(ModeSelectionError, match=r"never records mode 'Acro'.*Position"):
        select_mode(modes, "Acro")
    with pytest.raises(ModeSelectionError, match=r"mode_index: expected 1..2"):
        select_mode(modes, "Stabilized", 3)
    with pytest.raises(ModeSelectionError, match="records no flight modes"):
        select_mode([], "Stabilized")


def test_ardupilot_modes_sysid_runs_and_alias():
    mode = Stream("MODE", np.array([1.0, 12.0, 30.0]), {"ModeNum": np.array([0.0, 25.0, 5.0])})
    version = Stream("VER", np.array([0.5]), {"BU": np.array([2.0])})  # 2: Copter
    sidd_t = np.r_[np.arange(13.0, 23.0, 0.0025), np.arange(25.0, 28.0, 0.0025)]
    sidd = Stream("SIDD", sidd_t, {"Targ": np.zeros(sidd_t.size)})
    sids = Stream(
        "SIDS",
        np.array([12.5, 24.5]),
        {"Ax": np.array([7.0, 8.0]), "Mag": np.array([15.0, 10.0]),
         "FSt": np.array([0.5, 1.0]), "FSp": np.array([20.0, 30.0])},
    )  # fmt: skip
    modes = mode_intervals([mode, version, sidd, sids])
    assert [m.name for m in modes] == ["STABILIZE", "SYSTEMID", "LOITER"]
    assert math.isinf(modes[-1].stop_s)
    assert select_mode(modes, "SYSID") == modes[1]
    assert (modes[1].start_s, modes[1].stop_s) == (12.0, 30.0)
    runs = sysid_runs([mode, sidd, sids])
    assert [(r.start_s, round(r.stop_s, 4)) for r in runs] == [(13.0, 22.9975), (25.0, 27.9975)]
    assert runs[0].axis == "rate roll" and runs[0].band_hz == (0.5, 20.0)
    assert runs[1].axis == "rate pitch" and runs[1].settings["Mag"] == 10.0
    # without VER the numbers are named only when the vehicle is given
    assert mode_intervals([mode])[1].name == "mode 25"
    assert mode_intervals([mode], vehicle="plane")[2].name == "FBWA"  # Plane mode 5


# ---------------------------------------------------------------- quaternion → Euler


def test_quaternion_to_euler_matches_scipy_zyx():
    rotation = pytest.importorskip("scipy.spatial.transform").Rotation
    rotations = rotation.random(400, random_state=7)
    x, y, z, w = rotations.as_quat().T  # scipy: scalar last
    yaw, pitch, roll = rotations.as_euler("ZYX").T  # intrinsic z-y'-x''
    keep = np.abs(pitch) < np.radians(89.0)  # away from gimbal lock
    for sign in (1.0, -1.0):  # q and −q are the same attitude
        phi, theta, psi = quaternion_to_euler(sign * w, sign * x, sign * y, sign * z)
        assert np.allclose(phi[keep], roll[keep], atol=1e-9)
        assert np.allclose(theta[keep], pitch[keep], atol=1e-9)
        assert np.allclose(psi[keep], yaw[keep], atol=1e-9)
    # a quaternion of norm ≠ 1 (stored rounding) gives the same angles
    phi2, _, _ = quaternion_to_euler(1.01 * w, 1.01 * x, 1.01 * y, 1.01 * z)
    assert np.allclose(phi2[keep], roll[keep], atol=1e-9)


def test_builtin_signals_in_channels_and_expressions():
    rotation = pytest.importorskip("scipy.spatial.transform").Rotation
    n = 50
    angles = np.column_stack([np.linspace(-1, 1, n), np.linspace(0.5, -0.5, n), np.zeros(n)])
    rotations = rotation.from_euler("ZYX", angles[:, ::-1])  # (yaw, pitch, roll)
    x, y, z, w = rotations.as_quat().T
    t = np.arange(n) * 0.01
    names = ["t", *(f"vehicle_attitude.q_{k}" for k in range(4)), "vehicle_angular_velocity.xyz_0"]
    table = _finish_table(np.column_stack([t, w, x, y, z, 2 * t]), names, None, "log.ulg")
    data = to_flight_data(
        table,
        time="t",
        inputs={"p": "px4.p"},
        outputs={
            "phi": "px4.roll",
            "theta": {"column": "px4.pitch", "unit": "rad", "to": "deg"},
            "phi_expr": "quat_roll(vehicle_attitude.q_0, vehicle_attitude.q_1, "
            "vehicle_attitude.q_2, vehicle_attitude.q_3) * 2",
        },
    )
    assert np.allclose(data.output("phi"), angles[:, 0], atol=1e-9)
    assert np.allclose(data.output("theta"), np.degrees(angles[:, 1]), atol=1e-7)
    assert np.allclose(data.output("phi_expr"), 2 * angles[:, 0], atol=1e-9)
    assert np.allclose(data.input("p"), 2 * t)
    with pytest.raises(ChannelError, match=r"built-in signal 'px4.airspeed' needs.*airspeed"):
        to_flight_data(table, time="t", outputs={"V": "px4.airspeed"})


# ---------------------------------------------------------------- logs on disk


def _flight_ulog(path):
    """A 40 s PX4 log: vehicle_status (Position, Stabilized 10–30 s, Position), rate
    setpoints at ~200 Hz with jitter (a roll doublet at 12 s, a pitch sweep at 18–28 s),
    the attitude quaternion at 100 Hz."""
    stamps = jittered_stamps_us(RNG, 0.0, 40.0, 200.0, 0.0008)
    t = stamps * 1e-6
    roll = _square(t, 12.0, [(1, 1), (1, -1)], 0.7, 0.5) + RNG.normal(0, 0.005, t.size)
    pitch = _chirp(t, 18.0, 10.0, 0.5, 5.0, 0.4) + RNG.normal(0, 0.005, t.size)
    yaw = RNG.normal(0, 0.005, t.size)
    status_t = np.arange(0, 40_000_000, 500_000)
    nav = np.select([status_t < 10e6, status_t < 30e6], [2, 15], 2)
    att_t = np.arange(0, 40_000_000, 10_000)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (att_t.size, 1))
    topics = {
        "vehicle_status": ([("uint8_t", "nav_state")], status_t, nav[:, None]),
        "vehicle_rates_setpoint": (
            [("float", "roll"), ("float", "pitch"), ("float", "yaw")],
            stamps,
            np.column_stack([roll, pitch, yaw]),
        ),
        "vehicle_attitude": ([("float[4]", "q")], att_t, q),
    }
    return write_ulog(path, topics, {"MC_ROLLRATE_P": 0.15})


def test_inspect_ulog_table_figure_and_case_lines(tmp_path, capsys):
    pytest.importorskip("pyulog")
    path = _flight_ulog(tmp_path / "flight.ulg")
    assert main(["inspect", str(path), "--out", str(tmp_path / "out")]) == 0
    text = capsys.readouterr().out
    assert "PX4 ULog" in text and "vehicle_rates_setpoint" in text
    row = next(line for line in text.splitlines() if "vehicle_attitude " in line)
    assert row.split()[1:3] == ["4000", "100.00"]  # samples, rate Hz
    assert "Stabilized" in text and "Position" in text
    segments = [line.split() for line in text.splitlines() if "vehicle_rates_setpoint." in line]
    kinds = {(s[0], s[1]) for s in segments}
    assert kinds == {
        ("vehicle_rates_setpoint.roll", "doublet"),
        ("vehicle_rates_setpoint.pitch", "sweep"),
    }
    out = tmp_path / "out"
    assert (out / "overview.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "inspect.txt").read_text() == text.split("wrote ")[0]
    assert tomllib.loads((out / "segments.toml").read_text())["data"]["maneuvers"]

    assert main(["inspect", str(path), "--case-lines", "--pad", "0.5"]) == 0
    case = tomllib.loads(capsys.readouterr().out)
    maneuvers = case["data"]["maneuvers"]
    assert [m["name"] for m in maneuvers] == ["doublet_1", "sweep_1"]
    doublet, sweep = maneuvers
    assert doublet["file"] == str(path)
    # the doublet runs 12.0 .. 13.4 s, the sweep 18 .. 28 s; each padded by 0.5 s
    assert doublet["start"] == pytest.approx(11.5, abs=0.02)
    assert doublet["stop"] == pytest.approx(13.9, abs=0.02)
    assert sweep["start"] == pytest.approx(17.5, abs=0.05)
    assert sweep["stop"] == pytest.approx(28.5, abs=0.05)

    # chosen channels, a built-in one among them; an unknown one is a named error
    assert main(["inspect", str(path), "--channels", "px4.roll,vehicle_rates_setpoint.yaw"]) == 0
    text = capsys.readouterr().out
    assert "none in px4.roll, vehicle_rates_setpoint.yaw" in text
    assert main(["inspect", str(path), "--channels", "vehicle_gps.lat"]) == 1
    assert "channel 'vehicle_gps.lat': not in" in capsys.readouterr().err


def test_inspect_dataflash_modes_and_sysid(tmp_path, capsys):
    pytest.importorskip("pymavlink")
    types = {
        "MODE": (20, "QMBB", "TimeUS,Mode,ModeNum,Rsn"),
        "VER": (21, "QB", "TimeUS,BU"),
        "SIDS": (22, "QBfff", "TimeUS,Ax,Mag,FSt,FSp"),
        "SIDD": (23, "Qff", "TimeUS,Time,Targ"),
        "RATE": (24, "Qff", "TimeUS,RDes,R"),
    }
    records = [(100_000, "VER", (2,)), (200_000, "MODE", (0, 0, 1))]
    records += [(5_000_000, "MODE", (25, 25, 2)), (5_100_000, "SIDS", (7, 20.0, 1.0, 8.0))]
    records += [(20_000_000, "MODE", (0, 0, 2))]
    rate_t = jittered_stamps_us(RNG, 0.5, 24.0, 400.0, 0.0002)
    chirp = _chirp(rate_t * 1e-6, 6.0, 12.0, 1.0, 8.0, 20.0)
    for stamp, target in zip(rate_t, chirp, strict=True):
        records.append((int(stamp), "RATE", (target + RNG.normal(0, 0.2), 0.0)))
        if 6.0 <= stamp * 1e-6 < 18.0:
            records.append((int(stamp) + 1, "SIDD", (stamp * 1e-6 - 6.0, target)))
    path = write_dataflash(tmp_path / "00000001.BIN", types, records, {"RATE": ("skk", "F--")})
    assert main(["inspect", str(path)]) == 0
    text = capsys.readouterr().out
    assert "ArduPilot DataFlash log" in text
    assert "SYSTEMID" in text and "STABILIZE" in text
    assert "6.000 .. 17.99" in text and "rate roll, magnitude 20, 1–8 Hz" in text
    sweeps = [line.split() for line in text.splitlines() if " sweep " in line]
    # SIDD holds samples only while the mode runs (no quiet level): listed as a run
    assert {s[0] for s in sweeps} == {"RATE.RDes"}
    rdes = next(s for s in sweeps if s[0] == "RATE.RDes")
    assert float(rdes[2]) == pytest.approx(6.0, abs=0.05)
    assert float(rdes[3]) == pytest.approx(18.0, abs=0.05)
    assert "deg/s" in text  # the unit from the log's FMTU


def test_inspect_csv_table(tmp_path, capsys):
    t = np.arange(0.0, 30.0, 0.02)
    elevator = _square(t, 10.0, [(3, 1), (2, -1), (1, 1), (1, -1)], 0.5, 2.0)
    elevator += RNG.normal(0, 0.02, t.size)
    path = tmp_path / "flight.csv"
    rows = "\n".join(f"{a:.3f},{b:.5f}" for a, b in zip(t, elevator, strict=True))
    path.write_text("time [s],de [deg]\n" + rows + "\n")
    assert main(["inspect", str(path)]) == 0
    text = capsys.readouterr().out
    line = next(line for line in text.splitlines() if "3-2-1-1" in line)
    assert line.split()[0] == "de" and "deg" in line
    assert float(line.split()[2]) == pytest.approx(10.0, abs=0.03)
    assert float(line.split()[3]) == pytest.approx(13.5, abs=0.03)


def test_case_lines_clip_to_the_log_and_refuse_a_negative_pad():
    segment = detect_excitation(
        np.arange(0, 10, 0.01), np.where(np.arange(0, 10, 0.01) >= 0.5, 1.0, 0.0)
    )
    text = case_lines(segment, "a.csv", (0.0, 9.99), pad_s=2.0)
    (maneuver,) = tomllib.loads(text)["data"]["maneuvers"]
    assert maneuver["start"] == 0.0 and maneuver["name"] == "step_1"
    with pytest.raises(ValueError, match="pad"):
        case_lines(segment, "a.csv", (0.0, 9.99), pad_s=-1.0)


# ---------------------------------------------------------------- maneuvers by mode


def test_case_maneuver_by_mode(tmp_path):
    pytest.importorskip("pyulog")
    from flightid.cases.build import load_maneuvers
    from flightid.cases.checks import CaseError
    from flightid.cases.spec import _maneuvers

    _flight_ulog(tmp_path / "flight.ulg")
    data = {
        # two streams at their own rates: resampled onto one 100 Hz grid
        "variable": "vehicle_attitude,vehicle_rates_setpoint",
        "resample_hz": 100.0,
        "time": "t",
        "inputs": {"p_cmd": "vehicle_rates_setpoint.roll"},
        "outputs": {"phi": "px4.roll"},
    }
    section = {**data, "maneuvers": [{"file": "flight.ulg", "mode": "Stabilized"}]}
    specs = _maneuvers(section, "data", section)
    assert specs[0].mode == "Stabilized" and specs[0].mode_index is None
    (maneuver,) = load_maneuvers(SimpleNamespace(maneuvers=specs, data=data), tmp_path)
    # Stabilized from the first status message with nav_state 15 (10 s) to the first with
    # another (30 s); the data run inside it
    assert maneuver.time[0] >= 10.0 and maneuver.time[0] < 10.011
    assert maneuver.time[-1] <= 30.0 and maneuver.time[-1] > 29.989

    section = {**data, "maneuvers": [{"file": "flight.ulg", "mode": "Position"}]}
    with pytest.raises(CaseError, match=r"mode 'Position' occurs 2 times.*mode_index"):
        load_maneuvers(SimpleNamespace(maneuvers=_maneuvers(section, "data", section), data=data),
                       tmp_path)  # fmt: skip
    section["maneuvers"][0]["mode_index"] = 2
    (late,) = load_maneuvers(
        SimpleNamespace(maneuvers=_maneuvers(section, "data", section), data=data), tmp_path
    )
    assert late.time[0] >= 30.0
    bad = {**data, "maneuvers": [{"file": "flight.ulg", "mode": "Acro", "start": 3.0}]}
    with pytest.raises(CaseError, match="either mode .* or start/stop"):
        _maneuvers(bad, "data", bad)
    bad = {**data, "maneuvers": [{"file": "flight.ulg", "mode_index": 1}]}
    with pytest.raises(CaseError, match="mode_index: give the mode too"):
        _maneuvers(bad, "data", bad)
    csv = tmp_path / "a.csv"
    csv.write_text("t,x\n0,1\n1,2\n")
    section = {"time": "t", "maneuvers": [{"file": "a.csv", "mode": "Acro"}]}
    specs = _maneuvers(section, "data", section)
    with pytest.raises(CaseError, match="not a flight log that records modes"):
        load_maneuvers(SimpleNamespace(maneuvers=specs, data=section), tmp_path)


def test_mode_interval_matches_aliases():
    interval = ModeInterval("Stabilized", 15, 0.0, 1.0, "vehicle_status.nav_state", ("STAB",))
    assert interval.matches(" stab ") and interval.matches("STABILIZED")
    assert not interval.matches("Stab2")


def test_streams_without_a_rate_print_a_dash_not_inf_or_nan():
    # a log's parameter messages (three samples at one stamp) and a version message (one
    # sample) have no rate: the summary says NaN and the printed table a dash
    from flightid.data.formats import Stream
    from flightid.logs.inspection import _hz
    from flightid.logs.streams import summarize_stream

    one_stamp = Stream("PARM", np.array([1.0, 1.0, 1.0]), {"Value": np.array([1.0, 2.0, 3.0])})
    single = Stream("VER", np.array([2.0]), {"BU": np.array([3.0])})
    regular = Stream("ATT", np.arange(0.0, 1.0, 0.02), {"Roll": np.zeros(50)})
    assert math.isnan(summarize_stream(one_stamp).rate_hz)
    assert math.isnan(summarize_stream(single).rate_hz)
    assert summarize_stream(regular).rate_hz == pytest.approx(50.0)
    assert _hz(summarize_stream(one_stamp).rate_hz) == "–"
    assert _hz(summarize_stream(regular).rate_hz) == "50.00"
