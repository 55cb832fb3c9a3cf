"""Compiling a model's functions with numba, and saying why when it cannot be done.

numba compiles a function on its first call, for the types of the arguments; a function it
cannot type raises one of numba's errors (``TypingError``, ``UnsupportedError``, ...). An
error of any other kind raised by that first call (``ZeroDivisionError`` when θ holds a zero
divisor, say) comes from *running* the compiled code: the function did compile.

When the functions cannot be compiled they run in pure Python, several times slower. The
``CompileWarning`` then names the line of the user's model numba stopped at (read from
numba's message: the first ``File "...", line N`` outside flightid and numba), numba's reason
and how to avoid it, on one line.
"""

from __future__ import annotations

import linecache
import re
import warnings
import weakref
from collections.abc import Callable
from pathlib import Path
from typing import Any

from flightid.errors import CompileWarning

__all__ = [
    "compile_failure_message",
    "is_compile_error",
    "try_compiled",
    "warn_pure_python",
]

_PACKAGE = Path(__file__).resolve().parents[1]  # .../flightid
_ANSI = re.compile(r"\x1b\[[0-9;]*m")
_LOCATION = re.compile(r'File "([^"]+)", line (\d+)')
_REASON_LENGTH = 160


def is_compile_error(exc: BaseException) -> bool:
    """True for numba's own errors (the function cannot be compiled), False for an error
    the compiled code raised while running."""
    return type(exc).__module__.split(".")[0] == "numba"


def try_compiled(jitted: Callable, *arguments) -> BaseException | None:
    """Call the numba dispatcher ``jitted`` once on ``arguments`` (this compiles it): None
    when it compiled (also when the compiled code then raised, e.g. dividing by a zero
    start value), numba's error when it cannot be compiled."""
    try:
        jitted(*arguments)
    except Exception as exc:  # numba's errors have many classes
        if is_compile_error(exc):
            return exc
    return None


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.relative_to(folder)
    except ValueError:
        return False
    return True


def _is_library(path: str) -> bool:
    """A file of flightid or of numba (not the user's model)."""
    resolved = Path(path).resolve()
    if _inside(resolved, _PACKAGE):
        return True
    return "numba" in resolved.parts or resolved.name.startswith("<")


def _user_line(text: str) -> tuple[str, int, str] | None:
    """(file, line number, source text) of the first location in numba's message that is
    not in flightid or numba, or None."""
    for path, number in _LOCATION.findall(text):
        if _is_library(path):
            continue
        source = linecache.getline(path, int(number)).strip()
        return path, int(number), source
    return None


def _reason(text: str) -> str:
    """numba's own reason: the first line of its message that is not a pipeline header."""
    for line in text.splitlines():
        line = " ".join(line.split())
        if not line or line.startswith(("Failed in ", "During: ", "File ", "<source elided>")):
            continue
        return line if len(line) <= _REASON_LENGTH else line[: _REASON_LENGTH - 3] + "..."
    return "no reason given"


def _advice(reason: str) -> str:
    """How to avoid the fall-back, for the common reasons."""
    untyped = re.search(r"Untyped global name '([^']+)'", reason)
    if untyped:
        return (
            f"make {untyped.group(1)} a number, a tuple or a numpy array (numba cannot read "
            "other Python objects from inside f and h), or pass it as a parameter or input"
        )
    return (
        "use only numbers, numpy arrays and the math/numpy functions numba supports inside f "
        "and h (no Python objects, dicts, scipy or other non-compiled functions)"
    )


def compile_failure_message(model_name: str, exc: BaseException) -> str:
    """One line: the model runs in pure Python, the user's line numba stopped at (where its
    message names one), numba's reason and how to avoid it."""
    text = _ANSI.sub("", str(exc))
    reason = _reason(text)
    where = _user_line(text)
    located = (
        f" at {Path(where[0]).name} line {where[1]}" + (f" `{where[2]}`" if where[2] else "")
        if where is not None
        else ""
    )
    return (
        f"model {model_name!r} runs in pure Python (several times slower): numba cannot "
        f"compile its f/h{located} ({type(exc).__name__}: {reason}); to avoid it, "
        f"{_advice(reason)}; compiled = false ([estimation]) runs Python without this warning"
    )


# the fall-back messages already given, per model function: a run builds the same model's
# kernels several times (estimate, confirmation, accuracy), and one line says it all
_WARNED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def warn_pure_python(
    model_name: str, exc: BaseException, stacklevel: int = 2, function: Any = None
) -> None:
    """Warn (``CompileWarning``) that the model runs in pure Python, and why — once for the
    same model ``function`` (its f) and reason."""
    message = compile_failure_message(model_name, exc)
    if function is not None:
        try:
            given = _WARNED.setdefault(function, set())
        except TypeError:  # not weakly referable: warn every time
            given = set()
        if message in given:
            return
        given.add(message)
    warnings.warn(message, CompileWarning, stacklevel=stacklevel + 1)
