"""``--gdb PORT``: a GDB remote-protocol server on the emulated core, on 127.0.0.1.

The run waits for the client before the first instruction. While GDB holds the core (at
the start, a breakpoint, a step) the board's loop is blocked here: no instruction runs,
so virtual time, the bus and the world stand still and a debugged run's trace equals an
undebugged one. Served: the Cortex-M register set (r0-r12, sp, lr, pc, xpsr, as GDB's
m-profile target description), memory reads and writes (flash and SRAM; the peripherals
answer E01, a read would change them), software breakpoints (in exception handlers too),
single steps, range steps (``vCont;r``: a ``next`` over a C line is one packet), continue,
detach; no-ack mode, and TCP_NODELAY, so a step answers at once. A fault, an abort or a
hang halts the core and is reported as a signal (SIGSEGV, SIGBUS, SIGILL, SIGABRT, SIGINT)
with the registers where it happened, the run's one line as console output; the client
stays attached to inspect it until it detaches or kills, and then the run ends. (udbserver 0.3.0, the GDB server made for Unicorn, refuses Unicorn's
Thumb+M-class mode, hence this one.)
"""
from __future__ import annotations

import socket
from typing import Any

from unicorn import UC_HOOK_CODE, UcError
from unicorn import arm_const as A

from hexhil.protocol.errors import BadFile, TimedOut

REGS = tuple(A.UC_ARM_REG_R0 + i for i in range(13)) + (
    A.UC_ARM_REG_SP, A.UC_ARM_REG_LR, A.UC_ARM_REG_PC, A.UC_ARM_REG_XPSR)
TARGET_XML = ('<?xml version="1.0"?><!DOCTYPE target SYSTEM "gdb-target.dtd"><target>'
              '<architecture>arm</architecture><feature name="org.gnu.gdb.arm.m-profile">'
              + "".join(f'<reg name="r{i}" bitsize="32"/>' for i in range(13))
              + '<reg name="sp" bitsize="32" type="data_ptr"/><reg name="lr" bitsize="32"/>'
              '<reg name="pc" bitsize="32" type="code_ptr"/><reg name="xpsr" bitsize="32"/>'
              '</feature></target>')
MEMORY = ((0x00000000, 0x00080000), (0x08000000, 0x08080000), (0x20000000, 0x20020000))
ACCEPT_S = 600.0
SIGINT, SIGILL, SIGTRAP, SIGABRT, SIGBUS, SIGSEGV = 2, 4, 5, 6, 10, 11   # GDB's numbers
PC_REG, SP_REG, LR_REG = 15, 13, 14


def fault_signal(line: str) -> int:
    """The signal GDB is told for the fault a run's line names (hil/mcu/core.py)."""
    if "unaligned" in line:
        return SIGBUS
    if "undefined instruction" in line or "UsageFault" in line or "breakpoint" in line:
        return SIGILL
    if "lockup" in line:
        return SIGABRT
    return SIGSEGV


def _hex32(v: int) -> str:
    return (v & 0xFFFFFFFF).to_bytes(4, "little").hex()


class GdbServer:
    """One client, served between the board's chunks (``hold``)."""

    def __init__(self, board: Any, port: int) -> None:
        self.board = board
        self.core = board.core
        srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            srv.bind(("127.0.0.1", port))
        except OSError as exc:
            srv.close()
            raise BadFile(f"gdb_port {port}: cannot listen on 127.0.0.1:{port} "
                            f"({exc.strerror})", params=("gdb_port",)) from None
        srv.listen(1)
        srv.settimeout(ACCEPT_S)
        try:
            self.conn, _ = srv.accept()
        except TimeoutError:
            raise TimedOut(f"gdb_port {port}: no GDB client came in {ACCEPT_S:g} s",
                            params=("gdb_port",)) from None
        finally:
            srv.close()
        self.conn.settimeout(None)
        self.conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._ack = True             # until the client asks for QStartNoAckMode
        self._range: tuple[int, int] | None = None    # vCont;r: step while the PC is in it
        self._stop = "S05"           # the stop reply ``?`` repeats
        self._buf = b""
        self.attached = True
        self.halted = True           # GDB has the core before the first instruction
        self.stepping = False
        self.hit = False
        self.ended = False           # the run is over: the core cannot go on
        self._breaks: dict[int, int] = {}
        self._resume_at: int | None = None   # a breakpoint the next run steps over
        self.core.uc.reg_write(A.UC_ARM_REG_PC, self.core.pc | 1)

    # --- the board's side -----------------------------------------------------------
    def chunk_limit(self, n: int) -> int:
        """Serve GDB while it holds the core (before the first instruction); the
        instructions the next chunk may run."""
        if self.attached and self.halted:
            self._hold()
        return 1 if self.stepping else n

    def _hold(self) -> None:
        """Serve GDB until it lets the core run; a breakpoint at the PC it continues
        from is stepped over once."""
        self._serve()
        self._resume_at = self.core.pc if self.core.pc in self._breaks else None

    def after_chunk(self) -> None:
        """A chunk ran: at a breakpoint or the step's end GDB has the core, at once (the
        state it sees is the halt's, before the next events and exceptions)."""
        if not self.attached:
            return
        if self.stepping and not self.hit and self._range is not None and \
                self._range[0] <= self.core.pc < self._range[1]:
            return                      # a range step goes on
        if self.hit or self.stepping:
            self.hit = False
            self.stepping = False
            self._range = None
            self.halted = True
            self._stop = "S05"
            self._send(self._stop)
            self._hold()

    def halted_by(self, signal: int, line: str) -> None:
        """The run ends with a fault or a verdict: GDB is told ``signal`` with the
        registers as they are, and keeps the core until it detaches."""
        if not self.attached:
            return
        uc = self.core.uc
        regs = ";".join(f"{n:02x}:{_hex32(uc.reg_read(REGS[n]))}"
                        for n in (PC_REG, SP_REG, LR_REG))
        self._send("O" + (line + "\n").encode().hex())
        self._stop = f"T{signal:02x}{regs};"
        self._send(self._stop)
        self.halted = True
        self.ended = True
        self._serve()

    def run_ended(self, code: int = 0) -> None:
        if self.attached:
            self._send(f"W{code & 0xFF:02x}")
            self.detach()

    def detach(self) -> None:
        self.attached = False
        for h in self._breaks.values():
            self.core.uc.hook_del(h)
        self._breaks.clear()
        try:
            self.conn.close()
        except OSError:
            pass

    def _breakpoint(self, uc: Any, address: int, size: int, _: Any) -> None:
        if address == self._resume_at:
            self._resume_at = None       # the instruction GDB continued from
            return
        self.hit = True
        self.core.stop()

    # --- the protocol -------------------------------------------------------------
    def _read_packet(self) -> str | None:
        while True:
            start = self._buf.find(b"$")
            end = self._buf.find(b"#", start)
            if start >= 0 and end >= 0 and len(self._buf) >= end + 3:
                body = self._buf[start + 1:end].decode(errors="replace")
                self._buf = self._buf[end + 3:]
                if self._ack:
                    self.conn.sendall(b"+")
                return body
            data = self.conn.recv(4096)
            if not data:
                return None
            self._buf += data.replace(b"\x03", b"")

    def _send(self, body: str) -> None:
        raw = body.encode()
        try:
            self.conn.sendall(b"$" + raw + b"#%02x" % (sum(raw) & 0xFF))
        except OSError:
            self.attached = False

    def _serve(self) -> None:
        while self.attached and self.halted:
            try:
                packet = self._read_packet()
            except OSError:
                packet = None
            if packet is None:
                self.detach()
                return
            reply = self._answer(packet)
            if reply is not None:
                self._send(reply)

    def _answer(self, p: str) -> str | None:
        uc = self.core.uc
        if p.startswith("qSupported"):
            return "PacketSize=4000;qXfer:features:read+;QStartNoAckMode+"
        if p == "QStartNoAckMode":
            self._send("OK")
            self._ack = False
            return None
        if p.startswith("qXfer:features:read:target.xml:"):
            off, length = (int(x, 16) for x in p.rsplit(":", 1)[1].split(","))
            part = TARGET_XML[off:off + length]
            return ("l" if off + length >= len(TARGET_XML) else "m") + part
        if p == "?":
            return self._stop
        if p == "g":
            return "".join(_hex32(uc.reg_read(r)) for r in REGS)
        if p.startswith("p"):
            n = int(p[1:], 16)
            return _hex32(uc.reg_read(REGS[n])) if n < len(REGS) else "00000000"
        if p.startswith("P"):
            n, value = p[1:].split("=")
            if int(n, 16) < len(REGS):
                uc.reg_write(REGS[int(n, 16)], int.from_bytes(bytes.fromhex(value), "little"))
                if REGS[int(n, 16)] == A.UC_ARM_REG_PC:
                    self.core.pc = uc.reg_read(A.UC_ARM_REG_PC) & ~1
            return "OK"
        if p.startswith(("m", "M")):
            return self._memory(p)
        if p.startswith(("Z0,", "Z1,")):
            addr = int(p.split(",")[1], 16)
            if addr not in self._breaks:
                self._breaks[addr] = uc.hook_add(UC_HOOK_CODE, self._breakpoint, None, addr, addr)
            return "OK"
        if p.startswith(("z0,", "z1,")):
            h = self._breaks.pop(int(p.split(",")[1], 16), None)
            if h is not None:
                uc.hook_del(h)
            return "OK"
        if p[:1] in ("c", "C", "s", "S") or p.startswith("vCont;"):
            return self._resume(p)
        if p == "vCont?":
            return "vCont;c;s;r"
        if p in ("D", "k") or p.startswith("D;"):
            self._send("OK")
            self.detach()
            return None
        return {"qC": "QC1", "qfThreadInfo": "m1", "qsThreadInfo": "l", "qAttached": "1",
                "qSymbol::": "OK"}.get(p, "OK" if p.startswith("H") else "")

    def _resume(self, p: str) -> str | None:
        """``c``, ``s`` (and their with-a-signal forms ``C``, ``S``, which drop the
        signal) and ``vCont``'s first action, ``r`` a range step; after the run's end the
        stop again (the core cannot go on)."""
        action = p[6:7] if p.startswith("vCont;") else p[:1]
        if self.ended:
            return self._stop
        if action in ("c", "C"):
            self.halted = False
        elif action in ("s", "S"):
            self.halted, self.stepping = False, True
        elif action == "r":
            lo, hi = (int(x, 16) for x in p[7:].split(";")[0].split(":")[0].split(","))
            self.halted, self.stepping, self._range = False, True, (lo, hi)
        else:
            return ""
        return None

    def _memory(self, p: str) -> str:
        head, _, data = p[1:].partition(":")
        addr, length = (int(x, 16) for x in head.split(","))
        if not any(lo <= addr and addr + length <= hi for lo, hi in MEMORY):
            return "E01"
        try:
            if p[0] == "m":
                return bytes(self.core.uc.mem_read(addr, length)).hex()
            self.core.uc.mem_write(addr, bytes.fromhex(data))
            return "OK"
        except UcError:
            return "E01"
