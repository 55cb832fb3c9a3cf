"""The two forms of a model function, and the adapters between them.

A model function ``f`` (state derivative) or ``h`` (output map) is written in one of two forms:

    return form   f(t, x, u, theta) -> dx          a new 1-D float array per call
    out form      f(t, x, u, theta, out) -> None   writes its values into ``out``

The simulation kernels call the out form with buffers allocated once per trajectory, so a
step of the integration allocates nothing. The rest of the library (model checks, trim,
linearisation, filter gains) calls the return form. ``StateSpaceModel`` therefore exposes
both: ``model.f`` / ``model.h`` (return form) and ``model.f_out`` / ``model.h_out`` (out form),
whichever the user wrote:

* a return-form function is turned into the out form by ``as_out_form``: rewritten from its
  source where it has the documented shape (``return np.array([...])``, or one
  ``np.empty(n)`` filled and returned: ``flightid.model.outform_source``), which allocates
  nothing; otherwise adapted (``copy_out_form``: call, then copy into ``out`` — it still
  allocates the array it returns, so it is the slower path);
* an out-form function is adapted to the return form by ``as_return_form``: allocate, call;
  the adapter carries the original as its ``out_form`` attribute, which is how a model (and
  any copy of it, ``dataclasses.replace``) finds the allocation-free form again;
* a return-form function may carry its own out form as the attribute ``out_form`` (the
  built-in airplane and term-table models do: ``with_out_form``).

The form of a user's function is recognised by its number of positional parameters without
a default (4: return form, 5: out form) or given explicitly (``StateSpaceModel(...,
function_form="out")``); anything else is an ``InputError``.

Adapters are plain Python closures over the function they adapt; ``kernel_function`` rebuilds
them around numba-compiled inner functions for a compiled kernel (a closure over a Python
function cannot be compiled), or around the Python originals for the interpreted kernel.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable

import numpy as np

from flightid.errors import InputError

__all__ = [
    "FUNCTION_FORMS",
    "as_out_form",
    "copy_out_form",
    "as_return_form",
    "with_out_form",
    "function_form",
    "out_form_of",
    "kernel_function",
]

FUNCTION_FORMS = ("auto", "return", "out")
# number of positional parameters without a default → form
_FORM_BY_ARITY = {4: "return", 5: "out"}


def as_out_form(f: Callable) -> Callable:
    """The out form of the return-form ``f``: ``out[i] = f(t, x, u, theta)[i]``.

    Generated from ``f``'s source where it is of the documented shape (it ends in
    ``return np.array([...])`` or fills and returns one ``np.empty(n)``:
    ``flightid.model.outform_source``): the same expressions write into ``out`` and nothing
    is allocated. Otherwise the adapter ``copy_out_form(f)``. The generated form carries
    that adapter as ``python_form``: the interpreted kernels run it, as before."""
    from flightid.model.outform_source import generated_out_form

    generated = generated_out_form(f)
    if generated is None:
        return copy_out_form(f)
    generated.python_form = copy_out_form(f)
    return generated


def copy_out_form(f: Callable) -> Callable:
    """The adapter from the return form ``f`` to the out form: call, then copy into
    ``out`` (allocates the array ``f`` returns on every call)."""

    def f_out(t, x, u, theta, out):
        value = f(t, x, u, theta)
        for i in range(out.shape[0]):
            out[i] = value[i]

    f_out.adapts = (copy_out_form, f)
    return f_out


def as_return_form(f_out: Callable, size: int) -> Callable:
    """The return form of the out-form ``f_out`` whose values have ``size`` entries."""
    size = int(size)

    def f(t, x, u, theta):
        out = np.empty(size)
        f_out(t, x, u, theta, out)
        return out

    f.out_form = f_out
    f.adapts = (lambda inner: as_return_form(inner, size), f_out)
    return f


def with_out_form(f: Callable, f_out: Callable) -> Callable:
    """``f`` (return form), marked with its own out form ``f_out`` (the same values)."""
    f.out_form = f_out
    return f


def _arity(fn: Callable) -> int | None:
    """Positional parameters without a default of ``fn`` (its Python original); None if the
    signature cannot be read or takes ``*args``."""
    try:
        signature = inspect.signature(getattr(fn, "py_func", fn))
    except (TypeError, ValueError):
        return None
    count = 0
    for parameter in signature.parameters.values():
        if parameter.kind is inspect.Parameter.VAR_POSITIONAL:
            return None
        if (
            parameter.kind
            in (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
            and parameter.default is inspect.Parameter.empty
        ):
            count += 1
    return count


def function_form(fn: Callable, declared: str, argument: str) -> str:
    """The form ("return" or "out") of the user's function ``fn`` given as ``argument``
    ("f" or "h"), by its parameters or as ``declared`` ("auto", "return", "out")."""
    if declared not in FUNCTION_FORMS:
        raise InputError(f"function_form: expected one of {list(FUNCTION_FORMS)}, got {declared!r}")
    if getattr(fn, "out_form", None) is not None:
        # a return form that carries its out form (an adapter or a built-in model)
        return "return"
    arity = _arity(fn)
    found = _FORM_BY_ARITY.get(arity) if arity is not None else None
    if declared == "auto":
        if arity is None:
            return "return"
        if found is None:
            raise InputError(
                f"{argument}: expected a function {argument}(t, x, u, theta) -> array (return "
                f"form) or {argument}(t, x, u, theta, out) writing into out (out form), got one "
                f"with {arity} positional parameters"
            )
        return found
    if arity is not None and found != declared:
        expected = "(t, x, u, theta)" if declared == "return" else "(t, x, u, theta, out)"
        raise InputError(
            f"{argument}: function_form={declared!r} needs {argument}{expected}, got a function "
            f"with {arity} positional parameters"
        )
    return declared


def out_form_of(fn: Callable) -> Callable:
    """The out form of a model function given in either form: its ``out_form`` attribute,
    ``fn`` itself if it takes ``out``, else the adapter ``as_out_form(fn)``."""
    out = getattr(fn, "out_form", None)
    if out is not None:
        return out
    if function_form(fn, "auto", "function") == "out":
        return fn
    return as_out_form(fn)


def kernel_function(fn: Callable, compiled: bool) -> Callable:
    """``fn`` ready to be called by a kernel: numba-compiled (``compiled``) or the Python
    original, with every adapter rebuilt around the prepared inner function."""
    python_form = getattr(fn, "python_form", None)
    if python_form is not None and not compiled:
        # a generated out form: the interpreted kernel runs the user's own function
        return kernel_function(python_form, False)
    adapts = getattr(fn, "adapts", None)
    if adapts is not None:
        make, inner = adapts
        adapter = make(kernel_function(inner, compiled))
        if not compiled:
            return adapter
        import numba

        return numba.njit(adapter)
    if not compiled:
        return getattr(fn, "py_func", fn)
    if hasattr(fn, "py_func"):
        return fn
    import numba

    return numba.njit(fn)
