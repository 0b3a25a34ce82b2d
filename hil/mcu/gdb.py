"""``--gdb PORT``: a GDB remote-protocol server on the emulated core, on 127.0.0.1.

The run waits for the client before the first instruction. While GDB holds the core (at
the start, a breakpoint, a step) the board's loop is blocked here: no instruction runs,
so virtual time, the bus and the world stand still and a debugged run's trace equals an
undebugged one. Served: the Cortex-M register set (r0-r12, sp, lr, pc, xpsr, as GDB's
m-profile target description), memory reads and writes (flash and SRAM; the peripherals
answer E01, a read would change them), software breakpoints, single steps, continue,
detach. (udbserver 0.3.0, the GDB server made for Unicorn, refuses Unicorn's
Thumb+M-class mode, hence this one.)
"""
from __future__ import annotations

import socket
from typing import Any

from unicorn import UC_HOOK_CODE, UcError
from unicorn import arm_const as A

from protocol.errors import UserError

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
            raise UserError(f"gdb_port {port}: cannot listen on 127.0.0.1:{port} "
                            f"({exc.strerror})", params=("gdb_port",)) from None
        srv.listen(1)
        srv.settimeout(ACCEPT_S)
        try:
            self.conn, _ = srv.accept()
        except TimeoutError:
            raise UserError(f"gdb_port {port}: no GDB client came in {ACCEPT_S:g} s",
                            params=("gdb_port",)) from None
        finally:
            srv.close()
        self.conn.settimeout(None)
        self._buf = b""
        self.attached = True
        self.halted = True           # GDB has the core before the first instruction
        self.stepping = False
        self.hit = False
        self._breaks: dict[int, int] = {}
        self._resume_at: int | None = None   # a breakpoint the next run steps over
        self.core.uc.reg_write(A.UC_ARM_REG_PC, self.core.pc | 1)

    # --- the board's side -----------------------------------------------------------
    def chunk_limit(self, n: int) -> int:
        """Serve GDB while it holds the core; the instructions the next chunk may run."""
        if self.attached and self.halted:
            self._serve()
        self._resume_at = self.core.pc if self.core.pc in self._breaks else None
        return 1 if self.stepping else n

    def after_chunk(self) -> None:
        if not self.attached:
            return
        if self.hit or self.stepping:
            self.hit = False
            self.stepping = False
            self.halted = True
            self._send("S05")

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
            return "PacketSize=4000;qXfer:features:read+"
        if p.startswith("qXfer:features:read:target.xml:"):
            off, length = (int(x, 16) for x in p.rsplit(":", 1)[1].split(","))
            part = TARGET_XML[off:off + length]
            return ("l" if off + length >= len(TARGET_XML) else "m") + part
        if p == "?":
            return "S05"
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
        if p in ("c", "vCont;c") or p.startswith("vCont;c"):
            self.halted = False
            return None
        if p in ("s", "vCont;s") or p.startswith("vCont;s"):
            self.halted, self.stepping = False, True
            return None
        if p == "vCont?":
            return "vCont;c;s"
        if p in ("D", "k") or p.startswith("D;"):
            self._send("OK")
            self.detach()
            return None
        return {"qC": "QC1", "qfThreadInfo": "m1", "qsThreadInfo": "l", "qAttached": "1",
                "qSymbol::": "OK"}.get(p, "OK" if p.startswith("H") else "")

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
