"""Cramér–Rao bounds corrected for coloured (autocorrelated) residuals.

The computation lives at the estimation layer (``flightid.estimation.coloured``), where every
time-domain estimate uses it for its default σ; the names are kept here for the accuracy
assessment and the report.
"""

from __future__ import annotations

from flightid.estimation.coloured import (
    automatic_lag,
    coloured_covariance,
    residual_autocovariance,
)

__all__ = ["automatic_lag", "coloured_covariance", "residual_autocovariance"]
