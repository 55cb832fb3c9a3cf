"""Parameters per maneuver inside f and h (issue 12 item 5).

``StateSpaceModel(function_parameters=..., maneuver_parameters=...)`` / ``with_per_maneuver``
and the case-file entry ``NAME = { value, per_maneuver = true }``: in maneuver k the slot NAME
of the θ that f and h receive takes the value of the parameter NAME_k.

Independent references: each maneuver simulated on its own by the plain model with NAME set
to that maneuver's value (the substitution must reproduce it exactly); the true values the
data were simulated with (recovered within 3 σ); a model with one shared NAME, which cannot
fit both maneuvers (its cost is much higher).
"""

from __future__ import annotations

import numpy as np
import pytest

from flightid.cases import CaseError, load_case, prepare_case, run_case
from flightid.cases.build import build_model
from flightid.data import FlightData
from flightid.errors import InputError, InputTypeError
from flightid.estimation import MNR, MNRES, OutputErrorProblem, estimate
from flightid.model import Parameters, StateSpaceModel
from flightid.simulation import Simulator

DT = 0.02  # s


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


NAMES = ("Za", "Zd", "Ma", "Mq", "Md")
SHARED = {"Za": -1.2, "Zd": -0.15, "Ma": -6.0, "Mq": -1.8}
# the control power differs between the two maneuvers (e.g. two flight conditions)
MD_TRUE = (-9.0, -5.0)  # 1/s²


def _model(md: float = -8.0) -> StateSpaceModel:
    return StateSpaceModel(
        states=("alpha", "q"),
        inputs=("de",),
        outputs=("alpha", "q"),
        f=sp_f,
        h=sp_h,
        parameters=Parameters(dict(SHARED, Md=md)),
        name="short_period",
    )


def _doublet(n: int, start: float, amplitude: float = 0.05) -> FlightData:
    t = np.arange(n) * DT
    # doublet: +amplitude for 0.5 s, then −amplitude for 0.5 s
    de = np.where((t >= start) & (t < start + 0.5), amplitude, 0.0)
    de = np.where((t >= start + 0.5) & (t < start + 1.0), -amplitude, de)
    return FlightData(t, {"de": de}, {"alpha": np.zeros(n), "q": np.zeros(n)})


def _measured(seed: int = 11) -> list[FlightData]:
    """Two maneuvers, each simulated with its own Mδ, with seeded noise."""
    rng = np.random.default_rng(seed)
    maneuvers = []
    for data, md in zip((_doublet(300, 0.2), _doublet(250, 0.4, -0.04)), MD_TRUE, strict=True):
        model = _model(md)
        y = Simulator(model, data).outputs(model.parameters.values)
        # noise: 0.5 mrad on α, 1 mrad/s on q
        noisy = y + rng.normal(size=y.shape) * np.array([5e-4, 1e-3])
        maneuvers.append(
            FlightData(
                data.time, {"de": data.channel("de")}, {"alpha": noisy[:, 0], "q": noisy[:, 1]}
            )
        )
    return maneuvers


# ------------------------------------------------------------------ the substitution


def test_names_and_order_are_the_others_then_maneuver_major_copies():
    model = _model().with_per_maneuver(["Md", "Mq"], 3)
    # the others in order, then (Mq, Md) of maneuver 1, of 2, of 3 (model order: Mq before Md)
    assert model.parameters.names == [
        "Za", "Zd", "Ma",
        "Mq_1", "Md_1", "Mq_2", "Md_2", "Mq_3", "Md_3",
    ]  # fmt: skip
    assert model.function_parameters == NAMES
    assert model.maneuver_parameters == {
        "Mq": ("Mq_1", "Mq_2", "Mq_3"),
        "Md": ("Md_1", "Md_2", "Md_3"),
    }
    # θ_f of maneuver 3 takes Mq_3 and Md_3 into the slots 3 and 4
    np.testing.assert_array_equal(model.function_theta_map(2), [0, 1, 2, 7, 8])
    # the copies keep the settings of the base parameter
    assert model.parameters["Md_2"].value == -8.0 and model.parameters["Md_2"].free
    # one maneuver: nothing to expand
    assert _model().with_per_maneuver(["Md"], 1).parameters.names == list(NAMES)


def test_each_maneuver_is_simulated_with_its_own_copy():
    maneuvers = _measured()
    model = _model().with_per_maneuver(["Md"], 2)
    theta = model.parameters.with_values({"Md_1": MD_TRUE[0], "Md_2": MD_TRUE[1]}).values
    y = Simulator(model, maneuvers).outputs(theta)
    start = 0
    for data, md in zip(maneuvers, MD_TRUE, strict=True):
        # reference: the plain model with Mδ of this maneuver, on this maneuver alone
        plain = _model(md)
        expected = Simulator(plain, data).outputs(plain.parameters.values)
        np.testing.assert_array_equal(y[start : start + data.n_samples], expected)
        start += data.n_samples


def test_sensitivity_equations_handle_the_copies():
    """G from the sensitivity equations equals central differences; the copy of one maneuver
    has zero sensitivity in the other maneuver."""
    maneuvers = _measured()
    model = _model().with_per_maneuver(["Md"], 2)
    problem = OutputErrorProblem(model, maneuvers)
    theta = model.parameters.with_values({"Md_1": MD_TRUE[0], "Md_2": MD_TRUE[1]}).values
    g, _ = problem.sensitivities_from_equations(theta)
    g_fd, _ = problem.sensitivities(theta, central=True, relative_step=1e-6)
    n1 = maneuvers[0].n_samples
    md1, md2 = model.parameters.index("Md_1"), model.parameters.index("Md_2")
    assert np.max(np.abs(g[:n1, 1, md1])) > 1e-2 and np.max(np.abs(g[n1:, 1, md2])) > 1e-2
    assert np.all(g[n1:, :, md1] == 0.0) and np.all(g[:n1, :, md2] == 0.0)
    assert np.max(np.abs(g - g_fd)) <= 1e-5 * np.max(np.abs(g_fd))


@pytest.mark.parametrize(
    "solver",
    [MNR(), MNR(sensitivities="equations"), MNRES()],
    ids=["MNR", "MNR-equations", "MNRES"],
)
def test_estimation_recovers_each_maneuvers_value(solver):
    maneuvers = _measured()
    start = _model(-7.0).with_per_maneuver(["Md"], 2)
    start = start.with_parameters(
        start.parameters.with_values({n: 0.8 * v for n, v in SHARED.items()})
    )
    est = estimate(start, maneuvers, solver=solver)
    assert est.converged, est.message
    for k, md in enumerate(MD_TRUE, start=1):
        name = f"Md_{k}"
        assert abs(est.value(name) - md) < 3.0 * est.stddev(name), (name, est.value(name))
    # the two values are resolved apart by far more than their bounds
    assert abs(est.value("Md_1") - est.value("Md_2")) > 20 * est.stddev("Md_1")


def test_one_shared_value_cannot_fit_both_maneuvers():
    maneuvers = _measured()
    per = estimate(_model(-7.0).with_per_maneuver(["Md"], 2), maneuvers, solver=MNR())
    shared = estimate(_model(-7.0), maneuvers, solver=MNR())
    assert per.converged and shared.converged
    # the noise added to q has variance (1 mrad/s)²: the per-maneuver model reaches it, the
    # shared Mδ leaves the difference between the maneuvers in the q residuals
    assert per.r_diag[1] == pytest.approx(1e-6, rel=0.2)
    assert shared.r_diag[1] > 10.0 * per.r_diag[1], (shared.r_diag, per.r_diag)
    # ML cost ∝ log det R̂
    assert np.prod(shared.r_diag) > 10.0 * np.prod(per.r_diag)


# ------------------------------------------------------------------ Python API errors


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"maneuver_parameters": {"Mx": ("Md_1",)}}, r"'Mx' is not one of the function"),
        ({"maneuver_parameters": {"Md": ("Md_1", "Md_9")}}, r"'Md_9' is not a parameter"),
        ({"maneuver_parameters": {"Md": ("Md_1", "Za")}}, r"feeds several slots"),
        ({"maneuver_parameters": {}}, r"\['Md'\] are neither parameters"),
        ({"maneuver_parameters": ["Md"]}, r"maneuver_parameters: expected a mapping"),
    ],
)
def test_bad_declarations_are_named_input_errors(kwargs, message):
    arguments = dict(
        states=("alpha", "q"),
        inputs=("de",),
        outputs=("alpha", "q"),
        f=sp_f,
        h=sp_h,
        parameters=Parameters(dict(SHARED, Md_1=-8.0, Md_2=-8.0)),
        function_parameters=NAMES,
    )
    arguments.update(kwargs)
    with pytest.raises((InputError, InputTypeError), match=message):
        StateSpaceModel(**arguments)


def test_expansion_and_simulator_errors_are_named():
    with pytest.raises(InputError, match=r"\['Mx'\] are not parameters"):
        _model().with_per_maneuver(["Mx"], 2)
    with pytest.raises(InputError, match=r"n_maneuvers: expected at least 1"):
        _model().with_per_maneuver(["Md"], 0)
    with pytest.raises(InputError, match=r"per-maneuver parameters \['Md'\] for 3 maneuvers"):
        Simulator(_model().with_per_maneuver(["Md"], 3), _measured())


# ------------------------------------------------------------------ case files

_MODULE = """
import numpy as np

STATES = ("alpha", "q")
INPUTS = ("de",)
OUTPUTS = ("alpha", "q")
PARAMETERS = {"Za": -1.0, "Zd": -0.1, "Ma": -5.0, "Mq": -1.5, "Md": -7.0}


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


def _case(tmp_path, parameters: str, solver: str = "mnr", extra: str = "") -> object:
    files = []
    for k, data in enumerate(_measured(), start=1):
        rows = np.column_stack(
            [data.time, data.channel("de"), data.channel("alpha"), data.channel("q")]
        )
        np.savetxt(tmp_path / f"m{k}.csv", rows, delimiter=",", header="t,de,alpha,q", comments="")
        files.append(f"m{k}.csv")
    (tmp_path / "sp.py").write_text(_MODULE)
    (tmp_path / "case.toml").write_text(
        f"""title = "per-maneuver control power"
[data]
data_dir = "."
files = {files!r}
time = "t"
[data.inputs]
de = {{ column = "de" }}
[data.outputs]
alpha = {{ column = "alpha" }}
q = {{ column = "q" }}
[model]
module = "sp.py"
[parameters]
{parameters}
[initial_state]
default = 0.0
[biases.outputs]
q = 0.0
[estimation]
solver = "{solver}"
{extra}
"""
    )
    return tmp_path / "case.toml"


@pytest.mark.parametrize("solver", ["mnr", "mnres"])
def test_case_file_estimates_a_parameter_per_maneuver(tmp_path, solver):
    path = _case(tmp_path, "Md = { value = -7.0, per_maneuver = true }", solver)
    est = run_case(load_case(path), accuracy="cr").estimate
    assert est.converged, est.message
    # the model's other parameters, the copies (maneuver-major), then the output bias
    assert list(est.names) == ["Za", "Zd", "Ma", "Mq", "Md_1", "Md_2", "by_q"]
    for k, md in enumerate(MD_TRUE, start=1):
        name = f"Md_{k}"
        assert abs(est.value(name) - md) < 3.0 * est.stddev(name), (name, est.value(name))


def test_case_file_values_path_sets_the_copies(tmp_path):
    path = _case(tmp_path, "Md = { value = -7.0, per_maneuver = true, free = false }")
    case = load_case(path)
    prepared = prepare_case(case)
    assert [p.name for p in prepared.model.parameters if not p.free] == ["Md_1", "Md_2"]
    model, data = build_model(
        case, list(prepared.maneuvers), base=prepared.base, values={"Md_1": -9.0, "Md_2": -5.0}
    )
    theta = model.parameters.values
    np.testing.assert_array_equal(
        model.function_theta(theta, 1)[:5], [-1.0, -0.1, -5.0, -1.5, -5.0]
    )
    assert model.function_theta(theta, 0)[4] == -9.0


@pytest.mark.parametrize(
    "parameters, extra, message",
    [
        ("Mx = { value = 1.0, per_maneuver = true }", "", r"parameters.Mx: not a parameter"),
        ('Md = { value = 1.0, per_maneuver = "yes" }', "", r"parameters.Md.per_maneuver"),
        (
            "tau = { value = 0.0, per_maneuver = true }",
            "",
            r"parameters.tau.per_maneuver: 'tau' is a time delay",
        ),
    ],
)
def test_case_file_errors_are_named(tmp_path, parameters, extra, message):
    path = _case(tmp_path, parameters, extra=extra)
    if "tau" in parameters:
        text = path.read_text().replace(
            'module = "sp.py"', 'module = "sp.py"\noutput_delays = { q = "tau" }'
        )
        path.write_text(text)
    with pytest.raises(CaseError, match=message):
        prepare_case(load_case(path))


def test_case_file_refuses_a_prediction_with_copies(tmp_path):
    path = _case(tmp_path, "Md = { value = -7.0, per_maneuver = true }")
    text = path.read_text() + '\n[prediction]\nfiles = ["m1.csv"]\n'
    path.write_text(text)
    with pytest.raises(CaseError, match=r"prediction: not available with parameters per maneuver"):
        prepare_case(load_case(path))
