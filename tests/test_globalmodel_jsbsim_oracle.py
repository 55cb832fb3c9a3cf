"""The JSBSim validation study's ground truth (bench/globalmodel_jsbsim.py): the truth oracle
(the F-16 copy without its flight-control system, evaluated by ``run_ic``) against the
coefficients JSBSim's flying aircraft has in flight; the coefficients reconstructed from the
recorded motion against the truth, noise-free and with the noise first-order error
propagation predicts; the trims; and the study's measures on hand-built predictions."""

import importlib.util
import json
import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.signal

pytest.importorskip("jsbsim")

BENCH = Path(__file__).resolve().parents[1] / "bench" / "globalmodel_jsbsim.py"
DT = 0.02


@pytest.fixture(scope="module")
def study():
    # a script of bench/, loaded by path
    spec = importlib.util.spec_from_file_location("bench_globalmodel_jsbsim", BENCH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def oracle(study):
    with study.truth_oracle() as truth:
        yield truth


@pytest.fixture(scope="module")
def flights(study, oracle):
    """A multisine and a pull-up at M 0.6, 25 000 ft (α 1–17°, three lef positions) and a
    lateral multisine at M 0.5, 10 000 ft, noise-free."""
    quick = study.maneuver_designs(True)
    lateral = study.ManeuverDesign(
        "lateral", 8.0, (0.2, 1.5), {"stick": 0.1, "aileron": 0.12, "rudder": 0.2}
    )
    out = study.fly_condition(study.Condition(0.6, 25000.0), quick[:2], oracle, 1, noise=False)
    out += study.fly_condition(study.Condition(0.5, 10000.0), [lateral], oracle, 2, noise=False)
    return out


def test_the_oracle_equals_the_coefficients_jsbsim_flies_with(study, flights):
    """In-flight aerodynamic forces and moments of the F-16 with its flight-control system
    (recorded every sample) against the stripped copy at the recorded states: 1e-9."""
    for flight in flights:
        for c in study.COEFFICIENTS:
            np.testing.assert_allclose(flight.truth[c], flight.jsbsim[c], rtol=0, atol=1e-9)
    pull_up = flights[1]
    # the flights explore: α over more than 10°, all three leading-edge-flap positions,
    # the elevator over more than 3°, sideslip and roll rate in the lateral maneuver
    assert np.ptp(pull_up.true["alpha"]) > 10 * study.DEG
    assert set(np.round(pull_up.true["lef"], 4)) == {0.0, 0.262, 0.436}
    assert np.ptp(flights[0].true["de"]) > 3 * study.DEG
    assert np.ptp(flights[2].true["beta"]) > 0.3 * study.DEG
    assert np.max(np.abs(flights[2].true["p"])) > 10 * study.DEG
    assert np.ptp(flights[2].truth["Cl"]) > 0.01


def test_the_lef_schedule_is_the_flight_control_systems(study, flights):
    """The replica of the F-16's switch equals the recorded flap position, except at a
    sample just after α crossed a threshold (the flight-control system acted on the α of the
    step before): within 0.5° of 5° or 15°."""
    for flight in flights:
        alpha = flight.true["alpha"]
        expected = study.lef_schedule(alpha, flight.true["Mach"])
        differ = flight.true["lef"] != expected
        assert differ.mean() < 0.01
        near = np.min(np.abs(alpha[differ, None] - np.array([0.0873, 0.2618])), axis=1)
        assert np.all(near < 0.5 * study.DEG)


def test_the_oracle_responds_to_every_input(study, oracle):
    """Each input changes the coefficient it should (no property silently ignored), and a
    rate given as q̂ equals the same rate given in rad/s."""
    base = {"alpha": 0.1, "Mach": 0.6, "altitude_m": 6000.0, "lef": 0.0}
    c0 = oracle(base)
    moved = {
        "de": ("Cm", 0.1), "lef": ("CL", 0.436), "qhat": ("Cm", 0.01), "beta": ("CY", 0.05),
        "da": ("Cl", 0.1), "dr": ("Cn", 0.1), "phat": ("Cl", 0.05), "rhat": ("Cn", 0.05),
    }  # fmt: skip
    for name, (coefficient, step) in moved.items():
        changed = oracle({**base, name: step})
        assert abs(changed[coefficient] - c0[coefficient]) > 1e-3, name
    as_hat = oracle({**base, "qhat": 0.01})
    in_rad_s = oracle({**base, "q": 0.01 * 2 * float(oracle.fdm["ic/vt-fps"]) * 0.3048
                       / oracle.cbar_m})  # fmt: skip
    for c in study.COEFFICIENTS:
        assert as_hat[c] == pytest.approx(in_rad_s[c], rel=1e-12, abs=1e-15)
    grid = oracle({"alpha": np.zeros((2, 3)), "Mach": np.full((2, 3), 0.6)})
    assert grid["CL"].shape == (2, 3)
    with pytest.raises(study.StudyInputError, match="alpha, Mach"):
        oracle({"alpha": 0.1, "Mach": 0.5, "elevator": 0.1})
    with pytest.raises(study.StudyInputError, match="'de'.*finite"):
        oracle({"alpha": 0.1, "Mach": 0.5, "de": np.nan})
    with pytest.raises(study.StudyInputError, match="f16"):
        study.truth_oracle("c172x")


def test_noise_free_reconstruction_equals_the_truth(study, flights):
    """Noise-free motion with JSBSim's own rate derivatives: the forces are algebra (1e-10);
    the moments 1e-6: JSBSim's Euler equation uses inertial rates, the recorded rates are
    relative to the Earth (ω_E = 7.3·10⁻⁵ rad/s; measured 2·10⁻⁹ for C_m, 5·10⁻⁸ for C_n)."""
    for flight in flights:
        measured = dict(flight.measured)
        for rate in "pqr":
            measured[f"{rate}dot"] = flight.true[f"{rate}dot"]
        rebuilt = study.reconstruct(measured, flight.geometry)
        for c in ("CL", "CD", "CY"):
            np.testing.assert_allclose(rebuilt[c], flight.truth[c], rtol=0, atol=1e-10)
        for c in ("Cl", "Cm", "Cn"):
            np.testing.assert_allclose(rebuilt[c], flight.truth[c], rtol=0, atol=1e-6)


def test_reconstruction_error_is_the_noise_it_should_have(study, oracle):
    """With the study's noise, the mean squared reconstruction error of C_L, C_D against the
    first-order propagation of the noise, var δC_L = (m σ_a / q̄S)² + (C_L σ_q̄)² + (C_D σ_α)²
    (and C_L ↔ C_D), and of C_m against σ_q² Σh_k²/Δt² (Savitzky–Golay derivative weights
    h_k from scipy) times (I_y / q̄Sc̄)² plus the noise-free differentiation error: within
    ±12 % (about 4 standard errors of a mean over 1500 samples)."""
    design = study.maneuver_designs(True)[0]
    condition = study.Condition(0.6, 10000.0)
    clean = study.fly_condition(condition, [design], oracle, 7, noise=False)[0]
    noisy = study.fly_condition(condition, [design], oracle, 7, noise=True)[0]
    n = study.NOISE
    qs = noisy.true["qbar"] * noisy.geometry["S_m2"]
    CL, CD = noisy.truth["CL"], noisy.truth["CD"]
    accel = (noisy.geometry["mass_kg"] * n["accel"] / qs) ** 2
    predicted = {
        "CL": accel + (CL * n["qbar_rel"]) ** 2 + (CD * n["alpha"]) ** 2,
        "CD": accel + (CD * n["qbar_rel"]) ** 2 + (CL * n["alpha"]) ** 2,
    }
    for c, variance in predicted.items():
        mse = np.mean((noisy.coefficients[c] - noisy.truth[c]) ** 2)
        assert 0.88 < mse / np.mean(variance) < 1.12, c
    window = 2 * round(0.4 / DT / 2) + 1  # the default 0.4 s Savitzky–Golay window, odd
    h = scipy.signal.savgol_coeffs(window, 4, deriv=1, delta=DT)
    gain = noisy.geometry["Iy"] / (qs * noisy.geometry["cbar_m"])
    interior = slice(window, -window)  # the edges use other weights
    bias2 = np.mean((clean.coefficients["Cm"] - clean.truth["Cm"])[interior] ** 2)
    variance = np.mean(gain[interior] ** 2) * n["rate"] ** 2 * np.sum(h**2)
    mse = np.mean((noisy.coefficients["Cm"] - noisy.truth["Cm"])[interior] ** 2)
    assert 0.88 < mse / (bias2 + variance) < 1.12


def test_a_trim_at_each_quick_condition(study):
    """JSBSim's trim at each quick condition holds: 2 s later α within 0.05°, q within
    0.05°/s, the Mach number as set."""
    for condition in study.QUICK_CONDITIONS:
        fdm = study.trimmed_f16(condition)
        assert fdm["velocities/mach"] == pytest.approx(condition.mach, abs=1e-6)
        assert fdm["gear/gear-pos-norm"] == 0.0
        alpha0 = fdm["aero/alpha-rad"]
        for _ in range(100 * study.SUBSTEPS):
            fdm.run()
        assert abs(fdm["aero/alpha-rad"] - alpha0) < math.radians(0.05), condition
        assert abs(fdm["velocities/q-rad_sec"]) < math.radians(0.05), condition


def _prediction(value, half_width, outside):
    value = np.asarray(value, dtype=float)
    return SimpleNamespace(value=value, lower=value - half_width, upper=value + half_width,
                           outside=np.asarray(outside))  # fmt: skip


def test_interval_measures_by_hand(study):
    truth = np.array([0.0, 0.0, 0.0, 0.0, 1.0])
    # errors 0.1, 0.3, −0.1, 0.05 inside (half-width 0.2: 3 of 4 covered), 2.0 outside
    prediction = _prediction([0.1, 0.3, -0.1, 0.05, 3.0], 0.2, [0, 0, 0, 0, 1])
    m = study.interval_measures(prediction, truth)
    assert m["n"] == 5 and m["n_inside"] == 4
    assert m["coverage_inside"] == pytest.approx(0.75)
    assert m["rms_inside"] == pytest.approx(math.sqrt((0.01 + 0.09 + 0.01 + 0.0025) / 4))
    assert m["rms_outside"] == pytest.approx(2.0)
    assert m["flagged"] == pytest.approx(0.2)


def test_checks_fail_outside_the_goals(study):
    def run(cover, beyond):
        return {"held_out": {"coverage_inside": cover}, "beyond_flagged": beyond}

    results = {"runs": {"global": {"CL": run(0.95, 1.0), "CD": run(0.995, 0.95),
                                   "Cm": run(0.93, 0.5)}}}  # fmt: skip
    passed = [ok for ok, _ in study.checks(results)]
    # coverage CL, CD, Cm; then beyond-flagged CL, CD, Cm
    assert passed == [True, False, True, True, True, False]


def test_function_interval_coverage_by_hand(study):
    truth = np.array([0.0, 0.0, 0.0, 1.0])
    value = np.array([0.1, 0.3, -0.05, 3.0])
    prediction = _prediction(value, 1.0, [0, 0, 0, 1])
    # a prediction without the function interval (the model before it had one): NaN
    assert math.isnan(study.function_interval_coverage(prediction, truth))
    # half-width 0.2 about the value: errors 0.1 and −0.05 covered, 0.3 not; the fourth
    # point is outside the support and not counted
    prediction.function_lower, prediction.function_upper = value - 0.2, value + 0.2
    assert study.function_interval_coverage(prediction, truth) == pytest.approx(2 / 3)


def test_checks_use_the_function_interval_where_there_is_one(study):
    def run(pi, function):
        return {"held_out": {"coverage_inside": pi}, "held_out_function_coverage": function,
                "beyond_flagged": 1.0}  # fmt: skip

    results = {"runs": {"global": {"CL": run(1.0, 0.95), "CD": run(0.95, float("nan")),
                                   "Cm": run(0.95, 0.85)}}}  # fmt: skip
    checked = study.checks(results)
    assert [ok for ok, _ in checked[:3]] == [True, True, False]
    assert "function interval" in checked[0][1] and "prediction interval" in checked[1][1]


def test_flagged_shares_and_the_table_of_settings_tried(study):
    outside = np.array([True, False, True, True])
    assert study._flagged_share(outside, np.array([1, 1, 0, 1], dtype=bool)) == pytest.approx(2 / 3)
    assert math.isnan(study._flagged_share(outside, np.zeros(4, dtype=bool)))
    row = {"choice": "x", "coefficient": "CL", "terms": 3, "pse": 1e-4, "held_out_rms": 0.002,
           "pi_covers_truth": 0.99, "pi_covers_measured": 0.95,
           "function_covers_truth": float("nan"), "grid_rms_inside": 0.01}  # fmt: skip
    table = study.format_explored([row, {**row, "function_covers_truth": 0.93}])
    lines = table.splitlines()
    assert len(lines) == 4 and lines[2].count("|") == lines[0].count("|") == 10
    assert "| n/a |" in lines[2] and "| 0.930 |" in lines[3]


def test_the_stand_in_fitter_is_least_squares_and_flags_extrapolation(study):
    """The stand-in (the study's plumbing until the package lands): its value is the
    numpy least-squares fit of the same monomials; points far beyond the data are flagged."""
    rng = np.random.default_rng(3)
    n = 600
    signals = {"alpha": rng.uniform(-0.05, 0.3, n), "Mach": rng.uniform(0.3, 0.9, n),
               "de": rng.uniform(-0.1, 0.05, n), "qhat": rng.uniform(-0.01, 0.01, n)}  # fmt: skip
    signals["CL"] = (
        0.1 + 4.0 * signals["alpha"] - 3.0 * signals["alpha"] ** 2 + 0.01 * rng.standard_normal(n)
    )
    orders = {"alpha": 2, "Mach": 1, "de": 1, "qhat": 1}
    settings = study.StandInSettings(orders=orders, max_order=2, decimate=1)
    model = study.stand_in_fitter(signals, {"CL": "CL"}, ["alpha", "Mach", "de", "qhat"],
                                  settings=settings, maneuver_index=np.repeat([0, 1, 2], n // 3),
                                  dt=0.02)  # fmt: skip
    a, m, d, q = (signals[k] for k in ("alpha", "Mach", "de", "qhat"))
    columns = [np.ones(n), a, m, d, q, a * a, a * m, a * d, a * q, m * d, m * q, d * q]
    theta = np.linalg.lstsq(np.column_stack(columns), signals["CL"], rcond=None)[0]
    points = {"alpha": np.array([0.1, 0.7]), "Mach": np.array([0.5, 0.5]),
              "de": np.zeros(2), "qhat": np.zeros(2)}  # fmt: skip
    x = {k: v for k, v in points.items()}
    expected = np.column_stack([np.ones(2), x["alpha"], x["Mach"], x["de"], x["qhat"],
                                x["alpha"] ** 2, x["alpha"] * x["Mach"], x["alpha"] * x["de"],
                                x["alpha"] * x["qhat"], x["Mach"] * x["de"],
                                x["Mach"] * x["qhat"], x["de"] * x["qhat"]]) @ theta  # fmt: skip
    prediction = model.predict(points)["CL"]
    np.testing.assert_allclose(prediction.value, expected, rtol=1e-9, atol=1e-12)
    assert list(prediction.outside) == [False, True]
    assert np.all(prediction.lower < prediction.value) and np.all(
        prediction.value < prediction.upper
    )


def _docs_numbers():
    path = Path(__file__).resolve().parents[1] / "docs" / "docs_numbers.py"
    spec = importlib.util.spec_from_file_location("docs_numbers_for_study", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_quick_study_runs_end_to_end_with_the_stand_in(study, oracle, tmp_path, capsys):
    """The command line with the stand-in fitter: the guide line first, one numbers region
    the docs' parser reads, a PASS/FAIL line per target, the carpets (the truth there is the
    oracle's at the grid point) and the written maneuvers (reconstructed coefficients beside
    the truth)."""
    carpets, data = tmp_path / "carpets.json", tmp_path / "data"
    code = study.main(
        ["--quick", "--stand-in", "--carpets", str(carpets), "--write-data", str(data)]
    )
    out = capsys.readouterr().out
    assert out.splitlines()[0] == "<!-- guide: docs/globalmodel.md -->"
    regions = _docs_numbers().regions(out)
    assert list(regions) == ["globalmodel-jsbsim"]
    verdicts = [line for line in out.splitlines() if line.startswith(("PASS ", "FAIL "))]
    assert len(verdicts) == 6
    assert code == (0 if all(v.startswith("PASS") for v in verdicts) else 1)
    document = json.loads(carpets.read_text(encoding="utf-8"))
    alpha_deg, mach = document["alpha_deg"], document["Mach"]
    cl = document["coefficients"]["global"]["CL"]
    assert np.shape(cl["value"]) == (len(mach), len(alpha_deg))
    i, j = 2, 30
    point = {"alpha": math.radians(alpha_deg[j]), "Mach": mach[i],
             "de": document["de_rad"][i][j], "qhat": 0.0}  # fmt: skip
    assert cl["truth"][i][j] == pytest.approx(float(oracle(point)["CL"]), abs=1e-12)
    # the stand-in's cubic far beyond the data: every such grid point flagged
    beyond = np.asarray(alpha_deg) > document["alpha_data_max_deg"] + 5
    assert np.all(np.asarray(cl["outside"])[:, beyond])
    index = json.loads((data / "flights.json").read_text(encoding="utf-8"))
    assert len(index) == 18 and sum(f["held_out"] for f in index) == 6
    table = np.genfromtxt(data / index[0]["file"], delimiter=",", names=True)
    assert np.ptp(table["truth_CL"]) > 0.05
    # written at 10 Hz (every 5th sample of the 50 Hz recording)
    np.testing.assert_allclose(np.diff(table["time_s"]), 0.1, atol=1e-9)
    # the written coefficients are the reconstruction from noisy motion: near the truth
    # column (the study's noise gives an RMS of about 0.003), never equal to it
    rms = np.sqrt(np.mean((table["CL"] - table["truth_CL"]) ** 2))
    assert 1e-4 < rms < 0.01
