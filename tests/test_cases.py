"""Case files: parsing, named errors for bad cases, and a small case end to end."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from flightid.cases import CaseError, load_case, prepare_case, run_case
from flightid.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
CASES = sorted((ROOT / "examples/cases").glob("*.toml"))
WALK = ROOT / "examples/csv_walkthrough"
STANDARD = [
    "hfb320_longitudinal",
    "attas_lateral",
    "attas_lateral_two_maneuvers",
    "attas_short_period",
    "twin_otter_longitudinal",
]


@pytest.mark.parametrize("name", STANDARD)
def test_standard_cases_parse(name):
    case = load_case(ROOT / "examples/cases" / f"{name}.toml")
    assert case.maneuvers and "module" in case.model


@pytest.fixture()
def walk(tmp_path) -> Path:
    """A copy of the CSV walk-through (case, model, data) to edit."""
    target = tmp_path / "walk"
    shutil.copytree(WALK, target)
    return target


def _edit(path: Path, old: str, new: str) -> Path:
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new))
    return path


# ------------------------------------------------------------------ bad case files


def test_unknown_top_level_key(walk):
    _edit(walk / "my_case.toml", "[estimation]", "[estimaton]")
    with pytest.raises(CaseError, match=r"^estimaton: unknown key"):
        load_case(walk / "my_case.toml")


def test_bad_solver_named(walk):
    _edit(walk / "my_case.toml", 'solver = "mnr"', 'solver = "newton"')
    with pytest.raises(CaseError, match=r"estimation.solver: expected one of"):
        load_case(walk / "my_case.toml")


def test_not_toml(walk):
    (walk / "my_case.toml").write_text("title = \n")
    with pytest.raises(CaseError, match="not valid TOML"):
        load_case(walk / "my_case.toml")


def test_missing_model_section(walk):
    text = (walk / "my_case.toml").read_text()
    (walk / "my_case.toml").write_text(text.split("[model]")[0])
    with pytest.raises(CaseError, match=r"^model: missing section"):
        load_case(walk / "my_case.toml")


def test_unknown_parameter_named(walk):
    _edit(walk / "my_case.toml", "Ma = -3.0", "Malpha = -3.0")
    with pytest.raises(CaseError, match=r"parameters.Malpha: not a parameter of the model"):
        prepare_case(load_case(walk / "my_case.toml"))


def test_parameter_value_type(walk):
    _edit(walk / "my_case.toml", "Ma = -3.0", 'Ma = "minus three"')
    with pytest.raises(CaseError, match=r"parameters.Ma: expected a number"):
        load_case(walk / "my_case.toml")


def test_bad_initial_state_named(walk):
    _edit(walk / "my_case.toml", 'default = "measured"', 'beta = "measured"')
    with pytest.raises(CaseError, match=r"initial_state.beta: not a state"):
        prepare_case(load_case(walk / "my_case.toml"))


def test_unknown_column_named(walk):
    _edit(walk / "my_case.toml", 'column = "AOA"', 'column = "AoA_deg"')
    with pytest.raises(CaseError, match=r"outputs.alpha: no column named 'AoA_deg'"):
        prepare_case(load_case(walk / "my_case.toml"))


def test_missing_output_channel_named(walk):
    _edit(walk / "my_case.toml", 'q = { column = "pitch_rate"', 'qq = { column = "pitch_rate"')
    with pytest.raises(CaseError, match=r"data.outputs: the model's outputs \['q'\]"):
        prepare_case(load_case(walk / "my_case.toml"))


def test_model_module_missing_definition(walk):
    _edit(walk / "short_period.py", "def h(", "def h_renamed(")
    with pytest.raises(CaseError, match=r"model.module short_period.py: missing the definition h"):
        prepare_case(load_case(walk / "my_case.toml"))


def test_bad_data_file_named(walk):
    with (walk / "my_flight.csv").open("a") as out:
        out.write("10.02,0.0,abc,1.0\n")
    with pytest.raises(CaseError, match=r"data \(maneuver 1 'my_flight'.*not numeric"):
        prepare_case(load_case(walk / "my_case.toml"))


def test_bad_expression_in_case(walk):
    _edit(walk / "my_case.toml", 'column = "elevator"', 'expr = "elevator +"')
    with pytest.raises(CaseError, match=r"data.inputs.de: expression"):
        load_case(walk / "my_case.toml")  # parsed at validation time, before any data


def test_missing_data_dir(walk):
    with pytest.raises(CaseError, match="data.data_dir"):
        prepare_case(load_case(walk / "my_case.toml"), data_dir=walk / "nowhere")


# ------------------------------------------------------------------ end to end


def test_csv_walkthrough_end_to_end(tmp_path, capsys):
    out = tmp_path / "report"
    code = main(["run", str(WALK / "my_case.toml"), "--json", "--out", str(out), "--quiet"])
    assert code == 0
    payload = json.loads(capsys.readouterr().out)
    (entry,) = payload["results"]
    assert entry["converged"] is True
    values = {p["name"]: p["value"] for p in entry["parameters"]}
    # true values of make_flight.py: Ma = -4.5, Mq = -1.6, Mde = -7.0 (the 3 σ check of all six
    # is tests/test_input_interpolation.py::test_walkthrough_case_recovers_its_truth_within_3_sigma)
    assert values["Ma"] == pytest.approx(-4.5, rel=0.05)
    assert values["Mq"] == pytest.approx(-1.6, rel=0.05)
    assert values["Mde"] == pytest.approx(-7.0, rel=0.05)
    for name in ("results.json", "estimates.csv", "report.html", "figures/convergence.svg"):
        assert (out / name).is_file(), name
    assert "Correlation matrix" in (out / "report.html").read_text()
    assert json.loads((out / "results.json").read_text())["results"][0]["cost"] == entry["cost"]


def test_validate_command(capsys):
    assert main(["validate", str(WALK / "my_case.toml")]) == 0
    out = capsys.readouterr().out
    # the verdict is the last line, exactly ("valid" in out would also match "invalid")
    assert out.splitlines()[-1] == "valid"
    assert "invalid" not in out


def test_biases_and_estimated_initial_states(walk):
    """A known output offset is recovered by an output bias; x0 estimated per maneuver."""
    csv = walk / "my_flight.csv"
    lines = csv.read_text().splitlines()
    shifted = [lines[0]]
    for line in lines[1:]:
        t, de, a, q = (float(v) for v in line.split(","))
        shifted.append(f"{t},{de},{a + 0.3},{q}")  # +0.3 deg on AOA
    (walk / "shifted.csv").write_text("\n".join(shifted) + "\n")
    _edit(
        walk / "my_case.toml", 'file = "my_flight.csv"', 'files = ["my_flight.csv", "shifted.csv"]'
    )
    _edit(
        walk / "my_case.toml",
        'default = "measured"',
        'default = "measured"\nq = "estimate"\n\n[biases.outputs]\n'
        "alpha = { value = 0.0, per_maneuver = true }",
    )
    run = run_case(load_case(walk / "my_case.toml"))
    est = run.estimate
    assert est.converged
    assert {"x0_q_1", "x0_q_2", "by_alpha_1", "by_alpha_2"} <= set(est.names)
    # the bias difference between the maneuvers is the added 0.3 deg
    difference = est.value("by_alpha_2") - est.value("by_alpha_1")
    assert difference == pytest.approx(
        np.deg2rad(0.3), abs=3 * np.hypot(est.stddev("by_alpha_1"), est.stddev("by_alpha_2")) + 1e-4
    )
