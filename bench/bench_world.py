"""Hexapod world speed: real-time factor of the physics alone and of the full stack
(MicroPython firmware + lockstep bus + emulated servos + MuJoCo), and the wall time of the
whole ``experiment tactile-hexapod`` sweep on this machine.
"""
from __future__ import annotations

import math
import os
import tempfile
import time
from pathlib import Path
from typing import Any, Callable

from bench import Row
from hexhil.hil.link.firmware_process import IN_PROCESS
from hexhil.hil.scenario.world_section import OBSTACLE_BODY
from hexhil.hil.world.hexapod_world import PHYSICS_DT_US, HexapodWorld
from hexhil.hil import scenario as scenario_mod

# the folder bench/ is in, links not followed: run from a folder that holds links to a
# checkout's bench/ and scenarios/ only, the benches measure the installed package
ROOT = Path(__file__).absolute().parent.parent
SIM_S = 20.0
REPEATS = 3


def world_alone(path: Path = ROOT / "scenarios" / "obstacles-high-large.toml",
                seed: int = 1, controls: list | None = None,
                clock: Callable[[], float] = time.perf_counter) -> float:
    """Physics + AX-12 drives over a scenario's terrain, joints commanded at 50 Hz through
    the seam, timed on ``clock`` (wall, or CPU time). ``controls``, if given, gets each
    physics step's actuator controls."""
    sc = scenario_mod.load_scenario(path)
    world = HexapodWorld(sc, seed=seed)
    acts = world.actuators()
    q0 = [a.state()[0] for a in acts]
    if controls is not None:
        control_into = world.drives.control_into

        def recorded(q: Any, dt: float, ctrl: Any) -> None:
            control_into(q, dt, ctrl)
            controls.append(ctrl.copy())
        world.drives.control_into = recorded
    t0 = clock()
    for k in range(int(SIM_S * 50)):
        phase = 2 * math.pi * k / 50 / 1.4
        for i, a in enumerate(acts):
            a.command(q0[i] + 0.2 * math.sin(phase + i), 0.0, 1.0, True, (1, 1, 32, 32, 32))
        world.advance_to((k + 1) * 20_000)
    return SIM_S / (clock() - t0)


def bare_mj_step(path: Path = ROOT / "scenarios" / "obstacles-high-large.toml",
                 seed: int = 1, clock: Callable[[], float] = time.perf_counter) -> float:
    """Real-time factor of ``mujoco.mj_step`` alone on ``world_alone``'s model, terrain and
    trajectory: its controls are recorded in an untimed run, then a fresh world of the same
    seed is stepped with them (the same states, so the same contacts), one array copy and
    one ``mj_step`` a step. The floor of the world's cost."""
    import mujoco

    controls: list = []
    world_alone(path, seed, controls)
    world = HexapodWorld(scenario_mod.load_scenario(path), seed=seed)
    m, d = world.model, world.data
    t0 = clock()
    for ctrl in controls:
        d.ctrl[:] = ctrl
        mujoco.mj_step(m, d)
    return SIM_S / (clock() - t0)


def _full_stack() -> tuple[float, float, float, float]:
    """Tripod over low-density small obstacles, firmware under micropython, with and
    without recording to MCAP, and unrecorded with the real world model,
    alternated, best of ``REPEATS`` each (the machine is shared); (RTF recorded, RTF plain,
    RTF real model, sim s). The host and the firmware process are
    pinned to one core, as the issue's target is stated: nothing overlaps."""
    from hexhil.papers.tactile_hexapod import experiment as th

    spec = th.RunSpec("bench", "tripod", 1.0, True, 1, "low", "small", periods=15, model="ideal",
                      python="micropython")
    real = th.RunSpec("bench", "tripod", 1.0, True, 1, "low", "small", periods=15, model="real",
                      python="micropython")
    best = {False: math.inf, True: math.inf, "real": math.inf}
    cores = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(cores)})  # the firmware child inherits it
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for _ in range(REPEATS):
                for recorded in (False, True):
                    t0 = time.perf_counter()
                    out = th.run_one(spec, trace_dir=tmp if recorded else None)
                    best[recorded] = min(best[recorded], time.perf_counter() - t0)
                t0 = time.perf_counter()
                th.run_one(real)
                best["real"] = min(best["real"], time.perf_counter() - t0)
    finally:
        os.sched_setaffinity(0, cores)
    sim_s = out["sim_s"]
    return sim_s / best[True], sim_s / best[False], sim_s / best["real"], sim_s


def _sweep(python: str) -> tuple[float, int]:
    """The whole ``hexhil experiment tactile-hexapod`` sweep (its defaults: 3 seeds, real
    model, one worker process per core) with the firmware under ``python``; (wall s, runs)."""
    from hexhil.papers.tactile_hexapod import experiment as th
    from hexhil.executor import Executor

    with tempfile.TemporaryDirectory() as tmp:
        res = th.main(Path(tmp), th.SweepOptions(seeds=3, python=python),
                      Executor(os.cpu_count() or 1))
    return res["wall_s"], res["runs"]


def run() -> list[Row]:
    rows = [Row("world alone: real-time factor", world_alone(), "x real time", ">= 20x",
                "MuJoCo 2 ms steps + 18 AX-12 drives, high-large obstacles, 50 Hz commands")]
    rtf, plain, real, sim_s = _full_stack()
    rows.append(Row("world full stack: real-time factor", rtf, "x real time", ">= 20x",
                    f"micropython firmware + bus + servos + MuJoCo + MCAP recording, tripod "
                    f"{sim_s:.0f} s, host and firmware pinned to one core, best of {REPEATS}; "
                    f"{plain:.1f}x without recording"))
    rows.append(Row("world full stack, real model: real-time factor", real, "x real time", "",
                    f"as above without recording, world.model = real (backlash, unit spread, "
                    f"trial noise, {OBSTACLE_BODY} obstacles); ideal: {plain:.1f}x"))
    wall, runs = _sweep(IN_PROCESS)
    before, _ = _sweep("micropython")
    rows.append(Row("experiment tactile-hexapod (whole sweep)", wall, "s wall",
                    f"<= {before / 3:.0f} s",
                    f"`hexhil experiment tactile-hexapod` as run: {runs} runs on "
                    f"{os.cpu_count()} worker processes, firmware in process"))
    rows.append(Row("experiment tactile-hexapod, firmware under micropython", before, "s wall",
                    "", f"the baseline of the same bench run (`--python micropython`, the "
                        f"runtime the sweeps used before in process); {before / wall:.2f}x the time"))
    return rows
