"""The XL430-W250-T control table (addresses 0-147) and its units.

Source: ROBOTIS e-manual "XL430-W250-T" (Control Table of EEPROM Area / RAM Area,
firmware 4x). The indirect addresses (168-251, 578-661) are not modelled: reading or
writing them earns the Access error, as an undefined address does. SI units live
everywhere else in hexhil: the helpers at the bottom convert at this boundary only.
MicroPython-compatible.
"""
import math

MODEL_NUMBER = 1060
FIRMWARE_VERSION = 46
MODEL_NAME = "xl430-w250"
EEPROM_BUSY_US = 5000  # busy after an EEPROM write (packets wait): our 5 ms, as the AX-12's (docs/servo-bus.md)

R = "R"
RW = "RW"

# Addresses (e-manual).
MODEL_NUMBER_L = 0
FIRMWARE = 6
ID = 7
BAUD_RATE = 8
RETURN_DELAY_TIME = 9
DRIVE_MODE = 10
OPERATING_MODE = 11
PROTOCOL_TYPE = 13
HOMING_OFFSET = 20
TEMPERATURE_LIMIT = 31
MAX_VOLTAGE_LIMIT = 32
MIN_VOLTAGE_LIMIT = 34
PWM_LIMIT = 36
VELOCITY_LIMIT = 44
MAX_POSITION_LIMIT = 48
MIN_POSITION_LIMIT = 52
SHUTDOWN = 63
TORQUE_ENABLE = 64
LED = 65
STATUS_RETURN_LEVEL = 68
REGISTERED = 69
HARDWARE_ERROR_STATUS = 70
POSITION_D_GAIN = 80
POSITION_I_GAIN = 82
POSITION_P_GAIN = 84
GOAL_PWM = 100
GOAL_VELOCITY = 104
PROFILE_ACCELERATION = 108
PROFILE_VELOCITY = 112
GOAL_POSITION = 116
REALTIME_TICK = 120
MOVING = 122
MOVING_STATUS = 123
PRESENT_PWM = 124
PRESENT_LOAD = 126
PRESENT_VELOCITY = 128
PRESENT_POSITION = 132
VELOCITY_TRAJECTORY = 136
POSITION_TRAJECTORY = 140
PRESENT_INPUT_VOLTAGE = 144
PRESENT_TEMPERATURE = 146
BACKUP_READY = 147

TABLE_SIZE = 148
EEPROM_END = 64  # below: EEPROM, writable only with Torque Enable 0 (else Access error)

# Operating Mode values (address 11).
MODE_VELOCITY = 1
MODE_POSITION = 3
MODE_EXTENDED_POSITION = 4
MODE_PWM = 16
MODES = (MODE_VELOCITY, MODE_POSITION, MODE_EXTENDED_POSITION, MODE_PWM)
POSITION_MODES = (MODE_POSITION, MODE_EXTENDED_POSITION)
LIMITED_POSITION_MODES = (MODE_POSITION,)   # Goal Position within the position limits
CURRENT_MODES = ()                           # no current sensor: Present Load, not Current

# Hardware Error Status bits (address 70) and Shutdown (63) use the same bits.
HW_INPUT_VOLTAGE = 0x01
HW_OVERHEATING = 0x04
HW_MOTOR_ENCODER = 0x08
HW_ELECTRICAL_SHOCK = 0x10
HW_OVERLOAD = 0x20

EXT_POSITION_MAX = 1048575  # Goal Position range in extended position mode

# (address, name, size, access, default, min, max, signed). A default of None is set at
# run time (goal and present values come from where the horn is).
FIELDS = (
    (0, "model_number", 2, R, MODEL_NUMBER, 0, 65535, False),
    (2, "model_information", 4, R, 0, 0, 0, False),
    (6, "firmware_version", 1, R, FIRMWARE_VERSION, 0, 255, False),
    (7, "id", 1, RW, 1, 0, 252, False),
    (8, "baud_rate", 1, RW, 1, 0, 7, False),
    (9, "return_delay_time", 1, RW, 250, 0, 254, False),
    (10, "drive_mode", 1, RW, 0, 0, 13, False),
    (11, "operating_mode", 1, RW, MODE_POSITION, 0, 16, False),
    (12, "secondary_id", 1, RW, 255, 0, 255, False),
    (13, "protocol_type", 1, RW, 2, 1, 2, False),
    (20, "homing_offset", 4, RW, 0, -1044479, 1044479, True),
    (24, "moving_threshold", 4, RW, 10, 0, 1023, False),
    (31, "temperature_limit", 1, RW, 72, 0, 100, False),
    (32, "max_voltage_limit", 2, RW, 140, 60, 140, False),
    (34, "min_voltage_limit", 2, RW, 60, 60, 140, False),
    (36, "pwm_limit", 2, RW, 885, 0, 885, False),
    (44, "velocity_limit", 4, RW, 265, 0, 1023, False),
    (48, "max_position_limit", 4, RW, 4095, 0, 4095, False),
    (52, "min_position_limit", 4, RW, 0, 0, 4095, False),
    (60, "startup_configuration", 1, RW, 0, 0, 3, False),
    (63, "shutdown", 1, RW, 52, 0, 255, False),
    (64, "torque_enable", 1, RW, 0, 0, 1, False),
    (65, "led", 1, RW, 0, 0, 1, False),
    (68, "status_return_level", 1, RW, 2, 0, 2, False),
    (69, "registered_instruction", 1, R, 0, 0, 1, False),
    (70, "hardware_error_status", 1, R, 0, 0, 255, False),
    (76, "velocity_i_gain", 2, RW, 1000, 0, 16383, False),
    (78, "velocity_p_gain", 2, RW, 100, 0, 16383, False),
    (80, "position_d_gain", 2, RW, 4000, 0, 16383, False),
    (82, "position_i_gain", 2, RW, 0, 0, 16383, False),
    (84, "position_p_gain", 2, RW, 640, 0, 16383, False),
    (88, "feedforward_2nd_gain", 2, RW, 0, 0, 16383, False),
    (90, "feedforward_1st_gain", 2, RW, 0, 0, 16383, False),
    (98, "bus_watchdog", 1, RW, 0, 0, 127, False),
    (100, "goal_pwm", 2, RW, 0, -885, 885, True),
    (104, "goal_velocity", 4, RW, 0, -1023, 1023, True),
    (108, "profile_acceleration", 4, RW, 0, 0, 32767, False),
    (112, "profile_velocity", 4, RW, 0, 0, 32767, False),
    (116, "goal_position", 4, RW, None, -EXT_POSITION_MAX, EXT_POSITION_MAX, True),
    (120, "realtime_tick", 2, R, 0, 0, 32767, False),
    (122, "moving", 1, R, 0, 0, 1, False),
    (123, "moving_status", 1, R, 0, 0, 255, False),
    (124, "present_pwm", 2, R, 0, -885, 885, True),
    (126, "present_load", 2, R, 0, -1000, 1000, True),
    (128, "present_velocity", 4, R, 0, -1023, 1023, True),
    (132, "present_position", 4, R, None, -2147483648, 2147483647, True),
    (136, "velocity_trajectory", 4, R, 0, -1023, 1023, True),
    (140, "position_trajectory", 4, R, None, -2147483648, 2147483647, True),
    (144, "present_input_voltage", 2, R, 120, 0, 65535, False),
    (146, "present_temperature", 1, R, 32, 0, 255, False),
    (147, "backup_ready", 1, R, 0, 0, 1, False),
)

def index(fields):
    """(by address, by name, the field covering each address or None) of a field list."""
    by_address, by_name, owner = {}, {}, [None] * TABLE_SIZE
    for f in fields:
        by_address[f[0]] = f
        by_name[f[1]] = f
        for a in range(f[0], f[0] + f[2]):
            owner[a] = f
    return by_address, by_name, owner


BY_ADDRESS, BY_NAME, OWNER = index(FIELDS)


def get(table, address, size, signed=False):
    """A little-endian value of ``size`` bytes (two's complement when ``signed``)."""
    v = 0
    for i in range(size - 1, -1, -1):
        v = (v << 8) | table[address + i]
    if signed and v >= 1 << (8 * size - 1):
        v -= 1 << (8 * size)
    return v


def put(table, address, size, value):
    for i in range(size):
        table[address + i] = (value >> (8 * i)) & 0xFF


def table_of(fields, position):
    """A control table at power-on from a field list, the horn at ``position`` (pulses)."""
    table = bytearray(TABLE_SIZE)
    for f in fields:
        value = f[4]
        if value is None:
            value = position
        put(table, f[0], f[2], value)
    return table


def defaults(position=2048):
    """The control table at power-on, the horn at ``position`` (pulses)."""
    return table_of(FIELDS, position)


# --- Units (SI inside hexhil, XL430 units only here) --------------------------------

PULSES_PER_REV = 4096
POSITION_CENTRE = 2048          # 180 deg: our 0 rad, as the AX-12's 150 deg centre
RAD_PER_PULSE = 2.0 * math.pi / PULSES_PER_REV
RPM_PER_UNIT = 0.229            # Velocity Limit, Goal/Present Velocity, Profile Velocity
RPM2_PER_UNIT = 214.577         # Profile Acceleration (rev/min^2)
PWM_MAX = 885                   # PWM Limit 885 = 100 % duty (0.113 % a unit)
LOAD_FRACTION_PER_UNIT = 0.001  # Present Load, 0.1 %
VOLTAGE_V_PER_UNIT = 0.1
# e-manual specifications: stall torque 1.4 N m at 11.1 V (1.3 A), no-load speed 57 rpm
# at 11.1 V; the recommended supply is 11.1 V.
RATED_SUPPLY_V = 11.1
STALL_TORQUE_NM = 1.4
NO_LOAD_RPM = 57.0
BAUD_BPS = (9600, 57600, 115200, 1000000, 2000000, 3000000, 4000000, 4500000)


def fraction_to_load(fraction):
    """Present Load (0.1 % units, signed) of a load fraction."""
    return int(round(max(-1.0, min(1.0, fraction)) * 1000))


def position_to_rad(value):
    return (value - POSITION_CENTRE) * RAD_PER_PULSE


def rad_to_position(angle_rad):
    return int(round(angle_rad / RAD_PER_PULSE)) + POSITION_CENTRE


def velocity_to_rad_s(value):
    return value * RPM_PER_UNIT * 2.0 * math.pi / 60.0


def rad_s_to_velocity(speed_rad_s):
    return int(round(speed_rad_s * 60.0 / (2.0 * math.pi) / RPM_PER_UNIT))


def acceleration_to_rad_s2(value):
    return value * RPM2_PER_UNIT * 2.0 * math.pi / 3600.0


def baud_to_bps(value):
    """Baud Rate register (0-7) to bits per second."""
    return BAUD_BPS[value] if 0 <= value < len(BAUD_BPS) else 0


BAUD_RULE = "not one of " + "/".join(str(b) for b in BAUD_BPS) + " bps"


def bps_to_baud(bps):
    """The Baud Rate register for a line rate, or -1 when none matches exactly."""
    for i, b in enumerate(BAUD_BPS):
        if b == bps:
            return i
    return -1


def return_delay_us(value):
    """Return Delay Time register (2 us units) to microseconds."""
    return 2 * value
