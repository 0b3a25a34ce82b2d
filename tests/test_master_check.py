"""The rig checks the master: a deliberately wrong master gets each violation kind named;
our firmware gets none (lockstep, serial digest unchanged); the sensor node answers."""
from __future__ import annotations

from hexhil.hil.run import rig
from hexhil.hil.link.board_line import MISTAKES
from hexhil.hil.servobus.master_check import KINDS, MasterCheck
from hexhil.hil.servobus.switch_node import MODEL_NUMBER, SWITCHES, SensorNode
from hexhil.hil.run.lockstep import Simulator
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl


def _bus(levels=lambda: 0b100101):
    built = rig.build({"_path": "<test>", "bus": {"servos": 3}})
    bus = built.bus
    check = MasterCheck()
    bus.monitor = check
    bus.add_device(SensorNode(levels))
    return bus, check


def _transact(bus, packet: bytes, n: int = 64, timeout_us: int = 2_000) -> bytes:
    bus.master_write(packet)
    return bus.master_read(n, timeout_us)


def test_sensor_node_answers_ping_model_and_switches():
    bus, check = _bus()
    assert dxl.Parser().feed(_transact(bus, dxl.ping(100)))[0].code == 0
    model = dxl.Parser().feed(_transact(bus, dxl.read(100, 0, 3)))[0].params
    assert model == bytes((MODEL_NUMBER & 0xFF, MODEL_NUMBER >> 8, 1))
    sw = dxl.Parser().feed(_transact(bus, dxl.read(100, SWITCHES, 2)))[0].params
    assert sw == bytes((0b100101, 3))           # switches, presses seen so far
    refused = dxl.Parser().feed(_transact(bus, dxl.write(100, SWITCHES, b"\x01")))[0]
    assert refused.code & dxl.ERR_RANGE
    assert check.counts["bad_write"] == 1 and sum(check.counts.values()) == 1


def test_a_wrong_master_gets_each_kind_named():
    bus, check = _bus()
    t = bus.clock.t_us
    _transact(bus, dxl.write(1, ax12.RETURN_DELAY_TIME, b"\x00"))     # EEPROM: deaf 5 ms
    _transact(bus, dxl.ping(1))                                        # eeprom_busy
    bus.idle_until(bus.clock.t_us + 20_000)
    _transact(bus, dxl.packet(1, 0x92, b"\x24\x02"))                   # BULK_READ: unsupported
    _transact(bus, dxl.write(2, ax12.PRESENT_POSITION, b"\x00\x02"))  # read-only: bad_write
    _transact(bus, dxl.write(2, ax12.GOAL_POSITION, b"\x00\x04"))     # 1024: bad_write
    half = dxl.ping(3)
    bus.master_write(half[:3])
    bus.idle_until(bus.clock.t_us + 150_000)
    bus.master_write(half[3:])                                         # inter_byte_gap
    _transact(bus, dxl.ping(dxl.BROADCAST_ID), timeout_us=100)        # broadcast_read_ping
    bus.master_write(dxl.read(2, 36, 2))
    bus.master_write(dxl.ping(3))                                      # talk_over_reply
    bus.idle_until(bus.clock.t_us + 5_000)
    bad = bytearray(dxl.ping(2))
    bad[-1] ^= 0xFF
    _transact(bus, bytes(bad))                                         # bad_checksum
    on_the_line = [k for k in KINDS if k not in MISTAKES]   # MISTAKES: tests/test_virtual_board.py
    assert all(check.counts[k] >= 1 for k in on_the_line), check.counts
    assert check.counts["bad_write"] == 2 and check.counts["eeprom_busy"] == 1
    s = check.summary()
    assert s["total"] == sum(check.counts.values()) and set(s["first_s"]) == set(on_the_line)
    assert all(e["t_s"] >= t * 1e-6 for e in s["events"])


def test_our_firmware_breaks_no_rule_and_the_digest_holds():
    sc = {"_path": "<test>", "scenario": {"seed": 1}, "gait": {"name": "tripod"}}
    plain = Simulator(sc, seed=1).run(1.5)
    sim = Simulator(sc, seed=1)
    check = MasterCheck()
    sim.bus.monitor = check
    watched = sim.run(1.5)
    assert watched.serial_digest == plain.serial_digest and watched.cycles > 50
    assert sum(check.counts.values()) == 0, check.summary()
