"""Every estimator's text summary prints σ to two significant digits and each value at σ's
decimal place (flightid.numbers), so a known value/σ pair reads the same in all of them.

The pair: θ̂ = 12.3456789, σ = 0.0123456. σ to two significant digits is 0.012, its last
digit at 10⁻³, so θ̂ reads 12.346 (the fixed ``:.6g`` / ``:.4g`` columns printed 12.3457
and 0.01235).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from flightid.numbers import format_with_sigma
from flightid.regression import least_squares, stepwise, total_least_squares

VALUE, SIGMA = 12.3456789, 0.0123456
# by hand (module docstring), and by the rule every summary follows
VALUE_TEXT, SIGMA_TEXT = "12.346", "0.012"
OLD_VALUE_TEXT = "12.3457"


def test_the_known_pair_reads_as_derived_by_hand():
    assert format_with_sigma(VALUE, SIGMA) == (VALUE_TEXT, SIGMA_TEXT)


def _row(text: str, name: str) -> list[str]:
    """The whitespace-separated fields of the summary line that starts with ``name``."""
    (line,) = [row for row in text.splitlines() if row.strip().split(" ")[0] == name]
    return line.split()


def _line_fit():
    """z = 1 + 2x + noise: a two-term fit whose σ is known only at run time."""
    rng = np.random.default_rng(4)
    x = rng.normal(size=40)
    z = 1.0 + 2.0 * x + rng.normal(0.0, 0.1, 40)
    return x, z, least_squares(np.column_stack([np.ones(40), x]), z, ["one", "alpha"])


def _with_pair(fit, j: int = 1):
    """The fit with term j's estimate and σ set to the known pair."""
    estimates, std = fit.estimates.copy(), fit.std.copy()
    estimates[j], std[j] = VALUE, SIGMA
    return replace(fit, estimates=estimates, std=std, std_cr=std)


def test_least_squares_summary_prints_estimate_at_sigma_place():
    _, _, fit = _line_fit()
    row = _row(fit.summary(), "alpha")
    # the run's own numbers: σ to two digits, the estimate to its decimal place
    assert row[1:3] == list(format_with_sigma(fit.estimates[1], fit.std[1]))
    row = _row(_with_pair(fit).summary(), "alpha")
    assert row[1:3] == [VALUE_TEXT, SIGMA_TEXT]
    # t, partial F, p keep their own digits
    assert len(row) == 7


def test_total_least_squares_summary_prints_estimate_at_sigma_place():
    x, z, _ = _line_fit()
    fit = total_least_squares(np.column_stack([np.ones(40), x]), z, ["one", "alpha"])
    assert _row(fit.summary(), "alpha")[1:3] == list(
        format_with_sigma(fit.estimates[1], fit.std[1])
    )
    text = _with_pair(fit).summary()
    assert text.startswith("Total least squares")
    assert _row(text, "alpha")[1:3] == [VALUE_TEXT, SIGMA_TEXT]


def test_stepwise_summary_prints_the_selected_fit_at_sigma_place():
    rng = np.random.default_rng(5)
    alpha, beta = rng.normal(size=60), rng.normal(size=60)
    z = 0.5 + 3.0 * alpha + rng.normal(0.0, 0.05, 60)
    result = stepwise(z, ["alpha", "beta"], {"alpha": alpha, "beta": beta})
    assert "alpha" in result.selected
    j = result.fit.names.index("alpha")
    shown = _row(result.summary().split("\n\n", 1)[1], "alpha")[1:3]
    assert shown == list(format_with_sigma(result.fit.estimates[j], result.fit.std[j]))
    known = replace(result, fit=_with_pair(result.fit, j))
    assert _row(known.summary().split("\n\n", 1)[1], "alpha")[1:3] == [VALUE_TEXT, SIGMA_TEXT]


def test_recursive_summary_prints_value_and_last_filtered_at_their_sigma_place():
    from flightid.recursive.result import RecursiveResult

    rows = 4
    theta = np.full((rows, 2), [VALUE, -0.75])
    std = np.full((rows, 2), [SIGMA, 0.5])
    # the last row: its own value and σ (σ 0.00049: last digit at 10⁻⁵)
    theta[-1] = [12.34112233, -0.7512345]
    std[-1] = [0.00049, 0.5]
    result = RecursiveResult(
        method="ekf",
        parameter_names=("Ma", "Mq"),
        time_s=np.arange(rows, dtype=float),
        samples=np.arange(1, rows + 1),
        theta_history=theta,
        std_history=std,
        state_names=(),
        state_history=np.zeros((rows, 0)),
        report="last_3",
        units=("1/s2", "1/s"),
        initial=(10.0, -1.0),
        n_samples=rows,
        nis=np.zeros(rows),
        warnings=(),
        wall_time_s=0.0,
    )
    # reported value: mean of the last three rows
    value = float(np.mean(theta[-3:, 0]))
    sigma = float(np.mean(std[-3:, 0]))
    row = _row(result.summary(), "Ma")
    assert row[1:3] == list(format_with_sigma(value, sigma))
    assert row[3] == "12.34112"  # the last filtered value at its own σ (0.00049)
    assert row[4] == "10"  # the start value keeps six significant digits
    # the EFRLS has no σ: values keep six significant digits
    efrls = replace(result, method="efrls")
    row = _row(efrls.summary(), "Ma")
    assert row[1:4] == [f"{value:.6g}", "—", "12.3411"]


def test_frequency_summary_prints_estimate_at_sigma_place():
    from flightid.cases.frequency_case import FrequencyResult, FrequencySettings

    result = FrequencyResult(
        title="known pair",
        method="output_error",
        settings=FrequencySettings(),
        names=("Ma", "Mq"),
        values=np.array([VALUE, -2.0]),
        initial=np.array([10.0, -2.0]),
        std=np.array([SIGMA, np.nan]),
        std_coloured=np.array([SIGMA, np.nan]),
        free=np.array([True, False]),
        units=("1/s2", "1/s"),
        not_estimated={},
        nuisance=(),
        states=("alpha", "q"),
        inputs=("de",),
        outputs=("q",),
        frequencies_hz=np.linspace(0.1, 1.5, 36),
        spectra=(),
        model_outputs=(),
        system=None,
        S=None,
        cost=1.0,
        converged=True,
        message="converged",
        noise_cycles=1,
        iterations=3,
        wall_time_s=0.0,
        std_cr=np.array([0.00456789, np.nan]),
    )
    row = _row(result.summary(), "Ma")
    # estimate, σ (coloured), σ (CR) to two digits, start
    assert row[1:5] == [VALUE_TEXT, SIGMA_TEXT, "0.0046", "10"]
    # a parameter not estimated keeps six significant digits
    assert _row(result.summary(), "Mq")[1] == "-2"


def test_design_summary_prints_value_at_the_predicted_sigma_place():
    from flightid.design.information import PredictedAccuracy
    from flightid.design.optimize import Candidate, DesignProblem, InputSpec
    from flightid.design.result import DesignResult
    from flightid.model.statespace import StateSpaceModel

    def f(t, x, u, p):
        return np.array([p[0] * x[0] + p[1] * u[0]])

    def h(t, x, u, p):
        return np.array([x[0]])

    model = StateSpaceModel(("q",), ("de",), ("q",), f, h, {"Mq": -2.0, "Mde": -7.0}, x0=(0.0,))
    problem = DesignProblem(
        model, (InputSpec("de", 0.03, 0.0, (0.1, 1.5)),), 4.0, 0.05, {"q": 0.003}
    )
    time = np.arange(0.0, 4.0 + 1e-9, 0.05)
    perturbation = 0.03 * np.sign(np.sin(2 * np.pi * 0.5 * time))[:, None]
    sigmas = np.array([SIGMA, 0.000123])
    accuracy = PredictedAccuracy(
        names=("Mq", "Mde"),
        values=np.array([VALUE, -7.0]),
        typical=np.ones(2),
        information=np.diag(1.0 / sigmas**2),
        covariance=np.diag(sigmas**2),
        outputs=np.zeros((time.size, 1)),
        output_names=("q",),
        noise_std=np.array([0.003]),
    )
    best = Candidate(
        signal="square",
        time=time,
        perturbations=perturbation,
        input_names=("de",),
        amplitude_factors=(1.0,),
        setting={},
        accuracy=accuracy,
        criterion_value=1.0,
        response_peak={"q": 0.1},
    )
    reference = replace(accuracy, covariance=np.diag((2.0 * sigmas) ** 2))
    facts = {"name": "doublet", "duration_s": 4.0, "peak_amplitude": {"de": 0.03}}
    facts["response_peak"] = {"q": 0.1}
    result = DesignResult(problem, best, (best,), reference=(reference, facts))
    row = _row(result.summary(), "Mq")
    # value, predicted σ, σ %, reference σ, ratio
    assert row[1:3] == [VALUE_TEXT, SIGMA_TEXT]
    assert row[4:6] == ["0.025", "0.500"]
    assert _row(result.summary(), "Mde")[1:3] == ["-7.00000", "0.00012"]


@pytest.mark.parametrize("sigma", [0.0, np.nan, np.inf])
def test_least_squares_without_a_sigma_scale_keeps_six_digits(sigma):
    _, _, fit = _line_fit()
    estimates, std = fit.estimates.copy(), fit.std.copy()
    estimates[1], std[1] = VALUE, sigma
    text = replace(fit, estimates=estimates, std=std, std_cr=std).summary()
    assert _row(text, "alpha")[1] == OLD_VALUE_TEXT
