"""The emulated bus with 18 AX-12s (hil/bus.py, hil/servo.py) under random instruction
streams. After each stream: no exception escaped, every register within its documented
range (protocol/ax12.py FIELDS), the read-only identity registers unchanged, and after
the line has idled past the inter-byte timeout a PING to a servo is answered (resync)."""
from __future__ import annotations

import random

from fuzz.hostile import Rng, garbage
from fuzz.tally import Budget, Tally
from hil.bus import Bus
from hil.clock import VirtualClock
from hil.servo import Servo
from protocol import ax12
from protocol import dynamixel as dxl

SERVOS = 18
READ_TIMEOUT_US = 3_000        # the longest reply (50-byte READ) after 508 us return delay
IDENTITY = ((0, 2), (2, 1))    # model number and firmware version: read-only, never change
REBUILD_EVERY = 2_000          # streams on one bus before a fresh one (ID/baud drift)


def _instruction(rng: random.Random) -> bytes:
    """One instruction, mostly to the 18 IDs, mostly well formed; writes anywhere."""
    dev_id = rng.choice((rng.randrange(1, SERVOS + 1),) * 6 + (dxl.BROADCAST_ID, rng.randrange(254)))
    code = rng.choice((dxl.PING, dxl.READ, dxl.READ, dxl.WRITE, dxl.WRITE, dxl.REG_WRITE,
                       dxl.ACTION, dxl.SYNC_WRITE, rng.randrange(256)))
    if code == dxl.READ:
        params = bytes((rng.randrange(60), rng.randrange(60)))
    elif code in (dxl.WRITE, dxl.REG_WRITE):
        addr = rng.choice((ax12.GOAL_POSITION, ax12.MOVING_SPEED, ax12.TORQUE_ENABLE,
                           ax12.TORQUE_LIMIT, ax12.LOCK, ax12.RETURN_DELAY_TIME,
                           ax12.STATUS_RETURN_LEVEL, ax12.CW_ANGLE_LIMIT, rng.randrange(55)))
        params = bytes((addr,)) + rng.randbytes(rng.choice((1, 1, 2, 2, rng.randrange(6))))
    elif code == dxl.SYNC_WRITE:
        n = rng.choice((2, 4, rng.randrange(5)))
        ids = rng.sample(range(1, SERVOS + 1), rng.randrange(1, 7))
        params = bytes((rng.choice((ax12.GOAL_POSITION, rng.randrange(50))), n)) + b"".join(
            bytes((i,)) + rng.randbytes(n) for i in ids)
    else:
        params = rng.randbytes(rng.randrange(4))
    if rng.random() < 0.3:  # the address-changing writes are kept rare
        params = params.replace(bytes((ax12.ID,)), bytes((ax12.GOAL_POSITION,)), 1)
    return dxl.packet(dev_id, code, params)


def _fresh_bus() -> Bus:
    clock = VirtualClock()
    return Bus([Servo(i) for i in range(1, SERVOS + 1)], clock)


def check_servo(s: Servo) -> str:
    """The first broken invariant of a servo's control table, or ''."""
    t = s._present()
    if len(t) != ax12.TABLE_SIZE:
        return f"table of {len(t)} bytes"
    for address, name, size, *_rest, lo, hi in ax12.FIELDS:
        v = ax12.get(t, address, size)
        if address == ax12.MOVING_SPEED and v > hi and v <= 2047:
            continue  # wheel mode: 0-2047 (e-manual, address 32)
        if not lo <= v <= hi:
            return f"{name} = {v} outside {lo}-{hi}"
    for address, size in IDENTITY:
        if ax12.get(t, address, size) != ax12.get(ax12.defaults(s.edition), address, size):
            return f"read-only register {address} changed"
    return ""


def _pingable(bus: Bus) -> Servo | None:
    """A servo at the line's baud whose ID no other servo shares."""
    ids = [s.id for s in bus.servos if s.baud_bps == bus.baud]
    for s in bus.servos:
        if s.baud_bps == bus.baud and ids.count(s.id) == 1 and s.id != dxl.BROADCAST_ID:
            return s
    return None


def run(seed: int, budget_s: float | None, limit: int | None) -> list[Tally]:
    rng = random.Random(seed)
    junk_rng = Rng(seed)
    tally = Tally("emulated bus, 18 servos", "streams")
    budget = Budget(budget_s, limit)
    bus = _fresh_bus()
    while budget.more(tally.inputs):
        tally.inputs += 1
        if tally.inputs % REBUILD_EVERY == 0 or _pingable(bus) is None:
            bus = _fresh_bus()
        try:
            for _ in range(rng.randrange(1, 6)):
                data = _instruction(rng) if rng.random() < 0.7 else bytes(garbage(junk_rng))
                bus.master_write(data)
                bus.master_read(300, rng.choice((0, 200, READ_TIMEOUT_US)))
            for s in bus.servos:
                broken = check_servo(s)
                if broken:
                    tally.escape(f"stream {tally.inputs}: servo {s.id}: {broken}")
                    bus = _fresh_bus()
                    break
            bus.idle_until(bus.clock.t_us + dxl.INTER_BYTE_TIMEOUT_US + 1)
            bus.master_read(10_000, 0)  # drop what is still on the line
            target = _pingable(bus)
            if target is None:
                continue
            tally.resync_checked += 1
            bus.master_write(dxl.ping(target.id))
            reply = dxl.Parser().feed(bus.master_read(6, READ_TIMEOUT_US))
            if reply and reply[0].id == target.id:
                tally.resync_found += 1
            elif len(tally.notes) < 5:
                tally.notes[f"no PING reply at stream {tally.inputs}"] = target.id
        except Exception as exc:  # an escape is what the fuzzer is for: count and report it
            tally.escape(f"stream {tally.inputs}: {exc.__class__.__name__}: {exc}")
            bus = _fresh_bus()
    tally.wall_s = budget.elapsed_s()
    return [tally]
