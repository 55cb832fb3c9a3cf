"""Generated straight-line f and h of the built-in airplane models (issue 14, part 1) against
the table path, the reference implementation (``code="tables"``), on seeded random states,
inputs and parameters, for every model kind and feature: α̇ and β̇ terms, splines, |x|,
products and powers, thrust line and arm, engine momentum (constant or input), propeller
torque, accelerometer scales, Vrel/dVrel and rate_speed "V0", the lateral model measuring V
and α. Without α̇/β̇ terms the compiled functions keep the table path's operation order and
agree bit for bit; with them the loads per unit rate are formed linearly instead of by
differencing, and agree to rounding (1e-12 of the values' scale).

Also: a model the generator does not cover keeps the table path, explicitly; the generated
source lives in a file named by its content, reused as it is, and a changed table gives
another file and digest; a second process compiles nothing.
"""

from __future__ import annotations

import inspect
import json
import os
import subprocess
import sys
import textwrap

import numba
import numpy as np
import pytest

from flightid.aircraft import (
    AeroModel,
    Airplane,
    alpha_q_longitudinal_model,
    codegen,
    lateral_model,
    longitudinal_model,
    six_dof_model,
    wind_axis_longitudinal_model,
)
from flightid.aircraft.generated import module_name
from flightid.errors import InputError
from flightid.model.kernel_cache import kernel_digest


@pytest.fixture(autouse=True)
def _own_cache(tmp_path, monkeypatch):
    """Generated files and numba's cache in a fresh folder per test."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))


def _airplane(**changes):
    fields = dict(
        mass=1300.0, Ix=1500.0, Iy=3000.0, Iz=4000.0, Ixz=150.0, S=17.0, b=10.5, cbar=1.7,
        density=1.1, thrust_input="T", thrust_inclination=0.05, thrust_x=1.5, thrust_z=0.3,
        engine_momentum=85.0, propeller_torque_input="Q", rotation=-1,
    )  # fmt: skip
    fields.update(changes)
    return Airplane(**fields)


FULL_TERMS = {
    "CD": ["1", "alpha", "abs(de)", "de*de", "alpha*de", "alpha^3", "spline1(alpha,0.12)"],
    "CL": ["1", "alpha", "alphadot_hat", "de", "alpha*alphadot_hat", "spline1(alpha,-0.05)^2"],
    "CY": ["beta", "betadot_hat", "dr", "beta^5"],
    "Cl": ["beta", "phat", "da", "abs(beta)*phat", "rhat"],
    "Cm": ["1", "alpha", "qhat", "alphadot_hat", "de", "abs(alpha)^2*de"],
    "Cn": ["beta", "rhat", "betadot_hat", "dr", "p*r"],
}
PLAIN_TERMS = {
    "CX": ["1", "alpha", "alpha^2", "de", "Vrel", "dVrel^2"],
    "CY": ["beta", "dr", "phat"],
    "CZ": ["1", "alpha", "qhat", "de", "abs(de)*alpha", "spline1(alpha,0.1)^3"],
    "Cl": ["beta", "phat", "rhat", "da"],
    "Cm": ["1", "alpha", "qhat", "de", "alpha^4", "dVrel"],
    "Cn": ["beta", "rhat", "dr", "da*beta"],
}
ALL_OUTPUTS = (
    "V", "alpha", "beta", "theta", "phi", "ax", "ay", "az", "p", "q", "r", "pdot", "qdot", "rdot",
)  # fmt: skip


def _value(name, rng):
    """A random value of a state or input (SI units, rad)."""
    ranges = {
        "u": (35.0, 70.0), "v": (-6.0, 6.0), "w": (-4.0, 9.0), "V": (35.0, 70.0),
        "alpha": (-0.1, 0.25), "T": (0.0, 3000.0), "Q": (0.0, 400.0), "H": (50.0, 120.0),
        "qbar": (800.0, 2500.0), "ax": (-0.1, 0.3), "theta": (-0.3, 0.3), "phi": (-0.5, 0.5),
    }  # fmt: skip
    low, high = ranges.get(name, (-0.4, 0.4))
    return rng.uniform(low, high)


def _state_and_inputs(model, rng):
    x = np.array([_value(s, rng) for s in model.states])
    if "l_xz" in model.states:
        # direction cosines of random Θ, Φ
        th, ph = rng.uniform(-0.3, 0.3), rng.uniform(-0.5, 0.5)
        for name, value in zip(
            ("l_xz", "l_yz", "l_zz"),
            (-np.sin(th), np.sin(ph) * np.cos(th), np.cos(ph) * np.cos(th)),
            strict=True,
        ):
            x[model.states.index(name)] = value
    u = np.array([_value(n, rng) for n in model.inputs])
    return x, u


def _pair(builder, airplane, aero, **kwargs):
    """The model built with generated code and with the table path."""
    generated = builder(airplane, aero, **kwargs)
    tables = builder(airplane, aero, code="tables", **kwargs)
    assert generated.f.model_code == generated.h.model_code == "generated"
    assert tables.f.model_code == tables.h.model_code == "tables"
    return generated, tables


def _compare(generated, tables, exact, seed=0, n=25):
    """f and h of both, compiled (out form) and interpreted (return form), on ``n`` random
    points; compiled bit for bit where ``exact``, else to 1e-12 of the values' scale."""
    rng = np.random.default_rng(seed)
    n_theta = len(generated.parameters)
    jit = {
        key: (numba.njit(getattr(generated, key)), numba.njit(getattr(tables, key)))
        for key in ("f_out", "h_out")
    }
    sizes = {"f_out": len(generated.states), "h_out": len(generated.outputs)}
    returns = {key: numba.njit(getattr(generated, key)) for key in ("f", "h")}
    for _ in range(n):
        x, u = _state_and_inputs(generated, rng)
        theta = rng.uniform(-0.5, 0.5, n_theta)
        for key, (gen, tab) in jit.items():
            a, b = np.empty(sizes[key]), np.empty(sizes[key])
            gen(0.0, x, u, theta, a)
            tab(0.0, x, u, theta, b)
            assert np.all(np.isfinite(b))
            if exact:
                np.testing.assert_array_equal(a, b, err_msg=key)
            else:
                scale = max(np.max(np.abs(b)), 1.0)
                np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * scale, err_msg=key)
        # the return forms compile too (nopython: they call the register_jitable out form)
        for key, fn in returns.items():
            a, b = np.empty(sizes[key + "_out"]), fn(0.0, x, u, theta)
            jit[key + "_out"][0](0.0, x, u, theta, a)
            np.testing.assert_array_equal(a, b)
        for key in ("f", "h"):
            a = getattr(generated, key)(0.0, x, u, theta)
            b = getattr(tables, key)(0.0, x, u, theta)
            scale = max(np.max(np.abs(b)), 1.0)
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * scale, err_msg=key)


def test_six_dof_with_every_feature_agrees_with_the_table_path():
    """α̇ and β̇ terms (also times α), splines, |x|, powers, products, thrust line and arm,
    constant engine momentum, propeller torque, accelerometer signs/unit, ṗ q̇ ṙ."""
    aero = AeroModel(FULL_TERMS)
    generated, tables = _pair(
        six_dof_model, _airplane(), aero, outputs=ALL_OUTPUTS,
        accelerometer={"az": "up", "unit": "m/s^2"},
    )  # fmt: skip
    _compare(generated, tables, exact=False)


def test_six_dof_without_rate_terms_is_bit_identical():
    """CX/CZ form, Vrel and dVrel, rate_speed V0, engine momentum from an input channel."""
    aero = AeroModel(PLAIN_TERMS)
    airplane = _airplane(
        engine_momentum=0.0, engine_momentum_input="H", thrust_arm=0.4, thrust_x=0.0, thrust_z=0.0
    )
    generated, tables = _pair(
        six_dof_model, airplane, aero, outputs=ALL_OUTPUTS, reference_speed=52.0,
        rate_speed="V0", accelerometer="load_factor",
    )  # fmt: skip
    assert "H" in generated.inputs
    _compare(generated, tables, exact=True)


def test_longitudinal_model_with_alphadot_agrees():
    terms = {k: FULL_TERMS[k] for k in ("CD", "CL", "Cm")}
    generated, tables = _pair(
        longitudinal_model, _airplane(), AeroModel(terms),
        outputs=("V", "alpha", "q", "theta", "ax", "az", "qdot"),
    )  # fmt: skip
    _compare(generated, tables, exact=False)


def test_longitudinal_model_without_rate_terms_is_bit_identical():
    terms = {k: PLAIN_TERMS[k] for k in ("CX", "CZ", "Cm")}
    generated, tables = _pair(
        longitudinal_model, _airplane(), AeroModel(terms), reference_speed=50.0,
        outputs=("V", "alpha", "q", "theta", "ax", "az", "qdot"),
    )  # fmt: skip
    _compare(generated, tables, exact=True)


def test_lateral_model_with_betadot_agrees():
    """u, w, q measured; β̇ from v̇ alone (the lateral rule), torque and engine terms."""
    terms = {k: FULL_TERMS[k] for k in ("CY", "Cl", "Cn")}
    generated, tables = _pair(
        lateral_model, _airplane(), AeroModel(terms),
        outputs=("beta", "p", "r", "phi", "ay", "pdot", "rdot"),
    )  # fmt: skip
    _compare(generated, tables, exact=False)


@pytest.mark.parametrize("rates", [False, True])
def test_lateral_model_measuring_V_and_alpha_agrees(rates):
    terms = {k: (FULL_TERMS if rates else PLAIN_TERMS)[k] for k in ("CY", "Cl", "Cn")}
    generated, tables = _pair(
        lateral_model, _airplane(), AeroModel(terms), measured=("V", "alpha", "q"),
        outputs=("beta", "p", "r", "phi", "ay", "az"), accelerometer={"ay": "left"},
    )  # fmt: skip
    assert {"V", "alpha"} <= set(generated.inputs)
    _compare(generated, tables, exact=not rates)


@pytest.mark.parametrize("rates", [False, True])
def test_wind_axis_model_agrees(rates):
    terms = {
        "CD": ["1", "alpha", "alpha^2", "Vrel"],
        "CL": ["1", "alpha", "de", "spline1(alpha,0.1)"] + (["alphadot_hat"] if rates else []),
        "Cm": ["1", "alpha", "qhat", "abs(de)*de"] + (["alphadot_hat"] if rates else []),
    }
    generated, tables = _pair(
        wind_axis_longitudinal_model, _airplane(propeller_torque_input=None), AeroModel(terms),
        reference_speed=50.0,
        outputs=("V", "alpha", "theta", "q", "ax", "az", "qdot"),
        accelerometer={"unit": "m/s^2"},
    )  # fmt: skip
    _compare(generated, tables, exact=not rates)


def test_alpha_q_model_agrees_bit_for_bit():
    aero = AeroModel(
        {
            "CZ": ["1", "alpha", "qhat", "de", "alpha^2", "spline1(alpha,0.08)", "V*de"],
            "Cm": ["1", "alpha", "qhat", "de", "abs(alpha)*de", "alpha^3", "ax"],
        }
    )
    airplane = _airplane(thrust_input=None, propeller_torque_input=None)
    generated, tables = _pair(
        alpha_q_longitudinal_model, airplane, aero, outputs=("alpha", "q", "az"),
        accelerometer={"az": "up"},
    )  # fmt: skip
    _compare(generated, tables, exact=True)


def test_generated_code_is_straight_line():
    """The generated source has no loop and no table: the benchmark's f computes the loads
    from scalars; its h (no load outputs) computes no coefficient at all."""
    aero = AeroModel(PLAIN_TERMS)
    model = six_dof_model(
        _airplane(), aero, outputs=("V", "alpha", "beta", "p", "q", "r"), reference_speed=50.0
    )
    source = inspect.getsource(inspect.getmodule(model.f_out))
    assert "for " not in source and "while " not in source
    assert "theta[" not in inspect.getsource(model.h_out)
    assert "theta[" in inspect.getsource(model.f_out)


def test_an_uncovered_model_keeps_the_table_path(monkeypatch):
    """A term with both α̇̂ and β̇̂ (not affine in the rates), or more terms than
    ``codegen.MAX_TERMS``, keeps the table path — and says so."""
    terms = {**FULL_TERMS, "Cm": [*FULL_TERMS["Cm"], "alphadot_hat*betadot_hat"]}
    model = six_dof_model(_airplane(), AeroModel(terms))
    assert model.f.model_code == model.h.model_code == "tables"
    monkeypatch.setattr(codegen, "MAX_TERMS", 3)
    model = six_dof_model(_airplane(), AeroModel(PLAIN_TERMS), reference_speed=50.0)
    assert model.f.model_code == "tables"
    monkeypatch.setattr(codegen, "MAX_TERMS", 400)
    model = six_dof_model(_airplane(), AeroModel(PLAIN_TERMS), reference_speed=50.0)
    assert model.f.model_code == "generated"


def test_code_argument_is_checked():
    with pytest.raises(InputError, match="code"):
        six_dof_model(_airplane(), AeroModel(PLAIN_TERMS), reference_speed=50.0, code="fast")


def test_generated_file_is_reused_and_a_changed_table_gives_another(tmp_path):
    aero = AeroModel(FULL_TERMS)
    model = six_dof_model(_airplane(), aero)
    path = inspect.getfile(model.f_out)
    assert path.startswith(str(tmp_path / "numba" / "flightid_generated"))
    name = model.f_out.__module__
    with open(path, encoding="utf-8") as stream:
        source = stream.read()
    assert name == module_name(source)
    stamp = os.stat(path).st_mtime_ns
    # another process (its module not imported yet) finds the same file and keeps it
    del sys.modules[name]
    again = six_dof_model(_airplane(), aero)
    assert inspect.getfile(again.f_out) == path and os.stat(path).st_mtime_ns == stamp
    assert kernel_digest(again.f_out) == kernel_digest(model.f_out)
    # one more term, or another mass: another file, another digest
    more = AeroModel({**FULL_TERMS, "Cm": [*FULL_TERMS["Cm"], "beta^2"]})
    for other in (six_dof_model(_airplane(), more), six_dof_model(_airplane(mass=1301.0), aero)):
        assert inspect.getfile(other.f_out) != path
        assert kernel_digest(other.f_out) != kernel_digest(model.f_out)


def test_without_a_disk_cache_the_module_is_made_by_exec(monkeypatch):
    monkeypatch.setenv("FLIGHTID_KERNEL_CACHE", "0")
    aero = AeroModel({"CD": ["1", "alpha^2"], "CL": ["1", "alpha"], "Cm": ["1", "qhat"]})
    generated, tables = _pair(longitudinal_model, _airplane(), aero)
    assert getattr(sys.modules[generated.f_out.__module__], "__file__", None) is None
    _compare(generated, tables, exact=True, n=3)


_CHILD = r"""
import json, sys
from numba.core import event
compiles = []

class Compiles(event.Listener):
    def on_start(self, ev):
        compiles.append(1)

    def on_end(self, ev):
        pass

event.register("numba:compile", Compiles())
import numpy as np
from flightid.aircraft import AeroModel, Airplane, six_dof_model
from flightid.model.kernel_cache import compiled_function
airplane = Airplane(mass=1300.0, Ix=1500.0, Iy=3000.0, Iz=4000.0, Ixz=150.0, S=17.0, b=10.5,
                    cbar=1.7, density=1.1, thrust_input="T")
model = six_dof_model(airplane, AeroModel({"CD": ["1", "alpha^2"], "CL": ["1", "alpha"],
                      "CY": ["beta"], "Cl": ["phat"], "Cm": ["1", "qhat"], "Cn": ["rhat"]}))
f = compiled_function(model.f_out)
out = np.empty(9)
f(0.0, np.array([50.0, 1, 2, 0.1, 0.1, 0.1, -0.1, 0.0, 0.99]), np.array([1000.0]),
  np.full(len(model.parameters), 0.1), out)
print(json.dumps({"compiles": len(compiles), "out": out.tolist()}))
"""


def test_a_second_process_compiles_nothing(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "shared")}
    runs = []
    for _ in range(2):
        done = subprocess.run(
            [sys.executable, "-c", textwrap.dedent(_CHILD)], env=env, capture_output=True,
            text=True, check=True,
        )  # fmt: skip
        runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
    assert runs[0]["compiles"] > 0
    assert runs[1]["compiles"] == 0
    assert runs[1]["out"] == runs[0]["out"]


def test_prune_removes_only_generated_files_unused_for_the_period(tmp_path):
    # three generated sources: one neither read nor written for 40 days (removed, with its
    # numba cache entries), one written 40 days ago but read yesterday (kept: atime is the
    # sign of use — files are never touched, numba records their time stamps), one new
    import os
    import time

    from flightid.aircraft.generated import prune

    now = time.time()
    day = 86400.0
    old, used, new = (tmp_path / f"flightid_generated_{k}.py" for k in ("aa", "bb", "cc"))
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    for path in (old, used, new):
        path.write_text("x = 1\n")
        (cache / f"{path.stem}.f_out-26.py311.1.nbc").write_bytes(b"")
        (cache / f"{path.stem}.f_out-26.py311.nbi").write_bytes(b"")
    other = tmp_path / "notes.py"  # not a generated file: never touched
    other.write_text("")
    os.utime(old, (now - 40 * day, now - 40 * day))
    os.utime(used, (now - 1 * day, now - 40 * day))
    os.utime(other, (now - 400 * day, now - 400 * day))
    assert prune(tmp_path, days=30) == 1
    assert not old.exists() and used.exists() and new.exists() and other.exists()
    assert sorted(p.name.split(".")[0] for p in cache.iterdir()) == [
        "flightid_generated_bb",
        "flightid_generated_bb",
        "flightid_generated_cc",
        "flightid_generated_cc",
    ]
    # keep= is never removed, however old
    os.utime(used, (now - 50 * day, now - 50 * day))
    assert prune(tmp_path, days=30, keep=used) == 0 and used.exists()
