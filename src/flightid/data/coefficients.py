"""Aerodynamic force and moment coefficients from measured motion (as FVSysID's ATTAS data
preparation ``umr_reg_attas`` computes them).

Newton and Euler for a rigid body, solved for the aerodynamic force and moment, sample by
sample (no memory between samples, so maneuver boundaries need no care). Body axes
(x forward, y right, z down); accelerations are the specific forces at the CG (m/s², as
accelerometers measure them, gravity not included), rates in rad/s, angular accelerations
in rad/s², q̄ in Pa, masses in kg, inertias in kg·m², lengths in m, thrust in N.

Forces. With the thrust of engine i, T_i (N), along d_i = (cos ε_i, 0, −sin ε_i)
(ε_i the engine incidence in rad, positive with the thrust line pointing nose-up):

    m a = F_aero + Σ_i T_i d_i
    (C_X, C_Y, C_Z) = (m a − Σ_i T_i d_i) / (q̄ S)
    C_D = −C_X cos α − C_Z sin α,   C_L = C_X sin α − C_Z cos α

Moments about the CG. With the inertia tensor
I = [[I_x, −I_xy, −I_xz], [−I_xy, I_y, −I_yz], [−I_xz, −I_yz, I_z]]:

    M_aero,CG = I ω̇ + ω × (I ω) − Σ_i r_Ei × (T_i d_i)
    C_l,CG = L / (q̄ S b),   C_m,CG = M / (q̄ S c̄),   C_n,CG = N / (q̄ S b)

(b is the lateral reference length: the span, or b/2 where a reference normalises by
it, as FVSysID's ATTAS set-up does with b/2 = 10.75 m.) With I_xy = I_yz = 0 and two
engines at (x_E, ∓y_E, z_E) with ε = 0 these are the moment equations of that set-up
(C_l,CG = [I_x ṗ − I_xz ṙ − I_xz p q − (I_y − I_z) q r] / (q̄ S b/2), ...).

Moments about the aerodynamic reference point r_AC (from the CG):

    M_AC = M_CG − r_AC × F_aero
    C_l = C_l,CG − (y_AC C_Z − z_AC C_Y)/b
    C_m = C_m,CG − (z_AC C_X − x_AC C_Z)/c̄
    C_n = C_n,CG − (x_AC C_Y − y_AC C_X)/b

Omitted: rotor angular momentum (gyroscopic engine terms), propeller torque, thrust side
components (engines are in planes parallel to the x–z plane), time-varying mass and inertia.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from flightid.data.preprocess import PreprocessError
from flightid.data.transfer import cross3

__all__ = ["MassGeometry", "Engine", "aero_coefficients", "COEFFICIENTS"]

# the coefficients aero_coefficients returns, in this order
COEFFICIENTS = ("CX", "CY", "CZ", "Cl", "Cm", "Cn", "CL", "CD")


@dataclass(frozen=True)
class MassGeometry:
    """Mass, inertia and reference geometry (SI).

    Attributes:
        mass_kg: the mass m.
        Ix, Iy, Iz, Ixz, Ixy, Iyz: inertias in kg·m² (products of inertia with the sign
            convention of the tensor in the module docstring; I_xz > 0 for most airplanes).
        S_m2: the reference area S.
        cbar_m: the longitudinal reference length c̄ (C_m).
        b_m: the lateral reference length b (C_l, C_n): the span, or b/2.
        reference_point_m: the aerodynamic reference point (x, y, z) from the CG in m.
    """

    mass_kg: float
    Ix: float
    Iy: float
    Iz: float
    S_m2: float
    cbar_m: float
    b_m: float
    Ixz: float = 0.0
    Ixy: float = 0.0
    Iyz: float = 0.0
    reference_point_m: Sequence[float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("mass_kg", "Ix", "Iy", "Iz", "S_m2", "cbar_m", "b_m"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise PreprocessError(f"{name}: expected a positive number, got {value!r}")
        point = np.asarray(self.reference_point_m, dtype=float)
        if point.shape != (3,) or not np.all(np.isfinite(point)):
            raise PreprocessError(
                f"reference_point_m: expected 3 numbers (x, y, z) in m, got "
                f"{self.reference_point_m!r}"
            )


@dataclass(frozen=True)
class Engine:
    """One engine: its thrust (N, per sample), position from the CG (m) and incidence
    (rad, positive with the thrust line pointing nose-up)."""

    thrust_N: np.ndarray
    position_m: Sequence[float]
    incidence_rad: float = 0.0


def aero_coefficients(
    ax_m_s2: np.ndarray,
    ay_m_s2: np.ndarray,
    az_m_s2: np.ndarray,
    p_rad_s: np.ndarray,
    q_rad_s: np.ndarray,
    r_rad_s: np.ndarray,
    pdot_rad_s2: np.ndarray,
    qdot_rad_s2: np.ndarray,
    rdot_rad_s2: np.ndarray,
    qbar_Pa: np.ndarray,
    alpha_rad: np.ndarray,
    geometry: MassGeometry,
    engines: Sequence[Engine] = (),
) -> Mapping[str, np.ndarray]:
    """The coefficients ``COEFFICIENTS`` (dimensionless) per sample; see the module
    docstring for the equations. Accelerations are at the CG."""
    g = geometry
    ax, ay, az = (np.asarray(a, dtype=float) for a in (ax_m_s2, ay_m_s2, az_m_s2))
    omega = tuple(np.asarray(w, dtype=float) for w in (p_rad_s, q_rad_s, r_rad_s))
    omega_dot = tuple(np.asarray(w, dtype=float) for w in (pdot_rad_s2, qdot_rad_s2, rdot_rad_s2))
    qbar = np.asarray(qbar_Pa, dtype=float)
    alpha = np.asarray(alpha_rad, dtype=float)
    if np.any(qbar <= 0):
        k = int(np.argmax(qbar <= 0))
        raise PreprocessError(
            f"qbar: expected a positive dynamic pressure (Pa), got {float(qbar.flat[k]):.6g} at "
            f"sample {k + 1}"
        )
    # thrust force Σ T_i d_i and moment Σ r_Ei × (T_i d_i),  d_i = (cos ε_i, 0, −sin ε_i)
    thrust = [np.zeros_like(ax), np.zeros_like(ax), np.zeros_like(ax)]
    thrust_moment = [np.zeros_like(ax), np.zeros_like(ax), np.zeros_like(ax)]
    for engine in engines:
        position = np.asarray(engine.position_m, dtype=float)
        if position.shape != (3,):
            raise PreprocessError(
                f"engine position: expected 3 numbers (x, y, z) in m, got {engine.position_m!r}"
            )
        T = np.asarray(engine.thrust_N, dtype=float)
        force = (
            T * np.cos(engine.incidence_rad),
            np.zeros_like(T),
            -T * np.sin(engine.incidence_rad),
        )
        moment = cross3(tuple(position), force)
        for i in range(3):
            thrust[i] = thrust[i] + force[i]
            thrust_moment[i] = thrust_moment[i] + moment[i]
    force_scale = qbar * g.S_m2  # N per unit coefficient
    # C_F = (m a − Σ T_i d_i) / (q̄ S)
    CX = (g.mass_kg * ax - thrust[0]) / force_scale
    CY = (g.mass_kg * ay - thrust[1]) / force_scale
    CZ = (g.mass_kg * az - thrust[2]) / force_scale
    # I ω with I = [[I_x, −I_xy, −I_xz], [−I_xy, I_y, −I_yz], [−I_xz, −I_yz, I_z]]
    p, q, r = omega
    pd, qd, rd = omega_dot
    h = (
        g.Ix * p - g.Ixy * q - g.Ixz * r,
        -g.Ixy * p + g.Iy * q - g.Iyz * r,
        -g.Ixz * p - g.Iyz * q + g.Iz * r,
    )
    # I ω̇
    h_dot = (
        g.Ix * pd - g.Ixy * qd - g.Ixz * rd,
        -g.Ixy * pd + g.Iy * qd - g.Iyz * rd,
        -g.Ixz * pd - g.Iyz * qd + g.Iz * rd,
    )
    gyro = cross3(omega, h)
    # M_aero,CG = I ω̇ + ω × (I ω) − Σ r_Ei × (T_i d_i)
    L, M, N = (h_dot[i] + gyro[i] - thrust_moment[i] for i in range(3))
    x_ac, y_ac, z_ac = (float(c) for c in g.reference_point_m)
    # C_l = L/(q̄ S b) − (y_AC C_Z − z_AC C_Y)/b
    Cl = L / (force_scale * g.b_m) - (y_ac * CZ - z_ac * CY) / g.b_m
    # C_m = M/(q̄ S c̄) − (z_AC C_X − x_AC C_Z)/c̄
    Cm = M / (force_scale * g.cbar_m) - (z_ac * CX - x_ac * CZ) / g.cbar_m
    # C_n = N/(q̄ S b) − (x_AC C_Y − y_AC C_X)/b
    Cn = N / (force_scale * g.b_m) - (x_ac * CY - y_ac * CX) / g.b_m
    # C_L = C_X sin α − C_Z cos α,   C_D = −C_X cos α − C_Z sin α
    CL = CX * np.sin(alpha) - CZ * np.cos(alpha)
    CD = -CX * np.cos(alpha) - CZ * np.sin(alpha)
    return dict(zip(COEFFICIENTS, (CX, CY, CZ, Cl, Cm, Cn, CL, CD), strict=True))
