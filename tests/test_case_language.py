"""The one case language: ``[[stages]]`` (flightid.cases.stagespec / flightid.cases.stages)
on small synthetic data whose generating coefficients are the reference values.

References: the regression data are z = 0.5 + 2 a − 3 b (+ seeded noise), so the least-squares
estimates must be those numbers; the α–q data are simulated from known parameters
(``TRUTH``), so regression → output error must return them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flightid.cases import CaseError, load_case
from flightid.cases.stages import case_signals, run_regression_stage, run_stages
from flightid.cli.main import main

ROOT = Path(__file__).resolve().parents[1]

HEAD = """
[data]
file = "f.csv"
data_dir = "."
format = "csv"
time = "time"
[data.inputs]
a = "a"
b = "b"
c = "c"
[data.outputs]
z = "z"
"""


@pytest.fixture
def linear(tmp_path: Path) -> Path:
    """f.csv: z = 0.5 + 2 a − 3 b + noise (σ 0.01, seed 1); c is an unrelated candidate."""
    rng = np.random.default_rng(1)
    t = np.arange(200) * 0.1
    a, b, c = np.sin(t), np.cos(0.7 * t) + 0.1 * t, rng.standard_normal(200)
    z = 0.5 + 2.0 * a - 3.0 * b + 0.01 * rng.standard_normal(200)
    rows = "\n".join(",".join(f"{v:.17g}" for v in row) for row in zip(t, a, b, c, z, strict=True))
    (tmp_path / "f.csv").write_text("time,a,b,c,z\n" + rows + "\n")
    return tmp_path


def _case(directory: Path, text: str, name: str = "case.toml") -> Path:
    path = directory / name
    path.write_text(HEAD + text)
    return path


STEPWISE = """
[[stages]]
kind = "stepwise"
[stages.coefficients.z]
candidates = ["a", "b", "c", "a*b"]
"""


def test_stepwise_stage_selects_the_generating_terms(linear):
    case = load_case(_case(linear, STEPWISE))
    (stage,) = case.stages
    assert stage.kind == "stepwise" and stage.coefficients[0][:2] == ("z", "z")
    result = run_regression_stage(stage, case_signals(case))["z"]
    assert set(result.selected) == {"1", "a", "b"}
    # the generating coefficients 0.5, 2, −3, within 4 standard errors
    for term, truth in (("1", 0.5), ("a", 2.0), ("b", -3.0)):
        value, std = result.fit.parameter(term)
        assert abs(value - truth) < 4 * std and std < 0.01


def test_regression_stage_fits_exactly_the_given_terms(linear):
    text = (
        '[[stages]]\nkind = "regression"\n[stages.coefficients.z]\nterms = ["1", "a", "b", "c"]\n'
    )
    case = load_case(_case(linear, text))
    result = run_regression_stage(case.stages[0], case_signals(case))["z"]
    assert result.selected == ("1", "a", "b", "c")
    assert result.fit.parameter("a")[0] == pytest.approx(2.0, abs=0.005)
    assert result.fit.parameter("b")[0] == pytest.approx(-3.0, abs=0.005)
    assert abs(result.fit.parameter("c")[0]) < 4 * result.fit.parameter("c")[1]
    assert result.to_dict()["selected"] == ["1", "a", "b", "c"]


def test_a_file_of_regression_stages_runs_and_validates(linear, capsys):
    path = _case(linear, STEPWISE)
    assert main(["run", str(path), "--json", "--quiet"]) == 0
    import json

    document = json.loads(capsys.readouterr().out)
    assert document["results"] == []
    assert document["stages"][0]["coefficients"]["z"]["selected"] == ["1", "a", "b"]
    assert main(["validate", str(path)]) == 0
    out = capsys.readouterr().out
    assert "[0] stepwise 'stepwise': 1 coefficient(s), 4 terms" in out and "valid" in out


def test_files_without_stages_are_one_output_error_run():
    # every shipped output-error case parses unchanged, as one output-error run
    for path in sorted((ROOT / "examples" / "cases").glob("*.toml")):
        case = load_case(path)
        if path.stem == "twin_otter_stepwise":
            assert [s.kind for s in case.stages] == ["stepwise", "output_error", "prediction"]
        elif path.stem.startswith("unstab_sp_equation_error_"):
            assert [s.kind for s in case.stages] == ["regression"]
        elif path.stem == "globalmodel_f16":
            assert [s.kind for s in case.stages] == ["global_model"]
        else:
            assert case.stages == () and not case.staged, path.name


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            '[[stages]]\nkind = "compatibility"\n',
            r"stages\[0\]\.kind: 'compatibility' .*not available yet",
        ),
        ('[[stages]]\nkind = "filter_error"\n', r"not available yet"),
        ('[[stages]]\nkind = "bayes"\n', r"stages\[0\]\.kind: expected one of"),
        ("[[stages]]\nname = 'x'\n", r"stages\[0\]\.kind: missing"),
        (STEPWISE + STEPWISE, r"stages\[1\]\.kind: a second 'stepwise' stage"),
        (STEPWISE + '[[stages]]\nkind = "accuracy"\n', r"stages\[1\]: a accuracy stage follows"),
        (
            STEPWISE.replace('"stepwise"', '"stepwise"\nfrom = "previous"'),
            r"stages\[0\]\.from: only an output_error stage",
        ),
        (STEPWISE.replace('["a",', '["d",'), r"term 'd' uses \['d'\], not channels"),
        (STEPWISE.replace("[stages.coefficients.z]", "[stages.coefficients.y]"), r"\.y\.response"),
        (STEPWISE.replace("candidates", "terms"), r"z\.terms: unknown key"),
        (STEPWISE + "[estimation]\nsolver = 'mnr'\n", r"estimation: with \[\[stages\]\]"),
        (
            STEPWISE + '[[stages]]\nkind = "output_error"\nfrom = "previous"\n',
            r"model: missing section \[model\]; the output_error stage",
        ),
        (
            STEPWISE + '[model]\nmodule = "m.py"\n[[stages]]\nkind = "output_error"\n'
            'from = "previous"\n',
            r'stages\[1\]\.from: "previous" builds the model .* "alpha_q" only',
        ),
        (
            STEPWISE + '[model]\ntype = "alpha_q"\n[model.constants]\nmass = 1\nS = 1\n'
            'cbar = 1\nIy = 1\ng = 9.8\n[[stages]]\nkind = "output_error"\nfrom = "previous"\n',
            r"stages\[0\]\.coefficients: the alpha_q model takes CZ and Cm, got \['z'\]",
        ),
        (
            '[model]\ntype = "alpha_q"\n[model.constants]\nmass = 1\nS = 1\ncbar = 1\nIy = 1\n'
            'g = 9.8\n[[stages]]\nkind = "output_error"\n',
            r"stages\[0\]\.from: the alpha_q model has no model\.aero",
        ),
    ],
)
def test_stage_errors_name_the_key(linear, text, message):
    with pytest.raises(CaseError, match=message):
        load_case(_case(linear, text))


def test_an_empty_stage_list_is_refused(tmp_path):
    path = tmp_path / "case.toml"
    path.write_text("stages = []\n" + HEAD)
    with pytest.raises(CaseError, match=r"^stages: expected a non-empty array of tables"):
        load_case(path)


# ------------------------------------------------------------------ stepwise → output error

# the parameters the α–q data are simulated with (the reference values of the test)
TRUTH = {
    "CZ_0": -0.6537767,
    "CZ_alpha": -5.0,
    "CZ_de": -0.4,
    "Cm_0": 0.0,
    "Cm_alpha": -0.8,
    "Cm_qhat": -12.0,
    "Cm_de": -1.2,
}
CONSTANTS = {"mass": 1000.0, "S": 10.0, "cbar": 1.5, "Iy": 2000.0, "g": 9.80665}


def _alpha_q_flight(directory: Path) -> None:
    """f.csv: the α–q model with TRUTH on a 3-2-1-1 elevator input, with CZ, Cm and q̂ channels
    computed from the simulated states (+ seeded noise σ 1e-4 on CZ and Cm)."""
    from flightid.cases.alpha_q import alpha_q_model, structure_from_terms
    from flightid.data.flightdata import FlightData
    from flightid.model.parameters import Parameter, Parameters
    from flightid.simulation import simulate

    structure = structure_from_terms(
        {"CZ": ["1", "alpha", "de"], "Cm": ["1", "alpha", "qhat", "de"]}
    )
    parameters = Parameters([Parameter(n, v) for n, v in TRUTH.items()])
    model = alpha_q_model(structure, parameters, x0=(0.0, 0.0), **CONSTANTS)
    t = np.arange(501) * 0.02
    # 3-2-1-1 elevator input from t = 1 s, 0.05 rad, pulse unit 0.5 s
    de = np.zeros_like(t)
    for start, stop, sign in ((1.0, 2.5, 1), (2.5, 3.5, -1), (3.5, 4.0, 1), (4.0, 4.5, -1)):
        de[(t >= start) & (t < stop)] = 0.05 * sign
    inputs = {"V": np.full_like(t, 50.0), "qbar": np.full_like(t, 1500.0)}
    inputs |= {n: np.zeros_like(t) for n in ("theta", "phi", "ax", "p", "r")}
    inputs["de"] = de
    zeros = {n: np.zeros_like(t) for n in ("alpha", "q", "az")}
    y = simulate(model, FlightData(t, inputs, zeros, name="sim"))
    alpha, q, az = y.T
    qhat = q * CONSTANTS["cbar"] / (2 * 50.0)
    rng = np.random.default_rng(7)
    cz = TRUTH["CZ_0"] + TRUTH["CZ_alpha"] * alpha + TRUTH["CZ_de"] * de
    cm = TRUTH["Cm_alpha"] * alpha + TRUTH["Cm_qhat"] * qhat + TRUTH["Cm_de"] * de
    columns = {
        "time": t,
        **inputs,
        "alpha": alpha,
        "q": q,
        "az": az,
        "qhat": qhat,
        "CZ": cz + 1e-4 * rng.standard_normal(t.size),
        "Cm": cm + 1e-4 * rng.standard_normal(t.size),
    }
    rows = "\n".join(
        ",".join(f"{v:.17g}" for v in row) for row in zip(*columns.values(), strict=True)
    )
    (directory / "f.csv").write_text(",".join(columns) + "\n" + rows + "\n")


ALPHA_Q = """
[data]
file = "f.csv"
data_dir = "."
format = "csv"
time = "time"
[data.inputs]
V = "V"
qbar = "qbar"
theta = "theta"
phi = "phi"
ax = "ax"
p = "p"
r = "r"
de = "de"
qhat = "qhat"
CZ = "CZ"
Cm = "Cm"
[data.outputs]
alpha = "alpha"
q = "q"
az = "az"
[model]
type = "alpha_q"
[model.constants]
mass = 1000.0
S = 10.0
cbar = "cbar_column"
Iy = 2000.0
g = 9.80665
[[stages]]
kind = "stepwise"
[stages.coefficients.CZ]
candidates = ["alpha", "qhat", "de", "alpha^2"]
[stages.coefficients.Cm]
candidates = ["alpha", "qhat", "de", "alpha*de"]
[[stages]]
kind = "output_error"
from = "previous"
[[stages]]
kind = "accuracy"
"""


def test_stepwise_then_output_error_recovers_the_simulated_parameters(tmp_path):
    _alpha_q_flight(tmp_path)
    text = (tmp_path / "f.csv").read_text().splitlines()
    # a constant column for cbar: model.constants by column name takes its mean
    text = [text[0] + ",cbar_column"] + [line + ",1.5" for line in text[1:]]
    (tmp_path / "f.csv").write_text("\n".join(text) + "\n")
    case_path = tmp_path / "case.toml"
    case_path.write_text(ALPHA_Q)
    run = run_stages(load_case(case_path))
    ((stage, results),) = run.regressions
    assert set(results["CZ"].selected) == {"1", "alpha", "de"}
    assert set(results["Cm"].selected) == {"1", "alpha", "qhat", "de"}
    est = run.estimate
    assert est.converged, est.message
    assert set(est.names) == set(TRUTH)
    # noise-free outputs: output error returns the simulated parameters
    for name, truth in TRUTH.items():
        assert est.value(name) == pytest.approx(truth, abs=1e-6 + 1e-5 * abs(truth)), name
    # the accuracy stage ran (Cramér–Rao by default)
    assert run.output_error.accuracy is not None
    assert [s["kind"] for s in run.stages_dict()] == ["stepwise", "output_error", "accuracy"]
    assert run.stages_dict()[1]["start"]["Cm_alpha"] == results["Cm"].fit.parameter("alpha")[0]


def test_stages_form_of_a_run_case_gives_the_same_estimate(tmp_path):
    """The CSV walk-through case with its [estimation] written as an output_error stage and
    a prediction stage runs the same estimation (the stages are the same run)."""
    import shutil

    from flightid.cases import run_case

    walk = ROOT / "examples" / "csv_walkthrough"
    for name in ("my_case.toml", "my_flight.csv", "short_period.py"):
        shutil.copy(walk / name, tmp_path / name)
    text = (tmp_path / "my_case.toml").read_text()
    assert "[estimation]\n" in text
    staged = tmp_path / "staged.toml"
    staged.write_text(
        text.replace("[estimation]\n", '[[stages]]\nkind = "output_error"\n')
        + '\n[[stages]]\nkind = "prediction"\nfile = "my_flight.csv"\n'
    )
    case = load_case(staged)
    assert [s.kind for s in case.stages] == ["output_error", "prediction"]
    assert case.estimation == load_case(tmp_path / "my_case.toml").estimation
    single = run_case(load_case(tmp_path / "my_case.toml"))
    run = run_case(case)
    np.testing.assert_array_equal(run.estimate.values, single.estimate.values)
    # the prediction stage predicted the estimation maneuver itself: the estimate's own fit
    (prediction,) = run.predictions
    np.testing.assert_allclose(prediction.predicted, run.estimate.predicted, rtol=1e-12)


def test_regression_stages_see_every_maneuver(linear):
    """Two maneuvers (the file's halves) give the regression of the whole file: the stage's
    signals are the maneuvers' channels end to end."""
    lines = (linear / "f.csv").read_text().splitlines()
    (linear / "f1.csv").write_text("\n".join(lines[:101]) + "\n")
    (linear / "f2.csv").write_text("\n".join([lines[0], *lines[101:]]) + "\n")
    text = '[[stages]]\nkind = "regression"\n[stages.coefficients.z]\nterms = ["1", "a", "b"]\n'
    whole = load_case(_case(linear, text))
    halves = load_case(
        _case(linear, text.replace("[[stages]]", '[[stages]]\nname = "halves"'), "halves.toml")
    )
    assert halves.stages[0].name == "halves"
    raw = (
        (linear / "halves.toml")
        .read_text()
        .replace('file = "f.csv"', 'files = ["f1.csv", "f2.csv"]')
    )
    (linear / "halves.toml").write_text(raw)
    halves = load_case(linear / "halves.toml")
    assert [m.name for m in halves.maneuvers] == ["f1", "f2"]
    one = run_regression_stage(whole.stages[0], case_signals(whole))["z"]
    two = run_regression_stage(halves.stages[0], case_signals(halves))["z"]
    assert two.fit.residuals.shape == (200,)
    np.testing.assert_allclose(two.fit.estimates, one.fit.estimates, rtol=1e-12)


def test_regression_knows_nothing_about_cases_or_simulation():
    """DESIGN.md: `regression` fits regressions; case files are `cases`' business. Neither a
    source line of flightid/regression nor importing it brings in cases or simulate."""
    import re
    import subprocess
    import sys

    imports = re.compile(r"^\s*(from|import)\s+flightid\.(cases|simulate)\b", re.MULTILINE)
    for path in sorted((ROOT / "src" / "flightid" / "regression").glob("*.py")):
        assert not imports.search(path.read_text(encoding="utf-8")), path.name
    code = (
        "import sys, flightid.regression, flightid.regression.pipeline; "
        "print(sorted(m for m in sys.modules if m.startswith(('flightid.cases', "
        "'flightid.simulation'))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
