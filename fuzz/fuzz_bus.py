"""The emulated bus with 18 AX-12s (hil/servobus/line.py, hil/servobus/ax12_servo.py) under random instruction
streams. After each stream: no exception escaped, every register within its documented
range (protocol/dynamixel/ax12.py FIELDS), the read-only identity registers unchanged, and after
the line has idled past the inter-byte timeout a PING to a servo is answered (resync).
``run_streams`` and ``resync`` serve the Protocol 2.0 bus too (fuzz_v2_bus.py), through a
``BusSpec``; cov_targets.py drives both buses through the same specs."""
from __future__ import annotations

import random
from dataclasses import dataclass
from typing import Any, Callable

from fuzz.hostile import Rng, garbage
from fuzz.tally import Budget, Tally
from hexhil.hil.servobus.line import Bus
from hexhil.hil.clock import VirtualClock
from hexhil.hil.servobus.ax12_servo import Servo
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl

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
    return dxl.packet(dev_id, code, rare_id_writes(rng, params, ax12.ID, ax12.GOAL_POSITION))


def rare_id_writes(rng: random.Random, params: bytes, id_address: int, instead: int) -> bytes:
    """``params``, sometimes with the first ``id_address`` byte made ``instead``: the
    address-changing writes are kept rare."""
    if rng.random() < 0.3:
        params = params.replace(bytes((id_address,)), bytes((instead,)), 1)
    return params


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


@dataclass(frozen=True)
class BusSpec:
    """One protocol's emulated bus of 18 servos, as the bus fuzzers drive it."""

    title: str                                   # the tally's
    fresh_bus: Callable[[], Any]
    instruction: Callable[[random.Random], bytes]
    garbage: Callable[[Rng], bytes]
    check_servo: Callable[[Any], str]            # the first broken invariant, or ''
    pingable: Callable[[Any], Any]               # a servo a PING must reach, or None
    ping: Callable[[int], bytes]
    parser: Callable[[], Any]
    rebuild_every: int      # streams on one bus before a fresh one (ID/baud drift)
    read_bytes: int         # what the master reads after each instruction, at most
    reads_us: tuple[int, ...]   # how long it waits for them (one picked at random)
    settle_us: int          # the idle after a stream: past the inter-byte timeout
    drain_bytes: int        # then what is still on the line is read and dropped
    ping_reply_bytes: int
    read_timeout_us: int


def broken_servo(spec: BusSpec, bus: Any) -> str:
    """``servo ID: what`` for the first servo with a broken invariant, or ''."""
    for s in bus.servos:
        broken = spec.check_servo(s)
        if broken:
            return f"servo {s.id}: {broken}"
    return ""


def resync(spec: BusSpec, bus: Any) -> tuple[Any, bool]:
    """Idle past the inter-byte timeout, drop what is on the line and PING a servo: the
    servo (None when none can be reached) and whether it answered."""
    bus.idle_until(bus.clock.t_us + spec.settle_us)
    bus.master_read(spec.drain_bytes, 0)
    target = spec.pingable(bus)
    if target is None:
        return None, False
    bus.master_write(spec.ping(target.id))
    reply = spec.parser().feed(bus.master_read(spec.ping_reply_bytes, spec.read_timeout_us))
    return target, bool(reply) and reply[0].id == target.id


def run_streams(spec: BusSpec, seed: int, budget_s: float | None,
                limit: int | None) -> list[Tally]:
    """Random streams of instructions and garbage until the budget is spent."""
    rng = random.Random(seed)
    junk_rng = Rng(seed)
    tally = Tally(spec.title, "streams")
    budget = Budget(budget_s, limit)
    bus = spec.fresh_bus()
    while budget.more(tally.inputs):
        tally.inputs += 1
        if tally.inputs % spec.rebuild_every == 0 or spec.pingable(bus) is None:
            bus = spec.fresh_bus()
        try:
            for _ in range(rng.randrange(1, 6)):
                data = spec.instruction(rng) if rng.random() < 0.7 else \
                    bytes(spec.garbage(junk_rng))
                bus.master_write(data)
                bus.master_read(spec.read_bytes, rng.choice(spec.reads_us))
            broken = broken_servo(spec, bus)
            if broken:
                tally.escape(f"stream {tally.inputs}: {broken}")
                bus = spec.fresh_bus()
            target, answered = resync(spec, bus)
            if target is None:
                continue
            tally.resync_checked += 1
            if answered:
                tally.resync_found += 1
            elif len(tally.notes) < 5:
                tally.notes[f"no PING reply at stream {tally.inputs}"] = target.id
        except Exception as exc:  # an escape is what the fuzzer is for: count and report it
            tally.escape(f"stream {tally.inputs}: {exc.__class__.__name__}: {exc}")
            bus = spec.fresh_bus()
    tally.wall_s = budget.elapsed_s()
    return [tally]


AX12 = BusSpec("emulated bus, 18 servos", _fresh_bus, _instruction, garbage, check_servo,
               _pingable, dxl.ping, dxl.Parser, REBUILD_EVERY, 300, (0, 200, READ_TIMEOUT_US),
               dxl.INTER_BYTE_TIMEOUT_US + 1, 10_000, 6, READ_TIMEOUT_US)


def run(seed: int, budget_s: float | None, limit: int | None) -> list[Tally]:
    return run_streams(AX12, seed, budget_s, limit)
