"""Serving one firmware connection: its link requests (``protocol/sim_link.py``) become bus,
switch and CAN traffic in virtual time: UART writes and transactions go to the servo bus,
CAN frames to the run's CAN bus, events to the run result, and a sleep moves the clock,
samples the limit switches and hands over the CAN frames queued for the firmware."""
from __future__ import annotations

import json
import logging
import struct
from typing import TYPE_CHECKING, Any, Callable

from hexhil.hil.link.board_line import MISTAKES, BoardLine, set_master_baud
from hexhil.hil.canbus.bus import CanBus
from hexhil.hil.servobus.status_reads import MalformedReads, ReadsDone, StatusReads
from hexhil.hil.link.firmware_process import (
    Connection, DirectConnection, FirmwareError, LinkViolation
)
from hexhil.hil.run_result import RunTally
from hexhil.hil.seams import TraceRecorder
from hexhil.protocol import sim_link
from hexhil.protocol import link_schema as ls

if TYPE_CHECKING:   # hil/run builds the server; the server only calls it
    from hexhil.hil.run.lookahead import Lookahead

# the firmware's console as it prints (every runtime's log lines): a record each, with its
# virtual time ``t_s``; outside the ``hil`` tree, so the CLI shows it on stderr, not stdout
CONSOLE_LOG = logging.getLogger("hexhil.console")


class SwitchSampler:
    """The six limit-switch levels at each sleep; edges go to the result and the recorder."""

    def __init__(self, levels: Callable[[int], int], recorder: TraceRecorder | None) -> None:
        self.levels, self.recorder = levels, recorder
        self.bits = 0

    def sample(self, t_us: int, result: RunTally) -> int:
        bits = self.levels(t_us) & 0x3F
        changed = bits ^ self.bits
        if changed:
            for i in range(6):
                if changed & (1 << i):
                    result.switch_edges += 1
                    if self.recorder is not None:
                        self.recorder.switch_edge(t_us, i, bool(bits & (1 << i)))
        self.bits = bits
        return bits


class LinkServer:
    """Answers one firmware's requests until it closes the link."""

    def __init__(self, sim: Any, settings: dict[str, Any], switches: SwitchSampler,
                 on_wake: Callable[[int], None], on_slept: Callable[[], None],
                 lookahead: Lookahead | None = None) -> None:
        self.sim, self.settings, self.switches = sim, settings, switches
        self.on_wake, self.on_slept = on_wake, on_slept
        self.lookahead = lookahead   # the world stepping on after R's reply (a process's)
        self.bus = sim.rig.bus
        self.clock = sim.rig.clock
        self.can: CanBus = sim.can
        self.inbox = sim.firmware_port
        self.byte_us = 10_000_000 / self.bus.baud
        self._counting = False   # bus time counts from the first sleep on (boot excluded)
        self._held: list = []    # frames taken from the inbox that the last reply had no room for
        self.line: BoardLine | None = None   # the virtual board's UART, at its first line request
        self.console: Callable[[], None] | None = None  # takes what the firmware printed
        self.watch = getattr(sim, "watch", None)   # the run's limits (hil/run/limits.py)
        self.version = sim_link.VERSION      # the link version the hello agreed
        self.reads = StatusReads(self.bus)   # R: the cycle's status reads
        # timed events (T) ahead of the clock, in order: taken when the world reaches them
        self._timed: list[tuple[int, int, str, RunTally]] = []

    def _event(self, payload: bytes, result: RunTally) -> None:
        if not payload:
            raise LinkViolation("malformed event (no kind byte)")
        kind = payload[0]
        text = bytes(payload[1:]).decode("utf-8", errors="replace")
        try:
            self.take_event(kind, text, result)
        except ValueError as exc:   # JSON that does not parse
            raise LinkViolation(f"malformed event {kind}: {exc}") from None

    def _timed_event(self, payload: bytes, result: RunTally) -> None:
        """A T: the event of ``at_us`` (a console line's end on the ELF board, which the
        board may post before the host's clock gets there); held until the world reaches
        it, so that the trace, the result and the live console see it in time order. One
        of a time the host has passed (the clock runs ahead of the board by a servo reply
        it fetched) is taken at once, at its own time."""
        if len(payload) < sim_link.EVENT_AT_HEAD_LEN:
            raise LinkViolation(f"malformed timed event ({len(payload)} bytes)")
        at_us, kind = struct.unpack_from("<QB", payload, 0)
        text = bytes(payload[sim_link.EVENT_AT_HEAD_LEN:]).decode("utf-8", errors="replace")
        self._timed.append((at_us, kind, text, result))
        self.take_due(self.clock.t_us)

    def take_due(self, t_us: int) -> None:
        """The held timed events of ``t_us`` or before, each at its own time."""
        while self._timed and self._timed[0][0] <= t_us:
            at_us, kind, text, result = self._timed.pop(0)
            try:
                self.take_event(kind, text, result, at_us)
            except ValueError as exc:   # JSON that does not parse
                raise LinkViolation(f"malformed event {kind}: {exc}") from None

    def take_event(self, kind: int, text: str, result: RunTally, t_us: int | None = None
                   ) -> None:
        """An event of the firmware's (``EVENT_*`` kind) into the result and the trace, at
        ``t_us`` (the clock's time unless given)."""
        t = self.clock.t_us if t_us is None else t_us
        rec = self.sim.recorder
        if kind == sim_link.EVENT_EXCEPTION:
            result.exceptions.append(text)
            if rec is not None:
                rec.fault(t, "firmware_exception", text)
        elif kind == sim_link.EVENT_STOP:
            result.stop_reason = text
            if rec is not None:
                rec.fault(t, "safe_stop", text)
        elif kind == sim_link.EVENT_STATS:
            stats = json.loads(text)
            if not isinstance(stats, dict):
                raise ValueError("the stats are not a JSON object")
            result.firmware = stats
        elif kind == sim_link.EVENT_TACTILE:
            ev = json.loads(text)
            ev[ls.T_S] = t * 1e-6
            result.tactile_events.append(ev)
            if rec is not None:
                rec.telemetry(t, ev)
        elif kind == sim_link.EVENT_FAULT:   # a mistake the client's board saw: a run fault
            fault = json.loads(text)
            if not isinstance(fault, dict):
                raise ValueError("a fault event is not a JSON object")
            self.run_fault(str(fault.get(ls.NAME, "firmware_fault")),
                           str(fault.get(ls.DETAIL, "")), result, t)
        else:
            if kind == sim_link.EVENT_LOG:
                result.console_line(t * 1e-6, text)
                CONSOLE_LOG.info(text, extra={"t_s": t * 1e-6})
            if rec is not None:
                rec.telemetry(t, {"event": kind, "text": text})

    def run_fault(self, name: str, detail: str, result: RunTally, t_us: int | None = None
                  ) -> None:
        """A fault of the run now (or at ``t_us``): counted, recorded, and a direction
        mistake (the virtual board's, or one a C SDK's board saw) handed to the master
        check if one watches."""
        t = self.clock.t_us if t_us is None else t_us
        result.count_fault(name)
        if self.sim.recorder is not None:
            self.sim.recorder.fault(t, name, detail)
        check = getattr(self.bus, "monitor", None)
        if check is not None and name in MISTAKES:
            check.direction_mistake(t, name, detail)

    def _can_from_firmware(self, payload: bytes, result: RunTally) -> None:
        if len(payload) < 3 or payload[2] > sim_link.CAN_MAX_DLC or len(payload) != 3 + payload[2]:
            raise LinkViolation(f"malformed CAN message ({len(payload)} bytes)")
        arb_id, dlc = struct.unpack_from("<HB", payload, 0)
        result.count_can(arb_id)
        self.inbox.send_frame(arb_id, bytes(payload[3:3 + dlc]))

    def _can_records(self) -> tuple[int, bytes]:
        """(flags, u8 n + records) of the frames queued for the client, as many as one
        reply holds; FLAG_MORE when some are left (the client asks with OP_MORE)."""
        frames = self._held
        if not frames and self.inbox.buffer.empty():   # most sleeps: none (~1.5 us less)
            return 0, b"\0"
        limit = sim_link.MAX_CAN_PER_REPLY
        frames += self.inbox.frames(limit + 1 - len(frames))
        self._held = frames[limit:]
        body = bytearray((min(len(frames), limit),))
        for msg in frames[:limit]:
            body += struct.pack("<HB", msg.arbitration_id, msg.dlc) + \
                bytes(msg.data).ljust(8, b"\0")
        return (sim_link.FLAG_MORE if self._held else 0), bytes(body)

    def idle_to(self, wake_us: int) -> None:
        """The line idles to ``wake_us``, stopping at each host node's tick on the way
        (docs/api.md ``HostNode``); then ``on_wake`` at the wake."""
        clock, bus, next_tick = self.clock, self.bus, self.sim.next_tick_us
        while True:
            due = next_tick()
            if due is None or due >= wake_us:
                break
            self._idle_line(due)
            self.on_wake(clock.t_us)
        self._idle_line(wake_us)
        self.on_wake(clock.t_us)

    def _idle_line(self, t_us: int) -> None:
        """The line idles to ``t_us``, taking the held timed events on the way."""
        timed, clock = self._timed, self.clock
        while timed and timed[0][0] < t_us:
            if timed[0][0] > clock.t_us:
                self.bus.idle_until(timed[0][0])
            self.take_due(clock.t_us)
        if t_us > clock.t_us:
            self.bus.idle_until(t_us)

    def _sleep_reply(self, wake_us: int, end_us: int, result: RunTally) -> tuple[bytes, bool]:
        flags = 0
        ended = wake_us >= end_us
        if ended:
            wake_us = end_us
            flags |= sim_link.FLAG_END
        self.idle_to(wake_us)
        bits = self.switches.sample(self.clock.t_us, result)
        body = b"\0"
        if not ended:
            self.can.poll()
            more, body = self._can_records()
            flags |= more
        return struct.pack("<BB", flags, bits) + body, ended

    def _hello_reply(self, payload: bytes, result: RunTally) -> bytes:
        """The hello's reply in the version the client offers: the host speaks both."""
        if not payload or payload[0] not in sim_link.VERSIONS:
            raise LinkViolation(f"link version mismatch: the firmware speaks version "
                                f"{payload[0] if payload else 'none'}, this host speaks "
                                f"{' and '.join(str(v) for v in sim_link.VERSIONS)}")
        self.version = payload[0]
        bad = ls.problems(self.settings, ls.CONFIG)
        if bad:
            raise LinkViolation(f"the config does not fit protocol/link_schema.py: {bad[0]}")
        config = json.dumps(self.settings, sort_keys=True).encode()
        if len(config) + 10 > sim_link.MAX_REPLY_LEN:
            raise LinkViolation(f"the config is {len(config)} bytes of JSON: the hello reply "
                                f"holds {sim_link.MAX_REPLY_LEN - 10}")
        return struct.pack("<BB", self.version,
                           self.switches.sample(self.clock.t_us, result)) + config

    def _transact(self, tx: bytes, nrx: int, timeout_us: int, result: RunTally) -> bytes:
        """An X: ``tx`` on the servo line, then up to ``nrx`` bytes read within the time-out,
        carried out by the bus wing (hil/servobus/status_reads.py); its bus time counts."""
        return self._counted(self.reads.transact(tx, nrx, timeout_us, self.byte_us), result)

    def _write(self, data: bytes, result: RunTally) -> None:
        """A W with no R after it: the bytes on the servo line; its bus time counts."""
        self._counted(self.reads.write(data, self.byte_us), result)

    def _counted(self, done: ReadsDone, result: RunTally) -> bytes:
        """An exchange's bus time and wire time, once counting; its reply."""
        if self._counting:
            result.bus_busy_us += done.busy_us
            result.bus_wire_us += done.wire_us
        return done.reply

    def _reads(self, payload: bytes, result: RunTally, write: bytes | None = None) -> bytes:
        """Link version 2's R, after ``write`` (the W just before it, if one was): carried
        out by the bus wing (hil/servobus/status_reads.py); its bus time counts."""
        try:
            return self._counted(self.reads.carry_out(payload, self.byte_us, write), result)
        except MalformedReads as exc:
            raise LinkViolation(str(exc)) from None

    def serve(self, conn: Connection, end_us: int, result: RunTally) -> None:
        """Answer a socket connection's batches until the firmware closes it."""
        while True:
            try:
                msgs, closed = conn.batch()
            except LinkViolation as exc:   # more posted than a batch holds
                conn.reply_error(str(exc))
                raise FirmwareError(f"firmware link: {exc}") from None
            if self.answer(conn, msgs, closed, end_us, result):
                return

    def answer(self, conn: Connection | DirectConnection, msgs: list[tuple[int, bytes]],
               closed: bool, end_us: int, result: RunTally) -> bool:
        """Carry out one batch (posted messages, then the request) and reply to it; True once
        the firmware has closed the link. A message the host cannot carry out (unknown op,
        malformed, another link version): an error reply and FirmwareError (docs/link.md)."""
        try:
            return self._answer(conn, msgs, closed, end_us, result)
        except (LinkViolation, struct.error) as exc:
            text = f"malformed message: {exc}" if isinstance(exc, struct.error) else str(exc)
            if not closed:
                conn.reply_error(text)
            raise FirmwareError(f"firmware link: {text}") from None

    def _answer(self, conn: Connection | DirectConnection, msgs: list[tuple[int, bytes]],
                closed: bool, end_us: int, result: RunTally) -> bool:
        clock, rec = self.clock, self.sim.recorder
        if self.console is not None:   # what it printed since the last reply: of that time
            self.console()
        reply, slept, reads = None, False, False
        if self.lookahead is not None:
            self.lookahead.settle(msgs)
        write = None   # a W carried out with the R right after it (``_reads``)
        last = len(msgs) - 1
        for i, (op, payload) in enumerate(msgs):
            if op == sim_link.OP_WRITE:
                if (i < last and msgs[i + 1][0] == sim_link.OP_READS
                        and self.version == sim_link.VERSION_READS):
                    write = payload
                else:
                    self._write(payload, result)
            elif op == sim_link.OP_TRANSACT:
                nrx, timeout_us = struct.unpack_from("<HI", payload, 0)
                if nrx > sim_link.MAX_RX_LEN:
                    raise LinkViolation(f"a transact asks for {nrx} bytes, more than a reply "
                                        f"holds ({sim_link.MAX_RX_LEN})")
                reply = self._transact(payload[6:], nrx, timeout_us, result)
            elif op == sim_link.OP_READS and self.version == sim_link.VERSION_READS:
                reply = self._reads(payload, result, write)
                write = None
                reads = True
            elif op == sim_link.OP_CAN:
                self._can_from_firmware(payload, result)
            elif op == sim_link.OP_EVENT:
                self._event(payload, result)
            elif op == sim_link.OP_EVENT_AT:
                self._timed_event(payload, result)
            elif op == sim_link.OP_SLEEP:
                if len(payload) != 8:
                    raise LinkViolation(f"malformed sleep ({len(payload)} bytes, not 8)")
                (wake_us,) = struct.unpack_from("<Q", payload, 0)
                if self._counting:
                    result.loop_cycles += 1
                self._counting = True
                if self.line is not None:
                    self.line.active()
                reply, _ = self._sleep_reply(wake_us, end_us, result)
                slept = True
            elif op == sim_link.OP_MORE:
                more, body = self._can_records()
                reply = struct.pack("<BB", more, self.switches.bits) + body
            elif op in (sim_link.OP_LINE, sim_link.OP_DIRECTION):
                if self.line is None:
                    self.line = BoardLine(self)
                if op == sim_link.OP_LINE:
                    reply = self.line.answer(payload, end_us, result)
                else:
                    self.line.turn(payload, end_us, result)
            elif op == sim_link.OP_BAUD:
                set_master_baud(self, payload, result)
            elif op == sim_link.OP_HELLO:
                reply = self._hello_reply(payload, result)
            else:
                raise LinkViolation(f"unknown message op 0x{op:02x}")
        if self._timed:   # those the request's bus time passed; at the end, all
            self.take_due(sim_link.ERROR_T_US if closed else clock.t_us)
        # Recording comes after the reply: the clock stays until the firmware's next
        # batch, so the recorder's work overlaps the firmware's instead of delaying it; so
        # does the world's stepping ahead after R (hil/run/lookahead.py), which records
        # nothing and leaves the clock where it is.
        raw = conn.reply(clock.t_us, reply) if reply is not None and not closed else None
        if slept:
            self.on_slept()
        if reads and raw is not None and self.lookahead is not None:
            self.lookahead.step(end_us)
        if rec is not None and raw is not None:
            rec.link(clock.t_us, bytes(conn.raw), raw)
            rec.work_while(lambda: not conn.answered())   # until the next batch is in
        if closed:
            result.round_trips = conn.round_trips
        return closed
