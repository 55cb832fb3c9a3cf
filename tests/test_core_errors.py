"""Bad input gets a clear error naming the argument."""

from __future__ import annotations

import numpy as np
import pytest

from flightid.data import FlightData
from flightid.errors import EstimationError, InputError, InputTypeError
from flightid.estimation import MNRES, Convergence, estimate
from flightid.model import Parameter, Parameters, StateSpaceModel
from flightid.paper.examples12 import example1_data, example_model

T = np.arange(0.0, 1.0, 0.1)


@pytest.mark.parametrize(
    "kwargs, pattern",
    [
        ({"time": T, "outputs": {"y": np.ones(5)}}, r"outputs\['y'\]: expected 10 samples"),
        (
            {"time": T, "outputs": {"y": np.where(T > 0.5, np.nan, 1.0)}},
            r"outputs\['y'\]: values must be finite",
        ),
        ({"time": T[::-1], "outputs": {"y": np.ones(10)}}, "time: must be strictly increasing"),
        (
            {"time": np.r_[T[:5], T[5:] + 0.05], "outputs": {"y": np.ones(10)}},
            "time: sampling must be uniform",
        ),
        ({"time": T, "inputs": {"y": T}, "outputs": {"y": T}}, "cannot be both"),
        ({"time": T, "outputs": {"bad name": T}}, "identifiers"),
    ],
)
def test_flight_data_validation(kwargs, pattern):
    with pytest.raises(InputError, match=pattern):
        FlightData(**kwargs)


def test_flight_data_does_not_keep_a_reference_to_user_arrays():
    y = np.ones(10)
    data = FlightData(T, outputs={"y": y})
    y[0] = 5.0
    assert data.output("y")[0] == 1.0
    with pytest.raises(ValueError):
        data.outputs[0, 0] = 2.0


def test_parameter_errors():
    with pytest.raises(InputError, match="unique"):
        Parameters([Parameter("a", 1.0), Parameter("a", 2.0)])
    with pytest.raises(InputError, match="identifier"):
        Parameter("C l", 1.0)
    with pytest.raises(InputError, match="finite"):
        Parameter("a", float("nan"))
    with pytest.raises(InputError, match="outside its bounds"):
        Parameter("a", 2.0, upper=1.0)


def test_model_errors():
    f = h = lambda t, x, u, theta: x  # noqa: E731
    with pytest.raises(InputError, match=r"x0: expected 2 entries"):
        StateSpaceModel(("a", "b"), (), ("a",), f, h, Parameters({"k": 1.0}), x0=(0.0,))
    with pytest.raises(InputError, match="not a parameter name"):
        StateSpaceModel(("a",), (), ("a",), f, h, Parameters({"k": 1.0}), x0=("q",))
    with pytest.raises(InputTypeError, match="f: expected a function"):
        StateSpaceModel(("a",), (), ("a",), 3, h, Parameters({"k": 1.0}))


def test_estimate_argument_errors():
    model, data = example_model(), example1_data()
    with pytest.raises(InputError, match="noise: expected one of"):
        estimate(model, data, noise="sometimes")
    with pytest.raises(InputTypeError, match="solver: expected"):
        estimate(model, data, solver="mnres")
    with pytest.raises(InputError, match="R: expected 2 positive"):
        estimate(model, data, noise="fixed", R=[1.0, -1.0])
    with pytest.raises(InputError, match="Convergence.cost_rtol"):
        Convergence(cost_rtol=-1)
    with pytest.raises(InputError, match="MNRES.form"):
        MNRES(form="quadratic")
    with pytest.raises(InputError, match="MNRES.window: expected at least"):
        estimate(model, data, MNRES(form="recursive", window=3), method="euler")
    missing = FlightData(data.time, {"u": data.input("u")}, {"x1": data.output("x1")})
    with pytest.raises(InputError, match=r"outputs \['x2'\] are not output channels"):
        estimate(model, missing)
    no_input = FlightData(data.time, None, {"x1": data.output("x1"), "x2": data.output("x2")})
    with pytest.raises(InputError, match=r"inputs \['u'\] are not channels"):
        estimate(model, no_input)


def test_start_values_that_diverge_are_an_estimation_error():
    def f(t, x, u, theta):
        return theta[0] * x * x

    def h(t, x, u, theta):
        return x.copy()

    model = StateSpaceModel(("x",), (), ("x",), f, h, Parameters({"a": 80.0}), x0=(1.0,))
    t = np.arange(0.0, 2.0, 0.05)
    data = FlightData(t, outputs={"x": np.ones_like(t)})
    with pytest.raises(EstimationError, match="start values"):
        estimate(model, data)
