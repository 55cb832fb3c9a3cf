"""Functions, the constant pi and the time variable t in channel expressions (safe parser)."""

from __future__ import annotations

import numpy as np
import pytest

from flightid.data.loaders import (
    MAX_EXPRESSION_DEPTH,
    ChannelError,
    ChannelSpec,
    Table,
    parse_expression,
    to_flight_data,
)

RNG = np.random.default_rng(20261123)
N = 50
T = 10.0 + 0.05 * np.arange(N)  # s, the time column (does not start at 0)
X = RNG.uniform(-0.9, 0.9, N)  # inside (−1, 1): every function is defined
Y = RNG.uniform(0.1, 3.0, N)  # positive


def _table(x: np.ndarray = X, y: np.ndarray = Y) -> Table:
    data = np.column_stack([T, x, y])
    return Table(data, names=("time", "x", "y"), units=("s", "", ""), source="test table")


def _values(expr: str, table: Table | None = None, **kwargs) -> np.ndarray:
    data = to_flight_data(table or _table(), time=1, outputs={"z": {"expr": expr}}, **kwargs)
    return data.output("z")


# independent source for each value: numpy's own function applied to the same columns
@pytest.mark.parametrize(
    ("expr", "expected"),
    [
        ("sin($2)", np.sin(X)),
        ("cos(x)", np.cos(X)),
        ("tan($2)", np.tan(X)),
        ("asin(x)", np.arcsin(X)),
        ("acos(x)", np.arccos(X)),
        ("atan(x)", np.arctan(X)),
        ("atan2(x, y)", np.arctan2(X, Y)),
        ("atan2(-y, x)", np.arctan2(-Y, X)),
        ("sqrt(y)", np.sqrt(Y)),
        ("exp(x)", np.exp(X)),
        ("log(y)", np.log(Y)),
        ("abs(x)", np.abs(X)),
        ("pi", np.full(N, np.pi)),
        ("x * 180 / pi", X * 180 / np.pi),
        ("t", T),
        ("t - 10", T - 10),
        ("sin(2 * pi * 0.5 * t)", np.sin(2 * np.pi * 0.5 * T)),
    ],
)
def test_each_function_against_numpy(expr, expected):
    assert np.allclose(_values(expr), expected, rtol=1e-13, atol=1e-13)


def test_nesting_and_precedence():
    got = _values("sqrt(abs(sin(x) * cos(y))) + -log(exp(2 * y)) / 2 + atan2(sin(x), cos(x))")
    # atan2(sin x, cos x) = x for |x| < π; log(exp(2y))/2 = y
    expected = np.sqrt(np.abs(np.sin(X) * np.cos(Y))) - Y + X
    assert np.allclose(got, expected, rtol=1e-12, atol=1e-12)
    assert parse_expression("sin($1)") == ("call", "sin", ("col", 1))
    assert parse_expression("atan2($1, 2*t)") == (
        "call",
        "atan2",
        ("col", 1),
        ("*", ("num", 2.0), ("time",)),
    )


def test_time_variable_follows_start_stop():
    data = to_flight_data(_table(), time=1, outputs={"z": {"expr": "t + 0*x"}}, start=11.0)
    assert np.allclose(data.output("z"), data.time)
    assert data.output("z")[0] == pytest.approx(11.0)


def test_time_channel_itself_reads_the_column_named_t():
    data_ms = np.column_stack([1000 * T, X])
    table = Table(data_ms, names=("t", "x"), units=("ms", ""), source="ms table")
    data = to_flight_data(table, time={"expr": "t / 1000"}, outputs={"x": "x"})
    assert np.allclose(data.time, T)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("sinh($2)", "unknown function 'sinh'"),
        ("eval($2)", "unknown function 'eval'"),
        ("__import__($2)", "unknown function '__import__'"),
        ("x.__class__($2)", "unknown function"),
        ("sin()", r"sin\(\) takes 1 argument\(s\), got 0"),
        ("sin($2, $3)", r"sin\(\) takes 1 argument\(s\), got 2"),
        ("atan2($2)", r"atan2\(\) takes 2 argument\(s\), got 1"),
        ("atan2($2, $3, $1)", r"atan2\(\) takes 2 argument\(s\), got 3"),
        ("sin($2", "expected ',' or '\\)'"),
        ("$2, $3", "expected an operator or the end"),
        ("sin(,)", "expected a number"),
    ],
)
def test_bad_calls_are_named_errors(text, message):
    with pytest.raises(ChannelError, match=message):
        parse_expression(text)


def test_spec_refuses_bad_calls_early():
    with pytest.raises(ChannelError, match="unknown function 'system'"):
        ChannelSpec.from_value({"expr": "system($1)"}, "outputs.z")


def test_deep_nesting_of_calls_is_refused():
    text = "sin(" * (MAX_EXPRESSION_DEPTH + 1) + "$1" + ")" * (MAX_EXPRESSION_DEPTH + 1)
    with pytest.raises(ChannelError, match="nested deeper"):
        parse_expression(text)
    ok = "sin(" * 20 + "x" + ")" * 20
    expected = X
    for _ in range(20):
        expected = np.sin(expected)
    assert np.allclose(_values(ok), expected)


@pytest.mark.parametrize(
    ("expr", "row", "words"),
    [
        ("sqrt(x)", None, r"sqrt\(\) needs x ≥ 0"),
        ("log(x - x)", 1, r"log\(\) needs x > 0, got 0 at row 1"),
        ("log(x)", None, r"log\(\) needs x > 0"),
        ("asin(2 * x)", None, r"asin\(\) needs −1 ≤ x ≤ 1"),
        ("acos(x - 1.5)", 1, r"acos\(\) needs −1 ≤ x ≤ 1"),
    ],
)
def test_domain_errors_name_channel_and_first_row(expr, row, words):
    if row is None:
        # the first row where the argument leaves the domain, computed independently
        argument = {"sqrt(x)": X, "log(x)": X, "asin(2 * x)": 2 * X}[expr]
        bad = (argument <= 0) if expr.startswith("log") else (argument < 0)
        if expr.startswith("asin"):
            bad = np.abs(argument) > 1
        row = int(np.argmax(bad)) + 1
    with pytest.raises(ChannelError, match=words) as info:
        _values(expr)
    assert "outputs.z" in str(info.value)
    assert f"at row {row} of test table" in str(info.value)


def test_domain_error_outside_the_kept_rows_is_no_error():
    x = np.where(T < 11.0, -1.0, 1.0)  # negative only before t = 11 s
    got = _values("sqrt(x)", _table(x=x), start=11.0)
    assert np.allclose(got, 1.0)
    with pytest.raises(ChannelError, match="at row 1 of"):
        _values("sqrt(x)", _table(x=x))


def test_overflow_is_named_not_silent():
    with pytest.raises(ChannelError, match="non-finite value"):
        _values("exp(1000 * y)")
