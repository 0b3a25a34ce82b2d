"""The lockstep simulator: one virtual clock for the servo bus, switches, CAN and physics.

``Simulator`` owns the ``VirtualClock``, the ``Bus`` with 18 emulated AX-12s, the six
limit-switch levels, the CAN side (a python-can virtual bus) and, when given, a physics
world; it serves the firmware process over the simulator link (hil/link.py) and answers
every request in virtual time. Nothing here reads the wall clock except to report how
long a run took.

World seam (optional; issue 5's hexapod world implements it):
    world.actuators() -> 18 Actuators (servo-ID order), driven by the emulated servos
    world.advance_to(t_us)           physics keeps pace with bus time (Bus ``advance`` hook)
    world.switch_levels() -> 6 bools pressed limit switches, leg order LF..RH
    world.body_pose() -> .x_m .y_m .yaw_rad ground truth for the run summary
Without a world the servos drive ``KinematicActuator``s and the switches come from
``switches(t_us) -> int`` (bit i = leg i pressed), open by default.

Recorder seam: every hook goes through ``self.recorder`` when one is given (serial bytes,
CAN frames, switch edges, firmware telemetry and faults, link exchanges, ground truth);
after each reply the recorder gets ``idle()`` time while the firmware computes.
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
import struct
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import can

from firmware import config as fw_config
from protocol import sim_link
from hil.bus import Bus
from hil.clock import VirtualClock
from hil.faults import Faults
from hil.link import FirmwareProcess
from hil.servo import EEPROM_BUSY_US, Servo
from protocol.errors import UserError
from protocol import ax12

_channels = itertools.count()
BODY_SAMPLE_US = 100_000  # ground truth and servo state to the recorder at 10 Hz
RECORDER_SLICE = 8  # held messages the recorder encodes per wait (~20 us; a wait is ~100 us)


@dataclass
class RunResult:
    """What a run produced; ``host_tools/run.py`` turns it into the JSON summary."""

    runtime: str
    sim_time_s: float = 0.0
    wall_time_s: float = 0.0
    cycles: int = 0
    overruns: int = 0
    exceptions: list[str] = field(default_factory=list)
    exit_code: int | None = None
    stderr_tail: str = ""
    serial_digest: str = ""
    faults: dict[str, int] = field(default_factory=dict)
    stop_reason: str | None = None
    firmware: dict[str, Any] = field(default_factory=dict)
    tactile_events: list[dict[str, Any]] = field(default_factory=list)
    switch_edges: int = 0
    can_frames: dict[str, int] = field(default_factory=dict)
    bus_busy_us: int = 0        # bus time of the loop's transactions (after the first cycle)
    bus_wire_us: int = 0        # wire minimum of the same bytes
    loop_cycles: int = 0        # cycles counted for the two figures above
    round_trips: int = 0
    body: dict[str, float] = field(default_factory=lambda: {"dx_m": 0.0, "dy_m": 0.0,
                                                            "dyaw_deg": 0.0})

    @property
    def unhandled_exceptions(self) -> int:
        crashed = self.exit_code not in (0, None) and not self.exceptions
        return len(self.exceptions) + (1 if crashed else 0)


def firmware_settings(scenario: dict[str, Any], tactile: bool | None = None) -> dict[str, Any]:
    """The firmware/config.py overrides a scenario asks for (sent in the link's hello)."""
    fw, gait, bus = scenario.get("firmware", {}), scenario.get("gait", {}), scenario.get("bus", {})
    out: dict[str, Any] = {}
    for key in ("cycle_hz", "tactile", "servo_lost_s", "reads_per_cycle"):
        if key in fw:
            out[key] = fw[key]
    name = gait.get("name", fw_config.DEFAULTS["gait"])
    if name not in fw_config.PERIOD_FOR_GAIT_S:
        raise UserError(f"{scenario.get('_path', 'scenario')}: key 'gait.name' must be tripod "
                        f"or wave, got {name!r}")
    out["gait"] = name
    out["period_s"] = gait.get("period_s", fw_config.PERIOD_FOR_GAIT_S[name])
    for key in ("step_length_m", "step_height_m", "max_obstacle_height_m", "direction_deg"):
        if key in gait:
            out[key] = gait[key]
    for key in ("first_id", "baud"):
        if key in bus:
            out[key] = bus[key]
    if tactile is not None:
        out["tactile"] = tactile
    for key, lo in (("cycle_hz", 0.0), ("period_s", 0.0)):
        if not out.get(key, 1.0) > lo:
            raise UserError(f"{scenario.get('_path', 'scenario')}: '{key}' must be positive")
    return out


def eeprom_busy_us(scenario: dict[str, Any]) -> int:
    """``bus.eeprom_busy_us``: how long a servo ignores packets after an EEPROM write."""
    busy = scenario.get("bus", {}).get("eeprom_busy_us", EEPROM_BUSY_US)
    if busy < 0:
        raise UserError(f"{scenario.get('_path', 'scenario')}: key 'bus.eeprom_busy_us' must be "
                        f"0 or more, got {busy}")
    return busy


class Simulator:
    def __init__(self, scenario: dict[str, Any], seed: int = 0, world: Any = None,
                 recorder: Any = None, switches: Callable[[int], int] | None = None,
                 tactile: bool | None = None, can_server: Any = None) -> None:
        self.scenario = scenario
        self.seed = seed
        self.world = world
        self.recorder = recorder
        self.switches = switches
        self.can_server = can_server
        self.settings = firmware_settings(scenario, tactile)
        bus_cfg = scenario.get("bus", {})
        where = scenario.get("_path", "scenario")
        n = bus_cfg.get("servos", 18)
        first = bus_cfg.get("first_id", 1)
        edition = bus_cfg.get("edition", ax12.EDITION_EMANUAL)
        if edition not in ax12.EDITIONS:
            raise UserError(f"{where}: key 'bus.edition' must be one of {', '.join(ax12.EDITIONS)}")
        busy_us = eeprom_busy_us(scenario)
        self.clock = VirtualClock()
        actuators = world.actuators() if world is not None else [None] * n
        servos = []
        for k in range(n):
            a = actuators[k] if k < len(actuators) else None
            pos = ax12.rad_to_position(a.state()[0]) if a is not None else 512
            s = Servo(first + k, edition, actuator=a, position=pos, eeprom_busy_us=busy_us)
            if "return_delay_us" in bus_cfg:
                s.table[ax12.RETURN_DELAY_TIME] = min(254, bus_cfg["return_delay_us"] // 2)
            servos.append(s)
        faults = None
        if scenario.get("faults"):
            faults = Faults.from_scenario(scenario["faults"], seed, where=f"{where} [faults]",
                                          on_fault=self._on_fault)
        self.faults = faults
        self.bus = Bus(servos, self.clock, baud=bus_cfg.get("baud", 1_000_000),
                       echo=bus_cfg.get("echo", False), faults=faults,
                       on_bytes=self._on_bytes,
                       advance=world.advance_to if world is not None else None)
        self.byte_us = 10_000_000 / self.bus.baud
        self._digest = hashlib.sha256()
        self.can_channel = f"hexhil-sim-{next(_channels)}"
        self.can = can.Bus(interface="virtual", channel=self.can_channel,
                           receive_own_messages=False, preserve_timestamps=True)
        self._switch_bits = 0
        self._next_body_us = 0
        self._next_servo_us = 0
        self._pose0 = world.body_pose() if world is not None else None

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
        if self.switches is not None:
            return int(self.switches(t_us)) & 0x3F
        return 0

    def _sample_switches(self, result: RunResult) -> int:
        t = self.clock.t_us
        bits = self._levels(t)
        changed = bits ^ self._switch_bits
        if changed:
            for i in range(6):
                if changed & (1 << i):
                    result.switch_edges += 1
                    if self.recorder is not None:
                        self.recorder.switch_edge(t, i, bool(bits & (1 << i)))
        self._switch_bits = bits
        return bits

    def send_can(self, arb_id: int, data: bytes) -> None:
        """Put a frame on the simulated CAN bus for the firmware (host -> firmware)."""
        other = can.Bus(interface="virtual", channel=self.can_channel, preserve_timestamps=True)
        try:
            other.send(can.Message(arbitration_id=arb_id, data=data, is_extended_id=False,
                                   timestamp=self.clock.t_s))
        finally:
            other.shutdown()

    def _can_from_firmware(self, payload: bytes, result: RunResult) -> None:
        arb_id, dlc = struct.unpack_from("<HB", payload, 0)
        data = bytes(payload[3:3 + dlc])
        t = self.clock.t_us
        self.can.send(can.Message(arbitration_id=arb_id, data=data, is_extended_id=False,
                                  timestamp=t * 1e-6))
        key = "0x%03X" % arb_id
        result.can_frames[key] = result.can_frames.get(key, 0) + 1
        if self.recorder is not None:
            self.recorder.can(t, arb_id, data, "tx")
        if self.can_server is not None:
            self.can_server.publish(t, arb_id, data)

    def _can_to_firmware(self) -> list[tuple[int, bytes]]:
        frames = []
        while len(frames) < 255:
            msg = self.can.recv(timeout=0)
            if msg is None:
                break
            frames.append((msg.arbitration_id, bytes(msg.data)))
        if self.can_server is not None:
            for arb_id, data, ext in self.can_server.poll():
                if not ext and len(frames) < 255:
                    frames.append((arb_id, bytes(data)))
        if self.recorder is not None:
            for arb_id, data in frames:
                self.recorder.can(self.clock.t_us, arb_id, data, "rx")
        return frames

    def _event(self, payload: bytes, result: RunResult) -> None:
        kind = payload[0]
        text = bytes(payload[1:]).decode("utf-8", errors="replace")
        t = self.clock.t_us
        if kind == sim_link.EVENT_EXCEPTION:
            result.exceptions.append(text)
            if self.recorder is not None:
                self.recorder.fault(t, "firmware_exception", text)
        elif kind == sim_link.EVENT_STOP:
            result.stop_reason = text
            if self.recorder is not None:
                self.recorder.fault(t, "safe_stop", text)
        elif kind == sim_link.EVENT_STATS:
            result.firmware = json.loads(text)
        elif kind == sim_link.EVENT_TACTILE:
            ev = json.loads(text)
            ev["t_s"] = t * 1e-6
            result.tactile_events.append(ev)
            if self.recorder is not None:
                self.recorder.telemetry(t, ev)
        elif self.recorder is not None:
            self.recorder.telemetry(t, {"event": kind, "text": text})

    # --- serving the firmware ---------------------------------------------------------
    def run(self, duration_s: float | None = None, python: str | None = None,
            command: list[str] | None = None) -> RunResult:
        """Start the firmware, serve it until ``duration_s`` of virtual time, collect results."""
        if duration_s is None:
            duration_s = self.scenario.get("scenario", {}).get("duration_s", 10.0)
        if not duration_s > 0:
            raise UserError(f"duration must be positive, got {duration_s}")
        python = python or self.scenario.get("firmware", {}).get("python", "micropython")
        end_us = int(round(duration_s * 1e6))
        result = RunResult(runtime=python)
        wall0 = time.perf_counter()
        fw = FirmwareProcess(python, command=command)
        try:
            self._serve(fw.conn, end_us, result)
        finally:
            code, _, err = fw.finish()
        result.exit_code = code
        result.stderr_tail = "\n".join(err.strip().splitlines()[-5:])
        result.wall_time_s = time.perf_counter() - wall0
        result.sim_time_s = self.clock.t_us * 1e-6
        result.serial_digest = self._digest.hexdigest()
        result.cycles = int(result.firmware.get("cycles", 0))
        result.overruns = int(result.firmware.get("overruns", 0))
        if result.stop_reason is None:
            result.stop_reason = result.firmware.get("stop_reason")
        if self.faults is not None:
            result.faults.update(self.faults.counts)
        for key in ("timeouts", "corrupt_replies", "error_statuses", "echo_mismatch", "overruns"):
            v = result.firmware.get(key, 0)
            if v:
                result.faults["detected_" + key] = v
        if self._pose0 is not None:
            p0, p1 = self._pose0, self.world.body_pose()
            c, s = math.cos(p0.yaw_rad), math.sin(p0.yaw_rad)
            dx, dy = p1.x_m - p0.x_m, p1.y_m - p0.y_m
            dyaw = math.degrees(math.atan2(math.sin(p1.yaw_rad - p0.yaw_rad),
                                           math.cos(p1.yaw_rad - p0.yaw_rad)))
            result.body = {"dx_m": c * dx + s * dy, "dy_m": -s * dx + c * dy, "dyaw_deg": dyaw}
        self.can.shutdown()
        return result

    def _serve(self, conn, end_us: int, result: RunResult) -> None:
        bus = self.bus
        clock = self.clock
        rec = self.recorder
        counting = False
        ended = False
        while True:
            msgs, closed = conn.batch()
            reply = None
            slept = False
            for op, payload in msgs:
                if op == sim_link.OP_WRITE:
                    t0 = clock.t_us
                    bus.master_write(payload)
                    if counting:
                        result.bus_busy_us += clock.t_us - t0
                        result.bus_wire_us += round(len(payload) * self.byte_us)
                elif op == sim_link.OP_TRANSACT:
                    nrx, timeout_us = struct.unpack_from("<HI", payload, 0)
                    tx = payload[6:]
                    t0 = clock.t_us
                    bus.master_write(tx)
                    rx = bus.master_read(nrx, timeout_us)
                    if counting:
                        result.bus_busy_us += clock.t_us - t0
                        heard = len(rx) - (min(len(tx), len(rx)) if bus.echo else 0)
                        result.bus_wire_us += round((len(tx) + heard) * self.byte_us)
                    reply = rx
                elif op == sim_link.OP_CAN:
                    self._can_from_firmware(payload, result)
                elif op == sim_link.OP_EVENT:
                    self._event(payload, result)
                elif op == sim_link.OP_SLEEP:
                    (wake_us,) = struct.unpack_from("<Q", payload, 0)
                    if counting:
                        result.loop_cycles += 1
                    counting = True
                    flags = 0
                    if wake_us >= end_us:
                        wake_us = end_us
                        flags |= sim_link.FLAG_END
                        ended = True
                    if wake_us > clock.t_us:
                        bus.idle_until(wake_us)
                    bits = self._sample_switches(result)
                    frames = self._can_to_firmware() if not ended else []
                    body = bytearray(struct.pack("<BBB", flags, bits, len(frames)))
                    for arb_id, data in frames:
                        body += struct.pack("<HB", arb_id, len(data)) + data.ljust(8, b"\0")
                    reply = bytes(body)
                    slept = True
                elif op == sim_link.OP_HELLO:
                    config = json.dumps(self.settings, sort_keys=True).encode()
                    reply = struct.pack("<B", self._sample_switches(result)) + config
            # Recording comes after the reply: nothing here moves until the firmware's next
            # batch, so the recorder's work overlaps the firmware's instead of delaying it.
            raw = conn.reply(clock.t_us, reply) if reply is not None and not closed else None
            if slept:
                self._ground_truth()
            if rec is not None and raw is not None:
                rec.link(clock.t_us, bytes(conn.raw), raw)
                rec.idle(0 if conn.answered() else RECORDER_SLICE)
            if closed:
                result.round_trips = conn.round_trips
                return

    def _ground_truth(self) -> None:
        t = self.clock.t_us
        if self.recorder is None:
            return
        self.recorder.advance(t)
        if self.world is not None and t >= self._next_body_us:
            self._next_body_us = t + BODY_SAMPLE_US
            p = self.world.body_pose()
            cy, sy = math.cos(p.yaw_rad / 2), math.sin(p.yaw_rad / 2)
            cp, sp = math.cos(p.pitch_rad / 2), math.sin(p.pitch_rad / 2)
            cr, sr = math.cos(p.roll_rad / 2), math.sin(p.roll_rad / 2)
            quat = (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                    cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)
            self.recorder.body_pose(t, (p.x_m, p.y_m, p.z_m), quat)
            w = self.world
            self.recorder.joints(t, w.joint_names(), w.joint_positions().tolist(),
                                 w.joint_velocities().tolist(), w.joint_efforts_nm().tolist())
        if t >= self._next_servo_us:
            self._next_servo_us = t + BODY_SAMPLE_US
            self.recorder.servo_state(t, [s.snapshot() for s in self.bus.servos])
