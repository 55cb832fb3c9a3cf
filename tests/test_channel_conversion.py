"""Channel specifications with scale, offset and unit together.

The documented rule (flightid.data.loaders): value = (source · scale + offset) · unit factor,
scale and offset in the source unit, then ``subtract``. Written because a mutant applying the
unit factor before scale and offset survived the suite (issue 10 §6): every earlier test used
the default scale 1 and offset 0 whenever a unit was converted, where the two orders agree.
Unit factors are exact definitions: 1° = π/180 rad; 1 ft = 0.3048 m (international foot).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from flightid.data.loaders import ChannelSpec, Table, to_flight_data

RAW = np.array([-2.0, 0.5, 1.0, 4.0, 10.0])  # the file's numbers, source unit


def _table() -> Table:
    t = np.arange(RAW.size) * 0.1
    return Table(
        data=np.column_stack([t, RAW, 3.0 * RAW]),
        names=("t", "elevator", "height"),
        units=("s", "deg", "ft"),
        source="test table",
    )


@pytest.mark.parametrize(
    ("spec", "expected"),
    [
        # δe in degrees with a calibration 1.5·raw − 0.4 (deg), delivered in rad
        (
            {"column": "elevator", "scale": 1.5, "offset": -0.4, "unit": "deg", "to": "rad"},
            (1.5 * RAW - 0.4) * math.pi / 180.0,
        ),
        # expression, then scale and offset, then ft → m
        (
            {"expr": "$3 / 3", "scale": 2.0, "offset": 100.0, "unit": "ft", "to": "m"},
            (2.0 * RAW + 100.0) * 0.3048,
        ),
        # subtract comes last: Δ about the first converted sample
        (
            {"column": 2, "scale": -1.0, "offset": 5.0, "unit": "deg", "to": "rad",
             "subtract": "first"},
            ((-RAW + 5.0) - (-RAW[0] + 5.0)) * math.pi / 180.0,
        ),
    ],
)  # fmt: skip
def test_scale_and_offset_apply_in_the_source_unit_before_conversion(spec, expected):
    table = _table()
    values = ChannelSpec.from_value(spec, "inputs.x").evaluate(table, "inputs.x")
    np.testing.assert_allclose(values, expected, rtol=1e-14, atol=1e-15)
    # the other order, (source · factor) · scale + offset, is a different number here
    if spec.get("subtract") is None:
        factor = math.pi / 180.0 if spec["unit"] == "deg" else 0.3048
        source = RAW
        wrong = source * factor * spec["scale"] + spec["offset"]
        assert np.max(np.abs(wrong - expected)) > 0.1 * np.max(np.abs(expected))


def test_to_flight_data_delivers_the_converted_channel():
    data = to_flight_data(
        _table(),
        time="t",
        inputs={"de": {"column": "elevator", "scale": 1.5, "offset": -0.4, "unit": "deg",
                       "to": "rad"}},
        outputs={"h": {"column": "height", "scale": 0.5, "offset": 10.0, "unit": "ft",
                       "to": "m"}},
    )  # fmt: skip
    np.testing.assert_allclose(data.input("de"), (1.5 * RAW - 0.4) * math.pi / 180.0, rtol=1e-14)
    np.testing.assert_allclose(data.output("h"), (1.5 * RAW + 10.0) * 0.3048, rtol=1e-14)
