"""Rigid-body transfer of measured air data and accelerations between positions.

Positions are body-axis vectors (x forward, y right, z down) in m, relative to the centre of
gravity (CG); angular rates ω = (p, q, r) in rad/s, angular accelerations ω̇ = (ṗ, q̇, ṙ) in
rad/s². Every function works sample by sample on 1-D arrays (or scalars), so a maneuver
boundary needs no special care: there is no memory from one sample to the next.

Air data (``transfer_air_data``): the air-relative velocity of a point at r is
v(r) = v_CG + ω × r, so from a sensor at r_s to a point r_t

    v_t = v_s + ω × (r_t − r_s)

with v_s = V (cos β cos α, sin β, cos β sin α) and α_t = atan2(w_t, u_t),
β_t = asin(v_t / V_t), V_t = |v_t|. For r_t = 0 (the CG) and a noseboom at r_s = r_NB these
are the noseboom-to-CG equations of FVSysID's ATTAS data preparation (``umr_reg_attas``):
u = u_NB + y_NB r − z_NB q, v = v_NB + z_NB p − x_NB r, w = w_NB + x_NB q − y_NB p.

Accelerations (``transfer_accelerations``): a point at r of a rigid body has the specific
force a(r) = a_CG + ω̇ × r + ω × (ω × r), so from a sensor at r_s to a point r_t, with
d = r_t − r_s,

    a_t = a_s + ω̇ × d + ω × (ω × d)

For r_t = 0 and an accelerometer at r_s = r_A these are the accelerometer-to-CG equations of
the same set-up (a_xCG = a_x + x_A(q² + r²) − y_A(p q − ṙ) − z_A(p r + q̇), ...).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from flightid.data.preprocess import PreprocessError

__all__ = ["transfer_air_data", "transfer_accelerations"]


def _vector(position: Sequence[float], what: str) -> np.ndarray:
    vector = np.asarray(position, dtype=float)
    if vector.shape != (3,) or not np.all(np.isfinite(vector)):
        raise PreprocessError(f"{what}: expected 3 finite numbers (x, y, z) in m, got {position!r}")
    return vector


def cross3(a: tuple, b: tuple) -> tuple:
    """a × b for vectors given as 3-tuples of arrays or numbers."""
    # (a_y b_z − a_z b_y, a_z b_x − a_x b_z, a_x b_y − a_y b_x)
    return (
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    )


def transfer_air_data(
    V_m_s: np.ndarray,
    alpha_rad: np.ndarray,
    beta_rad: np.ndarray,
    p_rad_s: np.ndarray,
    q_rad_s: np.ndarray,
    r_rad_s: np.ndarray,
    sensor_m: Sequence[float],
    target_m: Sequence[float] = (0.0, 0.0, 0.0),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(V_m_s, alpha_rad, beta_rad) at ``target_m`` from air data measured at ``sensor_m``
    (body axes, m from the CG; default target: the CG). See the module docstring."""
    d = tuple(_vector(target_m, "target") - _vector(sensor_m, "sensor"))
    V, alpha, beta = (np.asarray(v, dtype=float) for v in (V_m_s, alpha_rad, beta_rad))
    # v_s = V (cos β cos α, sin β, cos β sin α)
    u_s = V * np.cos(beta) * np.cos(alpha)
    v_s = V * np.sin(beta)
    w_s = V * np.cos(beta) * np.sin(alpha)
    omega = (np.asarray(p_rad_s, float), np.asarray(q_rad_s, float), np.asarray(r_rad_s, float))
    # v_t = v_s + ω × (r_t − r_s)
    du, dv, dw = cross3(omega, d)
    u, v, w = u_s + du, v_s + dv, w_s + dw
    # V_t = √(u² + v² + w²),  α_t = atan2(w, u),  β_t = asin(v / V_t)
    V_t = np.sqrt(u * u + v * v + w * w)
    return V_t, np.arctan2(w, u), np.arcsin(v / V_t)


def transfer_accelerations(
    ax_m_s2: np.ndarray,
    ay_m_s2: np.ndarray,
    az_m_s2: np.ndarray,
    p_rad_s: np.ndarray,
    q_rad_s: np.ndarray,
    r_rad_s: np.ndarray,
    pdot_rad_s2: np.ndarray,
    qdot_rad_s2: np.ndarray,
    rdot_rad_s2: np.ndarray,
    sensor_m: Sequence[float],
    target_m: Sequence[float] = (0.0, 0.0, 0.0),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ax, ay, az) in m/s² at ``target_m`` from accelerometers at ``sensor_m`` (body axes,
    m from the CG; default target: the CG). See the module docstring."""
    d = tuple(_vector(target_m, "target") - _vector(sensor_m, "sensor"))
    omega = tuple(np.asarray(w, dtype=float) for w in (p_rad_s, q_rad_s, r_rad_s))
    omega_dot = tuple(np.asarray(w, dtype=float) for w in (pdot_rad_s2, qdot_rad_s2, rdot_rad_s2))
    # a_t = a_s + ω̇ × d + ω × (ω × d),  d = r_t − r_s
    tangential = cross3(omega_dot, d)
    centripetal = cross3(omega, cross3(omega, d))
    a_s = (np.asarray(ax_m_s2, float), np.asarray(ay_m_s2, float), np.asarray(az_m_s2, float))
    ax, ay, az = (a_s[i] + tangential[i] + centripetal[i] for i in range(3))
    return ax, ay, az
