"""The one result surface shared by every flightid result.

Every result — output-error ``Estimate``, ``AccuracyResult``, ``LeastSquaresResult`` and
``StepwiseResult`` — answers the same calls:

    summary()                       readable text table (units shown where known)
    to_dict()                       plain-Python, JSON-ready dictionary
    to_json(indent=2)               strict JSON of ``to_dict()`` (``flightid.report.jsonout``)
    to_frame()                      pandas DataFrame, one row per parameter, indexed by name
                                    (pandas is imported here, lazily: the ``pandas`` extra)
    conf_int(level=0.95, method=…)  (n, 2) numpy array [lower, upper], one row per row of
                                    ``conf_int_names`` (free parameters / regressors), in
                                    the parameters' units
    plot(path=None)                 a matplotlib ``Figure`` (drawn by ``flightid.report``,
                                    imported lazily); saved as PNG when ``path`` is given

``conf_int`` always returns an array (never a DataFrame, whatever is installed); the frame
with the labels is ``to_frame()``, which carries the default intervals as ``lower`` /
``upper`` columns.

``results.json`` is the document ``results_document`` builds: ``{"schema_version": "1",
"results": [entry, ...]}``, described by ``docs/schema/results.schema.json``.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from flightid.errors import FlightIdError, InputError

__all__ = [
    "SCHEMA_VERSION",
    "MissingDependencyError",
    "ResultSurface",
    "check_method",
    "require_pandas",
    "results_document",
    "t_intervals",
]

# version of the results.json layout; raised when a key changes meaning or disappears
SCHEMA_VERSION = "1"


class MissingDependencyError(FlightIdError, ImportError):
    """An optional package that a call needs is not installed."""


def require_pandas(call: str):
    """The ``pandas`` module, or ``MissingDependencyError`` naming the call and the extra."""
    try:
        import pandas
    except ImportError:
        raise MissingDependencyError(
            f"{call}: needs pandas, which is not installed; install it with "
            "pip install 'flightid[pandas]' (or pip install pandas)"
        ) from None
    return pandas


def results_document(entries: Iterable[dict]) -> dict:
    """The results.json document: ``{"schema_version": SCHEMA_VERSION, "results": [...]}``."""
    return {"schema_version": SCHEMA_VERSION, "results": list(entries)}


def check_method(method: str, methods: Sequence[str], argument: str = "method") -> str:
    """``method`` if it is one of ``methods``; else ``InputError`` naming both."""
    if not isinstance(method, str) or method not in methods:
        raise InputError(f"{argument}: expected one of {list(methods)}, got {method!r}")
    return method


def check_level(level: float) -> float:
    """The confidence level as a float in (0, 1) (``flightid.accuracy.levels.check_level``)."""
    from flightid.accuracy.levels import check_level as _check

    return _check(level)


def t_intervals(
    center: np.ndarray, std: np.ndarray, level: float, dof: int, distribution: str = "t"
) -> np.ndarray:
    """Individual intervals θ̂_j ± q·std_j as an (n, 2) array [lower, upper].

    q = t_{(1+c)/2}(dof) (Student t, ``distribution="t"``) or z_{(1+c)/2} (``"normal"``), c
    the confidence ``level``. With dof ≤ 0 the t quantile does not exist: InputError.
    """
    from scipy import stats

    level = check_level(level)
    check_method(distribution, ("t", "normal"), "distribution")
    if distribution == "t":
        if dof <= 0:
            raise InputError(
                f"dof: the t interval needs positive residual degrees of freedom, got {dof}"
            )
        # q = t_{(1+c)/2}(N − n_p)
        q = float(stats.t.ppf(0.5 * (1.0 + level), dof))
    else:
        # q = z_{(1+c)/2}
        q = float(stats.norm.ppf(0.5 * (1.0 + level)))
    center = np.asarray(center, dtype=float)
    half = q * np.asarray(std, dtype=float)
    return np.column_stack([center - half, center + half])


def finite_or_none(value: Any) -> float | None:
    """A float, or None for NaN / ±inf (JSON has neither)."""
    number = float(value)
    return number if np.isfinite(number) else None


class ResultSurface:
    """Mixin: ``to_frame``, ``to_json`` and ``plot`` built on each result's own
    ``_frame_rows()`` (list of dicts with a ``"name"`` key) and ``to_dict()``."""

    def _frame_rows(self) -> list[dict]:  # pragma: no cover - each result defines it
        raise NotImplementedError

    def to_frame(self):
        """The per-parameter table as a pandas DataFrame indexed by ``name``.

        Raises:
            MissingDependencyError: pandas is not installed (the ``pandas`` extra).
        """
        pandas = require_pandas(f"{type(self).__name__}.to_frame()")
        return pandas.DataFrame(self._frame_rows()).set_index("name")

    def to_json(self, indent: int | None = 2) -> str:
        """Strict JSON of ``to_dict()``: a non-finite number becomes null, listed under
        ``"nonfinite"`` (``flightid.report.jsonout``)."""
        from flightid.report.jsonout import dumps

        return dumps(self.to_dict(), indent=indent)

    def plot(self, path: str | Path | None = None, *, dpi: int = 120):
        """The result's figure (``flightid.report.result_figures``), a matplotlib ``Figure``;
        also written as PNG to ``path`` when given."""
        from flightid.report.result_figures import figure_of

        figure = figure_of(self)
        if path is not None:
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            figure.savefig(path, dpi=dpi)
        return figure
