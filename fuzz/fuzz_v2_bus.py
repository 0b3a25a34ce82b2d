"""The Protocol 2.0 bus with 18 emulated XL430s (hil/servobus/protocols/v2.py, hil/servobus/xseries_servo.py) under
random instruction streams: no exception escapes, every register within its documented
range (protocol/dynamixel/xl430.py FIELDS), the identity registers unchanged, and after the line
has idled a PING to a servo is answered (resync)."""
from __future__ import annotations

import random

from fuzz.fuzz_bus import BusSpec, rare_id_writes, run_streams
from fuzz.fuzz_v2_parser import garbage
from fuzz.tally import Tally
from hexhil.hil.servobus.protocols.v2 import Bus2
from hexhil.hil.clock import VirtualClock
from hexhil.hil.servobus.xseries_servo import XSeriesServo
from hexhil.protocol.dynamixel import v2 as dx2
from hexhil.protocol.dynamixel import xl430 as xl

SERVOS = 18
READ_TIMEOUT_US = 20_000       # a SYNC_READ of 18 x 148 bytes would take longer: fine
IDENTITY = ((0, 2), (6, 1))    # model number and firmware version
REBUILD_EVERY = 1_000
# Present values are signed and may be anything the actuator reports: not range-checked.
UNCHECKED = {"present_position", "position_trajectory", "present_velocity",
             "velocity_trajectory", "present_load", "present_pwm", "present_input_voltage",
             "present_temperature", "realtime_tick", "moving_status", "hardware_error_status",
             "model_information", "goal_position"}


def instruction(rng: random.Random) -> bytes:
    """One instruction, mostly to the 18 IDs, mostly well formed; writes anywhere."""
    dev_id = rng.choice((rng.randrange(1, SERVOS + 1),) * 6 + (dx2.BROADCAST_ID, rng.randrange(253)))
    instr = rng.choice((dx2.PING, dx2.READ, dx2.WRITE, dx2.WRITE, dx2.REG_WRITE, dx2.ACTION,
                        dx2.SYNC_READ, dx2.FAST_SYNC_READ, dx2.BULK_READ, dx2.FAST_BULK_READ,
                        dx2.SYNC_WRITE, dx2.BULK_WRITE, dx2.REBOOT, dx2.CLEAR,
                        dx2.CONTROL_TABLE_BACKUP, dx2.FACTORY_RESET, rng.randrange(256)))
    addr = rng.choice((xl.GOAL_POSITION, xl.TORQUE_ENABLE, xl.OPERATING_MODE, xl.GOAL_VELOCITY,
                       xl.PROFILE_ACCELERATION, xl.PROFILE_VELOCITY, xl.STATUS_RETURN_LEVEL,
                       xl.RETURN_DELAY_TIME, xl.HOMING_OFFSET, rng.randrange(160)))
    a2 = bytes((addr & 0xFF, addr >> 8))
    ids = rng.sample(range(1, SERVOS + 1), rng.randrange(1, 7))
    if instr in (dx2.READ, dx2.SYNC_READ, dx2.FAST_SYNC_READ):
        params = a2 + bytes((rng.randrange(1, 12), 0))
        if instr != dx2.READ:
            params += bytes(ids)
    elif instr in (dx2.WRITE, dx2.REG_WRITE):
        params = a2 + rng.randbytes(rng.choice((1, 2, 4, 4, rng.randrange(9))))
    elif instr == dx2.SYNC_WRITE:
        n = rng.choice((1, 4, rng.randrange(6)))
        params = a2 + bytes((n, 0)) + b"".join(bytes((i,)) + rng.randbytes(n) for i in ids)
    elif instr in (dx2.BULK_READ, dx2.FAST_BULK_READ):
        params = b"".join(bytes((i, rng.randrange(150), 0, rng.randrange(1, 6), 0)) for i in ids)
    elif instr == dx2.BULK_WRITE:
        params = b"".join(bytes((i, addr & 0xFF, addr >> 8, 4, 0)) + rng.randbytes(4) for i in ids)
    elif instr == dx2.FACTORY_RESET:
        params = bytes((dx2.RESET_EXCEPT_ID_BAUD,))   # the others move IDs and baud away
    else:
        params = rng.randbytes(rng.randrange(6))
    return dx2.packet(dev_id, instr, rare_id_writes(rng, params, xl.ID, xl.LED))


def fresh_bus() -> Bus2:
    servos = [XSeriesServo(i) for i in range(1, SERVOS + 1)]
    for s in servos:
        s.table[xl.BAUD_RATE] = 3
    return Bus2(servos, VirtualClock())


def check_servo(s: XSeriesServo) -> str:
    s._refresh_present()
    t = s.table
    if len(t) != xl.TABLE_SIZE:
        return f"table of {len(t)} bytes"
    for address, name, size, _acc, _d, lo, hi, signed in xl.FIELDS:
        if name in UNCHECKED:
            continue
        v = xl.get(t, address, size, signed)
        if not lo <= v <= hi:
            return f"{name} = {v} outside {lo}-{hi}"
    fresh = xl.defaults()
    for address, size in IDENTITY:
        if xl.get(t, address, size) != xl.get(fresh, address, size):
            return f"read-only register {address} changed"
    return ""


def pingable(bus: Bus2) -> XSeriesServo | None:
    ids = [s.id for s in bus.servos if s.baud_bps == bus.baud]
    for s in bus.servos:
        if s.baud_bps == bus.baud and ids.count(s.id) == 1:
            return s
    return None


XL430 = BusSpec("protocol 2.0 bus, 18 XL430s", fresh_bus, instruction, garbage, check_servo,
                pingable, dx2.ping, dx2.Parser, REBUILD_EVERY, 4000, (0, 300, READ_TIMEOUT_US),
                dx2.INTER_BYTE_TIMEOUT_US + 10_000, 100_000, 14, READ_TIMEOUT_US)


def run(seed: int, budget_s: float | None, limit: int | None) -> list[Tally]:
    return run_streams(XL430, seed, budget_s, limit)
