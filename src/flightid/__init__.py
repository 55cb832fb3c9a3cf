"""flightid — airplane parameter estimation with honest accuracy statements.

Output-error maximum likelihood with the MNRES, MNR and FPS optimizers of NASA RP-1153
(Murphy, 1986), model-structure determination by stepwise regression, and confidence limits
from the likelihood region.

The top-level names (``from flightid import estimate, FlightData, ...``) are loaded lazily
(PEP 562 module ``__getattr__``): ``import flightid`` alone does not import numpy, scipy or
numba, so that ``flightid --help`` starts quickly.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from flightid import results as _results
from flightid._version import __version__
from flightid.lazy_exports import lazy_exports

# public name -> module that defines it
_LAZY_EXPORTS: dict[str, str] = {
    "Convergence": "flightid.estimation",
    "Estimate": "flightid.estimation",
    "FPS": "flightid.estimation",
    "MNR": "flightid.estimation",
    "MNRES": "flightid.estimation",
    "estimate": "flightid.estimation",
    "FlightData": "flightid.data",
    "GlobalModel": "flightid.globalmodel",
    "fit_global_model": "flightid.globalmodel",
    "Parameter": "flightid.model",
    "Parameters": "flightid.model",
    "StateSpaceModel": "flightid.model",
    "Simulator": "flightid.simulation",
    "simulate": "flightid.simulation",
}

__all__ = [*_LAZY_EXPORTS, "__version__"]

if TYPE_CHECKING:  # static tools see the eager imports (re-exported through __all__)
    from flightid.data import FlightData  # noqa: F401
    from flightid.estimation import FPS, MNR, MNRES, Convergence, Estimate, estimate  # noqa: F401
    from flightid.globalmodel import GlobalModel, fit_global_model  # noqa: F401
    from flightid.model import Parameter, Parameters, StateSpaceModel  # noqa: F401
    from flightid.simulation import Simulator, simulate  # noqa: F401


def _result_summary(result: Any) -> str:
    """``Estimate.summary()`` / ``AccuracyResult.summary()``: the report layer's text."""
    from flightid.report.text import summary_of

    return summary_of(result)


def _result_figure(result: Any) -> Any:
    """``plot()`` of every result: the report layer's figure."""
    from flightid.report.result_figures import figure_of

    return figure_of(result)


# the results' summaries and figures are drawn by flightid.report, a layer above the results:
# handed in here (this package runs before any of its modules), imported on first use
_results.set_renderers(summary=_result_summary, figure=_result_figure)


__getattr__, __dir__ = lazy_exports(__name__, _LAZY_EXPORTS)
