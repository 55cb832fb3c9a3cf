"""Input and output time delays in the frequency-domain estimators: a delay τ is the factor
e^{−jωτ} (``LinearSystem.transfer``, ``delayed_inputs``).

The data are a multirotor roll-rate loop, p/p_cmd = ω_n² e^{−τs}/(s² + 2ζω_n s + ω_n²),
ω_n = 42 rad/s, ζ = 0.6, τ = 0.025 s, simulated independently of flightid: scipy.signal.lsim
on a ten times finer grid fed the exact delayed multisine p_cmd(t − τ), sampled at 200 Hz,
seeded white noise added. The input is smooth between samples, so the transforms use the
trapezoid rule for inputs and outputs alike.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from flightid.cases import CaseError, load_case
from flightid.cases.frequency_case import prepare_frequency_case, run_frequency_case
from flightid.frequency import (
    equation_error,
    finite_fourier_transform,
    frequency_grid,
    linear_system,
    maneuver_spectra,
    output_error,
)
from flightid.frequency.output_error import delayed_inputs
from flightid.model import Parameter, Parameters, StateSpaceModel

WN, ZETA, TAU = 42.0, 0.6, 0.025  # rad/s, -, s
DT = 0.005  # s (200 Hz)
BAND = (0.2, 12.0)  # Hz
STEP = 0.05  # Hz


def multisine(t: np.ndarray) -> np.ndarray:
    """Schroeder-phased multisine, 0.2–12 Hz in 0.2 Hz steps, rad/s."""
    freqs = np.arange(1, 61) * 0.2
    k = np.arange(1, freqs.size + 1)
    phase = -np.pi * k * (k - 1) / freqs.size
    waves = np.cos(2 * np.pi * freqs[None, :] * t[:, None] + phase[None, :])
    return 0.2 * waves.sum(axis=1) / np.sqrt(freqs.size / 2)


def rate_loop_record(seed: int = 1, duration_s: float = 20.0, noise: float = 0.02):
    """(t, p_cmd, p): the closed loop simulated by scipy on a 2 kHz grid with the exactly
    delayed input, sampled at 200 Hz, noise N(0, noise²) on p."""
    fine = 10
    t_fine = np.arange(int(round(duration_s / DT)) * fine + 1) * DT / fine
    loop = signal.lti([WN**2], [1.0, 2 * ZETA * WN, WN**2])
    _, p, _ = signal.lsim(loop, multisine(t_fine - TAU), t_fine)
    t = t_fine[::fine]
    rng = np.random.default_rng(seed)
    return t, multisine(t), p[::fine] + noise * rng.standard_normal(t.size)


# second order: ṗ = r,  ṙ = −ω_n² p − 2ζω_n r + ω_n² p_cmd
def loop_f(t, x, u, theta):
    wn, zeta = theta[0], theta[1]
    return np.array([x[1], -(wn**2) * x[0] - 2 * zeta * wn * x[1] + wn**2 * u[0]])


def loop_h(t, x, u, theta):
    return np.array([x[0]])


def loop_model(delay: str | None = "input", tau_free: bool = True, tau: float = 0.0):
    parameters = [Parameter("wn", 30.0), Parameter("zeta", 0.5)]
    if delay is not None:
        parameters.append(Parameter("tau", tau, free=tau_free))
    return StateSpaceModel(
        states=("p", "r"),
        inputs=("p_cmd",),
        outputs=("p",),
        f=loop_f,
        h=loop_h,
        parameters=Parameters(parameters),
        input_delays={"p_cmd": "tau"} if delay == "input" else None,
        output_delays={"p": "tau"} if delay == "output" else None,
    )


def _spectra(seed: int = 1):
    t, u, y = rate_loop_record(seed)
    frequencies = frequency_grid(BAND, STEP)
    return maneuver_spectra(t, u[:, None], y[:, None], frequencies, input_quadrature="trapezoid")


def _fit(model, spectra):
    return output_error(
        lambda theta: linear_system(model, theta),
        model.parameters.values,
        model.parameters.free_mask,
        [spectra],
        model.states,
        model.outputs,
    )


@pytest.fixture(scope="module")
def spectra():
    return _spectra()


@pytest.mark.parametrize("where", ["input", "output"])
def test_output_error_recovers_the_natural_frequency_and_the_delay(spectra, where):
    fit = _fit(loop_model(where), spectra)
    assert fit.converged, fit.message
    truth = np.array([WN, ZETA, TAU])
    # within 3 Cramér–Rao σ, and σ(τ) well below a sample
    assert np.all(np.abs(fit.theta - truth) < 3.0 * fit.std), (fit.theta, fit.std)
    assert fit.std[2] < 0.1 * DT


def test_without_the_delay_the_natural_frequency_is_biased(spectra):
    fit = _fit(loop_model(None), spectra)
    # the missing phase lag ωτ is absorbed by a slower, less damped loop: far outside 3σ
    assert WN - fit.theta[0] > 10.0
    assert abs(fit.theta[0] - WN) > 30.0 * fit.std[0]


def test_a_fixed_delay_gives_the_natural_frequency_within_3_sigma(spectra):
    fit = _fit(loop_model("input", tau_free=False, tau=TAU), spectra)
    assert fit.converged
    assert abs(fit.theta[0] - WN) < 3.0 * fit.std[0]
    assert abs(fit.theta[1] - ZETA) < 3.0 * fit.std[1]
    assert fit.theta[2] == TAU and np.isnan(fit.std[2])


def test_transfer_is_scipy_frequency_response_times_the_delay_phase():
    model = loop_model("input", tau=TAU)
    theta = np.array([WN, ZETA, TAU])
    f = np.array([0.5, 3.0, 6.7, 11.0])
    H = linear_system(model, theta).transfer(f)[:, 0, 0]
    _, reference = signal.freqresp(signal.lti([WN**2], [1.0, 2 * ZETA * WN, WN**2]), 2 * np.pi * f)
    # H(jω) = ω_n²/(s² + 2ζω_n s + ω_n²) · e^{−jωτ}
    np.testing.assert_allclose(H, reference * np.exp(-2j * np.pi * f * TAU), rtol=1e-12)


def test_delayed_input_transform_matches_the_transform_of_the_shifted_record():
    # a ramp-and-sine input that does not start or end at zero: the record's ends matter
    t = np.arange(2001) * DT
    u = 0.3 + 0.05 * t + 0.2 * np.sin(2 * np.pi * 1.3 * t)
    tau = 0.04
    f = frequency_grid((0.1, 5.0), 0.05)
    spectra = maneuver_spectra(
        t, u[:, None], np.zeros((t.size, 1)), f, detrend="none", input_quadrature="trapezoid"
    )
    model = loop_model("input", tau=tau)
    system = linear_system(model, np.array([WN, ZETA, tau]))
    fine = np.arange(20001) * DT / 10
    u_fine = 0.3 + 0.05 * fine + 0.2 * np.sin(2 * np.pi * 1.3 * fine)
    # reference: ũ(t) = u(t − τ) with u(0) held before the record, transformed directly
    shifted = np.where(fine < tau, u_fine[0], np.interp(fine - tau, fine, u_fine))
    reference = finite_fourier_transform(shifted, fine, f, quadrature="trapezoid")
    with_ends = delayed_inputs(system, spectra)[:, 0]
    phase_only = spectra.inputs[:, 0] * np.exp(-2j * np.pi * f * tau)
    error_with_ends = np.max(np.abs(with_ends - reference))
    error_phase_only = np.max(np.abs(phase_only - reference))
    # the end terms take the error from that of the bare phase factor down to the tail's
    # bound |∫_{T−τ}^T (u(s) − u(T)) e^{−jωs} ds| ≤ max|u̇|·τ²/2 over the last τ seconds
    u_dot = 0.05 + 0.2 * 2 * np.pi * 1.3 * np.cos(2 * np.pi * 1.3 * fine[fine >= t[-1] - tau])
    tail_bound = np.max(np.abs(u_dot)) * tau**2 / 2
    assert error_with_ends < 0.05 * error_phase_only
    assert error_with_ends < 1.05 * tail_bound


def _first_order(tau: float, free: bool):
    # ṗ = Lp p + Lda δ(t − τ)
    return StateSpaceModel(
        states=("p",),
        inputs=("da",),
        outputs=("p",),
        f=lambda t, x, u, th: np.array([th[0] * x[0] + th[1] * u[0]]),
        h=lambda t, x, u, th: np.array([x[0]]),
        parameters=Parameters(
            [Parameter("Lp", -3.0), Parameter("Lda", 10.0), Parameter("tau", tau, free=free)]
        ),
        input_delays={"da": "tau"},
    )


def test_equation_error_uses_a_fixed_delay_and_leaves_a_free_one_undetermined():
    lp, lda, tau = -8.0, 30.0, 0.05
    t = np.arange(4001) * DT
    fine = np.arange(40001) * DT / 10
    _, p, _ = signal.lsim(signal.lti([lda], [1.0, -lp]), multisine(fine - tau), fine)
    f = frequency_grid((0.2, 8.0), 0.05)
    spectra = [
        maneuver_spectra(t, multisine(t)[:, None], p[::10, None], f, input_quadrature="trapezoid")
    ]
    for free in (False, True):
        model = _first_order(tau, free)
        fit = equation_error(
            lambda theta, m=model: linear_system(m, theta),
            model.parameters.values,
            model.parameters.free_mask,
            spectra,
            model.states,
            model.outputs,
        )
        # noise-free data: the regression with the delayed input transform is near exact
        np.testing.assert_allclose(fit.theta[:2], [lp, lda], rtol=2e-3)
        assert not fit.estimated[2]


# ------------------------------------------------------------------ case files

_MODULE = """
import numpy as np

STATES = ("p", "r")
INPUTS = ("p_cmd",)
OUTPUTS = ("p",)
PARAMETERS = {"wn": 30.0, "zeta": 0.5}


def f(t, x, u, theta):
    wn, zeta = theta[0], theta[1]
    return np.array([x[1], -wn**2 * x[0] - 2 * zeta * wn * x[1] + wn**2 * u[0]])


def h(t, x, u, theta):
    return np.array([x[0]])
"""


def write_case(tmp_path, model_lines: str = "", parameters: str = "", table: str = ""):
    t, u, y = rate_loop_record()
    rows = np.column_stack([t, u, y])
    np.savetxt(tmp_path / "loop.csv", rows, delimiter=",", header="t,p_cmd,p", comments="")
    (tmp_path / "loop.py").write_text(_MODULE)
    (tmp_path / "case.toml").write_text(
        f"""title = "rate loop"
[data]
data_dir = "."
file = "loop.csv"
time = "t"
[data.inputs]
p_cmd = {{ column = "p_cmd" }}
[data.outputs]
p = {{ column = "p" }}
[model]
module = "loop.py"
{model_lines}
[parameters]
{parameters}
[initial_state]
default = 0.0
[frequency_domain]
band_hz = [{BAND[0]}, {BAND[1]}]
step_hz = {STEP}
input_quadrature = "trapezoid"
{table}
"""
    )
    return tmp_path / "case.toml"


def test_case_file_estimates_the_input_delay(tmp_path):
    path = write_case(tmp_path, 'input_delays = { p_cmd = "tau" }')
    result = run_frequency_case(load_case(path))
    assert result.converged, result.message
    values = dict(zip(result.names, result.values, strict=True))
    stds = dict(zip(result.names, result.std, strict=True))
    for name, truth in (("wn", WN), ("zeta", ZETA), ("tau", TAU)):
        assert abs(values[name] - truth) < 3.0 * stds[name], (name, values[name], stds[name])
    # the Bode figure's model response carries the delay
    H = result.model_transfer(np.array([6.0]))[0, 0, 0]
    plain = WN**2 / ((2j * np.pi * 6.0) ** 2 + 2 * ZETA * WN * 2j * np.pi * 6.0 + WN**2)
    assert abs(np.angle(H / plain) + 2 * np.pi * 6.0 * TAU) < 0.05


_FIRST_ORDER = """
import numpy as np

STATES = ("p",)
INPUTS = ("p_cmd",)
OUTPUTS = ("p",)
PARAMETERS = {"a": -30.0, "b": 30.0}


def f(t, x, u, theta):
    return np.array([theta[0] * x[0] + theta[1] * u[0]])


def h(t, x, u, theta):
    return np.array([x[0]])
"""


def test_case_file_equation_error_cannot_estimate_a_free_delay(tmp_path):
    path = write_case(
        tmp_path, 'input_delays = { p_cmd = "tau" }', table='method = "equation_error"'
    )
    (tmp_path / "loop.py").write_text(_FIRST_ORDER)
    # refused before estimating (prepare_frequency_case is what validate runs)
    with pytest.raises(CaseError, match=r"equation error determines no equation for \['tau'\]"):
        prepare_frequency_case(load_case(path))
    fixed = write_case(
        tmp_path,
        'input_delays = { p_cmd = "tau" }',
        "tau = { value = 0.025, free = false }",
        table='method = "equation_error"',
    )
    (tmp_path / "loop.py").write_text(_FIRST_ORDER)
    assert run_frequency_case(load_case(fixed)).converged
