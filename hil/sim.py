"""The lockstep simulator: one virtual clock for the servo bus, switches, CAN and physics.

``Simulator`` builds the scenario's rig (hil/rig.py: servos, bus, faults, world) and the
run's CAN bus (hil/can_bus.py), and runs one of two ways, both in virtual time:

* a world with a servo bus (the hexapod, or none: kinematic servos) is driven by the
  firmware process, whose link requests hil/link_server.py answers;
* a world that steps itself (seed 000's beams, ``step()``/``done()``) is stepped here.

Host-side CAN nodes (``add_node``: objects with ``period_us`` and ``tick(t_us)``, on the run's
CAN bus through ``sim.can.endpoint(...)``) tick on the same clock in both: seed 000's
estimator and controller, or a navigator beside the hexapod's firmware.

World seam of a firmware-driven world: ``actuators()`` (servo-ID order), ``advance_to(t_us)``,
``switch_levels()`` (6 bools, LF..RH), ``body_pose()`` (``x_m``, ``y_m``, ``z_m``, ``yaw_rad``,
``quat_wxyz``), ``joint_names()``/``joint_positions()``/... for the recorder. Without a world
the switches come from ``switches(t_us) -> int`` (bit i = leg i pressed), open by default.

With ``scene=True`` either kind of world is also drawn for the recorder's 3D scene
(``scene_shapes()``/``scene_frames()``/``scene_arrows()``, hil/world/scene.py): its geometry
when it changes, its frames and forces with every ground-truth sample. ``realtime=True``
holds each sample back until the wall clock has caught up with virtual time, so a person
can watch a live view.
"""
from __future__ import annotations

import hashlib
import struct
import time
from typing import Any, Callable

from hil import board_line
from hil import rig as rig_mod
from hil.can_bus import CanBus, RecorderListener
from hil.ground_truth import GroundTruth
from hil.link import IN_PROCESS, DirectConnection, FirmwareProcess
from hil.link_server import LinkServer, SwitchSampler, firmware_settings
from hil.run_result import RunResult, body_displacement
from hil.scenario import DEFAULT_DURATION_S
from protocol import link_schema as ls

BODY_SAMPLE_US = 100_000  # ground truth and servo state to the recorder at 10 Hz
# runs a firmware in this process on the link's exchange(bytes written, closed) -> reply
InProcessFirmware = Callable[[Callable[[bytes, bool], bytes]], None]


class Simulator:
    def __init__(self, scenario: dict[str, Any], seed: int = 0, world: Any = None,
                 recorder: Any = None, switches: Callable[[int], int] | None = None,
                 tactile: bool | None = None, can_server: Any = None, scene: bool = False,
                 realtime: bool = False) -> None:
        self.recorder = recorder
        self._realtime = realtime
        self._wall0_s: float | None = None
        self._digest = hashlib.sha256()
        self.rig = rig_mod.build(scenario, seed, world=world, on_fault=self._on_fault,
                                 on_bytes=self._on_bytes)
        self.scenario, self.seed, self.world = self.rig.scenario, seed, world
        self.clock, self.bus, self.faults = self.rig.clock, self.rig.bus, self.rig.faults
        self.can = CanBus(self.clock, self.scenario["faults"].get("can_drop_rate", 0.0), seed,
                          self._on_fault)
        if recorder is not None:
            self.can.add(RecorderListener(recorder))
        if can_server is not None:
            self.can.add_gateway(can_server)
        self._nodes: list[Any] = []
        self._next_tick_us: list[int] = []
        self._tactile = tactile
        self._switches = switches
        self._next_body_us = 0
        self._next_servo_us = 0
        self._stepped = world is not None and self.bus is None
        self._pose0 = world.body_pose() if world is not None and not self._stepped else None
        self._truth = GroundTruth(world, self.bus.servos if self.bus is not None else [],
                                  recorder, scene) if recorder is not None else None
        if self._stepped:
            world.attach(self.can)
        else:
            self.firmware_port = self.can.endpoint("tx")   # the firmware's CAN controller

    def add_node(self, node: Any) -> None:
        """A host-side CAN node (``period_us``, ``tick(t_us)``), ticked in the order added;
        first after one period, or at ``first_tick_us`` if the node has one."""
        self._nodes.append(node)
        self._next_tick_us.append(getattr(node, "first_tick_us", node.period_us))

    # --- hooks ------------------------------------------------------------------------
    def _on_bytes(self, t_us: int, direction: str, data: bytes) -> None:
        self._digest.update(struct.pack("<QB", t_us, 0x54 if direction == "tx" else 0x52))
        self._digest.update(data)
        if self.recorder is not None:
            self.recorder.serial(t_us, direction, data)

    def _on_fault(self, t_us: int, name: str, detail: str) -> None:
        if self.recorder is not None:
            self.recorder.fault(t_us, name, detail)

    def _levels(self, t_us: int) -> int:
        if self.world is not None:
            bits = 0
            for i, pressed in enumerate(self.world.switch_levels()):
                if pressed:
                    bits |= 1 << i
            return bits
        if self._switches is not None:
            return int(self._switches(t_us))
        return 0

    def send_can(self, arb_id: int, data: bytes) -> None:
        """Put a frame on the run's CAN bus from the host (delivered to the firmware)."""
        self.can.send(arb_id, data)

    def _tick(self, t_us: int) -> None:
        """Host nodes whose period has come round, in the order they were given. A period
        counts from the node's last tick, as the ground-truth samples' does, so a node at
        ``BODY_SAMPLE_US`` from 0 ticks at the instants the trace has ground truth for."""
        for i, node in enumerate(self._nodes):
            if t_us >= self._next_tick_us[i]:
                self._next_tick_us[i] = t_us + node.period_us
                node.tick(t_us)

    # --- running ----------------------------------------------------------------------
    def run(self, duration_s: float | None = None, python: str | None = None,
            command: list[str] | None = None, in_process: InProcessFirmware | None = None,
            board: Any = None) -> RunResult:
        """Serve the firmware (or step the world) until ``duration_s`` of virtual time.

        The firmware is a child process (``python``, or ``command``), or with ``in_process``
        a function that runs it in this process, given the link's ``exchange``
        (hil/link.py ``DirectConnection``): the same frames without a socket, or with
        ``board`` (hil/board_line.py ``BoardFirmware``) a main file on the virtual board."""
        if duration_s is None:
            duration_s = self.scenario["scenario"].get("duration_s", DEFAULT_DURATION_S)
        python = python or self.scenario["firmware"].get("python", "micropython")
        if in_process is not None:
            python = IN_PROCESS
        if board is not None:
            python = board_line.RUNTIME
        end_us = int(round(duration_s * 1e6))
        result = RunResult(runtime="none" if self._stepped else python)
        wall0 = time.perf_counter()
        try:
            if self._stepped:
                self._step_world(end_us, result)
            else:
                self._serve_firmware(python, command, in_process, end_us, result, board)
        finally:
            self.can.shutdown()
        result.wall_time_s = time.perf_counter() - wall0
        result.sim_time_s = self.clock.t_us * 1e-6
        if self.faults is not None:
            result.faults.update(self.faults.counts)
        if self.can.dropped:
            result.faults["can_drop"] = self.can.dropped
        return result

    def _step_world(self, end_us: int, result: RunResult) -> None:
        world, rec = self.world, self.recorder
        while True:
            world.step()
            t = world.t_us
            self.clock.advance_to(t)
            self._tick(t)
            if t % BODY_SAMPLE_US == 0:
                self._pace(t)
                if rec is not None:
                    rec.advance(t)
                    self._truth.draw(t)
            if world.done() or t >= end_us:
                break
        result.world = world.outcome()

    def _serve_firmware(self, python: str, command: list[str] | None,
                        in_process: InProcessFirmware | None, end_us: int,
                        result: RunResult, board: Any = None) -> None:
        server = LinkServer(self, firmware_settings(self.scenario, self._tactile),
                            SwitchSampler(self._levels, self.recorder), self._tick,
                            self._ground_truth)
        if in_process is not None:
            in_process(DirectConnection(
                lambda conn, msgs, closed: server.answer(conn, msgs, closed, end_us, result)
            ).exchange)
            result.exit_code = 0
        elif board is not None:
            board.serve(server, end_us, result)
        else:
            fw = FirmwareProcess(python, command=command)
            try:
                server.serve(fw.conn, end_us, result)
            finally:
                code, _, err = fw.finish()
            result.exit_code = code
            result.stderr_tail = "\n".join(err.strip().splitlines()[-5:])
        result.serial_digest = self._digest.hexdigest()
        result.cycles = int(result.firmware.get(ls.CYCLES, 0))
        result.overruns = int(result.firmware.get(ls.OVERRUNS, 0))
        if result.stop_reason is None:
            result.stop_reason = result.firmware.get(ls.STOP_REASON)
        for key in (ls.TIMEOUTS, ls.CORRUPT_REPLIES, ls.ERROR_STATUSES, ls.ECHO_MISMATCH,
                    ls.OVERRUNS):
            v = result.firmware.get(key, 0)
            if v:
                result.faults["detected_" + key] = v
        if self._pose0 is not None:
            result.body = body_displacement(self._pose0, self.world.body_pose())

    def _ground_truth(self) -> None:
        """Body pose, joints, scene and servo states to the recorder at 10 Hz of virtual time."""
        t = self.clock.t_us
        self._pace(t)
        if self.recorder is None:
            return
        self.recorder.advance(t)
        if self.world is not None and t >= self._next_body_us:
            self._next_body_us = t + BODY_SAMPLE_US
            self._truth.world_sample(t)
        if t >= self._next_servo_us:
            self._next_servo_us = t + BODY_SAMPLE_US
            self._truth.servo_sample(t)

    def _pace(self, t_us: int) -> None:
        """With ``realtime``: wait until the wall clock has run ``t_us`` since the start."""
        if not self._realtime:
            return
        now = time.perf_counter()
        if self._wall0_s is None:
            self._wall0_s = now - t_us * 1e-6
        ahead_s = self._wall0_s + t_us * 1e-6 - now
        if ahead_s > 0:
            time.sleep(ahead_s)
