"""A cycle's status reads compiled (hil/servobus/reads_core.c ``hx_reads``), through ctypes.

Link version 2 hands the host a cycle's status reads in one message, R; the general path
(hil/servobus/status_reads.py) carries each attempt out through ``Bus.transact``, tests
its reply with the master's own rule and packs it: about 60 us of a 930 us in-process
cycle, half of it left compiled (docs/performance.md). The SYNC_WRITE the
firmware sends just before, in the same batch (its W), goes with them: ``Bus.master_write``
and the servos' taking it cost about 5 us more a cycle in Python. On a plain line
(``Bus.plain``) whose world steps by its own ``advance_to``, the C code does the same from
the payload to the reply, stopping for the world's physics steps and handing back to the
general path wherever it does not serve an attempt. The bytes heard reach ``on_bytes``, in
order, as the bus hands them over, in one call where the C code hands back: on a plain
line nothing else records while the world steps (no fault, no monitor), so the calls'
order is the same as byte by byte, for one call a cycle instead of one a step. The same bytes
and times (tests/test_reads_core.py, and every shipped scenario's serial digest and trace).
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass
from typing import Any

from hexhil.hil.servobus import serial_stream, servo_rules
from hexhil.hil.servobus.line import Bus
from hexhil.hil.servobus.servo_core import ServoBank
from hexhil.hil.servobus.servo_layout import HANDOVER, LAYOUT

_P = ctypes.c_void_p
DONE, ADVANCE, PYTHON, PYTHON_REPLY, FALLBACK, WRITE_LEFT = range(len(HANDOVER))


class _Reads(ctypes.Structure):
    _fields_ = LAYOUT.fields("reads")


def _load() -> Any:
    lib = servo_rules.library()   # missing: servo_rules refuses every servo in one line
    fn = getattr(lib, "hx_reads", None) if lib is not None else None
    if fn is not None:
        fn.argtypes, fn.restype = [_P], ctypes.c_int
    return fn


_HX_READS = _load()


@dataclass
class Handover:
    """Where the general path takes over: read ``r``, attempt ``k`` (``code`` PYTHON: not
    begun; PYTHON_REPLY: its servo answered ``reply`` from ``start_us``, the clock at the
    end of its READ), the reads' outcomes so far (True, False, None: skipped) and the
    reply's body so far."""

    code: int
    r: int
    k: int
    done: list[bool | None]
    body: bytearray
    start_us: int = 0
    reply: bytes = b""


@dataclass
class Outcome:
    """What the C code did: the bus time and wire time its attempts took, and either the
    whole reply body or where the general path takes over."""

    busy_us: int
    wire_us: int
    body: bytes | None
    handover: Handover | None


class ReadsCore:
    """``hx_reads`` for one line; ``carry_out`` is None where the C code does not serve it
    (no library, not a plain line, a world it cannot see step)."""

    def __init__(self) -> None:
        self._s = _Reads()
        self._bank: ServoBank | None = None   # the one the C code was last given
        self._ref = ctypes.addressof(self._s)
        self._body, self._log, self._lens, self._reply = (
            self._ref + getattr(_Reads, f).offset for f in ("body", "log", "lens", "reply"))

    @staticmethod
    def available() -> bool:
        return _HX_READS is not None

    def carry_out(self, bus: Bus, payload: bytes, write: bytes | None = None
                  ) -> Outcome | None:
        """The R ``payload``, after the W ``write`` where one came just before it; None
        where nothing was done (the general path carries out both)."""
        bank: ServoBank | None = bus.servo_bank
        if (_HX_READS is None or bank is None or not bus.plain() or bank.next_step_us is None
                or bus.advance != bank.advance):
            return None
        s = self._s
        if bank is not self._bank:   # the first R, or the line re-indexed
            self._bank = bank
            s.bank, s.index, s.changed = bank.ref, bank.by_id_address, bank.changed_address
        s.payload, s.len = payload, len(payload)
        s.write, s.write_len = write, len(write) if write is not None else 0
        s.baud = bus.baud
        delay = bus.return_delay_override_us
        s.delay_override_us = -1 if delay is None else delay
        s.t_us = bus.clock.t_us
        s.at = 0   # the C code starts over: its counters, the W, the first read
        next_step = bank.next_step_us
        while True:
            s.next_step_us = next_step()
            code = _HX_READS(self._ref)
            if code == FALLBACK:
                return None
            if code != ADVANCE:
                self._heard(bus)
            bus.idle_until(s.t_us)   # the clock to where the C code is; the world steps
            if code == WRITE_LEFT:
                if bank.finish_sync_write(s.i, write[5:-1], s.t_us):
                    bus._reindex()   # an ID or baud changed: every read in the general path
                    code = PYTHON
                    break
            elif code != ADVANCE:
                break
        stats = bus.stats
        stats["tx_bytes"] += s.tx_bytes
        stats["rx_bytes"] += s.rx_bytes
        stats["packets"] += s.packets
        stats["replies"] += s.replies
        body = ctypes.string_at(self._body, s.body_len)
        if code == DONE:
            return Outcome(s.busy_us, s.wire_us, body, None)
        done = [None if d < 0 else bool(d) for d in s.done[:s.r]]
        return Outcome(s.busy_us, s.wire_us, None, Handover(
            code, s.r, s.k, done, bytearray(body), s.start_us,
            ctypes.string_at(self._reply, s.m)))

    def _heard(self, bus: Bus) -> None:
        """The bytes on the wire since the last call, to the bus's ``on_bytes`` in order:
        in one call where it takes a stream."""
        s, on_bytes = self._s, bus.on_bytes
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
