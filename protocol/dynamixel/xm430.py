"""The XM430-W350-T/R control table (addresses 0-147) and its units.

Source: ROBOTIS e-manual "XM430-W350-T/R" (emanual.robotis.com/docs/en/dxl/x/xm430-w350/:
Specifications; Control Table of EEPROM Area / RAM Area, firmware 4x). It is the X series'
layout of xl430.py (same addresses, units, baud rates and helpers, imported from there) with
a current sensor: Current Limit (38), Goal Current (102), Present Current (126, where the
XL430 has Present Load), Current Control Mode (0) and Current-based Position Control Mode
(5, position control with the torque capped by Goal Current); and its own defaults, limits,
gains and motor. MicroPython-compatible.
"""
from protocol.dynamixel.xl430 import (  # the X series' shared layout and units
    BACKUP_READY, BAUD_BPS, BAUD_RATE, BAUD_RULE, EEPROM_END, EXT_POSITION_MAX, FIRMWARE,
    GOAL_POSITION, GOAL_PWM, GOAL_VELOCITY, HARDWARE_ERROR_STATUS, HOMING_OFFSET,
    HW_ELECTRICAL_SHOCK, HW_INPUT_VOLTAGE, HW_MOTOR_ENCODER, HW_OVERHEATING, HW_OVERLOAD, ID,
    LED, MAX_POSITION_LIMIT, MAX_VOLTAGE_LIMIT, MIN_POSITION_LIMIT, MIN_VOLTAGE_LIMIT,
    MODE_EXTENDED_POSITION, MODE_POSITION, MODE_PWM, MODE_VELOCITY, MODEL_NUMBER_L, MOVING,
    MOVING_STATUS, OPERATING_MODE, DRIVE_MODE, POSITION_CENTRE, POSITION_D_GAIN,
    POSITION_I_GAIN, POSITION_P_GAIN, POSITION_TRAJECTORY, PRESENT_INPUT_VOLTAGE,
    PRESENT_POSITION, PRESENT_PWM, PRESENT_TEMPERATURE, PRESENT_VELOCITY,
    PROFILE_ACCELERATION, PROFILE_VELOCITY, PROTOCOL_TYPE, PULSES_PER_REV, PWM_LIMIT, PWM_MAX,
    R, RAD_PER_PULSE, REALTIME_TICK, REGISTERED, RETURN_DELAY_TIME, RPM2_PER_UNIT,
    RPM_PER_UNIT, RW, SHUTDOWN, STATUS_RETURN_LEVEL, TABLE_SIZE, TEMPERATURE_LIMIT,
    TORQUE_ENABLE, VELOCITY_LIMIT, VELOCITY_TRAJECTORY, VOLTAGE_V_PER_UNIT,
    acceleration_to_rad_s2, baud_to_bps, bps_to_baud, get, index, position_to_rad, put,
    rad_s_to_velocity, rad_to_position, return_delay_us, table_of, velocity_to_rad_s)

MODEL_NUMBER = 1020
FIRMWARE_VERSION = 46
MODEL_NAME = "xm430-w350"
EEPROM_BUSY_US = 5000  # busy after an EEPROM write (packets wait): our 5 ms, as the XL430's

CURRENT_LIMIT = 38
GOAL_CURRENT = 102
PRESENT_CURRENT = 126
PRESENT_LOAD = PRESENT_CURRENT   # where a load reads back: as the motor's current

# Operating Mode values (address 11).
MODE_CURRENT = 0
MODE_CURRENT_POSITION = 5
MODES = (MODE_CURRENT, MODE_VELOCITY, MODE_POSITION, MODE_EXTENDED_POSITION,
         MODE_CURRENT_POSITION, MODE_PWM)
POSITION_MODES = (MODE_POSITION, MODE_EXTENDED_POSITION, MODE_CURRENT_POSITION)
LIMITED_POSITION_MODES = (MODE_POSITION,)            # Goal Position within the limits
CURRENT_MODES = (MODE_CURRENT, MODE_CURRENT_POSITION)  # Goal Current caps the torque

# (address, name, size, access, default, min, max, signed), e-manual; a default of None is
# set at run time (goal and present values come from where the horn is).
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
    (31, "temperature_limit", 1, RW, 80, 0, 100, False),
    (32, "max_voltage_limit", 2, RW, 160, 95, 160, False),
    (34, "min_voltage_limit", 2, RW, 95, 95, 160, False),
    (36, "pwm_limit", 2, RW, 885, 0, 885, False),
    (38, "current_limit", 2, RW, 1193, 0, 1193, False),
    (44, "velocity_limit", 4, RW, 200, 0, 1023, False),
    (48, "max_position_limit", 4, RW, 4095, 0, 4095, False),
    (52, "min_position_limit", 4, RW, 0, 0, 4095, False),
    (60, "startup_configuration", 1, RW, 0, 0, 3, False),
    (63, "shutdown", 1, RW, 52, 0, 255, False),
    (64, "torque_enable", 1, RW, 0, 0, 1, False),
    (65, "led", 1, RW, 0, 0, 1, False),
    (68, "status_return_level", 1, RW, 2, 0, 2, False),
    (69, "registered_instruction", 1, R, 0, 0, 1, False),
    (70, "hardware_error_status", 1, R, 0, 0, 255, False),
    (76, "velocity_i_gain", 2, RW, 1920, 0, 16383, False),
    (78, "velocity_p_gain", 2, RW, 100, 0, 16383, False),
    (80, "position_d_gain", 2, RW, 0, 0, 16383, False),
    (82, "position_i_gain", 2, RW, 0, 0, 16383, False),
    (84, "position_p_gain", 2, RW, 800, 0, 16383, False),
    (88, "feedforward_2nd_gain", 2, RW, 0, 0, 16383, False),
    (90, "feedforward_1st_gain", 2, RW, 0, 0, 16383, False),
    (98, "bus_watchdog", 1, RW, 0, 0, 127, False),
    (100, "goal_pwm", 2, RW, 0, -885, 885, True),
    (102, "goal_current", 2, RW, 0, -1193, 1193, True),
    (104, "goal_velocity", 4, RW, 0, -1023, 1023, True),
    (108, "profile_acceleration", 4, RW, 0, 0, 32767, False),
    (112, "profile_velocity", 4, RW, 0, 0, 32767, False),
    (116, "goal_position", 4, RW, None, -EXT_POSITION_MAX, EXT_POSITION_MAX, True),
    (120, "realtime_tick", 2, R, 0, 0, 32767, False),
    (122, "moving", 1, R, 0, 0, 1, False),
    (123, "moving_status", 1, R, 0, 0, 255, False),
    (124, "present_pwm", 2, R, 0, -885, 885, True),
    (126, "present_current", 2, R, 0, -1193, 1193, True),
    (128, "present_velocity", 4, R, 0, -1023, 1023, True),
    (132, "present_position", 4, R, None, -2147483648, 2147483647, True),
    (136, "velocity_trajectory", 4, R, 0, -1023, 1023, True),
    (140, "position_trajectory", 4, R, None, -2147483648, 2147483647, True),
    (144, "present_input_voltage", 2, R, 120, 0, 65535, False),
    (146, "present_temperature", 1, R, 32, 0, 255, False),
    (147, "backup_ready", 1, R, 0, 0, 1, False),
)

BY_ADDRESS, BY_NAME, OWNER = index(FIELDS)


def defaults(position=POSITION_CENTRE):
    """The control table at power-on, the horn at ``position`` (pulses)."""
    return table_of(FIELDS, position)


# --- Units beyond the X series' shared ones ------------------------------------------
CURRENT_A_PER_UNIT = 0.00269     # Current Limit, Goal/Present Current: 2.69 mA
# e-manual specifications: stall torque 4.1 N m at 12.0 V (2.3 A), no-load speed 46 rpm
# at 12.0 V; the recommended supply is 12.0 V (10.0-14.8 V).
RATED_SUPPLY_V = 12.0
STALL_TORQUE_NM = 4.1
STALL_CURRENT_A = 2.3
NO_LOAD_RPM = 46.0


def fraction_to_load(fraction):
    """Present Current (2.69 mA units, signed) of a load, a fraction of the stall current."""
    return int(round(max(-1.0, min(1.0, fraction)) * STALL_CURRENT_A / CURRENT_A_PER_UNIT))
