"""Fly an exported aircraft in JSBSim with recorded inputs (the optional ``jsbsim`` package).

``fly_jsbsim`` loads the folder ``write_jsbsim`` wrote, sets the initial state, and steps
JSBSim ``substeps`` times per sample, the inputs linear between samples (flightid's
``input_interpolation="linear"``), returning flightid's outputs (V, alpha, beta, theta, phi,
ax, ay, az, p, q, r, pdot, qdot, rdot; SI units, accelerations in g of the airplane, body
axes, a_z ≈ −1 in level flight).

JSBSim's frame order (1.3): a frame first integrates the state with the accelerations of the
previous frame, then computes the loads at the new state with the controls set before it.
So the inputs of time t_j are set before the frame that ends at t_j: the state and the loads
read after it belong together. With ``flat_earth`` (default) the folder's
``planet_flat.xml`` (a non-rotating sphere with the airplane's g) is loaded and the standard
gravity model (GM/r²) chosen, so that JSBSim integrates the equations flightid integrates.
The integrators are set to 4th-order Adams–Bashforth (JSBSim's code 5) for rates and
positions.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from flightid.errors import InputError
from flightid.export._jsbsim_terms import FT_M, LBF_N, THRUST_PROPERTY

__all__ = ["FLY_OUTPUTS", "fly_jsbsim", "initial_from_body_state"]

FLY_OUTPUTS = (
    "V", "alpha", "beta", "theta", "phi", "ax", "ay", "az", "p", "q", "r", "pdot", "qdot", "rdot",
)  # fmt: skip
_INTEGRATORS = (
    "simulation/integrator/rate/rotational",
    "simulation/integrator/rate/translational",
    "simulation/integrator/position/rotational",
    "simulation/integrator/position/translational",
)
_ADAMS_BASHFORTH_4 = 5


def _aerodynamics_file(aircraft, aerodynamics) -> Path | None:
    """The aerodynamics file to fly: None (the aircraft's own), draw k (an int ≥ 1) or a
    path (relative to the aircraft folder or absolute)."""
    if aerodynamics is None:
        return None
    if isinstance(aerodynamics, int) and not isinstance(aerodynamics, bool):
        if not 1 <= aerodynamics < len(aircraft.aerodynamics_files):
            raise InputError(
                f"aerodynamics: draw {aerodynamics} not written; the aircraft has draws 1 to "
                f"{len(aircraft.aerodynamics_files) - 1}"
            )
        return aircraft.aerodynamics_files[aerodynamics]
    path = Path(aerodynamics)
    path = path if path.is_absolute() else aircraft.folder / path
    if not path.is_file():
        raise InputError(f"aerodynamics: expected a draw number or a file, got {aerodynamics!r}")
    return path


def _load_model(fdm, aircraft, aerodynamics: Path | None) -> bool:
    """Load the aircraft, with its <aerodynamics file=…> pointing at ``aerodynamics`` (a
    copy of the aircraft file in a temporary folder) when given."""
    if aerodynamics is None:
        fdm.set_aircraft_path(str(aircraft.folder.parent))
        return fdm.load_model(aircraft.name)
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch) / aircraft.name
        folder.mkdir()
        text = aircraft.aircraft_file.read_text(encoding="utf-8")
        own = 'file="aerodynamics/nominal.xml"'
        if own not in text:
            raise InputError(f"aircraft: {aircraft.aircraft_file} has no {own}")
        text = text.replace(own, f'file="{aerodynamics.resolve()}"')
        (folder / aircraft.aircraft_file.name).write_text(text, encoding="utf-8")
        fdm.set_aircraft_path(scratch)
        return fdm.load_model(aircraft.name)


def _load(aircraft, flat_earth: bool, dt_s: float, aerodynamics: Path | None):
    os.environ.setdefault("JSBSIM_DEBUG", "0")  # no start-up banner
    import jsbsim

    fdm = jsbsim.FGFDMExec(os.path.dirname(jsbsim.__file__))
    fdm.set_debug_level(0)
    if flat_earth and not fdm.load_planet(str(aircraft.planet_file), False):
        raise InputError(f"aircraft: JSBSim could not load the planet {aircraft.planet_file}")
    if not _load_model(fdm, aircraft, aerodynamics):
        raise InputError(f"aircraft: JSBSim could not load {aircraft.aircraft_file}")
    if flat_earth:
        fdm["simulation/gravity-model"] = 0  # GM/r² of the flat planet
    for name in _INTEGRATORS:
        fdm[name] = _ADAMS_BASHFORTH_4
    fdm.set_dt(dt_s)
    return fdm


def _input_properties(aircraft, inputs: Mapping[str, np.ndarray]) -> dict[str, tuple[str, float]]:
    """input name → (JSBSim property, factor from the input's unit to the property's)."""
    wanted = {name: (prop, 1.0) for name, prop in aircraft.controls.items()}
    if aircraft.thrust_input is not None:
        # lbf per N
        wanted[aircraft.thrust_input] = (THRUST_PROPERTY, 1.0 / LBF_N)
    missing = sorted(set(wanted) - set(inputs))
    unknown = sorted(set(inputs) - set(wanted))
    if missing or unknown:
        raise InputError(
            f"inputs: the aircraft reads {sorted(wanted)}; missing {missing}, unknown {unknown}"
        )
    return wanted


def _set_initial(fdm, initial: Mapping[str, float], altitude_m: float) -> None:
    known = ("u", "v", "w", "p", "q", "r", "theta", "phi", "psi")
    unknown = sorted(set(initial) - set(known))
    if unknown:
        raise InputError(f"initial: unknown names {unknown}; expected some of {list(known)}")
    fdm["ic/h-sl-ft"] = altitude_m / FT_M
    for name in ("u", "v", "w"):
        fdm[f"ic/{name}-fps"] = float(initial.get(name, 0.0)) / FT_M
    for name in ("p", "q", "r"):
        fdm[f"ic/{name}-rad_sec"] = float(initial.get(name, 0.0))
    for name in ("theta", "phi", "psi"):
        fdm[f"ic/{name}-rad"] = float(initial.get(name, 0.0))


def _read(fdm, g: float) -> list[float]:
    """flightid's outputs from JSBSim's properties (SI, accelerations in g)."""
    mass = fdm["inertia/mass-slugs"]
    # a = F/m (ft/s²) · 0.3048 / g
    accel = [fdm[f"forces/fb{a}-total-lbs"] / mass * FT_M / g for a in "xyz"]
    return [
        fdm["velocities/vt-fps"] * FT_M,
        fdm["aero/alpha-rad"],
        fdm["aero/beta-rad"],
        fdm["attitude/theta-rad"],
        fdm["attitude/phi-rad"],
        *accel,
        fdm["velocities/p-rad_sec"],
        fdm["velocities/q-rad_sec"],
        fdm["velocities/r-rad_sec"],
        fdm["accelerations/pdot-rad_sec2"],
        fdm["accelerations/qdot-rad_sec2"],
        fdm["accelerations/rdot-rad_sec2"],
    ]


def fly_jsbsim(
    aircraft,
    time_s: np.ndarray,
    inputs: Mapping[str, np.ndarray],
    initial: Mapping[str, float],
    *,
    substeps: int = 10,
    flat_earth: bool = True,
    altitude_m: float = 1000.0,
    aerodynamics: int | str | Path | None = None,
) -> dict[str, np.ndarray]:
    """Outputs {name: (N,)} of the exported ``aircraft`` (a ``JSBSimAircraft``) flown in JSBSim.

    Args:
        aircraft: what ``write_jsbsim`` returned.
        time_s: uniform sample times, s.
        inputs: {control or thrust input name: (N,)} in the model's units (rad, N).
        initial: body velocities u, v, w (m/s), rates p, q, r (rad/s), Euler angles theta,
            phi, psi (rad); missing ones are 0.
        substeps: JSBSim steps per sample interval.
        flat_earth: load the folder's non-rotating planet (module docstring).
        altitude_m: initial altitude (m; matters only for JSBSim's atmosphere).
        aerodynamics: fly another aerodynamics file: a draw number k (``draw_000k.xml``) or
            a file; default the aircraft's own (nominal).
    """
    time_s = np.asarray(time_s, dtype=float)
    steps = np.diff(time_s)
    if time_s.ndim != 1 or len(time_s) < 2 or not np.allclose(steps, steps[0], rtol=1e-9):
        raise InputError("time_s: expected at least two uniform sample times, s")
    if not isinstance(substeps, int) or substeps < 1:
        raise InputError(f"substeps: expected an integer ≥ 1, got {substeps!r}")
    properties = _input_properties(aircraft, inputs)
    aero_file = _aerodynamics_file(aircraft, aerodynamics)
    series = {k: np.asarray(v, dtype=float) for k, v in inputs.items()}
    bad = [k for k, v in series.items() if v.shape != time_s.shape]
    if bad:
        raise InputError(f"inputs: {bad} do not have one value per sample ({len(time_s)})")
    dt = float(steps[0]) / substeps
    fdm = _load(aircraft, flat_earth, dt, aero_file)
    _set_initial(fdm, initial, altitude_m)

    def set_inputs(t: float) -> None:
        # u(t) linear between samples
        for name, (prop, factor) in properties.items():
            fdm[prop] = float(np.interp(t, time_s, series[name])) * factor

    set_inputs(time_s[0])
    fdm.run_ic()
    rows = [_read(fdm, aircraft.g)]
    for k in range(1, len(time_s)):
        for j in range(1, substeps + 1):
            # the inputs of the frame's end time: the loads read after it use them
            set_inputs(time_s[k - 1] + j * dt)
            fdm.run()
        rows.append(_read(fdm, aircraft.g))
    table = np.array(rows)
    if not np.all(np.isfinite(table)):
        raise InputError("fly_jsbsim: JSBSim produced non-finite values")
    return {name: table[:, i] for i, name in enumerate(FLY_OUTPUTS)}


def initial_from_body_state(x: np.ndarray) -> dict[str, float]:
    """``initial`` of ``fly_jsbsim`` from a body state (u, v, w, p, q, r, l_xz, l_yz, l_zz):
    Θ = asin(−l_xz), Φ = atan2(l_yz, l_zz)."""
    x = np.asarray(x, dtype=float)
    names = ("u", "v", "w", "p", "q", "r")
    initial = {n: float(v) for n, v in zip(names, x[:6], strict=True)}
    initial["theta"] = math.asin(max(-1.0, min(1.0, -x[6])))
    initial["phi"] = math.atan2(x[7], x[8])
    return initial
