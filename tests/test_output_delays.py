"""Output time delays (issue 12 item 2): ``StateSpaceModel(output_delays=...,
delay_convention=...)``.

Independent references: ``np.interp`` on the undelayed simulation for the fractional delay
(with numpy's own end-value hold), and the two-sample formula of CASES.md §4 written out
sample by sample for the reference's convention.
"""

from __future__ import annotations

import numpy as np
import pytest

from flightid.data import FlightData
from flightid.errors import InputError
from flightid.estimation import MNR, MNRES, OutputErrorProblem, estimate
from flightid.model import Parameters, StateSpaceModel
from flightid.simulation import Simulator

DT = 0.02  # s
TAUS = [0.0, 0.3 * DT, DT, 2.5 * DT, -0.7 * DT]  # s


# short-period model: α̇ = Zα·α + q + Zδ·δ,  q̇ = Mα·α + Mq·q + Mδ·δ;  y = (α, q)
def sp_f(t, x, u, theta):
    return np.array(
        [
            theta[0] * x[0] + x[1] + theta[1] * u[0],
            theta[2] * x[0] + theta[3] * x[1] + theta[4] * u[0],
        ]
    )


def sp_h(t, x, u, theta):
    return np.array([x[0], x[1]])


TRUE = {"Za": -1.2, "Zd": -0.15, "Ma": -6.0, "Mq": -1.8, "Md": -9.0, "tau_q": 0.05}


def _model(tau: float = 0.0, convention: str = "fractional", delayed: bool = True):
    values = dict(TRUE, tau_q=tau)
    return StateSpaceModel(
        states=("alpha", "q"),
        inputs=("de",),
        outputs=("alpha", "q"),
        f=sp_f,
        h=sp_h,
        parameters=Parameters(values),
        name="short_period",
        output_delays={"q": "tau_q"} if delayed else None,
        delay_convention=convention,
    )


def _doublet(n: int = 200, start: float = 0.2) -> FlightData:
    t = np.arange(n) * DT
    # doublet: +0.05 rad for 0.5 s, then −0.05 rad for 0.5 s
    de = np.where((t >= start) & (t < start + 0.5), 0.05, 0.0)
    de = np.where((t >= start + 0.5) & (t < start + 1.0), -0.05, de)
    return FlightData(t, {"de": de}, {"alpha": np.zeros(n), "q": np.zeros(n)})


def _two_sample(s: np.ndarray, tau: float, dt: float) -> np.ndarray:
    # CASES.md §4: s_τ,k = (τ/dt)·s_{k−1} + (1 − τ/dt)·s_k, s_τ,0 = s_0
    out = s.copy()
    for k in range(1, s.shape[0]):
        out[k] = tau / dt * s[k - 1] + (1.0 - tau / dt) * s[k]
    return out


def _undelayed(data, theta):
    return Simulator(_model(delayed=False), data).outputs(theta)


@pytest.mark.parametrize("tau", TAUS)
def test_fractional_delay_is_np_interp_of_the_undelayed_output(tau):
    data = _doublet()
    model = _model(tau)
    y = Simulator(model, data).outputs(model.parameters.values)
    plain = _undelayed(data, model.parameters.values)
    t = data.time
    # np.interp holds the end values outside [t_0, t_N−1], as documented for the simulator
    np.testing.assert_allclose(y[:, 1], np.interp(t - tau, t, plain[:, 1]), rtol=0, atol=1e-13)
    np.testing.assert_array_equal(y[:, 0], plain[:, 0])  # α is not delayed


@pytest.mark.parametrize("tau", TAUS)
def test_two_sample_delay_is_the_reference_formula(tau):
    data = _doublet()
    model = _model(tau, "two_sample")
    y = Simulator(model, data).outputs(model.parameters.values)
    plain = _undelayed(data, model.parameters.values)
    np.testing.assert_allclose(y[:, 1], _two_sample(plain[:, 1], tau, DT), rtol=0, atol=1e-13)
    np.testing.assert_array_equal(y[:, 0], plain[:, 0])


def test_the_conventions_agree_for_delays_up_to_one_sample_and_differ_beyond():
    data = _doublet()
    for tau in (0.0, 0.3 * DT, 0.999 * DT, DT):
        a = Simulator(_model(tau), data).outputs(_model(tau).parameters.values)
        b = Simulator(_model(tau, "two_sample"), data).outputs(_model(tau).parameters.values)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-13)
    for tau in (2.5 * DT, -0.7 * DT):
        a = Simulator(_model(tau), data).outputs(_model(tau).parameters.values)
        b = Simulator(_model(tau, "two_sample"), data).outputs(_model(tau).parameters.values)
        assert np.max(np.abs(a - b)) > 1e-4


@pytest.mark.parametrize("convention", ["fractional", "two_sample"])
def test_each_maneuver_restarts_its_delay_and_each_batch_row_uses_its_own_tau(convention):
    first, second = _doublet(150, 0.1), _doublet(120, 0.3)
    model = _model(0.0, convention)
    theta = model.parameters.values
    rows = np.repeat(theta[None, :], 2, axis=0)
    rows[0, 5], rows[1, 5] = 2.5 * DT, -0.7 * DT
    sim = Simulator(model, [first, second])
    batch = sim.run(rows).outputs
    for b, tau in enumerate(rows[:, 5]):
        start = 0
        for data in (first, second):
            plain = _undelayed(data, rows[b])[:, 1]
            t = data.time
            expected = (
                np.interp(t - tau, t, plain)
                if convention == "fractional"
                else _two_sample(plain, tau, DT)
            )
            got = batch[b, start : start + t.shape[0], 1]
            np.testing.assert_allclose(got, expected, rtol=0, atol=1e-13)
            start += t.shape[0]


@pytest.mark.parametrize("convention", ["fractional", "two_sample"])
@pytest.mark.parametrize("tau", [0.3 * DT, 2.5 * DT, -0.7 * DT])
def test_sensitivity_equations_carry_the_delay_and_its_own_column(convention, tau):
    """G from the sensitivity-equation kernel equals central differences of whole delayed
    simulations, the ∂y/∂τ column included."""
    data = _doublet()
    problem = OutputErrorProblem(_model(tau, convention), data)
    theta = _model(tau, convention).parameters.values
    g, _ = problem.sensitivities_from_equations(theta)
    g_fd, _ = problem.sensitivities(theta, central=True, relative_step=1e-6)
    assert np.max(np.abs(g[:, 1, 5])) > 1e-2  # ∂q_τ/∂τ is not zero
    assert np.max(np.abs(g - g_fd)) <= 1e-5 * np.max(np.abs(g_fd))


def _measured(convention: str, seed: int = 7):
    data = _doublet(400)
    model = _model(TRUE["tau_q"], convention)
    y = Simulator(model, data).outputs(model.parameters.values)
    rng = np.random.default_rng(seed)
    # noise: 0.5 mrad on α, 1 mrad/s on q
    noisy = y + rng.normal(size=y.shape) * np.array([5e-4, 1e-3])
    return FlightData(
        data.time, {"de": data.channel("de")}, {"alpha": noisy[:, 0], "q": noisy[:, 1]}
    )


@pytest.mark.parametrize(
    "solver",
    [MNR(), MNR(sensitivities="equations"), MNRES()],
    ids=["MNR", "MNR-equations", "MNRES"],
)
def test_estimation_recovers_a_known_delay(solver):
    measured = _measured("fractional")
    start = _model(0.0)  # τ starts at 0 s, the other parameters at their true values × 0.8
    start = start.with_parameters(
        Parameters({n: (v * 0.8 if n != "tau_q" else 0.0) for n, v in TRUE.items()})
    )
    est = estimate(start, measured, solver=solver)
    assert est.converged, est.message
    i = list(est.names).index("tau_q")
    assert abs(est.values[i] - TRUE["tau_q"]) < 3.0 * est.std[i], (est.values[i], est.std[i])
    assert est.std[i] < 0.002  # s: the delay is resolved to a tenth of a sample


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"output_delays": {"r": "tau_q"}}, r"output_delays: 'r' is not an output"),
        ({"output_delays": {"q": "tau_x"}}, r"output_delays\['q'\]: expected the name"),
        ({"output_delays": {"q": 0.05}}, r"output_delays\['q'\]: expected the name"),
        ({"delay_convention": "cubic"}, r"delay_convention: expected one of"),
    ],
)
def test_bad_declarations_are_named_input_errors(kwargs, message):
    arguments = dict(
        states=("alpha", "q"),
        inputs=("de",),
        outputs=("alpha", "q"),
        f=sp_f,
        h=sp_h,
        parameters=Parameters(TRUE),
        output_delays={"q": "tau_q"},
    )
    arguments.update(kwargs)
    with pytest.raises(InputError, match=message):
        StateSpaceModel(**arguments)


def test_no_declaration_changes_nothing():
    model = _model(delayed=False)
    assert model.output_delays == {} and model.delay_convention == "fractional"
    assert model.output_delay_maps() == []


# ------------------------------------------------------------------ case files

_MODULE = """
import numpy as np

STATES = ("alpha", "q")
INPUTS = ("de",)
OUTPUTS = ("alpha", "q")
PARAMETERS = {"Za": -1.0, "Zd": -0.1, "Ma": -5.0, "Mq": -1.5, "Md": -8.0}


def f(t, x, u, theta):
    return np.array(
        [
            theta[0] * x[0] + x[1] + theta[1] * u[0],
            theta[2] * x[0] + theta[3] * x[1] + theta[4] * u[0],
        ]
    )


def h(t, x, u, theta):
    return np.array([x[0], x[1]])
"""


def _case_dir(tmp_path, extra_model: str, extra_parameters: str = "") -> object:
    measured = _measured("fractional")
    rows = np.column_stack(
        [measured.time, measured.channel("de"), measured.channel("alpha"), measured.channel("q")]
    )
    np.savetxt(tmp_path / "flight.csv", rows, delimiter=",", header="t,de,alpha,q", comments="")
    (tmp_path / "sp.py").write_text(_MODULE)
    (tmp_path / "case.toml").write_text(
        f"""title = "delayed q"
[data]
data_dir = "."
file = "flight.csv"
time = "t"
[data.inputs]
de = {{ column = "de" }}
[data.outputs]
alpha = {{ column = "alpha" }}
q = {{ column = "q" }}
[model]
module = "sp.py"
{extra_model}
[parameters]
{extra_parameters}
[initial_state]
default = 0.0
[biases.outputs]
q = 0.0
[estimation]
solver = "mnr"
"""
    )
    return tmp_path / "case.toml"


def test_case_file_declares_and_estimates_an_output_delay(tmp_path):
    from flightid.cases import load_case, run_case

    path = _case_dir(tmp_path, 'output_delays = { q = "tau_q" }\ndelay_convention = "fractional"')
    run = run_case(load_case(path), accuracy="cr")
    est = run.estimate
    assert est.converged, est.message
    # the new delay parameter comes after the biases (start 0 s, free)
    assert list(est.names)[-2:] == ["by_q", "tau_q"]
    assert abs(est.value("tau_q") - TRUE["tau_q"]) < 3.0 * est.stddev("tau_q")
    # the bias takes the mean of the seeded q noise (−1.6e-4 rad/s, itself 3.4 σ from 0)
    noise_q = np.random.default_rng(7).normal(size=(400, 2))[:, 1] * 1e-3
    assert abs(est.value("by_q") - noise_q.mean()) < 0.1 * est.stddev("by_q")


@pytest.mark.parametrize(
    "model_lines, parameters, message",
    [
        ('output_delays = { r = "tau" }', "", r"output_delays: 'r' is not an output"),
        ("output_delays = { q = 0.05 }", "", r"model.output_delays.q: expected a parameter name"),
        ('delay_convention = "cubic"', "", r"model.delay_convention"),
    ],
)
def test_case_file_delay_errors_are_named(tmp_path, model_lines, parameters, message):
    from flightid.cases import CaseError, load_case, run_case

    path = _case_dir(tmp_path, model_lines, parameters)
    with pytest.raises(CaseError, match=message):
        run_case(load_case(path), accuracy="none")


def test_case_file_passes_the_convention_to_the_model(tmp_path):
    from flightid.cases import load_case
    from flightid.cases.run import prepare_case

    path = _case_dir(tmp_path, 'output_delays = { q = "tau_q" }\ndelay_convention = "two_sample"')
    model = prepare_case(load_case(path)).model
    assert model.delay_convention == "two_sample"
    assert model.output_delays == {"q": "tau_q"}
    # [parameters] sets a new delay parameter like any other
    path = _case_dir(
        tmp_path, 'output_delays = { q = "tau_q" }', "tau_q = { value = 0.04, free = false }"
    )
    parameter = prepare_case(load_case(path)).model.parameters["tau_q"]
    assert (parameter.value, parameter.free) == (0.04, False)
