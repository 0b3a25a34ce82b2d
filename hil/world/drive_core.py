"""The drive bank's per-step arithmetic compiled (hil/world/drive_core.c), through ctypes.

``make`` builds ``_drive_core.so`` beside this file with the pinned ziglang's C compiler
(no hand installs). The C code does numpy's operations in numpy's order, element by
element, so the duties and the run's bytes are the same with or without it
(tests/test_drive_core.py); without the library ``DriveBank`` keeps its numpy path.
One call a physics step instead of about fifteen numpy calls: 18 us -> about 2 us.
"""
from __future__ import annotations

import ctypes
from pathlib import Path
from typing import Any

import numpy as np

LIBRARY = Path(__file__).with_name("_drive_core.so")
_P = ctypes.c_void_p


class _Bank(ctypes.Structure):
    _fields_ = [("n", ctypes.c_int), ("goal", _P), ("setpoint", _P), ("speed", _P),
                ("torque_limit", _P), ("margin", _P), ("slope", _P), ("punch", _P),
                ("duty", _P), ("enabled", _P)]


def _load() -> Any:
    if not LIBRARY.exists():
        return None
    try:
        lib = ctypes.CDLL(str(LIBRARY))
    except OSError:
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

    def __call__(self, q_rad: np.ndarray, dt_s: float, ctrl: np.ndarray | None = None,
                 stall_nm: float = 0.0) -> None:
        if q_rad.dtype != np.float64 or not q_rad.flags.c_contiguous:
            q_rad = np.ascontiguousarray(q_rad, dtype=np.float64)
        _HX_DUTY(self._ref, q_rad.ctypes.data, dt_s,
                 None if ctrl is None else ctrl.ctypes.data, stall_nm)
