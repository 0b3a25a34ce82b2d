"""``hexhil run``: a scenario, the lockstep simulator and its firmware or host nodes, and the
run summary."""
from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any, Callable

from hil import scenario as scenario_mod
from hil import board_line
from hil.board_line import BoardFirmware
from hil.rig import make_world
from hil.run_result import RunResult
from hil.sim import Simulator
from host_tools import in_process
from protocol import link_schema as ls
from protocol.errors import UserError

CAN_WAIT_TIMEOUT_S = 60.0


def summary(scenario: dict[str, Any], seed: int, result: RunResult,
            trace: str | None) -> dict[str, Any]:
    """The ``--json`` object of a firmware run (keys fixed by issue 4)."""
    wall = result.wall_time_s
    stopped = result.firmware.get(ls.STATE) in ("safe_stop", "fault")
    return {
        "scenario": _name(scenario),
        "seed": seed,
        "firmware_runtime": result.runtime,
        "sim_time_s": round(result.sim_time_s, 6),
        "wall_time_s": round(wall, 3),
        "real_time_factor": round(result.sim_time_s / wall, 2) if wall > 0 else None,
        "boot_s": round(result.firmware.get(ls.BOOT_S, 0.0), 6),
        "cycles": result.cycles,
        "overruns": result.overruns,
        "unhandled_exceptions": result.unhandled_exceptions,
        "serial_digest": result.serial_digest,
        "faults": dict(sorted(result.faults.items())),
        "stopped_safely": stopped and result.stop_reason is not None,
        "stop_reason": result.stop_reason,
        "body": {k: round(v, 4) for k, v in result.body.items()},
        "commanded_distance_m": round(result.firmware.get(ls.COMMANDED_DISTANCE_M, 0.0), 4),
        "trace": trace,
        "state": result.firmware.get(ls.STATE),
        "switch_edges": result.switch_edges,
        "trajectory_changes": result.firmware.get(ls.TRAJECTORY_CHANGES, 0),
        "steps": result.firmware.get(ls.STEPS, 0),
        "bus_time_per_cycle_us": round(result.bus_busy_us / result.loop_cycles, 1)
        if result.loop_cycles else None,
        "bus_wire_min_per_cycle_us": round(result.bus_wire_us / result.loop_cycles, 1)
        if result.loop_cycles else None,
    }


def _name(scenario: dict[str, Any]) -> str:
    return scenario["scenario"].get("name") or Path(scenario["_path"]).stem


def start_can_server(port: int, wait_clients: int) -> Any:
    from hil.can_server import CanServer

    try:
        server = CanServer(port=port)
    except OSError as exc:
        raise UserError(f"--can-server: cannot listen on 127.0.0.1:{port}: {exc.strerror}") from None
    print(f"can-server: {server.host}:{server.port} channel {server.channel} (socketcand)",
          flush=True)
    if wait_clients and not server.wait_for_clients(wait_clients, CAN_WAIT_TIMEOUT_S):
        server.close()
        raise UserError(f"--can-wait: {wait_clients} socketcand client(s) did not attach "
                        f"within {CAN_WAIT_TIMEOUT_S:.0f} s")
    return server


def _start_live(port: int) -> Any:
    from host_tools.trace.live import LiveServer

    live = LiveServer(port)
    print(f"live: ws://127.0.0.1:{live.port} (Foxglove WebSocket)", flush=True)
    return live


def _traverse(sc: dict[str, Any], seed: int, cfg: Any, recorder: Any, server: Any,
              trace: str | None, realtime: bool) -> tuple[dict[str, Any], RunResult]:
    """A beams scenario: seed 000's world and host nodes on the same lockstep simulator."""
    from host_tools.traversal import closed_loop

    wall0 = time.perf_counter()
    out = closed_loop.run(cfg, recorder, can_server=server, scene=recorder is not None,
                          realtime=realtime)
    result = RunResult("none", sim_time_s=out["t_end_s"], wall_time_s=time.perf_counter() - wall0,
                       world=out)
    wall = result.wall_time_s
    s = {"scenario": _name(sc), "seed": seed, "world": "beams",
         "sim_time_s": round(result.sim_time_s, 6), "wall_time_s": round(wall, 3),
         "real_time_factor": round(result.sim_time_s / wall, 2) if wall > 0 else None,
         "trace": trace}
    s.update(out)
    return s, result


def run(path: str, duration_s: float | None = None, seed: int | None = None,
        python: str | None = None, tactile: bool | None = None,
        out: str | None = None, can_server_port: int | None = None,
        can_wait_clients: int = 0, live_port: int | None = None,
        realtime: bool = False, navigator: str = "none",
        model_path: str | None = None, firmware: str | None = None
        ) -> tuple[dict[str, Any], RunResult]:
    """Load, simulate, summarise. Returns (summary, raw result).

    A recorded run (``out``) carries the 3D scene. With ``live_port`` the trace's channels
    are also served over the Foxglove WebSocket protocol on 127.0.0.1 (0 picks a free
    port; without ``out`` nothing is kept); ``realtime`` paces virtual time to the wall
    clock.

    With ``can_server_port`` the simulated CAN bus is served over socketcand on 127.0.0.1
    (0 picks a free port); ``can_wait_clients`` holds the start until that many stock
    clients are attached, so they see every frame.

    ``navigator`` (``model``, ``grnn``; host_tools/grnn/navigator.py) stops the walk where
    it predicts the goal ``gait.distance_m`` is reached.

    ``firmware``, a MicroPython main file, runs on the virtual STM32F411 board
    (hil/board_line.py, docs/your-firmware.md) instead of our firmware on the sim HAL.
    """
    sc = scenario_mod.load(path)
    board = BoardFirmware.of(firmware) if firmware is not None else None
    if board is not None and (python is not None or sc["world"].get("kind") == "beams"):
        raise UserError("--firmware runs a main file under micropython on the virtual board: "
                        + ("not with --python" if python is not None
                           else "a beams scenario has no firmware"))
    if seed is None:
        seed = sc["scenario"].get("seed", 0)
    if duration_s is not None and not duration_s > 0:
        raise UserError(f"--duration must be positive, got {duration_s}")
    if can_server_port is not None and not 0 <= can_server_port <= 65535:
        raise UserError(f"--can-server {can_server_port}: port must be 0-65535")
    if can_wait_clients < 0:
        raise UserError(f"--can-wait must be 0 or more, got {can_wait_clients}")
    python = python or sc["firmware"].get("python", "micropython")
    if board is not None:
        python = board_line.RUNTIME
    beams = sc["world"].get("kind") == "beams"
    if beams:
        from host_tools.traversal.closed_loop import config_from_scenario
        cfg = config_from_scenario(sc, seed)
    attach_navigator = (_plan_navigation(sc, navigator, model_path) if navigator != "none"
                        else None)
    world = None if beams else make_world(sc, seed)
    recorder = live = server = nav = None
    try:
        if live_port is not None:
            live = _start_live(live_port)
        if out or live:
            from host_tools.trace.recorder import Recorder
            recorder = Recorder(out or os.devnull, {
                "scenario": sc["_path"], "seed": seed,
                "firmware_runtime": "none" if beams else python}, live=live,
                **({"flush_interval_us": live.flush_interval_us} if live else {}))
        if can_server_port is not None:
            server = start_can_server(can_server_port, can_wait_clients)
        if beams:
            return _traverse(sc, seed, cfg, recorder, server, out, realtime)
        sim = Simulator(sc, seed, world=world, recorder=recorder, tactile=tactile,
                        can_server=server, scene=recorder is not None, realtime=realtime)
        if attach_navigator is not None:
            nav = attach_navigator(sim, world)
        result = (sim.run(duration_s, board=board) if board is not None
                  else in_process.run(sim, duration_s, python))
    finally:
        if server is not None:
            server.close()
        if recorder is not None:
            recorder.close()
        if live is not None:
            live.close()
    s = summary(sc, seed, result, out)
    if nav is not None:
        s["navigator"] = {"kind": navigator, **nav.summary(),
                          "goal_dx_m": round(nav.distance_m - result.body.get("dx_m", 0.0), 4)}
    return s, result


def _plan_navigation(sc: dict[str, Any], kind: str, model_path: str | None
                     ) -> Callable[[Simulator, Any], Any]:
    """What attaches the navigator to a run: its options checked and its estimator made
    (a GRNN file loaded) before anything opens; the goal ``gait.distance_m``, planned at the
    gait's nominal speed."""
    if kind not in ("model", "grnn"):
        raise UserError(f"--navigator {kind}: choose one of none, model, grnn")
    if sc["world"].get("kind") != "hexapod":
        raise UserError("--navigator walks the hexapod: this scenario's world is "
                        f"{sc['world'].get('kind', 'none')}")
    if "distance_m" not in sc["gait"]:
        raise UserError("--navigator needs the goal: the scenario has no gait.distance_m")
    if kind == "grnn" and not model_path:
        raise UserError("--navigator grnn needs --model MODEL.pt (hexhil grnn train)")
    from host_tools.grnn import navigator
    from hil.link_server import firmware_settings
    from protocol import hexapod

    fw = firmware_settings(sc)
    gait, period_s = fw["gait"], fw["period_s"]
    step_m = fw.get("step_length_m", hexapod.STEP_LENGTH_M)
    d = sc["gait"]["distance_m"]
    steps = hexapod.periods_for_distance(d, hexapod.speed_m_s(gait, step_m, period_s), period_s)
    estimator = navigator.make_estimator(kind, model_path, gait, period_s, step_m, d)
    return lambda sim, world: navigator.attach(sim, world, estimator, gait, period_s, step_m,
                                               d, steps)
