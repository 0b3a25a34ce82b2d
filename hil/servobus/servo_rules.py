"""The AX-12's rules that the compiled SYNC_WRITE and the servos served in Python both
follow, compiled once (hil/servobus/servo_core.c): the health rule (health.py
``ServoHealth``: ``hx_health_advance``, ``hx_health_errors``) and a write's check
(ax12_servo.py ``Servo.check_write``: ``hx_check_write``). They have no other
implementation: without the library no servo is made, in one line.
"""
from __future__ import annotations

import ctypes
from typing import Any

import numpy as np

from hexhil.hil.native import CORES, REBUILD, load_library
from hexhil.hil.servobus.servo_layout import LAYOUT
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.errors import BadFile

LIBRARY = CORES["servo bank and reads"]
_P = ctypes.c_void_p
_TABLE = ctypes.c_uint8 * ax12.TABLE_SIZE


def _cells() -> np.ndarray:
    """(start, size, min, max, writable) of each control-table address; start -1: reserved."""
    out = np.full((ax12.TABLE_SIZE, 5), -1, dtype=np.int32)
    for a in range(ax12.TABLE_SIZE):
        f = ax12.owner(a)
        if f is not None:
            out[a] = (f[0], f[2], f[6], f[7], f[3] != ax12.R)
    return out


CELLS = _cells()   # the C code's ``struct cell`` array (the bank's ``cells`` too)
_CELLS_AT = CELLS.ctypes.data


def _load() -> Any:
    lib = load_library(LIBRARY, keep_gil=True, layout=LAYOUT, fallback=False)
    if lib is None:
        return None
    lib.hx_health_advance.argtypes = [_P, ctypes.c_int64, ctypes.c_double, ctypes.c_int]
    lib.hx_health_advance.restype = None
    lib.hx_health_errors.argtypes = [_P, _P]
    lib.hx_check_write.argtypes = [_P, ctypes.c_int, _P, ctypes.c_int, ctypes.c_char_p,
                                   ctypes.c_int]
    lib.hx_health_errors.restype = lib.hx_check_write.restype = ctypes.c_int
    return lib


_LIB = _load()


def require() -> None:
    """A servo is made only where the rules are compiled."""
    if _LIB is None:
        raise BadFile(f"compiled core {LIBRARY.name} is not built (the servos' rules have "
                      f"no other implementation): {REBUILD}")


def health_advance(health_at: int, dt_us: int, load_frac: float, torque_limit: int) -> None:
    _LIB.hx_health_advance(health_at, dt_us, load_frac, torque_limit)


def health_errors(health_at: int, table: bytearray) -> int:
    return _LIB.hx_health_errors(health_at, _TABLE.from_buffer(table))


def check_write(original: bool, table: bytearray, address: int, data: bytes) -> int:
    return _LIB.hx_check_write(_CELLS_AT, original, _TABLE.from_buffer(table), address,
                               bytes(data), len(data))
