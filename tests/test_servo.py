"""One emulated AX-12A: instructions, access rules, error bits, alarms, motion."""
from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hexhil.hil.servobus.ax12_servo import Servo
from hexhil.protocol.dynamixel.ax12 import EEPROM_BUSY_US
from hexhil.hil.servobus import servo_rules
from hexhil.hil.servobus.drive import NO_LOAD_RAD_S, KinematicActuator, drive
from hexhil.hil.servobus.servo_layout import OVERLOAD_TIME_US
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl


def status(reply: bytes) -> dxl.Packet:
    (pkt,) = dxl.Parser().feed(reply)
    return pkt


def write(s: Servo, address: int, data: bytes, t_us: int | None = None) -> int:
    """WRITE and its status code; by default sent as soon as the servo listens again."""
    t = max(s.t_us, s.busy_until_us) if t_us is None else t_us
    return status(s.handle(dxl.WRITE, bytes((address,)) + data, False, t)).code


def test_defaults_differ_by_edition():
    e, o = Servo(1, "emanual"), Servo(1, "original")
    assert e.value("model_number") == 12 and e.value("temperature_limit") == 70
    assert o.value("temperature_limit") == 85 and o.value("max_voltage_limit") == 190
    assert e.value("torque_limit") == e.value("max_torque") == 1023
    with pytest.raises(ValueError):
        Servo(1, "third")


def test_ping_and_read_and_status_format():
    s = Servo(7)
    assert s.handle(dxl.PING, b"", False, 0) == dxl.status(7)
    pkt = status(s.handle(dxl.READ, bytes((0, 3)), False, 0))
    assert (pkt.id, pkt.code, list(pkt.params)) == (7, 0, [12, 0, ax12.FIRMWARE_VERSION])
    assert status(s.handle(dxl.READ, bytes((48, 3)), False, 0)).code == dxl.ERR_RANGE
    assert status(s.handle(dxl.READ, bytes((0,)), False, 0)).code == dxl.ERR_INSTRUCTION
    assert status(s.handle(0x22, b"", False, 0)).code == dxl.ERR_INSTRUCTION
    assert s.handle(dxl.PING, b"", True, 0) is None  # broadcast: never answered


@pytest.mark.parametrize("level, answered", [(0, {dxl.PING}), (1, {dxl.PING, dxl.READ}),
                                             (2, {dxl.PING, dxl.READ, dxl.WRITE})])
def test_status_return_level(level, answered):
    s = Servo(1)
    s.table[ax12.STATUS_RETURN_LEVEL] = level
    got = set()
    for code, params in ((dxl.PING, b""), (dxl.READ, b"\x00\x02"), (dxl.WRITE, b"\x19\x01")):
        if s.handle(code, params, False, 0) is not None:
            got.add(code)
    assert got == answered
    assert s.value("led") == 1  # the unanswered WRITE still happened


def test_writes_refused_with_range_change_nothing():
    s = Servo(1)
    before = bytes(s.table)
    assert write(s, ax12.MODEL_NUMBER_L, b"\x05") == dxl.ERR_RANGE          # read-only
    assert write(s, ax12.PRESENT_POSITION, b"\x00\x00") == dxl.ERR_RANGE     # read-only
    assert write(s, 10, b"\x01") == dxl.ERR_RANGE                            # reserved
    assert write(s, ax12.GOAL_POSITION, b"\x00\x04") == dxl.ERR_RANGE        # 1024 > 1023
    assert write(s, ax12.STATUS_RETURN_LEVEL, b"\x03") == dxl.ERR_RANGE
    assert write(s, 49, b"\x00\x00") == dxl.ERR_RANGE                        # past the table
    assert bytes(s.table) == before


def test_partial_write_of_a_two_byte_field_is_checked_whole():
    s = Servo(1)
    assert write(s, ax12.GOAL_POSITION + 1, b"\x03") == 0  # high byte only: 0x300 | 0 = 768
    assert s.value("goal_position") == 0x300
    assert write(s, ax12.GOAL_POSITION + 1, b"\x04") == dxl.ERR_RANGE


def test_lock_emanual_freezes_eeprom_until_power_cycle():
    s = Servo(1, "emanual")
    assert write(s, ax12.LOCK, b"\x01") == 0
    assert write(s, ax12.RETURN_DELAY_TIME, b"\x00") == dxl.ERR_RANGE
    assert write(s, ax12.LOCK, b"\x00") == dxl.ERR_RANGE
    assert write(s, ax12.LED, b"\x01") == 0 and write(s, ax12.PUNCH, b"\x40\x00") == 0
    s.power_cycle(0)
    assert s.value("lock") == 0 and write(s, ax12.RETURN_DELAY_TIME, b"\x00") == 0


def test_lock_original_allows_only_24_to_35():
    s = Servo(1, "original")
    write(s, ax12.LOCK, b"\x01")
    assert write(s, ax12.GOAL_POSITION, b"\x00\x01") == 0
    assert write(s, ax12.PUNCH, b"\x40\x00") == dxl.ERR_RANGE
    assert write(s, ax12.ID, b"\x02") == dxl.ERR_RANGE


def test_reg_write_and_action():
    s = Servo(1)
    assert status(s.handle(dxl.ACTION, b"", False, 0)).code == dxl.ERR_INSTRUCTION
    assert status(s.handle(dxl.REG_WRITE, b"\x19\x01", False, 0)).code == 0
    assert s.value("registered") == 1 and s.value("led") == 0
    assert status(s.handle(dxl.ACTION, b"", False, 0)).code == 0
    assert s.value("registered") == 0 and s.value("led") == 1
    assert s.handle(dxl.ACTION, b"", True, 0) is None  # broadcast, nothing registered: silent


def test_factory_reset_and_sync_write():
    s = Servo(9)
    write(s, ax12.RETURN_DELAY_TIME, b"\x00")
    reply = s.handle(dxl.FACTORY_RESET, b"", False, s.busy_until_us)
    assert status(reply).id == 9 and s.id == 1 and s.value("return_delay_time") == 250
    params = bytes((ax12.GOAL_POSITION, 2, 3, 0, 1, 1, 0x10, 0x02))
    assert s.handle(dxl.SYNC_WRITE, params, True, s.deaf_until_us - 1) is None  # rebooting
    assert s.value("goal_position") != 0x210 and s.ignored == 1
    assert s.handle(dxl.SYNC_WRITE, params, True, s.deaf_until_us) is None
    assert s.value("goal_position") == 0x210


def test_a_packet_during_an_eeprom_write_is_taken_when_the_write_is_done():
    s = Servo(3)
    assert write(s, ax12.CW_ANGLE_LIMIT, b"\x10\x00", t_us=1_000) == 0  # its status goes out
    done = 1_000 + EEPROM_BUSY_US
    assert s.busy_until_us == done and s.return_delay_us == 500
    n = s.instructions
    # the next EEPROM write (dynamixel-controller's wheel mode: CW then CCW) is not lost
    assert s.handle(dxl.WRITE, bytes((ax12.CCW_ANGLE_LIMIT, 0, 0)), False, done - 3_000) \
        == dxl.status(3)
    assert s.value("ccw_angle_limit") == 0 and s.instructions == n + 1 and s.held == 1
    assert s.return_delay_us == 500 + 3_000          # its status 3 ms later than usual
    assert s.busy_until_us == done + EEPROM_BUSY_US  # and it writes its own EEPROM
    assert s.handle(dxl.PING, b"", False, s.busy_until_us) == dxl.status(3)
    assert s.return_delay_us == 500 and s.ignored == 0
    # RAM writes and refused EEPROM writes leave it free
    assert write(s, ax12.LED, b"\x01") == 0 and write(s, ax12.CW_ANGLE_LIMIT, b"\xff\x07") == dxl.ERR_RANGE
    assert s.handle(dxl.PING, b"", False, s.t_us) == dxl.status(3) and s.held == 1
    # a broadcast SYNC_WRITE of an EEPROM field keeps every addressed servo busy, silently
    t = s.t_us + 10
    s.handle(dxl.SYNC_WRITE, bytes((ax12.CW_ANGLE_LIMIT, 2, 3, 0, 0)), True, t)
    assert s.value("cw_angle_limit") == 0 and s.busy_until_us == t + EEPROM_BUSY_US
    # and the busy time is the servo's own setting
    quick = Servo(4, eeprom_busy_us=0)
    assert write(quick, ax12.RETURN_DELAY_TIME, b"\x00", t_us=0) == 0
    assert quick.handle(dxl.PING, b"", False, 0) == dxl.status(4) and quick.held == 0


def test_goal_outside_angle_limits_sets_bit_and_horn_stops_at_limit():
    s = Servo(1)
    write(s, ax12.CW_ANGLE_LIMIT, b"\xc8\x00")  # 200
    write(s, ax12.TORQUE_ENABLE, b"\x01")
    assert write(s, ax12.GOAL_POSITION, b"\x64\x00") == dxl.ERR_ANGLE_LIMIT  # 100 < 200
    s.advance_to(5_000_000)
    assert s.value("present_position") == 200 and s.value("goal_position") == 100


def test_kinematic_motion_at_moving_speed():
    s = Servo(1)
    write(s, ax12.TORQUE_ENABLE, b"\x01")
    write(s, ax12.MOVING_SPEED, (100).to_bytes(2, "little"))  # 11.1 rpm
    write(s, ax12.GOAL_POSITION, (712).to_bytes(2, "little"))
    speed = ax12.speed_to_rad_s(100)
    travel = ax12.position_to_rad(712) - ax12.position_to_rad(512)
    t_arrive = int(travel / speed * 1e6)
    s.advance_to(t_arrive // 2)
    assert s.value("moving") == 1 and abs(s.value("present_position") - 612) <= 1
    assert s.value("present_speed") == 100
    s.advance_to(t_arrive + 1000)
    assert s.value("moving") == 0 and s.value("present_position") == 712


@pytest.mark.parametrize("moving_speed", [0, 1023])
def test_no_load_speed_caps_motion_and_torque_off_holds(moving_speed):
    no_load_rad_s = ax12.MAX_SPEED_RPM * 2 * math.pi / 60
    a = KinematicActuator(0.0)
    a.command(100.0, ax12.speed_to_rad_s(moving_speed), 1.0, True, (1, 1, 32, 32, 32))
    a.advance_to(1_000_000)
    assert a.state()[0] == pytest.approx(no_load_rad_s, rel=1e-9)
    a.command(100.0, ax12.speed_to_rad_s(0), 1.0, False, (1, 1, 32, 32, 32))
    a.advance_to(2_000_000)
    assert a.state()[:2] == (pytest.approx(no_load_rad_s, rel=1e-9), 0.0)


def test_wheel_mode_turns_endlessly_both_ways():
    s = Servo(1)
    write(s, ax12.TORQUE_ENABLE, b"\x01")
    assert write(s, ax12.MOVING_SPEED, (1500).to_bytes(2, "little")) == dxl.ERR_RANGE  # joint mode
    assert write(s, ax12.CW_ANGLE_LIMIT, bytes(4)) == 0  # CW = CCW = 0: wheel mode
    assert write(s, ax12.GOAL_POSITION, (5).to_bytes(2, "little")) == 0  # no angle limit in wheel
    assert write(s, ax12.MOVING_SPEED, (300).to_bytes(2, "little")) == 0  # CCW, 33.3 rpm
    start_s = s.t_us / 1e6  # once the EEPROM write of the angle limits has settled
    s.advance_to(3_000_000)  # 1.67 turns: wrapped, still turning
    assert s.value("moving") == 1 and s.value("present_speed") == 300
    turned = ax12.position_to_rad(512) + 300 * 0.111 / 60 * 2 * math.pi * (3.0 - start_s)
    assert s.actuator.state()[0] == pytest.approx((turned + math.pi) % (2 * math.pi) - math.pi)
    assert write(s, ax12.MOVING_SPEED, (1024 + 300).to_bytes(2, "little"), 3_000_000) == 0
    s.advance_to(3_500_000)
    assert s.value("present_speed") == 1024 + 300  # bit 10: CW
    write(s, ax12.MOVING_SPEED, b"\x00\x00", 3_500_000)
    s.advance_to(4_000_000)
    assert s.value("moving") == 0


def test_voltage_sag_slows_the_motor():
    s = Servo(1)
    write(s, ax12.TORQUE_ENABLE, b"\x01")
    write(s, ax12.GOAL_POSITION, (1000).to_bytes(2, "little"))  # Moving Speed 0: flat out
    s.advance_to(100_000)
    full = s.actuator.state()[1]
    s.set_supply_v(6.0, 100_000)
    s.advance_to(200_000)
    assert s.actuator.state()[1] == pytest.approx(full / 2)
    assert full == pytest.approx(ax12.speed_to_rad_s(0))


def test_stall_overload_shutdown_and_rearm():
    s = Servo(1)
    write(s, ax12.TORQUE_ENABLE, b"\x01")
    s.set_stalled(True, 0)
    write(s, ax12.GOAL_POSITION, (800).to_bytes(2, "little"))
    s.advance_to(OVERLOAD_TIME_US // 2)
    assert s.state_errors() == 0 and s.value("present_load") == 1023
    s.advance_to(OVERLOAD_TIME_US + 1000)
    assert s.state_errors() & dxl.ERR_OVERLOAD
    assert s.value("torque_limit") == 0 and s.alarm_led  # shutdown 36 includes overload
    s.set_stalled(False, OVERLOAD_TIME_US + 2000)
    assert write(s, ax12.TORQUE_LIMIT, b"\xff\x03", OVERLOAD_TIME_US + 3000) == 0
    s.advance_to(OVERLOAD_TIME_US + 5_000_000)
    assert s.value("present_position") == 800 and s.state_errors() == 0


def test_overheating_and_voltage_bits():
    s = Servo(1)
    s.set_hot_spot(90.0, 0)
    s.advance_to(5_000_000)
    assert s.value("present_temperature") > 70
    assert status(s.handle(dxl.PING, b"", False, 5_000_000)).code == dxl.ERR_OVERHEATING
    assert s.value("torque_limit") == 0
    s.set_hot_spot(None, 5_000_000)
    s.set_supply_v(5.0, 5_000_000)
    s.advance_to(400_000_000)
    assert status(s.handle(dxl.PING, b"", False, 400_000_000)).code == dxl.ERR_INPUT_VOLTAGE
    assert s.value("present_voltage") == 50


# --- properties -----------------------------------------------------------------------
_MOTION = {38, 39, 40, 41, 46}  # Present Speed, Load, Moving follow the new command
_READ_ONLY = [a for f in ax12.FIELDS if f[3] == ax12.R for a in range(f[0], f[0] + f[2])]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 55), st.binary(min_size=0, max_size=6)), max_size=12),
       st.sampled_from(ax12.EDITIONS))
def test_control_table_invariants_under_random_writes(writes, edition):
    s = Servo(1, edition)
    for address, data in writes:
        before = bytes(s.table)
        locked = before[ax12.LOCK]
        reply = s.handle(dxl.WRITE, bytes((address,)) + data, False, 0)
        err = status(reply).code if reply else 0  # Status Return Level < 2: no reply
        after = bytes(s.table)
        for a in _READ_ONLY:
            if a not in _MOTION:
                assert after[a] == before[a], a
        if err & dxl.ERR_RANGE:
            changed = [a for a in range(50) if after[a] != before[a] and a not in _MOTION]
            if err & before[ax12.SHUTDOWN]:  # alarm shutdown: only Torque Limit drops, to 0
                assert ax12.get(after, ax12.TORQUE_LIMIT, 2) == 0
                changed = [a for a in changed if a not in (34, 35)]
            assert changed == []
        for f in ax12.FIELDS:
            wheel = not any(s.table[ax12.CW_ANGLE_LIMIT:ax12.CCW_ANGLE_LIMIT + 2])   # both limits 0
            hi = 2047 if f[0] == ax12.MOVING_SPEED and wheel else f[7]
            assert f[6] <= ax12.get(s.table, f[0], f[2]) <= hi, f[1]
        if locked and edition == ax12.EDITION_EMANUAL:
            assert after[:ax12.EEPROM_END] == before[:ax12.EEPROM_END] and after[ax12.LOCK] == 1
        if locked and edition == ax12.EDITION_ORIGINAL:
            changed = [a for a in range(50) if after[a] != before[a] and a not in _MOTION]
            assert all(24 <= a <= 35 for a in changed), changed


class _Recorder:
    """An actuator that keeps what ``drive`` commanded."""

    def __init__(self) -> None:
        self.commands: list[tuple] = []

    def command(self, *args) -> None:
        self.commands.append(args)

    def state(self) -> tuple[float, float, float]:
        return 0.25, 0.0, 0.0


def test_drive_commands_what_the_conversions_give_for_every_register_value():
    """drive() reads Goal Position and Moving Speed from tables made once by ax12's own
    conversions: every goal (clamped to the angle limits) and every 11-bit speed in joint
    mode, and a wheel-mode speed, reach the actuator as the conversions give them."""
    act = _Recorder()
    t = ax12.defaults(ax12.EDITION_EMANUAL, 512)
    _view, t_at = servo_rules.address(t)   # the view keeps the table its size
    calls = servo_rules.ServoCalls()
    t[6:10] = bytes((100, 0, 0xE8, 0x03))   # CW limit 100, CCW limit 1000
    for goal in range(0, 1024, 7):
        for speed in (0, 1, 300, 1023, 1024, 1500, 2047):
            t[30:34] = bytes((goal & 0xFF, goal >> 8, speed & 0xFF, speed >> 8))
            drive(act, calls.setpoint(t_at, 1.0))
            goal_rad, speed_rad_s = act.commands[-1][:2]
            assert goal_rad == ax12.position_to_rad(min(1000, max(100, goal)))
            assert speed_rad_s == min(ax12.speed_to_rad_s(speed), NO_LOAD_RAD_S)
    t[6:10] = bytes(4)                        # wheel mode: the speed's sign picks the way
    t[32:34] = bytes((0x2C, 0x05))            # 300 | DIRECTION_BIT
    drive(act, calls.setpoint(t_at, 1.0))
    assert act.commands[-1][0] == -math.inf
    assert act.commands[-1][1] == 300 * ax12.SPEED_RPM_PER_UNIT * 2.0 * math.pi / 60.0
