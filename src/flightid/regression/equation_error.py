"""Equation-error set-up for airplanes: measured coefficients and regressors (RP-1153 §2.A).

Forces. The accelerometers measure a = q̄ S C / (m g) (in g, [2.24–2.26]), so

    C_X = m g a_x / (q̄ S) − T_x / (q̄ S),   C_Y = m g a_y / (q̄ S),
    C_Z = m g a_z / (q̄ S) − T_z / (q̄ S)

where T_x, T_z are optional thrust force components (body axes) to take out of C_X, C_Z
(by default thrust stays folded into C_X and C_Z as in RP-1153).

Moments. Solving the rotational equations [2.8]–[2.10] of RP-1153 for the coefficients, with
Γ = I_x I_z − I_xz²:

    F1 = I_x ṗ − I_xz ṙ ,  F2 = I_z ṙ − I_xz ṗ        (inverse of [dp/dt, dr/dt] = …/Γ)
    C_l = (F1 − (I_y − I_z) q r − I_xz p q) / (q̄ S b)
    C_m = (I_y q̇ − (I_z − I_x) p r − I_xz (r² − p²)) / (q̄ S c̄)
    C_n = (F2 − (I_x − I_y) p q + I_xz q r) / (q̄ S b)

Angular accelerations are used as measured when given; otherwise they come from the rates by
the local-polynomial derivative of ``flightid.regression.differentiate``.

Regressors: α, β (rad), the non-dimensional rates p̂ = p b/(2V), q̂ = q c̄/(2V), r̂ = r b/(2V),
and the controls (rad); products and powers are formed later by the term language.

Units: any consistent system (SI, or slug–ft–s with g = 32.174 ft/s²); angles in rad, rates in
rad/s, accelerations in g. Mass properties and q̄ may be constants or series (N,).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from flightid.data.units import G0
from flightid.errors import InputError, describe
from flightid.regression.differentiate import smooth_derivative

__all__ = [
    "Airframe",
    "force_coefficients",
    "moment_coefficients",
    "nondimensional_rates",
    "equation_error_signals",
    "G_SI",
    "G_FT",
]

G_SI = G0  # m/s², standard gravity (flightid.data.units)
G_FT = G0 / 0.3048  # ft/s²: the same standard gravity in international feet (32.174 ft/s²)


@dataclass(frozen=True)
class Airframe:
    """Mass, inertia and geometry (constants or series of length N).

    Attributes:
        mass: m [kg or slug].
        S: wing area [m² or ft²]; b: span, cbar: mean chord [m or ft].
        Ix, Iy, Iz, Ixz: inertias [kg·m² or slug·ft²] (only those needed must be given).
        g: gravity in the same length unit [m/s² or ft/s²].
    """

    mass: float | np.ndarray
    S: float | np.ndarray
    b: float | np.ndarray = np.nan
    cbar: float | np.ndarray = np.nan
    Ix: float | np.ndarray = np.nan
    Iy: float | np.ndarray = np.nan
    Iz: float | np.ndarray = np.nan
    Ixz: float | np.ndarray = 0.0
    g: float = G_SI


def _series(value, n: int | None, argument: str) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.ndim > 1 or (array.ndim == 1 and n is not None and array.shape[0] != n):
        raise InputError(
            f"{argument}: expected a number or a series of {n} samples, got {describe(array)}"
        )
    if np.any(np.isnan(array)):
        raise InputError(f"{argument}: required here but not given (or NaN)")
    return array


def _length(*values) -> int | None:
    for v in values:
        a = np.asarray(v)
        if a.ndim == 1:
            return a.shape[0]
    return None


def force_coefficients(
    a_x: np.ndarray | None,
    a_y: np.ndarray | None,
    a_z: np.ndarray | None,
    qbar: float | np.ndarray,
    airframe: Airframe,
    thrust_x: float | np.ndarray = 0.0,
    thrust_z: float | np.ndarray = 0.0,
) -> dict[str, np.ndarray]:
    """C_X, C_Y, C_Z from body-axis accelerations (g units); None skips an axis.

    Args:
        a_x: longitudinal acceleration at the centre of gravity, g (None skips C_X).
        a_y: lateral acceleration at the centre of gravity, g (None skips C_Y).
        a_z: normal acceleration at the centre of gravity, g (None skips C_Z).
        qbar: dynamic pressure [Pa or lbf/ft²].
        airframe: needs mass, S and g.
        thrust_x: thrust force component along x to remove [N or lbf].
        thrust_z: thrust force component along z to remove [N or lbf].
    """
    n = _length(a_x, a_y, a_z)
    m = _series(airframe.mass, n, "airframe.mass")
    S = _series(airframe.S, n, "airframe.S")
    qS = _series(qbar, n, "qbar") * S
    out: dict[str, np.ndarray] = {}
    if a_x is not None:
        # C_X = (m g a_x − T_x) / (q̄ S)
        out["CX"] = (m * airframe.g * _series(a_x, n, "a_x") - thrust_x) / qS
    if a_y is not None:
        # C_Y = m g a_y / (q̄ S)
        out["CY"] = m * airframe.g * _series(a_y, n, "a_y") / qS
    if a_z is not None:
        # C_Z = (m g a_z − T_z) / (q̄ S)
        out["CZ"] = (m * airframe.g * _series(a_z, n, "a_z") - thrust_z) / qS
    return out


def moment_coefficients(
    p: np.ndarray,
    q: np.ndarray,
    r: np.ndarray,
    qbar: float | np.ndarray,
    airframe: Airframe,
    *,
    pdot: np.ndarray | None = None,
    qdot: np.ndarray | None = None,
    rdot: np.ndarray | None = None,
    dt: float | None = None,
    window: int | None = None,
    which: tuple[str, ...] = ("Cl", "Cm", "Cn"),
) -> dict[str, np.ndarray]:
    """C_l, C_m, C_n from rates (rad/s) and angular accelerations (rad/s²).

    Angular accelerations not given are computed from the rates with ``smooth_derivative``
    (needs ``dt`` in s; ``window`` samples, default about 0.4 s).
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    r = np.asarray(r, dtype=float)
    n = p.shape[0]
    for name, value in (("q", q), ("r", r)):
        if value.shape != p.shape:
            raise InputError(f"{name}: expected {n} samples like p, got {describe(value)}")

    def accel(given, rate, name):
        if given is not None:
            return _series(given, n, name)
        if dt is None:
            raise InputError(f"{name} or dt: give the measured {name} or the sampling interval dt")
        return smooth_derivative(rate, dt, window)

    S = _series(airframe.S, n, "airframe.S")
    qS = _series(qbar, n, "qbar") * S
    out: dict[str, np.ndarray] = {}
    unknown = sorted(set(which) - {"Cl", "Cm", "Cn"})
    if unknown:
        raise InputError(f"which: expected names among 'Cl', 'Cm', 'Cn', got {unknown}")
    if "Cm" in which:
        Ix = _series(airframe.Ix, n, "airframe.Ix")
        Iy = _series(airframe.Iy, n, "airframe.Iy")
        Iz = _series(airframe.Iz, n, "airframe.Iz")
        Ixz = _series(airframe.Ixz, n, "airframe.Ixz")
        cbar = _series(airframe.cbar, n, "airframe.cbar")
        qd = accel(qdot, q, "qdot")
        # C_m = (I_y q̇ − (I_z − I_x) p r − I_xz (r² − p²)) / (q̄ S c̄)
        out["Cm"] = (Iy * qd - (Iz - Ix) * p * r - Ixz * (r**2 - p**2)) / (qS * cbar)
    if "Cl" in which or "Cn" in which:
        Ix = _series(airframe.Ix, n, "airframe.Ix")
        Iy = _series(airframe.Iy, n, "airframe.Iy")
        Iz = _series(airframe.Iz, n, "airframe.Iz")
        Ixz = _series(airframe.Ixz, n, "airframe.Ixz")
        b = _series(airframe.b, n, "airframe.b")
        pd = accel(pdot, p, "pdot")
        rd = accel(rdot, r, "rdot")
        # F1 = I_x ṗ − I_xz ṙ ,  F2 = I_z ṙ − I_xz ṗ
        F1 = Ix * pd - Ixz * rd
        F2 = Iz * rd - Ixz * pd
        if "Cl" in which:
            # C_l = (F1 − (I_y − I_z) q r − I_xz p q) / (q̄ S b)
            out["Cl"] = (F1 - (Iy - Iz) * q * r - Ixz * p * q) / (qS * b)
        if "Cn" in which:
            # C_n = (F2 − (I_x − I_y) p q + I_xz q r) / (q̄ S b)
            out["Cn"] = (F2 - (Ix - Iy) * p * q + Ixz * q * r) / (qS * b)
    return out


def nondimensional_rates(
    p: np.ndarray | None,
    q: np.ndarray | None,
    r: np.ndarray | None,
    V: np.ndarray,
    airframe: Airframe,
) -> dict[str, np.ndarray]:
    """p̂ = p b/(2V), q̂ = q c̄/(2V), r̂ = r b/(2V); rates in rad/s, V in length unit/s."""
    V = np.asarray(V, dtype=float)
    n = V.shape[0] if V.ndim == 1 else None
    if np.any(V <= 0):
        raise InputError("V: airspeed must be positive to form non-dimensional rates")
    out: dict[str, np.ndarray] = {}
    if p is not None:
        out["phat"] = _series(p, n, "p") * _series(airframe.b, n, "airframe.b") / (2.0 * V)
    if q is not None:
        out["qhat"] = _series(q, n, "q") * _series(airframe.cbar, n, "airframe.cbar") / (2.0 * V)
    if r is not None:
        out["rhat"] = _series(r, n, "r") * _series(airframe.b, n, "airframe.b") / (2.0 * V)
    return out


def equation_error_signals(
    channels: Mapping[str, np.ndarray],
    airframe: Airframe,
    *,
    dt: float | None = None,
    window: int | None = None,
    thrust_x: float | np.ndarray = 0.0,
    thrust_z: float | np.ndarray = 0.0,
) -> dict[str, np.ndarray]:
    """All coefficients and regressors computable from the channels given.

    Recognised channel names (SI or ft units, angles rad, rates rad/s, accelerations g):
    ``V, alpha, beta, p, q, r, pdot, qdot, rdot, ax, ay, az, qbar`` and any control
    (``de``, ``da``, ``dr``, ...), which is passed through. Returns the input channels plus
    CX, CY, CZ (from the accelerations present), Cm (from q), Cl and Cn (when p and r are
    present and ṗ, ṙ are measured or ``dt`` is given to differentiate) and phat, qhat, rhat.
    """
    signals = {k: np.asarray(v, dtype=float) for k, v in channels.items()}
    if "qbar" not in signals:
        raise InputError("channels: 'qbar' (dynamic pressure) is needed for the coefficients")
    accels = [signals.get(k) for k in ("ax", "ay", "az")]
    if any(a is not None for a in accels):
        forces = force_coefficients(
            *accels, signals["qbar"], airframe, thrust_x=thrust_x, thrust_z=thrust_z
        )
        signals.update(forces)
    rates = [signals.get(k) for k in ("p", "q", "r")]
    if "V" in signals:
        signals.update(nondimensional_rates(*rates, signals["V"], airframe))
    if rates[1] is not None:
        zeros = np.zeros_like(rates[1])
        p = rates[0] if rates[0] is not None else zeros
        r = rates[2] if rates[2] is not None else zeros
        lateral = rates[0] is not None and rates[2] is not None
        lateral = lateral and (dt is not None or ("pdot" in signals and "rdot" in signals))
        which = ("Cl", "Cm", "Cn") if lateral else ("Cm",)
        signals.update(
            moment_coefficients(
                p,
                rates[1],
                r,
                signals["qbar"],
                airframe,
                pdot=signals.get("pdot"),
                qdot=signals.get("qdot"),
                rdot=signals.get("rdot"),
                dt=dt,
                window=window,
                which=which,
            )
        )
    return signals
