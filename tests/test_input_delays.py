"""Input time delays (issue 12 item 2): ``StateSpaceModel(input_delays={"de": "tau_de"})`` and
``[model] input_delays`` in case files.

Independent references: the undelayed model simulated on data whose input column was shifted
beforehand with ``np.interp`` (numpy's own linear interpolation and end-value hold), the
two-sample formula of CASES.md §4 written out sample by sample, and, for a smooth input, a
simulation on a ten times finer grid fed the exact delayed input sin(ω(t − τ)).
"""

from __future__ import annotations

import numpy as np
import pytest

from flightid.cases import CaseError, load_case, prepare_case, run_case
from flightid.data import FlightData
from flightid.errors import InputError
from flightid.estimation import MNR, MNRES, OutputErrorProblem, estimate
from flightid.model import Parameters, StateSpaceModel
from flightid.simulation import Simulator

DT = 0.02  # s
TAU_TRUE = 0.07  # s: 3.5 samples, not a multiple of DT
TAUS = [0.0, 0.3 * DT, DT, 3.5 * DT, -0.7 * DT, -2.3 * DT, 1000 * DT]  # s


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


TRUE = {"Za": -1.2, "Zd": -0.15, "Ma": -6.0, "Mq": -1.8, "Md": -9.0, "tau_de": TAU_TRUE}


def _model(tau: float = 0.0, convention: str = "fractional", delayed: bool = True):
    return StateSpaceModel(
        states=("alpha", "q"),
        inputs=("de",),
        outputs=("alpha", "q"),
        f=sp_f,
        h=sp_h,
        parameters=Parameters(dict(TRUE, tau_de=tau)),
        name="short_period",
        input_delays={"de": "tau_de"} if delayed else None,
        delay_convention=convention,
    )


def _doublet(n: int = 200, start: float = 0.2, amplitude: float = 0.05) -> FlightData:
    t = np.arange(n) * DT
    # doublet: +amplitude for 0.5 s, then −amplitude for 0.5 s
    de = np.where((t >= start) & (t < start + 0.5), amplitude, 0.0)
    de = np.where((t >= start + 0.5) & (t < start + 1.0), -amplitude, de)
    return FlightData(t, {"de": de}, {"alpha": np.zeros(n), "q": np.zeros(n)})


def _with_input(data: FlightData, de: np.ndarray) -> FlightData:
    return FlightData(
        data.time, {"de": de}, {"alpha": np.zeros(data.n_samples), "q": np.zeros(data.n_samples)}
    )


def _two_sample(s: np.ndarray, tau: float, dt: float) -> np.ndarray:
    # CASES.md §4: s_τ,k = (τ/dt)·s_{k−1} + (1 − τ/dt)·s_k, s_τ,0 = s_0
    out = s.copy()
    for k in range(1, s.shape[0]):
        out[k] = tau / dt * s[k - 1] + (1.0 - tau / dt) * s[k]
    return out


def _plain(data: FlightData, theta: np.ndarray, interpolation: str = "linear") -> np.ndarray:
    model = _model(delayed=False)
    return Simulator(model, data, input_interpolation=interpolation).outputs(theta)


# ------------------------------------------------------------------ the rule


@pytest.mark.parametrize("interpolation", ["linear", "zoh"])
@pytest.mark.parametrize("tau", TAUS)
def test_delay_is_the_undelayed_model_on_an_np_interp_shifted_input(tau, interpolation):
    data = _doublet()
    model = _model(tau)
    theta = model.parameters.values
    y = Simulator(model, data, input_interpolation=interpolation).outputs(theta)
    t, de = data.time, data.channel("de")
    # np.interp holds the end values outside [t_0, t_N−1], as documented for the simulator
    shifted = _with_input(data, np.interp(t - tau, t, de))
    np.testing.assert_allclose(y, _plain(shifted, theta, interpolation), rtol=0, atol=1e-14)
    if tau != 0.0:
        assert np.max(np.abs(y - _plain(data, theta, interpolation))) > 1e-4


@pytest.mark.parametrize("tau", [0.3 * DT, 3.5 * DT, -0.7 * DT])
def test_two_sample_convention_uses_the_reference_formula_on_the_input(tau):
    data = _doublet()
    model = _model(tau, "two_sample")
    theta = model.parameters.values
    y = Simulator(model, data).outputs(theta)
    shifted = _with_input(data, _two_sample(data.channel("de"), tau, DT))
    np.testing.assert_allclose(y, _plain(shifted, theta), rtol=0, atol=1e-14)


def test_a_smooth_input_delayed_matches_the_exact_delayed_input_on_a_fine_grid():
    """u(t) = sin(ω t): the delayed simulation at dt is the simulation fed sin(ω(t − τ)) on a
    grid ten times finer, within the second-order error of the sampling."""
    n, tau, omega = 300, 0.07, 2 * np.pi * 0.8
    t = np.arange(n) * DT
    start = 0.5  # s: the input starts after τ so the end hold does not enter
    u = np.where(t >= start, 0.05 * np.sin(omega * (t - start)), 0.0)
    model = _model(tau)
    theta = model.parameters.values
    y = Simulator(model, _with_input(FlightData(t, {"de": u}, {"alpha": u, "q": u}), u)).outputs(
        theta
    )
    fine_t = np.arange(10 * (n - 1) + 1) * (DT / 10)
    fine_u = np.where(fine_t - tau >= start, 0.05 * np.sin(omega * (fine_t - tau - start)), 0.0)
    fine = _plain(
        _with_input(FlightData(fine_t, {"de": fine_u}, {"alpha": fine_u, "q": fine_u}), fine_u),
        theta,
    )
    error = np.max(np.abs(y - fine[::10]))
    # measured 1.9e-3 relative (the linear interpolation of the samples between t_k − τ's
    # neighbours; 0.8e-3 with τ a multiple of DT, the plain sampling error)
    assert error < 4e-3 * np.max(np.abs(fine)), error
    # a delay off by one sample is far outside that error
    undelayed = _plain(FlightData(t, {"de": u}, {"alpha": u, "q": u}), theta)
    assert np.max(np.abs(undelayed - fine[::10])) > 10 * error


@pytest.mark.parametrize("convention", ["fractional", "two_sample"])
def test_each_maneuver_restarts_and_each_batch_row_uses_its_own_tau(convention):
    # the second maneuver starts inside its doublet: a delay reaching into the first
    # maneuver's last samples (−0.05) would differ from the held first value (+0.04)
    first, second = _doublet(150, 0.1), _doublet(120, 0.0, amplitude=0.04)
    model = _model(0.0, convention)
    rows = np.repeat(model.parameters.values[None, :], 3, axis=0)
    rows[:, 5] = 3.5 * DT, -0.7 * DT, 3.5 * DT
    batch = Simulator(model, [first, second]).run(rows).outputs
    for b, tau in enumerate(rows[:, 5]):
        start = 0
        for data in (first, second):
            t, de = data.time, data.channel("de")
            shifted = (
                np.interp(t - tau, t, de)
                if convention == "fractional"
                else _two_sample(de, tau, DT)
            )
            expected = _plain(_with_input(data, shifted), rows[b])
            got = batch[b, start : start + t.shape[0]]
            np.testing.assert_allclose(got, expected, rtol=0, atol=1e-14)
            start += t.shape[0]


@pytest.mark.parametrize("tau", [0.3 * DT, 3.5 * DT, -0.7 * DT])
def test_sensitivity_equations_carry_the_input_delay_column(tau):
    """G from MNR(equations) (the τ column by central differences of whole simulations)
    equals central differences of all columns; ∂y/∂τ is not zero."""
    data = _doublet()
    problem = OutputErrorProblem(_model(tau), data)
    theta = _model(tau).parameters.values
    g, _ = problem.sensitivities_from_equations(theta)
    g_fd, _ = problem.sensitivities(theta, central=True, relative_step=1e-6)
    assert np.max(np.abs(g[:, 1, 5])) > 1e-2
    assert np.max(np.abs(g - g_fd)) <= 1e-4 * np.max(np.abs(g_fd))


def _measured(seed: int = 5) -> FlightData:
    data = _doublet(400)
    model = _model(TAU_TRUE)
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
def test_estimation_recovers_a_known_input_delay(solver):
    measured = _measured()
    start = _model(0.0)  # τ starts at 0 s, the other parameters at their true values × 0.8
    start = start.with_parameters(
        Parameters({n: (v * 0.8 if n != "tau_de" else 0.0) for n, v in TRUE.items()})
    )
    est = estimate(start, measured, solver=solver)
    assert est.converged, est.message
    assert abs(est.value("tau_de") - TAU_TRUE) < 3.0 * est.stddev("tau_de")
    assert est.stddev("tau_de") < 0.002  # s: a tenth of a sample


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"input_delays": {"dr": "tau_de"}}, r"input_delays: 'dr' is not an input of the model;"),
        (
            {"input_delays": {"q": "tau_de"}},
            r"'q' is not an input of the model \('q' is an output: use output_delays\)",
        ),
        ({"input_delays": {"de": "tau_x"}}, r"input_delays\['de'\]: expected the name"),
        ({"input_delays": {"de": 0.05}}, r"input_delays\['de'\]: expected the name"),
        ({"output_delays": {"de": "tau_de"}}, r"\('de' is an input: use input_delays\)"),
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
    )
    arguments.update(kwargs)
    with pytest.raises(InputError, match=message):
        StateSpaceModel(**arguments)


def test_no_declaration_changes_nothing():
    model = _model(delayed=False)
    assert model.input_delays == {} and model.input_delay_maps() == []


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


def _case(tmp_path, model_lines: str, parameters: str = "", solver: str = "mnr"):
    measured = _measured()
    rows = np.column_stack(
        [measured.time, measured.channel("de"), measured.channel("alpha"), measured.channel("q")]
    )
    np.savetxt(tmp_path / "flight.csv", rows, delimiter=",", header="t,de,alpha,q", comments="")
    (tmp_path / "sp.py").write_text(_MODULE)
    (tmp_path / "case.toml").write_text(
        f"""title = "delayed elevator"
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
{model_lines}
[parameters]
{parameters}
[initial_state]
default = 0.0
[biases.outputs]
q = 0.0
[estimation]
solver = "{solver}"
"""
    )
    return tmp_path / "case.toml"


@pytest.mark.parametrize("solver", ["mnr", "mnres"])
def test_case_file_declares_and_estimates_an_input_delay(tmp_path, solver):
    path = _case(tmp_path, 'input_delays = { de = "tau_de" }', solver=solver)
    est = run_case(load_case(path), accuracy="cr").estimate
    assert est.converged, est.message
    # the new delay parameter comes after the biases (start 0 s, free)
    assert list(est.names) == ["Za", "Zd", "Ma", "Mq", "Md", "by_q", "tau_de"]
    assert abs(est.value("tau_de") - TAU_TRUE) < 3.0 * est.stddev("tau_de")


def test_case_file_sets_a_new_input_delay_parameter(tmp_path):
    path = _case(
        tmp_path, 'input_delays = { de = "tau_de" }', "tau_de = { value = 0.04, free = false }"
    )
    model = prepare_case(load_case(path)).model
    assert model.input_delays == {"de": "tau_de"}
    assert (model.parameters["tau_de"].value, model.parameters["tau_de"].free) == (0.04, False)


@pytest.mark.parametrize(
    "model_lines, message",
    [
        ('input_delays = { dr = "tau" }', r"input_delays: 'dr' is not an input"),
        ('input_delays = { alpha = "tau" }', r"'alpha' is an output: use output_delays"),
        ("input_delays = { de = 0.05 }", r"model.input_delays.de: expected a parameter name"),
        ('input_delays = "de"', r"model.input_delays"),
    ],
)
def test_case_file_input_delay_errors_are_named(tmp_path, model_lines, message):
    path = _case(tmp_path, model_lines)
    with pytest.raises(CaseError, match=message):
        prepare_case(load_case(path))
