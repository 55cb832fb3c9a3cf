"""The one result surface shared by every flightid result.

Every result — output-error ``Estimate``, ``AccuracyResult``, ``LeastSquaresResult`` and
``StepwiseResult`` — answers the same calls:

    summary()                       readable text table (units shown where known)
    to_dict()                       plain-Python, JSON-ready dictionary
    to_json(indent=2)               strict JSON of ``to_dict()`` (``flightid.jsonout``)
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

The confidence intervals every ``conf_int`` draws on live here too: the level check, the
likelihood-region contour level Δ with its residual variance factor s², the projection of the
quadratic region on each axis, and the Student-t intervals of the linear fits.

For the output-error cost J(θ) = Σ_i ν_iᵀ R⁻¹ ν_i with N samples of n_o outputs and n_p free
parameters, the residual variance factor is

    s² = J(θ̂) / (N·n_o − n_p)                                        [5.30]

(≈ 1 when R is the residual estimate R̂ [3.45]; it carries the noise level when R is fixed,
e.g. R = I). A confidence region at level 1 − α is {θ : J(θ) − J(θ̂) ≤ Δ} with

    simultaneous (all n_p parameters at once):
        Δ = n_p s² F_α(n_p, N·n_o − n_p)                              [5.20, 5.23]
    individual (one parameter, the others free):
        Δ = s² F_α(1, N·n_o − n_p) = s² t²_{α/2}(N·n_o − n_p)

``distribution="normal"`` replaces the F quantiles by their large-sample limits,
q·F_α(q, ∞) = χ²_α(q) (q = n_p or 1). For a problem linear in θ the region is the ellipsoid
(θ − θ̂)ᵀ M (θ − θ̂) ≤ Δ, whose projection on axis j is θ̂_j ± √(Δ·(M⁻¹)_jj) [5.24–5.27]
(``ellipsoid_intervals``).

The text summary and the figure of a result are drawn by ``flightid.report``, a layer above
this module: the renderers are handed in from above (``set_renderers``, called by the
``flightid`` package itself, which Python imports before any of its modules), so that this
module imports nothing of the report. numpy and scipy are imported inside the functions that
use them: ``import flightid`` loads this module and stays light.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from flightid.errors import FlightIdError, InputError

if TYPE_CHECKING:
    import numpy as np

__all__ = [
    "DISTRIBUTIONS",
    "KINDS",
    "SCHEMA_VERSION",
    "MissingDependencyError",
    "RendererMissingError",
    "ResultSurface",
    "check_level",
    "check_method",
    "contour_level",
    "ellipsoid_intervals",
    "render_summary",
    "require_pandas",
    "residual_variance_factor",
    "results_document",
    "set_renderers",
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


KINDS = ("individual", "simultaneous")
DISTRIBUTIONS = ("t", "normal")


def check_level(level: float) -> float:
    """The confidence level 1 − α as a float in (0, 1); raises InputError otherwise."""
    try:
        value = float(level)
    except (TypeError, ValueError):
        raise InputError(f"level: expected a probability such as 0.95, got {level!r}") from None
    if not 0.0 < value < 1.0:
        raise InputError(f"level: expected a probability strictly between 0 and 1, got {value}")
    return value


def residual_variance_factor(cost: float, n_data: int, n_free: int) -> float:
    """s² = J(θ̂) / (N·n_o − n_p) [5.30] (dimensionless when J is weighted by R⁻¹)."""
    dof = n_data - n_free
    if dof <= 0:
        raise InputError(
            f"n_data: need more scalar measurements (N·n_o = {n_data}) than free parameters "
            f"({n_free}) to estimate s²"
        )
    return float(cost) / dof


def contour_level(
    level: float,
    n_data: int,
    n_free: int,
    s2: float,
    kind: str = "individual",
    distribution: str = "t",
) -> float:
    """Δ such that {J(θ) − J(θ̂) ≤ Δ} is the confidence region at ``level``.

    Args:
        level: confidence level 1 − α, e.g. 0.95.
        n_data: N·n_o, the number of scalar measurements.
        n_free: n_p, the number of free parameters.
        s2: residual variance factor s² [5.30].
        kind: ``"individual"`` (one parameter at a time) or ``"simultaneous"`` [5.24–5.25].
        distribution: ``"t"`` (F quantiles with N·n_o − n_p degrees of freedom, the paper's)
            or ``"normal"`` (χ² quantiles, the large-sample limit).
    Returns:
        Δ in the units of J.
    """
    from scipy import stats

    level = check_level(level)
    if kind not in KINDS:
        raise InputError(f"kind: expected one of {KINDS}, got {kind!r}")
    if distribution not in DISTRIBUTIONS:
        raise InputError(f"distribution: expected one of {DISTRIBUTIONS}, got {distribution!r}")
    q = n_free if kind == "simultaneous" else 1
    dof = n_data - n_free
    if distribution == "t":
        if dof <= 0:
            raise InputError(
                f"n_data: N·n_o = {n_data} must exceed the {n_free} free parameters "
                "for the F distribution"
            )
        # Δ = q s² F_α(q, N·n_o − n_p)                                   [5.20, 5.25]
        return float(q * s2 * stats.f.ppf(level, q, dof))
    # Δ = s² χ²_α(q)  (q F_α(q, ∞) = χ²_α(q))
    return float(s2 * stats.chi2.ppf(level, q))


def ellipsoid_intervals(center: np.ndarray, covariance: np.ndarray, delta: float) -> np.ndarray:
    """Projection of {(θ − θ̂)ᵀ C⁻¹ (θ − θ̂) ≤ Δ} on each axis: (n_f, 2) [lo, hi].

    Args:
        center: θ̂ (n_f,).
        covariance: C = M⁻¹ (n_f × n_f); inf on the diagonal for undetermined parameters.
        delta: the contour level Δ (units of J).
    """
    import numpy as np

    center = np.asarray(center, dtype=float)
    variance = np.diag(np.asarray(covariance, dtype=float)).copy()
    variance[~np.isfinite(variance)] = np.inf
    # half-width_j = √(Δ · C_jj)                                          [5.24–5.26]
    half = np.sqrt(delta * np.maximum(variance, 0.0))
    return np.column_stack([center - half, center + half])


def t_intervals(
    center: np.ndarray, std: np.ndarray, level: float, dof: int, distribution: str = "t"
) -> np.ndarray:
    """Individual intervals θ̂_j ± q·std_j as an (n, 2) array [lower, upper].

    q = t_{(1+c)/2}(dof) (Student t, ``distribution="t"``) or z_{(1+c)/2} (``"normal"``), c
    the confidence ``level``. With dof ≤ 0 the t quantile does not exist: InputError.
    """
    import numpy as np
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
    return number if math.isfinite(number) else None


class RendererMissingError(FlightIdError, RuntimeError):
    """A result's summary or figure was asked for before the report renderers were set
    (``set_renderers``; the ``flightid`` package sets them when it is imported)."""


# result → text summary, result → matplotlib Figure: set from above (``set_renderers``)
_summary_renderer: Callable[[Any], str] | None = None
_figure_renderer: Callable[[Any], Any] | None = None


def set_renderers(*, summary: Callable[[Any], str], figure: Callable[[Any], Any]) -> None:
    """Hand in the functions that draw a result: ``summary(result) -> str`` (the text table
    of ``Estimate.summary`` / ``AccuracyResult.summary``) and ``figure(result) -> Figure``
    (``ResultSurface.plot``). The ``flightid`` package sets them to ``flightid.report``'s
    renderers, imported on first use."""
    global _summary_renderer, _figure_renderer
    _summary_renderer, _figure_renderer = summary, figure


def _renderer(renderer: Callable | None, call: str) -> Callable:
    if renderer is None:
        raise RendererMissingError(
            f"{call}: no report renderer is set; import flightid (its package sets them) or "
            "call flightid.results.set_renderers"
        )
    return renderer


def render_summary(result: Any) -> str:
    """The text summary of ``result``, drawn by the renderer handed in (``set_renderers``)."""
    return _renderer(_summary_renderer, f"{type(result).__name__}.summary()")(result)


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
        ``"nonfinite"`` (``flightid.jsonout``)."""
        from flightid.jsonout import dumps

        return dumps(self.to_dict(), indent=indent)

    def plot(self, path: str | Path | None = None, *, dpi: int = 120):
        """The result's figure (drawn by ``flightid.report.result_figures``, handed in with
        ``set_renderers``), a matplotlib ``Figure``; also written as PNG to ``path`` when
        given."""
        figure = _renderer(_figure_renderer, f"{type(self).__name__}.plot()")(self)
        if path is not None:
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            figure.savefig(path, dpi=dpi)
        return figure
