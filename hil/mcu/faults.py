"""The Cortex-M4's fault exceptions (ARMv7-M ARM B1.5.14-B1.5.16, B3.2.15-B3.2.18): what
the core does where the firmware faults, and the run's verdict once the handler spins.

A fault the chip takes as an exception (an undefined instruction, a coprocessor instruction
with the FPU off, a branch to ARM state or to address 0, a bus error on a read, a write or
a fetch, a fetch from an execute-never region, an unaligned LDRD/LDM/STRD/STM, a BKPT with
no debugger) sets its status bits (CFSR, HFSR, MMFAR, BFAR), is taken as MemManage,
BusFault or UsageFault where SHCSR enables it and its priority preempts what runs, else as
HardFault (HFSR FORCED); where not even HardFault can be taken (in HardFault or NMI, or
FAULTMASK set) it is a lockup. The firmware's handler then runs from the stacked frame: it
may print, reset the MCU (``NVIC_SystemReset``), or return. Where it spins instead, in a
loop that branches to itself or still inside the handler after the masked-spin limit of
virtual time, the run ends ``crashed`` naming the fault and the handler. While a watchdog
runs, its reset comes first, as on the chip.

A write to nothing is an imprecise BusFault (the store is buffered: BFAR is not valid and
the stacked PC is the next instruction's); the rest are precise (the stacked PC is the
faulting instruction's). The run ends at the faulting instruction, as before, where the
vector is no handler (0, or without its Thumb bit), where the entry cannot stack its frame
(the stack below SRAM), and under GDB (the debugger is shown the faulting state).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

from unicorn import UC_HOOK_MEM_UNMAPPED
from unicorn import unicorn_const as U

from hexhil.hil.mcu.armv7m import (EXC_BUSFAULT, EXC_DEBUGMON, EXC_HARDFAULT, EXC_MEMMANAGE,
                                   EXC_PENDSV, EXC_SVCALL, EXC_SYSTICK, EXC_USAGEFAULT,
                                   INTR_BKPT, INTR_INVSTATE, INTR_NOCP, INTR_UDEF)
from hexhil.hil.mcu.core import NULL_JUMP, CoreFault
from hexhil.hil.mcu.timebase import FS_PER_S
from hexhil.hil.mcu.verdicts import SYSTEM_EXCEPTIONS, Verdict
from hexhil.hil.run_result import Ending

log = logging.getLogger(__name__)
NAMES = {EXC_HARDFAULT: "HardFault", EXC_MEMMANAGE: "MemManage", EXC_BUSFAULT: "BusFault",
         EXC_USAGEFAULT: "UsageFault"}
SHCSR, CFSR, HFSR, MMFAR, BFAR = 0x24, 0x28, 0x2C, 0x34, 0x38     # SCB offsets
ENABLE_BIT = {EXC_MEMMANAGE: 16, EXC_BUSFAULT: 17, EXC_USAGEFAULT: 18}   # SHCSR's fault enables
ACTIVE_BIT = {EXC_MEMMANAGE: 0, EXC_BUSFAULT: 1, EXC_USAGEFAULT: 3, EXC_SVCALL: 7,
              EXC_DEBUGMON: 8, EXC_PENDSV: 10, EXC_SYSTICK: 11}
HFSR_FORCED, HFSR_DEBUGEVT = 1 << 30, 1 << 31
MMARVALID, BFARVALID = 1 << 7, 1 << 15
WATCHDOGS = ("IWDG", "WWDG")


@dataclass(frozen=True)
class Cause:
    """A fault as the core records it: its exception, its CFSR/HFSR bit and their name,
    whether MMFAR/BFAR hold the address, whether it is imprecise (stacked PC after)."""

    exc: int
    bits: int
    name: str
    hfsr: int = 0
    address: bool = False
    imprecise: bool = False


CAUSES = {
    ("intr", INTR_UDEF): Cause(EXC_USAGEFAULT, 1 << 16, "UNDEFINSTR"),
    ("intr", INTR_INVSTATE): Cause(EXC_USAGEFAULT, 1 << 17, "INVSTATE"),
    ("intr", INTR_NOCP): Cause(EXC_USAGEFAULT, 1 << 19, "NOCP"),
    ("intr", INTR_BKPT): Cause(EXC_HARDFAULT, 0, "DEBUGEVT", HFSR_DEBUGEVT),
    NULL_JUMP: Cause(EXC_USAGEFAULT, 1 << 17, "INVSTATE"),
    ("uc", U.UC_ERR_INSN_INVALID): Cause(EXC_USAGEFAULT, 1 << 16, "UNDEFINSTR"),
    ("uc", U.UC_ERR_READ_UNALIGNED): Cause(EXC_USAGEFAULT, 1 << 24, "UNALIGNED"),
    ("uc", U.UC_ERR_WRITE_UNALIGNED): Cause(EXC_USAGEFAULT, 1 << 24, "UNALIGNED"),
    ("uc", U.UC_ERR_READ_UNMAPPED): Cause(EXC_BUSFAULT, 1 << 9 | BFARVALID, "PRECISERR",
                                          address=True),
    ("uc", U.UC_ERR_WRITE_UNMAPPED): Cause(EXC_BUSFAULT, 1 << 10, "IMPRECISERR", imprecise=True),
    ("uc", U.UC_ERR_FETCH_UNMAPPED): Cause(EXC_BUSFAULT, 1 << 8, "IBUSERR"),
    ("uc", U.UC_ERR_FETCH_PROT): Cause(EXC_MEMMANAGE, 1 << 0, "IACCVIOL"),
}


def intr_fault(intno: int) -> CoreFault:
    """What Unicorn's interrupt ``intno`` is on the chip, as a fault."""
    text = {INTR_UDEF: "an undefined instruction (UsageFault)",
            INTR_NOCP: "a coprocessor instruction with the FPU off (UsageFault NOCP)",
            INTR_INVSTATE: "a branch to ARM state (UsageFault INVSTATE: an address without "
            "its Thumb bit)"}.get(intno, f"CPU exception {intno}")
    return CoreFault(text, ("intr", intno))


class FaultStatus:
    """SCB's SHCSR (the fault enables; the active bits from the core), CFSR and HFSR
    (write 1 to clear), MMFAR and BFAR, at their reset values."""

    def __init__(self, core: Any, nvic: Any) -> None:
        self.core, self.nvic = core, nvic
        self.enables = self.cfsr = self.hfsr = self.mmfar = self.bfar = 0

    def read(self, offset: int) -> int:
        if offset == SHCSR:
            active = self.core.active
            svc_pended = EXC_SVCALL in self.nvic.pending
            return (self.enables | sum(1 << b for e, b in ACTIVE_BIT.items() if e in active)
                    | (svc_pended << 15))
        return {CFSR: self.cfsr, HFSR: self.hfsr, MMFAR: self.mmfar,
                BFAR: self.bfar}.get(offset, 0)

    def write(self, offset: int, value: int) -> None:
        if offset == SHCSR:
            self.enables = value & 0x70000
        elif offset == CFSR:
            self.cfsr &= ~value
        elif offset == HFSR:
            self.hfsr &= ~value
        elif offset == MMFAR:
            self.mmfar = value
        elif offset == BFAR:
            self.bfar = value

    def enabled(self, exc: int) -> bool:
        return bool(self.enables >> ENABLE_BIT[exc] & 1)


@dataclass(frozen=True)
class Taken:
    """A fault taken as an exception, while its handler runs."""

    line: str           # the fault's one line: its cause, the PC, the function, the time
    exc: int
    cause: str          # "UNDEFINSTR", with ", escalated: HFSR FORCED" where it was
    handler: str
    at_fs: int

    def text(self, how: str) -> str:
        return (f"{self.line}; the core took {NAMES[self.exc]} ({self.cause}) and its "
                f"handler {self.handler} {how}")


class Faults:
    """One board's fault exceptions: ``take`` a fault, then watch its handler."""

    def __init__(self, board: Any, limit_s: float) -> None:
        self.board = board
        self.limit_fs = int(limit_s * FS_PER_S)
        self.taken: Taken | None = None
        self.lines: list[str] = []          # every fault taken in the run, for its result
        self._address = 0
        board.core.uc.hook_add(UC_HOOK_MEM_UNMAPPED, self._unmapped)

    def _unmapped(self, _uc: Any, _access: int, addr: int, _size: int, _value: int,
                  _data: Any) -> bool:
        self._address = addr           # BFAR's, for a precise BusFault
        return False

    def take(self, fault: CoreFault) -> bool:
        """Take ``fault`` (raised at the core's PC) as its exception, as the chip does:
        False where it stays the run's end (no such fault on the chip, a debugger attached,
        a vector that is no handler); a lockup raises its one line."""
        board = self.board
        cause = CAUSES.get(getattr(fault, "origin", None))   # type: ignore[arg-type]
        if cause is None or board.debugger is not None:
            return False
        core = board.core
        line = board.fault_line(str(fault))
        exc, name = self._route(cause)
        if exc is None:
            raise CoreFault(f"{line}; a lockup: it faulted where even HardFault cannot be "
                            f"taken ({name})")
        vector = core.read32(core.vtor_base() + 4 * exc)
        if vector == 0 or not vector & 1:
            return False
        status = board.ppb.faults
        status.cfsr |= cause.bits
        status.hfsr |= cause.hfsr | (HFSR_FORCED if exc != cause.exc else 0)
        if cause.address:
            status.bfar = self._address
        if cause.imprecise:
            core.pc += 4 if core.read16(core.pc) >> 11 in (0x1D, 0x1E, 0x1F) else 2
        try:
            core.enter(exc)
        except CoreFault as exc_text:        # the frame could not be stacked
            raise CoreFault(f"{line}; a lockup: {exc_text}") from None
        self.taken = Taken(line, exc, name, board.image.function_at(vector & ~1),
                           core.now_fs())
        self.lines.append(line)
        log.debug("firmware %s: %s; taken as %s (%s)", board.image.path.name, line,
                    NAMES[exc], name)
        return True

    def _route(self, cause: Cause) -> tuple[int | None, str]:
        """The exception ``cause`` is taken as (None: a lockup) and its name."""
        nvic = self.board.nvic
        level = nvic.execution_priority()
        exc, name = cause.exc, cause.name
        if exc != EXC_HARDFAULT and not (self.board.ppb.faults.enabled(exc) and
                                         nvic.group_priority(exc) < level):
            exc, name = EXC_HARDFAULT, f"{name}, escalated: HFSR FORCED"
        if exc == EXC_HARDFAULT and level < 0:
            return None, name
        return exc, name

    def _watchdog(self) -> bool:
        """A watchdog runs: its reset ends a spin, as on the chip."""
        return any(p.name in WATCHDOGS and p.running for p in self.board.extra)

    def _handling(self) -> Taken | None:
        """The fault whose handler still runs, while no watchdog would reset the MCU."""
        t = self.taken
        if t is not None and t.exc not in self.board.core.active:
            t = self.taken = None
        return None if t is None or self._watchdog() else t

    def at_branch_to_self(self) -> None:
        """After a chunk that ended at a branch to itself with an exception active: a
        fault's handler spinning ends the run, else a handler that nothing enabled could
        ever preempt is a lockup (the startup's Default_Handler for an interrupt without a
        handler of its own)."""
        board = self.board
        core = board.core
        t = self._handling()
        if t is not None:
            raise CoreFault(t.text(f"then spun in a loop that branches to itself at PC "
                                   f"0x{core.pc:08x} (t={board.now_us() * 1e-6:.6f} s)"))
        if self._watchdog() or board.nvic.could_preempt(board.systick.csr & 3 == 3):
            return
        exc = core.active[-1]
        name = SYSTEM_EXCEPTIONS.get(exc, f"interrupt {exc - 16} (exception {exc})")
        raise CoreFault(board.fault_line(
            f"a lockup: {name} runs a loop that branches to itself and nothing can preempt "
            "it (an interrupt enabled without a handler of its own?)"))

    def sample(self) -> None:
        """At the board's tick: a fault's handler still running after the limit ends the
        run (a loop that makes no progress, or one that waits for what cannot come)."""
        board = self.board
        t = self._handling()
        if t is None or board.endings.verdict is not None:
            return
        now = board.core.now_fs()
        if now - t.at_fs >= self.limit_fs:
            pc = board.core.pc
            board.endings.ended_with(Verdict(Ending.CRASHED, "faulted: " + t.text(
                f"was still running after {(now - t.at_fs) / FS_PER_S:.3f} s, at PC "
                f"0x{pc:08x} in {board.image.function_at(pc)} "
                f"(t={board.now_us() * 1e-6:.6f} s)"), 1))

    def reset(self) -> str:
        """A system reset: the fault whose handler asked for it (its words for the log)."""
        t, self.taken = self.taken, None
        return f" from {t.handler} after {t.line}" if t is not None else ""
