"""Input design (issue 17): generators, predicted Cramér–Rao bounds, the optimiser's limits,
the [design] case table and ``flightid design``.

Reference values and their sources:
* orthogonality of distinct harmonics over one period: ∫₀ᵀ cos(2πkt/T+a) cos(2πlt/T+b) dt = 0
  for k ≠ l, and the same sum over N = T/Δt uniform samples (k + l < N) — closed form;
* RPF = (max − min)/(2√2 rms) = 1 for a sinusoid and 1/√2 for a square wave — closed form;
* 3-2-1-1 widths (3, 2, 1, 1)Δt with signs (+, −, +, −), Δt = 0.3/f_n (Plaetschke & Schulz);
* predicted bounds of y = θ₁u₁ + θ₂u₂ + e: C = σ²(UᵀU)⁻¹ (linear least squares, closed form);
  of ẋ = a x + b u, y = x + e under a step u₀ from x = 0: the sensitivities in closed form,
  ∂x/∂b = u₀(e^{at} − 1)/a, ∂x/∂a = b u₀ (t e^{at}/a − (e^{at} − 1)/a²);
* Monte Carlo: seeded (numpy default_rng), least squares written here / flightid's estimator.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from data_paths import needs_data
from flightid.cases import load_case
from flightid.cases.checks import CaseError
from flightid.data.flightdata import FlightData
from flightid.design.information import criterion_value, predict_accuracy
from flightid.design.multisine import assign_harmonics, design_multisine, schroeder_phases
from flightid.design.optimize import DesignProblem, InputSpec, design_input, trim_state
from flightid.design.signals import (
    doublet,
    natural_frequency_hz,
    pulse_width_s,
    relative_peak_factor,
    three_two_one_one,
    two_one_one,
)
from flightid.errors import InputError
from flightid.model.parameters import Parameter, Parameters
from flightid.model.statespace import StateSpaceModel
from flightid.simulation import simulate

# ------------------------------------------------------------------------------- signals


def test_multisine_inputs_are_mutually_orthogonal_over_one_period():
    period, dt = 20.0, 0.04
    multisine = design_multisine(("a", "b", "c"), period, (0.1, 2.0), [1.0, 0.5, 2.0])
    # harmonics dealt alternately: no frequency shared, together they fill the band
    k = [set(h.tolist()) for h in multisine.harmonics]
    assert not (k[0] & k[1] or k[0] & k[2] or k[1] & k[2])
    assert sorted(k[0] | k[1] | k[2]) == list(range(2, 41))
    t = np.arange(int(round(period / dt))) * dt  # one period, N = 500 samples
    u = multisine.signals(t)
    gram = u.T @ u
    norms = np.sqrt(np.diag(gram))
    cosine = gram / np.outer(norms, norms)
    # closed form: inner products of distinct harmonics vanish over a period
    np.testing.assert_allclose(cosine - np.eye(3), 0.0, atol=1e-12)
    # and each input starts at zero and peaks at its amplitude
    np.testing.assert_allclose(u[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.max(np.abs(u), axis=0), [1.0, 0.5, 2.0], rtol=0.02)
    assert np.all(np.max(np.abs(u), axis=0) <= np.array([1.0, 0.5, 2.0]) + 1e-15)


def test_one_band_per_input_must_not_share_harmonics():
    with pytest.raises(InputError, match=r"band_hz\[b\]: shares harmonics"):
        design_multisine(("a", "b"), 10.0, [(0.1, 1.0), (0.5, 1.5)], [1.0, 1.0])
    with pytest.raises(InputError, match="fewer than the 3 inputs"):
        assign_harmonics(3, 10.0, (0.1, 0.25))


def test_relative_peak_factor_closed_forms():
    t = np.arange(1000) / 1000.0
    # sinusoid: (2A) / (2√2 · A/√2) = 1
    assert relative_peak_factor(0.7 * np.cos(2 * np.pi * 3 * t)) == pytest.approx(1.0, abs=1e-12)
    # square wave: 2A / (2√2 A) = 1/√2
    square = np.where(t < 0.5, 1.0, -1.0)
    assert relative_peak_factor(square) == pytest.approx(1 / np.sqrt(2), abs=1e-12)
    with pytest.raises(InputError, match="zero everywhere"):
        relative_peak_factor(np.zeros(5))


def test_schroeder_formula_and_optimised_peak_factor_not_above_schroeder():
    # φ_i = −π i(i − 1)/M
    np.testing.assert_allclose(schroeder_phases(4), [0.0, -np.pi / 2, -3 * np.pi / 2, -3 * np.pi])
    for names, period, band in ((("de",), 20.0, (0.1, 2.0)), (("da", "dr"), 24.0, (0.1, 1.5))):
        multisine = design_multisine(names, period, band, [1.0] * len(names))
        for optimised, schroeder in zip(multisine.rpf, multisine.rpf_schroeder, strict=True):
            assert optimised <= schroeder
            assert optimised < 1.15  # measured 1.01–1.03 here; Schroeder 1.25–1.34
        # the peak factor recomputed independently on a fine grid of one period
        t = np.linspace(0.0, period, 20001)
        u = multisine.unit_signals(t)
        for j in range(len(names)):
            span = u[:, j].max() - u[:, j].min()
            rms = np.sqrt(np.mean(u[:-1, j] ** 2))
            assert span / (2 * np.sqrt(2) * rms) == pytest.approx(multisine.rpf[j], rel=2e-3)


def _runs(u: np.ndarray) -> list[tuple[int, float]]:
    """(length, value) of each run of equal non-zero samples."""
    runs, k = [], 0
    while k < u.size:
        j = k
        while j < u.size and u[j] == u[k]:
            j += 1
        if u[k] != 0:
            runs.append((j - k, float(u[k])))
        k = j
    return runs


def test_step_sequences_pulse_widths_and_signs():
    t = np.arange(0.0, 10.0, 0.05)
    # Δt = 0.4 s = 8 samples
    assert _runs(three_two_one_one(t, 1.0, 0.4, 0.1)) == [
        (24, 0.1),
        (16, -0.1),
        (8, 0.1),
        (8, -0.1),
    ]
    assert _runs(two_one_one(t, 1.0, 0.4, 0.1)) == [(16, 0.1), (8, -0.1), (8, 0.1)]
    assert _runs(doublet(t, 1.0, 0.4, -0.2)) == [(8, -0.2), (8, 0.2)]
    # the 3-2-1-1 starts at t = 1 s exactly (sample 20)
    assert np.flatnonzero(three_two_one_one(t, 1.0, 0.4, 0.1))[0] == 20
    # Plaetschke & Schulz: Δt = 0.3 / f_n; doublet half period 1/(2 f_n)
    assert pulse_width_s("3211", 0.5) == pytest.approx(0.6)
    assert pulse_width_s("doublet", 0.5) == pytest.approx(1.0)


def test_natural_frequency_of_a_second_order_system():
    omega, zeta = 3.0, 0.4

    def f(t, x, u, theta):
        # ẍ + 2ζω ẋ + ω² x = u
        return np.array([x[1], -(omega**2) * x[0] - 2 * zeta * omega * x[1] + u[0]])

    f_n = natural_frequency_hz(f, np.zeros(2), np.zeros(1), np.zeros(0))
    # |λ| = ω for the complex pair
    assert f_n == pytest.approx(omega / (2 * np.pi), rel=1e-6)


# ------------------------------------------------------------------- predicted accuracy


def _static_model(theta=(1.5, -0.8)) -> StateSpaceModel:
    def h(t, x, u, p):
        # y = θ₁u₁ + θ₂u₂
        return np.array([p[0] * u[0] + p[1] * u[1]])

    return StateSpaceModel((), ("u1", "u2"), ("y",), None, h, {"t1": theta[0], "t2": theta[1]})


def test_predicted_bounds_of_a_linear_regression_closed_form_and_monte_carlo():
    rng = np.random.default_rng(11)
    n, sigma = 200, 0.05
    t = np.arange(n) * 0.02
    u = np.column_stack([np.sin(3 * t) + 0.3, rng.uniform(-1, 1, n)])
    model = _static_model()
    predicted = predict_accuracy(model, FlightData(t, {"u1": u[:, 0], "u2": u[:, 1]}), {"y": sigma})
    # closed form: C = σ²(UᵀU)⁻¹
    closed = sigma**2 * np.linalg.inv(u.T @ u)
    # (forward-difference Jacobians inside the sensitivity equations: ~1e-8 relative)
    np.testing.assert_allclose(predicted.covariance, closed, rtol=1e-6)
    # Monte Carlo: 2000 seeded least-squares fits (written here, independent of flightid)
    truth = np.array([1.5, -0.8])
    noise = np.random.default_rng(12).normal(0.0, sigma, (2000, n))
    estimates = np.linalg.lstsq(u, (u @ truth)[:, None] + noise.T, rcond=None)[0].T
    realised = estimates.std(axis=0, ddof=1)
    # 2000 runs: the σ estimate's own relative spread is 1/√(2·1999) ≈ 1.6 %
    np.testing.assert_allclose(realised, predicted.std, rtol=0.06)
    np.testing.assert_allclose(
        np.corrcoef(estimates.T)[0, 1], predicted.correlation[0, 1], atol=0.06
    )


def _lag_f(t, x, u, p):
    # ẋ = a x + b₁u₁ + b₂u₂
    return np.array([p[0] * x[0] + p[1] * u[0] + p[2] * u[1]])


def _lag_h(t, x, u, p):
    return np.array([x[0]])


def _lag_model(a=-1.2, b1=0.8, b2=0.5, b2_free=True) -> StateSpaceModel:
    """A first-order lag with two inputs (one model, so one compiled kernel, for the tests)."""
    parameters = Parameters(
        [Parameter("a", a), Parameter("b1", b1), Parameter("b2", b2, free=b2_free)]
    )
    return StateSpaceModel(("x",), ("u1", "u2"), ("y",), _lag_f, _lag_h, parameters, x0=(0.0,))


def test_predicted_bounds_of_a_first_order_system_closed_form_and_estimator_monte_carlo():
    from flightid.estimation import estimate

    a, b, u0, sigma = -1.2, 0.8, 1.0, 0.02
    t = np.arange(0.0, 6.0 + 1e-9, 0.02)
    step = np.where(t > 0.5 - 1e-9, u0, 0.0)
    idle = np.zeros_like(t)  # u₂ = 0 and b₂ fixed: ẋ = a x + b u
    data = FlightData(t, {"u1": step, "u2": idle})
    model = _lag_model(a, b, b2_free=False)
    predicted = predict_accuracy(model, data, {"y": sigma}, input_interpolation="zoh")
    # closed form after the step at t₀ = 0.5 s (τ = t − t₀ ≥ 0), zero before
    tau = np.clip(t - 0.5, 0.0, None)
    e = np.exp(a * tau)
    g_b = u0 * (e - 1) / a
    g_a = b * u0 * (tau * e / a - (e - 1) / a**2)
    g = np.column_stack([g_a, g_b])
    closed = sigma**2 * np.linalg.inv(g.T @ g)
    np.testing.assert_allclose(predicted.covariance, closed, rtol=1e-6)
    # Monte Carlo with flightid's output-error estimator: 150 seeded noise draws
    clean = simulate(model, data, input_interpolation="zoh")[:, 0]
    rng = np.random.default_rng(21)
    estimates = []
    for _ in range(150):
        noisy = FlightData(
            t, {"u1": step, "u2": idle}, {"y": clean + rng.normal(0.0, sigma, t.size)}
        )
        result = estimate(model, noisy, noise="fixed", R=[sigma**2], input_interpolation="zoh")
        estimates.append(result.values[:2])  # a, b₁ (b₂ is fixed)
    realised = np.std(np.array(estimates), axis=0, ddof=1)
    # 150 runs: σ's own relative spread ≈ 1/√298 ≈ 6 %; 15 % is 2.5 of it
    np.testing.assert_allclose(realised, predicted.std, rtol=0.15)


def test_criteria_values():
    rng = np.random.default_rng(3)
    t = np.arange(100) * 0.02
    data = FlightData(t, {"u1": rng.normal(size=100), "u2": rng.normal(size=100)})
    predicted = predict_accuracy(_static_model(), data, {"y": 0.1})
    m, c = predicted.information, predicted.covariance
    assert criterion_value(predicted, "d_optimal") == pytest.approx(-np.log(np.linalg.det(m)))
    relative = np.diag(c) / np.array([1.5, 0.8]) ** 2
    assert criterion_value(predicted, "a_optimal") == pytest.approx(relative.sum())
    assert criterion_value(predicted, "parameters", ["t2"]) == pytest.approx(relative[1])
    with pytest.raises(InputError, match=r"\['t3'\] are not free parameters"):
        criterion_value(predicted, "parameters", ["t3"])


def test_an_input_that_leaves_a_parameter_undetermined_is_named():
    t = np.arange(100) * 0.02
    data = FlightData(t, {"u1": np.sin(t), "u2": np.zeros(100)})
    with pytest.raises(InputError, match=r"\['t2'\] undetermined"):
        predict_accuracy(_static_model(), data, {"y": 0.1})


# -------------------------------------------------------------------------- optimiser


def _short_period(values=None) -> StateSpaceModel:
    """A linear short-period model (ATTAS-like numbers), trimmed at δe = 0."""

    def f(t, x, u, p):
        # α̇ = Z_α α + (1 + Z_q) q + Z_δe δe;  q̇ = M_α α + M_q q + M_δe δe
        return np.array(
            [p[0] * x[0] + (1 + p[1]) * x[1] + p[2] * u[0], p[3] * x[0] + p[4] * x[1] + p[5] * u[0]]
        )

    def h(t, x, u, p):
        return np.array([x[0], x[1]])

    names = ("Za", "Zq", "Zde", "Ma", "Mq", "Mde")
    numbers = values or (-0.48, 0.10, -0.68, -4.9, -2.0, -7.2)
    return StateSpaceModel(
        ("alpha", "q"), ("de",), ("alpha", "q"), f, h, dict(zip(names, numbers, strict=True)),
        x0=(0.0, 0.0),
    )  # fmt: skip


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_optimiser_never_returns_an_input_outside_its_limits(seed):
    rng = np.random.default_rng(seed)
    signal = ["multisine", "3211", "211", "doublet"][seed - 1]
    amplitude = float(rng.uniform(0.01, 0.08))
    duration = float(rng.uniform(8.0, 16.0))
    limits = {"alpha": float(rng.uniform(0.005, 0.05)), "q": float(rng.uniform(0.01, 0.1))}
    problem = DesignProblem(
        _short_period(),
        (InputSpec("de", amplitude, 0.0, (0.1, 1.5)),),
        duration,
        0.05,
        {"alpha": 0.002, "q": 0.003},
        signal=signal,
        criterion=["d_optimal", "a_optimal", "parameters", "d_optimal"][seed - 1],
        parameters=("Ma", "Mq") if seed == 3 else (),
        limits=limits,
        candidates=3,
    )
    best, tried = design_input(problem)
    assert best.criterion_value == min(c.criterion_value for c in tried)
    for candidate in tried:
        # the limits checked independently: the input's samples, its length, and a fresh
        # simulation of the response against the one with the input at trim
        assert np.max(np.abs(candidate.perturbations)) <= amplitude * (1 + 1e-12)
        assert candidate.time[-1] <= duration + 1e-9
        y = simulate(problem.model, problem.flight_data(candidate.perturbations))
        y0 = simulate(problem.model, problem.flight_data(0 * candidate.perturbations))
        peak = np.max(np.abs(y - y0), axis=0)
        assert peak[0] <= limits["alpha"] * (1 + 1e-9)
        assert peak[1] <= limits["q"] * (1 + 1e-9)
    # a limit that binds is used up to within 1 % (the design does not waste amplitude)
    ratio = max(best.response_peak[o] / limits[o] for o in limits)
    assert best.amplitude_factors == (1.0,) or ratio > 0.99


def test_trim_state_is_the_equilibrium():
    model = _short_period()

    def with_bias(t, x, u, p):
        return model.f(t, x, u, p) + np.array([0.01, 0.2])

    biased = replace(model, f=with_bias)
    x = trim_state(biased, {"de": 0.04})
    np.testing.assert_allclose(
        biased.f(0.0, x, np.array([0.04]), biased.parameters.values), 0.0, atol=1e-12
    )


# ---------------------------------------------------------------------- case and CLI

_CASE = """
title = "design checks"
[data]
files = ["fvsysid/fAttasElv1.mat"]
time = 1
[data.inputs]
de = {{ column = 22, unit = "deg", to = "rad" }}
[data.outputs]
alpha = {{ column = 13, unit = "deg", to = "rad" }}
q = {{ column = 8, unit = "deg/s", to = "rad/s" }}
[model]
module = "{module}"
[design]
{design}
"""


def _case(tmp_path, design: str):
    from pathlib import Path

    module = Path(__file__).resolve().parents[1] / "examples" / "models" / "attas_short_period.py"
    path = tmp_path / "case.toml"
    path.write_text(_CASE.format(module=module.as_posix(), design=design), encoding="utf-8")
    return load_case(path)


@pytest.mark.parametrize(
    ("design", "message"),
    [
        ("duration_s = 10.0\ndt_s = 0.04\nnoise_std = {alpha = 0.001, q = 0.001}\n"
         "inputs = {de = {amplitude = 0.01}}\nband_hz = [0.1, 2]\nwobble = 1",
         r"design\.wobble: unknown key"),
        ("duration_s = 10.0\ndt_s = 0.04\nnoise_std = {alpha = 0.001}\n"
         "inputs = {de = {amplitude = 0.01}}\nband_hz = [0.1, 2]",
         r"design\.noise_std: missing σ for the model outputs \['q'\]"),
        ("duration_s = 10.0\ndt_s = 0.04\nnoise_std = {alpha = 0.001, q = 0.001}\n"
         "inputs = {de = {amplitude = 0.01}}\nsignal = \"chirp\"",
         r"design\.signal: expected one of"),
        ("duration_s = 10.0\ndt_s = 0.04\nnoise_std = {alpha = 0.001, q = 0.001}\n"
         "inputs = {de = {amplitude = -0.01}}\nband_hz = [0.1, 2]",
         r"design\.inputs\.de\.amplitude: expected a positive number"),
        ("duration_s = 10.0\ndt_s = 0.04\nnoise_std = {alpha = 0.001, q = 0.001}\n"
         "inputs = {de = {amplitude = 0.01}}",
         r"design\.inputs\.de\.band_hz: a multisine needs a band"),
        ("duration_s = 10.0\ndt_s = 0.04\nnoise_std = {alpha = 0.001, q = 0.001}\n"
         "inputs = {de = {amplitude = 0.01}}\nband_hz = [0.1, 2]\nlimits = {beta = 0.1}",
         r"design\.limits\.beta: not an output"),
        ("duration_s = 10.0\ndt_s = 0.04\nnoise_std = {alpha = 0.001, q = 0.001}\n"
         "inputs = {de = {amplitude = 0.01}}\nband_hz = [0.1, 2]\ncriterion = \"parameters\"",
         r"design\.parameters: criterion = \"parameters\" needs"),
    ],
)  # fmt: skip
def test_design_table_errors_name_the_key(tmp_path, design, message):
    from flightid.cases.design_case import run_design_case

    case = _case(tmp_path, design)
    with pytest.raises(CaseError, match=message):
        run_design_case(case)


@needs_data("fvsysid/fAttasElv1.mat")
def test_flightid_design_json_on_the_shipped_short_period_case(capsys):
    from flightid.cli.main import main

    assert main(["design", "examples/cases/short_period_design.toml", "--json", "--quiet"]) == 0
    document = json.loads(capsys.readouterr().out)
    names = ["Z0", "Za", "Zq", "Zde", "M0", "Ma", "Mq", "Mde"]
    assert list(document["predicted"]) == names
    assert all(s > 0 for s in document["predicted"].values())
    inputs = document["inputs"]
    assert set(inputs) == {"time", "de"}
    assert len(inputs["time"]) == len(inputs["de"]) == 626  # 25 s at 0.04 s
    assert max(abs(v) for v in inputs["de"]) <= 0.0495
    entry = document["results"][0]
    assert [p["name"] for p in entry["parameters"]] == names
    assert [p["std"] for p in entry["parameters"]] == list(document["predicted"].values())
    # the response limits of the case hold, and the design beats the flown Elv1 input
    assert entry["response_peak"]["alpha"] <= 0.0543 and entry["response_peak"]["q"] <= 0.139
    reference = entry["reference"]["predicted"]
    assert all(document["predicted"][n] < reference[n] for n in names)
    # the document is a results.json of layout 1: its entry is a design entry of the schema
    import jsonschema

    schema = json.loads(Path("docs/schema/results.schema.json").read_text())
    jsonschema.Draft202012Validator(schema).validate(document)
    design_only = {"$ref": "#/$defs/design_entry", "$defs": schema["$defs"]}
    jsonschema.Draft202012Validator(design_only).validate(entry)


def test_step_inputs_follow_one_another_and_a_too_short_duration_is_named():
    from flightid.design.optimize import DesignError

    specs = (InputSpec("u1", 0.2, pulse_s=0.5), InputSpec("u2", 0.1, pulse_s=0.3))
    problem = DesignProblem(
        _lag_model(a=-2.0, b1=1.0, b2=0.5), specs, 12.0, 0.05, {"y": 0.01}, signal="3211",
        candidates=1,
        start_s=1.0, gap_s=2.0,
    )  # fmt: skip
    best, _ = design_input(problem)
    t = best.time
    first = np.flatnonzero(best.perturbations[:, 0])
    second = np.flatnonzero(best.perturbations[:, 1])
    # u1: 7 × 0.5 s from t = 1 s; u2 starts a 2 s gap after u1 ends (t = 6.5 s); together
    # they need 1 + 3.5 + 2 + 7 × 0.3 = 8.6 s
    assert t[first[0]] == pytest.approx(1.0) and t[first[-1]] == pytest.approx(4.45)
    assert t[second[0]] == pytest.approx(6.5) and t[second[-1]] == pytest.approx(8.55)
    short = replace(problem, duration_s=6.0)
    with pytest.raises(DesignError, match=r"duration_s: no candidate fits in 6 s; .* needs 8\.6 s"):
        design_input(short)


def test_design_result_files_hold_the_input_and_the_predicted_bounds(tmp_path):
    import csv

    from flightid.design.result import DesignResult

    problem = DesignProblem(
        _short_period(), (InputSpec("de", 0.03, -0.02, (0.1, 1.5)),), 10.0, 0.05,
        {"alpha": 0.002, "q": 0.003}, candidates=2,
    )  # fmt: skip
    best, tried = design_input(problem)
    result = DesignResult(problem, best, tuple(tried), title="files")
    from flightid.report.estimator_reports import write_design_files

    main = write_design_files(result, tmp_path)
    assert main.name == "report.html"
    page = main.read_text()
    assert "data:image/png;base64," in page and "href='designed_input.csv'" in page
    document = json.loads((tmp_path / "results.json").read_text())
    entry = document["results"][0]
    assert entry["predicted"] == {
        n: float(s) for n, s in zip(best.accuracy.names, best.accuracy.std, strict=True)
    }
    with open(tmp_path / "designed_input.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 201 and list(rows[0]) == ["time_s", "de", "delta_de"]
    for row in rows:
        # the absolute column is trim + Δu, and Δu stays within its amplitude
        assert float(row["de"]) == pytest.approx(-0.02 + float(row["delta_de"]), abs=1e-9)
        assert abs(float(row["delta_de"])) <= 0.03 + 1e-12
    with open(tmp_path / "predicted_accuracy.csv", newline="") as handle:
        table = {r["name"]: float(r["predicted_std"]) for r in csv.DictReader(handle)}
    np.testing.assert_allclose(
        [table[n] for n in best.accuracy.names], best.accuracy.std, rtol=1e-5
    )
    assert (tmp_path / "figures" / "designed_input.png").stat().st_size > 10_000
    frame = result.to_frame()
    assert list(frame.index) == list(best.accuracy.names)
