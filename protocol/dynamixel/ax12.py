"""The AX-12A control table (addresses 0-49) and its units.

Sources: ROBOTIS e-manual "AX-12/AX-12A" and the original AX-12 user's manual (2006),
whose factory defaults differ; ``defaults(edition)`` gives either. SI units live
everywhere else in hexhil: the helpers at the bottom convert at this boundary only.
MicroPython-compatible.
"""
import math

MODEL_NUMBER = 12
FIRMWARE_VERSION = 24
MODEL_NAME = "ax-12a"
# An EEPROM write keeps a real servo busy for "a few ms" (the USB2AX notes; no source gives
# a figure: 5 ms is ours). A packet arriving meanwhile is taken when the write is done, not
# lost (ROBOTIS's wheel-mode advice writes two EEPROM fields back to back; docs/servo-bus.md).
EEPROM_BUSY_US = 5000

EDITION_EMANUAL = "emanual"    # ROBOTIS e-manual, AX-12A
EDITION_ORIGINAL = "original"  # AX-12 user's manual, 2006
EDITIONS = (EDITION_EMANUAL, EDITION_ORIGINAL)

R = "R"
RW = "RW"

# Addresses.
MODEL_NUMBER_L = 0
FIRMWARE = 2
ID = 3
BAUD_RATE = 4
RETURN_DELAY_TIME = 5
CW_ANGLE_LIMIT = 6
CCW_ANGLE_LIMIT = 8
TEMPERATURE_LIMIT = 11
MIN_VOLTAGE_LIMIT = 12
MAX_VOLTAGE_LIMIT = 13
MAX_TORQUE = 14
STATUS_RETURN_LEVEL = 16
ALARM_LED = 17
SHUTDOWN = 18
TORQUE_ENABLE = 24
LED = 25
CW_COMPLIANCE_MARGIN = 26
CCW_COMPLIANCE_MARGIN = 27
CW_COMPLIANCE_SLOPE = 28
CCW_COMPLIANCE_SLOPE = 29
GOAL_POSITION = 30
MOVING_SPEED = 32
TORQUE_LIMIT = 34
PRESENT_POSITION = 36
PRESENT_SPEED = 38
PRESENT_LOAD = 40
PRESENT_VOLTAGE = 42
PRESENT_TEMPERATURE = 43
REGISTERED = 44
MOVING = 46
LOCK = 47
PUNCH = 48

TABLE_SIZE = 50
EEPROM_END = 24  # addresses below this are EEPROM (kept across power cycles, locked by Lock)

# (address, name, size, access, e-manual default, original-manual default, min, max)
# A default of None means "set at run time" (Torque Limit copies Max Torque at power-on;
# Present values come from the motor).
FIELDS = (
    (0, "model_number", 2, R, MODEL_NUMBER, MODEL_NUMBER, 0, 65535),
    (2, "firmware_version", 1, R, FIRMWARE_VERSION, FIRMWARE_VERSION, 0, 255),
    (3, "id", 1, RW, 1, 1, 0, 253),
    (4, "baud_rate", 1, RW, 1, 1, 0, 254),
    (5, "return_delay_time", 1, RW, 250, 250, 0, 254),
    (6, "cw_angle_limit", 2, RW, 0, 0, 0, 1023),
    (8, "ccw_angle_limit", 2, RW, 1023, 1023, 0, 1023),
    (11, "temperature_limit", 1, RW, 70, 85, 0, 150),
    (12, "min_voltage_limit", 1, RW, 60, 60, 50, 250),
    (13, "max_voltage_limit", 1, RW, 140, 190, 50, 250),
    (14, "max_torque", 2, RW, 1023, 1023, 0, 1023),
    (16, "status_return_level", 1, RW, 2, 2, 0, 2),
    (17, "alarm_led", 1, RW, 36, 4, 0, 127),
    (18, "shutdown", 1, RW, 36, 4, 0, 127),
    (24, "torque_enable", 1, RW, 0, 0, 0, 1),
    (25, "led", 1, RW, 0, 0, 0, 1),
    (26, "cw_compliance_margin", 1, RW, 1, 0, 0, 255),
    (27, "ccw_compliance_margin", 1, RW, 1, 0, 0, 255),
    (28, "cw_compliance_slope", 1, RW, 32, 32, 0, 254),
    (29, "ccw_compliance_slope", 1, RW, 32, 32, 0, 254),
    (30, "goal_position", 2, RW, None, None, 0, 1023),
    (32, "moving_speed", 2, RW, 0, 0, 0, 1023),
    (34, "torque_limit", 2, RW, None, None, 0, 1023),
    (36, "present_position", 2, R, None, None, 0, 1023),
    (38, "present_speed", 2, R, 0, 0, 0, 2047),
    (40, "present_load", 2, R, 0, 0, 0, 2047),
    (42, "present_voltage", 1, R, 120, 120, 0, 255),
    (43, "present_temperature", 1, R, 32, 32, 0, 255),
    (44, "registered", 1, R, 0, 0, 0, 1),
    (46, "moving", 1, R, 0, 0, 0, 1),
    (47, "lock", 1, RW, 0, 0, 0, 1),
    (48, "punch", 2, RW, 32, 32, 0, 1023),
)

BY_ADDRESS = {}
BY_NAME = {}
for _f in FIELDS:
    BY_ADDRESS[_f[0]] = _f
    BY_NAME[_f[1]] = _f


def field_at(address):
    """The field that starts at ``address``, or None (reserved or mid-field)."""
    return BY_ADDRESS.get(address)


def owner(address):
    """The field that covers ``address`` (start or high byte), or None if reserved."""
    f = BY_ADDRESS.get(address)
    if f is not None:
        return f
    f = BY_ADDRESS.get(address - 1)
    if f is not None and f[2] == 2:
        return f
    return None


def defaults(edition=EDITION_EMANUAL, position=512):
    """A 50-byte control table at power-on for the given manual edition."""
    if edition not in EDITIONS:
        raise ValueError("unknown AX-12 manual edition %r (use %s)" % (edition, "/".join(EDITIONS)))
    col = 4 if edition == EDITION_EMANUAL else 5
    table = bytearray(TABLE_SIZE)
    for f in FIELDS:
        value = f[col]
        if value is None:
            if f[0] == TORQUE_LIMIT:
                value = _get(table, MAX_TORQUE, 2)
            else:
                value = position  # goal and present position start where the horn is
        _set(table, f[0], f[2], value)
    return table


def _get(table, address, size):
    if size == 1:
        return table[address]
    return table[address] | (table[address + 1] << 8)


def _set(table, address, size, value):
    table[address] = value & 0xFF
    if size == 2:
        table[address + 1] = (value >> 8) & 0xFF


get = _get
put = _set

# --- Units (SI inside hexhil, AX-12 units only here) -------------------------------

POSITION_RANGE_DEG = 300.0
POSITION_MAX = 1023
POSITION_CENTRE_DEG = 150.0
SPEED_RPM_PER_UNIT = 0.111
# e-manual AX-12A specifications: "No Load Speed 59rpm (at 12V)". Moving Speed 0 means no
# speed control, so the motor runs at this; register values above 59/0.111 = 531 ask for
# more than the motor can give (the actuator model saturates, not this table).
MAX_SPEED_RPM = 59.0
# e-manual AX-12A specifications: stall torque 1.5 N m at 12 V, no-load speed 59 rpm.
RATED_SUPPLY_V = 12.0
STALL_TORQUE_NM = 1.5
NO_LOAD_RPM = MAX_SPEED_RPM
DIRECTION_BIT = 0x400           # bit 10 of Present Speed and Present Load: CW when set
LOAD_FRACTION_PER_UNIT = 1.0 / 1023.0
VOLTAGE_V_PER_UNIT = 0.1


def position_to_rad(value):
    """Goal/Present Position (0-1023 over 300 deg) to a joint angle, 0 rad at the centre."""
    return math.radians(value * POSITION_RANGE_DEG / POSITION_MAX - POSITION_CENTRE_DEG)


def rad_to_position(angle_rad):
    """Joint angle to the nearest position unit, clamped to 0-1023."""
    v = int(round((math.degrees(angle_rad) + POSITION_CENTRE_DEG) * POSITION_MAX / POSITION_RANGE_DEG))
    return 0 if v < 0 else (POSITION_MAX if v > POSITION_MAX else v)


def speed_to_rad_s(value):
    """Moving Speed (0-1023; 0 = no limit: the no-load speed) to a speed limit in rad/s."""
    rpm = MAX_SPEED_RPM if value == 0 else (value & 0x3FF) * SPEED_RPM_PER_UNIT
    return rpm * 2.0 * math.pi / 60.0


def rad_s_to_speed(speed_rad_s):
    """Angular speed limit to Moving Speed units (1-1023; never 0, which means maximum)."""
    v = int(round(abs(speed_rad_s) * 60.0 / (2.0 * math.pi) / SPEED_RPM_PER_UNIT))
    return 1 if v < 1 else (1023 if v > 1023 else v)


def signed_to_rad_s(value):
    """Present Speed (magnitude bits 0-9, bit 10 = CW) to a signed rad/s; CCW positive."""
    mag = (value & 0x3FF) * SPEED_RPM_PER_UNIT * 2.0 * math.pi / 60.0
    return -mag if value & DIRECTION_BIT else mag


def rad_s_to_signed(speed_rad_s):
    """Signed rad/s to Present Speed units (CCW positive, bit 10 set for CW)."""
    v = int(round(abs(speed_rad_s) * 60.0 / (2.0 * math.pi) / SPEED_RPM_PER_UNIT))
    v = 1023 if v > 1023 else v
    return v | DIRECTION_BIT if speed_rad_s < 0 and v else v


def load_to_fraction(value):
    """Present Load to a signed fraction of maximum torque (CCW positive)."""
    mag = (value & 0x3FF) * LOAD_FRACTION_PER_UNIT
    return -mag if value & DIRECTION_BIT else mag


def fraction_to_load(fraction):
    v = int(round(abs(fraction) / LOAD_FRACTION_PER_UNIT))
    v = 1023 if v > 1023 else v
    return v | DIRECTION_BIT if fraction < 0 and v else v


def voltage_to_v(value):
    return value * VOLTAGE_V_PER_UNIT


def v_to_voltage(volts):
    return int(round(volts / VOLTAGE_V_PER_UNIT))


def baud_to_bps(value):
    """Baud Rate register to bits per second: 2 000 000 / (value + 1)."""
    return 2000000 // (value + 1)


BAUD_TOLERANCE = 0.03  # e-manual: a line within 3 % of the servo's rate decodes
BAUD_RULE = "no AX-12 rate 2000000/(n+1) within 3 % of it"


def bps_to_baud(bps):
    """The Baud Rate register nearest a line rate, or -1 when none is within 3 % of it."""
    n = min(254, max(0, round(2000000 / bps) - 1))
    return n if abs(baud_to_bps(n) - bps) <= BAUD_TOLERANCE * bps else -1


def return_delay_us(value):
    """Return Delay Time register (2 us units) to microseconds."""
    return 2 * value
