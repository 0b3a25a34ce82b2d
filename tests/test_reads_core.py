"""Link version 2's R (hil/servobus/reads_core.c ``hx_reads``): its retry and skip rules
and its reply, and the attempts it carries out itself on a plain line, which are the
line's own (``Bus.master_write`` then ``master_read``): runs of the shipped firmware with
them and with every attempt left to the line give the same R replies, byte for byte, the
same serial bytes and times (the digest), the same bus accounting and the same servo
state; so do scripted R payloads (retries, skips, refused ranges, a servo gone quiet) and
scripted X and lone W traffic, on plain, echoing, faulty and Protocol 2.0 lines. Each
hand-back to the line
is taken: a READ to an ID no servo has (before the attempt), replies the master does not
read whole (the margin's late Return Delay: cut off by the time-out, read by
``Bus.hear_reply``; their bytes left on the line make it no longer plain), a line that is
not plain (a fault schedule), a W with a bad checksum."""
from __future__ import annotations

import collections
import dataclasses
import random
import re
import struct
import types

import pytest

from hexhil.hil import scenario as scenario_mod
from hexhil.hil.link.server import LinkServer, SwitchSampler
from hexhil.hil.run.lockstep import Simulator
from hexhil.hil.run.rig import make_world
from hexhil.hil.run_result import RunTally
from hexhil.hil.servobus import status_reads
from hexhil.hil.servobus.status_reads import MalformedReads, StatusReads
from hexhil.in_process import run_firmware
from hexhil.protocol import sim_link
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl
from hexhil.protocol.dynamixel import v2 as dx2
from tests.test_servo_core import _state
from conftest import ROOT

CASES = {  # overlay, return delay override (us), the hand-backs the run must show
    "plain": (None, None, {"DONE"}),
    "missing-servo": ({"bus": {"servos": 17}}, None, {"DONE", "ATTEMPT"}),
    "late-replies": (None, 800, {"DONE", "HEAR", "ATTEMPT", "WRITE"}),  # bytes left: not plain
    "faults": ({"faults": {"bit_error_rate": 0.001}}, None, {"DONE", "ATTEMPT", "WRITE"})}
BIND, READS = StatusReads._bind, LinkServer._reads
HX_READS = status_reads._HX_READS


def _line_only(self) -> None:
    """Every attempt and W left to the line's own model."""
    BIND(self)
    self._s.fast = 0


def _counting(seen: collections.Counter):
    """The hand-backs of Rs (not an X's, nor a lone W's)."""
    def counted(ref):
        s = status_reads._Reads.from_address(ref)
        an_r = not s.one and s.len > 1
        code = HX_READS(ref)
        seen[status_reads.READS_ANSWERS[code]] += an_r
        return code
    return counted


def _run(case: str, compiled: bool, monkeypatch) -> tuple:
    overlay, delay, _ = CASES[case]
    sc = scenario_mod.load_scenario(ROOT / "scenarios" / "flat-tripod.toml")
    if overlay:
        sc = sc.overlay(overlay)
    sim = Simulator(sc, 4, world=make_world(sc, 4))
    sim.bus.return_delay_override_us = delay
    replies, outcomes = [], collections.Counter()

    def traced_reads(self, payload, result, write=None):
        replies.append(READS(self, payload, result, write))
        return replies[-1]
    monkeypatch.setattr(StatusReads, "_bind", BIND if compiled else _line_only)
    monkeypatch.setattr(status_reads, "_HX_READS", _counting(outcomes))
    monkeypatch.setattr(LinkServer, "_reads", traced_reads)
    try:
        r = sim.run(2.0, in_process=run_firmware)
    finally:
        sim.core.shutdown()
    firmware = dataclasses.replace(r.firmware, compute_us_mean=0, compute_us_max=0)  # wall time
    return (replies, r.serial_digest, r.cycles, r.bus_busy_us, r.bus_wire_us, r.round_trips,
            firmware, dict(sim.bus.stats), _state(sim)), outcomes


@pytest.mark.parametrize("case", list(CASES))
def test_a_run_is_the_same_with_every_attempt_left_to_the_line(case, monkeypatch):
    compiled, outcomes = _run(case, True, monkeypatch)
    general, _ = _run(case, False, monkeypatch)
    assert len(compiled[0]) > 50
    assert compiled == general
    assert {k for k, n in outcomes.items() if n} - {"ADVANCE"} == CASES[case][2], outcomes


def _read(dev: int, address: int, n: int, retries: int = 0, skip: int = sim_link.NO_SKIP,
          timeout_us: int = 3000, nparams: int | None = None, nrx: int | None = None) -> bytes:
    tx = dxl.read(dev, address, n)
    return struct.pack("<BBBBBHIB", dev, n if nparams is None else nparams, retries, 0, skip,
                       6 + n if nrx is None else nrx, timeout_us, len(tx)) + tx


def _attempts(reply: bytes) -> list[tuple[int, bytes]]:
    out, at = [], 1
    for _ in range(reply[0]):
        t_us, got = struct.unpack_from("<QH", reply, at)
        out.append((t_us, reply[at + 10:at + 10 + got]))
        at += 10 + got
    assert at == len(reply)
    return out


def _server(seed: int = 5, scenario: str = "flat-tripod.toml", overlay: dict | None = None
            ) -> tuple[Simulator, LinkServer, RunTally]:
    sc = scenario_mod.load_scenario(ROOT / "scenarios" / scenario)
    if overlay:
        sc = sc.overlay(overlay)
    sim = Simulator(sc, seed, world=make_world(sc, seed))
    server = LinkServer(sim.driver, {}, SwitchSampler(lambda t_us: 0, None),
                        lambda t_us: None, lambda: None)
    server._counting = True
    return sim, server, RunTally("test")


@pytest.mark.parametrize("compiled", [True, False])
def test_a_read_is_retried_while_it_fails_and_one_that_names_it_is_skipped(compiled,
                                                                          monkeypatch):
    """At 1 Mbps: a READ to ID 40 (no servo) tried three times, each its 80 us out and the
    600 us time-out, nothing heard; the read that skips on it is skipped; servo 1's
    Present Position (Return Delay 250: 500 us) is 80 + 500 + 80 us, and the one after it,
    named by a skip on it, is read too; a master expecting 3 parameters where 2 come tries
    again, and gives up after its one retry."""
    monkeypatch.setattr(StatusReads, "_bind", BIND if compiled else _line_only)
    sim, server, tally = _server()
    try:
        bus = sim.bus
        bus.master_write(dxl.sync_write(ax12.RETURN_DELAY_TIME, 1, [(1, bytes([250]))]))
        bus.idle_until(bus.clock.t_us + 20_000)   # the EEPROM write done
        t0 = bus.clock.t_us
        reads = [_read(40, 36, 2, retries=2, timeout_us=600), _read(2, 36, 2, skip=0),
                 _read(1, 36, 2), _read(3, 36, 2, skip=2),
                 _read(4, 36, 2, retries=1, nparams=3, nrx=9)]
        reply = server._reads(bytes([len(reads)]) + b"".join(reads), tally)
        attempts = _attempts(reply)
        assert [t - t0 for t, _ in attempts[:3]] == [680, 1360, 2040]
        assert [rx for _, rx in attempts[:3]] == [b""] * 3
        t_servo1, rx = attempts[3]
        assert t_servo1 - t0 == 2040 + 80 + 500 + 80 and rx[:5] == bytes([255, 255, 1, 4, 0])
        assert len(attempts) == 3 + 1 + 1 + 2   # read 1 skipped; read 4 tried twice
        assert [len(rx) for _, rx in attempts[5:]] == [8, 8]   # 9 asked, time-out: 8 heard
        assert tally.bus_busy_us == bus.clock.t_us - t0
        assert tally.bus_wire_us == 8 * 7 * 10 + 8 * 10 * 4   # out, and four replies heard
    finally:
        sim.core.shutdown()


@pytest.mark.parametrize("payload, said", [
    (b"", "malformed reads (0 bytes, 1 announced)"),
    (bytes([1, 1]), "malformed reads (2 bytes, 13 announced)"),
    (bytes([1]) + _read(1, 36, 2)[:-1], "malformed reads (20 bytes, 21 announced)"),
    (bytes([2]) + _read(1, 36, 2) + _read(2, 36, 2, skip=1),
     "read 1 skips on read 1, not an earlier one"),
    (bytes([1]) + _read(1, 0, 50, retries=40, nrx=56),
     "the reads' replies could be longer than a reply holds (2048)")])
def test_a_malformed_r_is_refused_after_its_w(payload, said):
    sim, server, tally = _server()
    try:
        w = dxl.sync_write(ax12.GOAL_POSITION, 2, [(1, (600).to_bytes(2, "little"))])
        with pytest.raises(MalformedReads, match="^" + re.escape(said) + "$"):
            server.reads.carry_out(payload, server.byte_us, w)
        assert sim.bus.servo(1).table[ax12.GOAL_POSITION] == 600 & 0xFF
    finally:
        sim.core.shutdown()


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
        nparams = n + rng.choice([0] * 6 + [-1, 1])   # the master expecting another length
        reads.append(_read(dev, a, n, retries, skip, timeout_us, max(0, nparams), nrx))
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
    """R payloads straight to the link server, with the C code's attempts and with every
    attempt left to the line, most after a W (a SYNC_WRITE in the same batch): the same
    replies, clock, counters, accounting and servo state after each. Between them a servo
    sometimes stops answering READs (Status Return Level 0). The C code carries whole Ws
    and Rs with retries and skips in them, and hands back every way."""
    twins = []
    for compiled in (True, False):
        sim, server, tally = _server()
        if not compiled:
            server.reads._bind = types.MethodType(_line_only, server.reads)
        twins.append((sim, server, tally, random.Random(9)))
    ours = twins[0][1].reads._ref
    seen: collections.Counter = collections.Counter()

    def codes(ref):
        s = status_reads._Reads.from_address(ref)
        a_w = s.at == 0 and s.write_len > 0
        code = HX_READS(ref)
        if ref != ours:
            return code
        seen[status_reads.READS_ANSWERS[code]] += 1
        seen["W in C"] += a_w and code not in (status_reads.WRITE, status_reads.MALFORMED)
        if code == status_reads.WRITE_LEFT:   # a servo left to its handle, or an ID changed
            seen["W: a servo left to Python" if s.i < 18 else "W: an ID changed"] += 1
        return code
    monkeypatch.setattr(status_reads, "_HX_READS", codes)
    try:
        for k in range(250):
            states = []
            for sim, server, tally, rng in twins:
                bus = sim.bus
                if k % 40 == 20:
                    bus.master_write(dxl.write(1 + k % 18, ax12.STATUS_RETURN_LEVEL,
                                               bytes([0 if k % 80 == 20 else 2])))
                payload = _payload(rng)
                reply = server._reads(payload, tally, _write(k))
                if server is twins[0][1]:   # attempts against reads: retries and skips
                    seen["retried"] += reply[0] > payload[0]
                    seen["skipped"] += reply[0] < payload[0]
                bus.idle_until(bus.clock.t_us + rng.choice([0, 2500, 10_000]))
                if k % 2:
                    bus.master_discard()   # a cut-off reply's bytes dropped: plain again
                states.append((reply, bus.clock.t_us, dict(bus.stats), tally.bus_busy_us,
                               tally.bus_wire_us, _state(sim)))
            assert states[0] == states[1], k
    finally:
        for sim, *_ in twins:
            sim.core.shutdown()
    for outcome in ("DONE", "ADVANCE", "ATTEMPT", "HEAR", "WRITE", "retried", "skipped",
                    "W in C"):
        assert seen[outcome] >= 5, seen
    assert seen["W: a servo left to Python"] >= 1 and seen["W: an ID changed"] >= 2, seen


def _x(rng: random.Random, k: int, protocol_1: bool) -> tuple[bytes, int, int]:
    """One X: a READ, its nrx and time-out; mostly the cycle's Present reads, then the edges."""
    if not protocol_1:   # Present Position (address 132, 4 bytes)
        return dx2.read(1 + k % 18, 132, 4), 15, rng.choice([3000, 200])
    dev = rng.choice([1 + k % 18] * 6 + [40])          # 40: no servo has it
    a, n = rng.choice([(36, 2), (36, 6), (43, 1), (0, 50), (10, 0), (70, 4)])  # (70, 4): refused
    nrx = n + 6 + rng.choice([0, 0, 0, -3, 4])           # exact, short (bytes left), long
    timeout_us = rng.choice([3000, 3000, 600, 520, 200])  # in time, cut off, before the reply
    return dxl.read(dev, a, n), max(0, nrx), timeout_us


@pytest.mark.parametrize("scenario,overlay", [
    ("flat-tripod.toml", None), ("flat-tripod.toml", {"bus": {"echo": True}}),
    ("flat-tripod.toml", {"faults": {"bit_error_rate": 0.002}}),
    ("flat-tripod-xl430.toml", None)], ids=["plain", "echo", "bit-errors", "protocol-2"])
def test_an_x_and_a_lone_w_are_the_lines_own(scenario, overlay, monkeypatch):
    """X messages (and now and then a SYNC_WRITE with no R after it) straight to the link
    server, with the C code's attempts and with every one left to the line: the same
    replies, clock, serial bytes (with their times, in order), counters, accounting and
    servo state. On a plain line most READs go out from the C code (a reply the master
    does not read whole is then read by the line); on any other, none."""
    twins = []
    for compiled in (True, False):
        sim, server, tally = _server(2, scenario, overlay)
        if not compiled:
            server.reads._bind = types.MethodType(_line_only, server.reads)
        seen: list = []
        sim.bus.on_bytes = lambda t_us, d, data, seen=seen: seen.append((t_us, d, bytes(data)))
        twins.append((sim, server, tally, random.Random(7), seen))
    ours, codes = twins[0][1].reads._ref, []

    def traced(ref):
        code = HX_READS(ref)
        if ref == ours:
            codes.append(code)
        return code
    monkeypatch.setattr(status_reads, "_HX_READS", traced)
    protocol_1 = twins[0][0].bus.protocol == 1
    alone = 0
    try:
        for k in range(300):
            states = []
            for sim, server, tally, rng, seen in twins:
                bus = sim.bus
                if k == 150:
                    bus.return_delay_override_us = 100
                if protocol_1 and k % 60 == 30:   # Status Return Level 0: no reply to a READ
                    bus.master_write(dxl.write(1 + k % 18, ax12.STATUS_RETURN_LEVEL, bytes([0])))
                if protocol_1 and k % 7 == 3:
                    goal = (512 + 8 * (k % 9)).to_bytes(2, "little")
                    server._write(dxl.sync_write(ax12.GOAL_POSITION, 2,
                                                 [(i, goal) for i in range(1, 19)]), tally)
                del codes[:]
                rx = server._transact(*_x(rng, k, protocol_1), tally)
                alone += server is twins[0][1] and status_reads.ATTEMPT not in codes
                bus.idle_until(bus.clock.t_us + rng.choice([0, 0, 150, 2500]))
                states.append((rx, bus.clock.t_us, len(seen), dict(bus.stats),
                               sorted(bus.missing_ids), tally.bus_busy_us, tally.bus_wire_us,
                               _state(sim)))
            assert states[0] == states[1], k
    finally:
        for sim, *_ in twins:
            sim.core.shutdown()
    assert twins[0][4] == twins[1][4]
    plain = overlay is None and protocol_1
    assert (alone > 100) if plain else (alone == 0), alone
