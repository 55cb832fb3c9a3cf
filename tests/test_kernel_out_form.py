"""Out-form model functions, allocation-free kernels and the parallel batch (issue 14).

The references: the return-form path of the same equations (the kernels' former calling
convention, still supported), the serial kernel for the parallel one, the one-block
sensitivity kernel for the split one, and closed-form solutions of a linear system.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from flightid.data import FlightData
from flightid.errors import InputError
from flightid.model import StateSpaceModel
from flightid.model.forms import as_out_form, kernel_function
from flightid.simulation import Simulator
from flightid.simulation.kernels import VariantTimer, make_kernel
from flightid.simulation.sensitivity import make_sensitivity_kernel


def _oscillator_return(t, x, u, theta):
    dx = np.empty(2)
    dx[0] = x[1]
    # ẍ = −k x − c ẋ − d ẋ|ẋ| + b u
    dx[1] = -theta[0] * x[0] - theta[1] * x[1] - theta[2] * x[1] * abs(x[1]) + theta[3] * u[0]
    return dx


def _oscillator_out(t, x, u, theta, out):
    out[0] = x[1]
    out[1] = -theta[0] * x[0] - theta[1] * x[1] - theta[2] * x[1] * abs(x[1]) + theta[3] * u[0]


def _outputs_return(t, x, u, theta):
    y = np.empty(3)
    y[0] = x[0]
    y[1] = x[1]
    y[2] = np.sin(x[0]) + theta[3] * u[0]
    return y


def _outputs_out(t, x, u, theta, out):
    out[0] = x[0]
    out[1] = x[1]
    out[2] = np.sin(x[0]) + theta[3] * u[0]


PARAMETERS = {"k": 6.0, "c": 0.4, "d": 0.3, "b": 2.0, "x0": 0.2}


def _model(f, h, **kwargs):
    return StateSpaceModel(
        ("x", "v"), ("u",), ("x", "v", "s"), f, h, dict(PARAMETERS), x0=["x0", 0.0], **kwargs
    )


def _data(n: int = 401, dt: float = 0.01) -> FlightData:
    t = np.arange(n) * dt
    u = np.where((t > 0.5) & (t < 1.0), 1.0, 0.0) - np.where((t > 1.0) & (t < 1.5), 1.0, 0.0)
    return FlightData(t, {"u": u + 0.1 * np.sin(3 * t)})


def _thetas(model, n_batch: int) -> np.ndarray:
    rng = np.random.default_rng(5)
    base = model.parameters.values
    return base[None, :] * (1.0 + 0.2 * rng.uniform(-1.0, 1.0, (n_batch, base.size)))


# ----------------------------------------------------------------------------- the forms


def test_the_form_is_recognised_by_the_number_of_parameters():
    model = _model(_oscillator_out, _outputs_return)
    x, u, theta = np.array([0.3, -0.2]), np.array([0.5]), _model_theta()
    # f was written in out form: model.f is its return form, model.f_out the function itself
    assert model.f_out is _oscillator_out
    np.testing.assert_array_equal(model.f(0.0, x, u, theta), _oscillator_return(0.0, x, u, theta))
    # h was written in return form: model.h_out copies its values into out
    out = np.full(3, np.nan)
    model.h_out(0.0, x, u, theta, out)
    np.testing.assert_array_equal(out, _outputs_return(0.0, x, u, theta))


def _model_theta():
    return np.array(list(PARAMETERS.values()))


def test_a_copy_of_the_model_keeps_the_out_form():
    model = _model(_oscillator_out, _outputs_out)
    copy = model.with_parameters(model.parameters.with_values({"k": 7.0}))
    assert copy.f_out is _oscillator_out and copy.h_out is _outputs_out


def test_a_replaced_function_gets_its_own_out_form():
    """replace(model, f=...) must not keep the out form of the old f (it would simulate the
    old model)."""
    from dataclasses import replace

    model = _model(_oscillator_out, _outputs_out)

    def slower(t, x, u, theta):
        return 0.5 * _oscillator_return(t, x, u, theta)

    changed = replace(model, f=slower)
    out = np.empty(2)
    x, u, theta = np.array([0.3, -0.2]), np.array([0.5]), _model_theta()
    changed.f_out(0.0, x, u, theta, out)
    np.testing.assert_array_equal(out, slower(0.0, x, u, theta))


@pytest.mark.parametrize(
    ("f", "form", "message"),
    [
        (lambda t, x, u: x, "auto", "3 positional parameters"),
        (_oscillator_return, "out", r"function_form='out' needs f\(t, x, u, theta, out\)"),
        (_oscillator_out, "return", r"function_form='return' needs f\(t, x, u, theta\)"),
        (_oscillator_out, "inplace", "function_form: expected one of"),
    ],
)
def test_a_wrong_form_is_a_named_input_error(f, form, message):
    with pytest.raises(InputError, match=message):
        _model(f, _outputs_return, function_form=form)


def test_an_explicit_out_form_is_accepted():
    model = _model(_oscillator_out, _outputs_out, function_form="out")
    assert model.f_out is _oscillator_out


# ----------------------------------------------------------------------------- kernels


@pytest.mark.parametrize("method", ["rk4", "euler"])
@pytest.mark.parametrize("interpolation", ["linear", "zoh"])
@pytest.mark.parametrize("compiled", [True, False])
def test_out_form_and_return_form_give_identical_outputs(method, interpolation, compiled):
    data = _data(201)
    ret = _model(_oscillator_return, _outputs_return)
    out = _model(_oscillator_out, _outputs_out)
    thetas = _thetas(ret, 3)
    kwargs = {"method": method, "input_interpolation": interpolation, "compiled": compiled}
    y_ret = Simulator(ret, data, **kwargs).run(thetas).outputs
    y_out = Simulator(out, data, **kwargs).run(thetas).outputs
    # the same arithmetic in the same order: bit-identical
    np.testing.assert_array_equal(y_ret, y_out)


def test_compiled_and_python_kernels_agree():
    data = _data(201)
    model = _model(_oscillator_out, _outputs_out)
    thetas = _thetas(model, 2)
    compiled = Simulator(model, data).run(thetas).outputs
    python = Simulator(model, data, compiled=False).run(thetas).outputs
    np.testing.assert_allclose(compiled, python, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("stabilized", [False, True])
def test_parallel_batch_is_bit_identical_to_serial(stabilized):
    import numba

    data = _data(301)
    model = _model(_oscillator_out, _outputs_return)
    thetas = _thetas(model, 21)
    # a trajectory that diverges must stop where it does serially too
    thetas[4, 0] = -1.0e6
    if stabilized:
        from flightid.model.unstable import with_stabilizing_gain

        clean = Simulator(model, data).outputs(model.parameters.values)
        data = FlightData(
            data.time, {"u": data.channel("u")}, dict(zip(model.outputs, clean.T, strict=True))
        )
        model = with_stabilizing_gain(model, 0.01 * np.ones((2, 3)))
    simulator = Simulator(model, data)
    kernel = simulator._feedback_kernel if stabilized else simulator._kernel
    kernel.min_parallel_samples = 0  # a small batch, run in parallel all the same
    kernel.timer = VariantTimer()  # no timings yet: the parallel variant runs first
    parallel = simulator.run(thetas)
    kernel.parallel_ok = False
    serial = simulator.run(thetas)
    kernel.parallel_ok = True
    np.testing.assert_array_equal(parallel.outputs, serial.outputs)
    np.testing.assert_array_equal(parallel.diverged, serial.diverged)
    assert parallel.diverged[4] and not parallel.diverged[5]
    if numba.get_num_threads() > 1:
        assert kernel.parallel_runs >= 1


def _reference_kernel_run(kernel, model, data, thetas):
    """Outputs of ``kernel`` (the raw batch kernel interface) for ``thetas``."""
    t = np.ascontiguousarray(data.time)
    u = np.ascontiguousarray(np.column_stack([data.channel(n) for n in model.inputs]))
    x0s = np.array([model.initial_state(th) for th in thetas])
    y = np.empty((thetas.shape[0], t.size, len(model.outputs)))
    flag = np.empty(thetas.shape[0], dtype=np.int64)
    kernel(thetas, x0s, t, u, 1, 0, len(model.outputs), y, flag)
    return y, flag


def test_the_parallel_kernel_itself_matches_the_serial_one():
    """The parallel variant, called directly (whatever the number of numba threads)."""
    model = _model(_oscillator_out, _outputs_out)
    data = _data(201)
    kernel, compiled = make_kernel(model.f_out, model.h_out)
    assert compiled
    thetas = _thetas(model, 7)
    y_serial, f_serial = _reference_kernel_run(kernel.serial, model, data, thetas)
    y_parallel, f_parallel = _reference_kernel_run(kernel.parallel, model, data, thetas)
    np.testing.assert_array_equal(y_serial, y_parallel)
    np.testing.assert_array_equal(f_serial, f_parallel)


@pytest.mark.parametrize("method", ["rk4", "euler"])
def test_closed_form_of_a_linear_system(method):
    """ẋ = −a x + b u with u = 1: x(t) = b/a + (x0 − b/a) e^(−a t); Euler's recursion
    x_{k+1} = (1 − aΔt) x_k + bΔt has the closed form b/a + (x0 − b/a)(1 − aΔt)^k."""

    def f(t, x, u, theta, out):
        out[0] = -theta[0] * x[0] + theta[1] * u[0]

    def h(t, x, u, theta, out):
        out[0] = x[0]

    a, b, x0, dt = 2.0, 3.0, 0.5, 0.01
    model = StateSpaceModel(("x",), ("u",), ("x",), f, h, {"a": a, "b": b}, x0=[x0])
    t = np.arange(301) * dt
    y = Simulator(model, FlightData(t, {"u": np.ones_like(t)}), method=method).outputs(
        model.parameters.values
    )[:, 0]
    k = np.arange(t.size)
    if method == "euler":
        expected = b / a + (x0 - b / a) * (1.0 - a * dt) ** k
        np.testing.assert_allclose(y, expected, rtol=1e-12)
    else:
        # RK4's one-step factor is the 4th-order Taylor polynomial of e^(−aΔt): global
        # error ≈ (aΔt)^5/120 per step relative, far below 1e-9 here
        expected = b / a + (x0 - b / a) * np.exp(-a * t)
        np.testing.assert_allclose(y, expected, rtol=1e-9)


def test_a_stateless_model_in_out_form():
    def h(t, x, u, theta, out):
        out[0] = theta[0] * u[0] ** 2

    model = StateSpaceModel((), ("u",), ("y",), None, h, {"c": 1.5})
    t = np.arange(11) * 0.1
    y = Simulator(model, FlightData(t, {"u": t})).run(np.array([[1.5], [2.0]])).outputs
    np.testing.assert_array_equal(y[:, :, 0], np.array([1.5, 2.0])[:, None] * t[None, :] ** 2)


# ----------------------------------------------------------------------------- sensitivities


@pytest.mark.parametrize("compiled", [True, False])
def test_sensitivities_of_out_form_and_return_form_are_identical(compiled):
    data = _data(201)
    free = np.array([0, 1, 3, 4])
    steps = 1e-6 * np.ones(free.size)
    results = []
    for f, h in ((_oscillator_return, _outputs_return), (_oscillator_out, _outputs_out)):
        model = _model(f, h)
        simulator = Simulator(model, data, compiled=compiled)
        results.append(simulator.run_with_sensitivities(model.parameters.values, free, steps))
    np.testing.assert_array_equal(results[0][0], results[1][0])
    np.testing.assert_array_equal(results[0][1], results[1][1])


@pytest.mark.parametrize("stabilized", [False, True])
def test_sensitivity_blocks_are_bit_identical_to_one_block(stabilized):
    """The columns of S split into blocks (integrated side by side) give the very numbers of
    the one-block integration, whatever the split."""
    model = _model(_oscillator_out, _outputs_out)
    data = _data(201)
    kernel = make_sensitivity_kernel(model.f_out, model.h_out)
    theta = model.parameters.values
    t = np.ascontiguousarray(data.time)
    u = np.ascontiguousarray(np.column_stack([data.channel(n) for n in model.inputs]))
    free = np.array([0, 1, 2, 3, 4])
    s0 = np.zeros((2, free.size))
    s0[0, 4] = 1.0  # x0 is the parameter "x0"
    steps = 1e-6 * np.maximum(np.abs(theta[free]), 1.0)
    z = np.ascontiguousarray(np.tile([[0.1, 0.0, 0.1]], (t.size, 1)))
    gain = 0.05 * np.ones((2, 3)) if stabilized else np.zeros((0, 0))
    results = []
    for n_blocks, variant in ((1, kernel.serial), (2, kernel.parallel), (3, kernel.parallel)):
        y = np.empty((t.size, 3))
        g = np.empty((t.size, 3, free.size))
        flag = variant(
            theta, model.initial_state(theta), s0, free, steps, 1e-7, t, u, 1, 0, 3, y, g, z,
            gain, n_blocks,
        )  # fmt: skip
        assert flag == -1
        results.append((y, g))
    for y, g in results[1:]:
        np.testing.assert_array_equal(y, results[0][0])
        np.testing.assert_array_equal(g, results[0][1])


def test_sensitivity_of_the_linear_system_is_the_closed_form():
    """ẋ = −a x + b, x(0) = x0: ∂x/∂b = (1 − e^(−a t))/a, ∂x/∂x0 = e^(−a t)."""

    def f(t, x, u, theta, out):
        out[0] = -theta[0] * x[0] + theta[1]

    def h(t, x, u, theta, out):
        out[0] = x[0]

    a, b, x0 = 1.5, 2.0, 0.5
    model = StateSpaceModel(("x",), (), ("x",), f, h, {"a": a, "b": b, "x0": x0}, x0=["x0"])
    t = np.arange(201) * 0.01
    simulator = Simulator(model, FlightData(t))
    free = np.array([1, 2])
    _, g = simulator.run_with_sensitivities(model.parameters.values, free, np.full(2, 1e-7))
    # f is linear: the forward-difference Jacobians are exact to rounding (about 1e-16/1e-7
    # relative), RK4 adds its O(Δt⁴) error
    np.testing.assert_allclose(g[:, 0, 0], (1.0 - np.exp(-a * t)) / a, rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(g[:, 0, 1], np.exp(-a * t), rtol=1e-7)


# ----------------------------------------------------------------------------- allocation


_ALLOCATION_SCRIPT = textwrap.dedent(
    """
    import numpy as np
    from numba.core.runtime import rtsys
    from flightid.data import FlightData
    from flightid.model import StateSpaceModel
    from flightid.simulation import Simulator

    def f(t, x, u, th, out):
        out[0] = x[1]
        out[1] = -th[0] * x[0] - th[1] * x[1] + u[0]

    def h(t, x, u, th, out):
        out[0] = x[0]
        out[1] = x[1]

    def f_ret(t, x, u, th):
        return np.array([x[1], -th[0] * x[0] - th[1] * x[1] + u[0]])

    for label, fn in (("out", f), ("return", f_ret)):
        model = StateSpaceModel(("a", "b"), ("u",), ("a", "b"), fn, h, {"k": 4.0, "c": 0.5},
                                x0=[1.0, 0.0])
        counts = []
        for n in (100, 1000):
            t = np.arange(n) * 0.01
            simulator = Simulator(model, FlightData(t, {"u": np.sin(t)}))
            thetas = np.tile(model.parameters.values, (3, 1))
            simulator.run(thetas)
            before = rtsys.get_allocation_stats().alloc
            simulator.run(thetas)
            counts.append(rtsys.get_allocation_stats().alloc - before)
            before = rtsys.get_allocation_stats().alloc
            simulator.run_with_sensitivities(
                model.parameters.values, np.array([0, 1]), np.full(2, 1e-6)
            )
            counts.append(rtsys.get_allocation_stats().alloc - before)
        print(label, *counts)
    """
)


def test_out_form_kernels_allocate_nothing_per_step():
    """numba's allocation counter (NUMBA_NRT_STATS): with out-form f and h, a batch and a
    sensitivity pass allocate as often for 1000 samples as for 100 (buffers per trajectory,
    none per step); the return form allocates per stage, so its count grows."""
    env = {**os.environ, "NUMBA_NRT_STATS": "1", "FLIGHTID_KERNEL_CACHE": "0"}
    result = subprocess.run(
        [sys.executable, "-c", _ALLOCATION_SCRIPT],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr
    lines = dict(line.split(" ", 1) for line in result.stdout.strip().splitlines())
    batch_100, sens_100, batch_1000, sens_1000 = map(int, lines["out"].split())
    assert batch_100 == batch_1000 and sens_100 == sens_1000
    ret_batch_100, _, ret_batch_1000, _ = map(int, lines["return"].split())
    # RK4 calls the return-form f 4 times per step: about 4 × 900 × 3 more allocations
    assert ret_batch_1000 - ret_batch_100 >= 4 * 900 * 3


# ----------------------------------------------------------------------------- built-in models


def test_builtin_airplane_model_out_form_matches_its_return_form():
    """The six-DOF model with α̇ and β̇ terms (the implicit solution's work arrays): out form
    and return form, Python and compiled, give the same numbers."""
    from flightid.aircraft import AeroModel, navion, six_dof_model

    aero = AeroModel(
        {
            "CD": ["1", "alpha"],
            "CL": ["1", "alpha", "alphadot_hat", "qhat"],
            "Cm": ["1", "alpha", "qhat", "alphadot_hat", "de"],
            "CY": ["beta", "betadot_hat"],
            "Cl": ["beta", "phat", "da"],
            "Cn": ["beta", "rhat", "betadot_hat", "dr"],
        }
    )
    rng = np.random.default_rng(3)
    names = aero.parameter_names
    values = dict(zip(names, 0.1 * rng.normal(size=len(names)), strict=True))
    model = six_dof_model(navion(), aero, aero.parameters(values))
    theta = model.parameters.values
    x = np.array([50.0, 1.0, 3.0, 0.1, -0.05, 0.02, -0.06, 0.01, 0.998])
    u = 0.02 * rng.normal(size=len(model.inputs))
    for fn, fn_out, size in ((model.f, model.f_out, 9), (model.h, model.h_out, 11)):
        expected = fn(0.0, x, u, theta)
        for variant in (kernel_function(fn_out, False), kernel_function(fn_out, True)):
            out = np.full(size, np.nan)
            variant(0.0, x, u, theta, out)
            np.testing.assert_allclose(out, expected, rtol=1e-14, atol=1e-14)
        # the adapter of the return form (the slow path) gives the same numbers
        out = np.full(size, np.nan)
        as_out_form(fn)(0.0, x, u, theta, out)
        np.testing.assert_array_equal(out, expected)


def test_a_parallel_variant_numba_cannot_compile_falls_back_to_serial_with_a_warning():
    """Both the batch and the sensitivity kernel run their serial variant, say so, and stop
    trying the parallel one, when numba rejects the parallel variant; other errors propagate."""
    from numba.core.errors import TypingError

    from flightid.simulation.kernels import run_parallel_variant

    def numba_rejects(*arguments):
        raise TypingError("parallel variant rejected (test)")

    def python_error(*arguments):
        raise ValueError("not numba's")

    with pytest.warns(RuntimeWarning, match="the parallel batch kernel did not compile"):
        assert run_parallel_variant(numba_rejects, (), "batch kernel", "serially") == (
            False,
            None,
        )
    with pytest.raises(ValueError, match="not numba's"):
        run_parallel_variant(python_error, (), "batch kernel", "serially")
    assert run_parallel_variant(lambda a, b: a + b, (1, 2), "batch kernel", "serially") == (
        True,
        3,
    )

    data = _data(301)
    model = _model(_oscillator_out, _outputs_return)
    thetas = _thetas(model, 21)
    simulator = Simulator(model, data)
    serial = simulator.run(thetas).outputs
    kernel = simulator._kernel
    kernel.min_parallel_samples = 0
    kernel.timer = VariantTimer()  # no timings yet: the parallel variant runs first
    kernel.parallel, kept = numba_rejects, kernel.parallel
    try:
        with pytest.warns(RuntimeWarning, match="running batches serially"):
            fallback = simulator.run(thetas).outputs
        assert kernel.parallel_ok is False
        np.testing.assert_array_equal(fallback, serial)
    finally:
        kernel.parallel, kernel.parallel_ok = kept, True
