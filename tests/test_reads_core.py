"""The compiled status reads (hil/servobus/reads_core.c ``hx_reads``) answer link version
2's R as the general path does (hil/link/server.py ``_attempts``): runs of the shipped
firmware with and without it give the same R replies, byte for byte, the same serial bytes
and times (the digest), the same bus accounting and the same servo state; so do scripted R
payloads (retries, skips, refused ranges, a servo gone quiet). Each way the C code hands back to the general path is taken: a READ to an ID no servo has (before the
attempt) and replies the master does not read whole (the margin's late Return Delay: cut
off by the time-out, read by ``Bus.hear_reply``; their bytes left on the line make it no
longer plain). A line that is not plain (a fault schedule) never reaches it. Built by
`make`; these tests fail if it is missing."""
from __future__ import annotations

import collections
import dataclasses
import random
import struct
from pathlib import Path

import pytest

from hexhil.hil import scenario as scenario_mod
from hexhil.hil.link.server import LinkServer, SwitchSampler
from hexhil.hil.run.lockstep import Simulator
from hexhil.hil.run.rig import make_world
from hexhil.hil.run_result import RunTally
from hexhil.hil.servobus import reads_core
from hexhil.in_process import run_firmware
from hexhil.protocol import sim_link
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl
from tests.test_servo_core import _state

ROOT = Path(__file__).resolve().parent.parent
CASES = {  # overlay, return delay override (us), the C code's outcomes the run must show
    "plain": (None, None, {"done"}),
    "missing-servo": ({"bus": {"servos": 17}}, None, {"done", reads_core.PYTHON}),
    "late-replies": (None, 800, {reads_core.PYTHON_REPLY, "general"}),  # bytes left: not plain
    "faults": ({"faults": {"bit_error_rate": 0.001}}, None, {"general"})}
CARRY_OUT, READS = reads_core.ReadsCore.carry_out, LinkServer._reads


def _run(case: str, compiled: bool, monkeypatch) -> tuple:
    overlay, delay, _ = CASES[case]
    sc = scenario_mod.load_scenario(ROOT / "scenarios" / "flat-tripod.toml")
    if overlay:
        sc = sc.overlay(overlay)
    sim = Simulator(sc, 4, world=make_world(sc, 4))
    sim.bus.return_delay_override_us = delay
    replies, outcomes = [], collections.Counter()

    def traced_carry_out(self, bus, payload, write=None):
        out = CARRY_OUT(self, bus, payload, write) if compiled else None
        outcomes["general" if out is None else
                 "done" if out.handover is None else out.handover.code] += 1
        return out

    def traced_reads(self, payload, result, write=None):
        replies.append(READS(self, payload, result, write))
        return replies[-1]
    monkeypatch.setattr(reads_core.ReadsCore, "carry_out", traced_carry_out)
    monkeypatch.setattr(LinkServer, "_reads", traced_reads)
    try:
        r = sim.run(2.0, in_process=run_firmware)
    finally:
        sim.core.shutdown()
    firmware = dataclasses.replace(r.firmware, compute_us_mean=0, compute_us_max=0)  # wall time
    return (replies, r.serial_digest, r.cycles, r.bus_busy_us, r.bus_wire_us, r.round_trips,
            firmware, dict(sim.bus.stats), _state(sim)), outcomes


def test_the_library_has_the_reads():
    assert reads_core.ReadsCore.available(), "hil/servobus/_servo_core.so missing: run make"


@pytest.mark.parametrize("case", list(CASES))
def test_a_run_is_the_same_with_and_without_the_compiled_reads(case, monkeypatch):
    compiled, outcomes = _run(case, True, monkeypatch)
    general, _ = _run(case, False, monkeypatch)
    assert len(compiled[0]) > 50
    assert compiled == general
    assert set(outcomes) == CASES[case][2], outcomes


def _payload(rng: random.Random) -> bytes:
    """A scripted R: reads that succeed, fail (a refused range: an error status; an ID no
    servo has; a short time-out), retry and skip on one another."""
    reads = []
    room = sim_link.MAX_REPLY_LEN - 9
    for j in range(rng.randrange(1, 7)):
        dev = rng.choice(list(range(1, 19)) * 2 + [40] * 2)
        a, n = rng.choice([(36, 2), (36, 6), (30, 4), (70, 4), (0, 50)])
        nrx = 6 + n + rng.choice([0, 0, 0, -2])
        retries = rng.choice([0, 1, 2])
        room -= (1 + retries) * (sim_link.ATTEMPT_HEAD_LEN + nrx)
        if room < 0:
            break
        skip = rng.choice([sim_link.NO_SKIP] * 2 + list(range(j)))
        timeout_us = rng.choice([3000] * 8 + [600, 150])
        tx = dxl.read(dev, a, n)
        nparams = n + rng.choice([0] * 6 + [-1, 1])   # the master expecting another length
        reads.append(struct.pack("<BBBBBHIB", dev, max(0, nparams), retries, 0, skip, nrx,
                                 timeout_us, len(tx)) + tx)
    return bytes([len(reads)]) + b"".join(reads)


def _write(k: int) -> bytes | None:
    """The W sent with step ``k``'s R, or None: the legs moved (most), every ID written
    with its own value (the line re-indexes: the reads go to the general path), Return
    Delay written (EEPROM: the servos busy a while; the Status Return Level writes between
    the steps leave one busy for the next W, which leaves it to Python), and a W whose
    checksum is wrong (the line's parser takes it, in Python)."""
    goal = (512 + 40 * (k % 5)).to_bytes(2, "little")
    if k % 50 == 11:
        return dxl.sync_write(ax12.ID, 1, [(i, bytes([i])) for i in range(1, 19)])
    if k % 50 == 31:
        return dxl.sync_write(ax12.RETURN_DELAY_TIME, 1, [(i, bytes([250])) for i in range(1, 19)])
    if k % 50 == 21:
        w = bytearray(dxl.sync_write(ax12.GOAL_POSITION, 2, [(i, goal) for i in range(1, 19)]))
        w[-1] ^= 0xFF
        return bytes(w)
    if k % 3 == 1:
        return dxl.sync_write(ax12.GOAL_POSITION, 2, [(i, goal) for i in range(1, 19)])
    return None


def test_scripted_reads_are_answered_the_same(monkeypatch):
    """R payloads straight to the link server, with and without the C code, most after a
    W (a SYNC_WRITE in the same batch): the same replies, clock, counters, accounting and
    servo state after each. Between them a servo sometimes stops answering READs (Status
    Return Level 0). The C code carries whole Ws and Rs with retries and skips in them,
    and hands over every way."""
    twins = []
    for compiled in (True, False):
        sc = scenario_mod.load_scenario(ROOT / "scenarios" / "flat-tripod.toml")
        sim = Simulator(sc, 5, world=make_world(sc, 5))
        server = LinkServer(sim.driver, {}, SwitchSampler(lambda t_us: 0, None),
                            lambda t_us: None, lambda: None)
        server._counting = True
        twins.append((compiled, sim, server, RunTally("test"), random.Random(9)))
    seen: collections.Counter = collections.Counter()
    hx_reads = reads_core._HX_READS

    def counted(self, bus, payload, write=None):
        out = CARRY_OUT(self, bus, payload, write)
        if out is None:
            seen["general"] += 1
        elif out.handover is not None:
            seen[out.handover.code] += 1
        else:   # attempts against reads: retries (more) and skips (fewer) in C
            seen["done"] += 1
            seen["done, retried"] += out.body[0] > payload[0]
            seen["done, skipped"] += out.body[0] < payload[0]
        seen["with a W, compiled"] += out is not None and write is not None
        return out

    def codes(ref):
        code = hx_reads(ref)
        if code == reads_core.WRITE_LEFT:   # a servo left to its handle, or an ID changed
            left = reads_core._Reads.from_address(ref).i < 18
            seen["W: a servo left to Python" if left else "W: an ID changed"] += 1
        return code
    monkeypatch.setattr(reads_core, "_HX_READS", codes)
    try:
        for k in range(250):
            states = []
            for compiled, sim, server, tally, rng in twins:
                monkeypatch.setattr(reads_core.ReadsCore, "carry_out",
                                    counted if compiled else (lambda *a: None))
                bus = sim.bus
                if k % 40 == 20:
                    bus.master_write(dxl.write(1 + k % 18, ax12.STATUS_RETURN_LEVEL,
                                               bytes([0 if k % 80 == 20 else 2])))
                reply = server._reads(_payload(rng), tally, _write(k))
                bus.idle_until(bus.clock.t_us + rng.choice([0, 2500, 10_000]))
                if k % 2:
                    bus.master_discard()   # a cut-off reply's bytes dropped: plain again
                states.append((reply, bus.clock.t_us, dict(bus.stats), tally.bus_busy_us,
                               tally.bus_wire_us, _state(sim)))
            assert states[0] == states[1], k
    finally:
        for _, sim, *_ in twins:
            sim.core.shutdown()
    for outcome in ("done", "done, retried", "done, skipped", reads_core.PYTHON,
                    reads_core.PYTHON_REPLY, "general", "with a W, compiled"):
        assert seen[outcome] >= 5, seen
    assert seen["W: a servo left to Python"] >= 1 and seen["W: an ID changed"] >= 2, seen
