"""A cycle's status reads carried out on the bus: link version 2's R (docs/link.md "R
reads"), with the SYNC_WRITE the firmware posts just before it (its W). The bus wing owns
them; their rules (the R's check, each read in order, tried again while its reply is not
its servo's status and retries are left, skipped when the read it names did not succeed,
the reply's packing, the bus and wire time) are compiled, hil/servobus/reads_core.c
``hx_reads``. It carries a plain line's attempts out itself and hands every other one to
the line (``Bus.transact``: ``master_write`` then ``master_read``), whose reply the master
tests with its own rule (protocol/dynamixel/v1.py ``status_ok``). An X (one transaction)
and a W with no R after it go the same way, as an R of one read without retries and an R
of none. The link server (hil/link/server.py) only frames the request and the reply and
adds the bus time to the run's tally.

The bytes the C code heard reach ``on_bytes`` in order, in one call at each hand-back: on
a plain line nothing else records while the world steps (no fault, no monitor), so the
calls' order is the same as byte by byte, for one call a cycle instead of one a step."""
from __future__ import annotations

import ctypes
import struct
from dataclasses import dataclass

from hexhil.hil.servobus import serial_stream, servo_rules
from hexhil.hil.servobus.line import Bus
from hexhil.hil.servobus.servo_core import ServoBank
from hexhil.hil.servobus.servo_layout import LAYOUT, MALFORMED_WHY, READS_ANSWERS
from hexhil.protocol import sim_link
from hexhil.protocol.dynamixel import v1 as dxl

DONE, ADVANCE, ATTEMPT, HEAR, WRITE, WRITE_LEFT, MALFORMED = range(len(READS_ANSWERS))
WHY_LENGTH, WHY_SKIP, WHY_ROOM = range(1, len(MALFORMED_WHY) + 1)
_READ_HEAD = struct.Struct("<BBBBBHIB")   # a read of R, up to its tx (protocol/sim_link.py)
_NO_STEP_US = 2 ** 62                      # no world step the C code must stop for


class MalformedReads(ValueError):
    """An R the host cannot carry out: its reads announce more bytes than it holds, skip on
    a later read, or could reply with more than a reply holds."""


@dataclass(frozen=True)
class ReadsDone:
    """R's reply (after its ``t_us``) and the bus time and wire time the W and the
    attempts took."""

    reply: bytes
    busy_us: int
    wire_us: int


class _Reads(ctypes.Structure):
    _fields_ = LAYOUT.fields("reads")


def _load():
    lib = servo_rules.library()   # missing: servo_rules refuses every servo in one line
    if lib is None:
        return None
    fn = lib.hx_reads
    fn.argtypes, fn.restype = [ctypes.c_void_p], ctypes.c_int
    return fn


_HX_READS = _load()


class StatusReads:
    """The R of one bus."""

    def __init__(self, bus: Bus) -> None:
        self.bus = bus
        self._parser = dxl.Parser()   # the master's test of a reply
        self._s = _Reads()
        self._bank: ServoBank | None = None   # the one the C code was last given
        self._ref = ctypes.addressof(self._s)
        self._body, self._log, self._lens, self._reply = (
            self._ref + getattr(_Reads, f).offset for f in ("body", "log", "lens", "reply"))

    def carry_out(self, payload: bytes, byte_us: float, write: bytes | None = None
                  ) -> ReadsDone:
        """The R ``payload``, after the W ``write`` where one came just before it;
        ``byte_us``: a byte's wire time at the master's rate, what the wire time counts."""
        return self._carry_out(payload, byte_us, write, False)

    def transact(self, tx: bytes, nrx: int, timeout_us: int, byte_us: float) -> ReadsDone:
        """An X (docs/link.md): ``tx`` out, then up to ``nrx`` bytes heard within
        ``timeout_us``, one attempt of a read with no retry; its reply is what was heard."""
        head = _READ_HEAD.pack(0, 0, 0, 0, sim_link.NO_SKIP, nrx, timeout_us, 0)
        done = self._carry_out(b"\x01" + head + tx, byte_us, None, True)
        return ReadsDone(done.reply[1 + sim_link.ATTEMPT_HEAD_LEN:], done.busy_us,
                         done.wire_us)

    def write(self, data: bytes, byte_us: float) -> ReadsDone:
        """A W with no R after it: an R of no reads."""
        return self._carry_out(b"\x00", byte_us, data, False)

    def _carry_out(self, payload: bytes, byte_us: float, write: bytes | None, one: bool
                   ) -> ReadsDone:
        if _HX_READS is None:
            servo_rules.require()
        s, bus = self._s, self.bus
        s.payload, s.len, s.one = payload, len(payload), one
        s.write, s.write_len = write, len(write) if write is not None else 0
        s.byte_us, s.echo = byte_us, bus.echo
        delay = bus.return_delay_override_us
        s.delay_override_us = -1 if delay is None else delay
        s.t_us = bus.clock.t_us
        s.at = 0   # the C code starts over: its counters, the W, the first read
        self._bind()
        while True:
            code = _HX_READS(self._ref)
            if code == ADVANCE:   # the world steps
                bus.idle_until(s.t_us)
                s.next_step_us = self._bank.next_step_us()
                continue
            if code == MALFORMED:
                if write is not None:
                    bus.master_write(write)   # the W is carried out all the same
                raise MalformedReads(self._why(len(payload)))
            self._heard()
            bus.idle_until(s.t_us)   # the clock to where the C code is
            if code == DONE:
                break
            if code == WRITE:
                bus.master_write(write)
            elif code == WRITE_LEFT:
                if self._bank.finish_sync_write(s.i, write[5:-1], s.t_us):
                    bus._reindex()   # an ID or baud changed
            else:
                self._attempt(payload, code == HEAR)
            s.t_us = bus.clock.t_us
            self._bind()
        stats = bus.stats
        stats["tx_bytes"] += s.tx_bytes
        stats["rx_bytes"] += s.rx_bytes
        stats["packets"] += s.packets
        stats["replies"] += s.replies
        return ReadsDone(ctypes.string_at(self._body, s.body_len), s.busy_us, s.wire_us)

    def _bind(self) -> None:
        """Whether the C code may carry attempts out (a plain line whose world steps by its
        own ``advance``), and the bank it reads."""
        s, bus = self._s, self.bus
        bank = bus.servo_bank
        s.fast = fast = (bank is not None and bank.next_step_us is not None
                         and bus.advance == bank.advance and bus.plain())
        if not fast:
            s.next_step_us = _NO_STEP_US
            return
        if bank is not self._bank:   # the first R, or the line re-indexed
            self._bank = bank
            s.bank, s.index, s.changed = bank.ref, bank.by_id_address, bank.changed_address
        s.baud = bus.baud
        s.next_step_us = bank.next_step_us()

    def _attempt(self, payload: bytes, hear: bool) -> None:
        """The attempt the C code left to the line, from its start or (``hear``) from the
        end of its READ, its servo having answered; what the master heard goes into the
        reply after its head, with whether it passed the master's test."""
        s, bus = self._s, self.bus
        dev_id, nparams, _, flags, _, nrx, timeout_us, _ = _READ_HEAD.unpack_from(
            payload, s.at)
        if hear:
            rx = bus.hear_reply(ctypes.string_at(self._reply, s.m), s.start_us, nrx,
                                timeout_us)
        else:
            tx_at = s.at + _READ_HEAD.size
            rx = bus.transact(payload[tx_at:tx_at + s.ntx], nrx, timeout_us)
        if not s.one:   # an X is not retried: nothing asks how it went
            start = s.ntx if flags & sim_link.READ_ECHO else 0
            s.ok = dxl.status_ok(self._parser, rx, start, len(rx), dev_id, nparams)
        s.m = len(rx)
        ctypes.memmove(self._body + s.body_len + sim_link.ATTEMPT_HEAD_LEN, rx, len(rx))

    def _why(self, n: int) -> str:
        s = self._s
        if s.why == WHY_SKIP:
            return f"read {s.r} skips on read {s.i}, not an earlier one"
        if s.why == WHY_ROOM:
            return ("the reads' replies could be longer than a reply holds "
                    f"({sim_link.MAX_REPLY_LEN})")
        return f"malformed reads ({n} bytes, {s.at} announced)"

    def _heard(self) -> None:
        """The bytes on the wire since the last call, to the bus's ``on_bytes`` in order:
        in one call where it takes a stream."""
        s, on_bytes = self._s, self.bus.on_bytes
        n = s.log_len
        if on_bytes is None or not n:
            return
        stream, lens = ctypes.string_at(self._log, n), ctypes.string_at(self._lens, s.nrec)
        s.log_len = s.nrec = 0
        many = getattr(on_bytes, "stream", None)
        if many is not None:
            many(stream, lens)
            return
        for t_us, direction, data in serial_stream.records(stream, lens):
            on_bytes(t_us, direction, data)
