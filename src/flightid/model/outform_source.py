"""Allocation-free out forms generated from the source of return-form model functions.

A model function written in the documented return form allocates the array it returns on
every call, and the call-then-copy adapter (``flightid.model.forms.as_out_form``) copies it
into the kernel's buffer: per RK4 step four arrays for ``f`` and one for ``h``, each a heap
allocation in the compiled kernel. ``generated_out_form(fn)`` rewrites the function's own
source into the out form ``fn_out(t, x, u, theta, out)`` that writes the same values, computed
by the same expressions in the same order, straight into ``out``:

    return np.array([e0, e1, ...])      →   out[0] = e0; out[1] = e1; ...; return
    dx = np.empty(n)   (or np.zeros(n)) →   (removed; dx is the out parameter)  /  dx[:] = 0.0
    ...  dx[i] = ...                        ...  dx[i] = ...
    return dx                           →   return

The generated function starts with a size check, ``out.shape[0] == n`` (n: the number of
values the function returns), so a buffer of another size raises ``ValueError`` instead of
being written past its end. It is compiled from a syntax tree that keeps the user's file
name and line numbers (numba's messages name the user's lines) and runs in the user's
module globals (its constants, ``np``, ``math``), so what it computes is what the user's
function computes, to the last bit.

Only functions whose shape is certain are rewritten; for anything else ``generated_out_form``
returns None and the caller keeps the adapter:

* a plain Python function (or a numba dispatcher's Python original) with readable source,
  no closure, no decorator, exactly the four positional parameters (t, x, u, theta);
* every ``return`` (outside nested functions, which are not allowed) is either
  ``np.array([...])`` with a list of expressions (no starred items, no keywords), or the name
  of one buffer variable assigned once, at the function's top level, by ``np.empty(n)`` or
  ``np.zeros(n)`` (n an integer literal, a module-level integer or ``len`` of a module-level
  tuple or list) and not rebound anywhere; ``np`` is checked to be numpy in the globals;
* the last statement is a ``return``; no ``yield``, ``global``, ``nonlocal``, ``lambda``,
  nested function or class.
"""

from __future__ import annotations

import ast
import inspect
import textwrap
import types
import weakref
from collections.abc import Callable

import numpy as np

__all__ = ["generated_out_form", "GENERATED_MARK"]

# attribute of a generated out form: the return-form function it was generated from
GENERATED_MARK = "generated_from"
_ALLOCATORS = {"empty": False, "zeros": True}  # numpy allocator → the buffer starts at zero
_FORBIDDEN = (
    ast.Yield,
    ast.YieldFrom,
    ast.Global,
    ast.Nonlocal,
    ast.Lambda,
    ast.FunctionDef,
    ast.AsyncFunctionDef,
    ast.ClassDef,
    ast.Await,
)
# per return-form function: its generated out form, or None where it cannot be generated
_GENERATED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class _NotGenerated(Exception):
    """The function is not of a shape ``generated_out_form`` rewrites."""


def generated_out_form(fn: Callable) -> Callable | None:
    """The allocation-free out form of the return-form model function ``fn`` generated from
    its source (module docstring), or None where ``fn`` is not of a shape that is rewritten
    with certainty. Remembered per function."""
    try:
        return _GENERATED[fn]
    except (KeyError, TypeError):
        pass
    try:
        generated = _generate(fn)
    except _NotGenerated:
        generated = None
    try:
        _GENERATED[fn] = generated
    except TypeError:  # not weakly referable
        pass
    return generated


def _python_function(fn: Callable) -> types.FunctionType:
    original = getattr(fn, "py_func", fn)
    if not isinstance(original, types.FunctionType) or original.__closure__:
        raise _NotGenerated("not a plain function without closure")
    if original.__defaults__ or original.__kwdefaults__:
        raise _NotGenerated("parameters with defaults")
    code = original.__code__
    if code.co_argcount != 4 or code.co_kwonlyargcount or code.co_flags & 0x0C:
        raise _NotGenerated("not (t, x, u, theta)")  # 0x04 *args, 0x08 **kwargs
    return original


def _source_tree(original: types.FunctionType) -> tuple[ast.FunctionDef, str]:
    try:
        lines, first = inspect.getsourcelines(original)
        filename = inspect.getsourcefile(original) or "<model>"
    except (OSError, TypeError) as exc:
        raise _NotGenerated("no source") from exc
    try:
        module = ast.parse(textwrap.dedent("".join(lines)))
    except SyntaxError as exc:
        raise _NotGenerated("source does not parse alone") from exc
    if len(module.body) != 1 or not isinstance(module.body[0], ast.FunctionDef):
        raise _NotGenerated("not a def statement")
    definition = module.body[0]
    if definition.decorator_list or definition.name != original.__name__:
        raise _NotGenerated("decorated or renamed")
    ast.increment_lineno(module, first - 1)
    return definition, filename


def _is_numpy_call(node: ast.AST, names: tuple[str, ...], namespace: dict) -> str | None:
    """The numpy function name of a call ``np.NAME(...)`` (NAME in ``names``, ``np`` bound to
    numpy in ``namespace``), else None."""
    if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)):
        return None
    base = node.func.value
    if not (isinstance(base, ast.Name) and namespace.get(base.id) is np):
        return None
    return node.func.attr if node.func.attr in names else None


def _static_size(node: ast.AST, namespace: dict) -> int:
    """The integer value of a buffer size: a literal, a module-level integer or ``len`` of
    a module-level tuple or list."""
    if isinstance(node, ast.Constant) and type(node.value) is int:
        return node.value
    if isinstance(node, ast.Name) and type(namespace.get(node.id)) is int:
        return namespace[node.id]
    if (
        isinstance(node, ast.Call)
        and isinstance(node.func, ast.Name)
        and node.func.id == "len"
        and "len" not in namespace
        and len(node.args) == 1
        and not node.keywords
        and isinstance(node.args[0], ast.Name)
        and isinstance(namespace.get(node.args[0].id), (tuple, list))
    ):
        return len(namespace[node.args[0].id])
    raise _NotGenerated("buffer size not static")


def _buffer(definition: ast.FunctionDef, namespace: dict) -> tuple[str, int, bool] | None:
    """(name, size, zeroed) of the buffer variable ``name = np.empty(n)`` / ``np.zeros(n)``
    at the top level of the body, if the function has one."""
    found = None
    for statement in definition.body:
        if not (
            isinstance(statement, ast.Assign)
            and len(statement.targets) == 1
            and isinstance(statement.targets[0], ast.Name)
        ):
            continue
        allocator = _is_numpy_call(statement.value, tuple(_ALLOCATORS), namespace)
        if allocator is None:
            continue
        call = statement.value
        if len(call.args) != 1 or call.keywords:
            continue
        if found is not None:
            raise _NotGenerated("two buffers")
        size = _static_size(call.args[0], namespace)
        found = (statement.targets[0].id, size, _ALLOCATORS[allocator], statement)
    return found


def _stores(definition: ast.FunctionDef, name: str) -> int:
    """How often ``name`` is bound in the function (assignments, loop targets, ...)."""
    count = 0
    for node in ast.walk(definition):
        if isinstance(node, ast.Name) and node.id == name and not isinstance(node.ctx, ast.Load):
            count += 1
        elif isinstance(node, ast.arg) and node.arg == name:
            count += 1
        elif isinstance(node, (ast.alias, ast.ExceptHandler)) and name in (
            getattr(node, "asname", None),
            getattr(node, "name", None),
        ):
            count += 1
    return count


def _fresh_name(definition: ast.FunctionDef) -> str:
    used = {n.id for n in ast.walk(definition) if isinstance(n, ast.Name)}
    used |= {a.arg for a in ast.walk(definition) if isinstance(a, ast.arg)}
    name = "out"
    while name in used:
        name = "_" + name
    return name


class _Returns(ast.NodeTransformer):
    """Rewrites every ``return`` into writes to the out parameter and a bare ``return``."""

    def __init__(self, out: str, buffer: str | None, namespace: dict) -> None:
        self.out = out
        self.buffer = buffer
        self.namespace = namespace
        self.sizes: set[int] = set()

    def visit_Return(self, node: ast.Return) -> list[ast.stmt]:
        value = node.value
        if self.buffer is not None and isinstance(value, ast.Name) and value.id == self.buffer:
            return [ast.copy_location(ast.Return(value=None), node)]
        if _is_numpy_call(value, ("array",), self.namespace) is None:
            raise _NotGenerated("a return that is neither np.array([...]) nor the buffer")
        if len(value.args) != 1 or value.keywords or not isinstance(value.args[0], ast.List):
            raise _NotGenerated("np.array of something else than a list")
        items = value.args[0].elts
        if any(isinstance(item, ast.Starred) for item in items):
            raise _NotGenerated("starred items")
        self.sizes.add(len(items))
        writes: list[ast.stmt] = []
        for i, item in enumerate(items):
            target = ast.Subscript(
                value=ast.Name(id=self.out, ctx=ast.Load()),
                slice=ast.Constant(value=i),
                ctx=ast.Store(),
            )
            # out[i] = e_i: the value np.array([...]) would hold at i
            writes.append(ast.copy_location(ast.Assign(targets=[target], value=item), node))
        writes.append(ast.copy_location(ast.Return(value=None), node))
        return writes


def _size_check(out: str, size: int, name: str, line_of: ast.AST) -> ast.stmt:
    """``if out.shape[0] != size: raise ValueError(...)``."""
    statement = ast.parse(
        f"if {out}.shape[0] != {size}:\n"
        f"    raise ValueError('{name}: writes {size} values into an out array of another "
        "size (the model has another number of states or outputs)')\n"
    ).body[0]
    for node in ast.walk(statement):
        if hasattr(node, "lineno"):
            node.lineno = node.end_lineno = line_of.lineno
            node.col_offset = node.end_col_offset = 0
    return statement


def _rewrite(definition: ast.FunctionDef, namespace: dict) -> ast.FunctionDef:
    """``definition`` turned into its out form (module docstring); raises ``_NotGenerated``."""
    if any(isinstance(node, _FORBIDDEN) for body in definition.body for node in ast.walk(body)):
        raise _NotGenerated("unsupported statements")
    if not definition.body or not isinstance(definition.body[-1], ast.Return):
        raise _NotGenerated("does not end in a return")
    found = _buffer(definition, namespace)
    buffer = None
    if found is not None:
        buffer, size, zeroed, statement = found
        if _stores(definition, buffer) != 1:
            raise _NotGenerated("buffer rebound")
    out = buffer if buffer is not None else _fresh_name(definition)
    returns = _Returns(out, buffer, namespace)
    body = []
    for statement_ in definition.body:
        if found is not None and statement_ is statement:
            if zeroed:
                # np.zeros(n): the buffer starts at zero
                body.append(ast.copy_location(ast.parse(f"{out}[:] = 0.0").body[0], statement_))
            continue
        rewritten = returns.visit(statement_)
        body.extend(rewritten if isinstance(rewritten, list) else [rewritten])
    sizes = returns.sizes | ({size} if found is not None else set())
    if len(sizes) != 1:
        raise _NotGenerated("returns of different sizes")
    definition.body = [_size_check(out, sizes.pop(), definition.name, definition), *body]
    definition.args.args.append(ast.arg(arg=out))
    return definition


def _generate(fn: Callable) -> Callable:
    original = _python_function(fn)
    definition, filename = _source_tree(original)
    namespace = original.__globals__
    rewritten = _rewrite(definition, namespace)
    module = ast.fix_missing_locations(ast.Module(body=[rewritten], type_ignores=[]))
    try:
        code = compile(module, filename, "exec")
    except (SyntaxError, ValueError) as exc:
        raise _NotGenerated("does not compile") from exc
    function_code = next(c for c in code.co_consts if isinstance(c, types.CodeType))
    generated = types.FunctionType(function_code, namespace, original.__name__)
    generated.__qualname__ = original.__qualname__
    generated.__module__ = original.__module__
    generated.__doc__ = original.__doc__
    setattr(generated, GENERATED_MARK, fn)
    return generated
