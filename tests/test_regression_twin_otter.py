"""Twin Otter (NASA SIDPAC data, maneuvers 018 and 017): stepwise regression, the
regression → output-error → prediction stages of examples/cases/twin_otter_stepwise.toml
(one case language, `flightid run`), and the `flightid regress` alias.

Reference values are this project's own results on maneuver 018 (docs/regression.md), kept
to catch regressions; physical plausibility checks (signs, magnitudes) are noted inline.
"""

import json
import os
from pathlib import Path

import numpy as np
import pytest

import flightid.cases.stages
from flightid.cases import CaseError, load_case
from flightid.cases.stages import case_signals, run_regression_stage, run_stages
from flightid.cli.main import main
from flightid.data.loaders import read_mat
from flightid.regression import Airframe, equation_error_signals
from flightid.regression.equation_error import G_FT
from flightid.regression.pipeline import fit_statistics, parameter_name

REPO = Path(__file__).resolve().parents[1]
CASE = REPO / "examples" / "cases" / "twin_otter_stepwise.toml"
DATA = Path(os.environ.get("FLIGHTID_DATA", REPO.parent / "shared" / "data"))
M018 = DATA / "sidpac_twin_otter" / "totter_lon_020213f1_018.mat"
M017 = DATA / "sidpac_twin_otter" / "totter_lon_020213f1_017.mat"

needs_data = pytest.mark.skipif(
    not M018.is_file(), reason=f"Twin Otter data not found under {DATA} (set FLIGHTID_DATA)"
)


def _stepwise_results():
    case = load_case(CASE)
    return run_regression_stage(case.stages[0], case_signals(case, DATA))


@needs_data
def test_equation_error_coefficients_match_the_file():
    F = read_mat(M018).data
    c = lambda k: F[:, k - 1]  # noqa: E731  (1-based SIDPAC columns)
    d = np.deg2rad
    af = Airframe(
        mass=c(48), S=c(77), b=c(78), cbar=c(79), Ix=c(49), Iy=c(50), Iz=c(51), Ixz=c(52), g=G_FT
    )
    channels = dict(V=c(2), p=d(c(5)), q=d(c(6)), r=d(c(7)), az=c(13), qbar=c(27))
    measured = equation_error_signals({**channels, "qdot": d(c(43))}, af)
    # C_m from the measured q̇ reproduces the file's C_m (column 65) to round-off
    np.testing.assert_allclose(measured["Cm"], c(65), atol=1e-12)
    # C_Z from a_z: the file's C_Z (column 63) differs by a constant (an a_z bias correction
    # of 0.124 ft/s² in the file, found by regressing one on the other)
    diff = measured["CZ"] - c(63)
    assert abs(diff.mean() - 0.00185) < 1e-4 and diff.std() < 5e-5
    np.testing.assert_allclose(measured["qhat"], c(72), atol=1e-5)
    # C_m from smoothed differentiation of q follows the file's C_m closely
    smoothed = equation_error_signals(channels, af, dt=0.02)
    assert np.corrcoef(smoothed["Cm"], c(65))[0, 1] > 0.99
    assert np.sqrt(np.mean((smoothed["Cm"] - c(65)) ** 2)) < 0.1 * np.std(c(65))


@needs_data
def test_stepwise_stage_selects_the_expected_terms():
    results = _stepwise_results()
    cm, cz = results["Cm"], results["CZ"]
    assert set(cm.selected) == {"1", "alpha", "qhat", "de", "alpha^2", "alpha*de"}
    assert set(cz.selected) == {"1", "alpha", "qhat", "de", "alpha^2"}
    assert cm.fit.r2 > 0.99 and cz.fit.r2 > 0.999
    # static stability, pitch damping and elevator power have the physical signs
    value = {n: cm.fit.parameter(n)[0] for n in cm.selected}
    assert value["alpha"] < 0 and value["qhat"] < 0 and value["de"] < 0
    # regression values: flightid's own output at commit 373f808 (docs/regression.md), not an
    # independent reference; they pin today's behaviour to 3 significant digits
    assert cm.fit.parameter("alpha")[0] == pytest.approx(-1.513, abs=2e-3)
    assert cm.fit.parameter("qhat")[0] == pytest.approx(-36.27, abs=0.02)
    assert cm.fit.parameter("de")[0] == pytest.approx(-1.875, abs=2e-3)
    assert cz.fit.parameter("alpha")[0] == pytest.approx(-6.280, abs=2e-3)
    # the classical σ s·√((XᵀX)⁻¹)_jj (std_cr), a regression value of the same commit
    assert cz.fit.std_cr[cz.fit.names.index("alpha")] == pytest.approx(0.00761, rel=0.01)


def test_missing_data_is_reported_with_the_key(tmp_path, capsys):
    assert main(["run", str(CASE), "--data-dir", str(tmp_path)]) == 1
    assert "data (maneuver 1 " in (err := capsys.readouterr().err) and "no such file" in err
    assert main(["run", str(CASE), "--data-dir", str(tmp_path / "nowhere")]) == 1
    assert "data.data_dir: the data directory" in capsys.readouterr().err


def _replaced(tmp_path: Path, old: str, new: str) -> Path:
    text = CASE.read_text()
    assert old in text
    path = tmp_path / "case.toml"
    path.write_text(text.replace(old, new, 1))
    return path


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        (
            '"alpha*de"]\n\n[stages.coefficients.CZ]',
            '"beta"]\n\n[stages.coefficients.CZ]',
            r"stages\[0\]\.coefficients\.Cm\.candidates: term 'beta' uses \['beta'\]",
        ),
        ("f_enter = 4.0", "f_enter = -1", r"stages\[0\]\.f_enter: expected a non-negative"),
        ('select = "pse"', 'select = "best"', r"stages\[0\]\.select: expected one of"),
        ('solver = "mnres"', 'solver = "newton"', r"stages\[1\]\.solver: expected one of"),
        ('noise = "max"', 'noise = "max"\nsteps = 3', r"stages\[1\]\.steps: unknown key"),
        ('from = "previous"', 'from = "before"', r"stages\[1\]\.from: expected one of"),
        ("g = 32.174", "", r"model\.constants: missing \['g'\]"),
        ("g = 32.174", "g = true", r"model\.constants\.g: expected a number"),
        ('cbar = "cbar"', 'cbar = "cbar"\nb = 3.0', r"model\.constants\.b: unknown constant"),
        (
            'theta = { column = "theta", unit = "deg" }',
            'theta = { column = "theta", unit = "parsec" }',
            r"data\.inputs\.theta",
        ),
        ('type = "alpha_q"', 'type = "lateral"', r"model\.constants: unknown key in \[model\]"),
        ('format = "mat"', 'format = "sidpac"', r'data\.format: "sidpac" .* format = "mat"'),
    ],
)
def test_case_errors_name_the_key(tmp_path, old, new, key):
    with pytest.raises(CaseError, match=key):
        load_case(_replaced(tmp_path, old, new))


def test_old_regress_keys_get_a_migration_error(tmp_path):
    """The old `flightid regress` dialect ([signals], [coefficients], [stepwise], [ml]) is
    refused with the new place of each key."""
    old = tmp_path / "old.toml"
    base = '[data]\nfile = "x.mat"\n'
    for section, text, new in [
        ("signals", "[signals]\nalpha = 4\n", r"\[data\.inputs\] / \[data\.outputs\]"),
        ("coefficients", "[coefficients.Cm]\ncandidates = ['alpha']\n", "stages.coefficients"),
        ("stepwise", "[stepwise]\nf_enter = 4.0\n", 'kind = "stepwise"'),
        ("ml", "[ml]\nmodel = 'alpha_q'\n", r'kind = "output_error" and from = "previous"'),
    ]:
        old.write_text(base + text)
        with pytest.raises(CaseError, match=rf"^{section}: a key of the old .*{new}"):
            load_case(old)


def test_parameter_names():
    assert parameter_name("Cm", "1") == "Cm_0"
    assert parameter_name("Cm", "alpha*qhat") == "Cm_alpha_qhat"
    assert parameter_name("CZ", "alpha^2") == "CZ_alpha2"


@pytest.fixture(scope="module")
def staged_run():
    """The stages of the Twin Otter case, run once for the tests below (≈ 5–10 s)."""
    if not (M018.is_file() and M017.is_file()):
        pytest.skip(f"Twin Otter maneuvers 018/017 not found under {DATA} (set FLIGHTID_DATA)")
    return run_stages(load_case(CASE), DATA)


def test_regression_to_output_error_stage_and_prediction(staged_run):
    from flightid.simulation import simulate

    result = staged_run.pipeline
    run = staged_run.output_error
    est = run.estimate
    assert est.converged, est.message
    assert est.model.name == "alpha_q_longitudinal"
    fit = fit_statistics(est.measured, est.predicted, est.output_names)
    # output-error fit on 018 (regression value: flightid's own output at commit 9c87972, not
    # an independent reference: RMS 0.00061 rad, 0.00080 rad/s, 0.0018 g)
    assert fit["alpha"]["rms"] < 0.0008 and fit["q"]["rms"] < 0.0010 and fit["az"]["rms"] < 0.0025
    assert min(v["r2"] for v in fit.values()) > 0.99
    # ML improves the time-history match over the regression start values
    start = simulate(run.model, run.maneuvers[0])  # the model at the start values
    assert est.cost < np.sum((est.measured - start) ** 2 / est.r_diag)
    # regression values: flightid's own ML output at commit 9c87972 (docs/regression.md), not
    # an independent reference (the one-language run gives the same numbers to 1e-12)
    assert est.value("Cm_alpha") == pytest.approx(-1.546, abs=0.005)
    assert est.value("Cm_qhat") == pytest.approx(-33.9, abs=0.3)
    assert est.value("CZ_alpha") == pytest.approx(-6.542, abs=0.02)
    # ML started from the stepwise estimates
    cm = staged_run.regressions[0][1]["Cm"]
    assert result.start["Cm_alpha"].value == cm.fit.parameter("alpha")[0]
    # prediction on maneuver 017 with the 018 estimates (x0 from 017's first samples):
    # the dynamics carry over; a constant a_z offset (different trim) remains
    (prediction,) = run.predictions
    assert prediction.name.endswith("017") and prediction.output_names == ("alpha", "q", "az")
    r2 = dict(zip(prediction.output_names, prediction.r2, strict=True))
    assert r2["alpha"] > 0.97 and r2["q"] > 0.98 and r2["az"] > 0.9
    residual = prediction.measured - prediction.predicted
    assert np.all(residual.std(axis=0) < [0.001, 0.001, 0.004])
    assert "Cm_alpha" in result.comparison() and "Regression → output error" in (
        staged_run.summary()
    )


@needs_data
def test_alpha_q_constants_are_the_column_means():
    from flightid.cases.alpha_q import alpha_q_constants

    case = load_case(CASE)
    constants = alpha_q_constants(case.model["constants"], M018, "mat")
    # the means of the file's mass and geometry columns (SIDPAC fdata 48, 77, 79)
    F = read_mat(M018).data
    assert constants["mass"] == pytest.approx(F[:, 47].mean(), rel=1e-12)
    assert constants["mass"] == pytest.approx(338.7861, rel=1e-4)
    assert constants["S"] == pytest.approx(422.483473, rel=1e-6)
    assert constants["cbar"] == pytest.approx(F[:, 78].mean(), rel=1e-12)
    assert constants["g"] == 32.174


@pytest.mark.parametrize("command", ["run", "regress"])
def test_cli_json_contract(staged_run, monkeypatch, capsys, command):
    # the stages themselves are the fixture's (the CLI only calls run_stages and prints)
    monkeypatch.setattr(flightid.cases.stages, "run_stages", lambda *args, **kw: staged_run)
    assert main([command, str(CASE), "--json", "--data-dir", str(DATA)]) == 0
    captured = capsys.readouterr()
    assert ("alias of `flightid run`" in captured.err) == (command == "regress")
    payload = json.loads(captured.out)
    assert {"results", "stages"} <= set(payload)
    assert [s["kind"] for s in payload["stages"]] == ["stepwise", "output_error", "prediction"]
    coefficients = payload["stages"][0]["coefficients"]
    assert set(coefficients) == {"Cm", "CZ"}
    for entry in coefficients.values():
        assert {"selected", "parameters", "r2", "pse", "steps"} <= set(entry)
        assert [p["name"] for p in entry["parameters"]] == entry["selected"]
        assert entry["steps"][0]["action"] == "start"
    (entry,) = payload["results"]
    assert entry["converged"] is True
    names = [p["name"] for p in entry["parameters"]]
    assert {"Cm_0", "Cm_alpha", "Cm_qhat", "Cm_de", "CZ_alpha"} <= set(names)
    assert all(p["std"] is not None and p["std"] > 0 for p in entry["parameters"])
    # ML started from the regression estimates
    cm = {p["name"]: p["value"] for p in coefficients["Cm"]["parameters"]}
    assert payload["stages"][1]["start"]["Cm_alpha"] == pytest.approx(cm["alpha"], rel=1e-12)
    (prediction,) = entry["prediction"]
    assert prediction["maneuver"].endswith("017") and prediction["outputs"] == ["alpha", "q", "az"]
    assert min(prediction["r2"]) > 0.9 and prediction["samples"] == 301
    assert entry["maneuvers"][0]["samples"] == 401
    assert main([command, str(CASE), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "Stepwise regression for Cm" in text and "prediction on totter_lon_020213f1_017" in text


def test_regress_ml_flag_points_to_the_stage(capsys):
    assert main(["regress", str(CASE), "--ml"]) == 1
    assert 'kind = "output_error", from = "previous"' in capsys.readouterr().err


@needs_data
def test_a_file_of_regression_stages_alone_needs_no_model(tmp_path, capsys):
    text = CASE.read_text().split("# stage 2")[0]
    head, constants = text.split("[model]")
    stages = constants[constants.index("# stage 1") :]
    bare = tmp_path / "bare.toml"
    bare.write_text(head.replace("[data]\n", f'[data]\ndata_dir = "{DATA}"\n', 1) + stages)
    case = load_case(bare)
    assert case.model == {} and [s.kind for s in case.stages] == ["stepwise"]
    assert main(["run", str(bare), "--json", "--quiet"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["results"] == [] and set(payload["stages"][0]["coefficients"]) == {"Cm", "CZ"}


@needs_data
def test_validate_checks_every_stage(capsys):
    assert main(["validate", str(CASE), "--data-dir", str(DATA)]) == 0
    out = capsys.readouterr().out
    assert "[0] stepwise 'stepwise': 2 coefficient(s), 12 terms" in out
    # the output-error model is checked with every candidate term (and the forced constant)
    assert "with every candidate term" in out and "14 free parameters" in out
    assert "Cm_alpha_qhat" in out and "CZ_0" in out
    assert "prediction maneuver totter_lon_020213f1_017" in out and out.rstrip().endswith("valid")


@needs_data
def test_signals_by_column_number_equal_by_name(tmp_path):
    text = CASE.read_text()
    for name, number in (
        ('qhat = "qhat"', "qhat = 72"),
        ('CZ = "CZ"', "CZ = 63"),
        ('Cm = "Cm"', "Cm = 65"),
        ('column = "elevator"', "column = 14"),
        ('alpha = { column = "alpha"', "alpha = { column = 4"),
    ):
        assert name in text
        text = text.replace(name, number)
    numbered = tmp_path / "numbered.toml"
    numbered.write_text(text.replace("[data]\n", f'[data]\ndata_dir = "{DATA}"\n', 1))
    by_number = case_signals(load_case(numbered))
    by_name = case_signals(load_case(CASE), DATA)
    for signal in ("alpha", "qhat", "de", "CZ", "Cm"):
        np.testing.assert_array_equal(by_name[signal], by_number[signal])
    # deg → rad conversion of the alpha channel (SIDPAC column 4 is alpha in deg)
    assert by_number["alpha"] == pytest.approx(np.deg2rad(read_mat(M018).data[:, 3]))
