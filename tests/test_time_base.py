"""Time is never warped: re-gridding (dt, gaps = "join", rounded stamps) moves no row by more
than half an interval without a named error saying by how much; uneven and multi-rate
records are resampled only on purpose (resample_hz: anti-alias low-pass with zero phase,
linear interpolation, split at gaps), and the data say what was done (FlightData.notes)."""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy.signal import butter, sosfilt

from flightid.cases.build import load_maneuvers, maneuver_entry
from flightid.cases.spec import CaseError, parse_case
from flightid.data.flightdata import FlightData
from flightid.data.loaders import (
    Table,
    load_flight_data,
    load_flight_segments,
    to_flight_data,
    to_flight_segments,
)
from flightid.data.resample import StreamSamples, resample_streams
from flightid.data.timebase import TimeBaseError

RNG = np.random.default_rng(20240611)


def _table(t: np.ndarray, *columns: np.ndarray, names=("t", "x")) -> Table:
    return Table(np.column_stack([t, *columns]), tuple(names), ("s",) + ("",) * len(columns))


def _write_csv(path, t, x):
    with open(path, "w", encoding="utf-8") as stream:
        stream.write("t,x\n")
        for a, b in zip(t, x, strict=True):
            stream.write(f"{float(a)!r},{float(b)!r}\n")
    return path


def _jittery_stamps(n: int, low: float = 0.004, high: float = 0.0056) -> np.ndarray:
    """Stamps with intervals drawn uniformly in [low, high] s (a ~208 Hz ULog topic)."""
    return np.concatenate([[0.0], np.cumsum(RNG.uniform(low, high, n - 1))])


# ---------------------------------------------------------------- re-gridding never warps


def test_dt_at_the_median_of_a_jittery_log_is_refused_naming_the_move():
    t = _jittery_stamps(2000)
    table = _table(t, np.sin(t))
    median = float(np.median(np.diff(t)))
    # independent reference: the largest move of t_0 + k·median from the stamps
    move = np.max(np.abs(t - (t[0] + np.arange(t.size) * median)))
    assert move > median / 2
    with pytest.raises(TimeBaseError) as info:
        to_flight_data(table, time="t", outputs={"x": "x"}, dt=median)
    message = str(info.value)
    assert "dt: re-gridding" in message and "at most half an interval" in message
    assert f"by {move:.4g} s" in message and "resample_hz" in message


def test_dt_on_a_burst_logged_file_no_longer_compresses_time():
    # 400 Hz bursts of 9 intervals of 2.5 ms, then a 13.61 ms pause: 1800 intervals span
    # 6.5 s; the median interval is 2.5 ms, so dt = 0.0025 passes the 10 % check
    pattern = np.r_[np.full(9, 0.0025), 6.5 / 180 - 0.0225]  # 10 intervals last 6.5/180 s
    t = np.concatenate([[0.0], np.cumsum(np.tile(pattern, 180))])
    assert t[-1] == pytest.approx(6.5) and np.median(np.diff(t)) == pytest.approx(0.0025)
    table = _table(t, np.cos(t))
    with pytest.raises(TimeBaseError, match=r"the stored rows span 6\.5 s, the grid 4\.5 s"):
        to_flight_data(table, time="t", outputs={"x": "x"}, dt=0.0025)
    # accepted only when asked for, and then the notes say by how much
    data = to_flight_data(table, time="t", outputs={"x": "x"}, dt=0.0025, allow_retime=True)
    assert data.time[-1] == pytest.approx(4.5)
    assert re.search(r"moved by at most 2 s .*allow_retime = true", data.notes[0])


def test_rounded_stamps_are_regridded_within_half_an_interval_and_say_so():
    t = np.round(0.04 * np.arange(500) + 3e-7 * RNG.normal(size=500), 6)
    data = to_flight_data(_table(t, t**2), time="t", outputs={"x": "x"})
    np.testing.assert_allclose(np.diff(data.time), np.mean(np.diff(t)), rtol=1e-9)
    assert np.max(np.abs(data.time - t)) < 0.02
    assert data.notes and "rows moved by at most" in data.notes[0]


def test_uneven_log_without_a_method_is_refused_proposing_resample_hz():
    t = _jittery_stamps(500)
    with pytest.raises(TimeBaseError, match=r"uneven sampling.*resample_hz = R.*= 200\b"):
        to_flight_data(_table(t, np.sin(t)), time="t", outputs={"x": "x"})


def test_join_at_a_false_median_is_refused():
    # a CSV written at 0.02 s on average whose stamps come in bursts (0.01, 0.01, 0.04 s):
    # the median interval is 0.01 s, and joining "recordings" of 3 rows would halve time
    t = np.concatenate([[0.0], np.cumsum(np.tile([0.01, 0.01, 0.04], 100))])
    assert np.median(np.diff(t)) == pytest.approx(0.01)
    assert (t[-1] - t[0]) / (t.size - 1) == pytest.approx(0.02)
    with pytest.raises(TimeBaseError, match=r"hold fewer than 5 rows.*resample_hz"):
        to_flight_data(_table(t, t), time="t", outputs={"x": "x"}, gaps="join")


def test_join_keeps_the_rate_of_the_recordings():
    # two recordings at 0.02 s, the second restarting its clock at 0 s
    first, second = 0.02 * np.arange(300), 0.02 * np.arange(200)
    t = np.r_[first, second]
    data = to_flight_data(_table(t, np.arange(500.0)), time="t", outputs={"x": "x"}, gaps="join")
    np.testing.assert_allclose(data.time, 0.02 * np.arange(500), atol=1e-9)
    assert "2 recording(s) joined at their common interval 0.02 s" in data.notes[0]
    assert "breaks closed: 5.98 → 0 s" in data.notes[0]
    # recordings at different rates are refused: joining them would change one's rate
    t = np.r_[0.02 * np.arange(300), 100 + 0.01 * np.arange(300)]
    with pytest.raises(TimeBaseError, match=r"would move by .* within its recording"):
        to_flight_data(_table(t, t), time="t", outputs={"x": "x"}, gaps="join")


# ---------------------------------------------------------------- declared resampling


def test_resampled_jittery_sinusoid_matches_the_analytic_signal(tmp_path):
    # 208 Hz topic with jitter and a 20 ms drop-out, resampled at 100 Hz (f_c = 40 Hz)
    t = np.delete(_jittery_stamps(3000), np.arange(800, 804))
    f_hz = 3.0
    path = _write_csv(tmp_path / "gyro.csv", t, np.sin(2 * np.pi * f_hz * t))
    data = load_flight_data(path, time="t", outputs={"x": "x"}, resample_hz=100)
    np.testing.assert_allclose(data.time * 100, np.round(data.time * 100), atol=1e-9)
    assert data.dt == pytest.approx(0.01)
    assert t[0] <= data.time[0] < t[0] + 0.01 and t[-1] - 0.01 < data.time[-1] <= t[-1]
    error = data.output("x") - np.sin(2 * np.pi * f_hz * data.time)
    # away from the filter's edge transients (0.5 s at each end) the analytic sine is met
    inner = (data.time > data.time[0] + 0.5) & (data.time < data.time[-1] - 0.5)
    assert np.max(np.abs(error[inner])) < 2e-3
    assert np.max(np.abs(error)) < 2e-2
    assert data.notes[0] == "resampled at 100 Hz onto t_k = k/100 s"
    assert "low-pass 40 Hz" in data.notes[1] and "zero phase" in data.notes[1]


def test_tone_above_half_the_rate_is_attenuated_not_aliased():
    # a 1 kHz stream: 2 Hz signal plus an 80 Hz tone; at R = 100 Hz the tone would alias
    # to 20 Hz at full amplitude without a low-pass
    t = _jittery_stamps(8000, 0.00095, 0.00105)
    x = np.sin(2 * np.pi * 2 * t) + np.sin(2 * np.pi * 80 * t)
    data = to_flight_data(_table(t, x), time="t", outputs={"x": "x"}, resample_hz=100)
    grid = data.time
    plain = np.interp(grid, t, x) - np.sin(2 * np.pi * 2 * grid)  # no low-pass: aliased
    left = data.output("x") - np.sin(2 * np.pi * 2 * grid)
    inner = slice(50, -50)

    def amplitude_at(signal, f_hz):
        # least-squares amplitude of the f_hz component on the grid
        basis = np.column_stack([np.sin(2 * np.pi * f_hz * grid), np.cos(2 * np.pi * f_hz * grid)])
        coef = np.linalg.lstsq(basis[inner], signal[inner], rcond=None)[0]
        return float(np.hypot(*coef))

    assert amplitude_at(plain, 20) > 0.9
    # |H(80 Hz)|² of the 4th-order Butterworth at 40 Hz, forward and backward: 1/(1 + 2⁸)
    assert amplitude_at(left, 20) < 1.5 / (1 + 2**8)
    assert np.max(np.abs(left[inner])) < 0.01


def test_resampling_introduces_no_time_shift():
    # a 1 kHz stream resampled at 50 Hz (f_c = 20 Hz): the phase of a 5 Hz tone on the grid
    t = _jittery_stamps(6000, 0.00095, 0.00105)
    f_hz = 5.0
    x = np.sin(2 * np.pi * f_hz * t)
    data = to_flight_data(_table(t, x), time="t", outputs={"x": "x"}, resample_hz=50)
    grid, y = data.time[25:-25], data.output("x")[25:-25]

    def delay_s(values, times):
        # y = a·sin(ω(t − τ)): τ = −atan2(cos coefficient, sin coefficient)/ω
        basis = np.column_stack(
            [np.sin(2 * np.pi * f_hz * times), np.cos(2 * np.pi * f_hz * times)]
        )
        s, c = np.linalg.lstsq(basis, values, rcond=None)[0]
        return -np.arctan2(c, s) / (2 * np.pi * f_hz)

    assert abs(delay_s(y, grid)) < 1e-5
    # independent reference: the same low-pass run forward only (causal) delays the tone
    fine = np.arange(int(t[-1] * 1000)) / 1000
    causal = sosfilt(butter(4, 20, fs=1000, output="sos"), np.sin(2 * np.pi * f_hz * fine))
    assert delay_s(causal[1000:], fine[1000:]) > 5e-3


def test_gaps_split_the_record_into_segments():
    # 200 Hz with jitter; 0.5 s of nothing from 3 s
    t = _jittery_stamps(2000, 0.0048, 0.0052)
    t = t[(t < 3.0) | (t > 3.5)]
    x = np.sin(2 * np.pi * t)
    table = _table(t, x)
    spec = {"time": "t", "outputs": {"x": "x"}, "name": "sweep", "resample_hz": 100}
    pieces = to_flight_segments(table, **spec)
    assert [p.name for p in pieces] == ["sweep_1", "sweep_2"]
    assert pieces[0].time[-1] < 3.0 < 3.5 < pieces[1].time[0]
    assert "segment 2 of 2" in pieces[1].notes[-1]
    for piece in pieces:
        np.testing.assert_allclose(
            piece.output("x")[30:-30], np.sin(2 * np.pi * piece.time[30:-30]), atol=1e-4
        )
    with pytest.raises(TimeBaseError, match=r"splits into 2 segments.*to_flight_segments"):
        to_flight_data(table, **spec)
    # a longer max_gap_s bridges the gap on purpose
    (bridged,) = to_flight_segments(table, max_gap_s=1.0, **spec)
    assert bridged.name == "sweep" and "1 segment(s)" in bridged.notes[-1]


def test_resample_streams_at_different_rates_share_one_grid():
    slow_t = 0.1 + _jittery_stamps(200, 0.021, 0.023)
    fast_t = _jittery_stamps(5000, 0.0009, 0.0011)
    slow = StreamSamples("slow", slow_t, np.sin(slow_t)[:, None])  # about 45 Hz
    fast = StreamSamples("fast", fast_t, np.cos(fast_t)[:, None])
    result = resample_streams([slow, fast], 50.0)
    (segment,) = result.segments
    # the grid k/50 inside the span both cover
    lo, hi = max(slow_t[0], fast_t[0]), min(slow_t[-1], fast_t[-1])
    np.testing.assert_allclose(
        segment.time_s, np.arange(np.ceil(lo * 50), np.floor(hi * 50) + 1) / 50
    )
    np.testing.assert_allclose(segment.values[0][:, 0], np.sin(segment.time_s), atol=1e-3)
    np.testing.assert_allclose(segment.values[1][5:-5, 0], np.cos(segment.time_s[5:-5]), atol=1e-4)
    assert "linear interpolation (not faster than the grid" in result.notes[1]
    assert "low-pass 20 Hz" in result.notes[2]


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"resample_hz": 0}, "resample_hz: expected a positive number"),
        ({"resample_hz": "100"}, "resample_hz: expected a positive number"),
        ({"resample_hz": 100, "max_gap_s": -1}, "max_gap_s: expected a positive number"),
        ({"resample_hz": 100, "dt": 0.01}, "give either resample_hz or dt"),
        ({"resample_hz": 100, "gaps": "join"}, "give either resample_hz or dt"),
        ({"max_gap_s": 1.0}, "max_gap_s: only used with resample_hz"),
    ],
)
def test_resampling_settings_are_checked(settings, message):
    t = 0.01 * np.arange(100)
    with pytest.raises(TimeBaseError, match=message):
        to_flight_segments(_table(t, t), time="t", outputs={"x": "x"}, **settings)


def test_flight_data_notes_travel_with_copies():
    data = FlightData(0.1 * np.arange(10), outputs={"y": np.arange(10.0)}, notes=("made",))
    assert data.slice_time(0.2, 0.6).notes == ("made",) and data.select().notes == ("made",)
    with pytest.raises(TypeError, match="notes: expected a sequence of strings"):
        FlightData(0.1 * np.arange(10), notes="made")


# ---------------------------------------------------------------- case files


def _case(data: dict, prediction: dict | None = None) -> dict:
    raw = {
        "data": {"time": "t", "outputs": {"x": {"column": "x"}}, **data},
        "model": {"module": "m.py"},
    }
    if prediction is not None:
        raw["prediction"] = prediction
    return raw


def test_resample_hz_in_case_files_makes_segments_maneuvers(tmp_path):
    t = _jittery_stamps(2000, 0.0048, 0.0052)
    _write_csv(tmp_path / "gappy.csv", t[(t < 3.0) | (t > 3.5)], np.sin(t[(t < 3.0) | (t > 3.5)]))
    _write_csv(tmp_path / "plain.csv", t, np.cos(t))
    raw = _case(
        {
            "resample_hz": 100,
            "maneuvers": [
                {"file": "gappy.csv", "name": "a"},
                {"file": "plain.csv", "name": "b", "resample_hz": 50},
            ],
        },
        prediction={"file": "plain.csv", "resample_hz": 20},
    )
    case = parse_case(raw, tmp_path / "case.toml")
    assert [m.resample_hz for m in case.maneuvers] == [100.0, 50.0]
    assert case.prediction[0].resample_hz == 20.0
    loaded = load_maneuvers(case, tmp_path)
    assert [m.name for m in loaded] == ["a_1", "a_2", "b"]
    assert [round(m.dt, 9) for m in loaded] == [0.01, 0.01, 0.02]
    (predicted,) = load_maneuvers(case, tmp_path, case.prediction, key="prediction")
    assert predicted.dt == pytest.approx(0.05)
    # the results' maneuver entries say what was done to the time base
    entry = maneuver_entry(loaded[2])
    assert entry["time_base"][0] == "resampled at 50 Hz onto t_k = k/50 s"
    # the stored times used as they are: no time_base entry
    plain = FlightData(0.1 * np.arange(5), outputs={"y": np.zeros(5)}, name="p")
    assert "time_base" not in maneuver_entry(plain)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"file": "a.csv", "resample_hz": -5}, "data.file.resample_hz: expected a positive"),
        ({"file": "a.csv", "resample_hz": 50, "dt": 0.02}, "data.file.resample_hz: give either"),
        ({"file": "a.csv", "max_gap_s": 0.1}, "data.file.max_gap_s: only used with resample_hz"),
        ({"file": "a.csv", "allow_retime": "yes"}, "data.file.allow_retime"),
    ],
)
def test_resampling_case_errors_name_the_key(tmp_path, data, message):
    with pytest.raises(CaseError) as info:
        parse_case(_case(data), tmp_path / "case.toml")
    assert message in str(info.value)


def test_load_flight_segments_reads_a_file(tmp_path):
    t = _jittery_stamps(600, 0.0048, 0.0052)
    path = _write_csv(tmp_path / "run.csv", t, np.sin(t))
    (data,) = load_flight_segments(path, time="t", outputs={"x": "x"}, resample_hz=100)
    assert data.name == "run" and data.dt == pytest.approx(0.01)
