"""The emulated AX-12's rules, compiled once (hil/servobus/servo_core.c), which the servos
served in Python (ax12_servo.py ``Servo``) and the compiled SYNC_WRITE and READ both follow:
the health's step (health.py ``ServoHealth``), a write's check and its effects, the alarms,
the set-point the control table gives the drive (drive.py ``drive``) and the Present
registers. They have no other implementation: without the library no servo is made, in one
line.
"""
from __future__ import annotations

import ctypes
import struct
from typing import Any

import numpy as np

from hexhil.hil import native
from hexhil.hil.native import CORES, load_library
from hexhil.hil.servobus.servo_layout import LAYOUT, READ_LEN, STATE_ROW
from hexhil.protocol.dynamixel import ax12

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
# Goal Position and Moving Speed in SI units for every register value, computed once by
# protocol/dynamixel/ax12.py's own conversions (the bank's ``position_rad`` and
# ``speed_rad_s`` too). Moving Speed keeps 11 bits (a wheel-mode value stays after a return
# to joint mode).
POSITION_RAD = np.array([ax12.position_to_rad(v) for v in range(ax12.POSITION_MAX + 1)])
SPEED_RAD_S = np.array([ax12.speed_to_rad_s(v) for v in range(2048)])
_TABLES = (POSITION_RAD.ctypes.data, SPEED_RAD_S.ctypes.data)


def _load() -> Any:
    lib = load_library(LIBRARY, keep_gil=True, layout=LAYOUT)
    if lib is None:
        return None
    _I64, _D, _I = ctypes.c_int64, ctypes.c_double, ctypes.c_int
    for name, args, res in (("hx_health_advance", [_P, _I64, _D, _I], None),
                            ("hx_health_errors", [_P, _P], _I),
                            ("hx_check_write", [_P, _I, _P, _I, ctypes.c_char_p, _I], _I),
                            ("hx_setpoint", [_P, _P, _P, _D, _P], None),
                            ("hx_rearm", [_P], None),
                            ("hx_alarm", [_P, _P, _I], _I),
                            ("hx_catch_up", [_P, _P, _P, _I64, _D], _I),
                            ("hx_apply", [_P, _P, _P, _I, ctypes.c_char_p, _I], _I),
                            ("hx_present", [_P, _P, _D, _D, _D], _I),
                            ("hx_sync_one", [_P, _P, _P, _P, _I, ctypes.c_char_p, _I], _I),
                            ("hx_read_one", [_P, _P, _P, _I, _I, _I, _P, _P], _I),
                            ("hx_state_row", [_P, _P, _P, _P], None),
                            ("hx_answer", [_P, _P, _I, _I, _P, _I, _P], _I)):
        fn = getattr(lib, name)
        fn.argtypes, fn.restype = args, res
    return lib


_LIB = _load()
# the rules, called with the addresses of a servo, its health and its table (``address``):
# health_advance(health, dt_us, load_frac, torque_limit); health_errors(health, table) ->
# error bits; rearm(health): the overload latch clears; alarm(servo, table, errors) and
# catch_up(servo, health, table, dt_us, load_frac): the health's step against the table's
# torque limit, its errors and their alarms -> whether the drive must be commanded again; apply(servo, health, table, address, data, len) ->
# servo_layout.APPLY_* bits; present(table, health, pos_rad, vel_rad_s, load_frac) ->
# Present Position
(health_advance, health_errors, rearm, alarm, catch_up, apply, present, _check, _setpoint,
 _sync_one, _read_one, _state_row, _answer) = (
    (_LIB.hx_health_advance, _LIB.hx_health_errors, _LIB.hx_rearm, _LIB.hx_alarm,
     _LIB.hx_catch_up, _LIB.hx_apply, _LIB.hx_present, _LIB.hx_check_write, _LIB.hx_setpoint,
     _LIB.hx_sync_one, _LIB.hx_read_one, _LIB.hx_state_row, _LIB.hx_answer)
    if _LIB is not None else (None,) * 13)


def library() -> Any:
    """The loaded ``_servo_core.so`` (layout checked, the GIL held), or None: the one load
    the servo bank (servo_core.py) and the status reads (status_reads.py) bind too."""
    return _LIB


def require() -> None:
    """A servo is made only where the rules are compiled."""
    native.require(_LIB, LIBRARY, "a servo")


def address(table: bytearray) -> tuple[Any, int]:
    """A control table's C view and its address: the table keeps its size while the view
    lives (it is written in place, never resized)."""
    view = _TABLE.from_buffer(table)
    return view, ctypes.addressof(view)


def check_write(original: bool, table_at: int, address: int, data: bytes) -> int:
    return _check(_CELLS_AT, original, table_at, address, bytes(data), len(data))


def sync_write(servo_at: int, health_at: int, table_at: int, original: bool,
               params: bytes) -> int:
    """A SYNC_WRITE's parameters to one servo: its entry checked and applied; the
    servo_layout.APPLY_* bits (0: no entry for it, refused or malformed)."""
    return _sync_one(servo_at, health_at, table_at, _CELLS_AT, original, bytes(params),
                     len(params))


_SETPOINT_READ = struct.Struct("9d").unpack_from   # a ctypes array's items cost 8 times more
_STATE_WRITE = struct.Struct("3d").pack_into


class ServoCalls:
    """The rules that answer through buffers, with one servo's own buffers (a servo is
    stepped by one thread at a time; two runs' threads never share them)."""

    def __init__(self) -> None:
        self._setpoint = (ctypes.c_double * 9)()
        self._state = (ctypes.c_double * 3)()
        self._status = ctypes.create_string_buffer(ax12.TABLE_SIZE + 6)
        self._row = ctypes.create_string_buffer(STATE_ROW.size)
        self._setpoint_at, self._state_at, self._status_at, self._row_at = (
            ctypes.addressof(b) for b in (self._setpoint, self._state, self._status, self._row))
        self._setpoint_view = memoryview(self._setpoint).cast("B")
        self._state_view = memoryview(self._state).cast("B")

    def setpoint(self, table_at: int, supply_frac: float
                 ) -> tuple[float, float, float, bool, tuple[int, int, int, int, int]]:
        """The set-point an AX-12 table gives its drive at ``supply_frac`` of 12 V: goal
        (NaN: hold where it reads), speed limit, torque limit fraction, Torque Enable and
        the compliance registers."""
        _setpoint(*_TABLES, table_at, supply_frac, self._setpoint_at)
        goal, speed, torque, enabled, a, b, c, d, e = _SETPOINT_READ(self._setpoint_view)
        return goal, speed, torque, enabled != 0.0, (int(a), int(b), int(c), int(d), int(e))

    def read(self, servo_at: int, health_at: int, table_at: int, address: int, length: int,
             broadcast: bool, state: tuple[float, float, float] | None) -> int:
        """A READ to the servo after its catch-up, ``state`` the horn's (None: the caller
        refreshes stale Present registers itself): servo_layout.READ_* bits and the status
        packet's length, which ``status`` reads back."""
        if state is not None:
            _STATE_WRITE(self._state_view, 0, *state)
        return _read_one(servo_at, health_at, table_at, address, length, broadcast,
                         None if state is None else self._state_at, self._status_at)

    def answer(self, table_at: int, health_at: int, code: int, error: int) -> bytes | None:
        """The status (no data) an instruction ``code`` earns with ``error``, or None where
        the Status Return Level answers nothing."""
        return self.status(_answer(table_at, health_at, code, error, None, 0,
                                   self._status_at))

    def status(self, code: int) -> bytes | None:
        """The status packet ``read`` or ``answer`` made, or None."""
        n = code & READ_LEN
        return ctypes.string_at(self._status_at, n) if n else None

    def state_row(self, table_at: int, health_at: int, state: tuple[float, float, float]
                  ) -> tuple:
        """An AX-12's row for the recorder's /servos (hil.seams.SERVO_STATE_FIELDS), from
        the horn's ``state``."""
        _STATE_WRITE(self._state_view, 0, *state)
        _state_row(table_at, health_at, self._state_at, self._row_at)
        return STATE_ROW.unpack(self._row.raw)
