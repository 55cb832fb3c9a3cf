"""Declared pre-processing pipelines ([data.constants], [data.signals], [[data.steps]]):
each built-in step against the component equations of CASES.md §6 written out here, the
whole §6 chain on the ATTAS files against a straight-line implementation, restart at
segment and maneuver boundaries, units, and the named errors."""

from __future__ import annotations

import math
import os
import tomllib
from pathlib import Path

import numpy as np
import pytest

from flightid.cases import CaseError, load_case, parse_case
from flightid.cases.build import load_maneuvers
from flightid.cli.main import main
from flightid.data.coefficients import Engine, MassGeometry, aero_coefficients
from flightid.data.loaders import ChannelError, Table, load_flight_data, read_table, to_flight_data
from flightid.data.pipeline import parse_pipeline
from flightid.data.preprocess import PreprocessError, ndiff8, smooth_mul_ts
from flightid.data.transfer import transfer_accelerations, transfer_air_data

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("FLIGHTID_DATA", ROOT / "../shared/data"))
needs_data = pytest.mark.skipif(
    not (DATA / "fvsysid").is_dir(), reason=f"real flight data not found at {DATA}"
)

# CASES.md §6 constants
MASS, IX, IY, IZ, IXZ = 17631.0, 1.33367e5, 2.52687e5, 3.59593e5, 1.14420e4
S, CBAR, B2 = 64.0, 3.159, 10.75
ACC = (-1.010, 0.886, 0.103)
NB = (13.080, -0.010, -0.027)
AC = (-0.02, -0.01, -0.12)
YE, XE, ZE = 2.990, -1.343, -0.652


def _motion(seed: int, n: int = 64) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {
        "V": rng.uniform(60.0, 120.0, n),
        "alpha": rng.uniform(-0.1, 0.3, n),
        "beta": rng.uniform(-0.1, 0.1, n),
        "p": rng.normal(0.0, 0.3, n),
        "q": rng.normal(0.0, 0.2, n),
        "r": rng.normal(0.0, 0.2, n),
        "pdot": rng.normal(0.0, 0.5, n),
        "qdot": rng.normal(0.0, 0.5, n),
        "rdot": rng.normal(0.0, 0.5, n),
        "ax": rng.normal(0.5, 1.0, n),
        "ay": rng.normal(0.0, 1.0, n),
        "az": rng.normal(-9.8, 1.0, n),
        "qbar": rng.uniform(2000.0, 8000.0, n),
        "FL": rng.uniform(5000.0, 12000.0, n),
        "FR": rng.uniform(5000.0, 12000.0, n),
    }


# ------------------------------------------------------------------ the steps' physics


def test_air_data_transfer_is_cases_step2():
    m = _motion(1)
    x, y, z = NB
    # CASES.md §6 step 2, written out
    u_nb = m["V"] * np.cos(m["beta"]) * np.cos(m["alpha"])
    v_nb = m["V"] * np.sin(m["beta"])
    w_nb = m["V"] * np.cos(m["beta"]) * np.sin(m["alpha"])
    u = u_nb + y * m["r"] - z * m["q"]
    v = v_nb + z * m["p"] - x * m["r"]
    w = w_nb + x * m["q"] - y * m["p"]
    V = np.sqrt(u**2 + v**2 + w**2)
    got = transfer_air_data(m["V"], m["alpha"], m["beta"], m["p"], m["q"], m["r"], NB)
    np.testing.assert_allclose(got[0], V, rtol=1e-13)
    np.testing.assert_allclose(got[1], np.arctan(w / u), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(got[2], np.arcsin(v / V), rtol=1e-12, atol=1e-15)
    # a rigid body: moving to another point and back gives the measured values
    there = transfer_air_data(m["V"], m["alpha"], m["beta"], m["p"], m["q"], m["r"], NB, ACC)
    back = transfer_air_data(*there, m["p"], m["q"], m["r"], ACC, NB)
    for a, b in zip(back, (m["V"], m["alpha"], m["beta"]), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-14)


def test_acceleration_transfer_is_cases_step7():
    m = _motion(2)
    x, y, z = ACC
    p, q, r, pd, qd, rd = (m[k] for k in ("p", "q", "r", "pdot", "qdot", "rdot"))
    # CASES.md §6 step 7, written out
    ax = m["ax"] + x * (q**2 + r**2) - y * (p * q - rd) - z * (p * r + qd)
    ay = m["ay"] - x * (p * q + rd) + y * (r**2 + p**2) - z * (q * r - pd)
    az = m["az"] - x * (p * r - qd) - y * (q * r + pd) + z * (p**2 + q**2)
    got = transfer_accelerations(m["ax"], m["ay"], m["az"], p, q, r, pd, qd, rd, ACC)
    for a, b in zip(got, (ax, ay, az), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-12)


def test_coefficients_are_cases_steps_8_and_9():
    m = _motion(3)
    p, q, r, pd, qd, rd = (m[k] for k in ("p", "q", "r", "pdot", "qdot", "rdot"))
    qbar, alpha, FL, FR = m["qbar"], m["alpha"], m["FL"], m["FR"]
    # CASES.md §6 steps 8 and 9, written out (engines at (x_E, ∓y_E, z_E), incidence 0)
    CX = (MASS * m["ax"] - (FL + FR)) / (qbar * S)
    CY = MASS * m["ay"] / (qbar * S)
    CZ = MASS * m["az"] / (qbar * S)
    CD = -CX * np.cos(alpha) - CZ * np.sin(alpha)
    CL = CX * np.sin(alpha) - CZ * np.cos(alpha)
    Cl_cg = (IX * pd - IXZ * rd - IXZ * p * q - (IY - IZ) * q * r) / (qbar * S * B2)
    Cm_cg = (IY * qd + (p**2 - r**2) * IXZ - p * r * (IZ - IX) - (FL + FR) * ZE) / (qbar * S * CBAR)
    Cn_cg = (IZ * rd - IXZ * pd + IXZ * q * r - (IX - IY) * p * q - (FL - FR) * YE) / (
        qbar * S * B2
    )
    x, y, z = AC
    Cl = Cl_cg - CZ * y / B2 + CY * z / B2
    Cm = Cm_cg - CX * z / CBAR + CZ * x / CBAR
    Cn = Cn_cg - CY * x / B2 + CX * y / B2
    geometry = MassGeometry(MASS, IX, IY, IZ, S, CBAR, B2, Ixz=IXZ, reference_point_m=AC)
    engines = [Engine(FL, (XE, -YE, ZE)), Engine(FR, (XE, YE, ZE))]
    got = aero_coefficients(
        m["ax"], m["ay"], m["az"], p, q, r, pd, qd, rd, qbar, alpha, geometry, engines
    )
    expected = dict(CX=CX, CY=CY, CZ=CZ, Cl=Cl, Cm=Cm, Cn=Cn, CL=CL, CD=CD)
    for name, values in expected.items():
        np.testing.assert_allclose(got[name], values, rtol=1e-11, atol=1e-14, err_msg=name)


def test_engine_incidence_and_full_inertia_tensor():
    # no motion except rates; one engine at (x, 0, z), thrust line ε nose-up: the thrust is
    # T (cos ε, 0, −sin ε), its pitching moment z·T cos ε + x·T sin ε (r × F, y component)
    m = _motion(4)
    eps, x, z, T = 0.05, -2.0, -0.5, m["FL"]
    geometry = MassGeometry(MASS, IX, IY, IZ, S, CBAR, B2, Ixz=IXZ, Ixy=300.0, Iyz=-200.0)
    got = aero_coefficients(
        m["ax"], m["ay"], m["az"], m["p"], m["q"], m["r"], m["pdot"], m["qdot"], m["rdot"],
        m["qbar"], m["alpha"], geometry, [Engine(T, (x, 0.0, z), eps)],
    )  # fmt: skip
    qs = m["qbar"] * S
    np.testing.assert_allclose(got["CX"], (MASS * m["ax"] - T * math.cos(eps)) / qs, rtol=1e-12)
    np.testing.assert_allclose(got["CZ"], (MASS * m["az"] + T * math.sin(eps)) / qs, rtol=1e-12)
    # Euler's equation with the full tensor by matrix algebra: M = I ω̇ + ω × (I ω)
    inertia = np.array([[IX, -300.0, -IXZ], [-300.0, IY, 200.0], [-IXZ, 200.0, IZ]])
    omega = np.column_stack([m["p"], m["q"], m["r"]])
    omega_dot = np.column_stack([m["pdot"], m["qdot"], m["rdot"]])
    moment = omega_dot @ inertia.T + np.cross(omega, omega @ inertia.T)
    thrust_pitch = z * T * math.cos(eps) + x * T * math.sin(eps)
    np.testing.assert_allclose(got["Cl"], moment[:, 0] / (qs * B2), rtol=1e-11)
    np.testing.assert_allclose(got["Cm"], (moment[:, 1] - thrust_pitch) / (qs * CBAR), rtol=1e-11)
    np.testing.assert_allclose(got["Cn"], moment[:, 2] / (qs * B2), rtol=1e-11)


def test_geometry_and_qbar_are_checked():
    with pytest.raises(PreprocessError, match="mass_kg: expected a positive number"):
        MassGeometry(0.0, IX, IY, IZ, S, CBAR, B2)
    m = _motion(5, 4)
    m["qbar"][2] = 0.0
    g = MassGeometry(MASS, IX, IY, IZ, S, CBAR, B2)
    with pytest.raises(PreprocessError, match="positive dynamic pressure.*sample 3"):
        aero_coefficients(*(m[k] for k in "ax ay az p q r pdot qdot rdot qbar alpha".split()), g)


# ------------------------------------------------------------------ signals and steps


def _table(columns: dict[str, np.ndarray], units: dict[str, str] | None = None) -> Table:
    names = tuple(columns)
    units = units or {}
    return Table(
        np.column_stack(list(columns.values())), names, tuple(units.get(k, "") for k in names), "t"
    )


def _ramp_table(n: int = 40, jump: int | None = None) -> Table:
    t = np.arange(n) * 0.1
    if jump is not None:
        t[jump:] += 5.0  # a gap: a second recording segment
    rng = np.random.default_rng(9)
    return _table({"t": t, "a": np.sin(t) + rng.normal(0, 0.01, n), "b": np.cos(2 * t)})


def test_signals_build_on_each_other_with_constants_in_any_order():
    table = _ramp_table()
    a, b = table.column("a"), table.column("b")
    signals = {  # written in reverse dependency order: flightid sorts them
        "s3": "s2 + b",
        "s2": {"column": "s1", "smooth": "smoothMulTS"},
        "s1": "a * k",
    }
    data = to_flight_data(
        table,
        time="t",
        constants={"k": 2.0},
        signals=signals,
        inputs={"u": "s3"},
        outputs={"y": "s2", "k2": "k * b"},
    )
    expected = smooth_mul_ts(2.0 * a) + b
    np.testing.assert_allclose(data.input("u"), expected, rtol=1e-14)
    np.testing.assert_allclose(data.output("k2"), 2.0 * b, rtol=1e-14)
    order = parse_pipeline({"k": 2.0}, signals).order
    assert [key for _, key in order] == ["s1", "s2", "s3"]


def test_a_signal_named_like_a_column_reads_the_column_and_channels_inherit_its_unit():
    table = _table({"t": np.arange(20) * 0.1, "p": np.linspace(0.0, 19.0, 20)})
    data = to_flight_data(
        table,
        time="t",
        signals={
            "p": {"column": "p", "unit": "deg/s"},
            "pdot": {"column": "p", "derivative": "ndiff8"},
        },
        inputs={"p": "p"},
        outputs={"pdot": "pdot"},
    )  # fmt: skip
    np.testing.assert_allclose(data.input("p"), np.deg2rad(np.linspace(0.0, 19.0, 20)))
    # d/dt of a ramp of 1 deg per 0.1 s: 10 deg/s in rad/s²
    np.testing.assert_allclose(data.output("pdot"), np.deg2rad(10.0), rtol=1e-9)
    assert data.units == {"p": "rad/s", "pdot": "rad/s/s"}


def test_smoothing_and_differentiation_restart_at_segments():
    # rows joined from two recordings (gaps = "join"): each is filtered on its own
    table = _ramp_table(60, jump=30)
    a = table.column("a")
    signals = {
        "a_s": {"column": "a", "smooth": "smoothMulTS"},
        "a_d": {"column": "a_s", "derivative": "ndiff8"},
    }
    data = to_flight_data(table, time="t", gaps="join", signals=signals, outputs={"y": "a_d"})
    expected = np.concatenate(
        [ndiff8(smooth_mul_ts(a[:30]), 0.1), ndiff8(smooth_mul_ts(a[30:]), 0.1)]
    )
    np.testing.assert_allclose(data.output("y"), expected, rtol=1e-12)
    whole = ndiff8(smooth_mul_ts(a), 0.1)
    assert np.max(np.abs(whole[25:35] - expected[25:35])) > 1e-3  # the restart matters
    # a step's result restarts trivially (sample by sample), but a signal built on it does too
    steps = [{"kind": "remove_bias", "biases": {"a": 0.5}}]
    data = to_flight_data(
        table, time="t", gaps="join", steps=steps,
        signals={"a_s": {"column": "a_c", "smooth": "smoothMulTS"}}, outputs={"y": "a_s"},
    )  # fmt: skip
    parts = [smooth_mul_ts(a[:30] - 0.5), smooth_mul_ts(a[30:] - 0.5)]
    np.testing.assert_allclose(data.output("y"), np.concatenate(parts), rtol=1e-12)


def test_start_stop_keeps_rows_before_the_pipeline_filters():
    table = _ramp_table(60)
    a = table.column("a")
    signals = {"a_s": {"column": "a", "smooth": "smoothMulTS"}}
    data = to_flight_data(
        table, time="t", start=1.0, stop=4.0, signals=signals, outputs={"y": "a_s"}
    )
    np.testing.assert_allclose(data.output("y"), smooth_mul_ts(a[10:41]), rtol=1e-12)


def test_a_reconstructed_csv_with_unit_headers_feeds_the_steps(tmp_path):
    # the file another run writes: `name [unit]` headers (flight-path reconstruction output)
    m = _motion(6, 30)
    header = "time [s],V [m/s],alpha [rad],beta [rad],p [rad/s],q [rad/s],r [rad/s]"
    rows = np.column_stack(
        [np.arange(30) * 0.04] + [m[k] for k in ("V", "alpha", "beta", "p", "q", "r")]
    )
    path = tmp_path / "reconstructed_man1.csv"
    path.write_text(header + "\n" + "\n".join(",".join(f"{v:.17g}" for v in row) for row in rows))
    steps = [{"kind": "transfer_air_data", "sensor": list(NB)}]
    data = load_flight_data(path, time="time", steps=steps, outputs={"alpha": "alpha_cg"})
    expected = transfer_air_data(m["V"], m["alpha"], m["beta"], m["p"], m["q"], m["r"], NB)[1]
    np.testing.assert_allclose(data.output("alpha"), expected, rtol=1e-12)
    assert data.units == {"alpha": "rad"}
    # a header unit that is not what the step needs is refused when the file is read
    path.write_text(
        header.replace("alpha [rad]", "alpha [deg]") + "\n" + path.read_text().split("\n", 1)[1]
    )
    with pytest.raises(
        PreprocessError, match=r"signals.alpha: expected rad, but column 'alpha' is in 'deg'"
    ):
        load_flight_data(path, time="time", steps=steps, outputs={"alpha": "alpha_cg"})


def test_the_reconstruction_writer_output_is_read_with_greek_names(tmp_path):
    # flightid.compat.reconstruct writes `α_rec [rad]`-style headers; a case uses them by name
    # in column, expr and step roles
    from flightid.compat.reconstruct import Reconstruction

    m = _motion(7, 30)
    columns = {"t [s]": np.arange(30) * 0.04, "V_rec [m/s]": m["V"], "α_rec [rad]": m["alpha"]}
    columns |= {"β_rec [rad]": m["beta"], "p [rad/s]": m["p"], "q [rad/s]": m["q"]}
    columns["r [rad/s]"] = m["r"]
    path = Reconstruction("man1", columns).write_csv(tmp_path / "reconstructed_man1.csv")
    steps = [
        {
            "kind": "transfer_air_data",
            "sensor": list(NB),
            "signals": {"V": "V_rec", "alpha": "α_rec", "beta": "β_rec"},
        }
    ]
    data = load_flight_data(
        path,
        time="t",
        steps=steps,
        inputs={"α2": "2 * α_rec"},
        outputs={"alpha": "alpha_cg"},
    )
    np.testing.assert_allclose(data.input("α2"), 2 * m["alpha"], rtol=1e-15)
    expected = transfer_air_data(m["V"], m["alpha"], m["beta"], m["p"], m["q"], m["r"], NB)[1]
    np.testing.assert_allclose(data.output("alpha"), expected, rtol=1e-12)


# ------------------------------------------------------------------ errors


# an aero_coefficients step with unit mass, inertia and geometry
_AERO_STEP = {
    "kind": "aero_coefficients",
    "mass": 1,
    "Ix": 1,
    "Iy": 1,
    "Iz": 1,
    "S": 1,
    "cbar": 1,
    "b": 1,
}


@pytest.mark.parametrize(
    ("signals", "steps", "constants", "error", "words"),
    [
        (
            {"a": "b + 1", "b": "a * 2"},
            None,
            None,
            PreprocessError,
            r"cycle: signals.a → signals.b → signals.a",
        ),
        (
            {"x": "ax_c * 2"},
            [{"kind": "remove_bias", "biases": {"ax": "x"}}],
            {"x": 1.0},
            PreprocessError,
            "also a signal",
        ),
        (
            {"ax": "ax_cg + 1"},
            [{"kind": "transfer_accelerations", "sensor": [0, 0, 0], "signals": {"ax": "ax"}}],
            None,
            PreprocessError,
            r"cycle: signals.ax → steps\[0\] \(transfer_accelerations\) → signals.ax",
        ),
        (
            None,
            [{"kind": "transfer_air_data", "sensor": "nose"}],
            {"NB": list(NB)},
            PreprocessError,
            "no constant named 'nose'.*constants: \\['NB'\\]",
        ),
        (None, [{"kind": "transfer_air_data"}], None, PreprocessError, r"missing \['sensor'\]"),
        (
            None,
            [{"kind": "transfer_air_data", "sensor": [1.0, 2.0]}],
            None,
            PreprocessError,
            r"expected a position \[x, y, z\]",
        ),
        (None, [{"kind": "smooth_all"}], None, PreprocessError, r"kind: expected one of"),
        (
            None,
            [{"kind": "transfer_air_data", "sensor": [0, 0, 0], "signals": {"VV": "V"}}],
            None,
            PreprocessError,
            "unknown role",
        ),
        (
            None,
            [{"kind": "transfer_air_data", "sensor": [0, 0, 0], "from": [0, 0, 0]}],
            None,
            PreprocessError,
            r"unknown key\(s\) \['from'\]",
        ),
        (
            {"alpha": {"column": 2, "unit": "deg", "to": "deg"}},
            [{"kind": "transfer_air_data", "sensor": [0, 0, 0]}],
            None,
            PreprocessError,
            "signals.alpha: expected rad, but the signal 'alpha' is in 'deg'",
        ),
        (
            None,
            [{**_AERO_STEP, "mass": {"value": 1.0, "unit": "m"}}],
            None,
            PreprocessError,
            "mass: expected a value in kg",
        ),
        (
            None,
            [{**_AERO_STEP, "cbar": -1}],
            None,
            PreprocessError,
            "cbar_m: expected a positive number",
        ),
        ({"y": "2 * NB"}, None, {"NB": list(NB)}, PreprocessError, "only single numbers"),
        (
            {"V_cg": "1"},
            [{"kind": "transfer_air_data", "sensor": [0, 0, 0]}],
            None,
            PreprocessError,
            "'V_cg' is already made by signals.V_cg",
        ),
        ({"pi": "1 + 1"}, None, None, ChannelError, "identifiers other than 't' and 'pi'"),
        ({"y": "sinh(2)"}, None, None, ChannelError, "unknown function 'sinh'"),
        (None, None, {"t": 1.0}, PreprocessError, "other than 't' and 'pi'"),
        ([1], None, None, PreprocessError, r"signals: expected a table of name = channel"),
        (
            None,
            "x",
            None,
            PreprocessError,
            r"steps: expected an array of tables \[\[data.steps\]\]",
        ),
        (
            None,
            [{"kind": "remove_bias", "biases": {}}],
            None,
            PreprocessError,
            r"steps\[0\] \(remove_bias\).biases: expected a table signal = bias",
        ),
        (
            None,
            [{"kind": "transfer_air_data", "sensor": [0, 0, 0], "signals": [1]}],
            None,
            PreprocessError,
            r"\(transfer_air_data\).signals: expected a table role = signal, got \[1\]",
        ),
        (
            None,
            [{"kind": "remove_bias", "biases": {"p": 0.1}, "names": [1]}],
            None,
            PreprocessError,
            r"\(remove_bias\).names: expected a table role = name, got \[1\]",
        ),
        (
            None,
            [{"kind": "remove_bias", "biases": {"p": 0.1}, "names": {"q": "pc"}}],
            None,
            PreprocessError,
            r"\(remove_bias\).names: unknown role\(s\) \['q'\]; roles: \['p'\]",
        ),
        (
            None,
            [
                {"kind": "transfer_air_data", "sensor": [0, 0, 0]},
                {"kind": "transfer_air_data", "sensor": [1, 0, 0]},
            ],
            None,
            PreprocessError,
            r"steps\[1\] \(transfer_air_data\).names.V: 'V_cg' is already made by steps\[0\]",
        ),
        (
            None,
            [{"kind": "transfer_air_data", "sensor": [0, 0, 0]}],
            {"V_cg": 1.0},
            PreprocessError,
            "constants.V_cg: the name is also a signal",
        ),
        (
            {"T": {"column": 1, "unit": "lbf", "to": "lbf"}},
            [{**_AERO_STEP, "engines": [{"thrust": "T", "position": [0, 0, 0]}]}],
            None,
            PreprocessError,
            "engines: the thrust signal 'T' is in 'lbf', expected N",
        ),
    ],
)
def test_bad_pipelines_are_named_errors_without_data(signals, steps, constants, error, words):
    with pytest.raises(error, match=words):
        parse_pipeline(constants, signals, steps)


def test_unknown_names_are_named_when_the_data_are_read():
    table = _ramp_table()
    with pytest.raises(
        ChannelError,
        match=r"signals.s: no column named 'c'.*nor a signal or constant \(known: \['k', 's0'\]\)",
    ):
        to_flight_data(
            table,
            time="t",
            constants={"k": 1.0},
            signals={"s0": "a", "s": "c + s0"},
            outputs={"y": "s"},
        )
    with pytest.raises(ChannelError, match="no column named 'V'"):
        to_flight_data(
            table,
            time="t",
            steps=[{"kind": "transfer_air_data", "sensor": [0, 0, 0]}],
            outputs={"y": "a"},
        )


def test_expression_names_resolve_signal_then_constant_then_column_and_stay_data():
    # columns a, b; a constant named like column b wins over it, $2 is always the column
    table = _ramp_table()
    a, b = table.column("a"), table.column("b")
    data = to_flight_data(
        table,
        time="t",
        constants={"b": 3.0},
        signals={"s": "a * b + $3"},
        outputs={"y": "s"},
    )
    np.testing.assert_allclose(data.output("y"), a * 3.0 + b, rtol=1e-14)
    # a dotted name is a column name (flight-log streams), never an attribute access
    with pytest.raises(ChannelError, match=r"no column named 's0.__class__'"):
        to_flight_data(
            table, time="t", signals={"s0": "a", "s": "s0.__class__"}, outputs={"y": "s"}
        )
    for text in ("__import__('os')", "a[0] + 1", "a ** 2", "(lambda: 1)()"):
        with pytest.raises(ChannelError):
            parse_pipeline(signals={"s": text})


def test_constants_take_units_and_lists():
    pipeline = parse_pipeline(
        {
            "m": {"value": 100.0, "unit": "lbm"},
            "pos": {"value": [1.0, 0.0, -2.0], "unit": "ft"},
            "k": 3,
        }
    )
    assert pipeline.constants["m"] == pytest.approx(45.359237)  # 1 lbm = 0.45359237 kg exactly
    assert pipeline.constants["pos"] == pytest.approx((0.3048, 0.0, -0.6096))
    assert pipeline.constants["k"] == 3.0


CASE = """
[data]
file = "f.csv"
time = "t"
[data.signals]
a = "b + 1"
b = "a * 2"
[data.outputs]
y = "a"
[model]
module = "m.py"
"""


def test_case_files_report_pipeline_errors_with_the_key(tmp_path):
    with pytest.raises(CaseError, match=r"data.signals and steps depend on each other in a cycle"):
        parse_case(tomllib.loads(CASE), tmp_path / "case.toml")
    bad = CASE.replace('a = "b + 1"\nb = "a * 2"', 'a = "b + 1"\n[[data.steps]]\nkind = "x"')
    with pytest.raises(CaseError, match=r"data.steps\[0\].kind: expected one of"):
        parse_case(tomllib.loads(bad), tmp_path / "case.toml")


# ------------------------------------------------------------------ the ATTAS §6 chain


def _cases_section6(raw: np.ndarray, dt: float) -> dict[str, np.ndarray]:
    """CASES.md §6 steps 1–9 for one maneuver, written straight from the text (S and D are
    flightid.data.preprocess's, checked against the §0 formulas in tests/test_preprocess.py)."""
    d2r = math.pi / 180.0
    col = lambda k: raw[:, k - 1]  # noqa: E731 - 1-based columns as CASES.md lists them
    ax, ay, az = col(2) - 6.76242e-3, col(3) + 1.50664e-3, col(4) - 8.39892e-2
    p, q, r = col(7) * d2r - 1.02555e-3, col(8) * d2r - 3.40891e-3, col(9) * d2r - 9.96192e-4
    alpha, beta, V = col(13) * d2r, col(14) * d2r, col(15)
    rho, FL, FR = col(34), col(37), col(38)
    x, y, z = NB
    u = V * np.cos(beta) * np.cos(alpha) + y * r - z * q
    v = V * np.sin(beta) + z * p - x * r
    w = V * np.cos(beta) * np.sin(alpha) + x * q - y * p
    V_cg = np.sqrt(u * u + v * v + w * w)
    a_s, b_s, V_s = (
        smooth_mul_ts(np.arctan(w / u)),
        smooth_mul_ts(np.arcsin(v / V_cg)),
        smooth_mul_ts(V_cg),
    )
    qbar = 0.5 * rho * V_s**2
    pd, qd, rd = (ndiff8(smooth_mul_ts(s), dt) for s in (p, q, r))
    x, y, z = ACC
    axc = ax + x * (q**2 + r**2) - y * (p * q - rd) - z * (p * r + qd)
    ayc = ay - x * (p * q + rd) + y * (r**2 + p**2) - z * (q * r - pd)
    azc = az - x * (p * r - qd) - y * (q * r + pd) + z * (p**2 + q**2)
    qs = qbar * S
    CX, CY, CZ = (MASS * axc - (FL + FR)) / qs, MASS * ayc / qs, MASS * azc / qs
    CD = -CX * np.cos(a_s) - CZ * np.sin(a_s)
    CL = CX * np.sin(a_s) - CZ * np.cos(a_s)
    Cl = (IX * pd - IXZ * rd - IXZ * p * q - (IY - IZ) * q * r) / (qs * B2)
    Cm = (IY * qd + (p**2 - r**2) * IXZ - p * r * (IZ - IX) - (FL + FR) * ZE) / (qs * CBAR)
    Cn = (IZ * rd - IXZ * pd + IXZ * q * r - (IX - IY) * p * q - (FL - FR) * YE) / (qs * B2)
    x, y, z = AC
    return {
        "CD": CD,
        "CL": CL,
        "CY": CY,
        "Cl": Cl - CZ * y / B2 + CY * z / B2,
        "Cm": Cm - CX * z / CBAR + CZ * x / CBAR,
        "Cn": Cn - CY * x / B2 + CX * y / B2,
        "alpha": a_s,
        "beta": b_s,
        "V": V_s,
        "p": col(7) * d2r,  # the model's rates: raw (CASES.md Q7)
    }


@needs_data
def test_the_attas_case_builds_the_section6_coefficients_per_maneuver():
    case = load_case(ROOT / "examples/cases/attas_aero_regression_linear.toml")
    maneuvers = load_maneuvers(case, DATA)
    files = ("fAttasElv1.mat", "fAttasAil1.mat", "fAttasRud1.mat")
    for data, name in zip(maneuvers, files, strict=True):
        raw = read_table(DATA / "fvsysid" / name).data
        expected = _cases_section6(raw, 0.04)
        for channel, values in expected.items():
            np.testing.assert_allclose(
                data.channel(channel), values, rtol=1e-9, atol=1e-12, err_msg=f"{name} {channel}"
            )
    # filtered over the concatenated record instead, the first maneuver's end would differ
    raw = np.vstack([read_table(DATA / "fvsysid" / f).data for f in files])
    joined = _cases_section6(raw, 0.04)["Cm"][:626]
    assert np.max(np.abs(joined[-10:] - maneuvers[0].output("Cm")[-10:])) > 1e-4


@needs_data
@pytest.mark.parametrize(
    "name", ["attas_aero_regression_linear", "attas_aero_regression_polar", "attas_qst_kirchhoff"]
)
def test_validate_accepts_the_regression_cases(name, capsys):
    code = main(
        ["validate", str(ROOT / "examples/cases" / f"{name}.toml"), "--data-dir", str(DATA)]
    )
    assert code == 0, capsys.readouterr().err
