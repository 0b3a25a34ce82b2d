"""Where a run's 20 ms cycle goes: ``breakdown`` times each part of it with
stopwatches on about 22 calls a cycle, ``light_cycle`` the same run with one stopwatch, on
the world step, for the overhead share a user's run has (bench_stack.py prints both).
"""
from __future__ import annotations

import os
import resource
import tempfile
import time
from pathlib import Path
from typing import Any, Callable
from unittest import mock

from bench.bench_world import ROOT
from hexhil.hil import scenario as scenario_mod
from hexhil.hil.link.firmware_child import FirmwareProcess
from hexhil.hil.link.firmware_process import Connection, DirectConnection
from hexhil.hil.link.server import LinkServer
from hexhil.hil.run.lockstep import Simulator
from hexhil.hil.run.rig import make_world
from hexhil.hil.servobus.status_reads import StatusReads
from hexhil.in_process import run_firmware
from hexhil.protocol import sim_link

SCENARIO = ROOT / "scenarios" / "obstacles-low-small.toml"   # the command, seed 3
BREAKDOWN_S = 10.0
OVERHEAD = "overhead share"   # of a cycle: all but the world step and the firmware's compute
TO_READS = "waiting for the reads after the wake"   # the firmware's part no host work overlaps
ONCE = "once a run: the firmware's start and end"   # ms, not a cycle's part
BOOT, LAST = "first message", "last reply"   # when they came and went


class _Stopwatch:
    """Seconds spent inside wrapped callables, by label, on ``clock`` (wall time, or this
    thread's CPU time). A call inside another of its own label counts once (``transact``
    falling back to ``master_write``); one of another label is not subtracted, and is also
    counted as "LABEL inside OUTER" (the world stepped from inside the bus, or from the
    lookahead)."""

    def __init__(self, clock: Callable[[], float] = time.perf_counter) -> None:
        self.s: dict[str, float] = {}
        self.clock = clock
        self._inside: set[str] = set()

    def wrap(self, label: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        clock, inside = self.clock, self._inside

        def timed(*args: Any, **kw: Any) -> Any:
            if label in inside:
                return fn(*args, **kw)
            outers = tuple(inside)
            inside.add(label)
            t0 = clock()
            try:
                return fn(*args, **kw)
            finally:
                inside.discard(label)
                dt = clock() - t0
                self.s[label] = self.s.get(label, 0.0) + dt
                for outer in outers:
                    key = f"{label} inside {outer}"
                    self.s[key] = self.s.get(key, 0.0) + dt
        return timed


def _after_sleeps(sw: _Stopwatch, batch: Callable[..., Any], reply: Callable[..., Any]
                  ) -> tuple[Callable[..., Any], Callable[..., Any]]:
    """``Connection.batch`` and ``reply``, timing into ``TO_READS`` each sleep's reply to
    the batch after it (the recorder's work between overlaps it): the firmware's compute up
    to its status reads, and its wake-up and the host's. Also what ``_once`` takes out: the
    wait for the first message and for the firmware's exit, and when the last reply went."""
    request = [0]   # the op the next reply answers
    sent = [0.0]    # when the last sleep's reply went, or 0.0

    def timed_batch(conn: Connection) -> tuple[list[tuple[int, bytes]], bool]:
        t0 = sw.clock()
        msgs, closed = batch(conn)
        if BOOT not in sw.s:
            sw.s[BOOT] = sw.s["wait once"] = sw.clock()
            sw.s["wait once"] -= t0
        if closed:
            sw.s["wait once"] += sw.clock() - t0
        elif sent[0]:
            sw.s[TO_READS] = sw.s.get(TO_READS, 0.0) + sw.clock() - sent[0]
        request[0] = msgs[-1][0] if msgs else 0
        return msgs, closed

    def timed_reply(conn: Connection, *args: Any) -> bytes:
        raw = reply(conn, *args)
        sw.s[LAST] = sent[0] = sw.clock()
        if request[0] != sim_link.OP_SLEEP:
            sent[0] = 0.0
        return raw
    return timed_batch, timed_reply


def _first_and_last(sw: _Stopwatch, exchange: Callable[..., Any]) -> Callable[..., Any]:
    """``DirectConnection.exchange``, noting when the firmware in this process first calls
    it and when the last call returns."""
    def exchange_noted(*args: Any) -> Any:
        sw.s.setdefault(BOOT, sw.clock())
        try:
            return exchange(*args)
        finally:
            sw.s[LAST] = sw.clock()
    return exchange_noted


def _once(s: dict[str, float], t0: float, t1: float) -> float:
    """Seconds of a run that are not its cycles' (the firmware's start up to its first
    message, and after the last reply: its exit, the processes' end): once a run, however
    long, so they are given apart instead of spread over a breakdown's few cycles (35 ms
    of a micropython start read as 70 us a cycle of a 10 s run)."""
    return s.pop(BOOT) - t0 + t1 - s.pop(LAST)


def _children_cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def breakdown(record: bool = True, in_process: bool = False, cpu: bool = False
              ) -> dict[str, float]:
    """Microseconds of the host's wall time per control cycle: waiting on the firmware (its
    compute and the link's latency, where the host has nothing else to do; with a child
    process this includes sending the reply, where the woken firmware often takes the
    host's core before the send returns), bus + servo
    emulation, world step, recorder, and the rest (the link server's own Python). The
    firmware's compute (its own counter) is given beside them: it runs while the host waits
    or records, so it is not one of the parts.

    ``in_process``: the firmware runs in this process, so "waiting" is its compute itself
    (the wall time outside the link's exchange), with no link latency.

    ``cpu``: every part in this thread's CPU time instead of wall time, and the child
    processes' CPU time (getrusage: the firmware's under micropython, the recorder's
    encoding child's in process) beside them and in the total: figures a shared, loaded
    machine does not inflate (waiting is then the host's own CPU in the link's calls), with
    the link's polling off (hil/link/firmware_process.py ``spin_us``): a poll is CPU time
    that does no work."""
    sc = scenario_mod.load_scenario(SCENARIO)
    clock = time.thread_time if cpu else time.perf_counter
    sw = _Stopwatch(clock)
    world = make_world(sc, 3)
    world.advance_to = sw.wrap("world", world.advance_to)
    rec = None
    with tempfile.TemporaryDirectory() as tmp:
        if record:
            from hexhil.trace.recorder import open_recorder
            from hexhil.trace.windows import encode_in_for
            rec = open_recorder(Path(tmp) / "b.mcap", {}, encode_in=encode_in_for(not in_process))
            for name in ("serial", "serial_stream"):   # called from inside the bus
                setattr(rec, name, sw.wrap("recorder in bus", getattr(rec, name)))
            for name in ("can", "switch_edge", "telemetry", "servo_state", "body_pose",
                         "joints", "fault", "link", "advance", "idle"):
                setattr(rec, name, sw.wrap("recorder", getattr(rec, name)))
        sim = Simulator(sc, 3, world=world, recorder=rec)
        for name in ("master_write", "master_read", "transact", "idle_until"):
            setattr(sim.bus, name, sw.wrap("bus", getattr(sim.bus, name)))
        carry_out = StatusReads.carry_out   # the cycle's status reads
        StatusReads.carry_out = sw.wrap("bus", carry_out)
        batch, reply, exchange = Connection.batch, Connection.reply, DirectConnection.exchange
        timed_batch, timed_reply = _after_sleeps(sw, batch, reply)
        Connection.batch = sw.wrap("wait", timed_batch)
        Connection.reply = sw.wrap("wait", timed_reply)
        DirectConnection.exchange = _first_and_last(sw, sw.wrap("host", exchange))
        no_poll = {sim_link.ENV_SPIN_US: "0"} if cpu else {}   # a poll: CPU time, no work
        try:
            child0 = _children_cpu_s()
            t0 = clock()
            with mock.patch.dict(os.environ, no_poll):
                r = sim.run(BREAKDOWN_S, in_process=run_firmware if in_process else None)
            total = clock() - t0
        finally:
            Connection.batch, Connection.reply = batch, reply
            StatusReads.carry_out = carry_out
            DirectConnection.exchange = exchange
            if rec is not None:
                rec.close()   # waits for the recorder's child, if it has one
        child = _children_cpu_s() - child0
    s = sw.s
    once = _once(s, t0, t0 + total)
    total -= once
    if in_process:
        s["wait"] = total - s["host"]
    else:
        s["wait"] -= s.pop("wait once")
    in_bus = s.get("recorder in bus", 0.0)
    wait = "firmware compute, in this process" if in_process else "waiting on the firmware"
    parts = {wait: s.get("wait", 0.0),
             "bus + servo emulation": (s.get("bus", 0.0) - s.get("world inside bus", 0.0)
                                       - in_bus),
             "world step": s.get("world", 0.0), "recorder": s.get("recorder", 0.0) + in_bus}
    parts["link server and the rest"] = total - sum(parts.values())
    parts["total"] = total
    cycles = max(1, r.cycles)
    out = {k: v / cycles * 1e6 for k, v in parts.items()}
    compute = out[wait] if in_process else r.firmware.compute_us_mean or 0.0
    out[ONCE] = once * 1e3
    if not in_process:
        out["firmware compute (overlaps)"] = compute
        out[TO_READS] = s.get(TO_READS, 0.0) / cycles * 1e6
    if cpu:   # a cycle's CPU: the host's, the firmware process's, the recorder's child's
        child_us = child / cycles * 1e6
        if in_process:
            out["recorder process CPU"] = child_us
        else:
            out["firmware process CPU"] = child_us
            compute = min(compute, child_us)
        out["total"] += child_us
    out[OVERHEAD] = 100.0 * (out["total"] - out["world step"] - compute) / out["total"]
    return out


def light_cycle(in_process: bool = False, record: bool = True) -> dict[str, float]:
    """``breakdown``'s run, recording unless told not to, with one stopwatch only, on the
    world step (and, in process, the link's exchange, outside which the firmware computes):
    the cycle's total, world step and firmware compute in us, and the overhead share of
    them. The breakdown wraps about 22 calls a cycle, which made its run 12-17 us a cycle
    slower than this one; a user's run has none, so the goal rows take their
    share from here. The total runs from the firmware's hello to its last reply (to where
    the host turns to the firmware's exit)."""
    from hexhil.trace.recorder import open_recorder
    from hexhil.trace.windows import encode_in_for

    sc = scenario_mod.load_scenario(SCENARIO)
    sw = _Stopwatch()
    world = make_world(sc, 3)
    world.advance_to = sw.wrap("world", world.advance_to)

    def noting(key: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def noted(*args: Any) -> Any:
            sw.s.setdefault(key, time.perf_counter())
            return fn(*args)
        return noted

    with tempfile.TemporaryDirectory() as tmp:
        rec = open_recorder(Path(tmp) / "b.mcap" if record else None, {},
                            encode_in=encode_in_for(not in_process))
        sim = Simulator(sc, 3, world=world, recorder=rec)
        exchange = _first_and_last(sw, sw.wrap("host", DirectConnection.exchange))
        with mock.patch.object(LinkServer, "_hello_reply",
                               noting(BOOT, LinkServer._hello_reply)), \
                mock.patch.object(FirmwareProcess, "finish",
                                  noting(LAST, FirmwareProcess.finish)), \
                mock.patch.object(DirectConnection, "exchange", exchange):
            r = sim.run(BREAKDOWN_S, in_process=run_firmware if in_process else None)
        if rec is not None:
            rec.close()
    cycles = max(1, r.cycles)
    total_us = (sw.s[LAST] - sw.s[BOOT]) / cycles * 1e6
    world_us = sw.s["world"] / cycles * 1e6
    compute_us = (total_us - sw.s["host"] / cycles * 1e6 if in_process
                  else r.firmware.compute_us_mean or 0.0)
    return {"total": total_us, "world step": world_us, "firmware compute": compute_us,
            OVERHEAD: 100.0 * (total_us - world_us - compute_us) / total_us}
