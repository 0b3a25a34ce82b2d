"""The drive bank's struct and constants as hil/world/drive_core.c and drive_core.py share
them: written once here; setup.py generates the C header from them (hil/native.py
``Layout``)."""
from __future__ import annotations

import ctypes
import math

from hexhil.hil.native import Layout
from hexhil.protocol.dynamixel import ax12

POSITION_UNIT_RAD = math.radians(ax12.POSITION_RANGE_DEG / ax12.POSITION_MAX)
PUNCH_FRACTION_PER_UNIT = 1.0 / 1023.0

_P = ctypes.c_void_p
LAYOUT = Layout("HX_DRIVE_LAYOUT_H", [
    ("bank", [("n", ctypes.c_int),
              *((name, _P, "double *") for name in (
                  "goal", "setpoint", "speed", "torque_limit", "margin", "slope", "punch",
                  "duty",
                  "compliance")),   # the registers margin, slope and punch came from
              ("enabled", _P, "unsigned char *"),   # numpy bool: one byte each
              # the joints as measured (the world's) and the potentiometers' zero offsets
              *((name, _P, "const double *") for name in ("q", "qd", "offset")),
              ("motor_no_load", ctypes.c_double)]),
], [("POSITION_UNIT_RAD", POSITION_UNIT_RAD), ("PUNCH_PER_UNIT", PUNCH_FRACTION_PER_UNIT)])
