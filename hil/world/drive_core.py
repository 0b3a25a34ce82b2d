"""The drive bank compiled (hil/world/drive_core.c), through ctypes: the one
implementation of ``DriveBank`` and ``MujocoActuator``'s arithmetic (hil/world/actuator.py):
a joint's command and compliance, its state, and every joint's per-step duty (one call a
physics step, about 2 us for 18 joints; numpy's ufuncs took 18 us). The compiled servo
bank (hil/servobus/servo_core.c) commands and reads the same joints through
``COMMAND_FN`` and ``STATE_FN``. The package builds ``_drive_core.so`` beside this file
(setup.py, the pinned ziglang's C compiler); a world without it is refused in one line.
"""
from __future__ import annotations

import ctypes
import struct
from typing import Any

import numpy as np

from hexhil.hil.native import CORES, load_library, require
from hexhil.hil.world.drive_layout import LAYOUT

LIBRARY = CORES["drive bank"]
_P, _D, _I = ctypes.c_void_p, ctypes.c_double, ctypes.c_int


class _Bank(ctypes.Structure):
    _fields_ = LAYOUT.fields("bank")


def _load() -> Any:
    lib = load_library(LIBRARY, keep_gil=True, layout=LAYOUT)   # short calls
    if lib is None:
        return None
    for name, args in (("hx_duty", [_P, _P, _D, _P, _D]), ("hx_state", [_P, _I, _P]),
                       ("hx_compliance", [_P, _I, _P]),
                       ("hx_command", [_P, _I, _D, _D, _D, _I, _P])):
        fn = getattr(lib, name)
        fn.argtypes, fn.restype = args, None
    return lib


_LIB = _load()
# what the compiled servo bank calls: (bank, joint, out[3]); (bank, joint, goal, speed,
# torque, enabled, compliance[5] or NULL)
STATE_FN, COMMAND_FN = ((ctypes.cast(_LIB.hx_state, _P).value,
                         ctypes.cast(_LIB.hx_command, _P).value) if _LIB is not None
                        else (None, None))
_COMPLIANCE = ctypes.c_double * 5
_STATE_READ = struct.Struct("3d").unpack_from
_PACK_COMPLIANCE = struct.Struct("5d").pack_into
# the arrays the struct points at, in its order after n, and their element types
_ARRAYS = [(f, np.bool_ if f == "enabled" else np.float64)
           for f, kind in _Bank._fields_[1:] if kind is _P]


class CompiledDrives:
    """The compiled bank bound to one ``DriveBank``'s arrays (which it updates in place:
    they must keep their buffers, as ``DriveBank`` does)."""

    def __init__(self, arrays: dict[str, np.ndarray], motor_no_load_rad_s: float) -> None:
        require(_LIB, LIBRARY, "a world's drive bank")
        for name, want in _ARRAYS:
            a = arrays[name]
            if a.dtype != want or not a.flags.c_contiguous:
                raise ValueError(f"{name}: {a.dtype}, not a contiguous {want.__name__} array")
        self._arrays = arrays   # keeps the buffers alive
        self._bank = _Bank(len(arrays["goal"]), *(arrays[f].ctypes.data for f, _ in _ARRAYS),
                           motor_no_load_rad_s)
        self.ref = ctypes.addressof(self._bank)   # what the compiled servo bank takes
        self._seen: tuple = (None, 0, None, 0)   # the last (q, its address, ctrl, its address)
        self._out = (ctypes.c_double * 3)()
        self._out_at = ctypes.addressof(self._out)
        self._out_view = memoryview(self._out).cast("B")
        self._registers = _COMPLIANCE()   # a command's compliance registers, packed
        self._registers_at = ctypes.addressof(self._registers)
        self._registers_view = memoryview(self._registers).cast("B")
        self._duty, self._state = _LIB.hx_duty, _LIB.hx_state
        self._command, self._compliance = _LIB.hx_command, _LIB.hx_compliance

    def duty(self, q_rad: np.ndarray, dt_s: float, ctrl: np.ndarray | None = None,
             stall_nm: float = 0.0) -> None:
        q, q_at, c, c_at = self._seen
        if q_rad is not q or ctrl is not c:   # a world passes the same two views every step
            if q_rad.dtype != np.float64 or not q_rad.flags.c_contiguous:
                q_rad = np.ascontiguousarray(q_rad, dtype=np.float64)
            if ctrl is not None and (ctrl.dtype != np.float64 or not ctrl.flags.c_contiguous
                                     or len(ctrl) < self._bank.n):
                raise ValueError("ctrl must be a contiguous float64 array of the bank's size")
            self._seen = q, q_at, c, c_at = (q_rad, q_rad.ctypes.data, ctrl,
                                             0 if ctrl is None else ctrl.ctypes.data)
        self._duty(self.ref, q_at, dt_s, c_at or None, stall_nm)

    def state(self, j: int) -> tuple[float, float, float]:
        self._state(self.ref, j, self._out_at)
        return _STATE_READ(self._out_view)   # a ctypes array's items cost more

    def compliance(self, j: int, registers: tuple[int, int, int, int, int]) -> None:
        self._compliance(self.ref, j, _COMPLIANCE(*registers))

    def command(self, j: int, goal_rad: float, speed_limit_rad_s: float,
                torque_limit_frac: float, enabled: bool,
                compliance: tuple[int, int, int, int, int] | None) -> None:
        if compliance is not None:
            _PACK_COMPLIANCE(self._registers_view, 0, *compliance)
        self._command(self.ref, j, goal_rad, speed_limit_rad_s, torque_limit_frac, enabled,
                      None if compliance is None else self._registers_at)
