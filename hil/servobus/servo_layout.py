"""The compiled servo core's structs and constants (hil/servobus/servo_core.c and
reads_core.c), written once here: the ctypes fields its Python side shares with it
(health.py ``ServoHealth``, ax12_servo.py ``Servo``, servo_core.py's bank, status_reads.py's
reads) and the control-table addresses, error bits, instructions and link limits it takes
from protocol/. setup.py generates the C header from them (hil/native.py ``Layout``)."""
from __future__ import annotations

import ctypes
import math
import struct

from hexhil.hil.native import Layout
from hexhil.hil.servobus.wire import US_BITS
from hexhil.protocol import sim_link
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl

_P = ctypes.c_void_p
_D, _I64, _I32 = ctypes.c_double, ctypes.c_int64, ctypes.c_int32
# a servo's TableServo.state_row as hx_state_rows packs it for the recorder
STATE_ROW = struct.Struct("<Bddddd??B")
# hx_apply's bits: the write changed the ID or Baud Rate (the line re-indexes); the drive
# must be commanded again
APPLY_ADDRESS, APPLY_COMMAND = 1, 2
# hx_read_one's answer: the status packet's length in its low byte; the drive must be
# commanded again; the Present registers must be refreshed first (a reading fault's way)
READ_LEN, READ_COMMAND, READ_REFRESH = 0xFF, 0x100, 0x200
# hx_reads's answers: done, or what the Python side carries out before it calls again
# (status_reads.py); and why an R is malformed (its ``why``)
READS_ANSWERS = ("DONE", "ADVANCE", "ATTEMPT", "HEAR", "WRITE", "WRITE_LEFT", "MALFORMED")
MALFORMED_WHY = ("WHY_LENGTH", "WHY_SKIP", "WHY_ROOM")

# The health model's parameters (our choices; the manuals give no thermal data or overload
# timing, docs/servo-bus.md), which health.py's rule (servo_core.c hx_health_*) reads:
# first order, dT/dt = (ambient + HEAT_AT_FULL_LOAD_C * load^2 - T) / THERMAL_TAU_S.
AMBIENT_C = 32.0               # the manuals' power-on Present Temperature
HEAT_AT_FULL_LOAD_C = 60.0     # steady rise above ambient at 100 % load
THERMAL_TAU_S = 60.0
OVERHEAT_TAU_S = 1.0           # time constant towards an injected hot-spot temperature
OVERLOAD_TIME_US = 1_000_000   # load saturated at the torque limit this long sets the bit

# the drive's speeds: Moving Speed 0 (the motor's no-load speed at 12 V), and the Moving
# flag's threshold, half a Present Speed unit
NO_LOAD_RAD_S = ax12.speed_to_rad_s(0)
MOVING_EPS_RAD_S = 0.5 * ax12.SPEED_RPM_PER_UNIT * 2.0 * math.pi / 60.0

HEALTH = [("supply_v", _D), ("supply_frac", _D), ("temperature_c", _D), ("_hot_spot_c", _D),
          ("saturated_us", _I64), ("voltage_units", _I32), ("temperature_units", _I32),
          ("overload", ctypes.c_bool),   # latched until Torque Limit is written again
          ("_hot", ctypes.c_bool)]
SERVO = [("t_us", _I64), ("busy_until_us", _I64), ("deaf_until_us", _I64), ("held_us", _I64),
         ("held", _I64), ("instructions", _I64), ("ignored", _I64), ("eeprom_busy_us", _I64),
         ("alarm_led", ctypes.c_bool), ("address_changed", ctypes.c_bool),
         ("_present_stale", ctypes.c_bool)]
# one control-table cell's field, from protocol/dynamixel/ax12.py (start < 0: reserved)
CELL = [("start", _I32), ("size", _I32), ("lo", _I32), ("hi", _I32), ("writable", _I32)]
_IN = "const double *"
BANK = [("n", ctypes.c_int), ("servo", _P, "struct servo **"),
        ("health", _P, "struct health **"), ("table", _P, "unsigned char **"),
        ("joint", _P, "const int32_t *"),      # the servo's joint; -1: not a MuJoCo joint
        ("original", _P, "const int32_t *"),   # the 2006 manual's Lock rule
        ("cells", _P, "const struct cell *"),  # TABLE_SIZE
        ("position_rad", _P, _IN), ("speed_rad_s", _P, _IN),   # Goal Position, Moving Speed
        # the joints' drive bank (hil/world/drive_core.c) and its state and command
        ("drives", _P, "void *"), ("state", _P, "hx_state_fn"), ("command", _P, "hx_command_fn")]
_U8 = ctypes.c_uint8
READS = [("bank", _P, "const struct bank *"), ("payload", ctypes.c_char_p,
                                                "const unsigned char *"),
         ("len", _I32),
         ("index", _P, "const int16_t *"),   # 256: the bank index an ID reaches; -1
         ("baud", _I64),
         ("byte_us", _D),                    # the master's byte time, what wire time counts
         ("echo", _I32),                     # the master hears its own bytes
         ("fast", _I32),                     # a plain line: attempts may be carried out in C
         ("one", _I32),                      # an X: one read, its tx the rest of the payload
         ("delay_override_us", _I64),        # -1: each servo's own Return Delay Time
         ("t_us", _I64),                     # the line's clock
         ("next_step_us", _I64),             # the clock reaching this steps the world
         ("r", _I32), ("k", _I32), ("at", _I32), ("phase", _I32), ("i", _I32), ("m", _I32),
         ("ok", _I32),                       # the attempt passed the master's test
         ("ntx", _I32),                      # the attempt's tx length
         ("why", _I32),                      # MALFORMED_WHY, from 1
         ("t0_us", _I64), ("t1_us", _I64), ("start_us", _I64),
         ("done", ctypes.c_int8 * 256),      # per read: 1 succeeded, 0 failed, -1 skipped
         ("reply", _U8 * 64),
         ("body", _U8 * (sim_link.MAX_REPLY_LEN + 16)),   # u8 attempts, then each
         ("body_len", _I32),
         ("log", _U8 * 32768),   # heard since the Python side took it: u64 t, u8 'T'/'R', bytes
         ("log_len", _I32), ("lens", _U8 * 1024), ("nrec", _I32),
         *((n, _I64) for n in ("tx_bytes", "rx_bytes", "packets", "replies", "busy_us",
                               "wire_us")),
         ("write", ctypes.c_char_p, "const unsigned char *"),   # the W before, or NULL
         ("write_len", _I32),
         ("changed", _P, "int32_t *")]   # the bank's flag: the W changed an ID or Baud Rate

_REGISTERS = ("ID", "BAUD_RATE", "RETURN_DELAY_TIME", "CW_ANGLE_LIMIT", "CCW_ANGLE_LIMIT",
              "TEMPERATURE_LIMIT", "MIN_VOLTAGE_LIMIT", "MAX_VOLTAGE_LIMIT",
              "STATUS_RETURN_LEVEL", "ALARM_LED", "SHUTDOWN", "EEPROM_END", "TORQUE_ENABLE",
              "CW_COMPLIANCE_MARGIN", "GOAL_POSITION", "MOVING_SPEED", "TORQUE_LIMIT",
              "PRESENT_POSITION", "PRESENT_SPEED", "PRESENT_LOAD", "PRESENT_VOLTAGE",
              "PRESENT_TEMPERATURE", "MOVING", "LOCK", "PUNCH", "TABLE_SIZE", "DIRECTION_BIT",
              "POSITION_MAX", "POSITION_CENTRE_DEG", "POSITION_RANGE_DEG")
_ERRORS = ("ERR_INPUT_VOLTAGE", "ERR_ANGLE_LIMIT", "ERR_OVERHEATING", "ERR_RANGE",
           "ERR_OVERLOAD")
LAYOUT = Layout("HX_SERVO_LAYOUT_H", [
    ("health", HEALTH), ("servo", SERVO), ("cell", CELL), ("bank", BANK), ("reads", READS)], [
    *((f"AX12_{n}", getattr(ax12, n)) for n in _REGISTERS),
    *((f"DXL_{n}", getattr(dxl, n)) for n in _ERRORS),
    ("DXL_READ", dxl.READ), ("DXL_PING", dxl.PING), ("DXL_SYNC_WRITE", dxl.SYNC_WRITE),
    ("DXL_BROADCAST_ID", dxl.BROADCAST_ID),
    ("LINK_READ_LEN", sim_link.READ_HEAD_LEN + 1),   # a read's head with its u8 ntx
    ("LINK_NO_SKIP", sim_link.NO_SKIP), ("LINK_READ_ECHO", sim_link.READ_ECHO),
    ("LINK_MAX_REPLY_LEN", sim_link.MAX_REPLY_LEN),
    ("LINK_ATTEMPT_HEAD_LEN", sim_link.ATTEMPT_HEAD_LEN), ("US_BITS", US_BITS),
    ("STATE_ROW", STATE_ROW.size), ("AX12_SPEED_UNIT", ax12.SPEED_RPM_PER_UNIT),
    ("AX12_LOAD_UNIT", ax12.LOAD_FRACTION_PER_UNIT), ("AX12_NO_LOAD_RAD_S", NO_LOAD_RAD_S),
    ("MOVING_EPS_RAD_S", MOVING_EPS_RAD_S), ("HX_APPLY_ADDRESS", APPLY_ADDRESS),
    ("HX_APPLY_COMMAND", APPLY_COMMAND), ("HX_READ_LEN", READ_LEN),
    ("HX_READ_COMMAND", READ_COMMAND), ("HX_READ_REFRESH", READ_REFRESH),
    ("HEALTH_AMBIENT_C", AMBIENT_C), ("HEALTH_HEAT_C", HEAT_AT_FULL_LOAD_C),
    ("HEALTH_THERMAL_TAU_S", THERMAL_TAU_S), ("HEALTH_OVERHEAT_TAU_S", OVERHEAT_TAU_S),
    ("HEALTH_OVERLOAD_US", OVERLOAD_TIME_US),
    *((f"HX_{n}", i) for i, n in enumerate(READS_ANSWERS)),
    *((f"HX_{n}", i) for i, n in enumerate(MALFORMED_WHY, 1))])
