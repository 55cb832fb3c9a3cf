"""Reading a case whose user model carries biases compiles nothing: the model's f and h are
compiled (or loaded from the kernel cache) by the kernel the estimation builds anyway, and a
model numba cannot compile still runs in Python with the one-line ``CompileWarning`` naming
the user's line.

The numba compilations are counted with numba's ``numba:compile`` events, with the disk
cache off (``FLIGHTID_KERNEL_CACHE=0``) and a model whose content no other test has (a
``TAG`` constant per test), so that every function that is compiled is compiled here.
"""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from numba.core import event

from flightid.cases import load_case, prepare_case, run_case
from flightid.cli.main import main
from flightid.errors import CompileWarning
from test_compile_cache import _Compiles

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "examples" / "csv_walkthrough"
_TAGS = iter(range(1, 10_000))


def _biased_case(tmp_path: Path, uncompilable: bool = False) -> tuple[Path, int]:
    """The CSV walk-through with an output bias on α and a TAG in f (1e-300 × a counter:
    nothing in value, unique in content); ``uncompilable``: f reads a dict global numba
    cannot type. (case, the line of f's second equation)."""
    target = tmp_path / "walk"
    shutil.copytree(WALK, target)
    source = (target / "short_period.py").read_text()
    tag = next(_TAGS) * 1e-300
    source = source.replace("PARAMETERS =", f'TAG = {tag!r}\nGAIN = {{"k": 1.0}}\nPARAMETERS =')
    factor = ' * GAIN["k"]' if uncompilable else " + TAG"
    source = source.replace("theta[5] * u[0]\n", f"theta[5] * u[0]{factor}\n")
    (target / "tagged.py").write_text(source)
    line = next(i + 1 for i, text in enumerate(source.splitlines()) if "dx[1] =" in text)
    case = target / "my_case.toml"
    text = case.read_text().replace('module = "short_period.py"', 'module = "tagged.py"')
    text = text.replace(
        "[estimation]",
        "[biases.outputs]\nalpha = 0.0\n\n[output]\nfigures = false\nreport = false\n\n"
        "[estimation]",
    )
    case.write_text(text)
    return case, line


@pytest.fixture()
def no_disk_cache(monkeypatch):
    monkeypatch.setenv("FLIGHTID_KERNEL_CACHE", "0")


def test_reading_a_biased_user_model_compiles_nothing(tmp_path, no_disk_cache):
    case, _ = _biased_case(tmp_path)
    listener = _Compiles()
    with event.install_listener("numba:compile", listener):
        prepared = prepare_case(load_case(case))
    # the user's f and h were compiled on zeros here, only to see that they compile
    assert listener.count == 0
    assert len(prepared.model.parameters) == 7  # six of the model, the bias on α


def test_validating_a_biased_user_model_compiles_nothing(tmp_path, no_disk_cache, capsys):
    case, _ = _biased_case(tmp_path)
    listener = _Compiles()
    with event.install_listener("numba:compile", listener):
        code = main(["validate", str(case)])
    out = capsys.readouterr().out
    assert code == 0, out
    assert out.splitlines()[-1] == "valid"
    assert listener.count == 0


def test_the_estimation_still_runs_the_compiled_model(tmp_path, no_disk_cache):
    case, _ = _biased_case(tmp_path)
    listener = _Compiles()
    with event.install_listener("numba:compile", listener):
        run = run_case(load_case(case), accuracy="none")
    assert run.estimate.converged
    # the kernels, and with them the user's f and h, are compiled by the estimation
    assert listener.count > 0
    # the same estimates as the interpreted model (compiled = false: the Python f and h)
    text = case.read_text().replace("[estimation]\n", "[estimation]\ncompiled = false\n")
    python_case = case.with_name("python_case.toml")
    python_case.write_text(text)
    python_run = run_case(load_case(python_case), accuracy="none")
    np.testing.assert_allclose(
        run.estimate.values, python_run.estimate.values, rtol=1e-9, atol=1e-12
    )


def test_a_biased_model_numba_cannot_compile_warns_when_the_kernel_is_built(
    tmp_path, no_disk_cache
):
    case, line = _biased_case(tmp_path, uncompilable=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error", CompileWarning)
        # reading the case says nothing and compiles nothing
        prepared = prepare_case(load_case(case))
    from flightid.simulation import Simulator

    with pytest.warns(CompileWarning) as caught:
        Simulator(prepared.model, list(prepared.maneuvers))
    (record,) = [w for w in caught if issubclass(w.category, CompileWarning)]
    message = str(record.message)
    assert f"tagged.py line {line}" in message and 'GAIN["k"]' in message
    assert "Untyped global name 'GAIN'" in message and "pure Python" in message
    assert "\n" not in message


def test_a_biased_model_numba_cannot_compile_runs_in_python(tmp_path, no_disk_cache, capsys):
    case, line = _biased_case(tmp_path, uncompilable=True)
    code = main(["run", str(case), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 0, err
    lines = err.splitlines()
    (warning,) = [w for w in lines if w.startswith("flightid: warning:") and "tagged" in w]
    assert f"tagged.py line {line}" in warning and "pure Python" in warning
