"""The full stack as users run it (issues 18 and 33): ``hexhil run`` unpinned, median of 5,
beside the world alone measured in the same run, with and without recording; where a
cycle's wall time goes and how much of it is overhead (neither the world step nor the
firmware's compute); and how the cost grows with servos and obstacles.
"""
from __future__ import annotations

import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Callable
from unittest import mock

from bench import Row
from bench.bench_world import ROOT, bare_mj_step, world_alone
from hil import scenario as scenario_mod
from hil.servobus.line import Bus
from hil.servobus.reads_core import ReadsCore
from hil.clock import VirtualClock
from hil.link.firmware_process import IN_PROCESS, Connection, DirectConnection, FirmwareProcess
from hil.link.server import LinkServer
from hil.run.rig import make_world
from hil.servobus.ax12_servo import Servo
from hil.run.lockstep import Simulator
from host_tools import Run
from host_tools.in_process import run_firmware
from protocol import sim_link
from protocol.dynamixel import ax12
from protocol.dynamixel import v1 as dxl

SCENARIO = ROOT / "scenarios" / "obstacles-low-small.toml"   # the command, seed 3
RUNS = 5
BREAKDOWN_S = 10.0
GROWTH_S = 10.0
GROWTH_RUNS = 3
CEILING_RUNS = 3   # a slow minute moved one breakdown's ceiling by 0.3 (wave 12)
OVERHEAD = "overhead share"   # of a cycle: all but the world step and the firmware's compute
TO_READS = "waiting for the reads after the wake"   # the firmware's part no host work overlaps
ONCE = "once a run: the firmware's start and end"   # ms, not a cycle's part
BOOT, LAST = "first message", "last reply"   # when they came and went


def _hexhil_rtf(*extra: str) -> float:
    """``hexhil run SCENARIO --seed 3 --json`` as a user runs it; its real-time factor."""
    out = subprocess.run([sys.executable, "-m", "host_tools.cli", "run", str(SCENARIO), "--seed",
                          "3", "--json", *extra], cwd=ROOT, capture_output=True, text=True,
                         check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])["real_time_factor"]


def _median_rtf(record: bool, *extra: str) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        out = ("--out", str(Path(tmp) / "run.mcap"), "--overwrite") if record else ()
        return statistics.median(_hexhil_rtf(*out, *extra) for _ in range(RUNS))


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
    of a micropython start read as 70 us a cycle of a 10 s run, wave 13)."""
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
            from host_tools.trace.recorder import open_recorder
            from host_tools.trace.windows import encode_in_for
            rec = open_recorder(Path(tmp) / "b.mcap", {}, encode_in=encode_in_for(not in_process))
            for name in ("serial", "serial_stream"):   # called from inside the bus
                setattr(rec, name, sw.wrap("recorder in bus", getattr(rec, name)))
            for name in ("can", "switch_edge", "telemetry", "servo_state", "body_pose",
                         "joints", "fault", "link", "advance", "idle"):
                setattr(rec, name, sw.wrap("recorder", getattr(rec, name)))
        sim = Simulator(sc, 3, world=world, recorder=rec)
        for name in ("master_write", "master_read", "transact", "idle_until"):
            setattr(sim.bus, name, sw.wrap("bus", getattr(sim.bus, name)))
        carry_out = ReadsCore.carry_out   # the cycle's status reads, compiled
        ReadsCore.carry_out = sw.wrap("bus", carry_out)
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
            ReadsCore.carry_out = carry_out
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


def light_cycle(in_process: bool = False) -> dict[str, float]:
    """``breakdown``'s run, recording, with one stopwatch only, on the world step (and, in
    process, the link's exchange, outside which the firmware computes): the cycle's total,
    world step and firmware compute in us, and the overhead share of them. The breakdown
    wraps about 22 calls a cycle, which made its run 12-17 us a cycle slower than this one
    (wave 14); a user's run has none, so the goal row takes its share from here. The
    total runs from the firmware's hello to its last reply (to where the host turns to the
    firmware's exit)."""
    from host_tools.trace.recorder import open_recorder
    from host_tools.trace.windows import encode_in_for

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
        rec = open_recorder(Path(tmp) / "b.mcap", {}, encode_in=encode_in_for(not in_process))
        sim = Simulator(sc, 3, world=world, recorder=rec)
        exchange = _first_and_last(sw, sw.wrap("host", DirectConnection.exchange))
        with mock.patch.object(LinkServer, "_hello_reply",
                               noting(BOOT, LinkServer._hello_reply)), \
                mock.patch.object(FirmwareProcess, "finish",
                                  noting(LAST, FirmwareProcess.finish)), \
                mock.patch.object(DirectConnection, "exchange", exchange):
            r = sim.run(BREAKDOWN_S, in_process=run_firmware if in_process else None)
        rec.close()
    cycles = max(1, r.cycles)
    total_us = (sw.s[LAST] - sw.s[BOOT]) / cycles * 1e6
    world_us = sw.s["world"] / cycles * 1e6
    compute_us = (total_us - sw.s["host"] / cycles * 1e6 if in_process
                  else r.firmware.compute_us_mean or 0.0)
    return {"total": total_us, "world step": world_us, "firmware compute": compute_us,
            OVERHEAD: 100.0 * (total_us - world_us - compute_us) / total_us}


def _obstacle_field(n: int) -> list[dict[str, float]]:
    """``n`` small obstacles in a grid ahead of the robot, 15 cm apart."""
    cols = max(1, math.ceil(math.sqrt(n)))
    return [{"x_m": 0.25 + 0.15 * (k // cols), "y_m": -0.15 * (cols - 1) / 2 + 0.15 * (k % cols),
             "length_m": 0.03, "width_m": 0.06, "height_m": 0.03} for k in range(n)]


def _full_stack_with_obstacles(n: int) -> float:
    sc = scenario_mod.load_scenario(ROOT / "scenarios" / "flat-tripod.toml")
    if n:
        sc = sc.overlay({"world": {"terrain": "obstacles", "obstacles": _obstacle_field(n)}})
    r = Run(sc, seed=1, duration_s=GROWTH_S).run()
    return r.sim_time_s / r.wall_time_s


def _growth(counts: tuple[int, ...]) -> dict[int, float]:
    """The full stack's real-time factor by obstacle count, median of ``GROWTH_RUNS``, the
    counts alternating: run one after the other, a machine slowing down inside the bench
    read as growth (34.8 % at 40 obstacles in one run, 15 % alternated right after)."""
    got: dict[int, list[float]] = {n: [] for n in counts}
    for _ in range(GROWTH_RUNS):
        for n in counts:
            got[n].append(_full_stack_with_obstacles(n))
    return {n: statistics.median(v) for n, v in got.items()}


def _bus_and_servos(n: int) -> float:
    """Real-time factor of ``n`` emulated servos on the bus with a scripted master doing the
    firmware's per-cycle traffic (one SYNC_WRITE to all, three status reads) at 50 Hz; the
    firmware needs all 18 servos, so this is the host side alone."""
    clock = VirtualClock()
    bus = Bus([Servo(i + 1) for i in range(n)], clock)
    ids = list(range(1, n + 1))
    parser = dxl.Parser()
    t0 = time.perf_counter()
    cycles = int(GROWTH_S * 50)
    for k in range(cycles):
        goal = [(i, ax12.rad_to_position(0.1 * math.sin(k / 25 + i)).to_bytes(2, "little")
                 + b"\x00\x02") for i in ids]
        bus.master_write(dxl.sync_write(ax12.GOAL_POSITION, 4, goal))
        for j in range(3):
            bus.master_write(dxl.read(ids[(3 * k + j) % n], ax12.PRESENT_POSITION, 6))
            parser.feed(bus.master_read(12, 1000))
        bus.idle_until((k + 1) * 20_000)
    return GROWTH_S / (time.perf_counter() - t0)


def _ceiling_row(label: str, in_process: bool, alone_us: float, parts: dict[str, float]
                 ) -> Row:
    """The best ratio to the world alone that this firmware allows: a cycle can be no shorter
    than its world step and the firmware's compute up to its status reads, which depend on
    each other (the firmware computes from the switches at its wake-up, and the world
    steps from the SYNC_WRITE it sent with the reads). In process nothing overlaps: the
    whole compute counts. Under micropython the world steps on while the firmware finishes
    its cycle after the reads (hil/run/lookahead.py), so what counts is the wait for the
    reads after the wake, which also holds the two processes' wake-ups. A ratio goal above
    this row is out of reach for any host-side overhead, however small. Measured without
    recording, as the ratio rows are; ``parts`` are the medians of ``CEILING_RUNS``
    breakdowns."""
    firmware = parts["firmware compute, in this process" if in_process else TO_READS]
    what = "firmware compute" if in_process else "the wait for the reads"
    world = parts["world step"]
    return Row(f"stack ceiling ({label}): world alone / (world step + {what})",
               alone_us / (world + firmware), "ratio", ">= 0.9" if in_process else ">= 0.65",
               f"no host overhead: world alone {alone_us:.0f} us, world step in a run "
               f"without recording {world:.0f} us + {what} {firmware:.0f} us a cycle, "
               f"medians of {CEILING_RUNS}")


def _cpu_rows(alone_us: float, bare_us: float) -> list[Row]:
    """The cycle in CPU time (host thread + firmware process): what this shared machine's
    load does not inflate; the ratios are those of a machine where nothing else runs and
    the two processes never overlap."""
    rows = [Row("stack CPU: world alone / bare mj_step", bare_us / alone_us, "ratio", ">= 0.8",
                f"CPU a cycle: world alone {alone_us:.0f} us, bare mj_step {bare_us:.0f} us")]
    for label, ip in (("micropython", False), (IN_PROCESS, True)):
        parts = breakdown(in_process=ip, cpu=True)
        del parts[ONCE]   # given in wall time below
        for name, us in parts.items():
            if name == OVERHEAD:
                rows.append(Row(f"stack CPU ({label}): {name}", us, "% of total", "",
                                "total - world step - firmware compute, in CPU time (the "
                                "goal is on the wall clock: the child's CPU holds its start)"))
            else:
                rows.append(Row(f"stack CPU ({label}): {name}", us, "us / cycle", "",
                                f"{BREAKDOWN_S:.0f} s run with recording, CPU time"))
        rows.append(Row(f"stack CPU ({label}): world alone / cycle", alone_us / parts["total"],
                        "ratio", "", "the run / world alone ratio on CPU time (recording "
                        "included; the goal is on the wall clock)"))
    return rows


def run() -> list[Row]:
    bare = bare_mj_step(SCENARIO, seed=3)
    alone = world_alone(SCENARIO, seed=3)
    cycle_us = 1e6 / 50
    alone_cpu_us = cycle_us / world_alone(SCENARIO, seed=3, clock=time.thread_time)
    bare_cpu_us = cycle_us / bare_mj_step(SCENARIO, seed=3, clock=time.thread_time)
    plain, recorded = _median_rtf(False), _median_rtf(True)
    rows = [Row("stack: bare mj_step (same model, terrain, controls)", bare, "x real time", "",
                "obstacles-low-small, seed 3: the world alone's recorded controls, mj_step only"),
            Row("stack: world alone (MuJoCo + 18 drives)", alone, "x real time", "",
                "obstacles-low-small, seed 3, joints commanded at 50 Hz"),
            Row("stack: world alone / bare mj_step", alone / bare, "ratio", ">= 0.8",
                "issue 43 goal"),
            Row("stack: hexhil run, unpinned", plain, "x real time", f">= {0.65 * alone:.0f}x",
                f"`hexhil run {SCENARIO.name} --seed 3 --json`, micropython, median of {RUNS}"),
            Row("stack: hexhil run --out, unpinned", recorded, "x real time", "",
                f"the same with recording, median of {RUNS}"),
            Row("stack: run / world alone", plain / alone, "ratio", ">= 0.65", "issue 43 goal"),
            Row("stack: run --out / world alone", recorded / alone, "ratio", "",
                "with recording")]
    inproc = _median_rtf(False, "--python", IN_PROCESS)
    rows += [Row(f"stack: hexhil run --python {IN_PROCESS}", inproc, "x real time", "",
                 f"firmware in the host's process (the sweeps' runtime), median of {RUNS}"),
             Row(f"stack: run --python {IN_PROCESS} / world alone", inproc / alone, "ratio",
                 ">= 0.9", "issue 43 goal; same serial digest as micropython")]
    rows += _cpu_rows(alone_cpu_us, bare_cpu_us)
    for label, ip in (("micropython", False), (IN_PROCESS, True)):
        plain = [breakdown(record=False, in_process=ip) for _ in range(CEILING_RUNS)]
        rows.append(_ceiling_row(label, ip, cycle_us / alone,
                                 {k: statistics.median(p[k] for p in plain) for k in plain[0]}))
        recorded, light = [], []
        for _ in range(CEILING_RUNS):   # alternating: a slow minute hits both alike
            recorded.append(breakdown(in_process=ip))
            light.append(light_cycle(ip))
        parts = {k: statistics.median(p[k] for p in recorded) for k in recorded[0]}
        watched = {k: statistics.median(p[k] for p in light) for k in light[0]}
        rows.append(Row(f"stack cycle ({label}): {OVERHEAD}", watched[OVERHEAD], "% of total",
                        "<= 10 %" if ip else "<= 25 %",
                        "issue 43 goal: total - world step - firmware compute, in a run "
                        "with a stopwatch on the world step only (light_cycle), median of "
                        f"{CEILING_RUNS}: " + ", ".join(f"{k} {watched[k]:.0f} us" for k in
                                                        ("total", "world step",
                                                         "firmware compute"))))
        for name, us in parts.items():
            note = (f"{BREAKDOWN_S:.0f} s run with recording, 50 Hz cycles, median of "
                    f"{CEILING_RUNS}")
            if name == OVERHEAD:
                rows.append(Row(f"stack cycle ({label}): {name}, in the breakdown", us,
                                "% of total", "", "the same share of the breakdown's own "
                                "total, which its stopwatches on 22 calls a cycle lengthen"))
                continue
            if name == ONCE:
                rows.append(Row(f"stack cycle ({label}): {name}", us, "ms / run", "",
                                "from the run's start to the firmware's first message, and "
                                "after the last reply; not in the cycle's parts or total"))
                continue
            target = "<= 150" if name == "firmware compute (overlaps)" else ""
            rows.append(Row(f"stack cycle ({label}): {name}", us, "us / cycle", target, note))
    growth = _growth((0, 10, 40))
    for n, rtf in growth.items():
        rows.append(Row(f"stack growth: {n} obstacles", rtf, "x real time", "",
                        f"flat-tripod + {n} obstacles, full stack, {GROWTH_S:.0f} s, "
                        f"median of {GROWTH_RUNS}, the counts alternating"))
    rows.append(Row("stack growth: 40 obstacles against 0", 100.0 * (1 - growth[40] / growth[0]),
                    "% slower", "<= 25 %", "issue 43 goal: 1 - RTF(40) / RTF(0), 36 % when filed"))
    for n in (6, 12, 18):
        rows.append(Row(f"stack growth: {n} servos (bus + servos only)", _bus_and_servos(n),
                        "x real time", "", "scripted master, the firmware's traffic per cycle"))
    return rows
