"""Exceptions raised by flightid.

Every error names the argument (or case-file key), what was expected and what came.
They subclass ValueError / TypeError so that generic handlers keep working.
"""

from __future__ import annotations


class FlightIdError(Exception):
    """Base class of all flightid errors."""


class InputError(FlightIdError, ValueError):
    """An argument has the wrong value, shape or content."""


class InputTypeError(FlightIdError, TypeError):
    """An argument has the wrong type."""


class ModelError(InputError):
    """A model's functions break their contract: ``f``/``h`` read past ``x``, ``u`` or θ,
    return the wrong number of values, non-numbers or non-finite values at the start, or
    raise; or a model module cannot be imported. The message names the function, what was
    expected and what came, and where (maneuver, sample, time)."""


class SimulationError(FlightIdError, ArithmeticError):
    """The system equations produced non-finite states or outputs (the simulation diverged)."""

    def __init__(self, message: str, *, step: int | None = None) -> None:
        super().__init__(message)
        self.step = step


class EstimationError(FlightIdError, RuntimeError):
    """Estimation cannot proceed (e.g. the information matrix is singular at the start)."""


class TaskError(FlightIdError, RuntimeError):
    """A task run on a batch engine (a profile-likelihood parameter, a random-search chunk, a
    Monte Carlo realisation) raised or could not run (its worker died too often). The message
    names the task and its error; the original exception is the ``__cause__``."""


class FlightIdWarning(UserWarning):
    """Base class of flightid's warnings; ``flightid`` prints each as one line
    ``flightid: warning: <message>``."""


class CompileWarning(FlightIdWarning, RuntimeWarning):
    """numba could not compile a model's functions, which then run in pure Python (several
    times slower; the message names the line of the model that caused it and how to avoid
    it: ``flightid.model.compilation``), or a kernel's parallel variant, whose serial variant
    then runs (``flightid.simulation.kernels.run_parallel_variant``)."""


def describe(value: object) -> str:
    """Short description of a value for error messages."""
    shape = getattr(value, "shape", None)
    if shape is not None:
        return f"{type(value).__name__} of shape {tuple(shape)}"
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _one_line(text: object) -> str:
    return " ".join(str(text).split()) or "(no message)"


def error_line(exc: BaseException) -> str:
    """The one-line message ``flightid`` prints for a failure (without the ``--debug`` hint
    for named errors): ``flightid: error: <message>``; also the ``error`` of a failed batch
    record."""
    if isinstance(exc, FlightIdError):
        return f"flightid: error: {exc}"
    if isinstance(exc, OSError) and exc.strerror:
        where = f": {exc.filename}" if exc.filename else ""
        return f"flightid: error: {exc.strerror}{where}"
    return (
        f"flightid: error: internal error: {type(exc).__name__}: {_one_line(exc)} "
        "(run with --debug for the traceback)"
    )
