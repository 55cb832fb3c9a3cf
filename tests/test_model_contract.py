"""The model contract (issue 10 §1): f and h are evaluated on the data at the start values
before estimating and in ``flightid validate``; every breach is a named ``ModelError``.

Each of the four failures seen on main is pinned twice: through ``flightid validate`` on a
model module (main printed "valid") and through ``estimate`` (main estimated and "converged",
or blamed the information matrix). The others pin the message content (function, index,
declared length, sample, time, file line) and that the check is cheap.
"""

from __future__ import annotations

import os
import re
import shutil
import time
from pathlib import Path

import numba
import numpy as np
import pytest

from flightid.cases import CaseError, load_case, prepare_case
from flightid.cli.main import build_parser, main
from flightid.data import FlightData
from flightid.errors import InputError, ModelError
from flightid.estimation import estimate
from flightid.model import ModelCheck, Parameters, StateSpaceModel, check_model

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "examples/csv_walkthrough"
DATA = Path(os.environ.get("FLIGHTID_DATA", ROOT / "../shared/data"))

# short period: α̇ = Z_α α + (1 + Z_q) q,  q̇ = M_α α + M_q q + M_δe δe  (5 parameters)
NAMES = ("Za", "Zq", "Ma", "Mq", "Mde")
VALUES = (-1.0, 0.0, -4.4, -1.5, -6.9)


def good_f(t, x, u, theta):
    dx = np.empty(2)
    dx[0] = theta[0] * x[0] + (1.0 + theta[1]) * x[1]
    dx[1] = theta[2] * x[0] + theta[3] * x[1] + theta[4] * u[0]
    return dx


def good_h(t, x, u, theta):
    y = np.empty(2)
    y[0] = x[0]
    y[1] = x[1]
    return y


def f_reads_u1(t, x, u, theta):
    dx = np.empty(2)
    dx[0] = theta[0] * x[0] + (1.0 + theta[1]) * x[1]
    dx[1] = theta[2] * x[0] + theta[3] * x[1] + theta[4] * u[1]
    return dx


def f_one_derivative(t, x, u, theta):
    return np.array([theta[2] * x[0] + theta[3] * x[1] + theta[4] * u[0]])


def h_one_output(t, x, u, theta):
    return np.array([x[0]])


def f_reads_theta5(t, x, u, theta):
    dx = np.empty(2)
    dx[0] = theta[0] * x[0] + (1.0 + theta[1]) * x[1]
    dx[1] = theta[2] * x[0] + theta[3] * x[1] + theta[5] * u[0]
    return dx


def _model(f=good_f, h=good_h, x0=(0.0, 0.0), inputs=("de",)) -> StateSpaceModel:
    parameters = Parameters(dict(zip(NAMES, VALUES, strict=True)))
    return StateSpaceModel(("alpha", "q"), inputs, ("alpha", "q"), f, h, parameters, x0=x0)


def _data(n: int = 301, dt: float = 0.02, name: str = "m1") -> FlightData:
    rng = np.random.default_rng(10)
    t = np.arange(n) * dt
    de = 0.05 * np.sign(np.sin(2.0 * np.pi * t / 4.0))
    alpha = 0.01 * rng.standard_normal(n)
    q = 0.01 * rng.standard_normal(n)
    return FlightData(t, {"de": de}, {"alpha": alpha, "q": q}, name=name)


# ------------------------------------------------------------------ the four observed failures

OBSERVED = [
    pytest.param(
        f_reads_u1,
        good_h,
        r"^f\(t, x, u, theta\) read u\[1\] but the model has 1 input \('de'\).*"
        r"at sample 0, t = 0 s$",
        id="f reads u[1] with one input",
    ),
    pytest.param(
        f_one_derivative,
        good_h,
        r"^f\(t, x, u, theta\) must return a 1-D NumPy array of 2 values \(one derivative per "
        r"state: 'alpha', 'q'\); got 1 value \(NumPy would broadcast it to every state\)",
        id="f returns one derivative for two states",
    ),
    pytest.param(
        good_f,
        h_one_output,
        r"^h\(t, x, u, theta\) must return a 1-D NumPy array of 2 values \(one value per "
        r"output: 'alpha', 'q'\); got 1 value",
        id="h returns one value for two outputs",
    ),
    pytest.param(
        f_reads_theta5,
        good_h,
        r"^f\(t, x, u, theta\) read theta\[5\] but the model has 5 parameters "
        r"\('Za', 'Zq', 'Ma', 'Mq', 'Mde'\)",
        id="f reads theta[5] with five parameters",
    ),
]


@pytest.mark.parametrize(("f", "h", "message"), OBSERVED)
def test_check_model_names_the_breach(f, h, message):
    with pytest.raises(ModelError, match=message):
        check_model(_model(f, h), _data())


@pytest.mark.parametrize(("f", "h", "message"), OBSERVED)
def test_check_model_sees_through_numba(f, h, message):
    """A jitted f/h is checked through its Python original (compiled code reads past arrays)."""
    jitted_f, jitted_h = numba.njit(f), numba.njit(h)
    with pytest.raises(ModelError, match=message):
        check_model(_model(jitted_f, jitted_h), _data())
    # ... and cheaply: nothing was compiled for the check
    assert jitted_f.signatures == [] and jitted_h.signatures == []


@pytest.mark.parametrize(("f", "h", "message"), OBSERVED)
def test_estimate_refuses_a_broken_model(f, h, message):
    """On main these estimated (u[1]: "converged" to a wrong Mδe) or blamed the information
    matrix (θ[5]); estimate() must stop before any estimation with the named error."""
    with pytest.raises(ModelError, match=message):
        estimate(_model(f, h), _data())


# ------------------------------------------------------------------ through the CLI


@pytest.fixture()
def walk(tmp_path) -> Path:
    """A copy of the CSV walk-through (case, model module, data) to break."""
    target = tmp_path / "walk"
    shutil.copytree(WALK, target)
    return target


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new))


# edits of examples/csv_walkthrough/short_period.py (parameters Za, Zq, Zde, Ma, Mq, Mde)
MODULE_BREACHES = [
    pytest.param(
        ("theta[5] * u[0]", "theta[5] * u[1]"),
        r"f\(t, x, u, theta\) read u\[1\] but the model has 1 input \('de'\) "
        r"\(short_period.py line 21: `dx\[1\] = .*u\[1\]`\); at sample 0, t = 0 s",
        id="u[1]",
    ),
    pytest.param(
        ("    return dx\n", "    return dx[1:]\n"),
        r"f\(t, x, u, theta\) must return a 1-D NumPy array of 2 values .* got 1 value "
        r"\(NumPy would broadcast it to every state\)",
        id="one derivative",
    ),
    pytest.param(
        ("    y[1] = x[1]\n    return y", "    return y[:1]"),
        r"h\(t, x, u, theta\) must return a 1-D NumPy array of 2 values .* got 1 value",
        id="one output",
    ),
    pytest.param(
        ("theta[5] * u[0]", "theta[6] * u[0]"),
        r"f\(t, x, u, theta\) read theta\[6\] but the model has 6 parameters",
        id="theta past its length",
    ),
]


@pytest.mark.parametrize(("edit", "message"), MODULE_BREACHES)
def test_validate_rejects_a_broken_model_module(walk, capsys, edit, message):
    _edit(walk / "short_period.py", *edit)
    assert main(["validate", str(walk / "my_case.toml")]) == 1
    captured = capsys.readouterr()
    assert "valid\n" not in captured.out
    error = captured.err.strip()
    assert error.startswith("flightid: error: ")
    assert len(error.splitlines()) == 1, "one line, no traceback"
    assert re.search(message, error), error


def test_validate_checks_the_user_function_under_biases(walk, capsys):
    """With biases, f and h are wrapped (and the user's compiled); the user's own functions
    are checked too, so u[1] is still found."""
    _edit(walk / "short_period.py", "theta[5] * u[0]", "theta[5] * u[1]")
    _edit(
        walk / "my_case.toml",
        'default = "measured"',
        'default = "measured"\n\n[biases.outputs]\nalpha = { value = 0.0 }',
    )
    assert main(["validate", str(walk / "my_case.toml")]) == 1
    assert "read u[1] but the model has 1 input ('de')" in capsys.readouterr().err


def test_validate_reports_what_it_checked(capsys):
    assert main(["validate", str(WALK / "my_case.toml")]) == 0
    out = capsys.readouterr().out
    assert "model functions checked: f and h evaluated at 7 samples of 1 maneuver(s)" in out
    assert "f returns 2 derivatives, h 2 outputs, with 1 input and 6 parameters" in out
    assert "model.module is Python code: it was executed" in out
    assert out.rstrip().endswith("\nvalid")


def test_validate_help_says_model_module_executes_python():
    parser = build_parser()
    subparsers = next(a for a in parser._actions if a.dest == "command")
    validate = subparsers.choices["validate"]
    assert "EXECUTES that file" in validate.description
    helps = {a.dest: a.help for a in subparsers._choices_actions}
    assert "model.module executes the Python file it names" in helps["validate"]


# ------------------------------------------------------------------ model-module import errors


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        pytest.param(
            ("    dx = np.empty(2)\n", "    dx = = np.empty(2)\n"),
            r"^model.module short_period.py line 17: importing it failed: SyntaxError: "
            r"invalid syntax.*`dx = = np.empty\(2\)`",
            id="syntax error",
        ),
        pytest.param(
            ("import numpy as np\n", "import numpy as np\nimport no_such_package_xyz\n"),
            r"^model.module short_period.py line 9: importing it failed: "
            r"ModuleNotFoundError: No module named 'no_such_package_xyz'",
            id="missing package",
        ),
        pytest.param(
            ("STATES = (", "SCALE = undefined_name\nSTATES = ("),
            r"^model.module short_period.py line 10: importing it failed: NameError: "
            r"name 'undefined_name' is not defined — `SCALE = undefined_name`",
            id="name error",
        ),
    ],
)
def test_model_module_import_error_names_file_and_line(walk, edit, message):
    _edit(walk / "short_period.py", *edit)
    with pytest.raises(ModelError, match=message) as info:
        prepare_case(load_case(walk / "my_case.toml"))
    assert isinstance(info.value, CaseError)  # still a case-file error for the CLI


# ------------------------------------------------------------------ the rest of the contract


def test_exception_in_f_names_function_sample_time_and_line():
    def f_fails_late(t, x, u, theta):
        if t > 3.0:
            raise ValueError("table lookup out of range")
        return good_f(t, x, u, theta)

    data = _data(n=301, dt=0.02)  # 0 … 6 s; the spread samples are 0, 75, 150, 225, 300
    with pytest.raises(ModelError) as info:
        check_model(_model(f_fails_late), data)
    message = str(info.value)
    assert message.startswith(
        "f(t, x, u, theta) raised ValueError: table lookup out of range "
        "(test_model_contract.py line "
    )
    # the first checked sample after 3 s: sample 225, t = 4.5 s
    assert message.endswith("at sample 225, t = 4.5 s")
    assert '`raise ValueError("table lookup out of range")`' in message


def test_h_reading_past_x_is_named():
    def h_reads_x2(t, x, u, theta):
        return np.array([x[0], x[2]])

    with pytest.raises(ModelError, match=r"^h\(t, x, u, theta\) read x\[2\] but the model has "
                       r"2 states \('alpha', 'q'\)"):  # fmt: skip
        check_model(_model(h=h_reads_x2), _data())


def test_negative_index_past_the_start_is_named():
    def f_reads_u_minus_2(t, x, u, theta):
        return good_f(t, x, np.array([u[-2]]), theta)

    with pytest.raises(ModelError, match=r"read u\[-2\] but the model has 1 input"):
        check_model(_model(f_reads_u_minus_2), _data())


@pytest.mark.parametrize(
    ("f", "got"),
    [
        pytest.param(lambda t, x, u, th: -6.9 * u[0], "the scalar", id="scalar"),
        pytest.param(lambda t, x, u, th: [x[1], u[0]], "a list of 2 item", id="list"),
        pytest.param(lambda t, x, u, th: None, "None", id="None"),
        pytest.param(lambda t, x, u, th: np.zeros((2, 1)), "shape (2, 1)", id="2-D"),
        pytest.param(lambda t, x, u, th: np.zeros(3), "got 3 values", id="too many"),
        pytest.param(lambda t, x, u, th: np.array(["a", "b"]), "dtype <U1", id="strings"),
        pytest.param(lambda t, x, u, th: np.zeros(2, complex), "dtype complex128", id="complex"),
    ],
)
def test_wrong_return_of_f_is_named(f, got):
    with pytest.raises(ModelError, match=r"^f\(t, x, u, theta\) must return") as info:
        check_model(_model(f), _data())
    assert got in str(info.value)


def test_integer_array_is_accepted():
    check_model(_model(h=lambda t, x, u, th: np.array([0, 1])), _data())


def test_non_finite_start_names_state_and_maneuver():
    """x0 from a parameter name per maneuver: the second maneuver starts at α = 0, where
    this f divides by α; the message names the state, maneuver, sample and time."""

    def f_over_alpha(t, x, u, theta):
        dx = good_f(t, x, u, theta)
        dx[1] = dx[1] / x[0]
        return dx

    parameters = Parameters({**dict(zip(NAMES, VALUES, strict=True)), "a0": 0.1})
    model = StateSpaceModel(
        ("alpha", "q"), ("de",), ("alpha", "q"), f_over_alpha, good_h, parameters,
        x0=[["a0", 0.0], [0.0, 0.0]],
    )  # fmt: skip
    with pytest.raises(ModelError) as info:
        check_model(model, [_data(name="first"), _data(name="second")])
    message = str(info.value)
    assert "non-finite derivative at the start values: 'q' = " in message
    assert "in maneuver 2 'second' at sample 0, t = 0 s" in message
    # the same model from α0 = 0.1 in both maneuvers is fine
    check_model(model.with_x0([["a0", 0.0], ["a0", 0.0]]), [_data(), _data()])


def test_non_finite_output_named():
    def h_log(t, x, u, theta):
        return np.array([x[0], np.log(x[1])])

    with pytest.raises(ModelError, match=r"non-finite output at the start values: 'q' = -inf"):
        check_model(_model(h=h_log), _data())


@pytest.mark.parametrize("argument", ["x", "u", "theta"])
def test_writing_into_an_argument_is_named(argument):
    def f_writes(t, x, u, theta):
        {"x": x, "u": u, "theta": theta}[argument][0] = 1.0
        return good_f(t, x, u, theta)

    with pytest.raises(ModelError, match=rf"changed its argument {argument} in place"):
        check_model(_model(f_writes), _data())


def test_inputs_may_come_from_output_channels():
    """The model's input 'alpha_m' is an *output* channel of the data (as OutputErrorProblem
    allows); u holds it in the model's input order."""
    seen = []

    def f_uses_measured(t, x, u, theta):
        seen.append(u.copy())
        return good_f(t, x, u, theta)

    data = _data()
    data = FlightData(
        data.time, {"de": data.input("de")},
        {"alpha": data.output("alpha"), "q": data.output("q"), "alpha_m": data.output("alpha")},
    )  # fmt: skip
    check_model(_model(f_uses_measured, inputs=("de", "alpha_m")), data)
    assert seen[0].tolist() == [data.input("de")[0], data.output("alpha")[0]]


def test_missing_input_channel_is_an_input_error():
    with pytest.raises(InputError, match=r"the model's inputs \['dr'\] are not channels"):
        check_model(_model(inputs=("de", "dr")), _data())


def test_cost_does_not_grow_with_the_record():
    """2 × 7 calls per maneuver whatever its length (first 3 samples + 5 spread)."""
    calls = []

    def counting_f(t, x, u, theta):
        calls.append(t)
        return good_f(t, x, u, theta)

    for n in (50, 6000):
        calls.clear()
        report = check_model(_model(counting_f), _data(n=n, dt=0.01))
        assert len(calls) == 7 and report.n_samples == 7
        assert calls[:3] == [0.0, 0.01, 0.02] and calls[-1] == pytest.approx((n - 1) * 0.01)


def test_6000_samples_with_a_jitted_model_is_cheap():
    jitted = _model(numba.njit(good_f), numba.njit(good_h))
    data = _data(n=6000, dt=0.01)
    started = time.perf_counter()
    report = check_model(jitted, data)
    elapsed = time.perf_counter() - started
    assert isinstance(report, ModelCheck)
    assert (report.f_shape, report.h_shape, report.n_inputs, report.n_parameters) == (
        (2,), (2,), 1, 5,
    )  # fmt: skip
    assert elapsed < 0.5, elapsed  # typically ~1 ms; generous for a busy machine


def test_paper_examples_pass():
    from flightid.paper import example3, examples12

    model = examples12.example_model()
    assert check_model(model, examples12.example1_data()).n_samples == 7
    assert check_model(example3.example3_model(), example3.example3_data(1)).f_shape == (6,)


@pytest.mark.skipif(
    not (DATA / "fvsysid").is_dir() or not (DATA / "sidpac_twin_otter").is_dir(),
    reason=f"real flight data not found at {DATA} (set FLIGHTID_DATA)",
)
@pytest.mark.parametrize(
    "name",
    [
        "attas_short_period",
        "attas_lateral",
        "attas_lateral_two_maneuvers",
        "hfb320_longitudinal",
        "twin_otter_longitudinal",
    ],
)
def test_shipped_cases_pass_validate(name, capsys):
    assert main(["validate", str(ROOT / "examples/cases" / f"{name}.toml"), "--data-dir",
                 str(DATA)]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert "model functions checked: f and h evaluated at" in out
    assert out.rstrip().endswith("\nvalid")
