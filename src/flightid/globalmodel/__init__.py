"""Global aerodynamic models over the flight envelope: one model of each coefficient over
the explanatory variables (α, β, Mach, rates, surfaces) from many maneuvers at many flight
conditions, by multivariate orthogonal functions selected by predicted squared error, with
prediction intervals from the coloured-residual covariance and a data-support flag on every
prediction.

    model = fit_global_model(signals, {"CL": "CL"}, ["alpha", "Mach", "de"],
                             settings=GlobalModelSettings(max_order=3), maneuver_index=index)
    p = model.predict({"alpha": grid, "Mach": 0.6, "de": 0.0})["CL"]
    p.value, p.lower, p.upper, p.outside
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from flightid.lazy_exports import lazy_exports

# public name -> module that defines it
_LAZY_EXPORTS: dict[str, str] = {
    "fit_global_model": "flightid.globalmodel.fit",
    "GlobalModel": "flightid.globalmodel.model",
    "CoefficientModel": "flightid.globalmodel.model",
    "Prediction": "flightid.globalmodel.model",
    "SourceInfo": "flightid.globalmodel.model",
    "load_global_model": "flightid.globalmodel.model",
    "GlobalModelSettings": "flightid.globalmodel.settings",
    "GlobalModelError": "flightid.globalmodel.variables",
    "MofPath": "flightid.globalmodel.mof",
    "Support": "flightid.globalmodel.support",
}

__all__ = list(_LAZY_EXPORTS)

if TYPE_CHECKING:  # static tools see the eager imports (re-exported through __all__)
    from flightid.globalmodel.fit import fit_global_model  # noqa: F401
    from flightid.globalmodel.model import (  # noqa: F401
        CoefficientModel,
        GlobalModel,
        Prediction,
        SourceInfo,
        load_global_model,
    )
    from flightid.globalmodel.mof import MofPath  # noqa: F401
    from flightid.globalmodel.settings import GlobalModelSettings  # noqa: F401
    from flightid.globalmodel.support import Support  # noqa: F401
    from flightid.globalmodel.variables import GlobalModelError  # noqa: F401

__getattr__, __dir__ = lazy_exports(__name__, _LAZY_EXPORTS)
