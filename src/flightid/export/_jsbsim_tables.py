"""Table models of a global model (``CoefficientModel.tables``) as JSBSim ``<table>``s.

A degree-1 table is a sum of hat functions: linear between its breakpoints along each
variable and held at its edge values outside them. JSBSim's ``<table>`` interpolates linearly
between its breakpoints and holds its edge values beyond them, so writing the fitted values on
their breakpoints reproduces the model exactly (up to the printed digits, which are the
shortest that read back as the same float). The tables:

* 1 variable: ``<independentVar lookup="row">`` and ``<tableData>`` with one
  "breakpoint value" line per breakpoint;
* 2 variables: row and column variables, ``<tableData>`` with the column breakpoints as its
  header line and one line per row breakpoint;
* 3 variables: row, column and table variables, one 2-D ``<tableData breakPoint="…">`` block
  per breakpoint of the third variable.

A table multiplied by a signal (``times``) becomes ``<product>`` of that signal and the table.
JSBSim looks a table up by property, so every variable a table reads is first written as a
function ``flightid/signal/<name>`` of its JSBSim expression (``SignalMap``).

Not written, with a named error: degree-3 tables (a cubic B-spline is not JSBSim's linear
interpolation; refit with degree 1) and tables with values left without data (NaN; refit
with smoothing > 0 so that every value is determined).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from flightid.export._jsbsim_terms import JSBSimExportError, SignalMap, number

__all__ = ["SIGNAL_PREFIX", "signal_functions", "table_coefficient_function", "table_signals"]

#: JSBSim property prefix of the signals tables read
SIGNAL_PREFIX = "flightid/signal/"
_LOOKUPS = ("row", "column", "table")


def check_exportable(name: str, coefficient) -> None:
    """A table model JSBSim reproduces exactly: degree-1 tables, every value determined."""
    tables = coefficient.tables
    for c, component in enumerate(tables.components):
        if component.degree != 1:
            raise JSBSimExportError(
                f"coefficient {name!r}, table {component.label!r}: degree {component.degree}; "
                "JSBSim's tables interpolate linearly, expected degree 1 (refit with degree = 1)"
            )
        if np.isnan(tables.values[c]).any():
            count = int(np.isnan(tables.values[c]).sum())
            raise JSBSimExportError(
                f"coefficient {name!r}, table {component.label!r}: {count} values have no data "
                "(NaN); expected every value determined (refit with smoothing > 0)"
            )


def table_signals(coefficient) -> list[str]:
    """The signals the tables of a coefficient read (variables and ``times``), in order."""
    names: list[str] = []
    for component in coefficient.tables.components:
        for name in (*component.variables, component.times):
            if name is not None and name not in names:
                names.append(name)
    return names


def signal_functions(names, signals: SignalMap, coefficient: str) -> list[ET.Element]:
    """``<function name="flightid/signal/<name>">`` = the JSBSim expression of each signal."""
    out = []
    for name in names:
        try:
            expression = signals.expression(name)
        except KeyError:
            raise JSBSimExportError(
                f"coefficient {coefficient!r}: the table signal {name!r} has no JSBSim "
                f"counterpart; map a control with controls={{{name!r}: 'fcs/…-pos-rad'}}"
            ) from None
        function = ET.Element("function", name=SIGNAL_PREFIX + name)
        ET.SubElement(function, "description").text = f"flightid signal {name}"
        function.append(expression)
        out.append(function)
    return out


def _rows(values: np.ndarray, rows: np.ndarray, columns: np.ndarray | None) -> str:
    """The text of one ``<tableData>``: 1-D "b v" lines, or a 2-D block with a header."""
    if columns is None:
        return "\n".join(f"{number(b)} {number(v)}" for b, v in zip(rows, values, strict=True))
    lines = [" ".join(number(c) for c in columns)]
    for b, line in zip(rows, values, strict=True):
        lines.append(" ".join([number(b), *(number(v) for v in line)]))
    return "\n".join(lines)


def _table(component, values: np.ndarray) -> ET.Element:
    """The ``<table>`` of one component's values on its breakpoints."""
    table = ET.Element("table")
    for variable, lookup in zip(component.variables, _LOOKUPS, strict=False):
        ET.SubElement(table, "independentVar", lookup=lookup).text = SIGNAL_PREFIX + variable
    points = [component.breakpoints[v] for v in component.variables]
    if len(points) == 1:
        ET.SubElement(table, "tableData").text = _rows(values, points[0], None)
    elif len(points) == 2:
        ET.SubElement(table, "tableData").text = _rows(values, points[0], points[1])
    else:
        for k, breakpoint in enumerate(points[2]):
            block = ET.SubElement(table, "tableData", breakPoint=number(breakpoint))
            block.text = _rows(values[:, :, k], points[0], points[1])
    return table


def table_coefficient_function(name: str, coefficient) -> ET.Element:
    """``<function name="flightid/coefficient/<name>">`` = Σ_c s_c · table_c (+ 0)."""
    function = ET.Element("function", name=f"flightid/coefficient/{name}")
    labels = " + ".join(f"table({c.label})" for c in coefficient.tables.components)
    ET.SubElement(function, "description").text = f"{name} = {labels}"
    total = ET.SubElement(function, "sum")
    for component, values in zip(
        coefficient.tables.components, coefficient.tables.values, strict=True
    ):
        table = _table(component, np.asarray(values, dtype=float))
        if component.times is None:
            total.append(table)
        else:
            product = ET.SubElement(total, "product")
            ET.SubElement(product, "property").text = SIGNAL_PREFIX + component.times
            product.append(table)
    ET.SubElement(total, "value").text = "0.0"
    return function
