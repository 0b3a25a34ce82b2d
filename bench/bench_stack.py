"""The full stack as users run it: ``hexhil run`` unpinned, median of 5,
beside the world alone measured in the same run, with and without recording; where a
cycle's wall time goes and how much of it is overhead (neither the world step nor the
firmware's compute); and how the cost grows with servos and obstacles.
"""
from __future__ import annotations

import json
import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench import Row
from bench.bench_world import ROOT, bare_mj_step, world_alone
from bench.cycle import (BREAKDOWN_S, ONCE, OVERHEAD, SCENARIO, TO_READS, breakdown,
                         light_cycle)
from hexhil.hil import scenario as scenario_mod
from hexhil.hil.clock import VirtualClock
from hexhil.hil.link.firmware_process import IN_PROCESS
from hexhil.hil.servobus.ax12_servo import Servo
from hexhil.hil.servobus.line import Bus
from hexhil import Run
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl

RUNS = 5
GROWTH_S = 10.0
GROWTH_RUNS = 3
CEILING_RUNS = 3   # a slow minute moved one breakdown's ceiling by 0.3


def _hexhil_rtf(*extra: str) -> float:
    """``hexhil run SCENARIO --seed 3 --json`` as a user runs it; its real-time factor."""
    out = subprocess.run([sys.executable, "-m", "hexhil.cli", "run", str(SCENARIO), "--seed",
                          "3", "--json", *extra], cwd=ROOT, capture_output=True, text=True,
                         check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])["real_time_factor"]


def _median_rtf(record: bool, *extra: str) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        out = ("--out", str(Path(tmp) / "run.mcap"), "--overwrite") if record else ()
        return statistics.median(_hexhil_rtf(*out, *extra) for _ in range(RUNS))


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
    goal = 0.9 if in_process else 0.65
    return Row(f"stack ceiling ({label}): world alone / (world step + {what})",
               alone_us / (world + firmware), "ratio", f">= {goal}",
               f"no host overhead: world alone {alone_us:.0f} us, world step in a run "
               f"without recording {world:.0f} us + {what} {firmware:.0f} us a cycle, "
               f"medians of {CEILING_RUNS}; the goal leaves the host "
               f"{alone_us / goal - world - firmware:.1f} us a cycle")


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
                "goal"),
            Row("stack: hexhil run, unpinned", plain, "x real time", f">= {0.65 * alone:.0f}x",
                f"`hexhil run {SCENARIO.name} --seed 3 --json`, micropython, median of {RUNS}"),
            Row("stack: hexhil run --out, unpinned", recorded, "x real time", "",
                f"the same with recording, median of {RUNS}"),
            Row("stack: run / world alone", plain / alone, "ratio", ">= 0.65", "goal"),
            Row("stack: run --out / world alone", recorded / alone, "ratio", "",
                "with recording")]
    inproc = _median_rtf(False, "--python", IN_PROCESS)
    rows += [Row(f"stack: hexhil run --python {IN_PROCESS}", inproc, "x real time", "",
                 f"firmware in the host's process (the sweeps' runtime), median of {RUNS}"),
             Row(f"stack: run --python {IN_PROCESS} / world alone", inproc / alone, "ratio",
                 ">= 0.9", "goal; same serial digest as micropython")]
    rows += _cpu_rows(alone_cpu_us, bare_cpu_us)
    for label, ip in (("micropython", False), (IN_PROCESS, True)):
        plain = [breakdown(record=False, in_process=ip) for _ in range(CEILING_RUNS)]
        rows.append(_ceiling_row(label, ip, cycle_us / alone,
                                 {k: statistics.median(p[k] for p in plain) for k in plain[0]}))
        recorded, light, light_recorded = [], [], []
        for k in range(RUNS):   # alternating: a slow minute hits all alike
            if k < CEILING_RUNS:
                recorded.append(breakdown(in_process=ip))
            light.append(light_cycle(ip, record=False))
            light_recorded.append(light_cycle(ip))
        parts = {k: statistics.median(p[k] for p in recorded) for k in recorded[0]}
        for runs, goal, what in (
                (light, "<= 10 %" if ip else "<= 25 %", "goal, as users run it "
                 "(default options: no trace)"),
                (light_recorded, "", "recording a trace (--out's recorder, without the "
                 "3D scene)")):
            watched = {k: statistics.median(p[k] for p in runs) for k in runs[0]}
            rows.append(Row(f"stack cycle ({label}): {OVERHEAD}" + ("" if goal else
                                                                    ", recording"),
                            watched[OVERHEAD], "% of total", goal,
                            f"{what}: total - world step - firmware compute, in a run with a "
                            "stopwatch on the world step only (light_cycle), median of "
                            f"{RUNS}: " + ", ".join(f"{k} {watched[k]:.0f} us" for k in
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
                    "% slower", "<= 25 %", "goal: 1 - RTF(40) / RTF(0)"))
    for n in (6, 12, 18):
        rows.append(Row(f"stack growth: {n} servos (bus + servos only)", _bus_and_servos(n),
                        "x real time", "", "scripted master, the firmware's traffic per cycle"))
    return rows
