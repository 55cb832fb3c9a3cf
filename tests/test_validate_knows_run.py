"""``flightid validate`` makes every check ``flightid run`` (and ``flightid design``) makes
before estimating; prediction uses the case's initial-state settings; a model numba cannot
compile is named by its line.

All cases are edits of the CSV walk-through (examples/csv_walkthrough: 10 s at 0.02 s of a
short-period model), copied to a temporary folder.
"""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from flightid.cases import CaseError, load_case, prepare_case, run_case
from flightid.cases.design_case import design_problem
from flightid.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "examples" / "csv_walkthrough"

# [design] of a multisine on the walk-through's model (dt_s 0.02 s: Nyquist 25 Hz)
DESIGN = """
[design]
duration_s = 10.0
dt_s = 0.02
signal = "{signal}"
noise_std = {{ alpha = {sigma}, q = 0.001 }}
{extra}
[design.inputs]
de = {{ amplitude = 0.02 }}
"""


@pytest.fixture()
def walk(tmp_path) -> Path:
    target = tmp_path / "walk"
    shutil.copytree(WALK, target)
    return target


def _edit(path: Path, old: str, new: str) -> Path:
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new))
    return path


def _validate(case: Path, capsys) -> tuple[int, str]:
    code = main(["validate", str(case)])
    captured = capsys.readouterr()
    return code, captured.out + captured.err


def _with_design(walk: Path, signal="multisine", sigma="0.001", extra="band_hz = [0.1, 2.0]"):
    case = walk / "my_case.toml"
    case.write_text(
        case.read_text() + DESIGN.format(signal=signal, sigma=sigma, extra=extra),
        encoding="utf-8",
    )
    return case


# ------------------------------------------------------------------ [design]


def test_validate_accepts_a_good_design(walk, capsys):
    code, out = _validate(_with_design(walk), capsys)
    assert code == 0, out
    assert "[design]: multisine for ['de']" in out
    assert out.splitlines()[-1] == "valid"


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        # a negative noise σ (flightid design refuses it; validate said "valid")
        ({"sigma": "-0.001"}, r"design\.noise_std\.alpha: expected a positive number"),
        # a band above the Nyquist frequency 1/(2·0.02 s) = 25 Hz (ran for minutes)
        ({"extra": "band_hz = [0.1, 40.0]"}, r"design\.band_hz: the band reaches 40 Hz, at or "
         r"above the Nyquist frequency 25 Hz"),
        ({"extra": "band_hz = [0.1, 25.0]"}, r"design\.band_hz: .* Nyquist frequency 25 Hz"),
        # a 3-2-1-1 starting before the record (its first pulses were cut off silently)
        ({"signal": "3211", "extra": "start_s = -5.0"}, r"design\.start_s: expected a time ≥ 0"),
        ({"signal": "3211", "extra": "gap_s = -1.0"}, r"design\.gap_s: expected a time ≥ 0"),
        ({"signal": "3211", "extra": "start_s = 12.0"}, r"design\.start_s: the first pulse "
         r"starts at 12 s, at or after the end"),
    ],
)  # fmt: skip
def test_validate_refuses_what_design_refuses(walk, capsys, edit, message):
    case = _with_design(walk, **edit)
    code, out = _validate(case, capsys)
    assert code == 1
    assert "valid\n" not in out
    import re

    assert re.search(message, out), out
    # the same named error from the design's own front door
    with pytest.raises(CaseError, match=message):
        design_problem(load_case(case))


def test_a_band_on_one_input_above_nyquist_is_named(walk):
    case = _with_design(walk, extra="")
    _edit(case, "de = { amplitude = 0.02 }", "de = { amplitude = 0.02, band_hz = [0.5, 30.0] }")
    with pytest.raises(CaseError, match=r"design\.inputs\.de\.band_hz: the band reaches 30 Hz"):
        design_problem(load_case(case))


# ------------------------------------------------------------------ estimator checks


def test_validate_refuses_filter_error_with_a_time_delay(walk, capsys):
    """The filter error method does not take delays: `run` refused it, `validate` passed it."""
    case = _edit(
        walk / "my_case.toml",
        'input_interpolation = "zoh"',
        'input_interpolation = "zoh"\nestimator = "filter_error"\n\n[process_noise]\nq = 0.01',
    )
    _edit(case, 'noise = "max"\n', "")
    _edit(case, 'module = "short_period.py"', 'module = "short_period.py"\noutput_delays = '
          '{ q = "tau_q" }')  # fmt: skip
    code, out = _validate(case, capsys)
    assert code == 1
    assert "estimation: model: time delays" in out and "filter error method" in out


def test_validate_refuses_a_case_with_nothing_free(walk, capsys):
    case = _edit(
        walk / "my_case.toml",
        "Ma = -3.0\nMde = { value = -5.0, free = true }",
        "\n".join(f"{p} = {{ value = {v}, free = false }}" for p, v in
                  (("Za", -0.5), ("Zq", 0.0), ("Zde", -0.05), ("Ma", -3.0), ("Mq", -1.0),
                   ("Mde", -5.0))),
    )  # fmt: skip
    code, out = _validate(case, capsys)
    assert code == 1 and "no parameter is free" in out


def test_validate_refuses_accuracy_methods_after_the_filter_error_method(walk, capsys):
    case = _edit(
        walk / "my_case.toml",
        'noise = "max"\ninput_interpolation = "zoh"',
        'input_interpolation = "zoh"\nestimator = "filter_error"\n\n[process_noise]\nq = 0.01'
        '\n\n[accuracy]\nmethods = ["profile"]',
    )
    code, out = _validate(case, capsys)
    assert code == 1 and "accuracy.methods: ['profile']" in out


def test_three_rows_are_refused_before_estimating(walk, capsys):
    """3 samples × 2 outputs = 6 measurements for 6 free parameters: the run estimated, then
    failed writing the result folder with an internal error; now both refuse it by name."""
    csv = walk / "my_flight.csv"
    csv.write_text("\n".join(csv.read_text().splitlines()[:4]) + "\n")
    code, out = _validate(walk / "my_case.toml", capsys)
    assert code == 1
    assert "3 samples × 2 outputs = 6 scalar measurements for 6 free parameters" in out
    out_dir = walk / "out"
    assert main(["run", str(walk / "my_case.toml"), "--out", str(out_dir), "--quiet"]) == 1
    assert "internal error" not in capsys.readouterr().err
    assert not out_dir.exists()


# ------------------------------------------------------------------ prediction


def _renamed_states(walk: Path) -> Path:
    """A model whose states x1, x2 have no data channel of their name: [initial_state] maps
    them to alpha and q (x2 estimated), and [prediction] predicts the same file."""
    module = (walk / "short_period.py").read_text()
    (walk / "renamed.py").write_text(
        module.replace('STATES = ("alpha", "q")', 'STATES = ("x1", "x2")')
    )
    case = _edit(walk / "my_case.toml", 'module = "short_period.py"', 'module = "renamed.py"')
    _edit(
        case,
        'default = "measured"        # x0 fixed at the first measured alpha and q',
        'x1 = { channel = "alpha" }\nx2 = { value = "estimate", channel = "q" }',
    )
    case.write_text(case.read_text() + '\n[prediction]\nfile = "my_flight.csv"\n')
    return case


def test_prediction_takes_the_initial_state_channels(walk, capsys):
    """The prediction used 'measured' from channels named x1, x2 and failed after a converged
    estimate (nothing saved); it now reads alpha and q, as [initial_state] says."""
    case = _renamed_states(walk)
    code, out = _validate(case, capsys)
    assert code == 0, out
    run = run_case(load_case(case))
    (prediction,) = run.predictions
    # h = x: the predicted first sample is the initial state, the first measured alpha, q
    np.testing.assert_allclose(prediction.predicted[0], prediction.measured[0], rtol=0, atol=0)


def test_prediction_takes_a_fixed_initial_state(walk):
    """A number in [initial_state] is the predicted maneuver's start too (was: measured)."""
    case = _edit(
        walk / "my_case.toml",
        'default = "measured"        # x0 fixed at the first measured alpha and q',
        'default = "measured"\nalpha = 0.01',
    )
    case.write_text(case.read_text() + '\n[prediction]\nfile = "my_flight.csv"\n')
    (prediction,) = run_case(load_case(case)).predictions
    # h = x: the predicted first sample is the initial state
    np.testing.assert_array_equal(prediction.predicted[0], [0.01, prediction.measured[0, 1]])


def test_the_prediction_table_overrides_the_initial_state(walk):
    case = _edit(
        walk / "my_case.toml",
        'default = "measured"        # x0 fixed at the first measured alpha and q',
        'default = "measured"\nalpha = 0.01',
    )
    case.write_text(
        case.read_text() + '\n[prediction]\nfile = "my_flight.csv"\n'
        "[prediction.initial_state]\nalpha = 0.02\nq = 0.03\n"
    )
    prepared = prepare_case(load_case(case))
    from flightid.cases.run import prediction_model

    model, _ = prediction_model(prepared.case, prepared.prediction_maneuvers[0], prepared.base)
    np.testing.assert_array_equal(model.initial_state(), [0.02, 0.03])


def test_a_bad_prediction_initial_state_stops_the_run_before_estimating(walk, monkeypatch):
    case = _renamed_states(walk)
    _edit(case, 'x1 = { channel = "alpha" }', "x1 = [0.0]")  # per estimation maneuver
    calls = []
    import flightid.cases.run as run_module

    monkeypatch.setattr(run_module, "estimate", lambda *a, **k: calls.append(1))
    with pytest.raises(CaseError, match=r"prediction\.initial_state\.x1: 'measured' needs"):
        run_case(load_case(case))
    assert calls == []


# ------------------------------------------------------------------ numba fall-back


def _divides_by_a_parameter(walk: Path) -> Path:
    module = (walk / "short_period.py").read_text()
    (walk / "divide.py").write_text(
        module.replace(
            "dx[1] = theta[3] * x[0] + theta[4] * x[1] + theta[5] * u[0]",
            "dx[1] = theta[3] * x[0] + theta[4] * x[1] + u[0] / (1.0 / theta[5])",
        )
    )
    case = _edit(walk / "my_case.toml", 'module = "short_period.py"', 'module = "divide.py"')
    return _edit(case, "[estimation]", "[biases.outputs]\nalpha = 0.0\n\n[estimation]")


def test_biases_on_a_model_dividing_by_a_parameter_stay_compiled(walk):
    """numba's division by the zero start of θ (the compile probe) was taken for a failure to
    compile: the biased model ran in pure Python with a warning naming only TypingError."""
    case = _divides_by_a_parameter(walk)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        run = run_case(load_case(case))
    assert run.estimate.converged


def _uncompilable(walk: Path, gain: float) -> tuple[Path, int]:
    """The walk-through with a dict global in f (numba cannot type it): (case, its line)."""
    module = (walk / "short_period.py").read_text()
    module = module.replace("PARAMETERS =", f'GAIN = {{"k": {gain}}}\nPARAMETERS =').replace(
        "theta[5] * u[0]\n", 'theta[5] * u[0] * GAIN["k"]\n'
    )
    (walk / "dictmodel.py").write_text(module)
    number = next(
        i + 1 for i, line in enumerate(module.splitlines()) if 'GAIN["k"]' in line and "dx" in line
    )
    case = _edit(walk / "my_case.toml", 'module = "short_period.py"', 'module = "dictmodel.py"')
    _edit(case, "[estimation]", "[output]\nfigures = false\nreport = false\n\n[estimation]")
    return case, number


def test_a_model_numba_cannot_compile_is_named_by_its_line(walk, capsys):
    """The fall-back warning named only 'TypingError'; now one line names the user's line,
    numba's reason and how to avoid it."""
    case, number = _uncompilable(walk, 1.25)
    code = main(["run", str(case), "--out", str(walk / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 0, err
    # one line for the fall-back (other findings of the run may be warned about too)
    (line,) = [
        w for w in err.splitlines() if w.startswith("flightid: warning:") and "dictmodel" in w
    ]
    assert f"dictmodel.py line {number}" in line and 'GAIN["k"]' in line
    assert "Untyped global name 'GAIN'" in line
    assert "make GAIN a number, a tuple or a numpy array" in line
    assert "pure Python" in line


def test_the_fall_back_is_a_compile_warning_in_the_python_api(walk):
    from flightid.errors import CompileWarning
    from flightid.simulation import Simulator

    case, number = _uncompilable(walk, 1.5)
    prepared = prepare_case(load_case(case))
    with pytest.warns(CompileWarning, match=f"dictmodel.py line {number}"):
        Simulator(prepared.model, list(prepared.maneuvers))
