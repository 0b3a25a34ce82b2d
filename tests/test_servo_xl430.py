"""The emulated XL430-W250-T (hil/servobus/xseries_servo.py) on a Protocol 2.0 line (hil/servobus/protocols/v2.py):
instructions, EEPROM lock, operating modes, the profile, hardware errors, reply timing."""
from __future__ import annotations

import pytest

from hexhil.hil.link.board_line import MISTAKES
from hexhil.hil.servobus.protocols.v2 import Bus2
from hexhil.hil.clock import VirtualClock
from hexhil.hil.servobus.servo_layout import OVERLOAD_TIME_US
from hexhil.hil.servobus.profile import Trapezoid
from hexhil.hil.servobus.xseries_servo import XSeriesServo
from hexhil.protocol.dynamixel import v2 as dx2
from hexhil.protocol.dynamixel import xl430 as xl


def make_bus(n: int = 18, rd_units: int = 0, **kw) -> Bus2:
    servos = []
    for i in range(1, n + 1):
        s = XSeriesServo(i)
        s.table[xl.BAUD_RATE] = 3            # 1 Mbps
        s.table[xl.RETURN_DELAY_TIME] = rd_units
        servos.append(s)
    return Bus2(servos, VirtualClock(), **kw)


def transact(bus: Bus2, pkt: bytes, timeout_us: int = 20000) -> list[dx2.Packet]:
    bus.master_write(pkt)
    return dx2.Parser().feed(bus.master_read(4096, timeout_us))


def one(bus: Bus2, pkt: bytes) -> dx2.Packet:
    (reply,) = transact(bus, pkt)
    return reply


def u32(p: dx2.Packet, i: int = 1) -> int:
    return xl.get(p.params, i, 4, True)


def test_ping_reports_model_1060_and_read_is_timed_by_the_return_delay() -> None:
    bus = make_bus(2, rd_units=250)
    r = one(bus, dx2.ping(2))
    assert (r.id, r.error, r.params[1] | r.params[2] << 8) == (2, 0, 1060)
    t0 = bus.clock.t_us
    bus.master_write(dx2.read(1, xl.PRESENT_POSITION, 4))       # 14 bytes
    data = bus.master_read(15, 10_000)                          # 15-byte reply
    assert bus.clock.t_us - t0 == 140 + 500 + 150
    assert u32(dx2.Parser().feed(data)[0]) == xl.POSITION_CENTRE


def test_eeprom_write_with_torque_on_is_an_access_error() -> None:
    bus = make_bus(1)
    assert one(bus, dx2.write(1, xl.TORQUE_ENABLE, b"\x01")).error == 0
    assert one(bus, dx2.write(1, xl.RETURN_DELAY_TIME, b"\x00")).error == dx2.ERR_ACCESS
    assert one(bus, dx2.write(1, xl.PRESENT_POSITION, bytes(4))).error == dx2.ERR_ACCESS
    assert one(bus, dx2.write(1, xl.GOAL_POSITION, bytes(2))).error == dx2.ERR_DATA_LENGTH
    assert one(bus, dx2.write(1, 66, b"\x01")).error == dx2.ERR_ACCESS
    bad_goal = (5000).to_bytes(4, "little")
    assert one(bus, dx2.write(1, xl.GOAL_POSITION, bad_goal)).error == dx2.ERR_DATA_LIMIT
    assert one(bus, dx2.write(1, xl.TORQUE_ENABLE, b"\x02")).error == dx2.ERR_DATA_RANGE


def test_sync_read_answers_in_list_order_each_after_the_previous() -> None:
    bus = make_bus(18, rd_units=10)
    ids = list(range(18, 0, -1))
    t0 = bus.clock.t_us
    got = transact(bus, dx2.sync_read(xl.PRESENT_POSITION, 4, ids))
    assert [p.id for p in got] == ids
    # 31-byte request, then 18 x (20 us delay + 15-byte reply)
    assert bus.clock.t_us - t0 >= 310 + 18 * (20 + 150)


def test_fast_sync_read_is_one_packet_and_a_missing_servo_ends_the_chain() -> None:
    bus = make_bus(3)
    (p,) = transact(bus, dx2.sync_read(xl.PRESENT_POSITION, 4, [3, 1, 2], fast=True))
    assert p.id == dx2.BROADCAST_ID
    blocks = dx2.fast_blocks(p.params, [4, 4, 4])
    assert [b[1] for b in blocks] == [3, 1, 2]
    assert [xl.get(b[2], 0, 4, True) for b in blocks] == [xl.POSITION_CENTRE] * 3
    got = transact(bus, dx2.sync_read(xl.PRESENT_POSITION, 4, [1, 9, 2]))
    assert [q.id for q in got] == [1]


def test_bulk_read_of_two_addresses_and_fast_bulk_read() -> None:
    bus = make_bus(2)
    req = [(1, xl.PRESENT_POSITION, 4), (2, xl.PRESENT_TEMPERATURE, 1)]
    a, b = transact(bus, dx2.bulk_read(req))
    assert (a.id, len(a.params), b.id, b.params[1]) == (1, 5, 2, 32)
    (f,) = transact(bus, dx2.bulk_read(req, fast=True))
    assert [(e, i, len(d)) for e, i, d in dx2.fast_blocks(f.params, [4, 1])] == [(0, 1, 4), (0, 2, 1)]


def test_bad_crc_gets_no_reply_and_the_next_packet_is_served() -> None:
    bus = make_bus(1)
    bad = bytearray(dx2.ping(1))
    bad[-2] ^= 0x40
    assert transact(bus, bytes(bad), 2000) == []
    assert one(bus, dx2.ping(1)).id == 1
    assert bus.stats["bad_checksum"] == 1


def test_status_return_level_and_broadcast_ping_order() -> None:
    bus = make_bus(3)
    assert transact(bus, dx2.write(2, xl.STATUS_RETURN_LEVEL, b"\x00")) == []  # new level
    assert transact(bus, dx2.write(2, xl.LED, b"\x01")) == []
    assert transact(bus, dx2.read(2, xl.LED, 1)) == []
    assert one(bus, dx2.ping(2)).id == 2                       # PING at every level
    assert [p.id for p in transact(bus, dx2.ping())] == [1, 2, 3]


def test_position_mode_moves_at_profile_velocity_then_trapezoid() -> None:
    bus = make_bus(1)
    s = bus.servos[0]
    transact(bus, dx2.write(1, xl.PROFILE_VELOCITY, (100).to_bytes(4, "little")))  # 22.9 rpm
    transact(bus, dx2.write(1, xl.TORQUE_ENABLE, b"\x01"))
    bus.master_write(dx2.write(1, xl.GOAL_POSITION, (3072).to_bytes(4, "little")))  # +90 deg
    bus.idle_until(bus.clock.t_us + 200_000)
    s.advance_to(bus.clock.t_us)
    v = xl.velocity_to_rad_s(100)
    moved = xl.position_to_rad(s.value("present_position"))
    assert moved == pytest.approx(v * 0.2, abs=0.01)
    assert s.value("present_velocity") == 100 and s.value("moving") == 1
    bus.idle_until(bus.clock.t_us + 2_000_000)
    s.advance_to(bus.clock.t_us)
    assert s.value("present_position") == 3072 and s.value("moving") == 0
    tr = Trapezoid(0, 0.0, 1.0, 0.0, 2.0, 4.0)  # 0.5 s up, 0 s cruise... triangle check
    assert tr.at(10**9) == (1.0, 0.0) and tr.at(250_000)[1] == pytest.approx(1.0)
    assert tr.duration_s == pytest.approx(1.0)


def test_velocity_and_pwm_modes_turn_endlessly() -> None:
    bus = make_bus(1)
    s = bus.servos[0]
    transact(bus, dx2.write(1, xl.OPERATING_MODE, bytes((xl.MODE_VELOCITY,))))
    transact(bus, dx2.write(1, xl.TORQUE_ENABLE, b"\x01"))
    transact(bus, dx2.write(1, xl.GOAL_VELOCITY, (-50).to_bytes(4, "little", signed=True)))
    bus.idle_until(bus.clock.t_us + 100_000)
    s.advance_to(bus.clock.t_us)
    assert s.value("present_velocity") == -50
    assert one(bus, dx2.write(1, xl.GOAL_VELOCITY, (400).to_bytes(4, "little"))).error \
        == dx2.ERR_DATA_LIMIT                                  # over Velocity Limit 265


def test_overload_shuts_down_until_reboot_and_the_alert_bit_shows_it() -> None:
    bus = make_bus(1)
    s = bus.servos[0]
    transact(bus, dx2.write(1, xl.TORQUE_ENABLE, b"\x01"))
    transact(bus, dx2.write(1, xl.GOAL_POSITION, (3000).to_bytes(4, "little")))
    s.set_stalled(True, bus.clock.t_us)
    bus.idle_until(bus.clock.t_us + OVERLOAD_TIME_US + 10_000)
    r = one(bus, dx2.read(1, xl.HARDWARE_ERROR_STATUS, 1))
    assert r.error & dx2.ALERT and r.params[1] == xl.HW_OVERLOAD
    assert s.value("torque_enable") == 0
    assert one(bus, dx2.write(1, xl.TORQUE_ENABLE, b"\x01")).error & 0x7F == dx2.ERR_RESULT_FAIL
    s.set_stalled(False, bus.clock.t_us)
    assert one(bus, dx2.reboot(1)).error & dx2.ALERT             # answered before rebooting
    bus.idle_until(bus.clock.t_us + 10_000)
    assert one(bus, dx2.read(1, xl.HARDWARE_ERROR_STATUS, 1)).params == b"\x00\x00"


def test_factory_reset_reg_write_action_clear_backup() -> None:
    bus = make_bus(1)
    s = bus.servos[0]
    assert one(bus, dx2.reg_write(1, xl.LED, b"\x01")).error == 0
    assert s.value("led") == 0 and s.value("registered_instruction") == 1
    assert transact(bus, dx2.action()) == []                  # broadcast: no reply
    assert s.value("led") == 1
    assert one(bus, dx2.action(1)).error == dx2.ERR_INSTRUCTION
    assert one(bus, dx2.control_table_backup(1)).error == 0
    assert one(bus, dx2.clear(1)).error == 0
    assert one(bus, dx2.factory_reset(1, dx2.RESET_EXCEPT_ID_BAUD)).error == 0
    bus.idle_until(bus.clock.t_us + 10_000)
    assert s.value("return_delay_time") == 250 and s.id == 1 and s.baud_bps == 1_000_000
    assert one(bus, dx2.packet(1, 0x77)).error == dx2.ERR_INSTRUCTION


def test_stuffed_write_reaches_the_table() -> None:
    bus = make_bus(1)
    transact(bus, dx2.write(1, xl.OPERATING_MODE, bytes((xl.MODE_EXTENDED_POSITION,))))
    goal = 0xFDFFFF                      # little-endian FF FF FD 00: stuffed on the wire
    raw = dx2.write(1, xl.GOAL_POSITION, goal.to_bytes(4, "little"))
    assert b"\xff\xff\xfd\xfd" in raw
    assert one(bus, raw).error == dx2.ERR_DATA_RANGE          # outside +-1048575
    r = one(bus, dx2.write(1, xl.HOMING_OFFSET, (-3).to_bytes(4, "little", signed=True)))
    assert r.error == 0 and bus.servos[0].value("homing_offset") == -3


def test_master_check_names_a_protocol_2_masters_mistakes() -> None:
    from hexhil.hil.servobus.master_check import MasterCheck
    from hexhil.hil.servobus.protocols import RULES
    KINDS_2 = RULES[2].kinds

    bus = make_bus(2)
    check = MasterCheck(protocol=2)
    bus.monitor = check
    transact(bus, dx2.write(1, xl.TORQUE_ENABLE, b"\x01"))
    transact(bus, dx2.write(1, xl.RETURN_DELAY_TIME, b"\x00"))      # EEPROM, torque on
    bus.master_write(dx2.write(2, xl.RETURN_DELAY_TIME, b"\x00"))  # fine ...
    bus.master_read(11, 5_000)
    bus.master_write(dx2.ping(2))                                   # ... but 2 is busy
    bus.master_write(dx2.ping(1))
    bus.master_write(dx2.ping(1))                                   # talks over 1's reply
    bus.master_read(100, 20_000)
    transact(bus, dx2.packet(1, 0x77))
    transact(bus, dx2.read(dx2.BROADCAST_ID, 0, 2))
    transact(bus, dx2.packet(1, dx2.SYNC_READ, b"\x84\x00\x04\x00\x01"))
    bad = bytearray(dx2.ping(1))
    bad[-1] ^= 1
    transact(bus, bytes(bad))
    raw = dx2.ping(1)
    bus.master_write(raw[:4])
    bus.idle_until(bus.clock.t_us + 200_000)
    bus.master_write(raw[4:])
    assert set(check.counts) == set(KINDS_2)
    # every kind the wire shows (the direction pin's come from the virtual board,
    # tests/test_virtual_board.py)
    assert all(check.counts[k] >= 1 for k in KINDS_2 if k not in MISTAKES), check.counts
    assert any("access error" in d for _, k, d in check.events if k == "bad_write")


def test_the_ax12_faults_reach_xl430s_through_the_scenario() -> None:
    from hexhil.hil.run import rig

    sc = {"_path": "t", "bus": {"model": "xl430-w250", "servos": 3, "return_delay_us": 0},
          "faults": {"unplug": [{"id": 2, "at_s": 0.05, "until_s": 0.1}],
                     "voltage_sag": [{"volts": 5.0, "at_s": 0.15}]}}
    bus = rig.build(sc).bus
    assert isinstance(bus, Bus2) and [s.id for s in bus.servos] == [1, 2, 3]
    assert one(bus, dx2.write(2, xl.LED, b"\x01")).error == 0
    bus.idle_until(60_000)
    assert transact(bus, dx2.ping(2), 2000) == []                    # unplugged
    bus.idle_until(110_000)
    assert one(bus, dx2.read(2, xl.LED, 1)).params == b"\x00\x00"    # power-cycled: RAM reset
    bus.idle_until(160_000)
    r = one(bus, dx2.read(1, xl.HARDWARE_ERROR_STATUS, 1))             # 5 V < Min Voltage 6 V
    assert r.error & dx2.ALERT and r.params[1] == xl.HW_INPUT_VOLTAGE


def test_profile_acceleration_follows_the_trapezoid() -> None:
    bus = make_bus(1)
    s = bus.servos[0]
    transact(bus, dx2.write(1, xl.PROFILE_ACCELERATION, (20).to_bytes(4, "little")))
    transact(bus, dx2.write(1, xl.PROFILE_VELOCITY, (100).to_bytes(4, "little")))
    transact(bus, dx2.write(1, xl.TORQUE_ENABLE, b"\x01"))
    bus.master_write(dx2.write(1, xl.GOAL_POSITION, (3072).to_bytes(4, "little")))
    t0 = bus.clock.t_us
    ramp = Trapezoid(t0, 0.0, xl.position_to_rad(3072), 0.0, xl.velocity_to_rad_s(100),
                     xl.acceleration_to_rad_s2(20))
    for dt_us in (100_000, 300_000, 700_000):
        bus.idle_until(t0 + dt_us)
        s.advance_to(bus.clock.t_us)
        want = xl.rad_to_position(ramp.at(bus.clock.t_us)[0])
        assert abs(s.value("present_position") - want) <= 2, dt_us
        assert s.value("position_trajectory") == want
    assert 0 < ramp.at(t0 + 100_000)[1] < xl.velocity_to_rad_s(100)   # still accelerating


def test_bad_xl430_bus_settings_are_one_line_errors() -> None:
    from conftest import hexhil_in_process

    for flags in (["--ids", "253"], ["--baud", "250000"]):
        r = hexhil_in_process("bus", "--model", "xl430-w250", "--pty", *flags)
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1, r.stderr
