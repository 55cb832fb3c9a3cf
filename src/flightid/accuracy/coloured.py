"""Cramér–Rao bounds corrected for coloured (autocorrelated) residuals.

The computation lives in ``flightid.coloured`` (beside ``flightid.errors``, below every
estimator: output error, filter error and regression use it for their default σ); the names
are kept here for the accuracy assessment and the report.
"""

from __future__ import annotations

from flightid.coloured import (
    automatic_lag,
    coloured_covariance,
    residual_autocovariance,
)

__all__ = ["automatic_lag", "coloured_covariance", "residual_autocovariance"]
