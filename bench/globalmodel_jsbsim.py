"""The JSBSim validation study of global aerodynamic models: does a model fitted over many
maneuvers predict the truth aircraft's coefficients, and do its 95 % prediction intervals and
its support flag tell the truth?

Truth aircraft: JSBSim's F-16 (``aircraft/f16``, tables of the Stevens–Lewis type in α, β, M,
δh, lef, rates). Two copies are loaded:

* the *flying* aircraft, the shipped model with its flight-control system (pitch g-command,
  α limiter, leading-edge-flap schedule), trimmed at each flight condition and flown with
  designed stick inputs (``fly_condition``);
* the *truth oracle* (``truth_oracle``), a copy in a temporary folder with the flight-control
  system and the systems removed (the surface positions are then plain properties that hold
  what is set), which evaluates C_L, C_D, C_Y, C_l, C_m, C_n at any point by JSBSim's own
  ``run_ic`` and its aerodynamic forces and moments.

Coefficients (both copies, and the reconstruction): body-axis forces over q̄ S; C_L, C_D
rotated by α only, C_L = C_X sin α − C_Z cos α, C_D = −C_X cos α − C_Z sin α (the form
``flightid.data.coefficients.aero_coefficients`` uses); moments about the centre of gravity
(JSBSim's ``moments/*-aero-lbsft``) over q̄ S b (C_l, C_n) and q̄ S c̄ (C_m). Units: angles in
rad, rates in rad/s, lengths in m, dynamic pressure in Pa, Mach dimensionless; p̂ = p b/2V,
q̂ = q c̄/2V, r̂ = r b/2V with V the true airspeed.

Flights: per condition (Mach × altitude) the trimmed aircraft (gear up, fuel frozen) flies
designed elevator-stick inputs (a multisine of ``flightid.design``, a pull-up with a small
multisine on top, in the full study a 3-2-1-1 on a gentle pull, and a combined maneuver held
out from the fit), simulated at 150 Hz and recorded at 50 Hz until the aircraft leaves the
study's envelope (``ENVELOPE``: α −10…30°, q̄ ≥ 2000 Pa). Lateral maneuvers are left out
(``maneuver_designs``: the flaperon mix they move is not a variable of the models).
Measurement noise (seeded) is added to what a flight-test instrumentation would record; the
coefficients are reconstructed from the noisy motion with ``aero_coefficients`` (specific
forces, rates, rate derivatives by ``smooth_derivative``, q̄, thrust, mass and geometry read
from JSBSim), as a user would; the per-sample truth is the oracle at the true states.

Measures (``fit_and_measure``): a global model of C_L, C_D, C_m over (α, M, δh, q̂, lef) with
the settings ``STUDY_CHOICE`` (its comment gives the reasons) fitted to the reconstructed
coefficients of all but one maneuver per condition; on the held-out maneuvers and on a grid
(α from below the data to well beyond it, Mach steps, δh at the data's trim schedule, q̂ = 0,
lef as the flight controls set it): the share of the truth inside the 95 % interval of the
coefficient itself (``function_lower`` … ``function_upper``, where the model gives it; "n/a"
where not) and inside the 95 % prediction interval, where the model says it is inside its
support; the prediction interval's share of the reconstructed (measured) coefficient; the RMS
error inside the support, the share flagged outside, the RMS error inside vs outside the
flag; the shares of grid points flagged with α more than 5° above or below the data and with
Mach more than 0.05 above it. ``--explore`` adds the table of the settings tried
(``EXPLORED_CHOICES``).

Usage::

    PYTHONPATH=src python bench/globalmodel_jsbsim.py [--quick] [--write-data DIR]
        [--carpets PATH] [--explore] [--stand-in]

It prints ``<!-- guide: docs/globalmodel.md -->``, the table between the numbers markers,
and PASS/FAIL lines. ``--write-data`` writes the maneuvers as CSV at 10 Hz (the shipped
example ``examples/data/globalmodel_f16`` is ``--quick --write-data``). ``--stand-in`` fits
with the fixed-polynomial stand-in of this module
instead of ``flightid.globalmodel`` (a check of the study's plumbing, not of the method).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import tempfile
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flightid.errors import EstimationError, InputError

# unit conversions (exact by definition)
FT_M = 0.3048
IN_M = 0.0254
LBF_N = 4.4482216152605
SLUG_KG = LBF_N / FT_M  # 14.5939… kg
SLUG_FT2_KG_M2 = SLUG_KG * FT_M**2
PSF_PA = LBF_N / FT_M**2
DEG = math.pi / 180.0

COEFFICIENTS = ("CL", "CD", "CY", "Cl", "Cm", "Cn")
FIT_RESPONSES = ("CL", "CD", "Cm")
FIT_VARIABLES = ("alpha", "Mach", "de", "qhat")
SAMPLE_HZ = 50.0
SUBSTEPS = 3  # JSBSim at 150 Hz: three steps per 50 Hz sample
# measurement-noise σ (SI): α, β 0.1°; p, q, r 0.1°/s; specific forces 0.02 m/s²;
# q̄ 0.5 % (relative); V 0.1 m/s; Mach 0.001
NOISE = {"alpha": 0.1 * DEG, "beta": 0.1 * DEG, "rate": 0.1 * DEG, "accel": 0.02,
         "qbar_rel": 0.005, "V": 0.1, "Mach": 0.001}  # fmt: skip

# the aerodynamic inputs of the truth oracle and the JSBSim properties they set
SURFACES = {
    "de": "fcs/elevator-pos-rad",
    "da": "fcs/aileron-pos-rad",
    "dr": "fcs/rudder-pos-rad",
    "lef": "fcs/lef-pos-rad",
    "flaperon": "fcs/flaperon-mix-rad",
    "speedbrake": "fcs/speedbrake-pos-rad",
}


class StudyInputError(InputError):
    """A request the study cannot serve (an aircraft other than the F-16, an unknown point
    variable)."""


class TrimError(EstimationError):
    """JSBSim could not trim (or load) the truth aircraft at a condition."""


# properties the stripped copy declares (the flight-control system defined them)
_DECLARED = ("fcs/lef-pos-rad", "fcs/flaperon-mix-rad", "fcs/aileron-pos-rad")


@dataclass(frozen=True)
class Condition:
    """A trim condition: Mach number and pressure altitude (ft, JSBSim's unit)."""

    mach: float
    altitude_ft: float

    @property
    def label(self) -> str:
        return f"M{self.mach:.2f}/{self.altitude_ft / 1000:.0f}kft"


FULL_CONDITIONS = tuple(
    Condition(m, h) for h in (10000.0, 25000.0) for m in (0.35, 0.5, 0.65, 0.8, 0.9)
)
QUICK_CONDITIONS = tuple(Condition(m, h) for h in (10000.0, 25000.0) for m in (0.4, 0.6, 0.8))


def _jsbsim():
    os.environ.setdefault("JSBSIM_DEBUG", "0")  # no start-up banner
    import jsbsim

    return jsbsim


def _executive(aircraft_path: str | None = None):
    jsbsim = _jsbsim()
    fdm = jsbsim.FGFDMExec(os.path.dirname(jsbsim.__file__))
    fdm.set_debug_level(0)
    if aircraft_path is not None:
        fdm.set_aircraft_path(aircraft_path)
    return fdm


def lef_schedule(alpha_rad: np.ndarray, mach: np.ndarray) -> np.ndarray:
    """The F-16's leading-edge-flap position (rad) as its flight-control system sets it in
    flight with the gear up: the first test of its switch that holds,
    α > 0.2618 → 0.436, α > 0.0873 → 0.262, M > 0.9 → −0.0349, else 0."""
    alpha = np.asarray(alpha_rad, dtype=float)
    mach = np.broadcast_to(np.asarray(mach, dtype=float), alpha.shape)
    return np.select(
        [alpha > 0.2618, alpha > 0.0873, mach > 0.9], [0.436, 0.262, -0.0349], default=0.0
    )


# ------------------------------------------------------------------------ the truth oracle
class TruthOracle:
    """The truth aircraft's coefficients at arbitrary points (module docstring).

    ``oracle(points)`` takes arrays (broadcast together) under the names ``alpha``, ``beta``
    (rad), ``Mach``, ``altitude_m`` (default 6000 m), rates ``p``, ``q``, ``r`` (rad/s) or
    ``phat``, ``qhat``, ``rhat`` (dimensionless, with the true airspeed), surfaces ``de``,
    ``da``, ``dr``, ``flaperon``, ``speedbrake`` (rad, default 0) and ``lef`` (rad; default
    the in-flight schedule ``lef_schedule``); gear up. It returns {C_L, C_D, C_Y, C_l, C_m,
    C_n} as arrays, moments about the centre of gravity of the aircraft as loaded.
    """

    def __init__(self, aircraft: str = "f16") -> None:
        if aircraft != "f16":
            raise StudyInputError(
                f"aircraft: expected 'f16' (the study's truth aircraft), got {aircraft!r}"
            )
        jsbsim = _jsbsim()
        self._folder = tempfile.mkdtemp(prefix="truth_aircraft_")
        source = Path(jsbsim.__file__).parent / "aircraft" / aircraft
        target = Path(self._folder) / "aircraft" / aircraft
        target.mkdir(parents=True)
        strip_flight_controls(source / f"{aircraft}.xml", target / f"{aircraft}.xml")
        self.fdm = _executive(str(Path(self._folder) / "aircraft"))
        if not self.fdm.load_model(aircraft):
            raise TrimError(f"JSBSim could not load the stripped {aircraft} copy")
        self.fdm.disable_output()
        self.fdm["gear/gear-pos-norm"] = 0.0
        self.S_m2 = self.fdm["metrics/Sw-sqft"] * FT_M**2
        self.b_m = self.fdm["metrics/bw-ft"] * FT_M
        self.cbar_m = self.fdm["metrics/cbarw-ft"] * FT_M

    def close(self) -> None:
        shutil.rmtree(self._folder, ignore_errors=True)

    def __enter__(self) -> TruthOracle:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __call__(self, points: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        names = ("alpha", "beta", "Mach", "altitude_m", "p", "q", "r", "phat", "qhat", "rhat")
        given = {k: np.asarray(v, dtype=float) for k, v in points.items()}
        unknown = set(given) - set(names) - set(SURFACES)
        if unknown or "alpha" not in given or "Mach" not in given:
            raise StudyInputError(
                f"points: expected alpha, Mach and optionally {names[1:]} and {tuple(SURFACES)}, "
                f"got {sorted(given)}"
            )
        for name, value in given.items():
            if not np.all(np.isfinite(value)):
                raise StudyInputError(f"points[{name!r}]: expected finite numbers, got {value!r}")
        arrays = np.broadcast_arrays(*given.values())
        shape = arrays[0].shape
        flat = {k: a.ravel() for k, a in zip(given, arrays, strict=True)}
        if "lef" not in flat:
            flat["lef"] = lef_schedule(flat["alpha"], flat["Mach"])
        out = {c: np.empty(arrays[0].size) for c in COEFFICIENTS}
        for i in range(arrays[0].size):
            for name, value in self._point({k: float(v[i]) for k, v in flat.items()}).items():
                out[name][i] = value
        return {k: v.reshape(shape) for k, v in out.items()}

    def _point(self, point: Mapping[str, float]) -> dict[str, float]:
        fdm = self.fdm
        fdm["ic/h-sl-ft"] = point.get("altitude_m", 6000.0) / FT_M
        fdm["ic/mach"] = point["Mach"]
        fdm["ic/alpha-rad"] = point["alpha"]
        fdm["ic/beta-rad"] = point.get("beta", 0.0)
        v_fps = fdm["ic/vt-fps"]
        b_ft, c_ft = self.b_m / FT_M, self.cbar_m / FT_M
        # p = 2V p̂ / b,  q = 2V q̂ / c̄,  r = 2V r̂ / b
        rates = {
            "p": point.get("p", 2.0 * v_fps * point.get("phat", 0.0) / b_ft),
            "q": point.get("q", 2.0 * v_fps * point.get("qhat", 0.0) / c_ft),
            "r": point.get("r", 2.0 * v_fps * point.get("rhat", 0.0) / b_ft),
        }
        for rate, value in rates.items():
            fdm[f"ic/{rate}-rad_sec"] = value
        for name, prop in SURFACES.items():
            fdm[prop] = point.get(name, 0.0)
        fdm.run_ic()
        return jsbsim_coefficients(fdm)


def jsbsim_coefficients(fdm) -> dict[str, float]:
    """The coefficients of JSBSim's current aerodynamic forces and moments (module
    docstring): C = F/(q̄ S), C_l = L/(q̄ S b), C_m = M/(q̄ S c̄), C_n = N/(q̄ S b);
    C_L = C_X sin α − C_Z cos α, C_D = −C_X cos α − C_Z sin α."""
    qs = fdm["aero/qbar-psf"] * fdm["metrics/Sw-sqft"]
    b, c = fdm["metrics/bw-ft"], fdm["metrics/cbarw-ft"]
    cx, cy, cz = (fdm[f"forces/fb{a}-aero-lbs"] / qs for a in "xyz")
    a = fdm["aero/alpha-rad"]
    return {
        "CL": cx * math.sin(a) - cz * math.cos(a),
        "CD": -(cx * math.cos(a) + cz * math.sin(a)),
        "CY": cy,
        "Cl": fdm["moments/l-aero-lbsft"] / (qs * b),
        "Cm": fdm["moments/m-aero-lbsft"] / (qs * c),
        "Cn": fdm["moments/n-aero-lbsft"] / (qs * b),
    }


def strip_flight_controls(source: Path, target: Path) -> None:
    """Write the aircraft file ``source`` to ``target`` without its ``<flight_control>``,
    ``<autopilot>`` and ``<system>`` elements; an empty flight-control section declares the
    surface properties the aerodynamics reads that the removed channels used to define."""
    tree = ET.parse(source)
    root = tree.getroot()
    for tag in ("flight_control", "autopilot", "system"):
        for element in root.findall(tag):
            root.remove(element)
    declared = ET.Element("flight_control", name="surfaces set directly (truth oracle)")
    for prop in _DECLARED:
        ET.SubElement(declared, "property", value="0").text = prop
    root.insert(list(root).index(root.find("aerodynamics")), declared)
    tree.write(target)


def truth_oracle(aircraft: str = "f16") -> TruthOracle:
    """The truth oracle of ``aircraft`` (``TruthOracle``); close it (or use ``with``) to
    remove its temporary folder."""
    return TruthOracle(aircraft)


# ------------------------------------------------------------------------------ the flights
@dataclass
class Flight:
    """One recorded maneuver at 50 Hz: ``true`` states and surfaces (SI, noise-free),
    ``measured`` (the same with seeded noise), ``coefficients`` reconstructed from the
    measured motion, ``truth`` (the oracle at the true states) and ``jsbsim`` (the
    coefficients of JSBSim's in-flight aerodynamic forces and moments)."""

    condition: Condition
    maneuver: str
    held_out: bool
    time_s: np.ndarray
    true: dict[str, np.ndarray]
    measured: dict[str, np.ndarray] = field(default_factory=dict)
    coefficients: dict[str, np.ndarray] = field(default_factory=dict)
    truth: dict[str, np.ndarray] = field(default_factory=dict)
    jsbsim: dict[str, np.ndarray] = field(default_factory=dict)
    geometry: dict[str, float] = field(default_factory=dict)


def trimmed_f16(condition: Condition, dt_s: float = 1.0 / (SAMPLE_HZ * SUBSTEPS)):
    """The shipped F-16 (with its flight-control system) trimmed by JSBSim in level flight
    at ``condition``: gear up, fuel frozen (constant mass and centre of gravity), engine
    running. Raises ``TrimError`` naming the condition when the trim fails."""
    fdm = _executive()
    fdm.load_model("f16")
    fdm.disable_output()
    for name, value in (("ic/h-sl-ft", condition.altitude_ft), ("ic/mach", condition.mach),
                        ("ic/gamma-deg", 0.0), ("ic/psi-true-deg", 0.0), ("ic/phi-deg", 0.0),
                        ("gear/gear-cmd-norm", 0.0), ("gear/gear-pos-norm", 0.0)):  # fmt: skip
        fdm[name] = value
    fdm.set_dt(dt_s)
    fdm.run_ic()
    fdm["propulsion/fuel_freeze"] = 1
    fdm["propulsion/set-running"] = -1
    try:
        fdm["simulation/do_simple_trim"] = 1
    except Exception as error:  # JSBSim's TrimFailureException
        raise TrimError(f"trim failed at {condition.label}: {error}") from error
    return fdm


# the pilot's commands the designed inputs drive (normalised stick and pedals)
COMMANDS = {
    "stick": "fcs/elevator-cmd-norm",
    "aileron": "fcs/aileron-cmd-norm",
    "rudder": "fcs/rudder-cmd-norm",
}


@dataclass(frozen=True)
class ManeuverDesign:
    """A maneuver: orthogonal multisines (``flightid.design``, band in Hz) on the commands
    named in ``amplitudes`` (peak, normalised command units) over ``duration_s``, plus a
    pull-up in the first ``pull_s`` seconds (stick ramped to ``pull`` over 40 % of that time,
    held 20 %, ramped back; negative stick pulls: a longer pull loops the aircraft into a
    stall over the top), plus 3-2-1-1 stick steps of height ``steps`` (unit 1 s, from 2 s,
    repeated every 12 s); ``held_out`` maneuvers are kept out of the fit."""

    name: str
    duration_s: float
    band_hz: tuple[float, float]
    amplitudes: Mapping[str, float]
    pull: float = 0.0
    pull_s: float = 10.0
    steps: float = 0.0
    held_out: bool = False


def maneuver_designs(quick: bool, lateral: bool = False) -> tuple[ManeuverDesign, ...]:
    """The maneuvers flown at every condition: a longitudinal multisine, a pull-up (to high
    α; at high speed the g limit stops it earlier), in the full study a 3-2-1-1 on a gentler
    pull, and a combined maneuver that is held out (quick: shorter, no 3-2-1-1).

    ``lateral=True`` adds a lateral multisine (aileron and rudder, a small stick multisine).
    The study leaves it out: the F-16's flight-control system then moves
    ``fcs/flaperon-mix-rad`` by about ±0.6 rad, which changes C_L by up to 0.2, a variable
    outside the longitudinal models of C_L, C_D, C_m over (α, M, δh, q̂)."""
    T = 15.0 if quick else 30.0
    designs = [
        ManeuverDesign("multisine", T, (0.1, 1.5), {"stick": 0.25}),
        ManeuverDesign("pull-up", T, (0.2, 1.2), {"stick": 0.08}, pull=-0.9),
    ]
    if not quick:
        designs.append(ManeuverDesign("3-2-1-1", T, (0.2, 1.0), {"stick": 0.05}, pull=-0.4,
                                      pull_s=T, steps=0.3))  # fmt: skip
    if lateral:
        designs.append(ManeuverDesign("lateral", T, (0.1, 1.5),
                                      {"stick": 0.1, "aileron": 0.12, "rudder": 0.2}))  # fmt: skip
    designs.append(
        ManeuverDesign("combined", 0.7 * T, (0.15, 1.2), {"stick": 0.2}, pull=-0.5, held_out=True)
    )
    return tuple(designs)


def command_signals(design: ManeuverDesign, time_s: np.ndarray) -> dict[str, np.ndarray]:
    """The commands (added to the trim commands) of ``design`` at ``time_s``: the
    multisines of ``flightid.design`` plus the pull-up ramp on the stick."""
    from flightid.design.multisine import design_multisine

    names = list(design.amplitudes)
    multisine = design_multisine(names, design.duration_s, design.band_hz,
                                 [design.amplitudes[n] for n in names])  # fmt: skip
    signals = dict(zip(names, multisine.signals(time_s).T, strict=True))
    fraction = time_s / design.pull_s
    # trapezoid: 0 → 1 over 0–40 %, 1 over 40–60 %, 1 → 0 over 60–100 %
    ramp = np.clip(np.minimum(fraction / 0.4, (1.0 - fraction) / 0.4), 0.0, 1.0)
    signals["stick"] = signals.get("stick", 0.0) + design.pull * ramp
    if design.steps:
        from flightid.design.signals import three_two_one_one

        for start_s in np.arange(2.0, design.duration_s - 7.0, 12.0):
            signals["stick"] = signals["stick"] + three_two_one_one(
                time_s, start_s, 1.0, design.steps
            )
    return signals


# properties recorded per sample → (name, factor to SI)
_RECORDED = (
    ("V", "velocities/vt-fps", FT_M),
    ("alpha", "aero/alpha-rad", 1.0),
    ("beta", "aero/beta-rad", 1.0),
    ("Mach", "velocities/mach", 1.0),
    ("altitude_m", "position/h-sl-ft", FT_M),
    ("p", "velocities/p-rad_sec", 1.0),
    ("q", "velocities/q-rad_sec", 1.0),
    ("r", "velocities/r-rad_sec", 1.0),
    ("p_aero", "velocities/p-aero-rad_sec", 1.0),
    ("q_aero", "velocities/q-aero-rad_sec", 1.0),
    ("r_aero", "velocities/r-aero-rad_sec", 1.0),
    ("pdot", "accelerations/pdot-rad_sec2", 1.0),
    ("qdot", "accelerations/qdot-rad_sec2", 1.0),
    ("rdot", "accelerations/rdot-rad_sec2", 1.0),
    ("ax", "forces/fbx-total-lbs", LBF_N),
    ("ay", "forces/fby-total-lbs", LBF_N),
    ("az", "forces/fbz-total-lbs", LBF_N),
    ("qbar", "aero/qbar-psf", PSF_PA),
    ("thrust", "propulsion/engine/thrust-lbs", LBF_N),
    ("stick", "fcs/elevator-cmd-norm", 1.0),
    *((name, prop, 1.0) for name, prop in SURFACES.items()),
)


# the study's envelope: a recording ends where the aircraft leaves it (α in rad, q̄ in Pa)
ENVELOPE = {"alpha_min": -10 * DEG, "alpha_max": 30 * DEG, "qbar_min": 2000.0}


def _inside_envelope(fdm) -> bool:
    alpha = fdm["aero/alpha-rad"]
    qbar = fdm["aero/qbar-psf"] * PSF_PA
    return ENVELOPE["alpha_min"] <= alpha <= ENVELOPE["alpha_max"] and qbar >= ENVELOPE["qbar_min"]


def _fly(fdm, commands: Mapping[str, np.ndarray]) -> tuple[dict, dict]:
    """Fly ``commands`` (added to the trim commands, one per 50 Hz sample) from trim; the
    recorded properties (SI; forces still in N) and the in-flight coefficients per sample,
    up to where the aircraft leaves ``ENVELOPE`` (the rest is not recorded)."""
    trim = {name: fdm[COMMANDS[name]] for name in commands}
    n = len(next(iter(commands.values())))
    rows = np.empty((n, len(_RECORDED)))
    flown = {c: np.empty(n) for c in COEFFICIENTS}
    for i in range(n):
        if not _inside_envelope(fdm):
            rows, flown = rows[:i], {k: v[:i] for k, v in flown.items()}
            break
        rows[i] = [fdm[prop] * factor for _, prop, factor in _RECORDED]
        for name, value in jsbsim_coefficients(fdm).items():
            flown[name][i] = value
        for name, command in commands.items():
            fdm[COMMANDS[name]] = trim[name] + command[i]
        for _ in range(SUBSTEPS):
            fdm.run()
    return {name: rows[:, j] for j, (name, _, _) in enumerate(_RECORDED)}, flown


def _mass_geometry(fdm) -> dict[str, float]:
    """Mass (kg), inertias (kg m²), reference geometry (m, m²) and the engine's position
    from the centre of gravity in body axes (m) as JSBSim holds them (fuel frozen)."""
    cg = [fdm[f"inertia/cg-{a}-in"] for a in "xyz"]
    # body axes from JSBSim's structural frame (x aft, z up, inches): x_b = −Δx, z_b = −Δz;
    # the F-16's thruster sits at the structural origin
    engine = (-(0.0 - cg[0]) * IN_M, (0.0 - cg[1]) * IN_M, -(0.0 - cg[2]) * IN_M)
    return {
        "mass_kg": fdm["inertia/mass-slugs"] * SLUG_KG,
        "Ix": fdm["inertia/ixx-slugs_ft2"] * SLUG_FT2_KG_M2,
        "Iy": fdm["inertia/iyy-slugs_ft2"] * SLUG_FT2_KG_M2,
        "Iz": fdm["inertia/izz-slugs_ft2"] * SLUG_FT2_KG_M2,
        # JSBSim's inertia/ixz is the product of inertia with the sign opposite to
        # MassGeometry's I_xz (a rolling flight reconstructs C_l, C_n to 1e-9 only so)
        "Ixz": -fdm["inertia/ixz-slugs_ft2"] * SLUG_FT2_KG_M2,
        "S_m2": fdm["metrics/Sw-sqft"] * FT_M**2,
        "b_m": fdm["metrics/bw-ft"] * FT_M,
        "cbar_m": fdm["metrics/cbarw-ft"] * FT_M,
        "engine_x_m": engine[0], "engine_y_m": engine[1], "engine_z_m": engine[2],
    }  # fmt: skip


def fly_condition(
    condition: Condition,
    designs: Sequence[ManeuverDesign],
    oracle: TruthOracle,
    seed: int,
    noise: bool = True,
) -> list[Flight]:
    """Each maneuver of ``designs`` flown from a fresh trim at ``condition`` and recorded at
    50 Hz; the truth per sample from ``oracle`` at the true states; the coefficients
    reconstructed from the motion with seeded measurement noise (``noise=False``: none)."""
    flights = []
    for index, design in enumerate(designs):
        fdm = trimmed_f16(condition)
        time_s = np.arange(0.0, design.duration_s, 1.0 / SAMPLE_HZ)
        true, flown = _fly(fdm, command_signals(design, time_s))
        time_s = time_s[: len(true["alpha"])]
        geometry = _mass_geometry(fdm)
        mass = geometry["mass_kg"]
        for axis in ("ax", "ay", "az"):
            true[axis] = true[axis] / mass  # specific force (m/s²): total non-gravity force / m
        truth = oracle(_oracle_points(true))
        flight = Flight(condition, design.name, design.held_out, time_s, true, truth=truth,
                        jsbsim=flown, geometry=geometry)  # fmt: skip
        rng = np.random.default_rng([seed, index])
        flight.measured = measure(true, rng if noise else None)
        flight.coefficients = reconstruct(flight.measured, geometry)
        flights.append(flight)
    return flights


def _oracle_points(true: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The oracle's point for each recorded sample: the true states and surfaces."""
    points = {k: true[k] for k in ("alpha", "beta", "Mach", "altitude_m", *SURFACES)}
    points.update(p=true["p_aero"], q=true["q_aero"], r=true["r_aero"])
    return points


def measure(
    true: Mapping[str, np.ndarray], rng: np.random.Generator | None
) -> dict[str, np.ndarray]:
    """What the instrumentation records: the true signals plus seeded white noise of σ
    ``NOISE`` (``rng`` None: noise-free); the rate derivatives by ``smooth_derivative`` of the
    measured rates; q̂ = q c̄ / 2V from the measured q and V (set by ``reconstruct``)."""
    from flightid.regression.differentiate import smooth_derivative

    def noisy(x: np.ndarray, sigma: float) -> np.ndarray:
        return x + (sigma * rng.standard_normal(x.shape) if rng is not None else 0.0)

    measured = {k: np.array(true[k]) for k in ("de", "da", "dr", "lef", "thrust")}
    measured["alpha"] = noisy(true["alpha"], NOISE["alpha"])
    measured["beta"] = noisy(true["beta"], NOISE["beta"])
    measured["Mach"] = noisy(true["Mach"], NOISE["Mach"])
    measured["V"] = noisy(true["V"], NOISE["V"])
    for rate in "pqr":
        measured[rate] = noisy(true[rate], NOISE["rate"])
        measured[f"{rate}dot"] = smooth_derivative(measured[rate], 1.0 / SAMPLE_HZ)
    for axis in ("ax", "ay", "az"):
        measured[axis] = noisy(true[axis], NOISE["accel"])
    # q̄ with a relative error: q̄ (1 + ε), ε ~ N(0, 0.005²)
    measured["qbar"] = true["qbar"] * noisy(np.ones_like(true["qbar"]), NOISE["qbar_rel"])
    return measured


def reconstruct(
    measured: dict[str, np.ndarray], geometry: Mapping[str, float]
) -> dict[str, np.ndarray]:
    """C_L, C_D, C_Y, C_l, C_m, C_n from the measured motion by ``aero_coefficients``
    (moments about the centre of gravity), and the measured q̂ = q c̄ / 2V into ``measured``."""
    from flightid.data.coefficients import Engine, MassGeometry, aero_coefficients

    g = geometry
    mass = MassGeometry(g["mass_kg"], g["Ix"], g["Iy"], g["Iz"], g["S_m2"], g["cbar_m"], g["b_m"],
                        Ixz=g["Ixz"])  # fmt: skip
    engine = Engine(measured["thrust"], (g["engine_x_m"], g["engine_y_m"], g["engine_z_m"]))
    m = measured
    # q̂ = q c̄ / (2V)
    m["qhat"] = m["q"] * g["cbar_m"] / (2.0 * m["V"])
    out = aero_coefficients(
        m["ax"],
        m["ay"],
        m["az"],
        m["p"],
        m["q"],
        m["r"],
        m["pdot"],
        m["qdot"],
        m["rdot"],
        m["qbar"],
        m["alpha"],
        mass,
        [engine],
    )
    return {c: np.asarray(out[c]) for c in COEFFICIENTS}


# ---------------------------------------------- a stand-in fitter (for the study's plumbing)
@dataclass(frozen=True)
class StandInSettings:
    """STAND-IN for ``flightid.globalmodel.GlobalModelSettings`` (the option names the study
    passes): polynomial orders per variable, the total order, the decimation and the
    residual variance of the prediction interval."""

    orders: Mapping[str, int]
    max_order: int = 3
    decimate: int = 5
    residual_variance: str = "global"
    sigma2_max: str = "response"  # no term selection in the stand-in: not used
    knots: Mapping | None = None  # the stand-in offers monomials only: not used
    cross_with: tuple[str, ...] = ()  # not used


@dataclass(frozen=True)
class StandInPrediction:
    """STAND-IN for ``flightid.globalmodel.Prediction`` (the attributes the study reads)."""

    value: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    std_mean: np.ndarray
    std_prediction: np.ndarray
    outside: np.ndarray
    distance_ratio: np.ndarray


@dataclass(frozen=True)
class StandInCoefficient:
    """STAND-IN for ``flightid.globalmodel.CoefficientModel``: every monomial of the fixed
    term set, fitted by ``least_squares``; a 95 % prediction interval
    ŷ ± t_{N−n_p, 0.975} sqrt(φᵀ C φ + s²_e) (C the coloured covariance, s²_e the residual
    mean square, globally or over the nearest data samples); outside the support where the
    k-NN distance ratio exceeds 2 or the leverage exceeds the data's largest."""

    terms: tuple[str, ...]
    exponents: np.ndarray
    scale: np.ndarray
    fit: object
    support: object
    residual_variance: str

    @property
    def pse(self) -> float:
        return float(self.fit.pse)

    def regressors(self, X: np.ndarray) -> np.ndarray:
        return np.prod((X / self.scale)[:, None, :] ** self.exponents[None], axis=2)

    def predict(self, X: np.ndarray, level: float = 0.95) -> StandInPrediction:
        from scipy import stats

        phi = self.regressors(X)
        value = phi @ self.fit.estimates
        # Var_mean = φᵀ C φ  (C: the coloured-residual covariance)
        var_mean = np.einsum("ij,jk,ik->i", phi, self.fit.covariance_default, phi)
        distance_ratio, neighbours = self.support.distance(X)
        if self.residual_variance == "local":
            s2 = np.mean(self.support.residuals[neighbours] ** 2, axis=1)
        else:
            s2 = np.full(len(X), self.fit.s2)
        std_prediction = np.sqrt(var_mean + s2)
        t = stats.t.ppf(0.5 + level / 2.0, self.fit.n_samples - self.fit.n_parameters)
        # leverage h₀ = φᵀ (ΦᵀΦ)⁻¹ φ against the data's largest
        leverage = np.einsum("ij,jk,ik->i", phi, self.support.gram_inverse, phi)
        outside = (distance_ratio > 2.0) | (leverage > self.support.leverage_max)
        return StandInPrediction(
            value,
            value - t * std_prediction,
            value + t * std_prediction,
            np.sqrt(var_mean),
            std_prediction,
            outside,
            distance_ratio,
        )


@dataclass(frozen=True)
class _StandInSupport:
    low: np.ndarray
    high: np.ndarray
    tree: object
    d_ref: float
    data_tree: object
    residuals: np.ndarray
    gram_inverse: np.ndarray
    leverage_max: float
    k: int = 5
    local_k: int = 100

    def coordinates(self, X: np.ndarray) -> np.ndarray:
        # v = (x − mid) / half-range
        return (X - (self.high + self.low) / 2) / ((self.high - self.low) / 2)

    def distance(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        v = self.coordinates(X)
        d, _ = self.tree.query(v, k=self.k)
        _, neighbours = self.data_tree.query(v, k=min(self.local_k, len(self.residuals)))
        return d[:, -1] / self.d_ref, neighbours


class StandInModel:
    """STAND-IN for ``flightid.globalmodel.GlobalModel``: ``coefficients`` and ``predict``."""

    def __init__(self, variables: Sequence[str], coefficients: Mapping[str, StandInCoefficient]):
        self.variables = tuple(variables)
        self.coefficients = dict(coefficients)

    def predict(self, points: Mapping[str, np.ndarray], level: float = 0.95):
        X = np.column_stack([np.asarray(points[v], dtype=float).ravel() for v in self.variables])
        return {name: c.predict(X, level) for name, c in self.coefficients.items()}


def _monomials(orders: Sequence[int], max_order: int) -> np.ndarray:
    ranges = [range(o + 1) for o in orders]
    grid = np.array(np.meshgrid(*ranges, indexing="ij")).reshape(len(orders), -1).T
    grid = grid[grid.sum(axis=1) <= max_order]
    return grid[np.lexsort((*grid.T[::-1], grid.sum(axis=1)))]


def stand_in_fitter(signals, responses, variables, *, settings, maneuver_index, dt, units=None):
    """STAND-IN for ``flightid.globalmodel.fit_global_model`` (same call): every monomial of
    ``settings.orders``/``max_order`` in the variables scaled by max|x|, no term selection;
    decimated per maneuver by ``settings.decimate``."""
    from scipy.spatial import cKDTree

    from flightid.regression.least_squares import least_squares

    index = np.asarray(maneuver_index)
    keep = np.concatenate(
        [np.flatnonzero(index == m)[:: settings.decimate] for m in np.unique(index)]
    )
    X = np.column_stack([np.asarray(signals[v], dtype=float)[keep] for v in variables])
    exponents = _monomials([settings.orders[v] for v in variables], settings.max_order)
    scale = np.max(np.abs(X), axis=0)
    labels = tuple(
        "*".join(f"{v}^{e}" if e > 1 else v for v, e in zip(variables, row, strict=True) if e)
        or "1"
        for row in exponents
    )
    low, high = X.min(axis=0), X.max(axis=0)
    v = (X - (high + low) / 2) / ((high - low) / 2)
    spacing = max(1, round(0.25 / (dt * settings.decimate)))
    reference = v[::spacing]
    tree = cKDTree(reference)
    d_ref = float(np.quantile(tree.query(reference, k=6)[0][:, -1], 0.99))
    coefficients = {}
    for name, channel in dict(responses).items():
        z = np.asarray(signals[channel], dtype=float)[keep]
        phi = np.prod((X / scale)[:, None, :] ** exponents[None], axis=2)
        fit = least_squares(phi, z, labels, maneuver_index=index[keep])
        gram_inverse = np.linalg.inv(phi.T @ phi)
        leverage = np.einsum("ij,jk,ik->i", phi, gram_inverse, phi)
        support = _StandInSupport(low, high, tree, d_ref, cKDTree(v), fit.residuals, gram_inverse,
                                  float(leverage.max()))  # fmt: skip
        coefficients[name] = StandInCoefficient(labels, exponents, scale, fit, support,
                                                settings.residual_variance)  # fmt: skip
    return StandInModel(variables, coefficients)


# ------------------------------------------------------------------------------ the measures
@dataclass(frozen=True)
class FitChoice:
    """The settings of the study's global models: the variables (``lef`` the leading-edge
    flap, rad), the highest power per variable and in total, the decimation per maneuver and
    PSE's σ²_max (``GlobalModelSettings``)."""

    name: str
    variables: tuple[str, ...] = FIT_VARIABLES
    orders: Mapping[str, int] = field(
        default_factory=lambda: {"alpha": 4, "Mach": 2, "de": 2, "qhat": 1, "lef": 1}
    )
    max_order: int = 3
    decimate: int = 5
    sigma2_max: str = "response"
    knots: Mapping[str, Sequence[float]] | None = None
    cross_with: tuple[str, ...] = ()

    def settings(self, settings_type: type, residual_variance: str):
        orders = {v: self.orders[v] for v in self.variables}
        extra = {} if self.sigma2_max == "response" else {"sigma2_max": self.sigma2_max}
        if self.knots:
            extra.update(knots=dict(self.knots), cross_with=self.cross_with)
        return settings_type(orders=orders, max_order=self.max_order, decimate=self.decimate,
                             residual_variance=residual_variance, **extra)  # fmt: skip


_ORDERS_4 = {"alpha": 4, "Mach": 2, "de": 2, "qhat": 1, "lef": 1}
_ORDERS_5 = {"alpha": 5, "Mach": 2, "de": 2, "qhat": 1, "lef": 1}
_WITH_LEF = (*FIT_VARIABLES, "lef")

# The study's settings, chosen for reasons of the data and the truth, not by the coverage:
# * the leading-edge flap ``lef`` is a variable: the truth's tables depend on it and the
#   flight controls move it in steps with α (0 → 0.262 rad at 5°, → 0.436 rad at 15°), which
#   no polynomial in (α, M, δh, q̂) can follow;
# * σ²_max = "full": "response" takes the variance of C_L over the whole envelope (σ ≈ 0.35,
#   about 10⁴ times the reconstruction noise's variance) as PSE's penalty scale, so that the
#   selection stops with a training residual several times the reconstruction noise;
#   "full" (s² of the fit on every candidate) is the noise-plus-lack-of-fit floor the data
#   can resolve;
# * α to the 5th power and total order 4: C_L(α) bends towards the stall, and with total
#   order 3 the α⁴ of the orders is never offered;
# * decimation 5 (10 Hz, 0.1 s): about the residuals' correlation time; more samples add no
#   information (the coloured-residual covariance accounts for the correlation), fewer thin
#   the support's reference set (in the full study the α-below flag drops to 0 at 10).
STUDY_CHOICE = FitChoice("+lef, full, alpha^5, order 4", _WITH_LEF, _ORDERS_5, max_order=4,
                         sigma2_max="full")  # fmt: skip

# the settings tried (``--explore``), the study's last
EXPLORED_CHOICES = (
    FitChoice("alpha, M, de, qhat (earlier)", FIT_VARIABLES, _ORDERS_4),
    FitChoice("+ full", FIT_VARIABLES, _ORDERS_4, sigma2_max="full"),
    FitChoice("decimate 1", FIT_VARIABLES, _ORDERS_4, decimate=1),
    FitChoice("decimate 10", FIT_VARIABLES, _ORDERS_4, decimate=10),
    FitChoice("alpha^5, order 4", FIT_VARIABLES, _ORDERS_5, max_order=4),
    FitChoice("full, alpha^5, order 4", FIT_VARIABLES, _ORDERS_5, max_order=4, sigma2_max="full"),
    FitChoice("+lef", _WITH_LEF, _ORDERS_4),
    FitChoice("+lef, full", _WITH_LEF, _ORDERS_4, sigma2_max="full"),
    FitChoice("+lef, full, decimate 1", _WITH_LEF, _ORDERS_4, decimate=1, sigma2_max="full"),
    # piecewise linear in α (ramps (α − κ)₊ at −5°…20° every 5°, each also times M, δh, q̂,
    # lef): the truth's tables are linear between breakpoints 5° apart; the study does not
    # use it, since it places the knots by knowledge of the truth a user would not have
    FitChoice(
        "+lef, full, alpha ramps every 5 deg",
        _WITH_LEF,
        {"alpha": 1, "Mach": 2, "de": 2, "qhat": 1, "lef": 1},
        sigma2_max="full",
        knots={"alpha": tuple(np.arange(-5.0, 20.5, 5.0) * DEG)},
        cross_with=("Mach", "de", "qhat", "lef"),
    ),  # fmt: skip
    STUDY_CHOICE,
)


POINT_VARIABLES = (*FIT_VARIABLES, "lef")


def _samples(flights: Sequence[Flight], which: str) -> dict[str, np.ndarray]:
    """The candidate variables (``POINT_VARIABLES``), coefficients, truth and maneuver index
    of ``flights`` stacked: ``which="measured"`` the variables as measured and the
    reconstructed coefficients (what the fit sees), ``"true"`` the true variables (where the
    held-out truth is)."""
    out: dict[str, list] = {k: [] for k in (*POINT_VARIABLES, *FIT_RESPONSES, "maneuver")}
    out.update({f"truth_{c}": [] for c in FIT_RESPONSES})
    for index, flight in enumerate(flights):
        source = flight.measured if which == "measured" else flight.true
        qhat = source["q"] * flight.geometry["cbar_m"] / (2.0 * source["V"])  # q̂ = q c̄ / 2V
        for name in POINT_VARIABLES:
            out[name].append(qhat if name == "qhat" else source[name])
        for c in FIT_RESPONSES:
            out[c].append(flight.coefficients[c])
            out[f"truth_{c}"].append(flight.truth[c])
        out["maneuver"].append(np.full(flight.time_s.size, index))
    return {k: np.concatenate(v) for k, v in out.items()}


def interval_measures(prediction, truth: np.ndarray) -> dict[str, float]:
    """Coverage and errors of one coefficient's prediction against the truth: the share of
    the truth inside the prediction interval where the model says it is inside its support,
    the RMS error inside and outside the flag, the share flagged outside."""
    outside = np.asarray(prediction.outside, dtype=bool)
    inside = ~outside
    error = np.asarray(prediction.value) - truth
    covered = (np.asarray(prediction.lower) <= truth) & (truth <= np.asarray(prediction.upper))

    def rms(mask: np.ndarray) -> float:
        return float(np.sqrt(np.mean(error[mask] ** 2))) if mask.any() else float("nan")

    return {
        "n": int(truth.size),
        "n_inside": int(inside.sum()),
        "coverage_inside": float(covered[inside].mean()) if inside.any() else float("nan"),
        "rms_inside": rms(inside),
        "rms_outside": rms(outside),
        "flagged": float(outside.mean()),
    }


def trim_schedule(alpha: np.ndarray, de: np.ndarray, bin_rad: float = 2 * DEG):
    """δh as a function of α from the data (the median per 2° bin of α, interpolated, held
    constant beyond the data): the grid's trim-like elevator."""
    edges = np.arange(alpha.min(), alpha.max() + bin_rad, bin_rad)
    which = np.digitize(alpha, edges)
    centres, medians = [], []
    for k in np.unique(which):
        centres.append(float(np.median(alpha[which == k])))
        medians.append(float(np.median(de[which == k])))
    return lambda a: np.interp(a, centres, medians)


def grid_points(quick: bool, schedule) -> dict[str, np.ndarray]:
    """The grid of the carpets and the extrapolation check: α from −10° to 40° in 1° steps ×
    Mach 0.3…1.0 (steps 0.05; quick 0.1), δh at the data's trim schedule, q̂ = 0, the
    leading-edge flap where the flight controls put it (``lef_schedule``)."""
    alpha = np.arange(-10.0, 40.5, 1.0) * DEG
    mach = np.round(np.arange(0.3, 1.001, 0.1 if quick else 0.05), 2)
    A, M = np.meshgrid(alpha, mach)  # (n_mach, n_alpha)
    return {"alpha": A, "Mach": M, "de": schedule(A), "qhat": np.zeros_like(A),
            "lef": lef_schedule(A, M)}  # fmt: skip


def _fitter_and_settings(fitter, settings_type):
    if fitter is None:  # the package under study
        from flightid.globalmodel import GlobalModelSettings, fit_global_model

        return fit_global_model, GlobalModelSettings
    return fitter, settings_type or StandInSettings


def mean_band_coverage(prediction, truth: np.ndarray) -> float:
    """Share of the truth inside the mean band ŷ ± t σ_mean where the model says it is inside
    its support; t is the interval's own quantile, (upper − ŷ) / σ_prediction."""
    value = np.asarray(prediction.value)
    t = (np.asarray(prediction.upper) - value) / np.asarray(prediction.std_prediction)
    half = t * np.asarray(prediction.std_mean)
    inside = ~np.asarray(prediction.outside, dtype=bool)
    covered = np.abs(value - truth) <= half
    return float(covered[inside].mean()) if inside.any() else float("nan")


def function_interval_coverage(prediction, truth: np.ndarray) -> float:
    """Share of the truth inside the interval of the coefficient itself
    (``function_lower`` … ``function_upper``: the mean band widened by the model-error
    variance, without the measurement noise) where the model says it is inside its support;
    NaN where the prediction has no such interval."""
    lower = getattr(prediction, "function_lower", None)
    upper = getattr(prediction, "function_upper", None)
    if lower is None or upper is None:
        return float("nan")
    inside = ~np.asarray(prediction.outside, dtype=bool)
    covered = (np.asarray(lower) <= truth) & (truth <= np.asarray(upper))
    return float(covered[inside].mean()) if inside.any() else float("nan")


def _flagged_share(outside: np.ndarray, mask: np.ndarray) -> float:
    """Share of the points under ``mask`` flagged outside (NaN where there are none)."""
    mask = np.asarray(mask).ravel()
    return float(outside[mask].mean()) if mask.any() else float("nan")


def _coefficient_measures(model, c: str, predictions: Mapping, data: Mapping) -> dict:
    """One coefficient's measures (``fit_and_measure``)."""
    held, grid = predictions["held"][c], predictions["grid"][c]
    outside = np.asarray(grid.outside, dtype=bool)
    shape = data["grid"]["alpha"].shape
    held_truth, grid_truth = data["held"][f"truth_{c}"], data["grid_truth"][c].ravel()
    measured = interval_measures(predictions["held_measured"][c], data["held_measured"][c])
    keys = ["value", "lower", "upper", "outside"]
    keys += [k for k in ("function_lower", "function_upper") if hasattr(grid, k)]
    carpet = {k: np.asarray(getattr(grid, k)).reshape(shape).tolist() for k in keys}
    carpet["truth"] = data["grid_truth"][c].tolist()
    return {
        "terms": list(model.coefficients[c].terms),
        "pse": float(model.coefficients[c].pse),
        "held_out": interval_measures(held, held_truth),
        "held_out_measured_coverage": measured["coverage_inside"],
        "held_out_mean_band_coverage": mean_band_coverage(held, held_truth),
        "held_out_function_coverage": function_interval_coverage(held, held_truth),
        "grid": interval_measures(grid, grid_truth),
        "grid_function_coverage": function_interval_coverage(grid, grid_truth),
        "beyond_flagged": _flagged_share(outside, data["beyond"]),
        "below_flagged": _flagged_share(outside, data["below"]),
        "mach_beyond_flagged": _flagged_share(outside, data["mach_beyond"]),
        "carpet": carpet,
    }


def fit_and_measure(
    flights: Sequence[Flight],
    truth_oracle: TruthOracle,
    quick: bool,
    fitter: Callable | None = None,
    settings_type: type | None = None,
    choice: FitChoice = STUDY_CHOICE,
    variances: Sequence[str] | None = None,
) -> dict:
    """Fit C_L, C_D, C_m over ``choice.variables`` to the reconstructed coefficients of the
    flights not held out (``fitter``: default ``flightid.globalmodel.fit_global_model``),
    then measure (``interval_measures``) on the held-out maneuvers (at their true states
    against their per-sample truth; also the interval's coverage of the reconstructed
    coefficient at the measured states, what a prediction interval promises, and the mean
    band's and the function interval's coverage of the truth) and on the grid (against
    ``truth_oracle``), once per residual variance (``variances``; default "global", the full
    study also "local"). Returns the measures, the selected terms, PSE, the grid's carpets
    and the extrapolation checks (α more than 5° above or below the data, Mach more than
    0.05 above it)."""
    fit, settings_type = _fitter_and_settings(fitter, settings_type)
    variables = choice.variables
    train = _samples([f for f in flights if not f.held_out], "measured")
    held = _samples([f for f in flights if f.held_out], "true")
    held_measured = _samples([f for f in flights if f.held_out], "measured")
    grid = grid_points(quick, trim_schedule(train["alpha"], train["de"]))
    alpha_min, alpha_max = float(train["alpha"].min()), float(train["alpha"].max())
    mach_max = float(train["Mach"].max())
    data = {
        "held": held,
        "held_measured": held_measured,
        "grid": grid,
        "grid_truth": truth_oracle({k: grid[k] for k in POINT_VARIABLES}),
        "beyond": grid["alpha"] > alpha_max + 5 * DEG,
        "below": grid["alpha"] < alpha_min - 5 * DEG,
        "mach_beyond": grid["Mach"] > mach_max + 0.05,
    }
    results: dict = {"alpha_data_max_deg": alpha_max / DEG, "alpha_data_min_deg": alpha_min / DEG,
                     "mach_data_max": mach_max, "choice": _choice_record(choice),
                     "runs": {}}  # fmt: skip
    if variances is None:
        variances = ("global",) if quick else ("global", "local")
    units = {"alpha": "rad", "Mach": "1", "de": "rad", "qhat": "1", "lef": "rad"}
    for variance in variances:
        model = fit({k: train[k] for k in (*variables, *FIT_RESPONSES)},
                    responses={c: c for c in FIT_RESPONSES}, variables=list(variables),
                    settings=choice.settings(settings_type, variance),
                    maneuver_index=train["maneuver"], dt=1.0 / SAMPLE_HZ,
                    units={v: units[v] for v in variables})  # fmt: skip
        predictions = {
            "held": model.predict({k: held[k] for k in variables}),
            "held_measured": model.predict({k: held_measured[k] for k in variables}),
            "grid": model.predict({k: grid[k].ravel() for k in variables}),
        }
        results["runs"][variance] = {
            c: _coefficient_measures(model, c, predictions, data) for c in FIT_RESPONSES
        }
    results["grid"] = {
        "alpha_deg": (grid["alpha"][0] / DEG).tolist(),
        "Mach": grid["Mach"][:, 0].tolist(),
        "de_rad": grid["de"].tolist(),
        "lef_rad": grid["lef"].tolist(),
    }
    thin = slice(None, None, 25)
    results["data"] = {
        "alpha_deg": (train["alpha"][thin] / DEG).tolist(),
        "Mach": train["Mach"][thin].tolist(),
        **{c: train[c][thin].tolist() for c in FIT_RESPONSES},
    }
    return results


def _choice_record(choice: FitChoice) -> dict:
    knots = {k: [float(x) for x in v] for k, v in (choice.knots or {}).items()} or None
    return {"name": choice.name, "variables": list(choice.variables),
            "orders": {v: choice.orders[v] for v in choice.variables},
            "max_order": choice.max_order, "decimate": choice.decimate,
            "sigma2_max": choice.sigma2_max, "knots": knots,
            "cross_with": list(choice.cross_with)}  # fmt: skip


def noise_share(flights: Sequence[Flight]) -> dict[str, dict[str, float]]:
    """Per coefficient: RMS of (reconstructed − truth) over all samples, the truth's standard
    deviation, and their ratio (the reconstruction-noise share)."""
    out = {}
    for c in COEFFICIENTS:
        error = np.concatenate([f.coefficients[c] - f.truth[c] for f in flights])
        truth = np.concatenate([f.truth[c] for f in flights])
        rms, spread = float(np.sqrt(np.mean(error**2))), float(np.std(truth))
        out[c] = {
            "rms": rms,
            "truth_std": spread,
            "share": rms / spread if spread > 0 else float("nan"),
        }
    return out


# ---------------------------------------------------------------------- the study and output
COVERAGE_GOAL = (0.90, 0.98)
BEYOND_FLAGGED_GOAL = 0.90


def fly_all(oracle: TruthOracle, quick: bool, seed: int = 29) -> list[Flight]:
    """Every maneuver at every condition (quick: ``QUICK_CONDITIONS``, shorter maneuvers)."""
    conditions = QUICK_CONDITIONS if quick else FULL_CONDITIONS
    designs = maneuver_designs(quick)
    return [
        f for i, c in enumerate(conditions) for f in fly_condition(c, designs, oracle, seed + i)
    ]


def study(quick: bool = False, fitter: Callable | None = None, settings_type: type | None = None,
          write_data: Path | None = None, explore: bool = False) -> dict:  # fmt: skip
    """Fly, reconstruct, fit and measure (module docstring); the results of
    ``fit_and_measure`` with ``STUDY_CHOICE`` plus the reconstruction-noise share, sample
    counts and wall times; ``explore``: also the rows of ``explore_choices``."""
    start = time.perf_counter()
    with truth_oracle() as oracle:
        flights = fly_all(oracle, quick)
        flown = time.perf_counter()
        if write_data is not None:
            write_flights(flights, write_data)
        results = fit_and_measure(
            flights, oracle, quick, fitter=fitter, settings_type=settings_type
        )
        if explore:
            results["explored"] = explore_choices(flights, oracle, quick, fitter, settings_type)
    results["noise"] = noise_share(flights)
    results["samples"] = {
        "fit": int(sum(f.time_s.size for f in flights if not f.held_out)),
        "held_out": int(sum(f.time_s.size for f in flights if f.held_out)),
        "maneuvers": len(flights),
        "conditions": len(QUICK_CONDITIONS if quick else FULL_CONDITIONS),
    }
    results["wall_s"] = {"flights": flown - start, "total": time.perf_counter() - start}
    results["quick"] = quick
    return results


def explore_choices(
    flights: Sequence[Flight],
    oracle: TruthOracle,
    quick: bool,
    fitter: Callable | None = None,
    settings_type: type | None = None,
    choices: Sequence[FitChoice] = EXPLORED_CHOICES,
) -> list[dict]:
    """One row per setting and coefficient (residual variance "global"): terms, PSE, the
    held-out RMS error and interval coverages, the grid RMS error inside the support."""
    rows = []
    for choice in choices:
        results = fit_and_measure(flights, oracle, quick, fitter, settings_type, choice=choice,
                                  variances=("global",))  # fmt: skip
        for c in FIT_RESPONSES:
            r = results["runs"]["global"][c]
            rows.append({
                "choice": choice.name, "coefficient": c, "terms": len(r["terms"]),
                "pse": r["pse"], "held_out_rms": r["held_out"]["rms_inside"],
                "pi_covers_truth": r["held_out"]["coverage_inside"],
                "pi_covers_measured": r["held_out_measured_coverage"],
                "function_covers_truth": r["held_out_function_coverage"],
                "grid_rms_inside": r["grid"]["rms_inside"],
            })  # fmt: skip
    return rows


def format_explored(rows: Sequence[Mapping]) -> str:
    """The table of the settings tried (``explore_choices``)."""
    lines = [
        "| settings | coefficient | terms | PSE | held-out RMS | PI covers truth | "
        "PI covers measured | function interval covers truth | grid RMS inside |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['choice']} | {r['coefficient']} | {r['terms']} | {r['pse']:.3e} | "
            f"{_number(r['held_out_rms'], 4)} | {_number(r['pi_covers_truth'])} | "
            f"{_number(r['pi_covers_measured'])} | {_na(r['function_covers_truth'])} | "
            f"{_number(r['grid_rms_inside'], 4)} |"
        )
    return "\n".join(lines)


def _coverage_check(c: str, r: Mapping) -> tuple[bool, str]:
    """The coverage goal on the function interval where the model has one, else on the
    prediction interval."""
    low, high = COVERAGE_GOAL
    cover = r.get("held_out_function_coverage", float("nan"))
    what = "function interval"
    if not np.isfinite(cover):
        cover, what = r["held_out"]["coverage_inside"], "prediction interval"
    ok = bool(low <= cover <= high)
    return ok, (f"{c}: held-out truth inside the 95 % {what} (inside the support) {cover:.3f} "
                f"in [{low:.2f}, {high:.2f}]")  # fmt: skip


def checks(results: Mapping) -> list[tuple[bool, str]]:
    """The study's targets as (passed, line): coverage of the held-out truth inside the
    support within ``COVERAGE_GOAL`` per coefficient (residual variance "global"), by the
    95 % interval of the coefficient itself (``function_lower`` … ``function_upper``) where
    the model gives one, else by the prediction interval; and ≥ 90 % of the grid points with
    α beyond the data's largest + 5° flagged outside."""
    run = results["runs"]["global"]
    lines = [_coverage_check(c, run[c]) for c in FIT_RESPONSES]
    for c in FIT_RESPONSES:
        share = run[c]["beyond_flagged"]
        lines.append((share >= BEYOND_FLAGGED_GOAL,
                      f"{c}: grid points with alpha > data max + 5 deg flagged outside {share:.3f} "
                      f">= {BEYOND_FLAGGED_GOAL:.2f}"))  # fmt: skip
    return lines


def _number(x: float, digits: int = 3) -> str:
    return "–" if not np.isfinite(x) else f"{x:.{digits}f}"


def _na(x: float, digits: int = 3) -> str:
    """A measure the fitted model may not offer (the function interval): "n/a" if NaN."""
    return "n/a" if not np.isfinite(x) else f"{x:.{digits}f}"


def _settings_line(choice: Mapping) -> str:
    orders = ", ".join(f"{k} {v}" for k, v in choice["orders"].items())
    return (f"settings: variables {', '.join(choice['variables'])}; orders {orders}; "
            f"max_order {choice['max_order']}; sigma2_max {choice['sigma2_max']}; "
            f"decimate {choice['decimate']}")  # fmt: skip


def format_tables(results: Mapping) -> str:
    """The numbers region: the settings; per residual variance and coefficient the held-out
    and grid measures; the selected terms and PSE; the reconstruction-noise share."""
    s = results["samples"]
    lines = [
        "<!-- numbers: globalmodel-jsbsim -->",
        f"F-16 (JSBSim): {s['conditions']} trim conditions, {s['maneuvers']} maneuvers, "
        f"{s['fit']} samples fitted at 50 Hz (decimated by {results['choice']['decimate']}), "
        f"{s['held_out']} held out; data alpha {results['alpha_data_min_deg']:.1f} to "
        f"{results['alpha_data_max_deg']:.1f} deg, Mach up to {results['mach_data_max']:.2f}",
        _settings_line(results["choice"]),
        "",
        "| residual variance | coefficient | terms | PSE | held-out function interval covers "
        "truth | PI covers truth | PI covers measured | mean band covers truth | "
        "held-out RMS | held-out flagged |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for variance, run in results["runs"].items():
        for c in FIT_RESPONSES:
            r, h = run[c], run[c]["held_out"]
            lines.append(
                f"| {variance} | {c} | {len(r['terms'])} | {r['pse']:.3e} | "
                f"{_na(r['held_out_function_coverage'])} | {_number(h['coverage_inside'])} | "
                f"{_number(r['held_out_measured_coverage'])} | "
                f"{_number(r['held_out_mean_band_coverage'])} | {_number(h['rms_inside'], 4)} | "
                f"{_number(h['flagged'])} |"
            )
    lines += [
        "",
        "| residual variance | coefficient | grid function interval covers truth | "
        "grid PI covers truth | grid RMS inside | grid RMS outside | grid flagged | "
        "alpha > max + 5 deg flagged | alpha < min - 5 deg flagged | "
        "Mach > max + 0.05 flagged |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for variance, run in results["runs"].items():
        for c in FIT_RESPONSES:
            r, g = run[c], run[c]["grid"]
            lines.append(
                f"| {variance} | {c} | {_na(r['grid_function_coverage'])} | "
                f"{_number(g['coverage_inside'])} | "
                f"{_number(g['rms_inside'], 4)} | {_number(g['rms_outside'], 4)} | "
                f"{_number(g['flagged'])} | {_number(r['beyond_flagged'])} | "
                f"{_number(r['below_flagged'])} | {_number(r['mach_beyond_flagged'])} |"
            )
    lines += ["", "| coefficient | reconstruction RMS (measured − truth) | truth std | share |",
              "|---|---|---|---|"]  # fmt: skip
    for c, n in results["noise"].items():
        if c not in FIT_RESPONSES:
            continue  # no lateral maneuvers: the lateral truth is about zero
        lines.append(f"| {c} | {n['rms']:.2e} | {n['truth_std']:.2e} | {n['share']:.3f} |")
    lines.append("")
    for c in FIT_RESPONSES:
        lines.append(f"{c} terms (global): " + ", ".join(results["runs"]["global"][c]["terms"]))
    lines.append("<!-- /numbers -->")
    return "\n".join(lines)


def carpets(results: Mapping) -> dict:
    """The carpet data for the figures: the α grid (deg) × Mach values (δh and lef along
    the grid, the study's settings), per residual variance and coefficient the prediction
    (value, lower, upper; function_lower, function_upper where the model gives them), the
    truth and the flag, arrays (n_Mach, n_alpha); the fitted data (every 25th sample)."""
    return {
        "alpha_deg": results["grid"]["alpha_deg"],
        "Mach": results["grid"]["Mach"],
        "de_rad": results["grid"]["de_rad"],
        "lef_rad": results["grid"]["lef_rad"],
        "settings": results["choice"],
        "alpha_data_max_deg": results["alpha_data_max_deg"],
        "alpha_data_min_deg": results["alpha_data_min_deg"],
        "coefficients": {
            v: {c: run[c]["carpet"] for c in FIT_RESPONSES} for v, run in results["runs"].items()
        },
        "data": results["data"],
    }


# the columns of a written maneuver (SI): name, key of the measured signals
_CSV_COLUMNS = (
    ("alpha_rad", "alpha"),
    ("Mach", "Mach"),
    ("V_m_s", "V"),
    ("q_rad_s", "q"),
    ("qhat", "qhat"),
    ("de_rad", "de"),
    ("lef_rad", "lef"),
    ("qbar_Pa", "qbar"),
)
WRITE_HZ = 10.0  # the written maneuvers' sample rate


def maneuver_file_name(index: int, flight: Flight) -> str:
    """``NN_M040_10kft_multisine.csv``: the maneuver's number, trim Mach × 100, altitude."""
    c = flight.condition
    altitude = f"{c.altitude_ft / 1000:.0f}kft"
    return f"{index:02d}_M{round(100 * c.mach):03d}_{altitude}_{flight.maneuver}.csv"


def write_flights(flights: Sequence[Flight], folder: Path) -> None:
    """Each maneuver as CSV at ``WRITE_HZ`` (every 5th sample; the measured signals in SI
    with q̂ = q c̄ / 2V, the reconstructed C_L, C_D, C_m and the per-sample truth
    ``truth_*``) and ``flights.json`` (conditions, maneuvers, files, mass and geometry)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    step = round(SAMPLE_HZ / WRITE_HZ)
    header = ["time_s", *(c for c, _ in _CSV_COLUMNS), *FIT_RESPONSES,
              *(f"truth_{c}" for c in FIT_RESPONSES)]  # fmt: skip
    index = []
    for k, f in enumerate(flights):
        name = maneuver_file_name(k, f)
        columns = [f.time_s] + [f.measured[key] for _, key in _CSV_COLUMNS]
        columns += [f.coefficients[c] for c in FIT_RESPONSES]
        columns += [f.truth[c] for c in FIT_RESPONSES]
        np.savetxt(folder / name, np.column_stack(columns)[::step], delimiter=",",
                   header=",".join(header), comments="", fmt="%.6g")  # fmt: skip
        index.append({"file": name, "mach": f.condition.mach,
                      "altitude_ft": f.condition.altitude_ft, "maneuver": f.maneuver,
                      "held_out": f.held_out, "sample_hz": WRITE_HZ,
                      "geometry": f.geometry})  # fmt: skip
    (folder / "flights.json").write_text(json.dumps(index, indent=1) + "\n", encoding="utf-8")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="6 conditions, shorter maneuvers")
    parser.add_argument("--write-data", type=Path,
                        help="write the maneuvers as CSV (10 Hz) here")  # fmt: skip
    parser.add_argument("--explore", action="store_true",
                        help="also print the table of the settings tried")  # fmt: skip
    parser.add_argument("--carpets", type=Path, help="write the carpet data (JSON) here")
    parser.add_argument("--stand-in", action="store_true",
                        help="fit with this module's fixed-polynomial stand-in")  # fmt: skip
    args = parser.parse_args(argv)
    fitter = stand_in_fitter if args.stand_in else None
    results = study(args.quick, fitter=fitter, write_data=args.write_data, explore=args.explore)
    print("<!-- guide: docs/globalmodel.md -->")
    print(format_tables(results))
    if args.explore:
        print("\nsettings tried (residual variance global):")
        print(format_explored(results["explored"]))
    wall = results["wall_s"]
    print(f"wall time: flights and truth {wall['flights']:.1f} s, total {wall['total']:.1f} s")
    if args.carpets is not None:
        args.carpets.parent.mkdir(parents=True, exist_ok=True)
        from flightid.jsonout import dumps

        args.carpets.write_text(dumps(carpets(results)), encoding="utf-8")
    passed = checks(results)
    for ok, line in passed:
        print(("PASS " if ok else "FAIL ") + line)
    return 0 if all(ok for ok, _ in passed) else 1


if __name__ == "__main__":
    raise SystemExit(main())
