"""The drive bank's per-step arithmetic compiled (hil/world/drive_core.c), through ctypes.

The package builds ``_drive_core.so`` beside this file (setup.py, the pinned ziglang's C
compiler). The C code does numpy's operations in numpy's order, element by
element, so the duties and the run's bytes are the same with or without it
(tests/test_drive_core.py); without the library ``DriveBank`` keeps its numpy path.
One call a physics step instead of about fifteen numpy calls: 18 us -> about 2 us.
"""
from __future__ import annotations

import ctypes
from typing import Any

import numpy as np

from hil.native import CORES, load_library

LIBRARY = CORES["drive bank"]
_P = ctypes.c_void_p


class _Bank(ctypes.Structure):
    _fields_ = [("n", ctypes.c_int), ("goal", _P), ("setpoint", _P), ("speed", _P),
                ("torque_limit", _P), ("margin", _P), ("slope", _P), ("punch", _P),
                ("duty", _P), ("enabled", _P)]


def _load() -> Any:
    lib = load_library(LIBRARY)
    if lib is None:
        return None
    fn = lib.hx_duty
    fn.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_double, ctypes.c_void_p,
                   ctypes.c_double]
    fn.restype = None
    return fn


_HX_DUTY = _load()


def available() -> bool:
    return _HX_DUTY is not None


class CompiledDuty:
    """``hx_duty`` bound to one bank's arrays (which it updates in place: they must keep
    their buffers, as ``DriveBank`` does)."""

    def __init__(self, arrays: dict[str, np.ndarray]) -> None:
        for name, a in arrays.items():
            want = np.bool_ if name == "enabled" else np.float64
            if a.dtype != want or not a.flags.c_contiguous:
                raise ValueError(f"{name}: {a.dtype}, not a contiguous {want.__name__} array")
        self._arrays = arrays   # keeps the buffers alive
        self._bank = _Bank(len(arrays["goal"]), *(arrays[f].ctypes.data for f, _ in
                                                   _Bank._fields_[1:]))
        self._ref = ctypes.addressof(self._bank)
        self._seen: tuple = (None, 0, None, 0)   # the last (q, its address, ctrl, its address)

    def __call__(self, q_rad: np.ndarray, dt_s: float, ctrl: np.ndarray | None = None,
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
        _HX_DUTY(self._ref, q_at, dt_s, c_at or None, stall_nm)
