"""Write a global aerodynamic model (``flightid.globalmodel.GlobalModel``) as a JSBSim
aircraft, so that the identified envelope can be flown.

Each coefficient of a global model is a polynomial in the term language
(``flightid.model.terms``: products of powers of the variables, splines ``(x − k)₊``), so the
model goes through the writer of identified airplane models (``flightid.export.jsbsim``):
``model.aero_model()`` with ``model.parameter_values()`` become the functions
``flightid/coefficient/<C>`` of ``aerodynamics/nominal.xml``, summed into the six JSBSim axes
with the airplane's S, b, c̄ and q̄. The aircraft folder is that of ``write_jsbsim`` (its
docstring): ``NAME.xml``, ``aerodynamics/nominal.xml`` (and ``draw_0001.xml`` … with
``draws``), ``planet_flat.xml``, ``export.json``.

Axes. The coefficients are those of flightid's airplane models (RP-1153 2.14–2.15):

* C_L, C_D: lift and drag in stability axes (the body axes turned by α about y, no β):
  X = q̄ S (C_L sin α − C_D cos α), Z = q̄ S (−C_L cos α − C_D sin α);
* C_X, C_Z (if modelled instead): body axes;
* C_Y: body-axis side force, Y = q̄ S C_Y;
* C_l, C_m, C_n: body-axis moments about the c.g. (JSBSim's AERORP is put at the c.g.),
  L = q̄ S b C_l, M = q̄ S c̄ C_m, N = q̄ S b C_n.

Coefficients measured in wind axes (the stability axes turned by β about z) have the same
C_L; drag and side force are turned: with C_D,w the drag along −x_w and C_Y,w the side force
along y_w,

    C_D = C_D,w cos β + C_Y,w sin β,    C_Y = −C_D,w sin β + C_Y,w cos β,

which the data must be given as before fitting.

Variables. Each variable of the model becomes the JSBSim expression of its signal
(``_jsbsim_terms.SignalMap``): alpha, beta (aero/alpha-rad, aero/beta-rad), Mach
(velocities/mach), p, q, r, the non-dimensional rates phat = p b/2V, qhat = q c̄/2V,
rhat = r b/2V (V the true airspeed), theta, phi, V, u, v, w, the controls (``controls``:
de, da, dr by default, in rad) and Vrel, dVrel (with ``reference_speed``). A variable with
a declared unit (``Normalisation.units``) must be in the unit of its expression (rad, rad/s,
m/s, non-dimensional "1"); a variable in degrees, say, is refused rather than written
wrongly. A variable without a declared unit is taken to be in that unit (``export.json``
lists it as ``jsbsim_unit``).

Support. ``export.json`` gains an entry ``global_model``: the variables with the data's
low/high (the box the model was fitted on) and the JSBSim expression each reads, the axis
convention and the note that the polynomial is evaluated as written everywhere: outside the
data's support it extrapolates, and JSBSim does not flag it (``GlobalModel.predict(points)``
says where a point is outside; the box itself has empty corners the data never visited).

    model = load_global_model("run/global_model.json")
    aircraft = write_jsbsim_global(model, airplane_from_table({"library": "navion"}),
                                   "out/Envelope", controls={"de": "fcs/elevator-pos-rad"})
    flown = fly_jsbsim(aircraft, t, {"de": de, "da": da, "dr": dr}, {"u": 60.0})

Table models. A coefficient fitted with ``method = "table"`` is written as JSBSim
``<table>`` functions (``_jsbsim_tables``): 1-D, 2-D and 3-D tables of the fitted values on
their breakpoints, a ``times`` signal as a product; JSBSim interpolates linearly and holds
the edge values, as the degree-1 model does, so the round trip is exact. Degree-3 tables and
tables with values left without data are refused (``JSBSimExportError``), and so are
``draws`` for a model with tables (the draws perturb polynomial parameters only).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from flightid.errors import InputTypeError, describe
from flightid.export._jsbsim_terms import DEFAULT_CONTROLS, FT_M, JSBSimExportError, SignalMap
from flightid.export.jsbsim import JSBSimAircraft, _check_airplane, write_aircraft

__all__ = ["AXES_NOTE", "EXTRAPOLATION_NOTE", "RANGE_FLAG_PROPERTY", "write_jsbsim_global"]

AXES_NOTE = (
    "CL, CD: stability axes (body axes turned by alpha, no beta): X = qbar S (CL sin alpha - "
    "CD cos alpha), Z = qbar S (-CL cos alpha - CD sin alpha); CX, CZ, CY: body axes; Cl, Cm, "
    "Cn: body-axis moments about the c.g. (AERORP at the c.g.)"
)
EXTRAPOLATION_NOTE = (
    "the coefficients are evaluated at every state: outside the data support (the box "
    "low..high of each variable, and empty regions inside it) a polynomial coefficient "
    "extrapolates and a table coefficient holds its edge values, and JSBSim does not flag it"
)
# the unit of each signal's JSBSim expression (flightid's signal units); "1": none
_RADIAN_SIGNALS = ("alpha", "beta", "theta", "phi")
_RATE_SIGNALS = ("p", "q", "r")
_SPEED_SIGNALS = ("V", "u", "v", "w")
_DIMENSIONLESS = {"", "-", "1"}


def _expected_unit(signal: str, controls: Mapping[str, str], thrust_input) -> str | None:
    """The unit the JSBSim expression of ``signal`` delivers ("1": non-dimensional), None
    for a signal without one (refused later by ``SignalMap``)."""
    if signal in _RADIAN_SIGNALS or signal in controls:
        return "rad"
    if signal in _RATE_SIGNALS:
        return "rad/s"
    if signal in _SPEED_SIGNALS:
        return "m/s"
    if signal == thrust_input:
        return "N"
    if signal in ("Mach", "phat", "qhat", "rhat", "Vrel", "dVrel", "alphadot_hat", "betadot_hat"):
        return "1"
    return None


def _unit_matches(unit: str, expected: str) -> bool:
    """A declared unit equal to the expected one (``flightid.data.units.same_unit``)."""
    from flightid.data.units import UnitError, parse_unit, same_unit

    try:
        if expected == "1":
            factor, dimension = parse_unit(unit)
            return abs(factor - 1.0) <= 1e-12 and not any(dimension)
        return same_unit(unit, expected)
    except UnitError:
        return False


def _check_units(model, signals: tuple[str, ...], controls, thrust_input) -> None:
    """Every variable the terms use, with a declared unit, is in its expression's unit."""
    norm = model.normalisation
    declared = dict(zip(norm.names, norm.units, strict=True))
    wrong = []
    for signal in signals:
        unit = declared.get(signal, "")
        expected = _expected_unit(signal, controls, thrust_input)
        if unit in _DIMENSIONLESS and expected in (None, "1"):
            continue
        if expected is not None and unit and not _unit_matches(unit, expected):
            wrong.append(f"{signal} in {unit!r} (JSBSim gives {expected!r})")
    if wrong:
        raise JSBSimExportError(
            "model: variables in units other than those the JSBSim aircraft delivers: "
            f"{', '.join(wrong)}; fit the model on the variables in those units"
        )


def _term_aero(model):
    """The ``AeroModel`` the aircraft writer takes: the term coefficients' terms, and for
    each table coefficient a constant placeholder ``<C>_tables`` (value 0) whose function is
    replaced by the tables after writing."""
    from flightid.aircraft.aero import AeroModel

    return AeroModel(
        {
            name: {f"{name}_tables": "1"}
            if c.tables is not None
            else dict(zip(c.parameters, c.terms, strict=True))
            for name, c in model.coefficients.items()
        }
    )


def _edit_aerodynamics(path: Path, edit) -> None:
    """Rewrite the aerodynamics file ``path`` with ``edit(root)`` applied to its XML tree
    (comments kept)."""
    import xml.etree.ElementTree as ET

    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
    root = ET.parse(path, parser).getroot()
    edit(root)
    ET.indent(root)
    text = ET.tostring(root, encoding="unicode")
    header = '<?xml version="1.0"?>\n<!-- flightid: identified aerodynamics (nominal values) -->\n'
    path.write_text(header + text + "\n", encoding="utf-8")


def _write_tables(model, nominal: Path, signals: SignalMap) -> None:
    """Replace each table coefficient's placeholder function in ``nominal`` (the written
    aerodynamics file) by its tables, preceded by the signal functions the tables read."""
    _edit_aerodynamics(nominal, lambda root: _insert_tables(model, root, signals))


def _insert_tables(model, root, signals: SignalMap) -> None:
    from flightid.export._jsbsim_tables import (
        signal_functions,
        table_coefficient_function,
        table_signals,
    )

    written: list[str] = []
    first = None
    for name, coefficient in model.coefficients.items():
        if coefficient.tables is None:
            continue
        wanted = f"flightid/coefficient/{name}"
        index, old = next(
            (k, e) for k, e in enumerate(root) if e.tag == "function" and e.get("name") == wanted
        )
        first = index if first is None else min(first, index)
        root.remove(old)
        root.insert(index, table_coefficient_function(name, coefficient))
        fresh = [s for s in table_signals(coefficient) if s not in written]
        for k, function in enumerate(signal_functions(fresh, signals, name)):
            root.insert(first + k, function)
        first += len(fresh)
        written += fresh


def _estimate(model) -> SimpleNamespace:
    """The values and the block-diagonal covariance of every coefficient's θ̂ (the form
    ``write_jsbsim`` takes from an ``Estimate``): coefficients are fitted separately, so
    their estimates are uncorrelated with each other."""
    names, values, blocks = [], [], []
    for name, coefficient in model.coefficients.items():
        if coefficient.tables is not None:
            # the placeholder of the table functions (``_term_aero``)
            names.append(f"{name}_tables")
            values.append(0.0)
            blocks.append(np.zeros((1, 1)))
            continue
        names.extend(coefficient.parameters)
        values.extend(np.asarray(coefficient.estimates, dtype=float))
        blocks.append(np.asarray(coefficient.covariance, dtype=float))
    covariance = np.zeros((len(names), len(names)))
    start = 0
    for block in blocks:
        stop = start + block.shape[0]
        covariance[start:stop, start:stop] = block
        start = stop
    return SimpleNamespace(
        names=tuple(names),
        values=np.array(values, dtype=float),
        free=(True,) * len(names),
        covariance=covariance,
    )


def _support_summary(model, signals: SignalMap) -> dict:
    """The entries of export.json a global model adds: ``values`` (every parameter of the
    model) and ``global_model`` (variables with the data's box and the JSBSim expression
    each reads, coefficients with their terms, axes, the extrapolation note, the range
    flag's property)."""
    import xml.etree.ElementTree as ET

    norm = model.normalisation
    variables = []
    for k, name in enumerate(norm.names):
        try:
            expression = ET.tostring(signals.expression(name), encoding="unicode")
        except (KeyError, JSBSimExportError):
            expression = None  # a variable no selected term uses may have none
        variables.append(
            {
                "name": name,
                "unit": norm.units[k],
                "low": float(norm.low[k]),
                "high": float(norm.high[k]),
                "jsbsim": expression,
                "jsbsim_unit": _expected_unit(name, signals.controls, signals.thrust_input),
            }
        )
    return {
        # the model's own parameters (a table coefficient's are its table values), in place
        # of the writer's list, which holds the tables' placeholders
        "values": model.parameter_values(),
        "global_model": {
            "variables": variables,
            "coefficients": {
                name: dict(zip(c.parameters, c.terms, strict=True))
                for name, c in model.coefficients.items()
            },
            "maneuvers": len(model.sources),
            "axes": AXES_NOTE,
            "extrapolation": EXTRAPOLATION_NOTE,
            "range_flag_property": RANGE_FLAG_PROPERTY,
        },
    }


def _check_model(model) -> None:
    from flightid.aircraft.aero import COEFFICIENTS
    from flightid.globalmodel.model import GlobalModel

    if not isinstance(model, GlobalModel):
        raise InputTypeError(f"model: expected a GlobalModel, got {describe(model)}")
    unknown = [c for c in model.coefficients if c not in COEFFICIENTS]
    if unknown:
        raise JSBSimExportError(
            f"model: the coefficients {unknown} have no JSBSim axis; expected names from "
            f"{list(COEFFICIENTS)}"
        )
    if not model.coefficients:
        raise JSBSimExportError("model: expected at least one coefficient, got none")
    from flightid.export._jsbsim_tables import check_exportable

    for name, coefficient in model.coefficients.items():
        if coefficient.tables is not None:
            check_exportable(name, coefficient)


def write_jsbsim_global(
    model,
    airplane,
    path_dir: str | Path,
    *,
    controls: Mapping[str, str] | None = None,
    dynamic_pressure: str = "atmosphere",
    reference_speed: float | None = None,
    draws: int = 0,
    seed: int | None = 0,
    overwrite: bool = False,
) -> JSBSimAircraft:
    """Write the global model as a JSBSim aircraft folder (module docstring).

    Args:
        model: the ``GlobalModel`` (coefficients named CL, CD, CY, Cl, Cm, Cn, or CX, CZ).
        airplane: the ``flightid.aircraft.Airplane`` (SI units): S, b, c̄, mass, inertia.
        path_dir: the aircraft folder to create; its name is the aircraft name.
        controls: variable name → JSBSim property (rad), added to / replacing
            de, da, dr → fcs/elevator-pos-rad, fcs/left-aileron-pos-rad, fcs/rudder-pos-rad.
        dynamic_pressure: "atmosphere" (JSBSim's q̄) or "airplane" (½ ρ V², the
            airplane's ρ).
        reference_speed: V0, m/s, for Vrel and dVrel terms.
        draws: K ≥ 0 draws of θ̂ from each coefficient's default covariance
            (``aerodynamics/draw_0001.xml`` …).
        seed: seed of the draws.
        overwrite: write into an existing non-empty folder.

    Returns:
        ``JSBSimAircraft``: the files written and the values.

    Raises:
        JSBSimExportError: a coefficient with no JSBSim axis, a variable with no JSBSim
            counterpart or in another unit, bad options, or a non-empty folder.
    """
    _check_model(model)
    _check_airplane(airplane)
    if controls is not None and not isinstance(controls, Mapping):
        raise InputTypeError(
            f"controls: expected a mapping {{variable: JSBSim property}}, got {describe(controls)}"
        )
    tabled = [name for name, c in model.coefficients.items() if c.tables is not None]
    if tabled and draws:
        raise JSBSimExportError(
            f"draws: expected 0 for a model with tables ({tabled}), got {draws!r}; the draws "
            "perturb polynomial parameters only"
        )
    aero = _term_aero(model) if tabled else model.aero_model()
    mapping = {**DEFAULT_CONTROLS, **dict(controls or {})}
    from flightid.export._jsbsim_tables import table_signals

    used = list(aero.signals) + [
        s for name in tabled for s in table_signals(model.coefficients[name])
    ]
    _check_units(model, tuple(dict.fromkeys(used)), mapping, airplane.thrust_input)
    span_ft = None if airplane.b is None else airplane.b / FT_M
    signals = SignalMap(
        span_ft, airplane.cbar / FT_M, reference_speed, "V", mapping, airplane.thrust_input
    )
    notes = (f"global model: {EXTRAPOLATION_NOTE}", f"axes: {AXES_NOTE}")
    result = write_aircraft(
        _estimate(model),
        airplane,
        path_dir,
        aero=aero,
        draws=draws,
        seed=seed,
        reference_speed=reference_speed,
        rate_speed="V",
        controls=controls,
        dynamic_pressure=dynamic_pressure,
        overwrite=overwrite,
        notes=notes,
        summary=_support_summary(model, signals),
    )
    if tabled:
        _write_tables(model, result.aerodynamics_files[0], signals)
    flag = _range_flag(model, signals)
    if flag is not None:
        for path in result.aerodynamics_files:
            _edit_aerodynamics(path, lambda root: root.insert(0, _range_flag(model, signals)))
    return result


# the property of the exported aircraft that says whether its state is outside the data's range
RANGE_FLAG_PROPERTY = "flightid/support/outside-range"


def _range_flag(model, signals: SignalMap):
    """The function ``RANGE_FLAG_PROPERTY`` (an XML element): 1 while any variable the
    aircraft can compute lies outside the data's range by more than the support margin (the
    range test of ``flightid.globalmodel.support``; the distance and leverage tests need the
    data and are not exported), else 0. None when JSBSim computes none of the variables."""
    import xml.etree.ElementTree as ET

    norm = model.normalisation
    margin = min(c.settings.support_margin for c in model.coefficients.values())
    tests = []
    for k, name in enumerate(norm.names):
        # allowed excess: margin · (high − low)
        allowance = margin * (float(norm.high[k]) - float(norm.low[k]))
        for tag, bound in (("lt", norm.low[k] - allowance), ("gt", norm.high[k] + allowance)):
            try:
                expression = signals.expression(name)
            except (KeyError, JSBSimExportError):
                break  # a variable JSBSim does not compute: no test
            test = ET.Element(tag)
            test.append(expression)
            ET.SubElement(test, "value").text = repr(float(bound))
            tests.append(test)
    if not tests:
        return None
    function = ET.Element("function", name=RANGE_FLAG_PROPERTY)
    ET.SubElement(
        function, "description"
    ).text = "1 while a variable of the global model is outside the range of its data (flightid)"
    ET.SubElement(function, "or").extend(tests)
    return function
