"""The drive bank's per-step arithmetic (hil/world/drive_core.c), through ctypes: the one
implementation of ``DriveBank.duty_for`` (hil/world/actuator.py). One call a physics step
(about 2 us for 18 joints; numpy's ufuncs took 18 us). The package builds
``_drive_core.so`` beside this file (setup.py, the pinned ziglang's C compiler); a world
without it is refused in one line.
"""
from __future__ import annotations

import ctypes
from typing import Any

import numpy as np

from hexhil.hil.native import CORES, REBUILD, load_library
from hexhil.hil.world.drive_layout import LAYOUT
from hexhil.protocol.errors import BadFile

LIBRARY = CORES["drive bank"]


class _Bank(ctypes.Structure):
    _fields_ = LAYOUT.fields("bank")


def _load() -> Any:
    lib = load_library(LIBRARY, layout=LAYOUT, fallback=False)
    if lib is None:
        return None
    fn = lib.hx_duty
    fn.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_double, ctypes.c_void_p,
                   ctypes.c_double]
    fn.restype = None
    return fn


_HX_DUTY = _load()


class CompiledDuty:
    """``hx_duty`` bound to one bank's arrays (which it updates in place: they must keep
    their buffers, as ``DriveBank`` does)."""

    def __init__(self, arrays: dict[str, np.ndarray]) -> None:
        if _HX_DUTY is None:
            raise BadFile(f"compiled core {LIBRARY.name} is not built (the drives have no "
                          f"other implementation): {REBUILD}")
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
