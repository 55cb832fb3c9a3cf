"""Channel expressions: arithmetic over column references, parsed here and never passed to
``eval`` (grammar and functions: ``flightid.data.loaders``)."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from flightid.data.signals import (
    BUILTIN_SIGNALS,
    builtin_signal,
    quaternion_pitch,
    quaternion_roll,
    quaternion_yaw,
)
from flightid.data.table import (
    ChannelError,
    Table,
)
from flightid.errors import describe

# a name starts with a letter of any script (α_rec, as reconstructed-signal files name their
# columns) or _, and goes on with letters, digits, _ and dots (flight-log stream.field)
_EXPR_TOKEN = re.compile(
    r"\s*(?:(?P<number>\d+\.?\d*(?:[eE][-+]?\d+)?|\.\d+(?:[eE][-+]?\d+)?)"
    r"|(?P<column>\$\d+)|(?P<name>[^\W\d][\w.]*)|(?P<op>[-+*/(),]))"
)


def _tokens(text: str) -> list[tuple[str, str, int]]:
    tokens = []
    position = 0
    text = text.rstrip()
    while position < len(text):
        m = _EXPR_TOKEN.match(text, position)
        if not m or m.end() == position:
            raise ChannelError(
                f"expression {text!r}: unexpected character {text[position:].strip()[:1]!r} at "
                f"position {position}"
            )
        kind = m.lastgroup
        tokens.append((kind, m.group(kind), m.start(kind)))
        position = m.end()
    return tokens


# nesting of parentheses, signs and operations in an expression at most (deeper ones are
# refused: parsing and evaluating recurse once per level)
MAX_EXPRESSION_DEPTH = 100


@dataclass(frozen=True)
class _Function:
    """A whitelisted function: argument count, the numpy function, and its domain (the mask
    of arguments it refuses, with the words for the error), or None where every finite
    argument is allowed (overflow to ±inf is caught after evaluation)."""

    n_args: int
    apply: Any
    refuses: Any = None
    domain: str = ""


_FUNCTIONS = {
    "sin": _Function(1, np.sin),
    "cos": _Function(1, np.cos),
    "tan": _Function(1, np.tan),
    # asin, acos: defined on −1 ≤ x ≤ 1
    "asin": _Function(1, np.arcsin, lambda x: np.abs(x) > 1, "−1 ≤ x ≤ 1"),
    "acos": _Function(1, np.arccos, lambda x: np.abs(x) > 1, "−1 ≤ x ≤ 1"),
    "atan": _Function(1, np.arctan),
    # atan2(y, x): the angle of (x, y) in (−π, π]; atan2(0, 0) = 0 as in numpy
    "atan2": _Function(2, np.arctan2),
    # sqrt: x ≥ 0
    "sqrt": _Function(1, np.sqrt, lambda x: x < 0, "x ≥ 0"),
    "exp": _Function(1, np.exp),
    # log (natural): x > 0
    "log": _Function(1, np.log, lambda x: x <= 0, "x > 0"),
    "abs": _Function(1, np.abs),
    # ZYX Euler angles (rad) of a Hamilton quaternion (w, x, y, z), flightid.data.signals
    "quat_roll": _Function(4, quaternion_roll),
    "quat_pitch": _Function(4, quaternion_pitch),
    "quat_yaw": _Function(4, quaternion_yaw),
}


class _Parser:
    """Recursive-descent parser: expr := term (±term)*, term := unary (×÷ unary)*,
    unary := −unary | atom, atom := NUMBER | $N | NAME | NAME ( expr {, expr} ) | ( expr ).
    Builds a tree of tuples; NAME ( ... ) must be a whitelisted function with its argument
    count, ``pi`` is the constant and ``t`` the time variable."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.tokens = _tokens(text)
        self.i = 0
        self.nesting = 0  # open parentheses and unary signs, limited by MAX_EXPRESSION_DEPTH

    def nest(self, parse):
        self.nesting += 1
        if self.nesting > MAX_EXPRESSION_DEPTH:
            raise ChannelError(
                f"expression {self.text[:40]!r}...: nested deeper than {MAX_EXPRESSION_DEPTH} "
                "levels (parentheses and signs); simplify it"
            )
        tree = parse()
        self.nesting -= 1
        return tree

    def peek(self):
        return self.tokens[self.i] if self.i < len(self.tokens) else (None, None, len(self.text))

    def take(self):
        token = self.peek()
        self.i += 1
        return token

    def fail(self, what: str):
        _, value, position = self.peek()
        got = "the end" if value is None else repr(value)
        raise ChannelError(
            f"expression {self.text!r}: expected {what} at position {position}, got {got}"
        )

    def parse(self):
        if not self.tokens:
            raise ChannelError("expression: empty")
        tree = self.expr()
        if self.i != len(self.tokens):
            self.fail("an operator or the end")
        # chains such as a+a+...+a nest without recursion here, but evaluating them recurses
        if _depth(tree) > MAX_EXPRESSION_DEPTH:
            raise ChannelError(
                f"expression {self.text[:40]!r}...: more than {MAX_EXPRESSION_DEPTH} nested "
                "operations; simplify it"
            )
        return tree

    def expr(self):
        tree = self.term()
        while self.peek()[1] in ("+", "-"):
            op = self.take()[1]
            tree = (op, tree, self.term())
        return tree

    def term(self):
        tree = self.unary()
        while self.peek()[1] in ("*", "/"):
            op = self.take()[1]
            tree = (op, tree, self.unary())
        return tree

    def unary(self):
        if self.peek()[1] in ("-", "+"):
            op = self.take()[1]
            operand = self.nest(self.unary)
            return ("neg", operand) if op == "-" else operand
        return self.atom()

    def atom(self):
        kind, value, _ = self.peek()
        if kind == "number":
            self.take()
            if not np.isfinite(float(value)):
                self.i -= 1
                self.fail("a finite number")
            return ("num", float(value))
        if kind == "column":
            self.take()
            return ("col", int(value[1:]))
        if kind == "name":
            position = self.take()[2]
            if self.peek()[1] == "(":
                return self.call(value, position)
            if value == "pi":
                return ("num", math.pi)
            if value == "t":
                return ("time",)
            return ("col", value)
        if value == "(":
            self.take()
            tree = self.nest(self.expr)
            if self.peek()[1] != ")":
                self.fail("')'")
            self.take()
            return tree
        self.fail("a number, a column ($N or a name) or '('")

    def call(self, name: str, position: int):
        """NAME ( expr {, expr} ): a whitelisted function with its number of arguments."""
        function = _FUNCTIONS.get(name)
        if function is None:
            raise ChannelError(
                f"expression {self.text!r}: unknown function {name!r} at position {position}; "
                f"known: {', '.join(sorted(_FUNCTIONS))}"
            )
        self.take()  # '('
        args = []
        if self.peek()[1] != ")":
            args.append(self.nest(self.expr))
            while self.peek()[1] == ",":
                self.take()
                args.append(self.nest(self.expr))
        if self.peek()[1] != ")":
            self.fail("',' or ')'")
        self.take()
        if len(args) != function.n_args:
            raise ChannelError(
                f"expression {self.text!r}: {name}() takes {function.n_args} argument(s), "
                f"got {len(args)} (at position {position})"
            )
        return ("call", name, *args)


def _depth(tree: tuple) -> int:
    """Depth of an expression tree (iterative: the tree may be deep)."""
    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        if node[0] == "call":
            stack.extend((child, depth + 1) for child in node[2:])
        elif node[0] not in ("num", "col", "time"):
            stack.extend((child, depth + 1) for child in node[1:])
    return deepest


def parse_expression(text: str) -> tuple:
    """Parse an arithmetic expression over columns into a tree (see module docstring)."""
    if not isinstance(text, str):
        raise ChannelError(f"expression: expected a string, got {describe(text)}")
    return _Parser(text).parse()


def _lookup(name: int | str, table: Table, where: str, names: Mapping[str, Any] | None):
    """A name's values: a signal or constant of ``names`` (signals: arrays over all rows),
    else the table's column (``$N`` is always the column), else a built-in log signal
    (``px4.roll``, ... of ``flightid.data.signals``, from the table's columns)."""
    if names and isinstance(name, str) and name in names:
        return names[name]
    try:
        return table.column(name, where)
    except ChannelError as exc:
        if isinstance(name, str) and name in BUILTIN_SIGNALS and name not in table.names:
            return _builtin(name, table, where)
        if not names or not isinstance(name, str):
            raise
        raise ChannelError(f"{exc}; nor a signal or constant (known: {sorted(names)})") from None


def _builtin(name: str, table: Table, where: str) -> np.ndarray:
    """A built-in log signal from the table's columns, or a ``ChannelError`` naming the
    columns (streams) it needs."""
    try:
        values, _ = builtin_signal(name, table.names.__contains__, table.column)
    except KeyError as exc:
        raise ChannelError(
            f"{where}: the built-in signal {name!r} needs the columns {exc.args[0]}; "
            f"read those streams (variable = ...) — {table.source or 'the table'} has "
            f"{[n for n in table.names if n][:12]}"
        ) from None
    return values


def _evaluate(
    tree: tuple,
    table: Table,
    where: str,
    time: np.ndarray | None = None,
    problems: list | None = None,
    names: Mapping[str, Any] | None = None,
) -> np.ndarray | float:
    """Values of an expression tree over the table's rows. ``time``: the values of ``t`` (s)
    (None: ``t`` is the column named t, as inside the time channel itself). ``names``:
    signals (arrays over all rows) and constants (numbers) looked up before the columns.
    Arguments outside a function's domain are recorded in ``problems`` as (words, mask,
    argument) and give NaN there; the caller reports the first such row it keeps."""
    kind = tree[0]
    if kind == "num":
        return tree[1]
    if kind == "col":
        return _lookup(tree[1], table, where, names)
    if kind == "time":
        return table.column("t", where) if time is None else time
    if kind == "neg":
        return -_evaluate(tree[1], table, where, time, problems, names)
    if kind == "call":
        function = _FUNCTIONS[tree[1]]
        args = [_evaluate(sub, table, where, time, problems, names) for sub in tree[2:]]
        if function.refuses is not None:
            refused = function.refuses(np.asarray(args[0], dtype=float))
            if np.any(refused) and problems is not None:
                problems.append((f"{tree[1]}() needs {function.domain}", refused, args[0]))
        with np.errstate(all="ignore"):
            return function.apply(*args)
    left = _evaluate(tree[1], table, where, time, problems, names)
    right = _evaluate(tree[2], table, where, time, problems, names)
    if kind == "+":
        return left + right
    if kind == "-":
        return left - right
    if kind == "*":
        return left * right
    with np.errstate(divide="ignore", invalid="ignore"):
        return left / right


def expression_columns(tree: tuple) -> list:
    """Column references used by an expression tree."""
    if tree[0] == "col":
        return [tree[1]]
    if tree[0] in ("num", "time"):
        return []
    children = tree[2:] if tree[0] == "call" else tree[1:]
    return [c for sub in children for c in expression_columns(sub)]
