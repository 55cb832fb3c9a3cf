"""`flightid validate` makes every check a frequency-domain or recursive run makes before
estimating (``prepare_frequency_case``, ``prepare_recursive_case``), every value of the
``[frequency_domain]`` and ``[recursive]`` tables is checked with a ``CaseError`` naming the
key, and the public functions of flightid.frequency and flightid.recursive answer wrong
arguments with an ``InputError`` naming the argument (not a raw ValueError, TypeError,
IndexError or AttributeError from inside numpy).
"""

from __future__ import annotations

import re

import numpy as np
import pytest

import flightid.frequency as fd
import flightid.recursive as rc
from flightid.cases import CaseError, load_case
from flightid.cases.recursive_case import run_recursive_case
from flightid.cli.main import main
from flightid.errors import InputError
from flightid.model import Parameter, Parameters, StateSpaceModel

DT = 0.01  # s: Nyquist 50 Hz

_MODULE = """
import numpy as np

STATES = ("p",)
INPUTS = ("da",)
OUTPUTS = ("p",)
PARAMETERS = {"Lp": -3.0, "Lda": 10.0}


def f(t, x, u, theta):
    return np.array([theta[0] * x[0] + theta[1] * u[0]])


def h(t, x, u, theta):
    return np.array([x[0]])
"""


def write_case(tmp_path, table: str, delay: bool = False, samples: int = 1000):
    """A roll-mode case (ṗ = Lp p + Lda δa) on a CSV sampled at 100 Hz, with ``table``
    (``delay``: the input delayed by a free parameter tau)."""
    t = np.arange(samples) * DT
    da = np.sin(2 * np.pi * 0.7 * t) + 0.5 * np.sin(2 * np.pi * 2.3 * t)
    p = np.zeros_like(t)
    for k in range(1, t.size):
        # Euler is enough here: the tests check settings, not estimates
        p[k] = p[k - 1] + DT * (-8.0 * p[k - 1] + 30.0 * da[k - 1])
    rows = np.column_stack([t, da, p, 0.5 * p])
    np.savetxt(tmp_path / "roll.csv", rows, delimiter=",", header="t,da,p,q", comments="")
    (tmp_path / "roll.py").write_text(_MODULE)
    path = tmp_path / "case.toml"
    delay_line = 'input_delays = { da = "tau" }' if delay else ""
    path.write_text(
        f"""title = "roll"
[data]
data_dir = "."
file = "roll.csv"
time = "t"
[data.inputs]
da = {{ column = "da" }}
[data.outputs]
p = {{ column = "p" }}
q = {{ column = "q" }}
[model]
module = "roll.py"
{delay_line}
[initial_state]
default = 0.0
{table}
"""
    )
    return path


def _validate(path, capsys) -> tuple[int, str]:
    code = main(["validate", str(path)])
    captured = capsys.readouterr()
    return code, captured.out + captured.err


FTR = """[recursive]
method = "ftr"
states = ["p"]
inputs = ["da"]
update_every_s = 1.0
"""


# ------------------------------------------------------------------ validate = run's checks


@pytest.mark.parametrize(
    "table, message",
    [
        # the band above the data's Nyquist frequency (50 Hz)
        (
            "[frequency_domain]\nband_hz = [0.5, 60.0]\nstep_hz = 0.5",
            r"band_hz: the highest frequency 60 Hz is at or above the Nyquist",
        ),
        # too few equations for the unknowns (output error)
        (
            "[frequency_domain]\nband_hz = [1.0, 1.1]\nstep_hz = 0.1",
            r"band_hz/step_hz: 2 frequencies give .* real equations for .* unknowns",
        ),
        # the FTR's frequencies above Nyquist
        (
            FTR + "frequencies_hz = { start = 1.0, stop = 55.0, step = 1.0 }",
            r"recursive.frequencies_hz.stop: the highest frequency 55 Hz is at or above the "
            r"Nyquist frequency 50 Hz",
        ),
        # an update interval that is no whole number of samples
        (
            FTR.replace("1.0\n", "1.005\n") + "frequencies_hz = { start = 1, stop = 5, step = 1 }",
            r"recursive.update_every_s: expected a whole number of samples",
        ),
        # a p0 of the wrong length for the model's augmented state (x, Lp, Lda)
        (
            '[recursive]\nmethod = "ekf"\np0 = [1, 1]\nq_states = 1e-6\nr0 = 1e-4',
            r"recursive.p0: expected a number or a list of 3 numbers",
        ),
        # a free input delay in a recursive filter
        (
            '[recursive]\nmethod = "ekf"\np0 = 1\nq_states = 1e-6\nr0 = 1e-4',
            r"model: .*input delay 'tau' of 'da' is free",
        ),
    ],
)
def test_validate_refuses_what_run_refuses(tmp_path, capsys, table, message):
    path = write_case(tmp_path, table, delay="input delay" in message)
    code, text = _validate(path, capsys)
    assert code == 1
    assert re.search(message, text), text


def test_validate_refuses_an_equation_error_parameter_without_an_equation(tmp_path, capsys):
    # a delay is not linear in the regression: a free one has no equation
    table = '[frequency_domain]\nmethod = "equation_error"\nband_hz = [0.2, 5.0]'
    path = write_case(tmp_path, table, delay=True)
    code, text = _validate(path, capsys)
    assert code == 1
    assert "equation error determines no equation for ['tau']" in text


def test_run_refuses_ftr_frequencies_above_nyquist(tmp_path):
    path = write_case(tmp_path, FTR + "frequencies_hz = { start = 1.0, stop = 55.0, step = 1.0 }")
    with pytest.raises(CaseError, match=r"recursive.frequencies_hz.stop: .*Nyquist"):
        run_recursive_case(load_case(path))


@pytest.mark.parametrize(
    "table",
    [
        "[frequency_domain]\nband_hz = [0.2, 5.0]\nstep_hz = 0.1",
        FTR + "frequencies_hz = { start = 0.2, stop = 5.0, step = 0.1 }",
        '[recursive]\nmethod = "ekf"\np0 = [1, 1, 1]\nq_states = 1e-6\nr0 = 1e-4',
    ],
)
def test_validate_accepts_a_valid_estimator_table(tmp_path, capsys, table):
    code, text = _validate(write_case(tmp_path, table), capsys)
    assert code == 0, text
    assert "settings valid for the data" in text


# ------------------------------------------------------------------ table values
# (most of these checks existed already and are pinned here with the new ones: a step that
# leaves fewer than two frequencies, repeated or shared FTR channels, input_delays_s)


@pytest.mark.parametrize(
    "table, message",
    [
        ("band_hz = [0.2]", r"frequency_domain.band_hz: expected \[low, high\]"),
        ('band_hz = [0.2, "5"]', r"frequency_domain.band_hz: expected a number"),
        ("band_hz = [0.0, 5.0]", r"frequency_domain.band_hz: expected 0 < low < high"),
        ("step_hz = 0", r"frequency_domain.step_hz: expected a positive step"),
        ("step_hz = 10.0", r"frequency_domain: step_hz: a step of 10.0 Hz leaves fewer than 2"),
        ("boundary = 1", r"frequency_domain.boundary: expected true or false"),
        ('detrend = "quadratic"', r"frequency_domain.detrend: expected one of"),
        ("max_noise_cycles = 2.5", r"frequency_domain.max_noise_cycles: expected a positive"),
        ("tolerance = 1.5", r"frequency_domain.tolerance: expected a number in \(0, 1\)"),
        ('input_quadrature = "simpson"', r"frequency_domain.input_quadrature: expected one of"),
        ('method = "ml"', r"frequency_domain.method: expected one of"),
        ("bandwidth = 3", r"frequency_domain.bandwidth: unknown key"),
    ],
)
def test_frequency_domain_values_are_named_case_errors(tmp_path, capsys, table, message):
    code, text = _validate(write_case(tmp_path, "[frequency_domain]\n" + table), capsys)
    assert code == 1
    assert re.search(message, text), text


@pytest.mark.parametrize(
    "table, message",
    [
        ('method = "ekf"\np0 = "big"\nq_states = 1\nr0 = 1', r"recursive.p0: expected a number"),
        (
            'method = "ekf"\np0 = 1\nq_states = -1\nr0 = 1',
            r"recursive.q_states: expected a number >= 0",
        ),
        ('method = "ekf"\np0 = 1\nq_states = 1\nr0 = 0', r"recursive.r0: expected a number > 0"),
        (
            'method = "efrls"\nforgetting = 1.2',
            r"recursive.forgetting: expected a number in \(0, 1\]",
        ),
        (
            'method = "ekf"\np0 = 1\nq_states = 1\nr0 = 1\ncompiled = "yes"',
            r"recursive.compiled: expected true or false",
        ),
        ('method = "ekf"\np0 = 1\nq_states = 1\nr0 = 1\nreport = "best"', r"recursive.report"),
        (
            'method = "ftr"\nstates = ["p", "p"]\ninputs = ["da"]\nupdate_every_s = 1.0\n'
            "frequencies_hz = { start = 1, stop = 5, step = 1 }",
            r"recursive.states: \['p'\] named more than once",
        ),
        (
            'method = "ftr"\nstates = ["p"]\ninputs = ["da", "p"]\nupdate_every_s = 1.0\n'
            "frequencies_hz = { start = 1, stop = 5, step = 1 }",
            r"recursive.inputs: \['p'\] also named in recursive.states",
        ),
        (
            FTR.split("\n", 1)[1] + "frequencies_hz = { start = 1, stop = 5, step = 1 }\n"
            "input_delays_s = { dr = 0.05 }",
            r"recursive.input_delays_s.dr: not one of recursive.inputs",
        ),
        (
            FTR.split("\n", 1)[1] + "frequencies_hz = { start = 1, stop = 5, step = 1 }\n"
            "input_delays_s = { da = -0.05 }",
            r"recursive.input_delays_s.da: expected a delay >= 0 s",
        ),
        (
            FTR.split("\n", 1)[1] + 'frequencies_hz = { start = 1, stop = 5, step = "1" }',
            r"recursive.frequencies_hz.step: expected a number",
        ),
        (
            FTR.split("\n", 1)[1]
            + "frequencies_hz = { start = 1, stop = 5, step = 1 }\nn_mean = 0",
            r"recursive.n_mean: expected a positive integer",
        ),
    ],
)
def test_recursive_values_are_named_case_errors(tmp_path, capsys, table, message):
    code, text = _validate(write_case(tmp_path, "[recursive]\n" + table), capsys)
    assert code == 1
    assert re.search(message, text), text


def test_ftr_input_delay_key_reaches_the_estimator(tmp_path):
    path = write_case(
        tmp_path,
        FTR + "frequencies_hz = { start = 0.2, stop = 5.0, step = 0.1 }\n"
        "input_delays_s = { da = 0.03 }",
    )
    from flightid.cases.recursive_case import prepare_recursive_case

    prepared = prepare_recursive_case(load_case(path))
    np.testing.assert_array_equal(prepared.estimator.input_delays_s, [0.03])


# ------------------------------------------------------------------ the public API


def _model():
    return StateSpaceModel(
        states=("p",),
        inputs=("u",),
        outputs=("p",),
        f=lambda t, x, u, th: np.array([th[0] * x[0] + th[1] * u[0]]),
        h=lambda t, x, u, th: np.array([x[0]]),
        parameters=Parameters([Parameter("a", -1.0), Parameter("b", 1.0)]),
    )


T = np.arange(400) * DT
U = np.sin(3 * T) + np.sin(11 * T)
Y = np.cos(2 * T)
F = fd.frequency_grid((0.2, 5.0), 0.1)
SPECTRA = fd.maneuver_spectra(T, U, Y, F)
MODEL = _model()


def system_of(theta):
    return fd.linear_system(MODEL, theta)


def _oe(**changes):
    arguments = dict(
        system_of=system_of,
        theta_start=[-1.0, 1.0],
        free=[True, True],
        spectra=[SPECTRA],
        states=("p",),
        outputs=("p",),
    )
    arguments.update(changes)
    return lambda: fd.output_error(**arguments)


def _ee(**changes):
    arguments = dict(
        system_of=system_of,
        theta_start=[-1.0, 1.0],
        free=[True, True],
        spectra=[SPECTRA],
        states=("p",),
        outputs=("p",),
    )
    arguments.update(changes)
    return lambda: fd.equation_error(**arguments)


def _augmented():
    return rc.AugmentedModel(MODEL, [0.0], compiled=False)


def _ekf():
    return rc.ExtendedKalmanFilter(_augmented(), 1.0, 1e-6, 1e-3)


FREQUENCY_CALLS = {
    "frequency_grid step string": (lambda: fd.frequency_grid((0.1, 1.0), "x"), "step_hz"),
    "spectra time string": (lambda: fd.maneuver_spectra("abc", U, Y, F), "time_s"),
    "spectra rows differ": (lambda: fd.maneuver_spectra(T, U[:-1], Y, F), "inputs: expected"),
    "spectra complex data": (lambda: fd.maneuver_spectra(T, U + 1j, Y, F), "complex"),
    "spectra frequency string": (lambda: fd.maneuver_spectra(T, U, Y, "x"), "frequencies_hz"),
    "spectra no frequency": (lambda: fd.maneuver_spectra(T, U, Y, []), "frequencies_hz"),
    "spectra zero frequency": (lambda: fd.maneuver_spectra(T, U, Y, [0.0, 1.0]), "> 0 Hz"),
    "spectra name": (lambda: fd.maneuver_spectra(T, U, Y, F, name=3), "name"),
    "transform signals string": (lambda: fd.finite_fourier_transform("a", T, F), "signals"),
    "remove_trend string": (lambda: fd.remove_trend("x", T), "signals"),
    "constant_transform": (lambda: fd.constant_transform("x", F), "time_s"),
    "linear_system model": (lambda: fd.linear_system("m"), "model: expected a StateSpaceModel"),
    "linear_system short θ": (lambda: fd.linear_system(MODEL, [1.0]), "theta: expected 2"),
    "linear_system θ string": (lambda: fd.linear_system(MODEL, "ab"), "theta"),
    "bias_like model": (lambda: fd.bias_like_parameters(3), "model"),
    "oe start string": (_oe(theta_start="ab"), "theta_start"),
    "oe one spectra": (_oe(spectra=SPECTRA), "pass \\[spectra\\]"),
    "oe system_of": (_oe(system_of=3), "system_of: expected a function"),
    "oe max_noise_cycles 0": (_oe(max_noise_cycles=0), "max_noise_cycles"),
    "oe max_noise_cycles string": (_oe(max_noise_cycles="3"), "max_noise_cycles"),
    "oe tolerance": (_oe(tolerance=-1), "tolerance"),
    "oe scales": (_oe(scales=[1.0]), "scales"),
    "oe boundary": (_oe(boundary="no"), "boundary"),
    "oe states": (_oe(states=("p", "q")), "states/outputs"),
    "oe integer mask": (_oe(free=[1, 5]), "free: expected a mask"),
    "ee start string": (_ee(theta_start="ab"), "theta_start"),
    "ee spectra": (_ee(spectra=[3]), "spectra: expected ManeuverSpectra"),
    "model_response system": (lambda: fd.model_response("s", SPECTRA), "system"),
    "model_response nuisance": (
        lambda: fd.model_response(system_of([-1.0, 1.0]), SPECTRA, [1.0]),
        "nuisance",
    ),
    "least squares strings": (lambda: fd.complex_least_squares("a", [1]), "regressors"),
    "frequency_response": (lambda: fd.frequency_response("a", U, DT), "inputs"),
    "frequency_response segment": (
        lambda: fd.frequency_response(U, Y, DT, segment_s="x"),
        "segment_s",
    ),
    "fit_loes": (lambda: fd.fit_loes("a", [1], [1], [0]), "omega_rad_s"),
    "loes_response": (lambda: fd.loes_response("a", [1], 0.0, [1.0]), "numerator"),
    "short_period_loes": (lambda: fd.short_period_loes("a", [1]), "omega_rad_s"),
}

RECURSIVE_CALLS = {
    "augmented x0 string": (lambda: rc.AugmentedModel(MODEL, "a"), "x0"),
    "augmented compiled": (lambda: rc.AugmentedModel(MODEL, [0.0], compiled="no"), "compiled"),
    "ekf jacobian_step": (
        lambda: rc.ExtendedKalmanFilter(_augmented(), 1.0, 1e-6, 1e-3, "x"),
        "jacobian_step",
    ),
    "ekf p0 strings": (lambda: rc.ExtendedKalmanFilter(_augmented(), ["a"] * 3, 1e-6, 1e-3), "p0"),
    "ekf r0 zero": (
        lambda: rc.ExtendedKalmanFilter(_augmented(), 1.0, 1e-6, 0.0),
        "r0: expected values > 0",
    ),
    "ukf_aug r0 zero": (
        lambda: rc.AugmentedUnscentedKalmanFilter(_augmented(), 1.0, 1e-6, 0.0),
        "r0",
    ),
    "efrls p0 zero": (
        lambda: rc.ExtendedForgettingRLS(_augmented(), 0.0),
        "p0: expected a start matrix > 0",
    ),
    "efrls forgetting bool": (
        lambda: rc.ExtendedForgettingRLS(_augmented(), 1.0, True),
        "forgetting",
    ),
    "ftr frequencies string": (
        lambda: rc.FourierTransformRegression(1, 1, "abc", 10),
        "frequencies_hz",
    ),
    "ftr names string": (
        lambda: rc.FourierTransformRegression(1, 1, [1, 2, 3], 10, parameter_names="ab"),
        "parameter_names",
    ),
    "ftr offsets list": (
        lambda: rc.FourierTransformRegression(1, 1, [1, 2, 3], 10, offsets=[1]),
        "offsets",
    ),
    "ftr offsets value": (
        lambda: rc.FourierTransformRegression(1, 1, [1, 2, 3], 10, offsets={"A11": "x"}),
        "offsets\\['A11'\\]",
    ),
    "feed t string": (lambda: _ekf().feed("x", [0.0], [0.0]), "t: expected a time"),
    "feed u string": (lambda: _ekf().feed(0.0, "a", [0.0]), "u: expected"),
    "feed_block strings": (
        lambda: rc.RecursiveEstimator(_ekf()).feed_block("a", [1], [2]),
        "t: expected",
    ),
}


@pytest.mark.parametrize("name", sorted(FREQUENCY_CALLS))
def test_frequency_api_arguments_are_named_input_errors(name):
    call, message = FREQUENCY_CALLS[name]
    with pytest.raises(InputError, match=message):
        call()


@pytest.mark.parametrize("name", sorted(RECURSIVE_CALLS))
def test_recursive_api_arguments_are_named_input_errors(name):
    call, message = RECURSIVE_CALLS[name]
    with pytest.raises(InputError, match=message):
        call()
