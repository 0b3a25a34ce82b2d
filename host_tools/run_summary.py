"""``hexhil run``: a scenario, the lockstep simulator and its firmware or host nodes, and the
run summary."""
from __future__ import annotations

import logging
from typing import Any

from hexhil.hil import scenario as scenario_mod
from hexhil.hil.canbus.socketcand import CanServer
from hexhil.hil.run.limits import RunLimits
from hexhil.hil.mcu.flash_fs import FlashFiles
from hexhil.hil.run_result import RunInterrupted, RunResult
from hexhil.hil.scenario import Scenario, WorldKind
from hexhil import plugins
from hexhil.lockstep_run import Run
from hexhil.protocol.errors import BadFile, BadValue, TimedOut, UserError

CAN_WAIT_TIMEOUT_S = 60.0
log = logging.getLogger(__name__)   # the addresses a client attaches to (hexhil prints them)


def summary(scenario: Scenario, seed: int, result: RunResult,
            trace: str | None, what_ran: dict[str, Any] | None = None) -> dict[str, Any]:
    """The ``--json`` object of a firmware run (its keys are a promise to scripts;
    ``what_ran``, ``Run.what_ran()``: the tactile rule as run and every override)."""
    wall = result.wall_time_s
    fw = result.firmware
    # ours reports its state; a firmware of yours that sends a stop event stopped itself
    stopped = fw.state in ("safe_stop", "fault") or fw.state is None
    return {
        "scenario": scenario.name,
        "seed": seed,
        "firmware_runtime": result.runtime,
        "sim_time_s": round(result.sim_time_s, 6),
        "wall_time_s": round(wall, 3),
        "real_time_factor": round(result.sim_time_s / wall, 2) if wall > 0 else None,
        "boot_s": round(fw.boot_s, 6),
        "cycles": result.cycles,
        "overruns": result.overruns,
        "unhandled_exceptions": result.unhandled_exceptions,
        "ending": result.ending.as_dict(),
        "serial_digest": result.serial_digest,
        "faults": dict(sorted(result.faults.items())),
        "no_servo_answered": result.no_servo_answered,
        "interrupted": result.interrupted,
        "limit_hit": result.limit_hit,
        "console_dropped_bytes": result.console_dropped_bytes,
        "violations": None if result.violations is None else dict(result.violations),
        "stopped_safely": stopped and result.stop_reason is not None,
        "stop_reason": result.stop_reason,
        "body": {k: round(v, 4) for k, v in result.body.as_dict().items()},
        "commanded_distance_m": round(fw.commanded_distance_m, 4),
        "trace": trace,
        "state": fw.state,
        "switch_edges": result.switch_edges,
        "trajectory_changes": fw.trajectory_changes,
        "steps": fw.steps,
        "bus_time_per_cycle_us": round(result.bus_busy_us / result.loop_cycles, 1)
        if result.loop_cycles else None,
        "bus_wire_min_per_cycle_us": round(result.bus_wire_us / result.loop_cycles, 1)
        if result.loop_cycles else None,
        "console": [{"t_s": round(t_s, 6), "text": text} for t_s, text in result.console],
        "tactile": None, "overrides": {}, **(what_ran or {}),
        **_deadline(fw.other),
    }


def _deadline(other: Any) -> dict[str, Any]:
    """An ELF's busy time per control cycle (hil/mcu/deadline.py), where it was measured."""
    mcu = other.get("mcu") if hasattr(other, "get") else None
    return {"deadline": mcu["deadline"]} if mcu and mcu.get("deadline") else {}


def start_can_server(port: int, wait_clients: int) -> CanServer:
    try:
        server = CanServer(port=port)
    except OSError as exc:
        raise BadFile(f"can_server_port: cannot listen on 127.0.0.1:{port}: {exc.strerror}",
                        params=("can_server_port",)) from None
    log.info("can-server: %s:%s channel %s (socketcand)", server.host, server.port,
             server.channel)
    if wait_clients and not server.wait_for_clients(wait_clients, CAN_WAIT_TIMEOUT_S):
        server.close()
        raise TimedOut(f"can_wait_clients: {wait_clients} socketcand client(s) did not attach "
                        f"within {CAN_WAIT_TIMEOUT_S:.0f} s", params=("can_wait_clients",))
    return server


def _beams_summary(sc: Scenario, seed: int, result: RunResult,
                   trace: str | None) -> dict[str, Any]:
    """The ``--json`` object of a beams run: the traversal's outcome."""
    wall = result.wall_time_s
    s = {"scenario": sc.name, "seed": seed, "world": "beams",
         "sim_time_s": round(result.sim_time_s, 6), "wall_time_s": round(wall, 3),
         "real_time_factor": round(result.sim_time_s / wall, 2) if wall > 0 else None,
         "trace": trace}
    s.update(result.host_nodes)
    return s


def run(path: str, duration_s: float | None = None, seed: int | None = None,
        python: str | None = None, tactile: bool | None = None,
        out: str | None = None, can_server_port: int | None = None,
        can_wait_clients: int = 0, live_port: int | None = None,
        realtime: bool = False, navigator: str = "none",
        model_path: str | None = None, firmware: str | None = None,
        gdb_port: int | None = None, coverage: str | None = None,
        overwrite: bool = False, limits: RunLimits | None = None,
        flash_files: FlashFiles | None = None, coverage_libraries: bool = False,
        masked_limit_s: float | None = None) -> tuple[dict[str, Any], RunResult]:
    """Load, simulate, summarise. Returns (summary, raw result).

    A recorded run (``out``) carries the 3D scene. With ``live_port`` the trace's channels
    are also served over the Foxglove WebSocket protocol on 127.0.0.1 (0 picks a free
    port; without ``out`` nothing is kept); ``realtime`` paces virtual time to the wall
    clock.

    With ``can_server_port`` the simulated CAN bus is served over socketcand on 127.0.0.1
    (0 picks a free port); ``can_wait_clients`` holds the start until that many stock
    clients are attached, so they see every frame.

    ``navigator`` (``model``, ``grnn``: registered by host_tools/papers/tactile_hexapod,
    host_tools/plugins.py) stops the walk where it predicts the goal ``gait.distance_m``
    is reached.

    ``firmware``, a MicroPython main file for the virtual board or an executable that
    speaks the link (hil/link/served_firmware.py), or an STM32F411 ELF, runs instead of our
    firmware; an ELF's ``gdb_port`` waits for a GDB client, ``coverage`` writes LCOV there
    (of its own sources; the toolchain's libraries too with ``coverage_libraries``),
    ``masked_limit_s`` sets how long it may spin masked or in a fault's handler
    (docs/elf-firmware.md). ``limits``: the run's wall-clock and memory caps
    (hil/run/limits.py); ``flash_files`` fills and reads back a MicroPython ELF's
    ``/flash`` (docs/micropython-on-the-chip.md).
    """
    sc = scenario_mod.load_scenario(path)
    given_seed = None if seed is None else scenario_mod.check_seed(seed, "seed",
                                                                 params=("seed",))
    seed = sc.scenario.seed if given_seed is None else given_seed
    if duration_s is not None:
        scenario_mod.check_duration(duration_s, "duration_s", params=("duration_s",))
    if can_server_port is not None and not 0 <= can_server_port <= 65535:
        raise BadValue(f"can_server_port {can_server_port}: port must be 0-65535",
                        params=("can_server_port",))
    if firmware is not None and python is not None:
        raise UserError(f"firmware {firmware} brings its own runtime: leave out python",
                        params=("firmware", "python"))
    if can_wait_clients < 0:
        raise BadValue(f"can_wait_clients must be 0 or more, got {can_wait_clients}",
                        params=("can_wait_clients",))
    if can_wait_clients and can_server_port is None:
        raise UserError("can_wait_clients waits for clients of can_server_port: give both",
                        params=("can_wait_clients", "can_server_port"))
    attach_navigator = (plugins.navigator_plan(navigator)(sc, model_path)
                        if navigator != "none" else None)
    server = nav = None
    try:
        if can_server_port is not None:
            server = start_can_server(can_server_port, can_wait_clients)
        with Run(sc, seed=given_seed, runtime=python, duration_s=duration_s, tactile=tactile,
                 trace=out, live_port=live_port, can_server=server, realtime=realtime,
                 firmware=firmware, gdb_port=gdb_port, coverage=coverage,
                 overwrite=overwrite, limits=limits, flash_files=flash_files,
                 coverage_libraries=coverage_libraries, masked_limit_s=masked_limit_s) as r:
            if r.live is not None:
                log.info("live: ws://127.0.0.1:%s (Foxglove WebSocket)", r.live.port)
            if attach_navigator is not None:
                nav = attach_navigator(r)
            try:
                result = r.run()
            except RunInterrupted as exc:
                beams = sc.world.kind is WorldKind.BEAMS
                exc.summary = (_beams_summary if beams else summary)(sc, seed, exc.result, out)
                exc.summary["interrupted"] = True
                raise
            what_ran = r.what_ran()
    finally:
        if server is not None:
            server.close()
    if sc.world.kind is WorldKind.BEAMS:
        return _beams_summary(sc, seed, result, out), result
    s = summary(sc, seed, result, out, what_ran)
    if nav is not None:
        s["navigator"] = {"kind": navigator, **nav.summary(),
                          "goal_dx_m": round(nav.distance_m - result.body.dx_m, 4)}
    return s, result
