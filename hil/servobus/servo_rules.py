"""The AX-12's rules that the compiled SYNC_WRITE and the servos served in Python both
follow, compiled once (hil/servobus/servo_core.c): the health rule (health.py
``ServoHealth``: ``hx_health_advance``, ``hx_health_errors``; ``hx_health_step``, both for
an AX-12's table in one call) and a write's check (ax12_servo.py ``Servo.check_write``:
``hx_check_write``). They have no other implementation: without the library no servo is
made, in one line.
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
    _I64, _D, _I = ctypes.c_int64, ctypes.c_double, ctypes.c_int
    for name, args, res in (("hx_health_advance", [_P, _I64, _D, _I], None),
                            ("hx_health_errors", [_P, _P], _I),
                            ("hx_health_step", [_P, _I64, _D, _P], _I),
                            ("hx_check_write", [_P, _I, _P, _I, ctypes.c_char_p, _I], _I)):
        fn = getattr(lib, name)
        fn.argtypes, fn.restype = args, res
    return lib


_LIB = _load()
# the rules, called with the addresses of a servo's health and table (``address``):
# (health, dt_us, load_frac, torque_limit); (health, table) -> error bits;
# (health, dt_us, load_frac, table) -> error bits: the step against the table's torque
# limit, then its errors; (cells, original, table, address, data, len) -> error bits
health_advance, health_errors, health_step, _check = (
    (_LIB.hx_health_advance, _LIB.hx_health_errors, _LIB.hx_health_step, _LIB.hx_check_write)
    if _LIB is not None else (None,) * 4)


def library() -> Any:
    """The loaded ``_servo_core.so`` (layout checked, the GIL held), or None: the one load
    the servo bank (servo_core.py) and the status reads (reads_core.py) bind too."""
    return _LIB


def require() -> None:
    """A servo is made only where the rules are compiled."""
    if _LIB is None:
        raise BadFile(f"compiled core {LIBRARY.name} is not built (the servos' rules have "
                      f"no other implementation): {REBUILD}")


def address(table: bytearray) -> tuple[Any, int]:
    """A control table's C view and its address: the table keeps its size while the view
    lives (it is written in place, never resized)."""
    view = _TABLE.from_buffer(table)
    return view, ctypes.addressof(view)


def check_write(original: bool, table_at: int, address: int, data: bytes) -> int:
    return _check(_CELLS_AT, original, table_at, address, bytes(data), len(data))
