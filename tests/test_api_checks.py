"""The public API at the front door: wrong argument types and values are named errors
(``flightid.errors``), complex data are refused, a record too short to estimate from is
refused before estimating, batch conditions stay what they say, and every case-table value is
checked with a ``CaseError`` naming its key."""

from __future__ import annotations

import copy
import re
import shutil
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from flightid import FPS, MNR, MNRES, FlightData, Parameter, Parameters, StateSpaceModel, estimate
from flightid.cases.checks import CaseError
from flightid.cases.spec import parse_case
from flightid.errors import FlightIdError, InputError, InputTypeError

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "examples" / "csv_walkthrough"
sys.path.insert(0, str(WALK))
import short_period as sp  # noqa: E402

T = np.arange(50) * 0.02
DE = np.where((T > 0.2) & (T < 0.4), 0.05, 0.0)


def _parameters() -> Parameters:
    return Parameters([Parameter(k, v) for k, v in sp.PARAMETERS.items()])


def _model() -> StateSpaceModel:
    return StateSpaceModel(sp.STATES, sp.INPUTS, sp.OUTPUTS, sp.f, sp.h, _parameters())


def _data(n: int = 50) -> FlightData:
    return FlightData(T[:n], {"de": DE[:n]}, {"alpha": np.sin(T[:n]), "q": np.cos(T[:n])})


# each call with a wrong argument: (the call, the error class, the message's start)
WRONG = {
    "FlightData inputs of text": (
        lambda: FlightData(T, {"de": "abc"}), InputTypeError, r"inputs\['de'\]: expected a"),
    "FlightData inputs of objects": (
        lambda: FlightData(T, {"de": [object()] * 50}), InputTypeError, r"inputs\['de'\]: "),
    "FlightData complex input": (
        lambda: FlightData(T, {"de": DE + 1j * DE}), InputTypeError,
        r"inputs\['de'\]: expected real numbers, got complex values"),
    "FlightData complex matrix": (
        lambda: FlightData(T, None, np.ones((50, 1)) * (1 + 0j), output_names=["a"]),
        InputTypeError, r"outputs: expected real numbers, got complex"),
    "FlightData complex time": (
        lambda: FlightData(T + 0j, {"de": DE}), InputTypeError, r"time: expected real numbers"),
    "FlightData name": (
        lambda: FlightData(T, {"de": DE}, name=5), InputTypeError, r"name: expected a string"),
    "FlightData units": (
        lambda: FlightData(T, {"de": DE}, units=["rad"]), InputTypeError, r"units: expected"),
    "FlightData uniform_rtol": (
        lambda: FlightData(T, {"de": DE}, uniform_rtol="x"), InputError, r"uniform_rtol"),
    "Parameter value text": (
        lambda: Parameter("a", "1.5"), InputTypeError, r"Parameter 'a': value: expected a real"),
    "Parameter free text": (
        lambda: Parameter("a", 1.0, free="no"), InputTypeError, r"Parameter 'a': free must be"),
    "Parameter scale text": (
        lambda: Parameter("a", 1.0, scale="x"), InputTypeError, r"Parameter 'a': scale: expected"),
    "Parameter lower text": (
        lambda: Parameter("a", 1.0, lower="x"), InputTypeError, r"Parameter 'a': lower: expected"),
    "Parameter lower NaN": (
        lambda: Parameter("a", 1.0, lower=float("nan")), InputError, r"Parameter 'a': lower"),
    "Parameter unit": (
        lambda: Parameter("a", 1.0, unit=5), InputTypeError, r"Parameter 'a': unit must be"),
    "Parameters of a number": (
        lambda: Parameters(5), InputTypeError, r"parameters: expected Parameter objects"),
    "StateSpaceModel states number": (
        lambda: StateSpaceModel(5, sp.INPUTS, sp.OUTPUTS, sp.f, sp.h, _parameters()),
        InputTypeError, r"states: expected a list of names"),
    "StateSpaceModel name": (
        lambda: StateSpaceModel(sp.STATES, sp.INPUTS, sp.OUTPUTS, sp.f, sp.h, _parameters(),
                                name=5), InputTypeError, r"name: expected a string"),
    "MNRES unknown setting": (
        lambda: MNRES(max_iterations=5), InputTypeError, r"MNRES.max_iterations: not a setting"),
    "MNRES window": (lambda: MNRES(form="batch", window=1), InputError, r"MNRES.window"),
    "MNRES max_condition text": (
        lambda: MNRES(max_condition="big"), InputTypeError, r"MNRES.max_condition: expected a"),
    "MNR relative_step text": (
        lambda: MNR(relative_step="x"), InputTypeError, r"MNR.relative_step: expected a number"),
    "MNR central text": (
        lambda: MNR(central="yes"), InputTypeError, r"MNR.central: expected True or False"),
    "MNR too many positional": (
        lambda: MNR(1e-6, False, "differences", 10, 1.0, 3), InputTypeError, r"MNR: expected at"),
    "FPS unknown setting": (
        lambda: FPS(max_evaluations=3), InputTypeError, r"FPS.max_evaluations: not a setting"),
    "FPS max_restarts": (lambda: FPS(max_restarts=-1), InputError, r"FPS.max_restarts"),
    "estimate data None": (
        lambda: estimate(_model(), None), InputTypeError, r"data: expected a FlightData"),
    "estimate R text": (
        lambda: estimate(_model(), _data(), noise="fixed", R="x"), InputTypeError, r"R: expected"),
    "estimate compiled text": (
        lambda: estimate(_model(), _data(), compiled="no"), InputTypeError, r"compiled: expected"),
    "estimate progress number": (
        lambda: estimate(_model(), _data(), progress=5), InputTypeError, r"progress: expected"),
    # 3 samples × 2 outputs = 6 measurements for 6 free parameters (ended in an internal error
    # when the result folder was written)
    "estimate on 3 samples": (
        lambda: estimate(_model(), _data(3), compiled=False), InputError,
        r"data: 3 samples × 2 outputs = 6 scalar measurements for 6 free parameters"),
}  # fmt: skip


@pytest.mark.parametrize("name", list(WRONG))
def test_wrong_arguments_are_named_errors(name):
    call, error, message = WRONG[name]
    with pytest.raises(error, match=message) as caught:
        call()
    assert isinstance(caught.value, FlightIdError)


def test_right_arguments_still_pass():
    """numpy numbers, 0-d arrays and dataclasses.replace go through the checks."""
    from dataclasses import replace

    p = Parameter("a", np.float32(1.5), free=np.bool_(True), scale=np.array(2.0), lower=-np.inf)
    assert (p.value, p.free, p.scale) == (1.5, True, 2.0)
    assert replace(MNRES(form="batch", window=10), window=12).window == 12
    data = FlightData(T, {"de": DE}, units={"de": "rad"}, name="m")
    assert data.input("de").dtype == np.float64


def test_enough_rows_estimate():
    """4 samples × 2 outputs = 8 measurements > 6 parameters: estimated (no error)."""
    result = estimate(_model(), _data(4), compiled=False)
    assert np.all(np.isfinite(result.values))


# ------------------------------------------------------------------ batch conditions


def test_batch_cells_stay_what_they_say(tmp_path):
    from flightid.batch.plan import expand_template

    (tmp_path / "case.toml").write_text('title = "{{ label }}"\n', encoding="utf-8")
    (tmp_path / "conditions.csv").write_text(
        "name,label,mass,speed,drag\nc1,a,1_000,nan,-2.5e-3\n", encoding="utf-8"
    )
    batch = tmp_path / "batch.toml"
    batch.write_text('[batch]\ntemplate = "case.toml"\ntable = "conditions.csv"\n')
    (case,) = expand_template(batch)
    # "1_000" is not 1000 and "nan" not a number the JSON record cannot hold; -2.5e-3 is
    assert case.conditions == {"label": "a", "mass": "1_000", "speed": "nan", "drag": -2.5e-3}


def test_a_nan_cell_shows_the_case_error_not_a_json_error(tmp_path):
    """A NaN cell used as a start value: the case's own error (a finite number expected) is
    recorded; the record of the failed case was an internal JSON error before."""
    from flightid.batch import run_batch

    walk = tmp_path / "walk"
    shutil.copytree(WALK, walk)
    template = (walk / "my_case.toml").read_text().replace("Ma = -3.0", "Ma = {{Ma0}}")
    template = template.replace('data_dir = "."', f'data_dir = "{walk.as_posix()}"')
    template = template.replace('module = "short_period.py"',
                                f'module = "{(walk / "short_period.py").as_posix()}"')  # fmt: skip
    (walk / "template.toml").write_text(template, encoding="utf-8")
    (walk / "conditions.csv").write_text("name,Ma0\nbad,nan\n", encoding="utf-8")
    batch = walk / "envelope.toml"
    batch.write_text('[batch]\ntemplate = "template.toml"\ntable = "conditions.csv"\n')
    result = run_batch([batch], tmp_path / "out", workers=1)
    assert result.failed == ("bad",)
    record = (tmp_path / "out" / "cases" / "bad" / "batch.json").read_text()
    assert "parameters.Ma: expected a finite number, got nan" in record
    assert "internal error" not in record


# ------------------------------------------------------------------ every case-table value

CASE = """
title = "t"
[data]
data_dir = "."
file = "my_flight.csv"
time = "time"
start = 0.5
stop = 9.0
[data.inputs]
de = { column = "elevator", unit = "deg", to = "rad" }
[data.outputs]
alpha = { column = "AOA", unit = "deg", to = "rad" }
q = { column = "pitch_rate", unit = "deg/s", to = "rad/s" }
[model]
module = "short_period.py"
[parameters]
Ma = -3.0
Mde = { value = -5.0, free = true, scale = 1.0, lower = -20.0, upper = 0.0, unit = "1/s2" }
[initial_state]
default = "measured"
q = { value = "measured", channel = "q", scale = 0.1 }
[biases.outputs]
alpha = { value = 0.0, free = true, scale = 0.01 }
[estimation]
solver = "mnr"
noise = "max"
compiled = false
[estimation.solver_settings]
relative_step = 1e-6
[estimation.convergence]
max_iterations = 20
[accuracy]
confidence = 0.95
bound_factor = 1.0
correlation_warning = 0.9
methods = ["cr"]
budget = 100
seed = 0
[output]
figures = false
"""
RAW = tomllib.loads(CASE)


def _leaves(table, prefix=()):
    for key, value in table.items():
        if isinstance(value, dict):
            yield from _leaves(value, (*prefix, key))
        else:
            yield (*prefix, key), value


# wrong values of each kind; a value of the key's own type is skipped (it may be right)
WRONG_VALUES = {"text": "x", "list": [1], "table": {"a": 1}, "bool": True, "nan": float("nan")}
KEYS = [path for path, _ in _leaves(RAW) if path[:2] != ("data", "data_dir")]


def _set(raw: dict, path: tuple, value) -> dict:
    raw = copy.deepcopy(raw)
    table = raw
    for key in path[:-1]:
        table = table[key]
    table[path[-1]] = value
    return raw


@pytest.mark.parametrize("kind", list(WRONG_VALUES))
@pytest.mark.parametrize("path", KEYS, ids=[".".join(p) for p in KEYS])
def test_every_case_value_is_checked_by_type(tmp_path, path, kind):
    """A wrong type in any key is a CaseError naming the key (parsing only: no data read)."""
    original = dict(_leaves(RAW))[path]
    bad = WRONG_VALUES[kind]
    if type(bad) is type(original) or (kind == "text" and path[-1] in ("time",)):
        pytest.skip("a value of the key's own type")
    if kind == "text" and isinstance(original, str):
        pytest.skip("a string key")
    if kind == "list" and path[0] == "initial_state":
        pytest.skip("a list is one initial state per maneuver")
    with pytest.raises(CaseError) as caught:
        parse_case(_set(RAW, path, bad), tmp_path / "case.toml")
    # the message starts with the key (an initial state's value: with the state's key)
    key = ".".join(path[:-1] if path[-1] == "value" and path[0] == "initial_state" else path)
    if path in (("data", "start"), ("data", "stop")):
        key = f"data.file.{path[1]}"  # the defaults of every maneuver: named by the maneuver
    assert str(caught.value).startswith(key), str(caught.value)


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        (("parameters", "Mde", "scale"), -1.0, r"parameters\.Mde\.scale: expected a positive"),
        (("parameters", "Mde", "lower"), 1.0, r"parameters\.Mde\.lower: expected lower < upper"),
        (("biases", "outputs", "alpha", "scale"), 0.0, r"biases\.outputs\.alpha\.scale: expected"),
        (("initial_state", "q", "scale"), -0.1, r"initial_state\.q\.scale: expected a positive"),
        (("initial_state", "q", "chanel"), "q", r"initial_state\.q\.chanel: unknown key"),
        (("accuracy", "correlation_warning"), -1.0, r"accuracy\.correlation_warning: expected"),
        (("accuracy", "correlation_warning"), 1.5, r"accuracy\.correlation_warning: expected"),
        (("data", "stop"), 0.2, r"data\.file\.stop: expected stop > start"),
    ],
)
def test_case_values_are_checked_by_range(tmp_path, path, value, message):
    with pytest.raises(CaseError, match=message):
        parse_case(_set(RAW, path, value), tmp_path / "case.toml")


def test_the_audited_case_itself_is_valid(tmp_path):
    walk = tmp_path / "walk"
    shutil.copytree(WALK, walk)
    (walk / "case.toml").write_text(CASE, encoding="utf-8")
    from flightid.cases import load_case, prepare_case

    prepared = prepare_case(load_case(walk / "case.toml"))
    assert re.fullmatch(r"short_period", prepared.model.name)
