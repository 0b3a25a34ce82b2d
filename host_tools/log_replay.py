"""Replay a real robot's imported log into a firmware (``hexhil replay`` of a trace made by
``hexhil trace import``): the firmware becomes the master of the logged line.

Such a trace holds no link exchanges, only what was on the robot's wires: the master's and
the servos' bytes on ``/serial``, CAN frames (``tx`` the controller's, ``rx`` for it) and
switch edges. So the firmware runs against a line that answers from the log
(``LoggedLine``, the servo bus's own ``Bus`` with its timing and read rules): each packet
the firmware sends is compared with the logged master's next one, and when they are the
same the servos' logged replies to it come back after the logged delays. The ``rx`` CAN
frames reach the firmware at their logged times, the switches change at theirs, and each
CAN frame the firmware sends is compared with the logged controller's next one. The first
packet or frame that differs, or one the firmware never sent, is the divergence, in words.
"""
from __future__ import annotations

import bisect
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can

from hexhil.hil import scenario as scenario_mod
from hexhil.hil.canbus.bus import CanBus
from hexhil.hil.clock import VirtualClock
from hexhil.hil.link.firmware_child import FirmwareProcess
from hexhil.hil.link.served_firmware import ElfFirmware, served_firmware
from hexhil.hil.link.server import LinkServer, SwitchSampler
from hexhil.hil.run_result import RunTally
from hexhil.hil.servobus.line import Bus
from hexhil.hil.servobus.wire import US_BITS, Burst
from hexhil.dynamixel.decode import DECODERS, packet_spans
from hexhil.replay_result import Divergence, ReplayResult
from hexhil.trace.protobuf import CanFrame, SerialBytes, SwitchEdge
from hexhil.trace.reader import Trace
from hexhil.trace.topics import T_CAN_RAW, T_SERIAL, T_SWITCHES
from hexhil.protocol.dynamixel import models
from hexhil.protocol.dynamixel import v1 as dxl
from hexhil.protocol.dynamixel import v2 as dx2
from hexhil.protocol.errors import BadValue



@dataclass(frozen=True)
class LoggedPacket:
    """One packet of the logged master, and what the servos sent back before its next."""

    t_us: int
    raw: bytes
    replies: tuple[tuple[int, bytes], ...]   # (delay after the packet's end, bytes)


class Diverged(Exception):
    """The firmware said something else than the logged master (stops the replay)."""

    def __init__(self, divergence: Divergence) -> None:
        super().__init__(divergence.topic)
        self.divergence = divergence


@dataclass(frozen=True)
class RobotLog:
    """What an imported trace holds for a replay."""

    baud: int
    model: str
    packets: tuple[LoggedPacket, ...]
    can_in: tuple[tuple[int, int, bytes], ...]     # (t_us, id, data) for the firmware
    can_out: tuple[tuple[int, int, bytes], ...]    # the logged controller's frames
    switch_t_us: tuple[int, ...]
    switch_bits: tuple[int, ...]
    end_us: int
    serial: bool = True     # the log has the servo line: the firmware's packets are compared
    can: bool = True        # the log has CAN: the firmware's frames are compared

    def switches(self, t_us: int) -> int:
        i = bisect.bisect_right(self.switch_t_us, t_us)
        return self.switch_bits[i - 1] if i else 0


def load_robot_log(path: str | Path) -> RobotLog:
    """An imported trace's line traffic, CAN and switches, for ``replay_log``."""
    with Trace(path) as tr:
        meta = tr.metadata()
        topics = set(tr.topics())
        try:
            bus = json.loads(meta.get("scenario_data", "{}")).get("bus", {})
        except ValueError:
            bus = {}
        model = bus.get("model", models.DEFAULT)
        baud = int(bus.get("baud", meta.get("baud", 1_000_000)))
        protocol = models.protocol(model)

        def wire(nbytes: int) -> int:   # the bus's wire time (hil/servobus/line.py)
            return (nbytes * US_BITS) // baud

        packets: list[list[Any]] = []
        end = 0
        for m in (tr.messages([T_SERIAL]) if T_SERIAL in topics else ()):
            s = SerialBytes.FromString(m.data)
            t = m.log_time_ns // 1000
            end = max(end, t + wire(len(s.data)))
            if s.direction == "tx":
                data = bytes(s.data)
                for off, n, _ in packet_spans(data, protocol):
                    packets.append([t + wire(off), data[off:off + n], []])
            elif packets and s.data:
                last = packets[-1]
                last[2].append((t - (last[0] + wire(len(last[1]))), bytes(s.data)))
        can_in, can_out = [], []
        for m in (tr.messages([T_CAN_RAW]) if T_CAN_RAW in topics else ()):
            f = CanFrame.FromString(m.data)
            t = m.log_time_ns // 1000
            end = max(end, t)
            (can_out if f.direction == "tx" else can_in).append(
                (t, f.arbitration_id, bytes(f.data)))
        sw_t, sw_bits = [], []
        for m in (tr.messages([T_SWITCHES]) if T_SWITCHES in topics else ()):
            e = SwitchEdge.FromString(m.data)
            sw_t.append(m.log_time_ns // 1000)
            sw_bits.append(e.switches)
            end = max(end, sw_t[-1])
    if not packets and not can_out:
        raise BadValue(f"{path}: nothing the firmware sends is logged (no master packets on "
                       f"{T_SERIAL}, no controller frames on {T_CAN_RAW}): nothing to compare")
    return RobotLog(baud, model,
                    tuple(LoggedPacket(t, raw, tuple(r)) for t, raw, r in packets),
                    tuple(can_in), tuple(can_out), tuple(sw_t), tuple(sw_bits),
                    end, T_SERIAL in topics, T_CAN_RAW in topics)


class LoggedLine(Bus):
    """The servo line with the log's servos: the firmware's packets are compared with the
    logged master's, and each matching one is answered with the logged replies."""

    def __init__(self, log: RobotLog, clock: VirtualClock) -> None:
        self.parser_class = dx2.Parser if models.protocol(log.model) == 2 else dxl.Parser
        super().__init__([], clock, baud=log.baud)
        self.log = log
        self.matched = 0
        self._names = DECODERS[models.protocol(log.model)].names
        self._table = models.table(log.model)
        self._own = self.parser_class()

    def words(self, raw: bytes) -> list[str]:
        """A packet in words, read against the log's servo model's table."""
        return self._names(raw, self._table)

    def _deliver(self, tx: bytearray, t_us: int) -> None:
        """The burst that ended at ``t_us``: each packet it completes, at its last byte."""
        p, t0 = self._own, t_us - self.wire_us(len(tx))
        for i, b in enumerate(tx):
            end_us = self.byte_end_us(t0, i)
            if p.push(b, end_us):
                self._packet(bytes(p.current().raw), end_us)

    def _packet(self, raw: bytes, t_us: int) -> None:
        if not self.log.serial:
            return   # no line in the log: nothing to compare, nobody answers
        k = self.matched
        if k == len(self.log.packets):
            return   # the log has ended: what the firmware says after it is not compared
        want = self.log.packets[k]
        if want.raw != raw:
            raise Diverged(Divergence(
                t_us / 1e6, "uart", want.raw.hex(), raw.hex(), k,
                {"expected": self.words(want.raw), "actual": self.words(raw)}))
        self.matched = k + 1
        for delay_us, data in want.replies:
            self._put(Burst(t_us + delay_us, bytearray(data), True))


class _LoggedCan(can.Listener):
    """Hears the firmware's frames and compares each with the logged controller's next."""

    def __init__(self, log: RobotLog, clock: VirtualClock) -> None:
        self.log, self.clock = log, clock
        self.matched = 0

    def on_message_received(self, msg: can.Message) -> None:
        if msg.is_rx or not self.log.can:
            return   # the log's own frames on their way to the firmware, or no CAN logged
        k = self.matched
        if k == len(self.log.can_out):
            return   # past the log's last controller frame: not compared
        want = self.log.can_out[k]
        got = (msg.arbitration_id, bytes(msg.data))
        if want[1:] != got:
            raise Diverged(Divergence(self.clock.t_us / 1e6, "can", f"C {want[1]:03X}#{want[2].hex()}",
                                      f"C {got[0]:03X}#{got[1].hex()}", k))
        self.matched = k + 1


class _LogWorld:
    """What the link server asks of a run (``rig``, ``can``, ``recorder``,
    ``firmware_port``, ``next_tick_us``), answered from the log."""

    def __init__(self, log: RobotLog) -> None:
        self.clock = VirtualClock()
        self.bus = LoggedLine(log, self.clock)
        self.rig = self
        self.can = CanBus(self.clock)
        self.firmware_port = self.can.endpoint("tx")
        self.logged_can = _LoggedCan(log, self.clock)
        self.can.add(self.logged_can)
        self._feeder = self.can.endpoint("rx", hears="rx")
        self.recorder = None
        self.log = log
        self._next_in = 0

    def next_tick_us(self) -> int | None:
        """A sleep stops at the next logged frame for the firmware, which arrives then."""
        k = self._next_in
        return self.log.can_in[k][0] if k < len(self.log.can_in) else None

    def wake(self, t_us: int) -> None:
        frames, k = self.log.can_in, self._next_in
        while k < len(frames) and frames[k][0] <= t_us:
            self._feeder.send(frames[k][1], frames[k][2])
            k += 1
        self._next_in = k


def _serve_process(server: LinkServer, python: str, log: RobotLog, world: _LogWorld,
                   tally: RunTally, result: ReplayResult, timeout_s: float,
                   theirs: Any = None) -> None:
    """A firmware in its own process (ours, or ``theirs``: a board main file, an
    executable), killed where it diverged (it waits for a reply), as hexhil replay runs it."""
    fw = FirmwareProcess(python, connect_timeout_s=timeout_s,
                         command=theirs.command() if theirs else None,
                         extra_env=theirs.env() if theirs else None)
    stopped = False
    try:
        try:
            server.serve(fw.conn, log.end_us, tally)
        except Diverged as d:
            result.divergence = d.divergence
            stopped = True
    finally:
        world.can.shutdown()
        if stopped:
            fw.kill()
            result.firmware_exit = fw.proc.returncode
        else:
            code, _, err = fw.finish(timeout_s=10.0)
            result.firmware_exit = code
            result.stderr_tail = err[-2000:]


def replay_log(path: str | Path, python: str = "micropython",
               scenario: str | Path | None = None, firmware: str | None = None,
               timeout_s: float = 60.0) -> ReplayResult:
    """Run a firmware against an imported robot log (the module docstring says how)."""
    if python not in ("micropython", "cpython"):
        raise BadValue(f"python must be micropython or cpython, not {python!r}",
                       params=("python",))
    log = load_robot_log(path)
    sc = scenario_mod.load_scenario(scenario) if scenario is not None else \
        scenario_mod.parse({"_path": str(path), "bus": {"model": log.model, "baud": log.baud}})
    world = _LogWorld(log)
    server = LinkServer(world, sc.firmware_settings(),
                        SwitchSampler(log.switches, None), world.wake, lambda: None)
    result = ReplayResult()
    tally = RunTally(python)
    wall0 = time.perf_counter()
    theirs = served_firmware(firmware) if firmware is not None else None
    if isinstance(theirs, ElfFirmware):   # the emulated board, in this process
        try:
            theirs.serve(server, log.end_us, tally)
        except Diverged as d:
            result.divergence = d.divergence
        finally:
            world.can.shutdown()
        result.firmware_exit = tally.exit_code
    else:
        _serve_process(server, python, log, world, tally, result, timeout_s, theirs)
    line, cans = world.bus, world.logged_can
    if result.divergence is None and line.matched < len(log.packets):
        want = log.packets[line.matched]
        result.divergence = Divergence(
            world.clock.t_us / 1e6, "uart", want.raw.hex(), "(nothing: firmware stopped)",
            line.matched, {"expected": line.words(want.raw), "actual": []})
    if result.divergence is None and cans.matched < len(log.can_out):
        t, arb, data = log.can_out[cans.matched]
        result.divergence = Divergence(world.clock.t_us / 1e6, "can", f"C {arb:03X}#{data.hex()}",
                                       "(nothing: firmware stopped)", cans.matched)
    result.identical = result.divergence is None
    result.exchanges = tally.round_trips
    result.compared_messages = line.matched + cans.matched
    result.extra.update(wall_s=time.perf_counter() - wall0, log=True,
                        master_packets=len(log.packets), controller_frames=len(log.can_out))
    return result
