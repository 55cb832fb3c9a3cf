"""Small hand-written PX4 ULog and ArduPilot DataFlash writers for the tests (from the
formats' specifications, as in test_loaders_formats.py, with integer fields added)."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

_ULOG_CODES = {"float": "f", "double": "d", "uint8_t": "B", "int32_t": "i", "uint16_t": "H"}


def _ulog_message(kind: str, payload: bytes) -> bytes:
    # ULog message header: uint16 msg_size (payload bytes), uint8 msg_type (ULog spec)
    return struct.pack("<HB", len(payload), ord(kind)) + payload


def write_ulog(path: Path, topics: dict, parameters: dict[str, float] | None = None) -> Path:
    """A ULog (docs.px4.io "ULog File Format"): header, flag bits, formats, parameters,
    subscriptions, then data messages in time order. ``topics``: name → (fields as
    [(type, name)], stamps µs, rows); types float, double, uint8_t, int32_t, uint16_t and
    float[N]."""
    out = bytearray(b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", 0))
    out += _ulog_message("B", bytes(16) + struct.pack("<3Q", 0, 0, 0))
    for name, (fields, _, _) in topics.items():
        text = f"{name}:uint64_t timestamp;" + "".join(f"{t} {f};" for t, f in fields)
        out += _ulog_message("F", text.encode())
    for name, value in (parameters or {}).items():
        key = f"float {name}".encode()
        out += _ulog_message("P", bytes([len(key)]) + key + struct.pack("<f", value))
    for msg_id, name in enumerate(topics):
        out += _ulog_message("A", struct.pack("<BH", 0, msg_id) + name.encode())
    messages = []
    for msg_id, (fields, time_us, rows) in enumerate(topics.values()):
        codes = "".join(
            "f" * int(t[6:-1]) if t.startswith("float[") else _ULOG_CODES[t] for t, _ in fields
        )
        for stamp, row in zip(time_us, rows, strict=True):
            values = [int(v) if c in "BiH" else float(v) for c, v in zip(codes, row, strict=True)]
            payload = struct.pack("<HQ" + codes, msg_id, int(stamp), *values)
            messages.append((int(stamp), msg_id, _ulog_message("D", payload)))
    for _, _, message in sorted(messages, key=lambda m: (m[0], m[1])):
        out += message
    path.write_bytes(bytes(out))
    return path


def _df_message(msg_type: int, payload: bytes) -> bytes:
    # DataFlash message: 0xA3 0x95, the type byte, the payload (ArduPilot LogStructure.h)
    return bytes([0xA3, 0x95, msg_type]) + payload


_DF_SIZES = {"Q": 8, "B": 1, "M": 1, "b": 1, "c": 2, "f": 4, "d": 8, "n": 4, "N": 16, "Z": 64}
_DF_STRUCT = {"Q": "Q", "B": "B", "M": "B", "b": "b", "c": "h", "f": "f", "d": "d"}


def write_dataflash(path: Path, types: dict, records: list, units: dict | None = None) -> Path:
    """A binary DataFlash log. ``types``: name → (type id, format, "TimeUS,..."); ``records``:
    (time µs, name, values after TimeUS); ``units``: name → (unit ids, mult ids) for FMTU
    with the labels s, d (deg), k (deg/s), E (rad/s), n (m/s)."""
    out = bytearray()

    def fmt(msg_type: int, name: str, form: str, columns: str) -> bytes:
        length = 3 + sum(_DF_SIZES[c] for c in form)
        payload = struct.pack(
            "<BB4s16s64s", msg_type, length, name.encode(), form.encode(), columns.encode()
        )
        return _df_message(0x80, payload)

    out += fmt(0x80, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns")
    out += fmt(0x81, "UNIT", "QbZ", "TimeUS,Id,Label")
    out += fmt(0x82, "MULT", "Qbd", "TimeUS,Id,Mult")
    out += fmt(0x83, "FMTU", "QBNN", "TimeUS,FmtType,UnitIds,MultIds")
    for name, (msg_type, form, columns) in types.items():
        out += fmt(msg_type, name, form, columns)
    for ident, label in (("s", "s"), ("d", "deg"), ("k", "deg/s"), ("E", "rad/s"), ("n", "m/s")):
        out += _df_message(0x81, struct.pack("<Qb64s", 0, ord(ident), label.encode()))
    for ident, mult in (("-", 0.0), ("F", 1e-6)):
        out += _df_message(0x82, struct.pack("<Qbd", 0, ord(ident), mult))
    for name, (unit_ids, mult_ids) in (units or {}).items():
        out += _df_message(
            0x83,
            struct.pack("<QB16s16s", 0, types[name][0], unit_ids.encode(), mult_ids.encode()),
        )
    for stamp, name, values in sorted(records, key=lambda r: r[0]):
        msg_type, form, _ = types[name]
        code = "<" + "".join(_DF_STRUCT[c] for c in form)
        out += _df_message(msg_type, struct.pack(code, int(stamp), *values))
    path.write_bytes(bytes(out))
    return path


def jittered_stamps_us(rng, start_s: float, stop_s: float, rate_hz: float, jitter_s: float):
    """Stamps (µs) at ``rate_hz`` with uniform jitter ±jitter_s, increasing."""
    t = np.arange(start_s, stop_s, 1.0 / rate_hz)
    t = t + jitter_s + rng.uniform(-jitter_s, jitter_s, t.size)  # ≥ start_s
    return np.round(np.sort(t) * 1e6).astype(np.int64)
