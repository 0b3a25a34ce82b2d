"""The drive bank's struct as hil/world/drive_core.c and drive_core.py share it: written
once here; setup.py generates the C header from it (hil/native.py ``Layout``)."""
from __future__ import annotations

import ctypes

from hexhil.hil.native import Layout

_P = ctypes.c_void_p
LAYOUT = Layout("HX_DRIVE_LAYOUT_H", [
    ("bank", [("n", ctypes.c_int),
              *((name, _P, "double *") for name in (
                  "goal", "setpoint", "speed", "torque_limit", "margin", "slope", "punch",
                  "duty")),
              ("enabled", _P, "const unsigned char *")]),   # numpy bool: one byte each
], [])
