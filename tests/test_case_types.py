"""Every case-file value is type-checked with an error naming the key (issue 10 §5).

Each bad value below went through on main: ``central = "no"`` counted as true,
``max_iterations = 2.5`` and ``compiled = "no"`` were accepted, string scales, non-UTF-8
files, deep expressions and huge powers ended in tracebacks.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

import flightid.cases.run as case_run
from flightid.cases import CaseError, load_case, run_case
from flightid.cases.build import build_convergence, build_solver
from flightid.cli.main import main
from flightid.data.loaders import ChannelError, parse_expression
from flightid.estimation import MNR
from flightid.model.terms import MAX_POWER, TermError, parse_term

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "examples/csv_walkthrough"


@pytest.fixture()
def walk(tmp_path) -> Path:
    """A copy of the walk-through case; its own input_interpolation line (if any) removed so
    that the tests below set it."""
    target = tmp_path / "walk"
    shutil.copytree(WALK, target)
    case = target / "my_case.toml"
    case.write_text(re.sub(r"(?m)^input_interpolation\s*=.*\n", "", case.read_text()))
    return case


def _edit(case: Path, old: str, new: str) -> Path:
    """Replace ``old`` by ``new``; ``old = END`` appends ``new`` (new tables go at the end,
    where they cannot take over the keys of the table before them)."""
    text = case.read_text()
    if old == END:
        case.write_text(text + "\n" + new + "\n")
        return case
    assert old in text, old
    case.write_text(text.replace(old, new, 1))
    return case


END = "<end of file>"
SOLVER = "[estimation]"  # keys of [estimation] go right after its header
PARAM = "Ma = -3.0"

# (text replaced, replacement, error expected: key and what was wrong)
BAD = [
    (END, '[estimation.solver_settings]\ncentral = "no"',
     r"^estimation\.solver_settings\.central: expected true or false, got 'no'$"),
    (END, "[estimation.solver_settings]\ncentral = 0",
     r"^estimation\.solver_settings\.central: expected true or false, got 0$"),
    (END, "[estimation.convergence]\nmax_iterations = 2.5",
     r"^estimation\.convergence\.max_iterations: expected an integer, got 2\.5$"),
    (END, '[estimation.convergence]\nmax_iterations = "3"',
     r"^estimation\.convergence\.max_iterations: expected an integer, got '3'$"),
    (END, "[estimation.convergence]\nmax_iterations = 3.0",
     r"^estimation\.convergence\.max_iterations: expected an integer, got 3\.0$"),
    (END, '[estimation.convergence]\ncost_rtol = "1e-4"',
     r"^estimation\.convergence\.cost_rtol: expected a number, got '1e-4'$"),
    (END, "[estimation.convergence]\ncost_rtol = nan",
     r"^estimation\.convergence\.cost_rtol: expected a number \(not NaN\), got nan$"),
    (END, "[estimation.convergence]\ncost_tol = 1e-4",
     r"^estimation\.convergence\.cost_tol: not a setting of Convergence; its settings: \["),
    (END, "[estimation.solver_settings]\nwindow = 3",
     r"^estimation\.solver_settings\.window: not a setting of MNR; its settings: \["),
    (SOLVER, SOLVER + '\ncompiled = "no"',
     r"^estimation\.compiled: expected true or false, got 'no'$"),
    (SOLVER, SOLVER + '\ninput_interpolation = "cubic"',
     r"^estimation\.input_interpolation: expected one of \['linear', 'zoh'\], got 'cubic'$"),
    (PARAM, 'Ma = { value = -3.0, scale = "big" }',
     r"^parameters\.Ma\.scale: expected a number, got 'big'$"),
    (PARAM, 'Ma = { value = -3.0, lower = "-10" }',
     r"^parameters\.Ma\.lower: expected a number, got '-10'$"),
    (PARAM, 'Ma = { value = -3.0, free = "yes" }',
     r"^parameters\.Ma\.free: expected true or false, got 'yes'$"),
    (PARAM, "Ma = inf", r"^parameters\.Ma: expected a finite number, got inf$"),
    (PARAM, "Ma = { value = -3.0, unit = 1 }", r"^parameters\.Ma\.unit: expected a string"),
    ('default = "measured"', 'default = "measured"\nq = { value = "estimate", scale = "x" }',
     r"^initial_state\.q\.scale: expected a number, got 'x'$"),
    ('default = "measured"', 'default = "measured"\nq = { value = 0.0, free = "no" }',
     r"^initial_state\.q\.free: expected true or false, got 'no'$"),
    ('default = "measured"', 'default = "measurd"',
     r"^initial_state\.default: expected one of \['measured', 'estimate'\], got 'measurd'$"),
    ('time = "time"', "time = 1.5", r"^data\.time: expected a positive integer, got 1\.5$"),
    ('data_dir = "."', "data_dir = 1", r"^data\.data_dir: expected a string, got 1$"),
    ('module = "short_period.py"', 'module = "short_period.py"\nname = 7',
     r"^model\.name: expected a string, got 7$"),
    (END, "[output]\nfigures = 1",
     r"^output\.figures: expected true or false, got 1$"),
    (END, "[output]\ndir = false", r"^output\.dir: expected a string, got False$"),
    (END, "[accuracy]\nseed = 1.5",
     r"^accuracy\.seed: expected a non-negative integer, got 1\.5$"),
    (END, "[biases.outputs]\nq = { value = 0.0, per_maneuver = \"no\" }",
     r"^biases\.outputs\.q\.per_maneuver: expected true or false, got 'no'$"),
]  # fmt: skip


@pytest.mark.parametrize(("old", "new", "message"), BAD, ids=[b[2][1:40] for b in BAD])
def test_bad_value_is_named(walk, old, new, message):
    _edit(walk, old, new)
    with pytest.raises(CaseError, match=message):
        load_case(walk)


def test_good_values_of_every_type_are_accepted(walk):
    _edit(walk, SOLVER, SOLVER + "\ncompiled = false")
    _edit(
        walk,
        END,
        "[estimation.solver_settings]\ncentral = true\nmax_halvings = 4\n"
        "max_relative_step = inf\nrelative_step = 1e-5\n"
        "[estimation.convergence]\nmax_iterations = 7\ncost_rtol = 1e-4\n",
    )
    _edit(walk, PARAM, "Ma = { value = -3.0, scale = 2, lower = -inf, upper = 0 }")
    case = load_case(walk)
    solver = build_solver(case)
    assert solver == MNR(central=True, max_halvings=4, relative_step=1e-5)
    assert build_convergence(case).max_iterations == 7


def test_central_no_cannot_reach_the_solver_as_true_from_the_cli(walk, capsys):
    _edit(walk, END, '[estimation.solver_settings]\ncentral = "no"')
    assert main(["validate", str(walk)]) == 1
    err = capsys.readouterr().err
    assert err == (
        "flightid: error: estimation.solver_settings.central: expected true or false, got 'no'\n"
    )


def test_non_utf8_case_file_is_named(walk, capsys):
    text = walk.read_text().replace('title = "My flight', 'title = "Mé flight')
    walk.write_bytes(text.encode("latin-1"))
    with pytest.raises(CaseError, match=r"not UTF-8 text \(byte 0xe9 at offset \d+\)"):
        load_case(walk)
    assert main(["run", str(walk)]) == 1
    assert "not UTF-8 text" in capsys.readouterr().err


def test_utf8_with_byte_order_mark_is_read(walk):
    walk.write_bytes(b"\xef\xbb\xbf" + walk.read_bytes())
    assert load_case(walk).title.startswith("My flight")


def test_case_path_that_is_a_folder_is_named(tmp_path):
    with pytest.raises(CaseError, match=r"is not a file"):
        load_case(tmp_path)


# ------------------------------------------------------------------ expressions and terms


@pytest.mark.parametrize(
    ("expression", "message"),
    [
        ("(" * 3000 + "elevator" + ")" * 3000, "nested deeper than 100 levels"),
        ("-" * 30000 + "elevator", "nested deeper than 100 levels"),
        ("+".join(["elevator"] * 500), "more than 100 nested operations"),
        ("elevator * 1e999", "expected a finite number"),
    ],
    ids=["parentheses", "signs", "long-chain", "overflowing-literal"],
)
def test_expression_limits_are_named(walk, expression, message):
    with pytest.raises(ChannelError, match=message):
        parse_expression(expression)
    _edit(walk, 'column = "elevator",', f'expr = "{expression}",')
    with pytest.raises(CaseError, match=rf"^data\.inputs\.de: .*{message}"):
        load_case(walk)


def test_expressions_within_the_limits_still_work():
    # 99 signs and one name: depth 100, the limit
    assert parse_expression("-" * 99 + "a")[0] == "neg"
    tree = parse_expression("(" * 40 + "$1" + ")" * 40 + " + 2")
    assert tree == ("+", ("col", 1), ("num", 2.0))


def test_term_powers_are_limited():
    assert parse_term(f"beta^{MAX_POWER}").label == f"beta^{MAX_POWER}"
    with pytest.raises(TermError, match=r"the power of 'beta' is 65; at most 64"):
        parse_term("beta^65")
    with pytest.raises(TermError, match=r"at most 64 is allowed"):
        parse_term("beta^" + "9" * 5000)  # int() of 5000 digits fails on its own
    with pytest.raises(TermError, match=r"multiply to the power 80"):
        parse_term("beta^40*beta^40")


# ------------------------------------------------------------------ input interpolation


def test_input_interpolation_is_parsed_and_passed_to_estimate(walk, monkeypatch):
    _edit(walk, SOLVER, SOLVER + '\ninput_interpolation = "zoh"')
    case = load_case(walk)
    assert case.estimation["input_interpolation"] == "zoh"
    seen = {}

    class Stop(Exception):
        pass

    def fake_estimate(model, data, solver=None, *, input_interpolation="linear", **kwargs):
        seen["input_interpolation"] = input_interpolation
        raise Stop

    monkeypatch.setattr(case_run, "estimate", fake_estimate)
    with pytest.raises(Stop):
        run_case(case)
    assert seen == {"input_interpolation": "zoh"}


def test_default_interpolation_is_linear(walk):
    case = load_case(walk)
    assert case_run.input_interpolation(case) == "linear"


def test_zoh_case_reaches_the_estimate(walk):
    """End to end (3 s of data, pure Python, 2 passes): the Estimate carries the setting."""
    text = walk.read_text().replace('time = "time"', 'time = "time"\nstop = 3.0')
    walk.write_text(text)
    _edit(walk, SOLVER, SOLVER + '\ncompiled = false\ninput_interpolation = "zoh"')
    _edit(walk, END, "[estimation.convergence]\nmax_iterations = 2")
    assert run_case(load_case(walk)).estimate.input_interpolation == "zoh"


def test_unit_powers_are_limited(walk):
    from flightid.data.units import MAX_UNIT_POWER, UnitError, parse_unit

    assert parse_unit(f"s^{MAX_UNIT_POWER}")[1] == (0, 0, MAX_UNIT_POWER, 0)
    with pytest.raises(UnitError, match=r"the power -9999 is out of range"):
        parse_unit("kt^-9999")  # 0.514^-9999 overflowed: OverflowError on main
    _edit(walk, 'unit = "deg", to = "rad"', 'unit = "deg^99999", to = "rad^99999"')
    with pytest.raises(CaseError, match=r"^data\.inputs\.de: .*the power 99999 is out of range"):
        load_case(walk)
