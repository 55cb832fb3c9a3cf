"""Numbers printed with the digits their σ supports (flightid.numbers); expectations by hand."""

import math

import pytest

from flightid.numbers import (
    format_at_sigma,
    format_interval,
    format_sigma,
    format_with_sigma,
    sigma_decimal_place,
)


@pytest.mark.parametrize(
    ("value", "sigma", "expected"),
    [
        # σ = 0.00033: last significant digit at 10⁻⁵, the value to the same place
        (4.00022, 0.00033, ("4.00022", "0.00033")),
        # σ rounds up into the next decade: 0.000996 → 0.0010, the value to 10⁻⁴
        (4.00022, 0.000996, ("4.0002", "0.0010")),
        (-123.456, 0.0456, ("-123.456", "0.046")),
        (0.0123456, 0.00021, ("0.01235", "0.00021")),
        # a large σ rounds the value to its tens or hundreds
        (56789.0, 1234.0, ("56800", "1200")),
        # very large and very small numbers: scientific, the mantissa cut at σ's place
        (12345678.0, 3400.0, ("1.23457e+07", "3400")),
        (1.234e-7, 5.6e-9, ("1.234e-07", "5.6e-09")),
        (2.5e-5, 1.1e-6, ("2.50e-05", "1.1e-06")),
        # a value smaller than σ's last digit is zero at that place
        (0.0004, 0.01, ("0.000", "0.010")),
        # σ with no scale: the value to six significant digits
        (4.000221234, 0.0, ("4.00022", "0")),
        (4.000221234, float("nan"), ("4.00022", "—")),
        (4.000221234, float("inf"), ("4.00022", "inf")),
        (float("nan"), 0.1, ("nan", "0.10")),
        (float("-inf"), 0.1, ("-inf", "0.10")),
    ],
)
def test_format_with_sigma_by_hand(value, sigma, expected):
    assert format_with_sigma(value, sigma) == expected


def test_interval_of_the_issue_shows_the_digits_sigma_supports():
    # 4.00022 ± 0.00033 at 95 %: ± 1.96·0.00033 = ± 0.000647 → [3.999573, 4.000867]
    half = 1.96 * 0.00033
    text = format_interval(4.00022 - half, 4.00022 + half, 0.00033)
    assert text == "[3.99957, 4.00087]"
    # open sides stay open
    assert format_interval(-math.inf, 5.0, 0.1) == "[-inf, 5.00]"


def test_sigma_decimal_place_and_missing_sigma():
    assert sigma_decimal_place(0.00033) == -5
    assert sigma_decimal_place(0.000996) == -4
    assert sigma_decimal_place(1234.0) == 2
    assert sigma_decimal_place(0.0) is None
    assert sigma_decimal_place(float("nan")) is None
    assert format_sigma(None) == "—"
    assert format_sigma(float("nan"), missing="-") == "-"
    assert format_at_sigma(None, 0.1) == "—"
    # rounding carries across the fixed/scientific border: σ's place is kept
    assert format_at_sigma(999999.997, 0.5) == "1.00000000e+06"
    assert format_at_sigma(-9.99999e-5, 1e-7) == "-0.00010000"
