"""The lockstep simulator: one virtual clock for the servo bus, switches, CAN and physics.

``Simulator`` builds the run core (hil/run/core.py: the scenario's rig, the run's CAN bus,
host nodes, recorder hooks, ground truth) and one of two drivers, both in virtual time:

* ``FirmwareDriver``: a world with a servo bus (the hexapod, or none: kinematic servos) is
  driven by the firmware, whose link requests hil/link/server.py answers;
* ``SteppedDriver``: a world that steps itself (seed 000's beams, hil/seams.py
  ``SteppedWorld``) is stepped here.

Host-side CAN nodes (``add_node``: hil/seams.py ``HostNode``, on the run's CAN bus through
``sim.can.endpoint(...)``) tick on the same clock in both: seed 000's estimator and
controller, or a navigator beside the hexapod's firmware.

Without a world the switches come from ``switches(t_us) -> int`` (bit i = leg i pressed),
open by default. With ``scene=True`` either kind of world is also drawn for the recorder's
3D scene (hil/world/scene.py): its geometry when it changes, its frames and forces with
every ground-truth sample. ``realtime=True`` paces the samples to the wall clock
(hil/run/core.py ``WallClockPacing``), so a person can watch a live view.
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable

from hexhil.hil.link.board_line import why_no_servo_answered
from hexhil.hil.link.served_firmware import ServedFirmware, judge
from hexhil.hil.link.firmware_child import FirmwareProcess
from hexhil.hil.link.firmware_process import IN_PROCESS, DirectConnection
from hexhil.hil.link.server import LinkServer, SwitchSampler
from hexhil.hil.run.core import RunCore, WallClockPacing
from hexhil.hil.run.limits import RunLimits, RunWatch
from hexhil.hil.run.lookahead import Lookahead
from hexhil.hil.run_result import (BodyDisplacement, Ending, FirmwareEnding, HexapodOutcome,
                             RunInterrupted, RunResult, RunTally)
from hexhil.hil.scenario import Scenario, check_duration
from hexhil.hil.seams import CanGateway, FirmwareWorld, HostNode, SteppedWorld, TraceRecorder
from hexhil.protocol import link_schema as ls

BODY_SAMPLE_US = 100_000  # ground truth and servo state to the recorder at 10 Hz
OWN_EXIT_WAIT_S = 10.0    # how long our firmware may take to exit once it closed the link
# runs a firmware in this process on the link's exchange(bytes written, closed) -> reply
InProcessFirmware = Callable[[Callable[[bytes, bool], bytes]], None]
# The firmware's stats event counters a run reports as detected faults. protocol/ will
# define the stats schema; until then its names are read here only.
DETECTED_COUNTERS = (ls.TIMEOUTS, ls.CORRUPT_REPLIES, ls.ERROR_STATUSES, ls.ECHO_MISMATCH,
                     ls.OVERRUNS)


def _final_state(world: FirmwareWorld) -> HexapodOutcome:
    """A firmware-driven world's state at the run's end (``RunResult.world``): the body's
    pose in the world frame and the feet that carry load."""
    pose = world.body_pose()
    contacts = getattr(world, "foot_contacts", None)
    return HexapodOutcome(pose.x_m, pose.y_m, pose.z_m, math.degrees(pose.yaw_rad),
                          sum(contacts()) if contacts is not None else None)


def _next_on_grid(t_us: int) -> int:
    """The first ground-truth instant after ``t_us`` (multiples of ``BODY_SAMPLE_US``)."""
    return (t_us // BODY_SAMPLE_US + 1) * BODY_SAMPLE_US


def _detected_faults(tally: RunTally) -> None:
    """The faults the firmware detected, from its last stats event, as the run's faults."""
    for key in DETECTED_COUNTERS:
        v = tally.firmware.get(key, 0)
        if v:
            tally.faults["detected_" + key] = v


class FirmwareDriver:
    """Serves the firmware's link: its sleeps move the clock, tick the host nodes and take
    the ground truth. Offers ``rig``, ``can``, ``recorder`` and ``firmware_port`` (the
    firmware's CAN controller) to hil/link/server.py."""

    def __init__(self, core: RunCore, tactile: bool | None,
                 switches: Callable[[int], int] | None) -> None:
        self.core, self._tactile, self._switches = core, tactile, switches
        self.rig, self.can, self.recorder = core.rig, core.can, core.recorder
        self.firmware_port = core.can.endpoint("tx")
        self._pose0 = core.world.body_pose() if core.world is not None else None
        self._next_body_us = 0
        self._next_servo_us = 0
        self.watch: RunWatch | None = None   # the run's limits, set by Simulator.run

    def next_tick_us(self) -> int | None:
        """The next host node tick or ground-truth sample: a sleep stops there, so both
        come on their grids (a node at its period, the samples every 100 ms)."""
        due = self.core.next_tick_us()
        if self.core.recorder is not None:
            truth = (min(self._next_body_us, self._next_servo_us) if self.core.world is not None
                     else self._next_servo_us)
            due = truth if due is None else min(due, truth)
        return due

    def _next_due(self) -> int | None:
        """The next instant something reads or changes the world besides the firmware: a
        host node tick, a ground-truth sample, an injected fault (the lookahead's limit)."""
        due = self.next_tick_us()
        faults = self.core.bus.faults if self.core.bus is not None else None
        if faults is not None:
            due = faults.next_us if due is None else min(due, faults.next_us)
        return due

    def _wake(self, t_us: int) -> None:
        """The line idled to ``t_us``: host nodes due tick, then the ground truth due is
        taken (body pose, joints, scene and servo states, at 10 Hz on the 100 ms grid)."""
        core = self.core
        core.tick_nodes(t_us)
        if core.recorder is None:
            return
        if core.world is not None and t_us >= self._next_body_us:
            self._next_body_us = _next_on_grid(t_us)
            core.truth.world_sample(t_us)
        if t_us >= self._next_servo_us:
            self._next_servo_us = _next_on_grid(t_us)
            core.truth.servo_sample(t_us)

    def _levels(self, t_us: int) -> int:
        if self.core.world is not None:
            return self.core.switch_bits()
        bits = int(self._switches(t_us)) if self._switches is not None else 0
        return self.core.faults.switch_bits(t_us, bits) if self.core.faults else bits

    def run(self, python: str, command: list[str] | None,
            in_process: InProcessFirmware | None, end_us: int, result: RunTally,
            firmware: ServedFirmware | None = None) -> None:
        core = self.core
        ahead = None
        if in_process is None and firmware is None and hasattr(core.world, "checkpoint"):
            ahead = Lookahead(core.world, lambda: core.clock.t_us, self._next_due)
        server = LinkServer(self, core.config.firmware_settings(self._tactile),
                            SwitchSampler(self._levels, core.recorder), self._wake,
                            self._ground_truth, ahead)
        if in_process is not None:
            in_process(DirectConnection(
                lambda conn, msgs, closed: server.answer(conn, msgs, closed, end_us, result)
            ).exchange)
            result.exit_code = 0
        elif firmware is not None:
            firmware.serve(server, end_us, result)
        else:
            fw = FirmwareProcess(python, command=command, watch=self.watch)
            closed = False
            try:
                server.serve(fw.conn, end_us, result)
                closed = True
            finally:   # ours exits as soon as it closed the link; an interrupt ends it at once
                code, out, err = fw.finish(OWN_EXIT_WAIT_S if closed else 0.0)
            result.exit_code = code
            result.stderr_tail = "\n".join(err.strip().splitlines()[-5:])
            # ours may stop before the end on its own (a safe stop): only a crash counts
            result.ending = judge(python, code, err, out, core.clock.t_us, core.clock.t_us)
        result.serial_digest = core.serial_digest
        _detected_faults(result)
        result.no_servo_answered = why_no_servo_answered(core.bus, result.faults)
        if self._pose0 is not None:
            result.body = BodyDisplacement.between(self._pose0, core.world.body_pose())
            result.world = _final_state(core.world)

    def _ground_truth(self) -> None:
        """After a sleep's reply: the wall-clock pacing and the recorder's window."""
        core = self.core
        t = core.clock.t_us
        core.pacing.pace(t)
        if core.recorder is not None:
            core.recorder.advance(t)


class SteppedDriver:
    """Steps a world that steps itself, ticking the host nodes after each step."""

    def __init__(self, core: RunCore) -> None:
        self.core = core
        self.watch: RunWatch | None = None   # the run's limits, set by Simulator.run
        core.world.attach(core.can)
        if hasattr(core.world, "faults"):    # seed 000's force sensor faults ([faults])
            core.world.faults = core.faults
        core.faults.start(core.clock, 0)

    def run(self, end_us: int, result: RunTally) -> None:
        core = self.core
        world, rec, faults = core.world, core.recorder, core.faults
        while True:
            world.step()
            t = world.t_us
            core.clock.advance_to(t)
            if faults.next_us <= t:
                faults.apply_due(t)
            core.tick_nodes(t)
            if t % BODY_SAMPLE_US == 0:
                core.pacing.pace(t)
                if rec is not None:
                    rec.advance(t)
                    core.truth.draw(t)
            if world.done() or t >= end_us:
                break
        result.world = world.outcome()


class Simulator:
    """One lockstep run: the core and the driver its world calls for."""

    def __init__(self, scenario: dict[str, Any] | Scenario, seed: int = 0,
                 world: FirmwareWorld | SteppedWorld | None = None,
                 recorder: TraceRecorder | None = None,
                 switches: Callable[[int], int] | None = None,
                 tactile: bool | None = None, can_server: CanGateway | None = None, scene: bool = False,
                 realtime: bool = False) -> None:
        self.core = RunCore(scenario, seed, world=world, recorder=recorder,
                            can_server=can_server, scene=scene,
                            pacing=WallClockPacing() if realtime else None)
        core = self.core
        self.rig, self.seed, self.world = core.rig, seed, world
        self.clock, self.bus, self.faults = core.clock, core.bus, core.faults
        self.can, self.recorder = core.can, core.recorder
        self._stepped = world is not None and self.bus is None
        if self._stepped:
            self.driver: FirmwareDriver | SteppedDriver = SteppedDriver(core)
        else:
            self.driver = FirmwareDriver(core, tactile, switches)
            self.firmware_port = self.driver.firmware_port

    def add_node(self, node: HostNode) -> None:
        """A host-side CAN node (hil/seams.py ``HostNode``), ticked in the order added."""
        self.core.add_node(node)

    def send_can(self, arb_id: int, data: bytes) -> None:
        """Put a frame on the run's CAN bus from the host (delivered to the firmware)."""
        self.core.send_can(arb_id, data)

    def run(self, duration_s: float | None = None, python: str | None = None,
            command: list[str] | None = None, in_process: InProcessFirmware | None = None,
            firmware: ServedFirmware | None = None,
            limits: RunLimits | None = None) -> RunResult:
        """Serve the firmware (or step the world) until ``duration_s`` of virtual time.

        The firmware is a child process (``python``, or ``command``), or with ``in_process``
        a function that runs it in this process, given the link's ``exchange``
        (hil/link/firmware_process.py ``DirectConnection``): the same frames without a socket, or
        ``firmware``, one that starts and serves itself (hil/link/served_firmware.py).
        ``limits`` (hil/run/limits.py, default ``RunLimits()``): a wall-clock or memory cap
        hit ends the run with ``Ending.LIMIT``, the trace finished as after Ctrl-C."""
        cfg = self.core.config
        duration_s = (cfg.scenario.duration_s if duration_s is None
                      else check_duration(duration_s, "duration_s"))
        python = python or cfg.firmware.python.value
        if in_process is not None:
            python = IN_PROCESS
        if firmware is not None:
            python = firmware.runtime
        end_us = int(round(duration_s * 1e6))
        result = RunTally(runtime="none" if self._stepped else python)
        watch = RunWatch(limits or RunLimits(), duration_s)
        self.driver.watch = watch
        wall0 = time.perf_counter()
        try:
            with watch:
                if isinstance(self.driver, SteppedDriver):
                    self.driver.run(end_us, result)
                else:
                    self.driver.run(python, command, in_process, end_us, result, firmware)
        except KeyboardInterrupt:
            result.interrupted = watch.hit is None
            result.serial_digest = self.core.serial_digest
        finally:
            self.core.shutdown()
        if watch.hit is not None:
            result.limit_hit = watch.hit
            result.ending = FirmwareEnding(Ending.LIMIT, watch.reason, result.ending.last_lines,
                                           self.clock.t_us * 1e-6, result.exit_code)
        result.wall_time_s = time.perf_counter() - wall0
        result.sim_time_s = self.clock.t_us * 1e-6
        if self.faults is not None:
            result.faults.update(self.faults.counts)
        if self.can.dropped:
            result.faults["can_drop"] = self.can.dropped
        frozen = result.result()
        if frozen.interrupted:
            raise RunInterrupted(frozen)
        return frozen
