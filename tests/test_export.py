"""flightid export: a result folder read back (case file checked by SHA-256, nothing
estimated again) and written as state-space JSON / NPZ, MATLAB .mat and a stand-alone Python
module; exported files replace only files flightid exported.

References: the short-period model of the CSV walk-through is linear, so A, B are its
parameters in closed form and σ of A's entries is σ of those parameters; the .mat file is
read by scipy.io.loadmat; the Python module runs in a separate interpreter without flightid
(``python -I``) and is compared with flightid's own simulation.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.io import loadmat
from tests.data_paths import DATA, needs_data

from flightid.aircraft import AeroModel, Airplane, longitudinal_model
from flightid.cases.load_run import CaseChangedError, RunFolderError, load_run
from flightid.cli.main import main
from flightid.data.flightdata import FlightData
from flightid.export import (
    ExportOverwriteError,
    PythonExportError,
    python_source,
    read_statespace,
    write_python,
    write_statespace,
)
from flightid.model.parameters import Parameters
from flightid.model.statespace import StateSpaceModel
from flightid.simulation import simulate
from flightid.simulation.prediction import initial_states

ROOT = Path(__file__).resolve().parents[1]
CSV_CASE = ROOT / "examples" / "csv_walkthrough" / "my_case.toml"

# reads the module named argv[2] from the folder argv[1] (no flightid on the path: python -I),
# simulates the inputs of argv[3] and saves the outputs to argv[4]
RUNNER = """
import importlib, sys
import numpy as np
sys.path.insert(0, sys.argv[1])
module = importlib.import_module(sys.argv[2])
data = np.load(sys.argv[3])
np.save(sys.argv[4], module.simulate(data["t"], data["u"]))
print("flightid imported" if any(m.split(".")[0] == "flightid" for m in sys.modules) else "ok")
"""


def _cli(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([*argv])
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """`flightid run` of a copy of the CSV walk-through case (short period, 501 samples)."""
    folder = tmp_path_factory.mktemp("case")
    shutil.copytree(CSV_CASE.parent, folder, dirs_exist_ok=True)
    out = folder / "run"
    code, _, err = _cli("run", str(folder / CSV_CASE.name), "--out", str(out), "--quiet")
    assert code == 0, err
    return out


def _run_standalone(tmp_path: Path, module: Path, t: np.ndarray, u: np.ndarray) -> np.ndarray:
    inputs, outputs = tmp_path / "inputs.npz", tmp_path / "outputs.npy"
    np.savez(inputs, t=t, u=u)
    script = tmp_path / "runner.py"
    script.write_text(RUNNER, encoding="utf-8")
    done = subprocess.run(
        [
            sys.executable,
            "-I",
            str(script),
            str(module.parent),
            module.stem,
            str(inputs),
            str(outputs),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"  # ran without flightid
    return np.load(outputs)


# ---------------------------------------------------------------------------- reading back


def test_results_json_holds_the_covariance_and_the_run_reads_back(run_dir):
    entry = json.loads((run_dir / "results.json").read_text())["results"][0]
    covariance = entry["covariance"]
    free = [p for p in entry["parameters"] if p["free"]]
    assert covariance["parameters"] == [p["name"] for p in free]
    # the default σ of the table is √ of the covariance's diagonal
    std = np.sqrt(np.diag(np.array(covariance["default"])))
    np.testing.assert_allclose(std, [p["std"] for p in free], rtol=1e-12)
    std_cr = np.sqrt(np.diag(np.array(covariance["cramer_rao"])))
    np.testing.assert_allclose(std_cr, [p["std_cr"] for p in free], rtol=1e-12)
    run = load_run(run_dir)
    assert run.values == {p["name"]: p["value"] for p in entry["parameters"]}
    assert run.maneuvers[0].n_samples == entry["maneuvers"][0]["samples"]
    # the recorded fit, reproduced by simulating the rebuilt model (no estimation)
    measured = np.column_stack([run.maneuvers[0].channel(n) for n in run.model.outputs])
    rms = np.sqrt(np.mean((measured - run.simulate(run.maneuvers[0])) ** 2, axis=0))
    np.testing.assert_allclose(rms, entry["fit_rms"], rtol=1e-6)


def test_a_changed_or_missing_case_file_is_refused_naming_both_digests(run_dir, tmp_path):
    copy = tmp_path / "run"
    shutil.copytree(run_dir, copy)
    document = json.loads((copy / "results.json").read_text())
    case = Path(document["results"][0]["case"]["file"])
    recorded = document["results"][0]["case"]["sha256"]
    edited = tmp_path / "my_case.toml"
    edited.write_text(case.read_text() + "\n# edited\n")
    document["results"][0]["case"]["file"] = str(edited)
    (copy / "results.json").write_text(json.dumps(document))
    with pytest.raises(CaseChangedError, match=recorded) as caught:
        load_run(copy)
    import hashlib

    assert hashlib.sha256(edited.read_bytes()).hexdigest() in str(caught.value)
    code, _, err = _cli("export", str(copy), "--format", "mat", "--out", str(tmp_path / "m"))
    assert code == 1 and "changed since the run" in err
    assert not (tmp_path / "m.mat").exists()
    edited.unlink()
    with pytest.raises(CaseChangedError, match="is missing"):
        load_run(copy)


def test_a_folder_that_is_not_a_run_is_refused(tmp_path):
    with pytest.raises(RunFolderError, match="expected a flightid run folder"):
        load_run(tmp_path)
    (tmp_path / "results.json").write_text('{"results": [{"estimator": "recursive"}]}')
    with pytest.raises(RunFolderError, match="output-error or filter-error run"):
        load_run(tmp_path)


# ---------------------------------------------------------------------------- state space


def test_statespace_json_and_npz_round_trip_the_linear_model(run_dir, tmp_path):
    code, printed, err = _cli(
        "export", str(run_dir), "--format", "statespace", "--out", str(tmp_path / "sp")
    )
    assert code == 0, err
    assert printed.split() == [
        "written:",
        str(tmp_path / "sp.json"),
        "written:",
        str(tmp_path / "sp.npz"),
    ]
    run = load_run(run_dir)
    linear = run.linearize()
    for path in (tmp_path / "sp.json", tmp_path / "sp.npz"):
        back = read_statespace(path)
        for key in ("A", "B", "C", "D", "x0", "u0", "f0", "y0", "covariance"):
            np.testing.assert_allclose(getattr(back, key), getattr(linear, key), rtol=1e-12, atol=0)
        assert (back.states, back.inputs, back.outputs) == (("alpha", "q"), ("de",), ("alpha", "q"))
        assert back.state_units == ("rad", "rad/s")
        assert [m.name for m in back.modes()] == ["short period"]
    # closed form: A = [[Za, 1 + Zq], [Ma, Mq]], B = [[Zde], [Mde]]; σ(A) = σ of those
    v, s = run.values, run.std
    np.testing.assert_allclose(linear.A, [[v["Za"], 1 + v["Zq"]], [v["Ma"], v["Mq"]]], rtol=1e-8)
    np.testing.assert_allclose(linear.B, [[v["Zde"]], [v["Mde"]]], rtol=1e-8)
    np.testing.assert_allclose(
        linear.block_std("A"), [[s["Za"], s["Zq"]], [s["Ma"], s["Mq"]]], rtol=1e-6
    )
    document = json.loads((tmp_path / "sp.json").read_text())
    mode = document["modes"][0]
    assert mode["name"] == "short period" and mode["omega_n_std_rad_per_s"] > 0


def test_mat_file_loads_in_scipy_and_matches(run_dir, tmp_path):
    code, _, err = _cli("export", str(run_dir), "--format", "mat", "--out", str(tmp_path / "sp"))
    assert code == 0, err
    linear = load_run(run_dir).linearize()
    mat = loadmat(tmp_path / "sp.mat")
    for key in ("A", "B", "C", "D"):
        np.testing.assert_array_equal(mat[key], getattr(linear, key))
        np.testing.assert_array_equal(mat[f"{key}_std"], linear.block_std(key))
    np.testing.assert_array_equal(mat["Covariance"], linear.covariance)
    np.testing.assert_array_equal(mat["x0"].ravel(), linear.x0)
    assert [str(c[0][0]) for c in mat["StateName"]] == ["alpha", "q"]
    assert [str(c[0][0]) for c in mat["InputName"]] == ["de"]
    (mode,) = linear.modes()
    assert str(mat["ModeName"][0, 0][0]) == "short period"
    assert mat["ModeEigenvalue"][0, 0] == mode.eigenvalue
    assert mat["ModeDampingRatioStd"][0, 0] == mode.damping_ratio_std


def test_at_gives_the_operating_point(run_dir, tmp_path):
    point = "alpha=0.1,q=0.02,de=-0.03"
    code, _, err = _cli(
        "export",
        str(run_dir),
        "--format",
        "statespace",
        "--out",
        str(tmp_path / "p"),
        "--at",
        point,
    )
    assert code == 0, err
    back = read_statespace(tmp_path / "p.json")
    np.testing.assert_array_equal(back.x0, [0.1, 0.02])
    np.testing.assert_array_equal(back.u0, [-0.03])
    code, _, err = _cli(
        "export", str(run_dir), "--format", "mat", "--out", str(tmp_path / "q"), "--at", "alpha=1"
    )
    assert code == 1 and "missing ['q', 'de']" in err


# ---------------------------------------------------------------------------- overwriting


def test_existing_files_are_replaced_only_with_overwrite_and_only_when_flightid_wrote_them(
    run_dir, tmp_path
):
    out = tmp_path / "m.mat"
    assert _cli("export", str(run_dir), "--format", "mat", "--out", str(out))[0] == 0
    first = out.read_bytes()
    code, _, err = _cli("export", str(run_dir), "--format", "mat", "--out", str(out))
    assert code == 1 and "give --overwrite" in err
    code, _, err = _cli("export", str(run_dir), "--format", "mat", "--out", str(out), "--overwrite")
    assert code == 0, err
    assert out.read_bytes() != b"" and len(out.read_bytes()) == len(first)
    # a file of the user's, and an export edited since, are never replaced
    mine = tmp_path / "mine.mat"
    mine.write_bytes(b"my own data")
    code, _, err = _cli(
        "export", str(run_dir), "--format", "mat", "--out", str(mine), "--overwrite"
    )
    assert code == 1 and "flightid did not write it" in err
    assert mine.read_bytes() == b"my own data"
    out.write_bytes(out.read_bytes() + b"edited")
    code, _, err = _cli("export", str(run_dir), "--format", "mat", "--out", str(out), "--overwrite")
    assert code == 1 and "changed since flightid exported it" in err
    assert out.read_bytes().endswith(b"edited")
    # the two files of statespace are checked before either is written
    (tmp_path / "s.npz").write_bytes(b"mine")
    linear = load_run(run_dir).linearize()
    with pytest.raises(ExportOverwriteError):
        write_statespace(linear, tmp_path / "s", overwrite=True)
    assert not (tmp_path / "s.json").exists()


# ---------------------------------------------------------------------------- python


def test_python_module_of_a_user_model_reproduces_the_simulation_without_flightid(
    run_dir, tmp_path
):
    out = tmp_path / "short_period_model.py"
    code, _, err = _cli("export", str(run_dir), "--format", "python", "--out", str(out))
    assert code == 0, err
    run = load_run(run_dir)
    maneuver = run.maneuvers[0]
    u = np.column_stack([maneuver.channel(n) for n in run.model.inputs])
    y = _run_standalone(tmp_path, out, maneuver.time, u)
    (x0,) = initial_states(run.model, [maneuver], None)
    expected = run.simulate(maneuver, x0)
    np.testing.assert_allclose(y, expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))
    text = out.read_text()
    assert "def f(t, x, u, theta):" in text and "THETA_STD" in text


def _input_data(inputs, n: int = 400, dt: float = 0.02, seed: int = 3) -> FlightData:
    """Elevator pulses with noise, a varying thrust, the other inputs 0."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    channels = {name: np.zeros(n) for name in inputs}
    channels["de"] = 0.02 * np.sign(np.sin(2 * np.pi * 0.4 * t)) + 0.002 * rng.normal(size=n)
    channels["T"] = 2000.0 + 100.0 * np.sin(2 * np.pi * 0.1 * t)
    return FlightData(t, channels, name="doublets")


def _load_module(path: Path):
    namespace: dict = {"__name__": "exported"}
    exec(compile(path.read_text(), str(path), "exec"), namespace)  # noqa: S102
    return namespace


def test_python_module_of_a_built_in_airplane_model_reproduces_the_simulation(tmp_path):
    airplane = Airplane(
        mass=1300.0, Ix=1500.0, Iy=3000.0, Iz=4000.0, Ixz=150.0, S=17.0, b=10.5, cbar=1.7,
        density=1.1, thrust_input="T",
    )  # fmt: skip
    aero = AeroModel(
        {"CD": ["1", "alpha"], "CL": ["1", "alpha"], "Cm": ["1", "alpha", "qhat", "de"]}
    )
    values = {"CD_0": 0.03, "CD_alpha": 0.3, "CL_0": 0.3, "CL_alpha": 5.0, "Cm_0": 0.02}
    values |= {"Cm_alpha": -0.8, "Cm_qhat": -12.0, "Cm_de": -1.1}
    parameters = aero.parameters().with_values(values)
    model = longitudinal_model(
        airplane, aero, parameters, x0=(60.0, 3.0, 0.0, -0.05, 0.0, float(np.cos(0.05)))
    )
    assert model.f.model_code == "generated"
    data = _input_data(model.inputs)
    path = write_python(model, tmp_path / "airplane.py", model.initial_state(), std=None)
    module = _load_module(path)
    u = np.column_stack([data.channel(n) for n in model.inputs])
    expected = simulate(model, data)
    y = module["simulate"](data.time, u)
    np.testing.assert_allclose(y, expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))
    text = path.read_text()
    assert "from numba" not in text and "import numba" not in text
    assert "def f_out(t, x, u, theta, out):" in text  # the generated straight-line code


def _closure_model(nonlinear: bool) -> StateSpaceModel:
    gain = 2.5  # captured: a closure, not copyable source

    def f(t, x, u, th):
        dx = np.array([th[0] * x[0] + th[1] * u[0] + gain * 0.01, th[2] * x[0] - x[1]])
        return dx + (np.array([0.1 * x[1] ** 2, 0.0]) if nonlinear else 0.0)

    def h(t, x, u, th):
        return np.array([x[0], x[1] + th[3]])

    parameters = Parameters({"a": -1.3, "b": 0.8, "c": 0.5, "bias": 0.02})
    return StateSpaceModel(("x1", "x2"), ("de",), ("y1", "y2"), f, h, parameters, x0=(0.1, 0.0))


def test_python_module_of_a_linear_closure_model_holds_its_exact_matrices(tmp_path):
    model = _closure_model(nonlinear=False)
    data = FlightData(np.arange(300) * 0.01, {"de": np.sin(np.arange(300) * 0.05)})
    path = write_python(model, tmp_path / "linear", model.initial_state(), method="rk4")
    assert path.name == "linear.py"
    module = _load_module(path)
    np.testing.assert_array_equal(module["A"], [[-1.3, 0.0], [0.5, -1.0]])
    np.testing.assert_array_equal(module["B"], [[0.8], [0.0]])
    expected = simulate(model, data)
    y = module["simulate"](data.time, data.channel("de").reshape(-1, 1))
    np.testing.assert_allclose(y, expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))


def test_models_that_cannot_be_written_are_refused_by_name():
    with pytest.raises(PythonExportError, match="not affine in the states and inputs"):
        python_source(_closure_model(nonlinear=True), (0.1, 0.0))
    with pytest.raises(PythonExportError, match="expected 2 values"):
        python_source(_closure_model(nonlinear=False), (0.1,))


# ---------------------------------------------------------------------------- real data


@needs_data("fvsysid/hfb320_1_10.asc")
def test_hfb320_run_exports_a_python_module_and_its_longitudinal_modes(tmp_path):
    case = ROOT / "examples" / "cases" / "hfb320_longitudinal.toml"
    out = tmp_path / "run"
    code, _, err = _cli(
        "run",
        str(case),
        "--out",
        str(out),
        "--quiet",
        "--accuracy",
        "none",
        "--data-dir",
        str(DATA),
    )
    assert code == 0, err
    module = tmp_path / "hfb320_model.py"
    assert _cli("export", str(out), "--format", "python", "--out", str(module))[0] == 0
    run = load_run(out)
    maneuver = run.maneuvers[0]
    u = np.column_stack([maneuver.channel(n) for n in run.model.inputs])
    y = _run_standalone(tmp_path, module, maneuver.time, u)
    (x0,) = initial_states(run.model, [maneuver], None)
    expected = run.simulate(maneuver, x0)
    np.testing.assert_allclose(y, expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))
    assert _cli("export", str(out), "--format", "statespace", "--out", str(tmp_path / "ss"))[0] == 0
    back = read_statespace(tmp_path / "ss.json")
    names = [m.name for m in back.modes()]
    assert names == ["short period", "phugoid"]
    sp = back.modes()["short period"]
    # the HFB-320 short period: ω_n about 3 rad/s, damping about 0.5 (a regression guard)
    assert 1.5 < sp.natural_frequency < 5.0 and 0.2 < sp.damping_ratio < 0.9
    assert sp.natural_frequency_std > 0


def _module_model(tmp_path: Path, body: str, name: str) -> StateSpaceModel:
    from flightid.cases.usermodel import load_user_model

    path = tmp_path / f"{name}.py"
    path.write_text(
        "import numpy as np\nimport flightid.errors\n\n"
        'STATES = ("x",)\nINPUTS = ("u",)\nOUTPUTS = ("y",)\nPARAMETERS = {"a": -1.0}\n\n'
        f"def f(t, x, u, theta):\n    return np.array([{body}])\n\n"
        "def h(t, x, u, theta):\n    return np.array([x[0]])\n",
        encoding="utf-8",
    )
    user = load_user_model(path)
    return StateSpaceModel(
        user.states, user.inputs, user.outputs, user.f, user.h, Parameters(user.parameters)
    )


def test_a_model_module_importing_flightid_is_not_copied(tmp_path):
    linear = python_source(
        _module_model(tmp_path, "theta[0] * x[0] + u[0]", "linear_uses_flightid"), (0.0,)
    )
    assert "import flightid" not in linear and "A = _export_np.array([-1.0])" in linear
    with pytest.raises(PythonExportError, match=r"imports \['flightid'\]"):
        python_source(
            _module_model(tmp_path, "theta[0] * x[0] ** 3 + u[0]", "cubic_uses_flightid"), (0.0,)
        )


def test_python_x0_follows_at(run_dir, tmp_path):
    out = tmp_path / "at.py"
    code, _, err = _cli(
        "export",
        str(run_dir),
        "--format",
        "python",
        "--out",
        str(out),
        "--at",
        "alpha=0.1,q=0.2,de=0",
    )
    assert code == 0, err
    np.testing.assert_array_equal(_load_module(out)["X0"], [0.1, 0.2])


def test_a_model_module_with_future_imports_is_copied_as_valid_python(tmp_path):
    from flightid.cases.usermodel import load_user_model

    path = tmp_path / "future_model.py"
    path.write_text(
        '"""A model module with its own docstring."""\n\nfrom __future__ import annotations\n\n'
        "import math\n\n"
        'STATES = ("x",)\nINPUTS = ("u",)\nOUTPUTS = ("y",)\nPARAMETERS = {"a": -1.0}\n\n'
        "def f(t, x, u, theta):\n    return [theta[0] * math.sin(x[0]) + u[0]]\n\n"
        "def h(t, x, u, theta):\n    return [x[0]]\n",
        encoding="utf-8",
    )
    user = load_user_model(path)
    model = StateSpaceModel(
        user.states,
        user.inputs,
        user.outputs,
        user.f,
        user.h,
        Parameters(user.parameters),
        x0=(0.3,),
    )
    written = write_python(model, tmp_path / "exported_future", (0.3,))
    data = FlightData(np.arange(200) * 0.05, {"u": np.cos(np.arange(200) * 0.1)})
    y = _load_module(written)["simulate"](data.time, data.channel("u").reshape(-1, 1))
    expected = simulate(model, data)
    np.testing.assert_allclose(y, expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))
