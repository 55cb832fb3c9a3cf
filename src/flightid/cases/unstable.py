"""The unstable-aircraft options of ``[estimation]`` applied to a built case model
(docs/unstable.md; ``flightid.model.unstable``):

    stabilizing_gain = { w = { w = 0.05 } }   # x_k ← x_k + S (z_k − y_k), S[state, output]
    eigenvalue_shift = 0.7                     # σ (1/s): data × e^(−σt), f − σx
    shooting_intervals = 10                    # multiple shooting: intervals per maneuver
    shooting_weight = [1, 1e3, 1e6]            # defect weights in samples, used in turn
                                               # (continuation; the default), or one number

They combine (applied in this order: eigenvalue shift, stabilizing gain, shooting); each
error is a ``CaseError`` naming the key.
"""

from __future__ import annotations

from collections.abc import Sequence

from flightid.cases.checks import CaseError
from flightid.cases.spec import Case
from flightid.data.flightdata import FlightData
from flightid.errors import InputError
from flightid.model.statespace import StateSpaceModel
from flightid.model.unstable import (
    DEFAULT_SHOOTING_WEIGHTS,
    exponentially_weighted,
    with_eigenvalue_shift,
    with_multiple_shooting,
    with_stabilizing_gain,
)

__all__ = ["apply_unstable_options", "UNSTABLE_KEYS"]

UNSTABLE_KEYS = ("stabilizing_gain", "eigenvalue_shift", "shooting_intervals")


def apply_unstable_options(
    case: Case, model: StateSpaceModel, maneuvers: Sequence[FlightData]
) -> tuple[StateSpaceModel, list[FlightData]]:
    """The model and maneuvers with the case's unstable-aircraft options applied."""
    settings = case.estimation
    maneuvers = list(maneuvers)
    if not any(k in settings for k in UNSTABLE_KEYS):
        return model, maneuvers
    if case.prediction and ("eigenvalue_shift" in settings or "shooting_intervals" in settings):
        raise CaseError(
            "prediction: not available with eigenvalue_shift or shooting_intervals (the "
            "estimated model is that of the transformed or cut-up data)"
        )
    key = "estimation.eigenvalue_shift"
    try:
        if "eigenvalue_shift" in settings:
            sigma = float(settings["eigenvalue_shift"])
            model = with_eigenvalue_shift(model, sigma)
            maneuvers = exponentially_weighted(maneuvers, sigma)
        key = "estimation.stabilizing_gain"
        if "stabilizing_gain" in settings:
            model = with_stabilizing_gain(model, settings["stabilizing_gain"])
        key = "estimation.shooting_intervals"
        if "shooting_intervals" in settings:
            model = with_multiple_shooting(
                model,
                maneuvers,
                int(settings["shooting_intervals"]),
                settings.get("shooting_weight", DEFAULT_SHOOTING_WEIGHTS),
            )
    except InputError as exc:
        raise CaseError(f"{key}: {exc}") from None
    return model, maneuvers
