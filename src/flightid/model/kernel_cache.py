"""On-disk cache of the compiled kernels, keyed by a digest of everything they are built from.

numba's own ``cache=True`` keys a function by its bytecode and, for a closure, by the pickled
cell contents. The kernels here are closures over the model's ``f`` and ``h`` (and over
helpers that close over them); a numba dispatcher pickles with a random per-process id, so
numba's key changes on every run and the cache never hits: every ``flightid run`` compiled
the kernels again (about 2–3 s on the HFB-320 case).

``cached_njit(py_func)`` keeps numba's cache (same files, same index, same invalidation when
the kernel's own source file changes) but replaces the key by a SHA-256 digest of what the
compiled code depends on, followed recursively from ``py_func``:

* every Python function reached: its bytecode, constants and names, its closure cells, and
  the values of the globals its code names (numba freezes globals into the compiled code);
* numba dispatchers: their compile options and their Python function;
* numbers, strings, tuples, NumPy arrays (dtype, shape, bytes): their values;
* modules and built-in functions: their names (``np``, ``math.cos``).

Anything else (an arbitrary object in a closure, a class of the user's) cannot be described
safely; the kernel is then compiled without the disk cache, as before. A changed model (its
source, one of its module-level constants, an aerodynamic table, a bias index) gives another
digest, hence a fresh compilation, never a stale kernel. A cached kernel that cannot be
loaded (numba re-imports the module whose globals the model functions use: a model module
that is no longer importable) is compiled again. ``FLIGHTID_KERNEL_CACHE=0`` turns the disk
cache off; numba's ``NUMBA_CACHE_DIR`` moves it.

numba names every compiled function ``qualname$uid`` with ``uid`` from a per-process counter,
and a kernel loaded from disk brings the names of the process that compiled it. Two models
built by the same code (two α–q models with other constants, say) compiled by two processes
doing the same work got the same names, and a third process loading both linked the second
to the first one's machine code: a wrong model, silently. The counter therefore starts at a
random offset in [2^47, 2^48) in each process (``_distinct_function_ids``), entries written
before that are not reused (the index key's tag), and a kernel that calls a numba function
compiled before this module was imported (an id from numba's own counter) is not cached at
all: it is compiled afresh.
"""

from __future__ import annotations

import hashlib
import itertools
import os
import secrets
import types
import weakref
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["cached_njit", "kernel_digest", "compiled_function", "content_key"]

# modules whose classes may appear in a closure or as a global (their behaviour is versioned
# with the library, which numba's cache index records)
_TRUSTED_CLASS_MODULES = ("builtins", "math", "numpy", "numba")


# tag of the index key; entries from before _distinct_function_ids carry another one
_KEY_TAG = "flightid-kernel-digest-2"


# ids at or above this come from the random offset; below it, from numba's own counter
_FIRST_DISTINCT_ID = 2**47


def _distinct_function_ids() -> None:
    """Start numba's per-process function id counter at a random offset in [2^47, 2^48), so
    that the names of functions compiled here (``qualname$uid``) differ from those in kernels
    other processes cached (module docstring)."""
    from numba.core.bytecode import FunctionIdentity

    FunctionIdentity._unique_ids = itertools.count(_FIRST_DISTINCT_ID + secrets.randbits(46))


def _compiled_before_the_offset(dispatcher: Any) -> bool:
    """A dispatcher already compiled with an id from numba's own counter (before this module
    was imported): its names may equal those of another process's functions, so a kernel
    that calls it is not cached (compiled afresh instead)."""
    for result in getattr(dispatcher, "overloads", {}).values():
        name = getattr(getattr(result, "fndesc", None), "unique_name", "")
        _, _, uid = name.rpartition("$")
        if uid.isdigit() and int(uid) < _FIRST_DISTINCT_ID:
            return True
    return False


_distinct_function_ids()


class _Undescribable(Exception):
    """An object reached from the kernel whose value cannot be put in the digest."""


def _code_names(code: types.CodeType) -> set[str]:
    """Names a code object and the code objects nested in it refer to."""
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _code_names(const)
    return names


def _update(hasher: Any, obj: Any, seen: set[int]) -> None:
    """Feed a deterministic description of ``obj`` into ``hasher``; ``_Undescribable`` if none."""
    if obj is None or isinstance(obj, (bool, int, float, complex, str, bytes)):
        hasher.update(f"{type(obj).__name__}:{obj!r};".encode())
    elif isinstance(obj, (tuple, list, frozenset)):
        hasher.update(f"{type(obj).__name__}[{len(obj)}](".encode())
        items = sorted(obj, key=repr) if isinstance(obj, frozenset) else obj
        for item in items:
            _update(hasher, item, seen)
        hasher.update(b")")
    elif isinstance(obj, np.ndarray):
        if obj.dtype.hasobject:
            raise _Undescribable("object array")
        hasher.update(f"ndarray:{obj.dtype.str}:{obj.shape}:".encode())
        hasher.update(np.ascontiguousarray(obj).tobytes())
    elif isinstance(obj, np.generic):
        hasher.update(f"{obj.dtype.str}:{obj!r};".encode())
    elif isinstance(obj, types.ModuleType):
        hasher.update(f"module:{obj.__name__};".encode())
    elif isinstance(obj, types.BuiltinFunctionType) or type(obj).__name__ == "ufunc":
        module = getattr(obj, "__module__", None) or "numpy"
        hasher.update(f"builtin:{module}.{obj.__name__};".encode())
    elif isinstance(obj, types.CodeType):
        _update_code(hasher, obj, seen)
    elif isinstance(obj, types.FunctionType):
        _update_function(hasher, obj, seen)
    elif hasattr(obj, "py_func") and type(obj).__module__.startswith("numba"):
        # a numba dispatcher: its options and the Python function it compiles
        if _compiled_before_the_offset(obj):
            raise _Undescribable("a numba function compiled before flightid's kernel cache")
        options = getattr(obj, "targetoptions", {})
        hasher.update(f"dispatcher:{sorted(options.items())!r}:".encode())
        _update_function(hasher, obj.py_func, seen)
    elif isinstance(obj, type) and obj.__module__.split(".")[0] in _TRUSTED_CLASS_MODULES:
        hasher.update(f"class:{obj.__module__}.{obj.__qualname__};".encode())
    else:
        raise _Undescribable(f"{type(obj).__module__}.{type(obj).__qualname__}")


def _update_code(hasher: Any, code: types.CodeType, seen: set[int]) -> None:
    hasher.update(f"code:{code.co_name}:{code.co_argcount}:".encode())
    hasher.update(code.co_code)
    hasher.update(repr((code.co_names, code.co_varnames, code.co_freevars)).encode())
    for const in code.co_consts:
        _update(hasher, const, seen)


def _update_function(hasher: Any, fn: types.FunctionType, seen: set[int]) -> None:
    if id(fn) in seen:  # recursion, or the same helper reached twice
        hasher.update(f"seen:{fn.__module__}.{fn.__qualname__};".encode())
        return
    seen.add(id(fn))
    hasher.update(f"function:{fn.__qualname__}:".encode())
    _update_code(hasher, fn.__code__, seen)
    _update(hasher, fn.__defaults__, seen)
    for cell in fn.__closure__ or ():
        _update(hasher, cell.cell_contents, seen)
    for name in sorted(_code_names(fn.__code__)):
        if name in fn.__globals__:
            hasher.update(f"global:{name}=".encode())
            _update(hasher, fn.__globals__[name], seen)


def kernel_digest(py_func: Callable) -> str | None:
    """SHA-256 (hex) of what the compiled ``py_func`` depends on, or None where something it
    reaches cannot be described (see the module docstring)."""
    hasher = hashlib.sha256()
    try:
        _update(hasher, py_func, set())
    except (_Undescribable, ValueError):
        # ValueError: an empty closure cell (a function defined before its helper)
        return None
    return hasher.hexdigest()


# content_key: fn -> key, forgotten with fn
_CONTENT_KEYS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
# compiled_function: content key -> dispatcher
_COMPILED_FUNCTIONS: dict[Any, Callable] = {}


def content_key(fn: Callable | None) -> Any:
    """A key that is equal for two functions computing the same thing: ``("digest", d)``
    with the ``kernel_digest`` d of ``fn``, or, where there is no digest, ``("id", id(fn))``
    (the function itself, then). Remembered per function object (a digest walks the whole
    call tree once)."""
    if fn is None:
        return ("none",)
    try:
        return _CONTENT_KEYS[fn]
    except (KeyError, TypeError):  # TypeError: no weak reference to fn possible
        pass
    digest = kernel_digest(fn)
    # the id of a function is unique while it lives; a kernel keyed on it keeps it alive
    key = ("digest", digest) if digest is not None else ("id", id(fn))
    try:
        _CONTENT_KEYS[fn] = key
    except TypeError:
        pass
    return key


def compiled_function(py_func: Callable) -> Callable:
    """The numba dispatcher of ``py_func`` (a plain Python function), one per process for
    all functions with the same ``content_key`` (a case built twice compiles its model
    functions once) and kept on disk like the kernels (``cached_njit``). A dispatcher is
    returned as it is."""
    if hasattr(py_func, "py_func"):
        return py_func
    key = content_key(py_func)
    dispatcher = _COMPILED_FUNCTIONS.get(key)
    if dispatcher is None:
        dispatcher = cached_njit(py_func)
        _COMPILED_FUNCTIONS[key] = dispatcher
    return dispatcher


def _cache_enabled() -> bool:
    return os.environ.get("FLIGHTID_KERNEL_CACHE", "1").strip().lower() not in ("0", "no", "off")


def cached_njit(py_func: Callable, parallel: bool = False) -> Callable:
    """``numba.njit(py_func, parallel=parallel)``, its compiled code kept on disk under the
    digest of ``kernel_digest`` (no disk cache where there is no digest, or no writable cache
    folder). The parallel and the serial compilation of one kernel are kept apart (the flag
    is part of the key)."""
    import numba

    dispatcher = numba.njit(py_func, parallel=parallel)
    digest = kernel_digest(py_func) if _cache_enabled() else None
    if digest is None:
        return dispatcher
    if parallel:
        digest += ":parallel"
    from numba.core.caching import FunctionCache

    class DigestCache(FunctionCache):
        """numba's function cache with the index key replaced by the digest."""

        def _index_key(self, sig, codegen):
            return (sig, codegen.magic_tuple(), (_KEY_TAG, digest))

        def _load_overload(self, sig, target_context):
            # a cached kernel that cannot be rebuilt (e.g. its model module is no longer
            # importable: numba re-imports the module of the functions' globals) is
            # compiled again instead
            try:
                return super()._load_overload(sig, target_context)
            except Exception:
                return None

    try:
        dispatcher._cache = DigestCache(py_func)
    except RuntimeError:  # numba found no folder to write its cache in
        pass
    return dispatcher
