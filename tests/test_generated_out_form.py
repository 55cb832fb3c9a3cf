"""Out forms generated from the source of return-form model functions
(``flightid.model.outform_source``).

The references: the user's own return-form function (called in Python, and run through the
call-then-copy adapter ``copy_out_form`` in the compiled kernel), bit for bit; and the
documented contract of the fall-back (unusual code keeps the adapter).
"""

from __future__ import annotations

import math
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

from flightid.cases.usermodel import load_user_model
from flightid.data import FlightData
from flightid.errors import CompileWarning
from flightid.model import Parameters, StateSpaceModel
from flightid.model.forms import as_out_form, copy_out_form, kernel_function, with_out_form
from flightid.model.outform_source import GENERATED_MARK, generated_out_form
from flightid.simulation import Simulator

ROOT = Path(__file__).resolve().parents[1]
# every model module of the examples, and the benchmark's 6-DOF user module
MODULES = sorted(
    [
        *(ROOT / "examples" / "models").glob("*.py"),
        *(ROOT / "examples" / "logs").glob("*.py"),
        ROOT / "bench" / "navion_user_model.py",
    ]
)
MODULES = [p for p in MODULES if "STATES" in p.read_text()]


def _random_point(user, rng):
    x = rng.uniform(0.5, 1.5, len(user.states)) * rng.choice([-1.0, 1.0], len(user.states))
    if user.path.name == "navion_user_model.py":
        x = np.array([50.0, 1.0, 3.0, 0.1, 0.05, -0.1, -0.05, 0.02, 0.99])
    u = rng.uniform(-1.0, 1.0, len(user.inputs))
    start = np.array(list(user.parameters.values()), dtype=float)
    theta = np.where(start != 0.0, start, 0.3) * rng.uniform(0.8, 1.2, start.size)
    return rng.uniform(0.0, 10.0), x, u, theta


@pytest.mark.parametrize("path", MODULES, ids=lambda p: p.name)
def test_every_example_module_gets_a_generated_out_form_with_the_same_values(path):
    """The generated out form of each example's f and h writes exactly the values the
    user's function returns (Python, bit for bit, at random points)."""
    user = load_user_model(path)
    rng = np.random.default_rng(3)
    for name, fn, size in (("f", user.f, len(user.states)), ("h", user.h, len(user.outputs))):
        if fn is None:
            continue
        generated = generated_out_form(fn)
        assert generated is not None, f"{path.name}: {name} was not rewritten"
        assert getattr(generated, GENERATED_MARK) is fn
        for _ in range(5):
            t, x, u, theta = _random_point(user, rng)
            out = np.full(size, np.nan)
            generated(t, x, u, theta, out)
            expected = np.asarray(fn(t, x, u, theta), dtype=float)
            assert np.array_equal(out, expected), f"{path.name}: {name}"


def _user_model(path: Path, x0=None) -> StateSpaceModel:
    user = load_user_model(path)
    return StateSpaceModel(
        user.states, user.inputs, user.outputs, user.f, user.h, Parameters(user.parameters),
        x0=tuple(x0) if x0 is not None else (0.1,) * len(user.states),
    )  # fmt: skip


def _adapted(fn):
    """A copy of ``fn`` (the original is left alone) marked with the call-then-copy adapter:
    the path the kernels took for every return-form function before out forms were
    generated."""
    import types

    copy = types.FunctionType(fn.__code__, fn.__globals__, fn.__name__)
    return with_out_form(copy, copy_out_form(copy))


def _inputs(names, n=301, dt=0.02):
    t = np.arange(n) * dt
    channels = {
        name: 0.05 * np.sin((i + 1) * 1.3 * t) + 0.02 * (t > 1.0) for i, name in enumerate(names)
    }
    if "thrust" in channels:
        channels["thrust"] = 1500.0 + 100.0 * np.sin(t)
    return FlightData(t, channels)


# Nelson (1998) App. B, the Navion's derivatives (per rad) in the order of the module
NAVION_VALUES = {
    "CD_0": 0.05, "CD_alpha": 0.33, "CL_0": 0.41, "CL_alpha": 4.44, "CL_qhat": 3.8,
    "CL_de": 0.355, "Cm_0": 0.05, "Cm_alpha": -0.683, "Cm_qhat": -9.96, "Cm_de": -0.923,
    "CY_beta": -0.564, "CY_dr": 0.157, "Cl_beta": -0.074, "Cl_phat": -0.410, "Cl_rhat": 0.107,
    "Cl_da": -0.134, "Cl_dr": 0.107, "Cn_beta": 0.071, "Cn_phat": -0.0575, "Cn_rhat": -0.125,
    "Cn_da": -0.0035, "Cn_dr": -0.072,
}  # fmt: skip


@pytest.mark.parametrize(
    "name, x0",
    [
        ("examples/logs/roll_mode.py", None),
        ("examples/models/attas_lateral.py", None),
        ("bench/navion_user_model.py", (53.0, 0.0, 2.0, 0.0, 0.0, 0.0, -0.04, 0.0, 0.999)),
    ],
)
def test_compiled_kernel_with_the_generated_form_matches_the_adapter_bit_for_bit(name, x0):
    """A documented-style user module: the simulator runs its generated out forms (the
    model's f_out/h_out are them), and the outputs of a batch equal, to the last bit, those
    of the call-then-copy adapter and of the pure Python kernel."""
    model = _user_model(ROOT / name, x0)
    if name.startswith("bench"):
        model = model.with_parameters(Parameters(NAVION_VALUES))
    assert getattr(model.f_out, GENERATED_MARK, None) is model.f
    assert getattr(model.h_out, GENERATED_MARK, None) is model.h
    data = _inputs(model.inputs)
    rng = np.random.default_rng(0)
    base = model.parameters.values
    base = np.where(base != 0.0, base, 0.1)
    thetas = base[None, :] * (1.0 + 0.05 * rng.uniform(-1.0, 1.0, (3, base.size)))
    adapted = StateSpaceModel(
        model.states, model.inputs, model.outputs, _adapted(model.f), _adapted(model.h),
        model.parameters, x0=model.x0,
    )  # fmt: skip
    assert getattr(adapted.f_out, GENERATED_MARK, None) is None
    generated = Simulator(model, data)
    assert generated.compiled
    y_generated = generated.run(thetas).outputs
    y_adapter = Simulator(adapted, data).run(thetas).outputs
    y_python = Simulator(model, data, compiled=False).run(thetas).outputs
    assert np.all(np.isfinite(y_generated))
    assert np.array_equal(y_generated, y_adapter)
    np.testing.assert_allclose(y_generated, y_python, rtol=1e-12, atol=1e-14)


def test_the_python_kernel_runs_the_users_own_function_through_the_adapter():
    """compiled = false is unchanged: the interpreted kernel calls the user's f and copies."""
    model = _user_model(ROOT / "examples" / "logs" / "roll_mode.py")
    python_f = kernel_function(model.f_out, compiled=False)
    assert getattr(python_f, GENERATED_MARK, None) is None
    make, inner = python_f.adapts
    assert make is copy_out_form and inner is model.f


# ----------------------------------------------------------------------------- patterns


def _buffer_zeros(t, x, u, theta):
    dx = np.zeros(3)
    dx[0] = theta[0] * x[0]
    if u[0] > 0.0:
        dx[2] = u[0]
    return dx


def _branches(t, x, u, theta):
    a = theta[0] * x[0]
    if a > 0.0:
        return np.array([a, math.cos(x[1])])
    return np.array([-a, 2 * x[1]])


def _out_already_used(t, x, u, theta):
    out = theta[0] * x[0]
    return np.array([out, out + 1.0])


@pytest.mark.parametrize(
    "fn, size", [(_buffer_zeros, 3), (_branches, 2), (_out_already_used, 2)], ids=str
)
def test_supported_patterns_compute_the_users_values(fn, size):
    """np.zeros buffers (zeroed again on every call), several returns, a variable the user
    called ``out``: same values as the return form, in Python and compiled."""
    import numba

    generated = generated_out_form(fn)
    assert generated is not None
    jitted = numba.njit(generated)
    for x, u in (([1.0, 0.3], [0.5]), ([-1.0, 0.2], [-0.5]), ([2.0, 1.0], [0.0])):
        x, u, theta = np.array(x), np.array(u), np.array([0.7])
        expected = fn(0.0, x, u, theta)
        for call in (generated, jitted):
            out = np.full(size, 7.0)
            call(0.0, x, u, theta, out)
            assert np.array_equal(out, expected)


def test_an_out_array_of_another_size_is_a_value_error_not_a_write_past_its_end():
    import numba

    generated = generated_out_form(_branches)
    for call in (generated, numba.njit(generated)):
        with pytest.raises(ValueError, match="writes 2 values"):
            call(0.0, np.ones(2), np.ones(1), np.ones(1), np.empty(1))


SIZE = 2
NAMES = ("a", "b")


def _size_by_global(t, x, u, theta):
    y = np.empty(SIZE)
    y[0] = x[0]
    y[1] = x[1]
    return y


def _size_by_len(t, x, u, theta):
    y = np.empty(len(NAMES))
    y[0] = x[0]
    y[1] = x[1]
    return y


@pytest.mark.parametrize("fn", [_size_by_global, _size_by_len])
def test_buffer_sizes_from_module_constants_are_read(fn):
    generated = generated_out_form(fn)
    assert generated is not None
    out = np.empty(2)
    generated(0.0, np.array([1.0, 2.0]), np.zeros(1), np.zeros(1), out)
    assert out.tolist() == [1.0, 2.0]


# ----------------------------------------------------------------------------- fall-back


def _computed_return(t, x, u, theta):
    dx = np.empty(2)
    dx[0] = x[1]
    dx[1] = -x[0]
    return 2.0 * dx


def _rebound_buffer(t, x, u, theta):
    dx = np.empty(2)
    dx[0] = x[1]
    dx = dx + 1.0
    return dx


def _list_variable(t, x, u, theta):
    values = [x[1], -x[0]]
    return np.array(values)


def _starred(t, x, u, theta):
    return np.array([*x])


def _with_keyword(t, x, u, theta):
    return np.array([x[1], -x[0]], dtype=np.float64)


def _nested(t, x, u, theta):
    def twice(v):
        return 2.0 * v

    return np.array([twice(x[1]), -x[0]])


def _defaults(t, x, u, theta, scale=2.0):
    return np.array([scale * x[1], -x[0]])


def _unknown_size(t, x, u, theta):
    dx = np.empty(x.shape[0])
    dx[0] = x[1]
    dx[1] = -x[0]
    return dx


def _mixed_sizes(t, x, u, theta):
    if x[0] > 0.0:
        return np.array([x[1], -x[0]])
    return np.array([x[1], -x[0], 0.0])


def _no_final_return(t, x, u, theta):
    if x[0] > 0.0:
        return np.array([x[1], -x[0]])
    else:
        return np.array([x[1], x[0]])


def _closure():
    gain = 2.0

    def f(t, x, u, theta):
        return np.array([gain * x[1], -x[0]])

    return f


def _decorated(fn):
    return fn


@_decorated
def _with_decorator(t, x, u, theta):
    return np.array([x[1], -x[0]])


_FROM_EXEC: dict = {"np": np}
exec("def f(t, x, u, theta):\n    return np.array([x[1], -x[0]])\n", _FROM_EXEC)


@pytest.mark.parametrize(
    "fn",
    [
        _computed_return,
        _rebound_buffer,
        _list_variable,
        _starred,
        _with_keyword,
        _nested,
        _defaults,
        _unknown_size,
        _mixed_sizes,
        _no_final_return,
        _closure(),
        _with_decorator,
        _FROM_EXEC["f"],
        lambda t, x, u, theta: np.array([x[1], -x[0]]),
    ],
    ids=lambda fn: getattr(fn, "__name__", "fn"),
)
def test_unusual_code_keeps_the_call_then_copy_adapter(fn):
    """Functions of another shape are not rewritten: the adapter runs them as before."""
    assert generated_out_form(fn) is None
    adapter = as_out_form(fn)
    assert adapter.adapts == (copy_out_form, fn)


def test_a_model_of_unusual_code_simulates_as_before():
    """The fall-back path end to end: a function that is not rewritten runs in the kernel
    through the adapter, and gives the closed form of ẋ = −a x + u."""

    def f(t, x, u, theta):
        rate = np.empty(1)
        rate[0] = -theta[0] * x[0] + u[0]
        return rate * 1.0

    model = StateSpaceModel(("x",), ("u",), ("y",), f, _h_one, Parameters({"a": 2.0}), x0=(0.0,))
    assert getattr(model.f_out, "adapts", None) == (copy_out_form, f)
    assert getattr(model.h_out, GENERATED_MARK, None) is _h_one
    t = np.arange(0.0, 2.0, 0.01)
    y = Simulator(model, FlightData(t, {"u": np.ones_like(t)})).outputs(np.array([2.0]))
    np.testing.assert_allclose(y[:, 0], 0.5 * (1.0 - np.exp(-2.0 * t)), atol=1e-8)


def _h_one(t, x, u, theta):
    return np.array([x[0]])


def test_a_compile_failure_of_a_generated_form_names_the_users_file_and_line(tmp_path):
    """numba's message for the generated form points at the user's own line (the generated
    code keeps the file name and line numbers), and the model falls back to Python."""
    module = tmp_path / "uncompilable_model.py"
    module.write_text(
        textwrap.dedent(
            """\
            import numpy as np

            STATES = ("x",)
            INPUTS = ("u",)
            OUTPUTS = ("y",)
            PARAMETERS = {"a": 1.0}
            TABLE = {"gain": 2.0}


            def f(t, x, u, theta):
                return np.array([TABLE["gain"] * u[0] - theta[0] * x[0]])


            def h(t, x, u, theta):
                return np.array([x[0]])
            """
        )
    )
    model = _user_model(module)
    assert getattr(model.f_out, GENERATED_MARK, None) is model.f
    t = np.arange(0.0, 1.0, 0.1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        simulator = Simulator(model, FlightData(t, {"u": np.ones_like(t)}))
    assert not simulator.compiled
    messages = [str(w.message) for w in caught if issubclass(w.category, CompileWarning)]
    assert any("uncompilable_model.py line 11" in m for m in messages), messages
    y = simulator.outputs(np.array([1.0]))
    # ẋ = 2 − x, x(0) = 0.1:  x(t) = 2 − 1.9 e^(−t)
    assert y[-1, 0] == pytest.approx(2.0 - 1.9 * np.exp(-t[-1]), rel=1e-4)


def test_a_kernel_compiled_for_the_models_sizes_matches_the_general_one_and_checks_them():
    """The state kernel with the numbers of states and outputs fixed in its code gives the
    general kernel's outputs bit for bit, and refuses arrays of other sizes."""
    from flightid.simulation.kernels import RK4, make_kernel

    model = _user_model(ROOT / "examples" / "logs" / "roll_mode.py")
    data = _inputs(model.inputs, n=201)
    t = np.ascontiguousarray(data.time)
    u = np.ascontiguousarray(data.channel("da")[:, None])
    thetas = np.array([[-2.0, 15.0], [-3.0, 12.0]])
    x0s = np.array([[0.1, 0.0], [0.0, 0.2]])
    results = []
    for sizes in (None, (2, 2)):
        kernel, compiled = make_kernel(model.f_out, model.h_out, sizes=sizes)
        assert compiled
        y = np.empty((2, t.size, 2))
        flag = np.empty(2, dtype=np.int64)
        kernel(thetas, x0s, t, u, RK4, 0, 2, y, flag)
        assert flag.tolist() == [-1, -1]
        results.append(y)
    assert np.array_equal(results[0], results[1])
    with pytest.raises(ValueError, match="initial states"):
        kernel(thetas, np.zeros((2, 3)), t, u, RK4, 0, 2, np.empty((2, t.size, 2)), flag)
    with pytest.raises(ValueError, match="n_outputs"):
        kernel(thetas, x0s, t, u, RK4, 0, 3, np.empty((2, t.size, 3)), flag)


# ----------------------------------------------------------------------------- serial or parallel


def test_the_variant_timer_runs_the_faster_variant_and_probes_the_other():
    """Parallel first, then serial once; then the faster one, the other every 8th batch;
    a change of speed (load) moves the choice."""
    from flightid.simulation.kernels import VariantTimer

    timer = VariantTimer()
    assert timer.choose() is True
    timer.record(True, 4e-9)  # parallel: 4 ns per sample (a loaded machine)
    assert timer.choose() is False
    timer.record(False, 2e-9)
    choices = []
    for _ in range(16):
        choices.append(timer.choose())
    # calls 3 … 18: serial, except the probes at calls 8 and 16
    assert [i + 3 for i, c in enumerate(choices) if c] == [8, 16]
    for _ in range(10):  # the load is gone: parallel measures 1 ns per sample
        timer.record(True, 1e-9)
    assert timer.choose() is True


def test_a_batch_runs_serially_where_the_parallel_variant_measured_slower():
    """BatchKernel follows its timer (results identical either way)."""
    from flightid.simulation.kernels import VariantTimer

    model = _user_model(ROOT / "examples" / "logs" / "roll_mode.py")
    data = _inputs(model.inputs, n=201)
    simulator = Simulator(model, data)
    kernel = simulator._kernel
    kernel.min_parallel_samples = 0
    thetas = np.array([[-2.0, 15.0], [-3.0, 12.0], [-1.0, 9.0]])
    try:
        kernel.timer = VariantTimer()
        kernel.timer.record(True, 1.0)  # parallel: very slow
        kernel.timer.record(False, 1e-9)
        runs = kernel.parallel_runs
        serial = simulator.run(thetas).outputs
        assert kernel.parallel_runs == runs
        assert kernel.timer.seconds_per_sample[False] > 1e-9  # the serial batch was timed
        kernel.timer = VariantTimer()  # parallel first
        parallel = simulator.run(thetas).outputs
        import numba

        if numba.get_num_threads() > 1:
            assert kernel.parallel_runs == runs + 1
        assert np.array_equal(serial, parallel)
    finally:
        kernel.min_parallel_samples = 20_000
        kernel.timer = VariantTimer()


def _blow_up(t, x, u, theta):
    # ẋ = θ x²: x(t) = 1/(1 − t) for x(0) = 1, θ = 1 (infinite at t = 1)
    return np.array([theta[0] * x[0] * x[0]])


def _constant_output(t, x, u, theta):
    return np.array([1.0])


@pytest.mark.parametrize("compiled", [True, False])
def test_a_state_that_overflows_stops_the_trajectory_even_where_the_output_stays_finite(
    compiled,
):
    """The state kernel's finiteness test covers the state, not only the outputs: the
    trajectory stops at the first sample whose state is non-finite (an independent RK4
    loop gives that sample), its outputs are NaN from there on."""
    model = StateSpaceModel(
        ("x",), ("u",), ("y",), _blow_up, _constant_output, Parameters({"a": 1.0}), x0=(1.0,)
    )
    t = np.arange(0.0, 2.0, 0.01)
    # the reference: RK4 of ẋ = x² from 1, first non-finite state
    x, first = 1.0, None
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(t.size):
            if not np.isfinite(x):
                first = k
                break
            dt = 0.01
            k1 = np.float64(x) ** 2
            k2 = (x + 0.5 * dt * k1) ** 2
            k3 = (x + 0.5 * dt * k2) ** 2
            k4 = (x + dt * k3) ** 2
            x = x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    assert first is not None
    simulator = Simulator(model, FlightData(t, {"u": np.zeros_like(t)}), compiled=compiled)
    with np.errstate(over="ignore", invalid="ignore"):
        batch = simulator.run(np.array([[1.0]]))
    assert batch.diverged[0]
    assert f"(sample {first})" in batch.messages[0]
    y = batch.outputs[0, :, 0]
    assert np.all(y[:first] == 1.0) and np.all(np.isnan(y[first:]))


def _allocations_per_run(model, n_samples: int) -> int:
    """numba's allocation count of one ``Simulator.run`` of ``n_samples`` samples."""
    from numba.core.runtime import _nrt_python, rtsys

    t = np.arange(n_samples) * 0.01
    simulator = Simulator(model, FlightData(t, {"da": np.sin(t)}))
    theta = model.parameters.values[None, :]
    simulator.run(theta)
    was_enabled = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    try:
        before = rtsys.get_allocation_stats().alloc
        simulator.run(theta)
        return rtsys.get_allocation_stats().alloc - before
    finally:
        if not was_enabled:
            _nrt_python.memsys_disable_stats()


def test_the_kernel_of_a_documented_module_allocates_nothing_per_step():
    """numba's allocation counter: a documented-style module (f and h return np.empty
    buffers) allocates as often for 1000 samples as for 100 (buffers per trajectory only);
    through the call-then-copy adapter its arrays are allocated at every stage."""
    model = _user_model(ROOT / "examples" / "logs" / "roll_mode.py")
    assert _allocations_per_run(model, 100) == _allocations_per_run(model, 1000)
    adapted = StateSpaceModel(
        model.states, model.inputs, model.outputs, _adapted(model.f), _adapted(model.h),
        model.parameters, x0=model.x0,
    )  # fmt: skip
    # RK4: 4 calls of f and 1 of h per step, 900 more steps
    assert _allocations_per_run(adapted, 1000) - _allocations_per_run(adapted, 100) >= 5 * 900
