"""An estimated model as a stand-alone Python module: f, h, the estimated values and a
simulation that integrates as flightid does, runnable with numpy alone (no flightid).

The module holds

* the model's functions ``f(t, x, u, theta)`` (dx/dt) and ``h(t, x, u, theta)`` (y), written
  one of two ways:

  - **source**: the module that defines the model's f and h, copied whole — a user model
    module (``[model] module``) or the straight-line module flightid writes for a built-in
    airplane model (``flightid.aircraft.codegen``; its numba decorator is replaced by one
    that does nothing). Refused when the module imports flightid or a module outside the
    standard library, numpy, scipy and numba, or when f and h are not both defined in it;
  - **linear**: for any other model whose f and h are affine in x and u and do not depend on
    t (checked at random points to 1e-9 relative):
    f = A x + B u + f_c, h = C x + D u + h_c, the matrices taken exactly from the model
    at the estimated values (f_c = f(0, 0), column j of [A B] = f(e_j) − f_c);
    ``theta`` is accepted for the common signature and not used;

* ``STATES``, ``INPUTS``, ``OUTPUTS``, ``THETA_NAMES`` (θ as f and h read it), ``THETA``
  (the estimated values), ``THETA_STD`` (their σ; NaN for fixed ones), ``X0`` (the initial
  state given), ``METHOD`` and ``INPUT_INTERPOLATION`` (the integration of the run);
* ``simulate(t, u, x0=X0, theta=THETA, ...)``: the outputs (N, n_o) at the samples t (N,)
  for the inputs u (N, n_u), by fixed-step RK4 (or Euler) with the input between samples
  held (``"zoh"``) or linear (``"linear"``, u at the half step = (u_k + u_{k+1})/2) — the
  arithmetic of ``flightid.simulate``, so the two agree to rounding.

Models that cannot be written are refused with ``PythonExportError`` saying why: time
delays (not in f and h), parameters per maneuver, and f and h that are neither copyable
source nor affine in x and u (table-path airplane models, bias wrappers around a nonlinear
model, closures).
"""

from __future__ import annotations

import ast
import inspect
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from flightid.export.files import ExportError, write_exports
from flightid.model.statespace import StateSpaceModel

__all__ = ["PythonExportError", "python_source", "write_python"]

# names the export section defines (a copied module may define STATES, INPUTS, OUTPUTS too:
# the export section sets them again, to the model's)
EXPORT_NAMES = (
    "THETA",
    "THETA_NAMES",
    "THETA_STD",
    "X0",
    "METHOD",
    "INPUT_INTERPOLATION",
    "simulate",
    "_export_np",
)
# top-level modules a copied model module may import
ALLOWED_IMPORTS = frozenset({"numpy", "scipy", "numba"})
GENERATED_PREFIX = "flightid_generated_"
NUMBA_IMPORT = "from numba.extending import register_jitable"
NO_NUMBA = (
    "def register_jitable(function):  # numba's decorator, not needed here\n    return function"
)
AFFINE_TOLERANCE = 1e-9


class PythonExportError(ExportError):
    """A model that cannot be written as a stand-alone Python module."""


def _module_of(function) -> object | None:
    function = getattr(function, "py_func", function)
    return sys.modules.get(getattr(function, "__module__", "") or "")


def _module_source(model: StateSpaceModel) -> tuple[str | None, str]:
    """(source of the module defining f and h, how it was found) or (None, why not)."""
    f = getattr(model.f, "py_func", model.f)
    h = getattr(model.h, "py_func", model.h)
    module = _module_of(h)
    if module is None or (model.states and _module_of(f) is not module):
        return None, "f and h are not defined in one module"
    name = module.__name__
    if name.startswith("flightid.") or name == "flightid":
        return None, f"f and h are flightid's own functions ({name}), not a model module"
    if getattr(module, "h", None) is not h or (
        model.states and getattr(module, "f", None) is not f
    ):
        return None, f"f and h are not the module-level f and h of {name}"
    generated = name.startswith(GENERATED_PREFIX)
    source = getattr(module, "__flightid_source__", None)
    if source is None:
        try:
            source = inspect.getsource(module)
        except (OSError, TypeError):
            return None, f"the source of {name} cannot be read"
    if generated:
        if NUMBA_IMPORT not in source:
            return None, "the generated airplane module has an unexpected form"
        return source.replace(NUMBA_IMPORT, NO_NUMBA), "built-in airplane model (generated code)"
    problem = _foreign_imports(source)
    if problem:
        return None, f"the model module {name} {problem}"
    where = getattr(module, "__file__", name)
    return source, f"model module {Path(where).name if where else name}"


def _imported_modules(tree: ast.Module) -> list[str]:
    """The top-level names of the modules ``tree`` imports (``.x`` for a relative import)."""
    names: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [a.name.split(".")[0] for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            level = "." * node.level
            names.append(
                level + (node.module or "") if level else (node.module or "").split(".")[0]
            )
    return names


def _defined_names(tree: ast.Module) -> set[str]:
    """Names the module body binds by assignment, ``def`` or ``class``."""
    names: set[str] = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef)):
            names.add(node.name)
        targets = node.targets if isinstance(node, ast.Assign) else []
        targets = [node.target] if isinstance(node, ast.AnnAssign) else targets
        names |= {t.id for t in targets if isinstance(t, ast.Name)}
    return names


def _foreign_imports(source: str) -> str:
    """'' when ``source`` imports only the standard library, numpy, scipy and numba and does
    not define a name the export section defines; else what is wrong."""
    try:
        tree = ast.parse(source)
    except SyntaxError as exc:
        return f"cannot be parsed ({exc})"
    foreign = {
        n
        for n in _imported_modules(tree)
        if n not in ALLOWED_IMPORTS and n not in sys.stdlib_module_names
    }
    if foreign:
        return f"imports {sorted(foreign)} (only the standard library, numpy, scipy, numba)"
    clash = sorted(_defined_names(tree) & set(EXPORT_NAMES))
    if clash:
        return f"defines {clash}, which the exported module defines itself"
    return ""


def _split_future_imports(source: str) -> tuple[str, str]:
    """(the ``from __future__`` import lines of ``source``, the rest): they must open the
    written module, before the copied code's own docstring."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return "", source
    lines = source.splitlines(keepends=True)
    future = [
        node
        for node in tree.body
        if isinstance(node, ast.ImportFrom) and node.module == "__future__"
    ]
    taken = {i for node in future for i in range(node.lineno - 1, node.end_lineno)}
    head = "".join(lines[i] for i in sorted(taken))
    rest = "".join(line for i, line in enumerate(lines) if i not in taken)
    return (head + "\n" if head else ""), rest


def _affine_parts(
    model: StateSpaceModel, theta_f: np.ndarray, seed: int = 0
) -> tuple[tuple[np.ndarray, ...] | None, str]:
    """((A, B, f_c, C, D, h_c), '') for f and h affine in (x, u) and independent of t, else
    (None, why not)."""
    n_s, n_u = len(model.states), len(model.inputs)

    def both(t: float, z: np.ndarray) -> np.ndarray:
        x, u = z[:n_s], z[n_s:]
        dx = np.asarray(model.f(t, x, u, theta_f), dtype=float) if n_s else np.zeros(0)
        return np.concatenate([dx, np.asarray(model.h(t, x, u, theta_f), dtype=float)])

    with np.errstate(all="ignore"):
        zero = np.zeros(n_s + n_u)
        try:
            constant = both(0.0, zero)
            columns = [both(0.0, np.eye(n_s + n_u)[j]) - constant for j in range(n_s + n_u)]
        except Exception as exc:  # a model that fails at 0 (1/V) is not affine
            return None, f"f and h cannot be evaluated at x = 0, u = 0 ({type(exc).__name__})"
        jac = np.column_stack(columns) if columns else np.zeros((constant.size, 0))
        rng = np.random.default_rng(seed)
        for _ in range(3):
            z = rng.normal(size=n_s + n_u)
            t = float(rng.uniform(0.0, 100.0))
            try:
                value = both(t, z)
            except Exception as exc:
                return None, f"f and h fail at a test point ({type(exc).__name__})"
            # affine: (f, h)(t, z) = c + J z for every t and z
            predicted = constant + jac @ z
            scale = np.abs(constant) + np.abs(jac) @ np.abs(z) + np.abs(value)
            if not np.all(np.isfinite(value)) or np.any(
                np.abs(value - predicted) > AFFINE_TOLERANCE * np.maximum(scale, 1e-300)
            ):
                return None, "f and h are not affine in the states and inputs (or depend on t)"
    a, b = jac[:n_s, :n_s], jac[:n_s, n_s:]
    c, d = jac[n_s:, :n_s], jac[n_s:, n_s:]
    return (a, b, constant[:n_s], c, d, constant[n_s:]), ""


def _literal(array: np.ndarray) -> str:
    """``np.array([...])`` with every float's repr (exact; NaN and ±inf by name)."""
    values = np.asarray(array, dtype=float).ravel()
    text = [repr(float(v)) if np.isfinite(v) else f"float('{v}')" for v in values]
    return "_export_np.array([" + ", ".join(text) + "])"


def _linear_source(parts: tuple[np.ndarray, ...], n_s: int, n_o: int) -> str:
    a, b, fc, c, d, hc = parts
    # np.array(...).reshape keeps empty matrices their shape
    return "\n".join(
        [
            "import numpy as _export_np",
            "",
            "# f = A x + B u + F_C,  h = C x + D u + H_C  (at the estimated values)",
            f"A = {_literal(a)}.reshape({a.shape})",
            f"B = {_literal(b)}.reshape({b.shape})",
            f"F_C = {_literal(fc)}",
            f"C = {_literal(c)}.reshape({c.shape})",
            f"D = {_literal(d)}.reshape({d.shape})",
            f"H_C = {_literal(hc)}",
            "",
            "",
            "def f(t, x, u, theta=None):",
            '    """dx/dt (theta is not used: the matrices hold the estimated values)."""',
            "    return A @ _export_np.asarray(x, dtype=float) + B @ _export_np.asarray(u, "
            "dtype=float) + F_C",
            "",
            "",
            "def h(t, x, u, theta=None):",
            '    """y (theta is not used: the matrices hold the estimated values)."""',
            "    return C @ _export_np.asarray(x, dtype=float) + D @ _export_np.asarray(u, "
            "dtype=float) + H_C",
            "",
        ]
    )


_SIMULATE = '''

def simulate(t, u, x0=X0, theta=THETA, method=METHOD, input_interpolation=INPUT_INTERPOLATION):
    """Outputs (N, n_o) at the samples t (N,) for the inputs u (N, n_u), from x0: RK4 (or
    Euler) with the input between samples held ("zoh") or linear ("linear"), as flightid
    integrates; a sample where an output or state is not finite and all after it are NaN."""
    t = _export_np.asarray(t, dtype=float)
    u = _export_np.asarray(u, dtype=float).reshape(t.size, len(INPUTS))
    theta = _export_np.asarray(theta, dtype=float)
    x = _export_np.array(x0, dtype=float)
    y = _export_np.full((t.size, len(OUTPUTS)), _export_np.nan)
    for k in range(t.size):
        y[k] = h(t[k], x, u[k], theta)
        finite = _export_np.isfinite(y[k]).all() and _export_np.isfinite(x).all()
        if not finite:
            y[k:] = _export_np.nan
            break
        if k == t.size - 1 or not len(STATES):
            continue
        dt = t[k + 1] - t[k]
        if method == "euler":
            # x_{k+1} = x_k + dt f(t_k, x_k, u_k)
            x = x + dt * _export_np.asarray(f(t[k], x, u[k], theta), dtype=float)
            continue
        if input_interpolation == "zoh":
            u_half = u_end = u[k]
        else:
            u_end = u[k + 1]
            u_half = 0.5 * (u[k] + u_end)
        half = 0.5 * dt
        k1 = _export_np.asarray(f(t[k], x, u[k], theta), dtype=float)
        k2 = _export_np.asarray(f(t[k] + 0.5 * dt, x + half * k1, u_half, theta), dtype=float)
        k3 = _export_np.asarray(f(t[k] + 0.5 * dt, x + half * k2, u_half, theta), dtype=float)
        k4 = _export_np.asarray(f(t[k] + dt, x + dt * k3, u_end, theta), dtype=float)
        # x_{k+1} = x_k + dt/6 (k1 + 2 k2 + 2 k3 + k4)
        x = x + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return y


if __name__ == "__main__":
    print(__doc__)
    for _name, _value, _std in zip(THETA_NAMES, THETA, THETA_STD):
        print(f"{_name:>12} = {_value:.10g}  (sigma {_std:.3g})")
'''


def _check_model(model: StateSpaceModel) -> None:
    if not isinstance(model, StateSpaceModel):
        raise PythonExportError(
            f"model: expected a StateSpaceModel (Estimate.model), got {type(model).__name__}"
        )
    if model.output_delays or model.input_delays:
        raise PythonExportError(
            f"model {model.name!r}: has time delays ({dict(model.output_delays or {})}, "
            f"{dict(model.input_delays or {})}), which f and h do not hold; a stand-alone "
            "module cannot be written"
        )
    if model.maneuver_parameters:
        raise PythonExportError(
            f"model {model.name!r}: has parameters per maneuver "
            f"{list(model.maneuver_parameters)}; a stand-alone module cannot be written"
        )


def python_source(
    model: StateSpaceModel,
    x0: Sequence[float] | np.ndarray,
    *,
    std: Sequence[float] | np.ndarray | None = None,
    method: str = "rk4",
    input_interpolation: str = "linear",
    description: str = "",
) -> str:
    """The text of the stand-alone module of ``model`` at its parameter values (module
    docstring). ``x0``: the initial state ``X0``; ``std``: σ of every parameter (NaN for
    fixed ones). Raises ``PythonExportError`` for a model that cannot be written."""
    _check_model(model)
    x0 = np.asarray(x0, dtype=float).ravel()
    if x0.size != len(model.states):
        raise PythonExportError(
            f"x0: expected {len(model.states)} values (one per {list(model.states)}), got {x0.size}"
        )
    if method not in ("rk4", "euler") or input_interpolation not in ("linear", "zoh"):
        raise PythonExportError(
            f"method, input_interpolation: expected 'rk4'|'euler' and 'linear'|'zoh', got "
            f"{method!r}, {input_interpolation!r}"
        )
    theta_f = np.asarray(model.function_theta(model.parameters.values, 0), dtype=float)
    body, how = _module_source(model)
    if body is None:
        parts, why_not = _affine_parts(model, theta_f)
        if parts is None:
            raise PythonExportError(
                f"model {model.name!r}: a stand-alone module cannot be written: its f and h "
                f"are not copyable source ({how}) and {why_not}"
            )
        body = _linear_source(parts, len(model.states), len(model.outputs))
        how = "linear model, its matrices at the estimated values (f and h do not read THETA)"
    names = model.parameters.names
    if theta_f.size == len(names):
        theta_names = list(names)
    else:  # substituted θ (not expected: per-maneuver parameters are refused above)
        theta_names = [f"theta[{i}]" for i in range(theta_f.size)]
    sigma = np.full(len(names), np.nan) if std is None else np.asarray(std, dtype=float)
    theta_std = sigma if theta_f.size == len(names) else np.full(theta_f.size, np.nan)
    from flightid._version import __version__

    header = (
        f'"""{model.name}: stand-alone model written by flightid {__version__} '
        f"(flightid export --format python).\n\n"
        f"{description + chr(10) + chr(10) if description else ''}"
        f"f and h: {how}. THETA holds the estimated values; simulate(t, u) integrates as\n"
        'flightid does. Needs numpy only (and what the model code imports)."""\n\n'
    )
    future, body = _split_future_imports(body)
    header += (
        future + "# ---------------------------------------------------------------- model code\n"
    )
    section = "\n".join(
        [
            "",
            "",
            "# ------------------------------------------------- written by flightid export",
            "import numpy as _export_np  # noqa: E402",
            "",
            f"STATES = {tuple(model.states)!r}",
            f"INPUTS = {tuple(model.inputs)!r}",
            f"OUTPUTS = {tuple(model.outputs)!r}",
            f"THETA_NAMES = {tuple(theta_names)!r}",
            f"THETA = {_literal(theta_f)}",
            f"THETA_STD = {_literal(theta_std)}",
            f"X0 = {_literal(x0)}",
            f"METHOD = {method!r}",
            f"INPUT_INTERPOLATION = {input_interpolation!r}",
        ]
    )
    return header + body.rstrip("\n") + "\n" + section + "\n" + _SIMULATE


def write_python(
    model: StateSpaceModel,
    path: str | Path,
    x0: Sequence[float] | np.ndarray,
    *,
    std: Sequence[float] | np.ndarray | None = None,
    method: str = "rk4",
    input_interpolation: str = "linear",
    description: str = "",
    overwrite: bool = False,
) -> Path:
    """Write the stand-alone module of ``model`` (``python_source``) to ``path`` (``.py``
    appended when missing); an existing file is replaced only with ``overwrite`` and only
    when flightid exported it. Returns the path."""
    text = python_source(
        model,
        x0,
        std=std,
        method=method,
        input_interpolation=input_interpolation,
        description=description,
    )
    path = Path(path)
    if path.suffix != ".py":
        path = path.with_name(path.name + ".py")
    (written,) = write_exports(
        {path: lambda tmp: tmp.write_text(text, encoding="utf-8")}, overwrite
    )
    return written
