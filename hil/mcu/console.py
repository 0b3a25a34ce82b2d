"""The firmware's console: USART1 (and USART6) output at any baud, and ARM semihosting.

Each line becomes an event on the link as the other runtimes' prints do
(hil/link/served_firmware.py ``console_events``): ``event KIND TEXT`` is that event (a C
firmware's stats, stop or tactile events), any other line a log line in ``/telemetry``;
its time is when its last byte (the newline) left the UART, or the semihosting call's.
Semihosting (``BKPT 0xAB``, r0 = operation, r1 = argument): SYS_WRITEC, SYS_WRITE0,
SYS_WRITE (to any handle), SYS_EXIT and SYS_EXIT_EXTENDED; others answer -1.
"""
from __future__ import annotations

from typing import Callable

from unicorn import arm_const as A

from hexhil.hil.mcu.core import Core
from hexhil.hil.mcu.timebase import FS_PER_US

SYS_WRITEC, SYS_WRITE0, SYS_WRITE, SYS_EXIT, SYS_EXIT_EXTENDED = 0x03, 0x04, 0x05, 0x18, 0x20
ADP_APPLICATION_EXIT = 0x20026
MAX_LINE = 1000
MAX_STRING = 4096


class Console:
    """Collects bytes into lines; ``emit(at_us, line)`` hears each whole one, with the
    virtual time its last byte came at."""

    def __init__(self, emit: Callable[[int, str], None]) -> None:
        self.emit = emit
        self._buf = bytearray()
        self._at_us = 0       # when the last byte came
        self.lines = 0

    def put(self, data: bytes, at_us: int) -> None:
        self._at_us = at_us
        for b in data:
            if b == 0x0A:
                self.flush()
            elif b != 0x0D:
                self._buf.append(b)
                if len(self._buf) >= MAX_LINE:
                    self.flush()

    def flush(self) -> None:
        """The line so far (at the run's end, one without its newline), at its last byte's
        time."""
        if self._buf:
            self.lines += 1
            self.emit(self._at_us, self._buf.decode(errors="replace"))
            self._buf.clear()


def semihost(core: Core, console: Console) -> int | None:
    """Carry out the semihosting call the core stopped at; the exit code when the
    firmware asked to exit."""
    uc = core.uc
    now_us = core.now_fs() // FS_PER_US
    op, arg = uc.reg_read(A.UC_ARM_REG_R0), uc.reg_read(A.UC_ARM_REG_R1)
    result = 0
    if op == SYS_WRITEC:
        console.put(bytes(uc.mem_read(arg, 1)), now_us)
    elif op == SYS_WRITE0:
        out = bytearray()
        while len(out) < MAX_STRING:
            b = uc.mem_read(arg + len(out), 1)[0]
            if b == 0:
                break
            out.append(b)
        console.put(bytes(out), now_us)
    elif op == SYS_WRITE:
        buf, n = core.read32(arg + 4), core.read32(arg + 8)
        console.put(bytes(uc.mem_read(buf, min(n, MAX_STRING))), now_us)
    elif op == SYS_EXIT:
        return 0 if arg == ADP_APPLICATION_EXIT else 1
    elif op == SYS_EXIT_EXTENDED:
        reason, code = core.read32(arg), core.read32(arg + 4)
        return code if reason == ADP_APPLICATION_EXIT else 1
    else:
        result = 0xFFFFFFFF
    uc.reg_write(A.UC_ARM_REG_R0, result)
    return None
