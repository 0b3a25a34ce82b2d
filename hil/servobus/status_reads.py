"""A cycle's status reads carried out on the bus: link version 2's R (docs/link.md "R
reads"), with the SYNC_WRITE the firmware posts just before it (its W). The bus wing owns
them: each read in order, tried again while its reply is not its servo's status (the
master's own test, protocol/dynamixel/v1.py ``status_ok``) and retries are left, skipped
when the read it names did not succeed. Compiled on a plain line (reads_core.py), which
hands back what it does not serve; the link server (hil/link/server.py) only frames the
request and the reply and adds the bus time to the run's tally."""
from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Callable

from hexhil.hil.servobus import reads_core
from hexhil.hil.servobus.line import Bus
from hexhil.hil.servobus.reads_core import Handover, ReadsCore
from hexhil.protocol import sim_link
from hexhil.protocol.dynamixel import v1 as dxl


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


class StatusReads:
    """The R of one bus; ``byte_us``: a byte's wire time at the master's rate, what the
    wire time counts."""

    def __init__(self, bus: Bus) -> None:
        self.bus = bus
        self._parser = dxl.Parser()   # the master's test of a reply
        self._core = ReadsCore()
        self._busy_us = self._wire_us = 0

    def carry_out(self, payload: bytes, byte_us: float, write: bytes | None = None
                  ) -> ReadsDone:
        """The R ``payload``, after the W ``write`` where one came just before it."""
        self._busy_us = self._wire_us = 0
        out = self._core.carry_out(self.bus, payload, write)
        if out is None:
            if write is not None:
                self._write(write, byte_us)
            reply = self._attempts(self.parse(payload), 0, 0, [], bytearray(1), byte_us)
        elif out.handover is None:
            reply = out.body
        else:
            h = out.handover
            reads = self.parse(payload)
            heard = ((lambda: self._hear_reply(reads[h.r], h, byte_us))
                     if h.code == reads_core.PYTHON_REPLY else None)   # its servo answered
            reply = self._attempts(reads, h.r, h.k, h.done, h.body, byte_us, heard)
        if out is not None:
            self._busy_us += out.busy_us
            self._wire_us += out.wire_us
        return ReadsDone(reply, self._busy_us, self._wire_us)

    def _count(self, tx_bytes: int, rx: bytes, t0_us: int, byte_us: float) -> None:
        """An exchange's bus time (from ``t0_us`` to now) and wire time (what the master
        sent and heard of others, not its own echo)."""
        self._busy_us += self.bus.clock.t_us - t0_us
        heard = len(rx) - (min(tx_bytes, len(rx)) if self.bus.echo else 0)
        self._wire_us += round((tx_bytes + heard) * byte_us)

    def _write(self, data: bytes, byte_us: float) -> None:
        t0 = self.bus.clock.t_us
        self.bus.master_write(data)
        self._busy_us += self.bus.clock.t_us - t0
        self._wire_us += round(len(data) * byte_us)

    def _transact(self, tx: bytes, nrx: int, timeout_us: int, byte_us: float) -> bytes:
        t0 = self.bus.clock.t_us
        rx = self.bus.transact(tx, nrx, timeout_us)
        self._count(len(tx), rx, t0, byte_us)
        return rx

    def _hear_reply(self, read: tuple, h: Handover, byte_us: float) -> bytes:
        """What the master reads of the reply the compiled reads left on its way
        (PYTHON_REPLY), the clock at the end of its READ."""
        nrx, timeout_us, tx = read[5:]
        t0 = self.bus.clock.t_us - self.bus.wire_us(len(tx))   # the READ's start
        rx = self.bus.hear_reply(h.reply, h.start_us, nrx, timeout_us)
        self._count(len(tx), rx, t0, byte_us)
        return rx

    @staticmethod
    def parse(payload: bytes) -> list[tuple]:
        """R's reads, checked: (dev_id, nparams, retries, flags, skip, nrx, timeout_us, tx)."""
        reads, at, room = [], 1, sim_link.MAX_REPLY_LEN - 9
        for _ in range(payload[0]):
            dev_id, nparams, retries, flags, skip, nrx, timeout_us, ntx = struct.unpack_from(
                "<BBBBBHIB", payload, at)
            at += sim_link.READ_HEAD_LEN + 1
            if skip != sim_link.NO_SKIP and skip >= len(reads):
                raise MalformedReads(f"read {len(reads)} skips on read {skip}, not an "
                                     f"earlier one")
            room -= (1 + retries) * (sim_link.ATTEMPT_HEAD_LEN + nrx)
            reads.append((dev_id, nparams, retries, flags, skip, nrx, timeout_us,
                          payload[at:at + ntx]))
            at += ntx
        if at != len(payload):
            raise MalformedReads(f"malformed reads ({len(payload)} bytes, {at} announced)")
        if room < 0:
            raise MalformedReads("the reads' replies could be longer than a reply holds "
                                 f"({sim_link.MAX_REPLY_LEN})")
        return reads

    def _attempts(self, reads: list[tuple], r: int, k: int, done: list[bool | None],
                  body: bytearray, byte_us: float,
                  heard: Callable[[], bytes] | None = None) -> bytes:
        """``reads[r:]`` from attempt ``k`` of read ``r`` (its earlier ones failed), the
        outcomes of the earlier reads in ``done``, their attempts in ``body``; ``heard``:
        attempt ``k`` was begun, and this gives what the master reads of it."""
        clock = self.bus.clock
        for dev_id, nparams, retries, flags, skip, nrx, timeout_us, tx in reads[r:]:
            if skip != sim_link.NO_SKIP and done[skip] is not True:
                done.append(None)
                continue
            start = len(tx) if flags & sim_link.READ_ECHO else 0
            ok = False
            while k <= retries:
                rx = self._transact(tx, nrx, timeout_us, byte_us) if heard is None else heard()
                heard = None
                body += struct.pack("<QH", clock.t_us, len(rx)) + rx
                body[0] += 1
                ok = dxl.status_ok(self._parser, rx, start, len(rx), dev_id, nparams)
                k += 1
                if ok:
                    break
            done.append(ok)
            k = 0
        return bytes(body)
