"""Prediction, simulation and linearization from the frequency-domain and recursive results:
the same calls as an ``Estimate`` (``predict``, ``simulate``, ``linearize``), answered by the
same functions of ``flightid.simulation.prediction``.

References: ``flightid.simulate`` of a model built here with the result's values (the
prediction must equal it to rounding), output bands from sensitivities differenced here over
``flightid.simulate`` runs (σ_y² = diag S P Sᵀ), and the closed-form A, B of the linear
short-period model.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pytest

import flightid
from flightid.cases import load_case
from flightid.cases.frequency_case import run_frequency_case
from flightid.data.flightdata import FlightData
from flightid.model.parameters import Parameters
from flightid.model.statespace import StateSpaceModel
from flightid.recursive import (
    AugmentedModel,
    ExtendedForgettingRLS,
    ExtendedKalmanFilter,
    FourierTransformRegression,
    run_recursive,
)
from flightid.simulation.prediction import Prediction, PredictionError, PredictionWarning

NAMES = ("Za", "Zde", "Ma", "Mq", "Mde")
TRUE = {"Za": -1.2, "Zde": -0.15, "Ma": -6.0, "Mq": -1.8, "Mde": -8.0}
DT = 0.02
TIME = np.arange(0.0, 20.0, DT)
NOISE = (2e-4, 5e-4)

_MODULE = """
import numpy as np

STATES = ("alpha", "q")
INPUTS = ("de",)
OUTPUTS = ("alpha", "q")
PARAMETERS = {"Za": -1.0, "Zde": -0.1, "Ma": -5.0, "Mq": -1.5, "Mde": -7.0}


def f(t, x, u, th):
    dx = np.empty(2)
    dx[0] = th[0] * x[0] + x[1] + th[1] * u[0]
    dx[1] = th[2] * x[0] + th[3] * x[1] + th[4] * u[0]
    return dx


def h(t, x, u, th):
    return np.array([x[0], x[1]])
"""


def short_period_f(t, x, u, th):
    dx = np.empty(2)
    # α̇ = Z_α α + q + Z_δe δe
    dx[0] = th[0] * x[0] + x[1] + th[1] * u[0]
    # q̇ = M_α α + M_q q + M_δe δe
    dx[1] = th[2] * x[0] + th[3] * x[1] + th[4] * u[0]
    return dx


def short_period_h(t, x, u, th):
    return np.array([x[0], x[1]])


def short_period(values, x0=(0.0, 0.0)) -> StateSpaceModel:
    return StateSpaceModel(
        ("alpha", "q"),
        ("de",),
        ("alpha", "q"),
        short_period_f,
        short_period_h,
        Parameters({n: float(values[n]) for n in NAMES}),
        x0=tuple(float(v) for v in x0),
    )


def elevator(phase_seed: int) -> np.ndarray:
    """A multisine on 0.1–2 Hz (rad), random phases from the seed."""
    freqs = np.arange(1, 21) * 0.1
    phases = np.random.default_rng(phase_seed).uniform(0, 2 * np.pi, freqs.size)
    return 0.01 * np.sin(2 * np.pi * freqs[None, :] * TIME[:, None] + phases).sum(axis=1) / 3


def maneuver(seed: int, name: str) -> FlightData:
    """The true model's response to a multisine, with seeded white noise."""
    de = elevator(seed)
    silent = FlightData(TIME, {"de": de}, {"alpha": 0 * TIME, "q": 0 * TIME})
    y = flightid.simulate(short_period(TRUE), silent)
    z = y + np.random.default_rng(seed).normal(0.0, NOISE, y.shape)
    return FlightData(
        TIME,
        {"de": de},
        {"alpha": z[:, 0], "q": z[:, 1]},
        name=name,
        units={"alpha": "rad", "q": "rad/s", "de": "rad"},
    )


HELD_OUT = maneuver(7, "held out")


def reference_output(values, data: FlightData) -> np.ndarray:
    """flightid.simulate of a model built here, from the data's first samples."""
    start = (data.output("alpha")[0], data.output("q")[0])
    return flightid.simulate(short_period(values, start), data)


def direct_band(values, covariance: np.ndarray, data: FlightData) -> np.ndarray:
    """σ_y = √diag(S P Sᵀ), S by central differences of flightid.simulate runs here."""
    base = dict(values)
    columns = []
    for name in NAMES:
        step = 1e-5 * max(abs(base[name]), 1e-3)
        up = reference_output({**base, name: base[name] + step}, data)
        down = reference_output({**base, name: base[name] - step}, data)
        columns.append((up - down) / (2 * step))
    s = np.stack(columns, axis=-1)  # (N, n_o, n_p)
    return np.sqrt(np.einsum("koa,ab,kob->ko", s, covariance, s))


def write_case(directory: Path, method: str = "output_error") -> Path:
    data = maneuver(1, "estimation")
    rows = np.column_stack([TIME, data.input("de"), data.output("alpha"), data.output("q")])
    np.savetxt(directory / "sp.csv", rows, delimiter=",", header="t,de,alpha,q", comments="")
    (directory / "sp.py").write_text(_MODULE)
    path = directory / f"{method}.toml"
    path.write_text(
        f"""title = "short period"
[data]
data_dir = "."
file = "sp.csv"
time = "t"
[data.inputs]
de = {{ column = "de" }}
[data.outputs]
alpha = {{ column = "alpha" }}
q = {{ column = "q" }}
[model]
module = "sp.py"
[initial_state]
default = 0.0
[frequency_domain]
method = "{method}"
band_hz = [0.1, 2.0]
step_hz = 0.05
"""
    )
    return path


@pytest.fixture(scope="module")
def frequency(tmp_path_factory):
    result = run_frequency_case(load_case(write_case(tmp_path_factory.mktemp("fd"))))
    assert result.converged, result.message
    return result


@pytest.fixture(scope="module")
def ekf():
    data = maneuver(1, "estimation")
    augmented = AugmentedModel(short_period(short_period_start()), [0.0, 0.0], compiled=False)
    filter_ = ExtendedKalmanFilter(augmented, 10.0, [1e-12, 1e-12], np.square(NOISE), 1e-5)
    z = np.column_stack([data.output("alpha"), data.output("q")])
    return run_recursive(filter_, TIME, data.input("de")[:, None], z)


def short_period_start() -> dict:
    return {"Za": -1.0, "Zde": -0.1, "Ma": -5.0, "Mq": -1.5, "Mde": -7.0}


def _values(names, values) -> dict:
    return dict(zip(names, np.asarray(values, dtype=float), strict=True))


# ---------------------------------------------------------------- frequency domain


def test_frequency_result_predicts_a_held_out_maneuver_as_flightid_simulate(frequency):
    values = _values(frequency.names, frequency.values)
    # the estimate is near the truth (else the prediction below would prove little)
    for name in NAMES:
        assert abs(values[name] - TRUE[name]) < 0.05 * abs(TRUE[name]), name
    prediction = frequency.predict(HELD_OUT)
    assert isinstance(prediction, Prediction) and prediction.predicted_std is None
    reference = reference_output(values, HELD_OUT)
    np.testing.assert_allclose(prediction.predicted, reference, rtol=0, atol=1e-10)
    assert np.all(prediction.r2 > 0.99)
    simulated = frequency.simulate(HELD_OUT)
    np.testing.assert_allclose(simulated, reference, rtol=0, atol=1e-10)
    both = frequency.predict([HELD_OUT, maneuver(8, "second")])
    assert isinstance(both, tuple) and len(both) == 2


def test_frequency_bands_are_s_p_st_of_its_coloured_covariance(frequency):
    values = _values(frequency.names, frequency.values)
    # the covariance behind the reported σ
    np.testing.assert_allclose(np.sqrt(np.diag(frequency.covariance)), frequency.std, rtol=1e-12)
    band = frequency.predict(HELD_OUT, bands=True).predicted_std
    np.testing.assert_allclose(band, direct_band(values, frequency.covariance, HELD_OUT), rtol=1e-4)
    cr = frequency.predict(HELD_OUT, bands=True, std="cr").predicted_std
    direct_cr = direct_band(values, frequency.covariance_cr, HELD_OUT)
    np.testing.assert_allclose(cr, direct_cr, rtol=1e-4)


def test_frequency_linearize_gives_the_identified_a_and_b(frequency):
    v = _values(frequency.names, frequency.values)
    linear = frequency.linearize()
    # A = [[Z_α, 1], [M_α, M_q]],  B = [[Z_δe], [M_δe]]
    np.testing.assert_allclose(linear.A, [[v["Za"], 1.0], [v["Ma"], v["Mq"]]], rtol=1e-8)
    np.testing.assert_allclose(linear.B, [[v["Zde"]], [v["Mde"]]], rtol=1e-8)
    sigma = _values(frequency.names, frequency.std)
    # entries linear in θ: σ(A_11) = σ(Z_α), σ(B_21) = σ(M_δe)
    assert linear.block_std("A")[0, 0] == pytest.approx(sigma["Za"], rel=1e-5)
    assert linear.block_std("B")[1, 0] == pytest.approx(sigma["Mde"], rel=1e-5)
    assert linear.notes == ()
    assert linear.output_units == ("rad", "rad/s") or linear.output_units == ("", "")


def test_frequency_equation_error_has_no_band_and_says_why(tmp_path):
    result = run_frequency_case(load_case(write_case(tmp_path, "equation_error")))
    with pytest.raises(PredictionError, match="equation error .* no joint parameter covariance"):
        result.predict(HELD_OUT, bands=True)
    values = _values(result.names, result.values)
    np.testing.assert_allclose(
        result.predict(HELD_OUT).predicted, reference_output(values, HELD_OUT), atol=1e-10
    )
    linear = result.linearize()
    assert linear.covariance is None
    assert any("no σ of the entries: frequency-domain equation error" in n for n in linear.notes)


# ---------------------------------------------------------------- recursive


def test_ekf_result_predicts_a_held_out_maneuver_as_flightid_simulate(ekf):
    values = _values(ekf.parameter_names, ekf.values)
    for name in NAMES:
        assert abs(values[name] - TRUE[name]) < 0.05 * abs(TRUE[name]), name
    prediction = ekf.predict(HELD_OUT)
    reference = reference_output(values, HELD_OUT)
    np.testing.assert_allclose(prediction.predicted, reference, rtol=0, atol=1e-10)
    np.testing.assert_allclose(ekf.simulate(HELD_OUT), reference, rtol=0, atol=1e-10)
    # given initial states replace the first samples
    given = ekf.predict(HELD_OUT, x0={"alpha": 0.01, "q": 0.0})
    start = flightid.simulate(short_period(values, (0.01, 0.0)), HELD_OUT)
    np.testing.assert_allclose(given.predicted, start, rtol=0, atol=1e-10)


def test_ekf_bands_are_s_p_st_of_the_final_filter_covariance(ekf):
    # the covariance is the last P̂'s parameter block: its σ are the last filtered σ
    np.testing.assert_allclose(np.sqrt(np.diag(ekf.covariance)), ekf.last_filtered_std, rtol=1e-12)
    values = _values(ekf.parameter_names, ekf.values)
    band = ekf.predict(HELD_OUT, bands=True).predicted_std
    np.testing.assert_allclose(band, direct_band(values, ekf.covariance, HELD_OUT), rtol=1e-4)


def test_ekf_linearize_gives_the_identified_a_and_b_and_modes(ekf):
    v = _values(ekf.parameter_names, ekf.values)
    linear = ekf.linearize()
    np.testing.assert_allclose(linear.A, [[v["Za"], 1.0], [v["Ma"], v["Mq"]]], rtol=1e-8)
    np.testing.assert_allclose(linear.B, [[v["Zde"]], [v["Mde"]]], rtol=1e-8)
    assert linear.block_std("A")[1, 1] == pytest.approx(np.sqrt(ekf.covariance[3, 3]), rel=1e-5)
    (mode,) = linear.modes()
    # λ² − (Z_α + M_q) λ + (Z_α M_q − M_α) = 0:  ω_n² = Z_α M_q − M_α, 2ζω_n = −(Z_α + M_q)
    wn = np.sqrt(v["Za"] * v["Mq"] - v["Ma"])
    assert mode.natural_frequency == pytest.approx(wn, rel=1e-8)
    assert mode.damping_ratio == pytest.approx(-(v["Za"] + v["Mq"]) / (2 * wn), rel=1e-8)
    assert np.isfinite(mode.natural_frequency_std) and mode.natural_frequency_std > 0


def test_efrls_result_predicts_but_has_no_band():
    data = maneuver(1, "estimation")
    augmented = AugmentedModel(short_period(short_period_start()), [0.0, 0.0], compiled=False)
    z = np.column_stack([data.output("alpha"), data.output("q")])
    result = run_recursive(
        ExtendedForgettingRLS(augmented, 1e3, 0.998, 1e-7), TIME, data.input("de")[:, None], z
    )
    assert result.covariance is None
    with pytest.raises(PredictionError, match="EFRLS gives no parameter covariance"):
        result.predict(HELD_OUT, bands=True)
    values = _values(result.parameter_names, result.values)
    np.testing.assert_allclose(
        result.predict(HELD_OUT).predicted, reference_output(values, HELD_OUT), atol=1e-10
    )
    linear = result.linearize()
    assert linear.covariance is None and np.isnan(linear.block_std("A")).all()
    assert any("EFRLS gives no parameter covariance" in n for n in linear.notes)


def test_ftr_result_has_no_model_to_predict_with():
    data = maneuver(1, "estimation")
    ftr = FourierTransformRegression(2, 1, np.arange(0.1, 2.0, 0.05), 250)
    z = np.column_stack([data.output("alpha"), data.output("q")])
    result = run_recursive(ftr, TIME, data.input("de")[:, None], z, report="final")
    for call in (lambda: result.predict(HELD_OUT), lambda: result.simulate(HELD_OUT)):
        with pytest.raises(PredictionError, match="holds no state-space model"):
            call()
    with pytest.raises(PredictionError, match="holds no state-space model"):
        result.linearize()


# ---------------------------------------------------------------- shipped cases

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("FLIGHTID_DATA", ROOT / "../shared/data"))
needs_data = pytest.mark.skipif(
    not (DATA / "fvsysid").is_dir(), reason=f"book data not found at {DATA} (set FLIGHTID_DATA)"
)


@needs_data
def test_shipped_short_period_cases_give_the_same_short_period_mode():
    from flightid.cases.recursive_case import run_recursive_case
    from flightid.cases.run import run_case

    cases = ROOT / "examples/cases"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        oe = run_case(load_case(cases / "attas_short_period.toml"), accuracy="none")
    first = oe.maneuvers[0]
    reference = oe.estimate.linearize(at=first).modes()["short period"]
    frequency = run_frequency_case(load_case(cases / "attas_short_period_frequency_domain.toml"))
    with pytest.warns(PredictionWarning, match="'Z0'.*'M0'"):
        fd = frequency.linearize(at=first).modes()["short period"]
    rec = run_recursive_case(load_case(cases / "attas_short_period_recursive_ekf.toml"))
    ekf = rec.linearize(at=first).modes()["short period"]
    for mode in (fd, ekf):
        # within 3 combined σ of the output-error mode, each σ finite
        for q in ("natural_frequency", "damping_ratio"):
            sigma = np.hypot(getattr(mode, q + "_std"), getattr(reference, q + "_std"))
            assert abs(getattr(mode, q) - getattr(reference, q)) < 3 * sigma, (q, mode)
    prediction = rec.predict(first, bands=True)
    assert np.all(prediction.r2 > 0.98) and np.all(prediction.predicted_std[1:] > 0)
