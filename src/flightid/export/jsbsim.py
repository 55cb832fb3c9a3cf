"""Write an identified airplane model as a JSBSim aircraft (folder JSBSim's ``load_model``
reads), with optional parameter draws from the covariance as alternative aerodynamics.

The folder ``path_dir`` (its name is the aircraft's name, as JSBSim requires) holds

* ``NAME.xml``: the aircraft. ``<metrics>``: wing area S, span b (c̄ for a
  longitudinal-only airplane), chord c̄, and the aerodynamic reference point, the eye point
  and the visual reference point all at the centre of gravity (flightid's moments are about
  the c.g.). ``<mass_balance>``: mass, I_x, I_y, I_z, I_xz (I_xz = ∫ x z dm, written with
  ``negated_crossproduct_inertia="false"``; a longitudinal-only airplane gets I_x = I_z = I_y
  as the flightid models do), c.g. at the origin. ``<ground_reactions>``: three stiff
  contacts below the c.g. for parking only (no landing-gear model). No ``<propulsion>``: the
  airplane's thrust (``Airplane.thrust_input``) is the property ``flightid/thrust-lbs``
  (T in lbf, to be set by the user each step), acting along the airplane's thrust line as in
  flightid: X += T cos σ_T, Z −= T sin σ_T, M += l_T T. ``<aerodynamics
  file="aerodynamics/nominal"/>``: the identified model.
* ``aerodynamics/nominal.xml``: the coefficients as JSBSim functions
  ``flightid/coefficient/<C>`` (C_X, C_Y, C_Z, C_D, C_L, C_l, C_m, C_n: the sums of
  parameter × term, ``_jsbsim_terms``), then the body-axis forces and moments (axes X, Y, Z,
  ROLL, PITCH, YAW; RP-1153 2.14–2.15):

      X = q̄ S (C_X + C_L sin α − C_D cos α),   Y = q̄ S C_Y,
      Z = q̄ S (C_Z − C_L cos α − C_D sin α),
      L = q̄ S b C_l,   M = q̄ S c̄ C_m,   N = q̄ S b C_n

  with q̄ = aero/qbar-psf (JSBSim's atmosphere, ``dynamic_pressure="atmosphere"``) or
  q̄ = ½ ρ V² with the airplane's constant ρ (``dynamic_pressure="airplane"``, the equations
  flightid integrates).
* ``aerodynamics/draw_0001.xml`` …: the same with parameter draws (``draws=K``), and
  ``draws.json`` with the drawn values; fly a draw by pointing the aircraft's
  ``<aerodynamics file=…>`` at it.
* ``planet_flat.xml``: a spherical planet, 1000 times the earth's radius, that does not
  rotate, with the airplane's g at sea level (GM = g R²); loaded with
  ``FGFDMExec.load_planet(path, False)`` and ``simulation/gravity-model = 0`` it makes
  JSBSim's equations those flightid integrates
  (no Coriolis or centrifugal terms, g constant to 3e-7 below 1000 m).
* ``export.json``: what was written, the parameter values, the control mapping and the
  approximation rules used.

Refused (``JSBSimExportError``): terms in signals with no JSBSim counterpart
(``_jsbsim_terms``), an engine angular momentum or propeller torque (not written), an
existing non-empty folder unless ``overwrite``. Approximated by a named rule: α̇ and β̇ terms
(``ALPHADOT_RULE``, ``BETADOT_RULE``). Axes the model has no coefficient for (a decoupled
lateral or longitudinal model) are listed (``unmodelled_axes``, a header note): JSBSim sees
no aerodynamic load on them.

``fly_jsbsim`` (``_jsbsim_fly``) flies the folder in JSBSim with recorded inputs.

From a case run of a built-in airplane model (``[model] type`` lateral, longitudinal,
six_dof or wind_axis_longitudinal; a user module or the α–q model has no aerodynamic model
to export)::

    spec = run.case.model
    write_jsbsim(run.estimate, airplane_from_table(spec["airplane"]), "out/HFB320",
                 aero=AeroModel(spec["aero"]), reference_speed=spec.get("reference_speed"),
                 rate_speed=spec.get("rate_speed", "V"), draws=20, seed=1)
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flightid.errors import InputTypeError, describe
from flightid.export._jsbsim_fly import fly_jsbsim, initial_from_body_state
from flightid.export._jsbsim_terms import (
    ALPHADOT_RULE,
    BETADOT_RULE,
    DEFAULT_CONTROLS,
    FT_M,
    LBF_N,
    THRUST_PROPERTY,
    JSBSimExportError,
    SignalMap,
    number,
)

__all__ = [
    "ALPHADOT_RULE",
    "BETADOT_RULE",
    "DEFAULT_CONTROLS",
    "THRUST_PROPERTY",
    "JSBSimAircraft",
    "JSBSimExportError",
    "fly_jsbsim",
    "initial_from_body_state",
    "write_jsbsim",
]

SLUG_KG = LBF_N / FT_M  # kg per slug
SLUG_FT2_KG_M2 = SLUG_KG * FT_M**2  # kg·m² per slug·ft²
SLUG_FT3_KG_M3 = SLUG_KG / FT_M**3  # kg/m³ per slug/ft³
# JSBSim turns a weight (lbs) into a mass (slug) dividing by this
JSBSIM_LB_PER_SLUG = 32.174049
DYNAMIC_PRESSURES = ("atmosphere", "airplane")
RATE_SPEEDS = ("V", "V0")
_AXES = ("X", "Y", "Z", "ROLL", "PITCH", "YAW")
# the coefficients that act on each axis
_AXIS_COEFFICIENTS = {
    "X": {"CX", "CD", "CL"}, "Y": {"CY"}, "Z": {"CZ", "CD", "CL"},
    "ROLL": {"Cl"}, "PITCH": {"Cm"}, "YAW": {"Cn"},
}  # fmt: skip


@dataclass(frozen=True)
class JSBSimAircraft:
    """What ``write_jsbsim`` wrote.

    Attributes:
        folder: the aircraft folder (load with ``FGFDMExec.set_aircraft_path(folder.parent)``
            and ``load_model(name)``).
        name: the aircraft name (the folder's name).
        aircraft_file: ``NAME.xml``.
        aerodynamics_files: ``aerodynamics/nominal.xml`` then the draws.
        planet_file: ``planet_flat.xml`` (flightid's flat, non-rotating earth).
        values: parameter name → value of the nominal aerodynamics.
        draws: (K, n_free) drawn values of the free parameters (``free_names``).
        free_names: names of the drawn parameters.
        rules: the approximation rules the aerodynamics use (empty when exact).
        controls: flightid control → JSBSim property.
        thrust_input: the airplane's thrust channel (its value goes to ``THRUST_PROPERTY``
            in lbf), or None.
        g: the airplane's acceleration of gravity, m/s².
        unmodelled_axes: the JSBSim axes no coefficient of the model acts on (e.g. X, Z,
            PITCH for a lateral model): JSBSim sees no aerodynamic load there.
    """

    folder: Path
    name: str
    aircraft_file: Path
    aerodynamics_files: tuple[Path, ...]
    planet_file: Path
    values: dict[str, float]
    draws: np.ndarray
    free_names: tuple[str, ...]
    rules: tuple[str, ...] = ()
    controls: dict[str, str] = field(default_factory=dict)
    thrust_input: str | None = None
    g: float = 9.80665
    unmodelled_axes: tuple[str, ...] = ()


# ------------------------------------------------------------------ parameters and checks
def _parameter_source(estimate_or_model):
    """(values by name, free names, covariance over them or None) of an ``Estimate``
    (``covariance_default``, else ``covariance``), a model with ``parameters``, a
    ``Parameters`` or a mapping {name: value}."""
    if hasattr(estimate_or_model, "covariance") and hasattr(estimate_or_model, "names"):
        names = list(estimate_or_model.names)
        values = dict(zip(names, np.asarray(estimate_or_model.values, float), strict=True))
        free = [n for n, f in zip(names, estimate_or_model.free, strict=True) if f]
        cov = getattr(estimate_or_model, "covariance_default", None)
        cov = estimate_or_model.covariance if cov is None else cov
        return values, free, np.asarray(cov, dtype=float)
    parameters = getattr(estimate_or_model, "parameters", estimate_or_model)
    if hasattr(parameters, "names") and hasattr(parameters, "values"):
        values = dict(zip(parameters.names, np.asarray(parameters.values, float), strict=True))
        return values, [], None
    if isinstance(estimate_or_model, Mapping):
        return {str(k): float(v) for k, v in estimate_or_model.items()}, [], None
    raise InputTypeError(
        "estimate_or_model: expected an Estimate, a model with parameters, a Parameters or a "
        f"mapping {{name: value}}, got {describe(estimate_or_model)}"
    )


def _check_airplane(airplane) -> None:
    """The airplane quantities the export cannot write are refused by name."""
    from flightid.aircraft.airplane import Airplane

    if not isinstance(airplane, Airplane):
        raise InputTypeError(f"airplane: expected an Airplane, got {describe(airplane)}")
    unsupported = {
        "engine_momentum": airplane.engine_momentum != 0.0,
        "engine_momentum_input": airplane.engine_momentum_input is not None,
        "propeller_torque_input": airplane.propeller_torque_input is not None,
    }
    named = [k for k, used in unsupported.items() if used]
    if named:
        raise JSBSimExportError(
            f"airplane: {named} (engine gyroscopic moments, propeller torque) have no "
            "counterpart in the exported aircraft; expected 0 / None"
        )


def _check_rate_options(reference_speed, rate_speed) -> None:
    """V0 positive or None; rate_speed "V" or "V0" (the latter with V0)."""
    if rate_speed not in RATE_SPEEDS:
        raise JSBSimExportError(f"rate_speed: expected one of {RATE_SPEEDS}, got {rate_speed!r}")
    valid = isinstance(reference_speed, (int, float)) and not isinstance(reference_speed, bool)
    if reference_speed is not None and not (
        valid and math.isfinite(reference_speed) and reference_speed > 0
    ):
        raise JSBSimExportError(
            f"reference_speed: expected a positive speed V0 (m/s) or None, got "
            f"{describe(reference_speed)}"
        )
    if rate_speed == "V0" and reference_speed is None:
        raise JSBSimExportError('rate_speed="V0": needs reference_speed (V0, m/s)')


def _check_options(aero, dynamic_pressure, draws, controls) -> None:
    """aero an AeroModel, dynamic_pressure known, draws ≥ 0, controls {name: property}."""
    from flightid.aircraft.aero import AeroModel

    if not isinstance(aero, AeroModel):
        raise InputTypeError(f"aero: expected an AeroModel, got {describe(aero)}")
    if dynamic_pressure not in DYNAMIC_PRESSURES:
        raise JSBSimExportError(
            f"dynamic_pressure: expected one of {DYNAMIC_PRESSURES}, got {dynamic_pressure!r}"
        )
    if isinstance(draws, bool) or not isinstance(draws, int) or draws < 0:
        raise JSBSimExportError(f"draws: expected an integer ≥ 0, got {describe(draws)}")
    if not all(isinstance(k, str) and isinstance(v, str) and v for k, v in controls.items()):
        raise InputTypeError(
            f"controls: expected a mapping {{control name: JSBSim property}}, got "
            f"{describe(controls)}"
        )


# ------------------------------------------------------------------ XML
def _sub(parent: ET.Element, tag: str, text: str | None = None, **attributes) -> ET.Element:
    element = ET.SubElement(parent, tag, attributes)
    if text is not None:
        element.text = text
    return element


def _location(parent: ET.Element, name: str | None, x_ft: float, y_ft: float, z_ft: float):
    """A structural-frame point (x aft, y right, z up), ft."""
    attributes = {"unit": "FT"} if name is None else {"name": name, "unit": "FT"}
    element = _sub(parent, "location", **attributes)
    for axis, value in zip("xyz", (x_ft, y_ft, z_ft), strict=True):
        _sub(element, axis, number(value))
    return element


def _metrics(root: ET.Element, airplane) -> None:
    metrics = _sub(root, "metrics")
    _sub(metrics, "wingarea", number(airplane.S / FT_M**2), unit="FT2")
    span = airplane.b if airplane.b is not None else airplane.cbar
    _sub(metrics, "wingspan", number(span / FT_M), unit="FT")
    _sub(metrics, "chord", number(airplane.cbar / FT_M), unit="FT")
    for point in ("AERORP", "EYEPOINT", "VRP"):
        _location(metrics, point, 0.0, 0.0, 0.0)


def _mass_balance(root: ET.Element, airplane) -> None:
    balance = _sub(root, "mass_balance", negated_crossproduct_inertia="false")
    lateral = airplane.Ix is not None
    inertia = {
        "ixx": airplane.Ix if lateral else airplane.Iy,
        "iyy": airplane.Iy,
        "izz": airplane.Iz if lateral else airplane.Iy,
        "ixy": 0.0,
        "ixz": airplane.Ixz if lateral else 0.0,
        "iyz": 0.0,
    }
    for tag, value in inertia.items():
        _sub(balance, tag, number(value / SLUG_FT2_KG_M2), unit="SLUG*FT2")
    # weight (lbs) = mass (slug) · 32.174049: JSBSim divides by the same number
    _sub(balance, "emptywt", number(airplane.mass / SLUG_KG * JSBSIM_LB_PER_SLUG), unit="LBS")
    _location(balance, "CG", 0.0, 0.0, 0.0)


def _ground_reactions(root: ET.Element, airplane) -> None:
    """Three stiff contacts one chord below the c.g. (parking only)."""
    reactions = _sub(root, "ground_reactions")
    chord_ft = airplane.cbar / FT_M
    weight_lbf = airplane.mass * airplane.g / LBF_N
    half_track = (airplane.b if airplane.b is not None else airplane.cbar) / FT_M / 4.0
    points = {"NOSE": (-chord_ft, 0.0), "LEFT_MAIN": (0.2 * chord_ft, -half_track),
              "RIGHT_MAIN": (0.2 * chord_ft, half_track)}  # fmt: skip
    for name, (x_ft, y_ft) in points.items():
        contact = _sub(reactions, "contact", type="BOGEY", name=name)
        _location(contact, None, x_ft, y_ft, -chord_ft)
        for tag, value in (("static_friction", 0.8), ("dynamic_friction", 0.5),
                           ("rolling_friction", 0.02)):  # fmt: skip
            _sub(contact, tag, number(value))
        # a spring that holds the weight at 0.1 ft deflection, damping of the same order
        _sub(contact, "spring_coeff", number(10.0 * weight_lbf), unit="LBS/FT")
        _sub(contact, "damping_coeff", number(weight_lbf), unit="LBS/FT/SEC")
        _sub(contact, "max_steer", "0", unit="DEG")
        _sub(contact, "brake_group", "NONE")
        _sub(contact, "retractable", "0")


def _coefficient_function(aero, coefficient, values, signals: SignalMap) -> ET.Element:
    """<function name="flightid/coefficient/C"> = Σ θ_j x_j (+ 0, so a sum has two terms)."""
    function = ET.Element("function", name=f"flightid/coefficient/{coefficient}")
    terms = aero.terms(coefficient)
    names = [aero.parameter_name(coefficient, t) for t in terms]
    text = " + ".join(
        n if t.is_constant else f"{n}·{t.label}" for n, t in zip(names, terms, strict=True)
    )
    _sub(function, "description", f"{coefficient} = {text}")
    total = _sub(function, "sum")
    for name, term in zip(names, terms, strict=True):
        total.append(signals.term(coefficient, term, values[name]))
    _sub(total, "value", "0.0")
    return function


def _coefficient(present: set[str], name: str, scale: float = 1.0):
    """[element] of ``scale`` · flightid/coefficient/name if the model has it, else []."""
    if name not in present:
        return []
    element = ET.Element("product")
    _sub(element, "value", number(scale))
    _sub(element, "property", f"flightid/coefficient/{name}")
    return [element]


def _body_coefficient(present: set[str], axis: str) -> list[ET.Element]:
    """The body-axis force coefficient of ``axis`` from C_X, C_Z or C_D, C_L [2.15]."""
    own = _coefficient(present, "C" + axis)
    if axis == "Y":
        return own
    trig = {"X": (("CL", "sin", 1.0), ("CD", "cos", -1.0)),
            "Z": (("CL", "cos", -1.0), ("CD", "sin", -1.0))}[axis]  # fmt: skip
    parts = own
    for name, function, sign in trig:
        for element in _coefficient(present, name, sign):
            angle = _sub(element, function)
            _sub(angle, "property", "aero/alpha-rad")
            parts.append(element)
    return parts


def _axis_function(axis: str, present, qbar: ET.Element, airplane, thrust: bool):
    """The <function> of one JSBSim axis (lbf or lbf·ft), or None if it has no load."""
    s_ft2 = airplane.S / FT_M**2
    span = airplane.b if airplane.b is not None else airplane.cbar
    length = {"ROLL": span, "PITCH": airplane.cbar, "YAW": span}.get(axis)
    moment = {"ROLL": "Cl", "PITCH": "Cm", "YAW": "Cn"}.get(axis)
    coefficients = (
        _body_coefficient(present, axis) if moment is None else _coefficient(present, moment)
    )
    terms = []
    if coefficients:
        product = ET.Element("product")
        product.append(qbar)
        # S ft² (· b or c̄ ft for a moment)
        scale = s_ft2 if length is None else s_ft2 * length / FT_M
        _sub(product, "value", number(scale))
        total = _sub(product, "sum")
        total.extend(coefficients)
        _sub(total, "value", "0.0")
        terms.append(product)
    thrust_factor = {
        "X": math.cos(airplane.thrust_inclination),
        "Z": -math.sin(airplane.thrust_inclination),
        "PITCH": airplane.thrust_moment_arm / FT_M,
    }.get(axis)
    if thrust and thrust_factor is not None:
        # X_T = T cos σ_T, Z_T = −T sin σ_T, M_T = l_T T (lbf, lbf·ft)
        product = ET.Element("product")
        _sub(product, "value", number(thrust_factor))
        _sub(product, "property", THRUST_PROPERTY)
        terms.append(product)
    if not terms:
        return None
    function = ET.Element("function", name=f"flightid/load/{axis}")
    total = _sub(function, "sum")
    total.extend(terms)
    _sub(total, "value", "0.0")
    return function


def _qbar_element(airplane, dynamic_pressure: str) -> ET.Element:
    if dynamic_pressure == "atmosphere":
        element = ET.Element("property")
        element.text = "aero/qbar-psf"
        return element
    # q̄ = ½ ρ V², psf from slug/ft³ and ft/s
    element = ET.Element("product")
    _sub(element, "value", number(0.5 * airplane.rho / SLUG_FT3_KG_M3))
    _sub(element, "property", "velocities/vt-fps")
    _sub(element, "property", "velocities/vt-fps")
    return element


def _aerodynamics(aero, values, airplane, signals: SignalMap, dynamic_pressure: str):
    """The <aerodynamics> element: coefficient functions, then the six axes."""
    root = ET.Element("aerodynamics")
    thrust = airplane.thrust_input is not None
    if thrust:
        _sub(root, "property", THRUST_PROPERTY, value="0")
    for coefficient in aero.coefficients:
        root.append(_coefficient_function(aero, coefficient, values, signals))
    present = set(aero.coefficients)
    for axis in _AXES:
        function = _axis_function(
            axis, present, _qbar_element(airplane, dynamic_pressure), airplane, thrust
        )
        if function is not None:
            _sub(root, "axis", name=axis).append(function)
    return root


def _write_xml(element: ET.Element, path: Path, comment: str | None = None) -> None:
    ET.indent(element)
    text = ET.tostring(element, encoding="unicode")
    header = '<?xml version="1.0"?>\n'
    if comment:
        header += f"<!-- {comment} -->\n"
    path.write_text(header + text + "\n", encoding="utf-8")


def _planet(airplane, path: Path) -> None:
    """A spherical, non-rotating planet with g at sea level (GM = g R²), of 1000 times the
    earth's radius: g falls by 2h/R (3e-7 at h = 1000 m) and the local vertical turns by V/R
    (1e-8 rad/s at 60 m/s), so that the equations are those of flightid's flat earth."""
    radius_ft = 1000.0 * 20925646.32546  # 1000 × the WGS84 semi-major axis, ft
    planet = ET.Element("planet", name="flightid flat earth")
    _sub(planet, "description", "non-rotating sphere, g at sea level = the airplane's g")
    _sub(planet, "equatorial_radius", number(radius_ft), unit="FT")
    _sub(planet, "polar_radius", number(radius_ft), unit="FT")
    _sub(planet, "rotation_rate", "0.0", unit="RAD/SEC")
    # GM = g R², ft³/s²
    _sub(planet, "GM", number(airplane.g / FT_M * radius_ft**2), unit="FT3/SEC2")
    _sub(planet, "J2", "0.0")
    _write_xml(planet, path)


# ------------------------------------------------------------------ draws
def _draws(values, free, covariance, count: int, seed) -> np.ndarray:
    """(count, n_free) draws θ̂ + L z, z ~ N(0, I), L Lᵀ = C (symmetric square root)."""
    if count == 0:
        return np.empty((0, len(free)))
    if covariance is None or not free:
        raise JSBSimExportError(
            f"draws={count}: needs a parameter covariance (an Estimate with free parameters); "
            "got a model or values without one"
        )
    cov = np.asarray(covariance, dtype=float)
    if cov.shape != (len(free), len(free)) or not np.all(np.isfinite(cov)):
        raise JSBSimExportError(
            f"draws: the covariance must be a finite {len(free)}×{len(free)} matrix over the "
            f"free parameters {free}; got shape {cov.shape} (undetermined parameters have σ = inf)"
        )
    eigenvalues, vectors = np.linalg.eigh(0.5 * (cov + cov.T))
    # round-off leaves eigenvalues of about −1e-10 of the largest: clipped to 0
    if eigenvalues.min() < -1e-8 * max(eigenvalues.max(), 0.0):
        raise JSBSimExportError(
            f"draws: the covariance is not positive semi-definite (smallest eigenvalue "
            f"{eigenvalues.min():.3g})"
        )
    root = vectors * np.sqrt(np.clip(eigenvalues, 0.0, None))
    rng = np.random.default_rng(seed)
    mean = np.array([values[n] for n in free])
    return mean + rng.standard_normal((count, len(free))) @ root.T


# ------------------------------------------------------------------ the export
def _prepare_folder(path_dir, overwrite: bool) -> Path:
    folder = Path(path_dir)
    name = folder.name
    if not name or not all(c.isalnum() or c in "-_." for c in name):
        raise JSBSimExportError(
            f"path_dir: the folder name is the aircraft name; expected letters, digits, "
            f"'-', '_', '.', got {name!r}"
        )
    if folder.exists() and any(folder.iterdir()) and not overwrite:
        raise JSBSimExportError(
            f"path_dir: {folder} exists and is not empty; choose a new folder or pass "
            "overwrite=True"
        )
    (folder / "aerodynamics").mkdir(parents=True, exist_ok=True)
    return folder


def write_jsbsim(
    estimate_or_model,
    airplane,
    path_dir: str | Path,
    *,
    aero,
    draws: int = 0,
    seed: int | None = 0,
    reference_speed: float | None = None,
    rate_speed: str = "V",
    controls: Mapping[str, str] | None = None,
    dynamic_pressure: str = "atmosphere",
    overwrite: bool = False,
) -> JSBSimAircraft:
    """Write the identified model as a JSBSim aircraft folder (module docstring).

    Args:
        estimate_or_model: the parameter values: an ``Estimate`` (values; its covariance
            for ``draws``), a model with ``parameters``, a ``Parameters`` or a mapping
            {name: value}.
        airplane: the ``flightid.aircraft.Airplane`` (SI units) of the model.
        path_dir: the aircraft folder to create; its name is the aircraft name.
        aero: the ``AeroModel`` whose parameters the values are.
        draws: K ≥ 0 parameter draws from the covariance, written as
            ``aerodynamics/draw_0001.xml`` … (needs an Estimate).
        seed: seed of the draws (``numpy.random.default_rng``).
        reference_speed, rate_speed: V0 (m/s) and "V" or "V0", as given to the model
            builder (Vrel, dVrel; p̂ = p b/2V or p b/2V0 …).
        controls: flightid control name → JSBSim property, added to / replacing
            ``DEFAULT_CONTROLS`` (de, da, dr → fcs/elevator-pos-rad,
            fcs/left-aileron-pos-rad, fcs/rudder-pos-rad); the property carries the control
            in the model's own unit (rad) and sign convention.
        dynamic_pressure: "atmosphere" (JSBSim's q̄) or "airplane" (½ ρ V² with the
            airplane's ρ, as flightid's equations).
        overwrite: write into an existing non-empty folder.

    Returns:
        ``JSBSimAircraft``: the files written and the values.

    Raises:
        JSBSimExportError: a term or airplane quantity without a JSBSim counterpart, a
            missing parameter value, bad options, or a non-empty folder.
    """
    return write_aircraft(
        estimate_or_model, airplane, path_dir, aero=aero, draws=draws, seed=seed,
        reference_speed=reference_speed, rate_speed=rate_speed, controls=controls,
        dynamic_pressure=dynamic_pressure, overwrite=overwrite,
    )  # fmt: skip


def write_aircraft(
    estimate_or_model,
    airplane,
    path_dir: str | Path,
    *,
    aero,
    draws: int = 0,
    seed: int | None = 0,
    reference_speed: float | None = None,
    rate_speed: str = "V",
    controls: Mapping[str, str] | None = None,
    dynamic_pressure: str = "atmosphere",
    overwrite: bool = False,
    notes: tuple[str, ...] = (),
    summary: Mapping[str, object] | None = None,
) -> JSBSimAircraft:
    """``write_jsbsim`` with ``notes`` (lines added to the aircraft file's header) and
    ``summary`` (entries added to ``export.json``), for writers of other model kinds
    (``globalmodel_jsbsim``) that go through the same aircraft."""
    _check_airplane(airplane)
    if controls is not None and not isinstance(controls, Mapping):
        raise InputTypeError(
            f"controls: expected a mapping {{control name: JSBSim property}}, got "
            f"{describe(controls)}"
        )
    mapping = {**DEFAULT_CONTROLS, **dict(controls or {})}
    _check_options(aero, dynamic_pressure, draws, mapping)
    _check_rate_options(reference_speed, rate_speed)
    values, free, covariance = _parameter_source(estimate_or_model)
    missing = [n for n in aero.parameter_names if n not in values]
    if missing:
        raise JSBSimExportError(
            f"estimate_or_model: no values for the aerodynamic parameters {missing}"
        )
    signals = SignalMap(
        None if airplane.b is None else airplane.b / FT_M, airplane.cbar / FT_M,
        reference_speed, rate_speed, mapping, airplane.thrust_input,
    )  # fmt: skip
    nominal = _aerodynamics(aero, values, airplane, signals, dynamic_pressure)
    drawn = _draws(values, free, covariance, draws, seed)
    folder = _prepare_folder(path_dir, overwrite)
    name = folder.name
    files = [folder / "aerodynamics" / "nominal.xml"]
    _write_xml(nominal, files[0], "flightid: identified aerodynamics (nominal values)")
    for k, row in enumerate(drawn, start=1):
        draw_values = {**values, **dict(zip(free, row, strict=True))}
        element = _aerodynamics(aero, draw_values, airplane, signals, dynamic_pressure)
        files.append(folder / "aerodynamics" / f"draw_{k:04d}.xml")
        _write_xml(element, files[-1], f"flightid: parameter draw {k} of {draws}, seed {seed}")
    root = ET.Element("fdm_config", name=name, version="2.0", release="BETA")
    header = _sub(root, "fileheader")
    _sub(header, "author", "flightid export")
    _sub(header, "description", f"identified model of {airplane.name} (flightid)")
    for rule in sorted(signals.rules):
        _sub(header, "note", "approximation: " + rule)
    unmodelled = tuple(a for a in _AXES if not _AXIS_COEFFICIENTS[a] & set(aero.coefficients))
    if unmodelled:
        _sub(header, "note", f"no aerodynamic model on the axes {', '.join(unmodelled)}")
    for note in notes:
        _sub(header, "note", note)
    _metrics(root, airplane)
    _mass_balance(root, airplane)
    _ground_reactions(root, airplane)
    _sub(root, "aerodynamics", file="aerodynamics/nominal.xml")
    aircraft_file = folder / f"{name}.xml"
    _write_xml(root, aircraft_file)
    planet_file = folder / "planet_flat.xml"
    _planet(airplane, planet_file)
    used = {s: mapping[s] for s in aero.signals if s in mapping}
    result = JSBSimAircraft(
        folder, name, aircraft_file, tuple(files), planet_file,
        {n: float(values[n]) for n in aero.parameter_names}, drawn, tuple(free),
        tuple(sorted(signals.rules)), used, airplane.thrust_input, airplane.g, unmodelled,
    )  # fmt: skip
    _write_summary(
        result, airplane, dynamic_pressure, reference_speed, rate_speed, seed, summary or {}
    )
    return result


def _write_summary(
    result: JSBSimAircraft, airplane, dynamic_pressure, v0, rate_speed, seed, extra: Mapping
):
    summary = {
        "aircraft": result.aircraft_file.name,
        "aerodynamics": [str(p.relative_to(result.folder)) for p in result.aerodynamics_files],
        "planet": result.planet_file.name,
        "values": result.values,
        "controls": result.controls,
        "thrust_property_lbs": THRUST_PROPERTY if airplane.thrust_input else None,
        "dynamic_pressure": dynamic_pressure,
        "reference_speed_m_s": v0,
        "rate_speed": rate_speed,
        "rules": list(result.rules),
        "unmodelled_axes": list(result.unmodelled_axes),
        **extra,
    }
    (result.folder / "export.json").write_text(json.dumps(summary, indent=2) + "\n")
    if len(result.draws):
        draws = {
            "seed": seed,
            "free_names": list(result.free_names),
            "draws": result.draws.tolist(),
        }
        (result.folder / "draws.json").write_text(json.dumps(draws, indent=1) + "\n")
