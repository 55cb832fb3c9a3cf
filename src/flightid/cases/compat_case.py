"""``[model] type = "kinematic"`` in case files: the keys, their check and the model.

    [model]
    type = "kinematic"
    states = ["u", "v", "w", "φ", "θ", "ψ", "h"]     # integrated (default these seven;
                                                      # also "x_N", "y_E": positions)
    outputs = ["V", "α", "β", "φ", "θ", "ψ", "h"]    # default V, α, β and the states' own;
                                                      # also V_N V_E V_D V_G χ (ground speeds)
    g = 9.80                                          # L/s²
    accelerometer_position = [-1.010, 0.886, 0.103]   # L from the CG (adds pdot qdot rdot)
    airdata_position = [13.080, -0.010, -0.027]       # L from the CG
    velocity_at = "cg"                                # or "airdata"
    beta = "atan2"                                    # or "asin"
    input_biases = ["ax", "ay", "az", "p", "q", "r"]  # b_ax ... b_r (default all six)
    input_scales = []                                 # f_ax ... (default none)
    output_biases = ["α", "β"]                        # b_α, b_β (default α, β)
    output_scales = ["α", "β"]                        # f_α, f_β (default α, β)
    bias_convention = "sensor"                        # m = f·x + b; "correction": x = m + b
    scale_convention = "factor"                       # f; "fraction": f = 1 + λ
    scale_reference = { "α" = 0.35 }                  # scale about a constant (default 0)
    wind = ["W_N", "W_E"]                             # constant-wind parameters (L/s)
    names = { b_ax = "ax_bias" }                      # report parameters under other names
    length_unit = "m"                                 # or "ft" (labels and units)
    output_delays = { "α" = "τ_α" }                   # delay parameters, after the sensors'
    input_delays = { q = "τ_q" }                      # the model reads q(t − τ_q)
    delay_convention = "two_sample"

Every parameter starts free (biases and λ at 0, f at 1, delays at 0 s); [parameters] sets
start values and fixes them. See docs/compat.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from flightid.cases.checks import CaseError, _known
from flightid.compat.kinematic import KinematicSpec, kinematic_spec, model_from_spec
from flightid.errors import InputError, InputTypeError
from flightid.model.statespace import DELAY_CONVENTIONS, StateSpaceModel

__all__ = ["KINEMATIC_KEYS", "kinematic_section", "spec_from_case", "kinematic_from_case"]

# [model] keys of type = "kinematic", each an argument of kinematic_spec (but type, name and
# the delay keys)
_ARGUMENTS = (
    "states",
    "outputs",
    "g",
    "accelerometer_position",
    "airdata_position",
    "velocity_at",
    "beta",
    "input_biases",
    "input_scales",
    "output_biases",
    "output_scales",
    "bias_convention",
    "scale_convention",
    "scale_reference",
    "wind",
    "names",
    "length_unit",
)
KINEMATIC_KEYS = frozenset(
    {"type", "name", "output_delays", "input_delays", "delay_convention", *_ARGUMENTS}
)


def _delay_table(model: Mapping[str, Any], key: str, what: str) -> dict[str, str]:
    delays = model.get(key, {})
    if not isinstance(delays, Mapping):
        raise CaseError(f"model.{key}: expected a table {{{what} = 'parameter'}}, got {delays!r}")
    for channel, parameter in delays.items():
        if not isinstance(parameter, str) or not parameter.isidentifier():
            raise CaseError(
                f"model.{key}.{channel}: expected a parameter name (the delay in s), "
                f"got {parameter!r}"
            )
    return dict(delays)


def _spec(model: Mapping[str, Any]) -> KinematicSpec:
    delays = _delay_table(model, "output_delays", "output")
    input_delays = _delay_table(model, "input_delays", "input")
    arguments = {k: model[k] for k in _ARGUMENTS if k in model}
    # the delay parameters after the sensors' (and wind's): output delays', then input delays'
    names = tuple(dict.fromkeys([*delays.values(), *input_delays.values()]))
    try:
        spec = kinematic_spec(delays=names, **arguments)
    except (InputError, InputTypeError) as exc:
        raise CaseError(f"model.{exc}") from None
    for output in delays:
        if output not in spec.outputs:
            raise CaseError(
                f"model.output_delays.{output}: not an output of the kinematic model; its "
                f"outputs: {list(spec.outputs)}"
            )
    for channel in input_delays:
        if channel not in spec.inputs:
            raise CaseError(
                f"model.input_delays.{channel}: not an input of the kinematic model; its "
                f"inputs: {list(spec.inputs)}"
            )
    return spec


def kinematic_section(model: Mapping[str, Any]) -> Mapping[str, Any]:
    """Check a ``[model]`` table with ``type = "kinematic"`` (raises ``CaseError`` naming the
    key); returns it unchanged."""
    _known(model, KINEMATIC_KEYS, "model")
    if "name" in model and not isinstance(model["name"], str):
        raise CaseError(f"model.name: expected a string, got {model['name']!r}")
    convention = model.get("delay_convention", "fractional")
    if convention not in DELAY_CONVENTIONS:
        raise CaseError(
            f"model.delay_convention: expected one of {list(DELAY_CONVENTIONS)}, got {convention!r}"
        )
    _spec(model)
    return model


def spec_from_case(case) -> KinematicSpec:
    """The ``KinematicSpec`` of a case whose ``[model]`` has ``type = "kinematic"``."""
    return _spec(case.model)


def kinematic_from_case(case) -> StateSpaceModel:
    """The kinematic model of a case (before its [parameters], initial states and biases)."""
    spec = spec_from_case(case)
    return model_from_spec(
        spec,
        name=case.model.get("name", "kinematic"),
        output_delays=dict(case.model.get("output_delays", {})) or None,
        input_delays=dict(case.model.get("input_delays", {})) or None,
        delay_convention=case.model.get("delay_convention", "fractional"),
    )
