"""From a shipped case to a model you can fly: prediction, linear model, modes and export on
the HFB-320 (built-in model and user module), ATTAS short period and ATTAS lateral cases, and
on the simulated RP-1153 example-3 Navion.

References: the fit of each run (the residuals the estimation reports) for ``predict``; the
estimation's own model outputs for the exported stand-alone module; for the Navion, the
lateral estimate completed with the Navion's longitudinal derivatives flown in JSBSim against
flightid's 6-DOF simulation of the same values, and derivatives probed from JSBSim's
aerodynamic forces and moments against the estimates.
"""

from __future__ import annotations

import contextlib
import io
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from data_paths import needs_data
from flightid.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
CASES = ROOT / "examples" / "cases"
HFB320_DATA = "fvsysid/hfb320_1_10.asc"

# (case file, data file, expected mode names, built-in airplane model)
FLY_CASES = {
    "hfb320_builtin": (
        "hfb320_longitudinal_builtin.toml",
        HFB320_DATA,
        {"short period", "phugoid"},
        True,
    ),
    "attas_short_period": (
        "attas_short_period.toml",
        "fvsysid/fAttasElv1.mat",
        {"short period"},
        False,
    ),
    # β is an input of the lateral case: A holds p, r only, and a note says so
    "attas_lateral": (
        "attas_lateral.toml",
        "fvsysid/fAttasAilRud1.mat",
        {"roll subsidence"},
        False,
    ),
    # the same HFB-320 case with the hand-written model module
    "hfb320_user_module": (
        "hfb320_longitudinal.toml",
        HFB320_DATA,
        {"short period", "phugoid"},
        False,
    ),
}


def _cli(*argv: str) -> tuple[int, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([*argv])
    return code, out.getvalue() + err.getvalue()


def _run(case_file: Path):
    from flightid.cases import run_case

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # outlier and convergence notes of the real data
        return run_case(case_file, accuracy="none")


def _load_module(path: Path) -> dict:
    namespace: dict = {"__name__": "exported"}
    exec(compile(path.read_text(), str(path), "exec"), namespace)  # noqa: S102
    return namespace


def _case_params():
    return [pytest.param(key, marks=needs_data(spec[1]), id=key) for key, spec in FLY_CASES.items()]


def _check_predictions(run) -> None:
    """predict on each estimation maneuver, from the run's initial state, equals the fit."""
    estimate = run.estimate
    values = estimate.model.parameters.values
    for k, maneuver in enumerate(run.maneuvers):
        x0 = estimate.model.initial_state(values, k)
        prediction = estimate.predict(maneuver, x0=x0)
        rows = estimate.maneuver_index == k
        fit = np.sqrt(np.mean(estimate.residuals[rows] ** 2, axis=0))
        np.testing.assert_allclose(prediction.rms, fit, rtol=1e-9, atol=0)
        np.testing.assert_allclose(
            prediction.predicted, estimate.predicted[rows], rtol=0, atol=1e-9
        )


def _check_linear_model(run, expected_modes: set[str]):
    """The linear model at the first maneuver: finite matrices, each entry with a σ, and
    the expected modes named and stable."""
    linear = run.estimate.linearize(at=run.maneuvers[0])
    for block in "ABCD":
        matrix = getattr(linear, block)
        assert matrix.size and np.all(np.isfinite(matrix)), block
        std = linear.block_std(block)
        assert std.shape == matrix.shape and np.all(np.isfinite(std)), block
    modes = linear.modes()
    assert expected_modes <= set(modes.names), modes.names
    assert all(modes[name].stable for name in expected_modes)
    return linear


def _check_exports(run, out: Path, tmp_path: Path, built_in: bool) -> None:
    """flightid export of the result folder ``out``: statespace and python succeed (the
    module reproduces the estimation's simulation), jsbsim only for a built-in model."""
    code, text = _cli("export", str(out), "--format", "statespace", "--out", str(tmp_path / "ss"))
    assert code == 0, text
    assert (tmp_path / "ss.json").is_file() and (tmp_path / "ss.npz").is_file()
    code, text = _cli("export", str(out), "--format", "python", "--out", str(tmp_path / "mod"))
    assert code == 0, text
    estimate, maneuver = run.estimate, run.maneuvers[0]
    module = _load_module(tmp_path / "mod.py")
    u = np.column_stack([maneuver.channel(n) for n in estimate.model.inputs])
    x0 = estimate.model.initial_state(estimate.model.parameters.values, 0)
    y = module["simulate"](maneuver.time, u, x0=x0)
    expected = estimate.predicted[estimate.maneuver_index == 0]
    np.testing.assert_allclose(y, expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))
    jsbsim_out = tmp_path / "aircraft" / "AC"
    code, text = _cli("export", str(out), "--format", "jsbsim", "--out", str(jsbsim_out))
    if built_in:
        assert code == 0, text
        assert (jsbsim_out / "AC.xml").is_file()
        assert (jsbsim_out / "aerodynamics" / "nominal.xml").is_file()
    else:
        assert code != 0
        assert "built-in airplane model" in text, text
        assert not jsbsim_out.exists()


@pytest.mark.parametrize("key", _case_params())
def test_shipped_case_predicts_linearizes_and_exports(key, tmp_path):
    case_name, _, expected_modes, built_in = FLY_CASES[key]
    case_file = CASES / case_name
    run = _run(case_file)
    _check_predictions(run)
    linear = _check_linear_model(run, expected_modes)
    if key == "attas_lateral":
        assert any("['beta'] are measured states" in n for n in linear.notes), linear.notes
    out = tmp_path / "run"
    code, text = _cli("run", str(case_file), "--out", str(out), "--quiet")
    assert code == 0, text
    _check_exports(run, out, tmp_path, built_in)


# ---------------------------------------------------------------- RP-1153 example 3, Navion


def _script():
    """docs/fly_cases_numbers.py, which holds the Navion 6-DOF set-up both use."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "fly_cases_numbers", ROOT / "docs" / "fly_cases_numbers.py"
    )
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    return script


def _navion_six_dof(estimate):
    return _script().navion_six_dof(estimate)


def _navion_maneuvers(t):
    return _script().navion_maneuvers(t)


@pytest.fixture(scope="module")
def navion_run():
    from flightid.paper.example3 import run_example3

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return run_example3(2)


def test_navion_lateral_estimate_linearizes_with_its_lateral_modes(navion_run):
    """The decoupled lateral model of example 3 (u, w, q measured inputs): Dutch roll, roll
    subsidence and spiral named, each with σ; the note says the longitudinal states are held."""
    estimate, data = navion_run["estimate"], navion_run["data"]
    linear = estimate.linearize(at=data)
    for block in "ABCD":
        assert np.all(np.isfinite(getattr(linear, block))), block
        assert np.all(np.isfinite(linear.block_std(block))), block
    modes = linear.modes()
    # the spiral: the slowest real lateral mode, its bank angle in l_yz = sin Φ cos Θ
    assert {"Dutch roll", "roll subsidence", "spiral"} <= set(modes.names), modes.names
    assert modes["spiral"].time_constant > 5 * modes["roll subsidence"].time_constant
    dutch = modes["Dutch roll"]
    assert dutch.stable and 0.0 < dutch.damping_ratio < 1.0
    assert np.isfinite(dutch.damping_ratio_std) and dutch.damping_ratio_std > 0
    assert any("['u', 'w', 'q'] are measured states" in n for n in linear.notes)


def test_navion_estimate_flown_in_jsbsim_equals_flightid(navion_run, tmp_path):
    """The example-3 estimate, completed with the Navion's longitudinal derivatives, exported
    to JSBSim and flown from trim with the estimation maneuver's doublets and a held-out
    maneuver, equals flightid's 6-DOF simulation of the same values within 0.1 σ of the
    estimated measurement noise (RMS) in β, p, r, Φ, a_y."""
    pytest.importorskip("jsbsim")
    from flightid.data.flightdata import FlightData
    from flightid.export._jsbsim_fly import fly_jsbsim, initial_from_body_state
    from flightid.export.jsbsim import write_jsbsim
    from flightid.model.linearization import linearize
    from flightid.paper.example3 import DT, DURATION, OUTPUTS
    from flightid.simulation import simulate

    estimate = navion_run["estimate"]
    airplane, aero, values, model, trim = _navion_six_dof(estimate)
    six_dof = linearize(model, trim.x, [trim.inputs[n] for n in model.inputs])
    linear_modes = set(six_dof.modes().names)
    assert {"short period", "phugoid", "Dutch roll", "roll subsidence", "spiral"} <= linear_modes
    aircraft = write_jsbsim(values, airplane, tmp_path / "Navion", aero=aero,
                            dynamic_pressure="airplane")  # fmt: skip
    assert aircraft.unmodelled_axes == ()
    sigma = np.sqrt(estimate.r_diag)
    t = np.arange(0.0, DURATION + DT / 2, DT)
    for label, perturbation in _navion_maneuvers(t).items():
        inputs = {n: np.full(t.shape, v) for n, v in trim.inputs.items()}
        for name, series in perturbation.items():
            inputs[name] = inputs[name] + series
        y = simulate(model, FlightData(t, {n: inputs[n] for n in model.inputs}))
        flown = fly_jsbsim(aircraft, t, inputs, initial_from_body_state(trim.x), substeps=10)
        for i, name in enumerate(OUTPUTS):
            column = y[:, model.outputs.index(name)]
            # the maneuver moves the output by many σ, so the comparison can fail
            assert np.ptp(column) > 20 * sigma[i], (label, name)
            error = math.sqrt(float(np.mean((flown[name] - column) ** 2)))
            assert error < 0.1 * sigma[i], (label, name, error / sigma[i])


def test_fly_cases_numbers_script_prints_the_navion_tables():
    """docs/fly_cases_numbers.py (the modes, levels and round-trip table of the shipped cases)
    on the Navion, which needs no data: the lateral modes with σ, the Level met by the
    Dutch roll and roll mode (class I, category B), round-trip errors below 0.1 σ."""
    pytest.importorskip("jsbsim")
    import importlib.util

    spec = importlib.util.spec_from_file_location("fly_cases_numbers", ROOT / "docs" /
                                                  "fly_cases_numbers.py")  # fmt: skip
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    lines = script.navion()
    text = "\n".join(lines)
    for name in ("Dutch roll", "roll subsidence", "spiral", "short period", "phugoid"):
        assert f"| {name} |" in text, name
    assert "| roll-mode time constant τ_R | " in text
    rows = [line for line in lines if line.startswith(("| estimation", "| held-out"))]
    assert len(rows) == 2
    for row in rows:
        ratios = [float(cell) for cell in row.strip("|").split("|")[1:]]
        assert len(ratios) == 5 and max(ratios) < 0.1, row
