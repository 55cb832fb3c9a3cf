"""Built-in airplane models through case files: a CSV of simulated Navion lateral data, a case
TOML with the built-in lateral model and its aerodynamic terms, ``flightid run`` end to end."""

import json

import numpy as np
import pytest

from flightid.aircraft import Accelerometer, airplane_from_table, body_state, navion
from flightid.cases import load_case
from flightid.cases.build import base_model
from flightid.cases.spec import CaseError
from flightid.cli.main import main
from flightid.paper.example3 import (
    LATERAL_TERMS,
    OUTPUTS,
    SIMULATION_VALUES,
    _truth,
    example3_data,
    example3_start_values,
)

CHANNELS = ("da", "dr", "u", "w", "q")


def _toml_list(items):
    return "[" + ", ".join(f'"{i}"' for i in items) + "]"


def _write_csv(path, data):
    names = ["time", *CHANNELS, *OUTPUTS]
    columns = [data.time] + [data.channel(n) for n in CHANNELS + OUTPUTS]
    np.savetxt(path, np.column_stack(columns), delimiter=",", header=",".join(names),
               comments="", fmt="%.12g")  # fmt: skip


def _case_text(csv_name, x0, airplane_lines, model_extra="", start=None):
    """Case TOML: built-in lateral model with the aero terms of RP-1153 table V."""
    start = example3_start_values() if start is None else start
    aero = "\n".join(f"{c} = {_toml_list(terms)}" for c, terms in LATERAL_TERMS.items())
    parameters = "\n".join(
        # scale: floor of the relative convergence test and first perturbation (as example 3)
        f"{n} = {{ value = {float(v)!r}, scale = {max(abs(SIMULATION_VALUES[n]), 0.01)!r} }}"
        for n, v in start.items()
    )
    x0_lines = "\n".join(f"{s} = {float(v)!r}" for s, v in x0.items())
    return f"""title = "Navion lateral, built-in model"
[data]
data_dir = "."
file = "{csv_name}"
time = "time"
[data.inputs]
{chr(10).join(f'{n} = "{n}"' for n in CHANNELS)}
[data.outputs]
{chr(10).join(f'{n} = "{n}"' for n in OUTPUTS)}

[model]
type = "lateral"
controls = ["da", "dr"]
outputs = {_toml_list(OUTPUTS)}
{model_extra}
[model.airplane]
{airplane_lines}
[model.aero]
{aero}

[parameters]
{parameters}

[initial_state]
{x0_lines}

[estimation]
solver = "mnres"
noise = "max"
[estimation.convergence]
max_iterations = 200
"""


@pytest.fixture(scope="module")
def trim_x0():
    trim = _truth()[0]
    x = body_state(trim.V, trim.alpha, trim.beta, trim.theta, trim.phi)
    # lateral states (v, p, r, l_xz, l_yz, l_zz) at trim
    return dict(zip(("v", "p", "r", "l_xz", "l_yz", "l_zz"), x[[1, 3, 5, 6, 7, 8]], strict=True))


def _navion_lines():
    airplane = navion(thrust_input=None)
    return "\n".join(
        f"{k} = {float(getattr(airplane, k))!r}"
        for k in ("mass", "Ix", "Iy", "Iz", "Ixz", "S", "b", "cbar", "density")
    )


def test_flightid_run_recovers_the_simulation_values(tmp_path, trim_x0, capsys):
    # RP-1153 table IV noise case 2, seeded; outputs of the 6-DOF run (no numba compilation)
    data = example3_data(2, seed=3, source="6dof")
    _write_csv(tmp_path / "navion_lateral.csv", data)
    case = tmp_path / "navion_lateral.toml"
    case.write_text(_case_text("navion_lateral.csv", trim_x0, _navion_lines()))
    assert main(["run", str(case), "--json", "--quiet"]) == 0
    entry = json.loads(capsys.readouterr().out)["results"][0]
    assert entry["converged"], entry["message"]
    estimates = {p["name"]: p for p in entry["parameters"]}
    assert set(estimates) == set(SIMULATION_VALUES)
    for name, truth in SIMULATION_VALUES.items():
        value, std = estimates[name]["value"], estimates[name]["std"]
        # every estimate within 3 Cramér–Rao bounds of its simulation value (RP-1153 table V)
        print(f"{name:14s} {value:9.4f} ± {std:.4f} (simulation {truth})")
        assert abs(value - truth) < 3 * std, (name, value, truth, std)
    # the large derivatives within 5 %
    for name in ("CY_beta", "Cl_beta", "Cl_phat", "Cl_da", "Cl_alpha_phat", "Cn_alpha_rhat"):
        assert abs(estimates[name]["value"] / SIMULATION_VALUES[name] - 1) < 0.05, name


def _model_case(tmp_path, model_lines, name="case.toml"):
    """A case whose [model] section is ``model_lines`` (the data file is not read)."""
    path = tmp_path / name
    path.write_text(
        'title = "t"\n[data]\nfile = "none.csv"\ntime = "time"\n[data.outputs]\nbeta = "beta"\n'
        f"[model]\n{model_lines}\n"
    )
    return load_case(path)


LATERAL = 'type = "lateral"\nairplane = { library = "navion" }\n'


def test_library_airplane_with_overrides():
    from flightid.aircraft.units import isa_density

    plain = airplane_from_table({"library": "navion"})
    assert plain == navion(thrust_input=None)
    high = airplane_from_table({"library": "navion", "altitude": 1500.0, "mass": 1200.0})
    assert high.rho == pytest.approx(isa_density(1500.0), rel=1e-12)  # ISA at 1500 m
    assert high.mass == 1200.0 and high.Ix == plain.Ix


def test_builtin_model_from_a_case_with_spline_terms(tmp_path):
    case = _model_case(
        tmp_path,
        'type = "wind_axis_longitudinal"\nairplane = { library = "navion" }\n'
        'outputs = ["V", "alpha", "q", "az"]\n'
        '[model.aero]\nCD = ["1", "alpha"]\nCL = ["1", "alpha", "spline1(alpha,0.15)"]\n'
        'Cm = ["1", "alpha", "qhat", "de"]\n',
    )
    model, description = base_model(case)
    assert "built-in wind_axis_longitudinal" in description
    assert "CL_alpha_s0p15" in model.parameters.names
    assert model.states == ("V", "alpha", "theta", "q")
    assert model.inputs == ("de",)
    assert model.outputs == ("V", "alpha", "q", "az")


def test_builtin_model_accelerometer_convention(tmp_path):
    # spec.py decides which [model] keys a case file may hold; the builder reads
    # model.accelerometer when it is there (a Case edited here stands in for the file)
    from dataclasses import replace

    case = _model_case(tmp_path, LATERAL + 'outputs = ["ay"]\n[model.aero]\nCY = ["beta"]\n')
    default, _ = base_model(case)
    flipped, _ = base_model(
        replace(case, model={**case.model, "accelerometer": {"ay": "left", "unit": "m/s^2"}})
    )
    x = np.array([2.0, 0.0, 0.0, 0.0, 0.0, 1.0])  # v = 2 m/s: β ≈ 0.037 rad
    u = np.array([53.6, 0.0, 0.0])
    theta = np.array([-0.4])
    ay = default.h(0.0, x, u, theta)[0]
    assert flipped.h(0.0, x, u, theta)[0] == pytest.approx(-9.80665 * ay, rel=1e-14)
    assert Accelerometer.from_value({"ay": "left", "unit": "m/s^2"}).factors(9.80665)[1] < 0
    with pytest.raises(CaseError, match="model.accelerometer.az: expected one of"):
        base_model(replace(case, model={**case.model, "accelerometer": {"az": "sideways"}}))


@pytest.mark.parametrize(
    ("lines", "message"),
    [
        ('type = "lateral"\nairplane = { library = "navion", wingspan = 10.0 }\n'
         '[model.aero]\nCY = ["beta"]\n', "model.airplane.wingspan: unknown key"),
        ('type = "lateral"\nairplane = { library = "cessna" }\n[model.aero]\nCY = ["beta"]\n',
         "model.airplane.library: expected one of \\['navion'\\]"),
        ('type = "lateral"\nairplane = { mass = 1000.0 }\n[model.aero]\nCY = ["beta"]\n',
         "model.airplane.Ix: missing"),
        ('type = "lateral"\nairplane = { library = "navion", mass = -1.0 }\n'
         '[model.aero]\nCY = ["beta"]\n', "Airplane.mass: expected a positive"),
        (LATERAL + '[model.aero]\nCY = ["spline1(alpha)"]\n', "model.aero: term"),
        (LATERAL + '[model.aero]\nCY = "beta"\n', "model.aero.CY: expected a list of terms"),
        (LATERAL + 'controls = ["da"]\n[model.aero]\nCY = ["gamma"]\n',
         "model: .*unknown signal 'gamma'"),
        (LATERAL + 'outputs = ["alpha_dot"]\n[model.aero]\nCY = ["beta"]\n',
         "model: outputs: unknown output names"),
    ],
)  # fmt: skip
def test_builtin_model_errors_name_the_key(tmp_path, lines, message):
    with pytest.raises(CaseError, match=message):
        base_model(_model_case(tmp_path, lines))


def test_measured_initial_body_states_are_derived_from_flight_variables():
    from flightid.cases.build import _first_measured
    from flightid.cases.spec import CaseError
    from flightid.data import FlightData

    V, alpha, beta, theta, phi = 53.6, 0.06, 0.02, 0.05, -0.3
    t = np.arange(3) * 0.05
    data = FlightData(
        t,
        outputs={
            n: np.full(3, v)
            for n, v in (("V", V), ("alpha", alpha), ("beta", beta), ("theta", theta), ("phi", phi))
        },
    )
    # body_state: (u, v, w, p, q, r, l_xz, l_yz, l_zz) from V, α, β, Θ, Φ [2.19–2.24]
    expected = body_state(V, alpha, beta, theta, phi)
    for state, index in (("u", 0), ("v", 1), ("w", 2), ("l_xz", 6), ("l_yz", 7), ("l_zz", 8)):
        assert _first_measured(data, state, f"initial_state.{state}") == pytest.approx(
            expected[index], rel=1e-12, abs=1e-15
        )
    no_theta = FlightData(t, outputs={"phi": np.full(3, phi)})
    with pytest.raises(CaseError, match=r"initial_state.l_zz: .*missing \['theta'\]"):
        _first_measured(no_theta, "l_zz", "initial_state.l_zz")
