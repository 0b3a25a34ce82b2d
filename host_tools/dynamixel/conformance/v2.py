"""Check a Protocol 2.0 bus (our X-series emulators, or real X-series servos behind a USB
adapter) against the spec: the ``hexhil conformance --protocol 2`` checks.

A pyserial client, like host_tools/dynamixel/conformance/v1.py for Protocol 1.0 (whose ``Check`` rows
and table it shares). Per servo: PING status format and CRC, no reply to a bad CRC, byte
stuffing of a status packet that holds FF FF FD, the error numbers (instruction, data
length, data limit, access), the EEPROM lock while the torque is on, Status Return
Levels, response timing against Return Delay Time; per bus: the reply order of SYNC_READ
and BULK_READ, and FAST_SYNC_READ / FAST_BULK_READ as one packet in list order. What it
changes (Homing Offset, Return Delay, Status Return Level, Torque Enable) it restores and
checks that it did. Each servo is checked against its own model's control table, found
from the model number its PING returns (protocol/dynamixel/models.py; a model not listed
there is checked as an XL430, whose layout the X series shares).
"""
from __future__ import annotations

import time
from dataclasses import asdict
from typing import Any

from types import ModuleType

from hexhil.dynamixel.conformance.v1 import EEPROM_PAUSE_S, SILENCE_S, Checker, Link
from hexhil.protocol.dynamixel import models
from hexhil.protocol.dynamixel import v2 as dx2
from hexhil.protocol.dynamixel import xl430 as xl

STUFFED_OFFSET = int.from_bytes(b"\xff\xff\xfd\xff", "little", signed=True)  # in range
TIMING_ROUNDS = 12   # the fastest of these: a loaded host only adds time


class Link2(Link):
    """One pyserial port speaking Protocol 2.0; keeps the last exchange's wire bytes."""

    def __init__(self, port: str, baud: int, timeout_s: float) -> None:
        super().__init__(port, baud, timeout_s)
        self.wire = b""       # every byte heard during the last exchange
        self.bad_crc = 0      # status packets with a bad CRC heard during it

    def exchange(self, pkt: bytes, n_packets: int = 1, timeout_s: float | None = None
                 ) -> tuple[list[dx2.Packet], float]:
        """Send ``pkt``; up to ``n_packets`` status packets (not our echo) and the time
        from the write to the last one."""
        timeout_s = self.timeout_s if timeout_s is None else timeout_s
        t0 = self.send(pkt)
        deadline = t0 + timeout_s
        parser = dx2.Parser()
        wire = bytearray()
        got: list[dx2.Packet] = []
        t_last = timeout_s
        while len(got) < n_packets:
            left = deadline - time.perf_counter()
            if left <= 0:
                break
            self.ser.timeout = left
            chunk = self.ser.read(max(1, self.ser.in_waiting))
            wire.extend(chunk)
            for p in parser.feed(chunk):
                if p.instr == dx2.STATUS:
                    got.append(p)
                    t_last = time.perf_counter() - t0
        self.wire, self.bad_crc = bytes(wire), parser.bad_crc
        return got, t_last

    def transact(self, pkt: bytes, timeout_s: float | None = None  # type: ignore[override]
                 ) -> dx2.Packet | None:
        got, _ = self.exchange(pkt, 1, timeout_s)
        return got[0] if got else None

    def silent(self, pkt: bytes) -> bool:
        return not self.exchange(pkt, 1, min(self.timeout_s, SILENCE_S))[0]


class Checker2(Checker):
    """Runs the Protocol 2.0 checks on a Link2 and collects ``Check`` rows (``add``)."""

    link: Link2

    def __init__(self, link: Link2) -> None:
        super().__init__(link)
        self.model_numbers: dict[int, int] = {}     # what each servo's PING said

    def layout(self, i: int) -> ModuleType:
        """The control table of servo ``i``'s model (the XL430's when unknown)."""
        name = models.by_number(2, self.model_numbers.get(i, -1))
        return models.table(name) if name is not None else xl

    def read(self, i: int, address: int, n: int) -> bytes | None:  # type: ignore[override]
        p = self.link.transact(dx2.read(i, address, n))
        return p.params[1:] if p is not None and p.id == i and len(p.params) == n + 1 else None

    def write(self, i: int, address: int, data: bytes) -> int | None:  # type: ignore[override]
        """The error field of the WRITE's status packet, or None (no reply)."""
        p = self.link.transact(dx2.write(i, address, data))
        if address < xl.EEPROM_END:
            time.sleep(EEPROM_PAUSE_S)
        return p.error if p is not None and p.id == i else None

    def scan(self, ids: list[int] | None, scan_timeout_s: float) -> list[int]:
        candidates = range(dx2.MAX_ID + 1) if ids is None else ids
        found = []
        for i in candidates:
            p = self.link.transact(dx2.ping(i), scan_timeout_s if ids is None else None)
            if p is not None and p.id == i:
                found.append(i)
            elif ids is not None:
                crc = self.link.bad_crc
                self.add(i, "status_crc" if crc else "present", False,
                         "a status packet with a bad CRC" if crc else "no answer to PING")
        if ids is None:
            self.add(None, "scan", bool(found), f"IDs 0-252: found {found}")
        return found

    def check_found(self, found: list[int]) -> None:
        """Each servo found, then the bus-wide group reads."""
        for i in found:
            self.servo(i)
        if found:
            self.group_reads(found)

    def servo(self, i: int) -> None:
        link = self.link
        p = link.transact(dx2.ping(i))
        ok = p is not None and len(p.params) == 4 and p.error & 0x7F == 0
        if ok:
            self.model_numbers[i] = p.params[1] | p.params[2] << 8
        self.add(i, "ping_status_format", ok, "55 ERR model_L model_H firmware, CRC valid"
                 if ok else f"got {p!r}")
        bad = bytearray(dx2.ping(i))
        bad[-1] ^= 0xFF
        self.add(i, "no_reply_to_bad_crc", link.silent(bytes(bad)),
                 "a PING with a bad CRC is ignored")
        table = self.read(i, 0, xl.TABLE_SIZE)
        if not self.add(i, "read_table", table is not None and len(table) == xl.TABLE_SIZE,
                        f"READ 0-{xl.TABLE_SIZE - 1}"):
            return
        torque = table[xl.TORQUE_ENABLE]
        if torque:
            self.write(i, xl.TORQUE_ENABLE, b"\x00")
        self._stuffing(i)
        self._errors(i)
        self._return_levels(i)
        self._timing(i, table)
        if torque:
            self.write(i, xl.TORQUE_ENABLE, b"\x01")
        self._restore(i, table)

    def _stuffing(self, i: int) -> None:
        old = self.read(i, xl.HOMING_OFFSET, 4)
        err = self.write(i, xl.HOMING_OFFSET, STUFFED_OFFSET.to_bytes(4, "little", signed=True))
        p = self.link.transact(dx2.read(i, xl.HOMING_OFFSET, 4))
        ok = err == 0 and p is not None and p.params[1:] == b"\xff\xff\xfd\xff" \
            and p.raw in self.link.wire
        self.add(i, "byte_stuffing", ok, "FF FF FD written and read back, the status packet "
                 "stuffed (FF FF FD FD)" if ok else f"write error {err}, reply "
                 f"{self.link.wire.hex()}: FF FF FD not stuffed as the e-manual says")
        if old is not None:
            self.write(i, xl.HOMING_OFFSET, old)

    def _errors(self, i: int) -> None:
        cases = (("instruction_error", dx2.packet(i, 0x77), dx2.ERR_INSTRUCTION),
                 ("data_length_error", dx2.write(i, xl.GOAL_POSITION, b"\x00\x08"),
                  dx2.ERR_DATA_LENGTH),
                 ("data_limit_error", dx2.write(i, xl.GOAL_POSITION, (5000).to_bytes(4, "little")),
                  dx2.ERR_DATA_LIMIT),
                 ("access_error", dx2.write(i, xl.PRESENT_POSITION, bytes(4)), dx2.ERR_ACCESS))
        for name, pkt, want in cases:
            p = self.link.transact(pkt)
            got = None if p is None else p.error & 0x7F
            self.add(i, name, got == want, f"error number {want} expected, got {got}")
        self.write(i, xl.TORQUE_ENABLE, b"\x01")
        err = self.write(i, xl.RETURN_DELAY_TIME, b"\x00")
        self.write(i, xl.TORQUE_ENABLE, b"\x00")
        self.add(i, "eeprom_lock", err is not None and err & 0x7F == dx2.ERR_ACCESS,
                 f"EEPROM write with torque on: access error (7) expected, got {err}")

    def _return_levels(self, i: int) -> None:
        link = self.link
        self.write(i, xl.STATUS_RETURN_LEVEL, b"\x01")
        ok1 = self.read(i, xl.LED, 1) is not None and link.silent(dx2.write(i, xl.LED, b"\x00"))
        link.silent(dx2.write(i, xl.STATUS_RETURN_LEVEL, b"\x00"))
        ok0 = link.transact(dx2.ping(i)) is not None and link.silent(dx2.read(i, xl.LED, 1))
        link.silent(dx2.write(i, xl.STATUS_RETURN_LEVEL, b"\x02"))
        ok2 = self.read(i, xl.STATUS_RETURN_LEVEL, 1) == b"\x02"
        self.add(i, "status_return_level", ok1 and ok0 and ok2,
                 f"level 1 answers READ not WRITE: {ok1}; level 0 PING only: {ok0}; back to 2: {ok2}")

    def _timing(self, i: int, table: bytes) -> None:
        best = {}
        for rd in (0, 250):
            self.write(i, xl.RETURN_DELAY_TIME, bytes((rd,)))
            best[rd] = min(self.link.exchange(dx2.ping(i))[1] for _ in range(TIMING_ROUNDS))
        self.write(i, xl.RETURN_DELAY_TIME, table[xl.RETURN_DELAY_TIME:xl.RETURN_DELAY_TIME + 1])
        ok = best[250] - best[0] >= 300e-6
        self.add(i, "return_delay_timing", ok,
                 f"fastest PING round trip {best[0] * 1e3:.2f} ms at delay 0, "
                 f"{best[250] * 1e3:.2f} ms at 250 (2 us units: expect +0.5 ms)")

    def _restore(self, i: int, table: bytes) -> None:
        after = self.read(i, 0, xl.TABLE_SIZE)
        if after is None:
            self.add(i, "restored", False, "READ of the table failed")
            return
        layout = self.layout(i)
        changed = [f[1] for f in layout.FIELDS if f[3] == xl.RW and
                   xl.get(after, f[0], f[2]) != xl.get(table, f[0], f[2])]
        self.add(i, "restored", not changed, "every writable cell as found" if not changed
                 else f"changed: {changed}")

    def group_reads(self, ids: list[int]) -> None:
        """Reply order of sync and bulk reads, and their fast forms, over the found IDs."""
        order = list(reversed(ids))
        number = {d: self.model_numbers.get(d, -1).to_bytes(2, "little", signed=True)
                  for d in order}          # what each servo's PING said its model is
        got, _ = self.link.exchange(dx2.sync_read(xl.MODEL_NUMBER_L, 2, order), len(order))
        ok = [p.id for p in got] == order and all(p.params[1:] == number[p.id] for p in got)
        self.add(None, "sync_read_order", ok, f"asked {order}, answered {[p.id for p in got]}")
        got, _ = self.link.exchange(dx2.sync_read(xl.MODEL_NUMBER_L, 2, order, fast=True))
        blocks = dx2.fast_blocks(got[0].params, [2] * len(order)) if got else []
        ok = len(got) == 1 and got[0].id == dx2.BROADCAST_ID and \
            [b[1] for b in blocks] == order and all(b[2] == number[b[1]] for b in blocks)
        self.add(None, "fast_sync_read", ok, f"one packet from ID 254, blocks {[b[1] for b in blocks]}")
        req = [(d, xl.ID, 1) if k % 2 else (d, xl.MODEL_NUMBER_L, 2) for k, d in enumerate(order)]
        got, _ = self.link.exchange(dx2.bulk_read(req), len(req))
        ok = [p.id for p in got] == order and all(
            p.params[1:] == (bytes((d,)) if n == 1 else number[d]) for p, (d, _, n) in zip(got, req))
        self.add(None, "bulk_read_order", ok, f"asked {order}, answered {[p.id for p in got]}")
        got, _ = self.link.exchange(dx2.bulk_read(req, fast=True))
        blocks = dx2.fast_blocks(got[0].params, [n for _, _, n in req]) if got else []
        ok = len(got) == 1 and [b[1] for b in blocks] == order
        self.add(None, "fast_bulk_read", ok, f"one packet, blocks {[b[1] for b in blocks]}")


def run_checks(port: str, baud: int, ids: list[int] | None, timeout_s: float = 0.05,
               scan_timeout_s: float = 0.015) -> dict[str, Any]:
    """Every Protocol 2.0 check; a JSON-ready dict shaped like Protocol 1.0's result."""
    checker = Checker2(Link2(port, baud, timeout_s))
    found = checker.run(ids, scan_timeout_s)
    rows = checker.rows
    return {"port": port, "baud": baud, "echo": False, "protocol": 2, "servos": found,
            "ok": bool(rows) and all(r.result != "fail" for r in rows),
            "passed": sum(r.result == "pass" for r in rows),
            "failed": sum(r.result == "fail" for r in rows),
            "skipped": sum(r.result == "skip" for r in rows),
            "checks": [asdict(r) for r in rows]}
