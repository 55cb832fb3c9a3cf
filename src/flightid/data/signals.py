"""Built-in signals of flight logs: Euler angles from the attitude quaternion, and the usual
PX4 / ArduPilot channels for rates, attitudes, control inputs and airspeed, by one name.

Euler angles (ZYX: yaw ψ, then pitch θ, then roll φ) from a unit quaternion
q = (w, x, y, z) in the Hamilton convention (PX4 ``vehicle_attitude.q[0..3]``, body → NED):

    φ = atan2(2(w x + y z), 1 − 2(x² + y²))
    θ = asin(2(w y − x z))                  (argument clipped to [−1, 1])
    ψ = atan2(2(w z + x y), 1 − 2(y² + z²))

The quaternion is normalised first, so stored rounding does not push θ's argument past ±1.

Built-in names (``px4.roll`` ...) deliver SI units (rad, rad/s, m/s; control inputs as the
log stores them). Each has alternatives, tried in order: the first whose columns the table
holds (``stream.field`` as the log readers name them) is used.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "BUILTIN_SIGNALS",
    "BuiltinSignal",
    "quaternion_to_euler",
    "builtin_signal",
]


def _unit_quaternion(w, x, y, z) -> tuple[np.ndarray, ...]:
    w, x, y, z = (np.asarray(v, dtype=float) for v in (w, x, y, z))
    # |q| = √(w² + x² + y² + z²); a zero quaternion gives NaN (no attitude)
    norm = np.sqrt(w * w + x * x + y * y + z * z)
    with np.errstate(invalid="ignore", divide="ignore"):
        return w / norm, x / norm, y / norm, z / norm


def quaternion_roll(w, x, y, z) -> np.ndarray:
    """Roll φ (rad) of the Hamilton quaternion (w, x, y, z), ZYX Euler angles."""
    w, x, y, z = _unit_quaternion(w, x, y, z)
    # φ = atan2(2(w x + y z), 1 − 2(x² + y²))
    return np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))


def quaternion_pitch(w, x, y, z) -> np.ndarray:
    """Pitch θ (rad) of the Hamilton quaternion (w, x, y, z), ZYX Euler angles."""
    w, x, y, z = _unit_quaternion(w, x, y, z)
    # θ = asin(2(w y − x z)), the argument clipped to [−1, 1] against rounding
    return np.arcsin(np.clip(2.0 * (w * y - x * z), -1.0, 1.0))


def quaternion_yaw(w, x, y, z) -> np.ndarray:
    """Yaw ψ (rad) of the Hamilton quaternion (w, x, y, z), ZYX Euler angles, in (−π, π]."""
    w, x, y, z = _unit_quaternion(w, x, y, z)
    # ψ = atan2(2(w z + x y), 1 − 2(y² + z²))
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quaternion_to_euler(w, x, y, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(φ, θ, ψ) in rad of Hamilton quaternions (w, x, y, z): ZYX Euler angles."""
    return quaternion_roll(w, x, y, z), quaternion_pitch(w, x, y, z), quaternion_yaw(w, x, y, z)


_DEG = math.pi / 180.0  # rad per deg


def _same(x):
    return np.asarray(x, dtype=float)


def _deg(x):
    # rad = deg · π/180
    return np.asarray(x, dtype=float) * _DEG


@dataclass(frozen=True)
class BuiltinSignal:
    """A built-in signal: its name, delivered unit, what it is, and its alternatives
    ``(stream, fields, combine)`` in the order they are tried (``combine`` maps the fields'
    values to the signal in ``unit``)."""

    name: str
    unit: str
    what: str
    sources: tuple[tuple[str, tuple[str, ...], Callable[..., np.ndarray]], ...]


def _quat(stream: str, fn) -> tuple:
    return (stream, ("q_0", "q_1", "q_2", "q_3"), fn)


def _one(stream: str, field: str, fn=_same) -> tuple:
    return (stream, (field,), fn)


def _ardupilot(stream: str, field: str, fn=_same) -> tuple[tuple, ...]:
    """A DataFlash field, as a type logged once (``ATT``) or as instance 0 (``ATT_0``)."""
    return (_one(stream, field, fn), _one(f"{stream}_0", field, fn))


_SIGNALS = (
    BuiltinSignal(
        "px4.roll",
        "rad",
        "roll φ from vehicle_attitude.q (ZYX Euler)",
        (_quat("vehicle_attitude", quaternion_roll),),
    ),
    BuiltinSignal(
        "px4.pitch",
        "rad",
        "pitch θ from vehicle_attitude.q (ZYX Euler)",
        (_quat("vehicle_attitude", quaternion_pitch),),
    ),
    BuiltinSignal(
        "px4.yaw",
        "rad",
        "yaw ψ from vehicle_attitude.q (ZYX Euler)",
        (_quat("vehicle_attitude", quaternion_yaw),),
    ),
    *(
        BuiltinSignal(
            f"px4.{axis}",
            "rad/s",
            f"body rate {axis} (filtered gyro)",
            (
                _one("vehicle_angular_velocity", f"xyz_{k}"),
                _one("sensor_combined", f"gyro_rad_{k}"),
            ),
        )
        for k, axis in enumerate("pqr")
    ),
    BuiltinSignal(
        "px4.airspeed",
        "m/s",
        "true airspeed",
        (
            _one("airspeed_validated", "true_airspeed_m_s"),
            _one("airspeed", "true_airspeed_m_s"),
        ),
    ),
    *(
        BuiltinSignal(
            f"px4.{name}",
            "",
            f"normalised {name} command (−1..1)",
            (
                _one("actuator_controls_0", f"control_{k}"),
                _one("vehicle_torque_setpoint", f"xyz_{k}"),
            ),
        )
        for k, name in enumerate(("aileron", "elevator", "rudder"))
    ),
    BuiltinSignal(
        "px4.throttle",
        "",
        "normalised throttle command (0..1)",
        (
            _one("actuator_controls_0", "control_3"),
            _one("vehicle_thrust_setpoint", "xyz_2", lambda z: -np.asarray(z, dtype=float)),
        ),
    ),
    *(
        BuiltinSignal(
            f"ardupilot.{axis}",
            "rad",
            f"{field.lower()} angle (ATT, deg → rad)",
            _ardupilot("ATT", field, _deg),
        )
        for axis, field in (("roll", "Roll"), ("pitch", "Pitch"), ("yaw", "Yaw"))
    ),
    *(
        BuiltinSignal(
            f"ardupilot.{axis}",
            "rad/s",
            f"body rate {axis} (RATE, deg/s → rad/s; else IMU gyro)",
            (
                *_ardupilot("RATE", rate, _deg),
                *_ardupilot("IMU", gyro),
            ),
        )
        for axis, rate, gyro in (("p", "R", "GyrX"), ("q", "P", "GyrY"), ("r", "Y", "GyrZ"))
    ),
    BuiltinSignal("ardupilot.airspeed", "m/s", "airspeed (ARSP)", _ardupilot("ARSP", "Airspeed")),
    *(
        BuiltinSignal(
            f"ardupilot.{name}",
            "",
            f"{name} stick, RC input {channel} (µs PWM; the default RCMAP)",
            _ardupilot("RCIN", f"C{channel}"),
        )
        for name, channel in (("aileron", 1), ("elevator", 2), ("throttle", 3), ("rudder", 4))
    ),
)
BUILTIN_SIGNALS: dict[str, BuiltinSignal] = {s.name: s for s in _SIGNALS}


def builtin_signal(
    name: str, has: Callable[[str], bool], values: Callable[[str], np.ndarray]
) -> tuple[np.ndarray, BuiltinSignal] | None:
    """The built-in signal ``name`` from the first alternative whose columns ``stream.field``
    exist (``has``), read with ``values``; None where ``name`` is no built-in. A built-in
    name none of whose alternatives is present raises ``KeyError`` naming what it needs."""
    signal = BUILTIN_SIGNALS.get(name)
    if signal is None:
        return None
    for stream, fields, combine in signal.sources:
        columns = [f"{stream}.{f}" for f in fields]
        if all(has(c) for c in columns):
            return combine(*(values(c) for c in columns)), signal
    raise KeyError(needs_words(signal.sources))


def needs_words(sources: Sequence[tuple]) -> str:
    """'a.x, a.y or b.z': the columns of each alternative."""
    return " or ".join(", ".join(f"{s}.{f}" for f in fields) for s, fields, _ in sources)
