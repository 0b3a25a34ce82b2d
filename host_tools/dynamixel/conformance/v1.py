"""Check a Protocol 1.0 bus (our emulator or real AX-12s behind a USB adapter) against the spec.

A pyserial client: scan or ping the IDs, read the control table, check status packet
format, error replies (bad checksum, out-of-range goal, goal outside the angle limits,
ACTION with nothing registered), REG_WRITE/ACTION, Status Return Levels and response
timing against Return Delay Time, then restore what it changed and check that it did.
A line that echoes the master's bytes is detected and the echo stripped.

Only the settings it tests are changed (Status Return Level, Return Delay Time, CW Angle
Limit, Goal Position, LED); a real servo needs a few ms after an EEPROM write, so the
checker pauses after each. An instruction whose repeat changes nothing (PING, READ, WRITE
and REG_WRITE of the same data, ACTION with nothing registered, a bad packet) is sent again
when its reply is missing or says the packet arrived corrupt; a check that still lacks a
reply fails as "no reply" (a lost packet or a silent servo), not as a non-conforming servo.
"""
from __future__ import annotations

import math
import time
from typing import Any

import serial

from hexhil.hil.servobus import switch_node as sensor_node
from hexhil.dynamixel.conformance.report import Cause, Check, summarise
from hexhil.protocol.dynamixel import ax12
from hexhil.protocol.dynamixel import v1 as dxl
from hexhil.protocol.errors import BadFile

EEPROM_PAUSE_S = 0.01
TRIES = 3  # sends of a repeatable instruction before its reply counts as missing
# before a resend after silence: a servo that took a corrupt length byte for a long packet
# keeps reading until the line is quiet this long (protocol/dynamixel/v1.py), then listens anew
RESYNC_S = dxl.INTER_BYTE_TIMEOUT_US * 1e-6
TIMING_ROUNDS = 3  # return-delay measurements, all taken: noise only adds time
_NEED_REPLIES = ("bad_checksum_reply", "out_of_range_goal", "action_nothing_registered",
                 "reg_write_action", "angle_limit_error", "status_return_level",
                 "return_delay_timing", "restored")
SILENCE_S = 0.05  # how long "no reply" is awaited; a late reply can only turn a fail into a pass
_PROTOCOL_ERRORS = dxl.ERR_ANGLE_LIMIT | dxl.ERR_RANGE | dxl.ERR_CHECKSUM | dxl.ERR_INSTRUCTION


def said(p: dxl.Packet | None) -> str:
    """A status packet (or its absence) in words, for a failed check's detail."""
    if p is None:
        return "no reply"
    errors = dxl.error_names(p.code)
    return f"status from ID {p.id} with error bits {', '.join(errors)}" if errors else \
        f"status from ID {p.id} with no error bit"


class Link:
    """One pyserial port; ``transact`` sends a packet and returns the status, if any."""

    def __init__(self, port: str, baud: int, timeout_s: float) -> None:
        try:
            self.ser = serial.serial_for_url(port, baudrate=baud, timeout=timeout_s)
        except (serial.SerialException, ValueError) as exc:
            raise BadFile(f"cannot open {port}: {exc}") from None
        self.baud = baud
        self.timeout_s = timeout_s
        self.echo = False

    def close(self) -> None:
        self.ser.close()

    def wire_s(self, nbytes: int) -> float:
        return nbytes * 10.0 / self.baud

    def send(self, pkt: bytes) -> float:
        """Write ``pkt`` after dropping stale input; the time (perf_counter) of the write.

        The clock starts before the write: flush() (tcdrain) returns only once the bus has
        read the packet, and a checker descheduled after it would start late and time a
        reply as sooner than the servo's Return Delay (0.37 ms at 500 us on a loaded host)."""
        self.ser.reset_input_buffer()
        t0 = time.perf_counter()
        self.ser.write(pkt)
        self.ser.flush()
        return t0

    def transact(self, pkt: bytes, timeout_s: float | None = None
                 ) -> tuple[dxl.Packet | None, float]:
        """Send ``pkt``; the first status packet heard (echo skipped) and its latency in s."""
        timeout_s = self.timeout_s if timeout_s is None else timeout_s
        t0 = self.send(pkt)
        deadline = t0 + timeout_s
        parser = dxl.Parser()
        while True:
            left = deadline - time.perf_counter()
            if left <= 0:
                return None, timeout_s
            self.ser.timeout = left
            chunk = self.ser.read(6 if parser.pending() < 4 else
                                  max(1, parser.buf[3] + 4 - parser.pending()))
            for p in parser.feed(chunk):
                if p.raw == pkt:
                    self.echo = True
                elif p.id == pkt[2]:  # a late reply to an earlier packet is not ours
                    return p, time.perf_counter() - t0

    def silent(self, pkt: bytes, wait_s: float | None = None) -> bool:
        """True when nothing but echo answers ``pkt`` within SILENCE_S (or the timeout)."""
        return self.transact(pkt, min(self.timeout_s, SILENCE_S) if wait_s is None else wait_s
                             )[0] is None


class Checker:
    """Runs the checks on a Link and collects ``Check`` rows."""

    def __init__(self, link: Link) -> None:
        self.link = link
        self.rows: list[Check] = []
        self.unanswered: list[str] = []  # instructions the current check got no reply to

    def add(self, dev_id: int | None, name: str, ok: bool | None, detail: str) -> bool:
        cause = Cause.NONE
        if ok is False:
            cause = Cause.NO_REPLY if self.unanswered else Cause.SERVO
        if cause is Cause.NO_REPLY:
            detail = f"no reply to {', '.join(dict.fromkeys(self.unanswered))}; {detail}"
        self.rows.append(Check(dev_id, name, "skip" if ok is None else ("pass" if ok else "fail"),
                               detail, cause.value))
        self.unanswered = []
        return bool(ok)

    # --- helpers ---------------------------------------------------------------------
    def ask(self, pkt: bytes, retry: bool = True, count: bool = True) -> dxl.Packet | None:
        """The status ``pkt`` gets, sent up to TRIES times when ``retry`` (its repeat must change
        nothing): again on no reply, or on a checksum error to a packet that left intact. A
        reply still missing is noted against the current check unless ``count`` is False."""
        intact = dxl.checksum(pkt, 2, len(pkt) - 1) == pkt[-1]
        tries = TRIES if retry else 1
        p = None
        for n in range(tries):
            if n and p is None:
                time.sleep(RESYNC_S)
            p = self.link.transact(pkt)[0]
            if p is not None and not (intact and p.code & dxl.ERR_CHECKSUM):
                return p
        if p is None and count:
            self.unanswered.append(f"{dxl.INSTRUCTION_NAMES[pkt[4]]} "
                                   f"({f'{tries} tries' if retry else 'once per attempt'})")
        return p

    def read(self, dev_id: int, address: int, n: int) -> bytes | None:
        p = self.ask(dxl.read(dev_id, address, n))
        if p is None or p.id != dev_id or len(p.params) != n:
            return None
        return p.params

    def write(self, dev_id: int, address: int, data: bytes, reply: bool = True,
              count: bool = True) -> dxl.Packet | None:
        pkt = dxl.write(dev_id, address, data)
        if not reply:
            self.link.silent(pkt, 0.005)
            return None
        return self.ask(pkt, count=count)

    # --- the run --------------------------------------------------------------------
    def run(self, ids: list[int] | None, scan_timeout_s: float) -> list[int]:
        """Scan (or ping ``ids``), check what answered, close the link; the IDs found."""
        try:
            found = self.scan(ids, scan_timeout_s)
            self.check_found(found)
        finally:
            self.link.close()
        return found

    def check_found(self, found: list[int]) -> None:
        """Each device found: a servo, or a sensor node (told apart by its model number)."""
        for i in found:
            model = self.read(i, 0, 2)
            if model is not None and dxl.u16(model[0], model[1]) == sensor_node.MODEL_NUMBER:
                self.sensor_node(i)
            else:
                self.servo(i)

    def scan(self, ids: list[int] | None, scan_timeout_s: float) -> list[int]:
        if ids is None:
            found = [i for i in range(dxl.MAX_ID + 1)
                     if self.link.transact(dxl.ping(i), scan_timeout_s)[0]]
            self.add(None, "scan", bool(found),
                     f"IDs 0-253: found {found}" if found else "no servo answered a PING")
            return found
        found = []
        for i in ids:
            p = self.ask(dxl.ping(i))
            if self.add(i, "present", p is not None, "answers PING" if p else "no answer to PING"):
                found.append(i)
        return found

    def servo(self, i: int) -> None:
        p = self.ask(dxl.ping(i))
        ok = p is not None and p.id == i and p.raw[3] == 2 and not p.code & _PROTOCOL_ERRORS
        self.add(i, "ping_status_format", ok,
                 "FF FF ID 02 ERR CHK, no protocol error bits" if ok else f"PING: {said(p)}")
        table = self.read(i, 0, ax12.TABLE_SIZE)
        srl0 = None if table is None else table[ax12.STATUS_RETURN_LEVEL]
        if table is None:  # Status Return Level 0 answers PING only: lift it for the checks
            self.write(i, ax12.STATUS_RETURN_LEVEL, b"\x02", reply=False)
            time.sleep(EEPROM_PAUSE_S)
            table = self.read(i, 0, ax12.TABLE_SIZE)
            srl0 = 0
        if table is None:
            self.add(i, "read_table", False, "READ of addresses 0-49 not answered, even after "
                     "setting Status Return Level 2")
            return
        model = ax12.get(table, ax12.MODEL_NUMBER_L, 2)
        bad = [] if model != ax12.MODEL_NUMBER else \
            [f[1] for f in ax12.FIELDS if not f[6] <= ax12.get(table, f[0], f[2]) <= f[7]]
        self.add(i, "read_table", not bad and table[ax12.ID] == i,
                 f"model {model}, firmware {table[ax12.FIRMWARE]}" +
                 (f"; out of range: {bad}" if bad else "") +
                 ("" if table[ax12.ID] == i else f"; ID cell says {table[ax12.ID]}"))
        part = self.read(i, 0, 2)
        self.add(i, "read_consistency", part == table[0:2],
                 "READ(0,2) matches the table" if part == table[0:2] else f"READ(0,2) = {part!r}")
        locked = table[ax12.LOCK] == 1
        if srl0 == 1:
            if locked:
                for name in _NEED_REPLIES:
                    self.add(i, name, None, "Lock set at Status Return Level 1: WRITE is not "
                             "answered and the level cannot be raised until power-off")
                return
            self.write(i, ax12.STATUS_RETURN_LEVEL, b"\x02", reply=False)
            time.sleep(EEPROM_PAUSE_S)
        try:
            self._errors(i, table)
            self._registered(i, table)
            if locked:
                for name in ("status_return_level", "return_delay_timing", "angle_limit_error"):
                    self.add(i, name, None, "Lock is set: EEPROM cannot be written until power-off")
            else:
                self._angle_limit(i, table)
                self._return_levels(i)
                self._timing(i, table)
        finally:
            self._restore(i, table, srl0, locked)

    def sensor_node(self, i: int) -> None:
        """The limit-switch sensor node (hil/servobus/switch_node.py): its table, switches read-only."""
        p = self.ask(dxl.ping(i))
        ok = p is not None and p.raw[3] == 2 and not p.code & _PROTOCOL_ERRORS
        self.add(i, "ping_status_format", ok, "sensor node answers PING" if ok else f"PING: {said(p)}")
        table = self.read(i, 0, sensor_node.TABLE_SIZE)
        ok = table is not None and table[sensor_node.ID] == i
        self.add(i, "read_table", ok, f"sensor node table read, switches "
                 f"0b{table[sensor_node.SWITCHES]:06b}" if ok else
                 "READ 0-27 not answered" if table is None else f"ID cell says {table[sensor_node.ID]}")
        if not ok:
            return
        reply = self.write(i, sensor_node.SWITCHES, b"\x3f")
        after = self.read(i, sensor_node.SWITCHES, 1)
        ok = reply is not None and bool(reply.code & dxl.ERR_RANGE) and after is not None
        self.add(i, "switches_read_only", ok, "WRITE to Switches refused with the Range bit"
                 if ok else f"WRITE to Switches: {said(reply)}")

    def _errors(self, i: int, table: bytes) -> None:
        bad = bytearray(dxl.ping(i))
        bad[-1] ^= 0xA5
        p = self.ask(bytes(bad))
        self.add(i, "bad_checksum_reply", p is not None and bool(p.code & dxl.ERR_CHECKSUM),
                 "answered with error bit 4 (checksum)" if p is not None and p.code & dxl.ERR_CHECKSUM
                 else f"PING with a bad checksum: {said(p)}")
        p = self.write(i, ax12.GOAL_POSITION, (1024).to_bytes(2, "little"))
        goal = self.read(i, ax12.GOAL_POSITION, 2)
        ok = p is not None and bool(p.code & (dxl.ERR_RANGE | dxl.ERR_ANGLE_LIMIT)) \
            and goal == table[ax12.GOAL_POSITION:ax12.GOAL_POSITION + 2]
        self.add(i, "out_of_range_goal", ok,
                 f"goal 1024 refused: {', '.join(dxl.error_names(p.code))} bit" if ok else
                 f"WRITE goal 1024: {said(p)}; goal afterwards "
                 f"{'unread' if goal is None else dxl.u16(goal[0], goal[1])}")
        if table[ax12.REGISTERED]:
            self.add(i, "action_nothing_registered", None, "an instruction is registered; not fired")
        else:
            p = self.ask(dxl.action(i))
            self.add(i, "action_nothing_registered", p is not None and bool(p.code & dxl.ERR_INSTRUCTION),
                     "instruction error" if p is not None and p.code & dxl.ERR_INSTRUCTION
                     else f"ACTION: {said(p)}")

    def _registered(self, i: int, table: bytes) -> None:
        if table[ax12.REGISTERED]:
            self.add(i, "reg_write_action", None, "an instruction is already registered")
            return
        led = table[ax12.LED]
        for _ in range(TRIES):  # ACTION alone cannot be repeated (it would find nothing
            p = self.ask(dxl.reg_write(i, ax12.LED, bytes((1 - led,))))  # registered): redo both
            mid = self.read(i, ax12.LED, 20)  # LED(25) .. Registered(44)
            q = self.ask(dxl.action(i), retry=False)
            after = self.read(i, ax12.LED, 20)
            if q is not None:
                break
            self.write(i, ax12.LED, bytes((led,)), count=False)
        reg = ax12.REGISTERED - ax12.LED
        wrong = [w for w, bad in (
            (f"REG_WRITE: {said(p)}", p is None or p.code & _PROTOCOL_ERRORS),
            ("READ after REG_WRITE not answered", mid is None),
            ("LED changed before ACTION", mid is not None and mid[0] != led),
            ("Registered not 1 after REG_WRITE", mid is not None and mid[reg] != 1),
            (f"ACTION: {said(q)}", q is None or q.code & _PROTOCOL_ERRORS),
            ("READ after ACTION not answered", after is None),
            ("LED unchanged after ACTION", after is not None and after[0] != 1 - led),
            ("Registered not 0 after ACTION", after is not None and after[reg] != 0)) if bad]
        self.add(i, "reg_write_action", not wrong, "; ".join(wrong) or
                 "REG_WRITE held (Registered=1), ACTION applied it")
        self.write(i, ax12.LED, bytes((led,)), count=False)

    def _angle_limit(self, i: int, table: bytes) -> None:
        pos = ax12.get(table, ax12.PRESENT_POSITION, 2)
        cw = ax12.get(table, ax12.CW_ANGLE_LIMIT, 2)
        ccw = ax12.get(table, ax12.CCW_ANGLE_LIMIT, 2)
        if not (cw or ccw) or pos >= ccw or pos + 1 > 1023:
            self.add(i, "angle_limit_error", None, "wheel mode or horn at the CCW limit")
            return
        self.write(i, ax12.CW_ANGLE_LIMIT, (pos + 1).to_bytes(2, "little"))
        time.sleep(EEPROM_PAUSE_S)
        p = self.write(i, ax12.GOAL_POSITION, pos.to_bytes(2, "little"))
        ok = p is not None and bool(p.code & dxl.ERR_ANGLE_LIMIT)
        self.add(i, "angle_limit_error", ok, f"goal {pos} below CW limit {pos + 1}: angle limit bit"
                 if ok else f"WRITE goal {pos} below CW limit {pos + 1}: {said(p)}")
        self.write(i, ax12.GOAL_POSITION, table[ax12.GOAL_POSITION:ax12.GOAL_POSITION + 2], count=False)
        self.write(i, ax12.CW_ANGLE_LIMIT, table[ax12.CW_ANGLE_LIMIT:ax12.CW_ANGLE_LIMIT + 2],
                   count=False)
        time.sleep(EEPROM_PAUSE_S)

    def _return_levels(self, i: int) -> None:
        link = self.link
        led = self.read(i, ax12.LED, 1)
        wrong = []
        for level in (1, 0):
            self.write(i, ax12.STATUS_RETURN_LEVEL, bytes((level,)), reply=False)
            time.sleep(EEPROM_PAUSE_S)
            for name, pkt in (("PING", dxl.ping(i)), ("READ", dxl.read(i, ax12.LED, 1)),
                              ("WRITE", dxl.write(i, ax12.LED, led or b"\x00"))):
                if name == "PING" or (name == "READ" and level == 1):
                    if self.ask(pkt) is None:
                        wrong.append(f"level {level}: {name} not answered")
                elif not link.silent(pkt):
                    wrong.append(f"level {level}: {name} answered (must be silent)")
        self.write(i, ax12.STATUS_RETURN_LEVEL, b"\x02", reply=False)
        time.sleep(EEPROM_PAUSE_S)
        self.add(i, "status_return_level", not wrong, "; ".join(wrong) or
                 "level 1: PING+READ answered; level 0: PING only")

    def _timing(self, i: int, table: bytes) -> None:
        link = self.link
        best = {0: math.inf, 250: math.inf}  # fastest of several: scheduling and USB only add
        floor = link.wire_s(12) + 500e-6  # PING out and status back, plus 500 us
        # Every round, not the first that passes: a load burst can slow all 7 pings of one
        # setting, which would make a servo that ignores its Return Delay look conforming.
        for _ in range(TIMING_ROUNDS):
            for rd in best:
                self.write(i, ax12.RETURN_DELAY_TIME, bytes((rd,)))
                time.sleep(EEPROM_PAUSE_S)
                best[rd] = min(best[rd], *(link.transact(dxl.ping(i))[1] for _ in range(7)))
        ok = best[250] >= floor - 100e-6 and best[250] - best[0] >= 300e-6
        self.write(i, ax12.RETURN_DELAY_TIME, table[ax12.RETURN_DELAY_TIME:ax12.RETURN_DELAY_TIME + 1],
                   count=False)
        time.sleep(EEPROM_PAUSE_S)
        self.add(i, "return_delay_timing", ok,
                 f"fastest PING round trip {best[0] * 1e3:.2f} ms at delay 0, "
                 f"{best[250] * 1e3:.2f} ms at 500 us (expect +0.5 ms, >= {floor * 1e3:.2f} ms)")

    def _restore(self, i: int, table: bytes, srl0: int, locked: bool) -> None:
        after = self.read(i, 0, ax12.TABLE_SIZE)  # still at Status Return Level 2
        if after is None:
            self.add(i, "restored", False, "the table could not be read back to compare")
            return
        rw = [f for f in ax12.FIELDS if f[3] == ax12.RW and f[0] != ax12.STATUS_RETURN_LEVEL]
        changed = [f[1] for f in rw if ax12.get(after, f[0], f[2]) != ax12.get(table, f[0], f[2])]
        if srl0 != 2:
            self.write(i, ax12.STATUS_RETURN_LEVEL, bytes((srl0,)), reply=False)
            time.sleep(EEPROM_PAUSE_S)
            back = (self.read(i, ax12.STATUS_RETURN_LEVEL, 1) == bytes((1,)) if srl0 == 1
                    else self.link.silent(dxl.read(i, ax12.STATUS_RETURN_LEVEL, 1)))
            if not back:
                changed.append("status_return_level")
        self.add(i, "restored", not changed, "every writable cell as found" if not changed
                 else f"changed: {changed}")


def run_checks(port: str, baud: int, ids: list[int] | None, timeout_s: float = 0.05,
               scan_timeout_s: float = 0.015) -> dict[str, Any]:
    """Run every check; the result as a JSON-ready dict (``ok`` true when none failed)."""
    link = Link(port, baud, timeout_s)
    checker = Checker(link)
    found = checker.run(ids, scan_timeout_s)
    return summarise(port, baud, link.echo, found, checker.rows)
