"""``Bus.transact`` (hil/servobus/line.py) is ``master_write`` then ``master_read``: twin
rigs, one reading through ``transact`` and one through the two general calls, see the same
replies, clock, serial bytes (with their times, in order), world advances, counters and
servo state on the same traffic. The traffic takes ``transact``'s own path (a READ to one
servo whose whole reply arrives in time) and every way out of it: a reply longer than the
master asks for, a time-out inside the reply or before it, a missing ID, a refused read,
Status Return Level 0, the margin's return delay override, bytes left on the line, and
lines it leaves to the general calls (echo, a fault schedule, Protocol 2.0)."""
from __future__ import annotations

import random
from pathlib import Path

import pytest

from hexhil.hil import scenario as scenario_mod
from hexhil.hil.run import rig as rig_mod
from hexhil.hil.run.rig import make_world
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl
from tests.test_servo_core import _state

ROOT = Path(__file__).resolve().parent.parent
FAULTS = {"bit_error_rate": 0.002}


_wrote = [False]   # master_write was called (the general path)


def _rig(scenario: str, overlay: dict | None) -> tuple[rig_mod.Rig, list]:
    """A scenario's rig on its world; what the line says (bytes, advances), in order."""
    sc = scenario_mod.load_scenario(ROOT / "scenarios" / scenario)
    if overlay:
        sc = sc.overlay(overlay)
    seen: list = []
    rig = rig_mod.build(sc, 2, world=make_world(sc, 2),
                        on_bytes=lambda t_us, direction, data: seen.append((t_us, direction, data)))
    advance = rig.bus.advance

    def advanced(t_us: int) -> None:
        seen.append((t_us, "advance"))
        advance(t_us)
    rig.bus.advance = advanced
    write = rig.bus.master_write

    def wrote(data: bytes) -> None:
        _wrote[0] = True
        write(data)
    rig.bus.master_write = wrote
    return rig, seen


def _read(bus, tx: bytes, nrx: int, timeout_us: int, general: bool) -> bytes:
    if general:
        bus.master_write(tx)
        return bus.master_read(nrx, timeout_us)
    return bus.transact(tx, nrx, timeout_us)


def _script(rng: random.Random, k: int) -> tuple[bytes, int, int]:
    """One READ, its nrx and time-out: mostly the cycle's Present reads, then the edges."""
    dev = rng.choice([1 + k % 18] * 6 + [40])          # 40: no servo has it
    a, n = rng.choice([(36, 2), (36, 6), (43, 1), (0, 50), (10, 0), (70, 4)])  # (70, 4): refused
    nrx = n + 6 + rng.choice([0, 0, 0, -3, 4])           # exact, short (bytes left), long
    timeout_us = rng.choice([3000, 3000, 600, 520, 200])  # in time, cut off, before the reply
    return dxl.read(dev, a, n), max(0, nrx), timeout_us


@pytest.mark.parametrize("scenario,overlay", [
    ("flat-tripod.toml", None), ("flat-tripod.toml", {"bus": {"echo": True}}),
    ("flat-tripod.toml", {"faults": FAULTS}), ("flat-tripod-xl430.toml", None)],
    ids=["plain", "echo", "bit-errors", "protocol-2"])
def test_transact_is_write_then_read(scenario, overlay):
    twins = [_rig(scenario, overlay) for _ in range(2)]
    rngs = [random.Random(7), random.Random(7)]
    protocol_1 = twins[0][0].bus.protocol == 1
    fast = 0
    for k in range(300):
        states = []
        for general, (rig, seen), rng in zip((False, True), twins, rngs):
            bus = rig.bus
            if k == 150:
                bus.return_delay_override_us = 100
            if protocol_1 and k % 60 == 30:   # Status Return Level 0: no reply to a READ
                bus.master_write(dxl.write(1 + k % 18, ax12.STATUS_RETURN_LEVEL, bytes([0])))
            if protocol_1:
                tx, nrx, timeout_us = _script(rng, k)
            else:
                tx, nrx, timeout_us = _x_read(1 + k % 18), 15, rng.choice([3000, 200])
            packets = bus.stats["packets"]
            rx = _read(bus, tx, nrx, timeout_us, general)
            if not general and bus.stats["packets"] > packets and not _wrote[0]:
                fast += 1   # a READ taken without master_write
            _wrote[0] = False
            bus.idle_until(bus.clock.t_us + rng.choice([0, 0, 150, 2500]))
            states.append((rx, bus.clock.t_us, len(seen), dict(bus.stats),
                           sorted(bus.missing_ids), _state(rig)))
        assert states[0] == states[1], k
    assert twins[0][1] == twins[1][1]
    plain = overlay is None and protocol_1
    assert (fast > 100) if plain else (fast == 0), fast


def _x_read(dev: int) -> bytes:
    """A Protocol 2.0 READ of Present Position (address 132, 4 bytes)."""
    from hexhil.protocol.dynamixel import v2 as dx2
    return dx2.read(dev, 132, 4)
