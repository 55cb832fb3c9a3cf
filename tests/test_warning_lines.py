"""Every warning the user sees is one ``flightid: warning: ...`` line (flightid.cli.main),
the numba fall-back to the serial kernel included (flightid.simulation.kernels)."""

import io
import warnings

import pytest

from flightid.cli.main import _one_line_warnings, warning_line
from flightid.errors import CompileWarning, FlightIdWarning
from flightid.simulation.kernels import run_parallel_variant


class _NumbaLikeError(Exception):
    """Stands for a numba compilation error (its module starts with "numba")."""


_NumbaLikeError.__module__ = "numba.core.errors"


def _parallel_that_fails(*arguments):
    raise _NumbaLikeError("Cannot determine Numba type of <class 'object'>\n\nsecond line")


def test_the_parallel_fallback_warns_as_flightid():
    with pytest.warns(CompileWarning) as caught:
        ok, result = run_parallel_variant(_parallel_that_fails, (), "batch kernel", "serially")
    assert (ok, result) == (False, None)
    (record,) = caught
    assert issubclass(record.category, FlightIdWarning)
    assert issubclass(record.category, RuntimeWarning)  # still caught as before
    assert str(record.message) == (
        "the parallel batch kernel did not compile (_NumbaLikeError); serially"
    )


def test_other_errors_of_the_parallel_variant_propagate():
    def broken(*arguments):
        raise ValueError("not numba's")

    with pytest.raises(ValueError, match="not numba's"):
        run_parallel_variant(broken, (), "batch kernel", "serially")


def test_every_warning_is_one_line_without_a_path():
    stream = io.StringIO()
    show = _one_line_warnings()
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        show(
            CompileWarning("the parallel batch kernel did not compile (X); running serially"),
            CompileWarning,
            "/usr/lib/python3/site-packages/flightid/simulation/kernels.py",
            330,
            stream,
        )
        show(
            RuntimeWarning("invalid value\n  encountered in divide"),
            RuntimeWarning,
            "/usr/lib/python3/site-packages/numpy/core/_methods.py",
            12,
            stream,
        )
    assert stream.getvalue().splitlines() == [
        "flightid: warning: the parallel batch kernel did not compile (X); running serially",
        "flightid: warning: invalid value encountered in divide (RuntimeWarning)",
    ]
    assert "site-packages" not in stream.getvalue()
    assert warning_line("a  b", UserWarning) == "flightid: warning: a b (UserWarning)"
