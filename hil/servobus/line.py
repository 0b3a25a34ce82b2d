"""A half-duplex TTL serial line carrying bytes between one master and AX-12 servos.

Lockstep, in virtual integer microseconds on a ``hil.clock.VirtualClock``: no threads,
no sleeps, no wall clock. The master's bytes take wire time (10 bits a byte at the
baud); each servo parses the line, answers after its Return Delay Time, and its status
bytes take wire time too. Bytes that overlap on the line (the master talking while a
servo answers, two servos answering at once) are corrupted for everyone: the line is
modelled as a wired AND, the idle-high level losing to any driven low bit. A servo at
another baud decodes the master's bits with its own UART timing (``resample``), which
yields the garbage a real mismatch does. With ``echo`` the master also hears its own
bytes, as on a single-wire adapter.

Exact accounting: a 2-byte READ (8 bytes out) answered after Return Delay 250 (500 us)
with 8 bytes costs 80 + 500 + 80 us at 1 Mbps.
"""
from __future__ import annotations

from typing import Callable, Iterable

from hexhil.hil.clock import VirtualClock
from hexhil.hil.servobus.ax12_servo import Servo
from hexhil.hil.servobus.servo_core import ServoBank
from hexhil.hil.servobus.wire import US_BITS, Burst, and_overlap, merge_burst, resample
from hexhil.protocol.dynamixel import v1 as dxl

OnBytes = Callable[[int, str, bytes], None]
Advance = Callable[[int], None]


class Bus:
    """The line, its servos and the master's receive FIFO; see the module docstring."""

    protocol = 1  # Dynamixel Protocol 1.0 (hil/servobus/protocols/v2.py: 2.0)
    parser_class = dxl.Parser

    def __init__(self, servos: Iterable[Servo], clock: VirtualClock, baud: int = 1_000_000,
                 echo: bool = False, faults=None, on_bytes: OnBytes | None = None,
                 advance: Advance | None = None) -> None:
        if baud <= 0:
            raise ValueError(f"baud must be positive, got {baud}")
        self.servos = list(servos)
        self.clock = clock
        self.baud = int(baud)
        self.echo = echo
        self.faults = faults
        self.on_bytes = on_bytes
        self.advance = advance
        self.monitor = None              # hil/servobus/master_check.py: sees what the master sends
        # Timing-margin hooks (hexhil margin; off by default): the master sees a byte this
        # long after it arrived (a USB adapter's latency timer); every servo answers after
        # this delay whatever its register 5 holds (a configure write that did not take).
        self.rx_latency_us = 0
        self.return_delay_override_us: int | None = None
        self._rx: list[Burst] = []     # heard by the master, oldest first, never overlapping
        self._own_rules = all(getattr(type(self), f) is getattr(Bus, f) for f in (  # not Bus2's
            "master_write", "master_read", "_deliver", "_dispatch", "_schedule", "_move_to"))
        self._parser = self.parser_class()
        self._off: set[int] = set()      # id(servo) of unplugged servos
        self.missing_ids: set[int] = set()   # IDs packets went to that no servo has
        self.stats = {"tx_bytes": 0, "rx_bytes": 0, "packets": 0, "replies": 0,
                      "collisions": 0, "bad_checksum": 0}
        self._reindex()
        if faults is not None:
            faults.attach(self)

    # --- wiring ---------------------------------------------------------------------
    def _reindex(self) -> None:
        self._by_id: dict[int, list[Servo]] = {}
        self._same: list[Servo] = []
        self._foreign: list[tuple[Servo, dxl.Parser]] = []
        for s in self.servos:
            s.address_changed = False
            if s.baud_bps == self.baud:
                self._same.append(s)
                self._by_id.setdefault(s.id, []).append(s)
            else:
                self._foreign.append((s, self.parser_class()))
        self.servo_bank = ServoBank.build(self._same, Servo)

    def add_device(self, device) -> None:
        """Another Protocol 1.0 device on the line (hil/servobus/switch_node.py), served like a servo."""
        self.servos.append(device)
        self._reindex()

    def servo(self, dev_id: int) -> Servo | None:
        """The first servo configured with ``dev_id`` (whatever its baud)."""
        for s in self.servos:
            if s.id == dev_id:
                return s
        return None

    def set_plugged(self, servo: Servo, plugged: bool, t_us: int) -> None:
        """Unplug a servo (it hears and says nothing); plugging it back power-cycles it."""
        if plugged:
            if id(servo) in self._off:
                self._off.discard(id(servo))
                servo.power_cycle(t_us)
                self._reindex()
        else:
            self._off.add(id(servo))

    # --- time -----------------------------------------------------------------------
    def set_master_baud(self, baud: int) -> None:
        """The master's UART runs at ``baud`` (a clock error): servos at another rate now
        decode its bytes, and it theirs, with their own timing (``resample``)."""
        self.baud = int(baud)
        self._reindex()

    def byte_end_us(self, start_us: int, i: int) -> int:
        """When byte ``i`` of a burst starting at ``start_us`` has fully arrived."""
        return start_us + ((i + 1) * US_BITS) // self.baud

    def wire_us(self, nbytes: int) -> int:
        return (nbytes * US_BITS) // self.baud

    def _move_to(self, t_us: int) -> None:
        clock = self.clock
        if t_us <= clock.t_us:
            return
        faults = self.faults
        while faults is not None and faults.next_us <= t_us:
            te = faults.next_us
            if te > clock.t_us:
                clock.advance_to(te)
                if self.advance is not None:
                    self.advance(te)
            faults.apply_due(te)
        clock.advance_to(t_us)
        if self.advance is not None:
            self.advance(t_us)
        if self.on_bytes is not None:
            for b in self._rx:
                if not b.emitted and b.reply and self.byte_end_us(b.start_us, len(b.data) - 1) <= t_us:
                    b.emitted = True
                    self.on_bytes(b.start_us, "rx", bytes(b.data))

    def idle_until(self, t_us: int) -> None:
        """Let the line stay idle until t_us (servos keep moving, faults keep firing)."""
        self._move_to(int(t_us))

    # --- master side ----------------------------------------------------------------
    def master_write(self, data: bytes) -> None:
        """Send bytes now; returns when the last has left (the clock moves by wire time)."""
        if not data:
            return
        t0 = self.clock.t_us
        if self.monitor is not None:
            self.monitor.master_bytes(self, t0, data)
        tx = bytearray(data)
        faults = self.faults
        if faults is not None:
            faults.corrupt(tx, t0, "tx")
        t1 = t0 + self.wire_us(len(tx))
        if self._rx and and_overlap(self._rx, tx, t0, t1, self.baud):  # the wired AND
            self._collision(t0, "master talked over a servo's reply")
        self.stats["tx_bytes"] += len(tx)
        if self.on_bytes is not None:
            self.on_bytes(t0, "tx", bytes(tx))
        if self.echo:
            self._put(Burst(t0, bytearray(tx), False))
        self._move_to(t1)
        self._deliver(tx, t1)
        for s, parser in self._foreign:
            if id(s) not in self._off:
                self._deliver_foreign(s, parser, tx, t1)

    def master_read(self, n: int, timeout_us: int) -> bytes:
        """Up to n bytes heard before now + timeout_us; the clock moves to the n-th byte's
        arrival, or to the deadline when fewer came."""
        deadline = self.clock.t_us + int(timeout_us)
        out = bytearray()
        t_last = deadline
        rx = self._rx
        lat = self.rx_latency_us
        while rx and len(out) < n:
            b = rx[0]
            data = b.data
            i = b.read
            j = min(len(data), i + n - len(out))
            if j > i and self.byte_end_us(b.start_us, j - 1) + lat <= deadline:
                out += data[i:j]   # the whole packet at once: its last byte is in time
                t_last = self.byte_end_us(b.start_us, j - 1) + lat
                i = j
            while i < len(data) and len(out) < n:
                t = self.byte_end_us(b.start_us, i) + lat
                if t > deadline:
                    break
                out.append(data[i])
                t_last = t
                i += 1
            b.read = i
            if i < len(data):
                break
            if b.reply and not b.emitted and self.on_bytes is not None:
                b.emitted = True
                self.on_bytes(b.start_us, "rx", bytes(data))
            rx.pop(0)
        self.stats["rx_bytes"] += len(out)
        self._move_to(t_last if len(out) >= n else deadline)
        return bytes(out)

    def transact(self, tx: bytes, nrx: int, timeout_us: int) -> bytes:
        """``master_write(tx)`` then ``master_read(nrx, timeout_us)``."""
        self.master_write(tx)
        return self.master_read(nrx, timeout_us)

    def hear_reply(self, reply: bytes, start_us: int, nrx: int, timeout_us: int) -> bytes:
        """``master_read(nrx, timeout_us)`` of a servo's status sent from ``start_us`` onto a
        plain line, the clock at the end of its READ (the compiled status reads' attempt,
        status_reads.py): whole and in time, here."""
        m, deadline = len(reply), self.clock.t_us + int(timeout_us)
        t_last = start_us + self.wire_us(m)
        if m > nrx or t_last > deadline:   # bytes left on the line, or a reply cut off
            self._put(Burst(start_us, bytearray(reply), True))
            return self.master_read(nrx, timeout_us)
        self.stats["rx_bytes"] += m
        if self.on_bytes is not None:
            self.on_bytes(start_us, "rx", reply)
        self._move_to(t_last if m == nrx else deadline)
        return reply

    def plain(self) -> bool:
        """Nothing on the line and no fault, hook or other class's rule in play: a READ's
        reply is worked out without the parser and the bursts (hil/servobus/reads_core.c)."""
        return not (self._rx or not self._own_rules or self.faults is not None or self.echo
                    or self.monitor is not None or self._foreign or self._off
                    or self.rx_latency_us or self.servo_bank is None or self._parser.pending())

    def next_rx_us(self) -> int | None:
        """When the burst now arriving has fully arrived (real-time server), or None. (A
        burst leaves ``_rx`` once read whole: every one there has bytes unread.)"""
        return self.byte_end_us(self._rx[0].start_us, len(self._rx[0].data) - 1) \
            if self._rx else None

    def reply_end_us(self) -> int | None:
        """When the last status the master has not fully read will have arrived, or None."""
        ends = [self.byte_end_us(b.start_us, len(b.data) - 1) for b in self._rx if b.reply]
        return max(ends) if ends else None

    def next_bytes(self) -> tuple[int | None, int]:
        """When the next byte the master has not read will have arrived (None: no byte on
        its way), and how many bytes its burst holds from it on, back to back (the
        virtual board's UART, hil/link/board_line.py, counts them itself instead of asking)."""
        if not self._rx:
            return None, 0
        b = self._rx[0]
        return self.byte_end_us(b.start_us, b.read) + self.rx_latency_us, len(b.data) - b.read

    def master_discard(self) -> int:
        """Drop the bytes that have arrived by now unread (the master's receiver was off);
        returns how many of them were status bytes (echoed bytes are not counted)."""
        now, rx, lost = self.clock.t_us, self._rx, 0
        while rx:
            b = rx[0]
            i = b.read
            while i < len(b.data) and self.byte_end_us(b.start_us, i) + self.rx_latency_us <= now:
                i += 1
            if b.reply:
                lost += i - b.read
            b.read = i
            if i < len(b.data):
                break
            if b.reply and not b.emitted and self.on_bytes is not None:
                b.emitted = True
                self.on_bytes(b.start_us, "rx", bytes(b.data))
            rx.pop(0)
        return lost

    # --- the line -------------------------------------------------------------------
    def _put(self, burst: Burst) -> None:
        """Add a burst to what the master hears, merging (AND) any overlap."""
        if merge_burst(self._rx, burst, self.baud):  # echo over a reply: counted in master_write
            self._collision(burst.start_us, "two servos answered at once")

    def _collision(self, t_us: int, detail: str) -> None:
        self.stats["collisions"] += 1
        if self.faults is not None:
            self.faults.report(t_us, "collision", detail)

    def _deliver(self, tx: bytearray, t_us: int) -> None:
        """Servos at the line's baud parse the bytes that ended at t_us. Whole valid
        packets at the start (a SYNC_WRITE and a READ sent back to back) are taken at once,
        as the parser would take them byte by byte; the rest goes through the parser."""
        parser = self._parser
        n = len(tx)
        at = 0
        while (parser.pending() == 0 and n - at >= 6 and tx[at] == 0xFF
               and tx[at + 1] == 0xFF and tx[at + 2] != 0xFF and tx[at + 3] >= 2
               and at + tx[at + 3] + 4 <= n):
            end = at + tx[at + 3] + 4
            if (~sum(tx[at + 2:end - 1])) & 0xFF != tx[end - 1]:
                break
            self.stats["packets"] += 1
            self._dispatch(tx[at + 2], tx[at + 4], bytes(tx[at + 5:end - 1]), t_us)
            at = end
        if at == n:
            return
        if at:
            tx = tx[at:]
        bad = parser.bad_checksum
        for byte in tx:
            if parser.push(byte, t_us):
                self.stats["packets"] += 1
                self._dispatch(parser.id, parser.code,
                               bytes(parser.buf[5:5 + parser.nparams]), t_us)
            elif parser.bad_checksum != bad:
                bad = parser.bad_checksum
                self.stats["bad_checksum"] += 1
                # the rejected packet's first byte was dropped: ID now at 1, INSTR at 3
                for s in self._by_id.get(parser.last_bad_checksum_id, ()):
                    if id(s) not in self._off:
                        self._schedule(s, s.checksum_error(parser.buf[3], t_us), t_us)

    def _dispatch(self, dev_id: int, code: int, params: bytes, t_us: int) -> None:
        if dev_id == dxl.BROADCAST_ID:
            if code == dxl.SYNC_WRITE and self.servo_bank is not None and not self._off:
                if self.servo_bank.sync_write(params, t_us):   # an ID or baud changed
                    self._reindex()
                return
            targets = self._same
        else:
            targets = self._by_id.get(dev_id)
            if not targets:
                self.missing_ids.add(dev_id)
                return
        off = self._off
        changed = False
        bank = self.servo_bank
        for s in targets:
            if off and id(s) in off:
                continue
            reply = False if bank is None or code != dxl.READ or dev_id == dxl.BROADCAST_ID \
                else bank.read(s, params, t_us)   # False: the servo's own handle answers
            if reply is False:
                reply = s.handle(code, params, dev_id == dxl.BROADCAST_ID, t_us)
            if reply is not None:
                self._schedule(s, reply, t_us)
            changed = changed or s.address_changed
        if changed:
            self._reindex()

    def _deliver_foreign(self, s: Servo, parser: dxl.Parser, tx: bytearray, t_us: int) -> None:
        """A servo at another baud decodes the line with its own UART timing."""
        bad = parser.bad_checksum
        for byte in resample(tx, self.baud, s.baud_bps):
            reply = None
            if parser.push(byte, t_us):
                dev_id = parser.id
                if dev_id != s.id and dev_id != dxl.BROADCAST_ID:
                    continue
                reply = s.handle(parser.code, bytes(parser.buf[5:5 + parser.nparams]),
                                 dev_id == dxl.BROADCAST_ID, t_us)
            elif parser.bad_checksum != bad:
                bad = parser.bad_checksum
                if parser.last_bad_checksum_id == s.id:
                    reply = s.checksum_error(parser.buf[3], t_us)
            if reply is not None:
                self._schedule(s, resample(reply, s.baud_bps, self.baud), t_us)
            if s.address_changed:
                self._reindex()
                return

    def _schedule(self, s: Servo, reply: bytes | None, t_us: int) -> None:
        if not reply:
            return
        faults, data, delay = self.faults, bytearray(reply), self.return_delay_override_us
        start = t_us + (s.return_delay_us if delay is None else delay)
        bursts = [(start, data)]
        if faults is not None:
            if faults.drop_status(s.id, start):
                return
            faults.corrupt(data, start, "rx")
            bursts = faults.status_bursts(s.id, data, start, self.wire_us(len(data)), 1)
        for t, burst in bursts:   # none, one, or a twin's too ([faults] status_*)
            self.stats["replies"] += 1
            self._put(Burst(t, burst, True))
