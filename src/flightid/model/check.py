"""The model contract, checked on the data before anything is estimated.

A ``StateSpaceModel`` promises (see ``flightid.model.statespace``)

    f(t, x, u, θ) → 1-D numeric array of n_x values (dx/dt, one per state)
    h(t, x, u, θ) → 1-D numeric array of n_y values (y, one per output)

with ``x`` of length n_x, ``u`` of length n_u (the model's inputs, in order) and ``θ`` the
*full* parameter vector (n_p values, free and fixed). The compiled simulation kernel reads
and writes these arrays without bounds checks, so a model that reads ``u[1]`` with one input,
returns one derivative for two states (NumPy broadcasts it to both) or one output for two
(the kernel reads past the array) runs on garbage and can still "converge".

``check_model`` evaluates the *Python* originals of ``f`` and ``h`` (``f.py_func`` for a numba
dispatcher), where NumPy checks every index, for every maneuver at the first samples and at a
handful spread through the record, with x = x0 of that maneuver and θ = the start values.
Each evaluation must

* not raise (an exception names the function, maneuver, sample and time, and the line of the
  model file that raised; an index past ``x``, ``u`` or ``θ`` is named with the length the
  model declares, e.g. "read u[1] but the model has 1 input ('de')");
* return a NumPy array (not a scalar, list or 0-d array) of a real numeric dtype and shape
  exactly (n_x,) for f and (n_y,) for h;
* leave its arguments unchanged (the kernel passes views of the data and of θ);
* at the first sample of each maneuver (the start values) be finite; a non-finite entry is
  named by its state or output.

A model without states (``states=()``) has no f to check: only h is evaluated, with x the
empty array.

No trajectory is integrated, so the check costs 2 × (samples checked) Python calls: a few
milliseconds, whatever the record length.
"""

from __future__ import annotations

import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flightid.data.flightdata import FlightData
from flightid.errors import InputTypeError, ModelError, describe
from flightid.model.binding import bind_feedback, bind_maneuvers, check_method
from flightid.model.statespace import StateSpaceModel

__all__ = ["ModelCheck", "check_model"]

# Samples checked per maneuver: the first FIRST_SAMPLES and SPREAD_SAMPLES spread evenly
# over the record (the last sample included).
FIRST_SAMPLES = 3
SPREAD_SAMPLES = 5

_SIGNATURE = {"f": "f(t, x, u, theta)", "h": "h(t, x, u, theta)"}


@dataclass(frozen=True)
class ModelCheck:
    """What ``check_model`` evaluated (it raises ``ModelError`` on any violation).

    Attributes:
        model: the model's name.
        n_maneuvers: maneuvers checked.
        n_samples: samples at which f and h were each evaluated (over all maneuvers).
        f_shape, h_shape: shapes the functions returned: (n_states,), (n_outputs,).
        n_inputs, n_parameters: lengths of u and θ passed to them.
        elapsed_s: wall time of the check (s).
    """

    model: str
    n_maneuvers: int
    n_samples: int
    f_shape: tuple[int, ...]
    h_shape: tuple[int, ...]
    n_inputs: int
    n_parameters: int
    elapsed_s: float

    def summary(self) -> str:
        """One line for ``flightid validate``."""
        # a model without states (f_shape (0,)) has only h checked
        functions, returns = (
            ("f and h", f"f returns {self.f_shape[0]} derivatives, h")
            if self.f_shape[0]
            else ("h (no states, no f)", "h returns")
        )
        return (
            f"model functions checked: {functions} evaluated at {self.n_samples} samples of "
            f"{self.n_maneuvers} maneuver(s) at the start values; {returns} "
            f"{self.h_shape[0]} outputs, with {_plural(self.n_inputs, 'input')} "
            f"and {_plural(self.n_parameters, 'parameter')}; no index out of range, all finite "
            f"at the start "
            f"({self.elapsed_s * 1e3:.0f} ms)"
        )


# ------------------------------------------------------------------ named arguments


class _ArgumentIndexError(IndexError):
    """An out-of-range index into one of the arrays passed to f or h."""

    def __init__(self, argument: str, key: object, write: bool, original: IndexError) -> None:
        super().__init__(str(original))
        self.argument = argument
        self.key = key
        self.write = write


class _Named(np.ndarray):
    """ndarray that names itself in IndexError (used only to locate a failed read).

    Only the array passed in carries the name; views and results of arithmetic do not, so
    the message never blames ``u`` for an index into something computed from it.
    """

    _argument: str | None = None

    def __array_finalize__(self, obj) -> None:
        self._argument = None

    def _located(self, key, write: bool, exc: IndexError) -> IndexError:
        if self._argument is None:
            return exc
        return _ArgumentIndexError(self._argument, key, write, exc)

    def __getitem__(self, key):
        try:
            return super().__getitem__(key)
        except IndexError as exc:
            raise self._located(key, False, exc) from None

    def __setitem__(self, key, value) -> None:
        try:
            super().__setitem__(key, value)
        except IndexError as exc:
            raise self._located(key, True, exc) from None


def _named(values: np.ndarray, argument: str) -> _Named:
    array = np.array(values, dtype=float).view(_Named)
    array._argument = argument
    return array


# ------------------------------------------------------------------ messages


def _plural(n: int, word: str) -> str:
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


def _declared(model: StateSpaceModel, argument: str) -> str:
    """'1 input ('de')' — what the model declares for one argument of f/h."""
    names = {
        "x": (model.states, "state"),
        "u": (model.inputs, "input"),
        "theta": (list(model.function_parameters), "parameter"),
    }[argument]
    listed = ", ".join(repr(n) for n in names[0][:12]) + (", ..." if len(names[0]) > 12 else "")
    return f"{_plural(len(names[0]), names[1])} ({listed})" if names[0] else f"no {names[1]}s"


def _key_text(key: object) -> str:
    if isinstance(key, tuple):
        return ", ".join(_key_text(k) for k in key)
    if isinstance(key, slice):
        parts = ("" if v is None else str(v) for v in (key.start, key.stop, key.step))
        return ":".join(parts).rstrip(":") or ":"
    if isinstance(key, np.ndarray):
        return f"<array {key.tolist()}>" if key.size <= 6 else f"<array of {key.size}>"
    return repr(key) if not isinstance(key, (int, np.integer)) else str(int(key))


def _user_line(exc: BaseException) -> str:
    """', at model.py line 12: `return u[1]`' — the innermost frame outside NumPy and flightid."""
    skip = (str(Path(np.__file__).parent), str(Path(__file__).parents[1]))
    where = ""
    for frame in traceback.extract_tb(exc.__traceback__):
        filename = frame.filename or ""
        if filename.startswith(skip) or filename.startswith("<frozen"):
            continue
        code = f": `{frame.line.strip()}`" if frame.line else ""
        where = f" ({Path(filename).name} line {frame.lineno}{code})"
    return where


@dataclass(frozen=True)
class _Site:
    """Where one evaluation happens."""

    maneuver: int
    maneuver_name: str
    n_maneuvers: int
    sample: int
    time_s: float

    def __str__(self) -> str:
        where = f"at sample {self.sample}, t = {self.time_s:.6g} s"
        if self.n_maneuvers > 1:
            label = f" '{self.maneuver_name}'" if self.maneuver_name else ""
            where = f"in maneuver {self.maneuver + 1}{label} {where}"
        return where


# ------------------------------------------------------------------ evaluation


def _python_function(function: Callable) -> Callable:
    """The Python original of a numba dispatcher (NumPy bounds-checks every index there)."""
    return getattr(function, "py_func", function)


def _call(
    name: str,
    function: Callable,
    model: StateSpaceModel,
    arguments: tuple[np.floating, np.ndarray, np.ndarray, np.ndarray],
    site: _Site,
) -> object:
    """function(t, x, u, θ) on copies; every failure becomes a ModelError naming the site."""
    t, x, u, theta = arguments
    copies = (x.copy(), u.copy(), theta.copy())
    try:
        # non-finite results are reported below by name, not as NumPy warnings
        with np.errstate(all="ignore"):
            result = function(t, *copies)
    except IndexError as exc:
        raise _index_error(name, function, model, arguments, site, exc) from None
    except Exception as exc:
        raise ModelError(
            f"{_SIGNATURE[name]} raised {type(exc).__name__}: {exc}{_user_line(exc)}; {site}"
        ) from exc
    for argument, before, after in zip(("x", "u", "theta"), (x, u, theta), copies, strict=True):
        if not np.array_equal(before, after, equal_nan=True):
            raise ModelError(
                f"{_SIGNATURE[name]} changed its argument {argument} in place; the simulation "
                f"passes views of the states, the data and θ, so f and h must not write into "
                f"them (copy first); {site}"
            )
    return result


def _index_error(
    name: str,
    function: Callable,
    model: StateSpaceModel,
    arguments: tuple,
    site: _Site,
    exc: IndexError,
) -> ModelError:
    """Name the argument an IndexError came from by repeating the call with named arrays."""
    t, x, u, theta = arguments
    located: BaseException = exc
    try:
        with np.errstate(all="ignore"):
            function(t, _named(x, "x"), _named(u, "u"), _named(theta, "theta"))
    except _ArgumentIndexError as again:
        located = again
    except Exception:  # noqa: BLE001 — anything else: report the original IndexError
        pass
    if isinstance(located, _ArgumentIndexError):
        key = located.key
        integer = isinstance(key, (int, np.integer)) and not isinstance(key, bool)
        verb = "wrote" if located.write else "read"
        if integer:
            return ModelError(
                f"{_SIGNATURE[name]} {verb} {located.argument}[{int(key)}] but the model has "
                f"{_declared(model, located.argument)}{_user_line(exc)}; {site}"
            )
        return ModelError(
            f"{_SIGNATURE[name]} indexed {located.argument}[{_key_text(key)}]: {exc}; "
            f"{located.argument} holds {_declared(model, located.argument)}"
            f"{_user_line(exc)}; {site}"
        )
    return ModelError(
        f"{_SIGNATURE[name]} raised IndexError: {exc}{_user_line(exc)}; the model has "
        f"{_declared(model, 'x')}, {_declared(model, 'u')} and {_declared(model, 'theta')}; "
        f"{site}"
    )


def _check_result(
    name: str, result: object, model: StateSpaceModel, site: _Site, at_start: bool
) -> np.ndarray:
    """Type, dtype, shape (and at the start, finiteness) of what f or h returned."""
    if name == "f":
        names, what, kind = model.states, "derivative", "state"
    else:
        names, what, kind = model.outputs, "value", "output"
    expected = (
        f"a 1-D NumPy array of {_plural(len(names), 'value')} (one {what} per {kind}: "
        f"{', '.join(repr(n) for n in names)})"
    )
    if not isinstance(result, np.ndarray):
        if isinstance(result, (int, float, complex, np.generic)):
            extra = " (NumPy would broadcast it to every " + kind + ")" if len(names) > 1 else ""
            got = f"the scalar {result!r} ({type(result).__name__}){extra}"
        elif isinstance(result, (list, tuple)):
            got = f"a {type(result).__name__} of {len(result)} item(s) (wrap it in np.array)"
        else:
            got = describe(result) if result is not None else "None (missing return?)"
        raise ModelError(f"{_SIGNATURE[name]} must return {expected}; got {got}; {site}")
    if result.dtype.kind not in "fiu":
        raise ModelError(
            f"{_SIGNATURE[name]} must return {expected} of real numbers; got an array of "
            f"dtype {result.dtype}; {site}"
        )
    if result.shape != (len(names),):
        if result.ndim == 1:
            got = f"{_plural(result.shape[0], 'value')}"
            if result.shape[0] == 1 and len(names) > 1:
                got += f" (NumPy would broadcast it to every {kind})"
        else:
            got = f"an array of shape {result.shape}"
        raise ModelError(f"{_SIGNATURE[name]} must return {expected}; got {got}; {site}")
    if at_start:
        values = np.asarray(result, dtype=float)
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            listed = ", ".join(f"{names[i]!r} = {values[i]}" for i in bad)
            raise ModelError(
                f"{_SIGNATURE[name]} returned a non-finite {what if name == 'f' else 'output'} "
                f"at the start values: "
                f"{listed}; {site} (check the start values, x0 and the data there)"
            )
    return result


def _samples(n: int) -> list[int]:
    """The first FIRST_SAMPLES samples and SPREAD_SAMPLES spread over [0, n − 1]."""
    spread = np.linspace(0, n - 1, SPREAD_SAMPLES).round().astype(int).tolist() if n > 1 else []
    return sorted(set(range(min(FIRST_SAMPLES, n))) | set(spread))


def check_model(
    model: StateSpaceModel,
    data: FlightData | Sequence[FlightData],
    *,
    method: str = "rk4",
) -> ModelCheck:
    """Evaluate f and h on the data at the start values and check the model contract.

    Args:
        model: the model; its parameter values are the start values.
        data: one ``FlightData`` or a list (maneuvers) with the model's input channels (as
            inputs or outputs of the data), as for ``estimate`` and ``simulate``.
        method: the integration method the estimate will use, ``"rk4"`` or ``"euler"``
            (checked like the simulator checks it).

    Returns:
        A ``ModelCheck`` saying what was evaluated.

    Raises:
        ModelError: f or h raises, reads past x, u or θ, returns the wrong type, dtype or
            number of values, changes its arguments, or is non-finite at the start.
        InputError / InputTypeError: the model or data themselves are unusable (missing
            input channels, x0 for another number of maneuvers, unknown method).
    """
    from time import perf_counter

    started = perf_counter()
    if not isinstance(model, StateSpaceModel):
        raise InputTypeError(f"model: expected a StateSpaceModel, got {describe(model)}")
    # The maneuvers, their input matrices, x0 maps and feedback options, resolved and
    # checked as the simulator resolves and checks them (flightid.model.binding).
    check_method(method)
    bound = bind_maneuvers(model, data)
    bind_feedback(model, bound)
    theta = np.array(model.parameters.values, dtype=float)
    functions = {"f": _python_function(model.f), "h": _python_function(model.h)}
    # a model without states has no f to call (simulate.kernels: h alone at every sample)
    checked = ("h", "f") if model.has_states else ("h",)
    n_maneuvers = len(bound.maneuvers)
    shapes = {"f": (len(model.states),), "h": (len(model.outputs),)}
    n_checked = 0
    for i, (maneuver, t, u) in enumerate(
        zip(bound.maneuvers, bound.times, bound.inputs, strict=True)
    ):
        x0 = model.initial_state(theta, i if model.per_maneuver_x0 else 0)
        if t.shape[0] == 0:
            continue
        for k in _samples(t.shape[0]):
            site = _Site(i, maneuver.name or "", n_maneuvers, k, float(t[k]))
            # f and h receive the θ of their own layout (per-maneuver parameters substituted)
            theta_f = model.function_theta(theta, i)
            arguments = (t[k], x0, np.array(u[k], dtype=float), theta_f)
            # y_k = h(t_k, x_k, u_k, θ), then dx/dt = f(t_k, x_k, u_k, θ), as the kernel does
            for name in checked:
                result = _call(name, functions[name], model, arguments, site)
                _check_result(name, result, model, site, at_start=k == 0)
            n_checked += 1
    return ModelCheck(
        model=model.name,
        n_maneuvers=n_maneuvers,
        n_samples=n_checked,
        f_shape=shapes["f"],
        h_shape=shapes["h"],
        n_inputs=len(model.inputs),
        n_parameters=int(theta.size),
        elapsed_s=perf_counter() - started,
    )
