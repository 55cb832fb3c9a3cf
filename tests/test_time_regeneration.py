"""[data] dt: the stored time replaced by t_0 + k·dt in to_flight_data, load_flight_data and
case files (also per maneuver), where no row moves by more than dt/2; named errors."""

from __future__ import annotations

import numpy as np
import pytest

from flightid.cases.build import load_maneuvers
from flightid.cases.spec import CaseError, parse_case
from flightid.data.loaders import load_flight_data
from flightid.errors import InputError

N = 101


def _jittery_csv(path, t0=3.0):
    """Stamps k·0.02 s truncated to multiples of 2⁻⁹ s, so that the intervals are 0.01953 or
    0.02148 s as in SIDPAC's dcmp_lon_example.mat (float32 stamps), about a uniform 0.02 s
    grid; x = sin(t), y = 2·row."""
    t = t0 + np.floor(np.arange(N) * 0.02 * 512) / 512
    rows = np.column_stack([t, np.sin(t), 2.0 * np.arange(N)])
    with open(path, "w", encoding="utf-8") as stream:
        stream.write("t,x,y\n")
        for row in rows:
            stream.write(",".join(repr(float(v)) for v in row) + "\n")
    return path


def test_dt_regenerates_the_time(tmp_path):
    path = _jittery_csv(tmp_path / "jitter.csv")
    spec = {"inputs": {"x": {"column": "x"}}, "outputs": {"y": {"column": "y"}}, "time": "t"}
    # without dt the jitter (10 %) is refused as uneven sampling
    with pytest.raises(InputError, match="uneven sampling"):
        load_flight_data(path, **spec)
    data = load_flight_data(path, dt=0.02, **spec)
    # t_k = t_0 + k·dt with t_0 = 3.0 s, the first stored stamp
    np.testing.assert_allclose(data.time, 3.0 + 0.02 * np.arange(N), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(data.output("y"), 2.0 * np.arange(N))  # rows unchanged
    # start/stop pick rows by their stored stamps; t_0 is the first kept one
    part = load_flight_data(path, dt=0.02, start=3.5, **spec)
    first = int(np.argmax(np.loadtxt(path, delimiter=",", skiprows=1)[:, 0] >= 3.5))
    assert part.n_samples == N - first
    assert part.time[0] == pytest.approx(np.loadtxt(path, delimiter=",", skiprows=1)[first, 0])
    np.testing.assert_allclose(np.diff(part.time), 0.02, rtol=1e-9)
    # the time variable of expressions sees the regenerated times
    ramp = load_flight_data(
        path, dt=0.02, time="t", inputs={"ramp": {"expr": "t"}}, outputs=spec["outputs"]
    )
    np.testing.assert_allclose(ramp.input("ramp"), ramp.time, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("dt", "message"),
    [
        (0.0, "dt: expected a positive number of seconds"),
        (-0.02, "dt: expected a positive number of seconds"),
        (float("nan"), "dt: expected a positive number of seconds"),
        ("0.02", "dt: expected a positive number of seconds"),
        (0.2, "dt: 0.2 s is not within 10 % of the median stored interval"),
    ],
)
def test_dt_named_errors(tmp_path, dt, message):
    path = _jittery_csv(tmp_path / "jitter.csv")
    with pytest.raises(InputError, match=message):
        load_flight_data(path, time="t", outputs={"y": {"column": "y"}}, dt=dt)


def _case(data: dict) -> dict:
    return {
        "data": {
            "time": "t",
            "inputs": {"x": {"column": "x"}},
            "outputs": {"y": {"column": "y"}},
            **data,
        },  # fmt: skip
        "model": {"module": "m.py"},
    }


def test_dt_in_case_files_also_per_maneuver(tmp_path):
    _jittery_csv(tmp_path / "a.csv", t0=0.0)
    _jittery_csv(tmp_path / "b.csv", t0=1.0)
    raw = _case(
        {
            "dt": 0.02,
            "maneuvers": [{"file": "a.csv"}, {"file": "b.csv", "dt": 0.02005}],
        }
    )
    case = parse_case(raw, tmp_path / "case.toml")
    assert [m.dt for m in case.maneuvers] == [0.02, 0.02005]
    first, second = load_maneuvers(case, tmp_path)
    np.testing.assert_allclose(first.time, 0.02 * np.arange(N), atol=1e-12)
    # 0.02005 s moves the last row by 100 × 0.00005 = 0.005 s (plus the stamps' truncation)
    np.testing.assert_allclose(second.time, 1.0 + 0.02005 * np.arange(N), atol=1e-12)
    # no dt: the stored times (here refused as uneven)
    plain = parse_case(_case({"file": "a.csv"}), tmp_path / "case.toml")
    assert plain.maneuvers[0].dt is None
    with pytest.raises(CaseError, match="uneven sampling"):
        load_maneuvers(plain, tmp_path)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"file": "a.csv", "dt": 0}, "data.file.dt: expected a positive sampling interval"),
        ({"file": "a.csv", "dt": "0.02"}, "data.file.dt: expected a number"),
        ({"maneuvers": [{"file": "a.csv", "dt": -1}]}, "data.maneuvers[0].dt: expected a positive"),
    ],
)
def test_dt_case_errors_name_the_key(tmp_path, data, message):
    with pytest.raises(CaseError) as info:
        parse_case(_case(data), tmp_path / "case.toml")
    assert message in str(info.value)
