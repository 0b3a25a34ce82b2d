"""How a firmware ends on the chip where the host sees its process end: the run's verdict.

On the chip nothing exits: newlib's `_exit` (libnosys, CubeIDE's syscalls.c) is a loop,
`abort` ends in it, a failed `assert` prints its message through `__assert_func` and calls
`abort`, a return from `main` lands in the startup's loop after it, and CubeMX's
`Error_Handler` spins with interrupts masked. Each ends the run here as the same source
built for the host would end its process: `_exit(0)` and a `main` returning 0 before the
run's end are an early exit, any other status, `abort` and a failed assertion a crash, a
core running with PRIMASK or FAULTMASK set (awake) for longer than ``masked_limit_s`` of
virtual time a hang, and so is a handler that keeps an exception of its own priority or
lower pending for as long (``HAL_Delay`` in an interrupt above SysTick: the tick it waits
for is never taken), and a handler that branches to itself for as long while
something of a higher priority still preempts it (CubeMX's `Default_Handler` for an
interrupt without a handler, below SysTick); one that nothing can preempt is the board's
lockup at once (board.py ``_lockup``). Found from the ELF's symbols (a code hook at each
function's entry, and at the return address `main` was called with) and the core's state,
sampled at the board's tick (each 1 to 10 ms).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from unicorn import UC_HOOK_CODE, UcError
from unicorn import arm_const as A

from hexhil.hil.mcu.armv7m import (BRANCH_TO_SELF, EXC_BUSFAULT, EXC_HARDFAULT, EXC_MEMMANAGE,
                                   EXC_NMI, EXC_PENDSV, EXC_SVCALL, EXC_SYSTICK,
                                   EXC_USAGEFAULT)
from hexhil.hil.mcu.timebase import FS_PER_S
from hexhil.hil.run.limits import MASKED_LIMIT_S
from hexhil.hil.run_result import Ending

MAX_TEXT = 200              # of a string the firmware passed (a file name, an expression)
SYSTEM_EXCEPTIONS = {EXC_NMI: "the NMI handler", EXC_HARDFAULT: "the HardFault handler",
                     EXC_MEMMANAGE: "MemManage", EXC_BUSFAULT: "BusFault",
                     EXC_USAGEFAULT: "UsageFault", EXC_SVCALL: "the SVC handler",
                     EXC_PENDSV: "the PendSV handler", EXC_SYSTICK: "the SysTick handler"}


@dataclass(frozen=True)
class Verdict:
    """How the firmware ended: ``kind``, the one line naming the symbol, its status."""

    kind: Ending
    reason: str
    exit_code: int


def _signed(word: int) -> int:
    return word - (1 << 32) if word & 0x80000000 else word


class Endings:
    """The hooks and the masked-interrupt watch of one board; ``verdict`` once it ended."""

    def __init__(self, board: Any, masked_limit_s: float = MASKED_LIMIT_S) -> None:
        self.board = board
        self.verdict: Verdict | None = None
        self._limit_fs = int(masked_limit_s * FS_PER_S)
        self._masked_since: int | None = None
        self._masked_key: tuple[str | None, int | None] = (None, None)
        self._spin: tuple[int, int] | None = None    # (PC, since) of a handler's `b .`
        self._held: tuple[tuple[int, int], int] | None = None   # ((active, held), since)
        self._assertion: str | None = None
        self._returns: set[int] = set()
        symbols = board.image.symbols
        for name, hook in (("_exit", self._exit), ("abort", self._abort),
                           ("__assert_func", self._assert), ("main", self._main)):
            addr = symbols.get(name)
            if addr:
                self._hook(addr & ~1, hook)

    def _hook(self, addr: int, hook: Any) -> None:
        self.board.core.uc.hook_add(UC_HOOK_CODE, lambda uc, a, size, _: hook(), None,
                                    addr, addr)

    def _arg(self, n: int) -> int:
        return self.board.core.reg(A.UC_ARM_REG_R0 + n)

    def _string(self, addr: int) -> str:
        out = bytearray()
        try:
            while len(out) < MAX_TEXT:
                b = self.board.core.uc.mem_read(addr + len(out), 1)[0]
                if b == 0:
                    break
                out.append(b)
        except UcError:        # a bad pointer: what was read
            pass
        return out.decode(errors="replace")

    def _lr(self) -> int:
        return self.board.core.reg(A.UC_ARM_REG_LR)

    def _caller(self) -> str:
        return self.board.image.function_at(self._lr())

    # --- the hooks (inside a chunk: the verdict ends it at this instruction) --------
    def _end(self, kind: Ending, reason: str, code: int) -> None:
        if self.verdict is not None:
            return
        board = self.board
        self.ended_with(Verdict(kind, f"{reason} at t={board.now_us() * 1e-6:.6f} s", code))
        board.core.shared.touched += 1        # Python took part: the C loop hands over
        board.core.stop()

    def ended_with(self, verdict: Verdict) -> None:
        """The run's verdict; the byte waiting in USART1/6's DR reaches the console, as it
        would leave the chip."""
        self.verdict = verdict
        board = self.board
        now_fs = board.core.now_fs()
        for usart in (board.usart1, board.usart6):
            if usart.tdr is not None:
                board.sent(usart.tdr, now_fs)
                usart.tdr = None

    def _exit(self) -> None:
        code = _signed(self._arg(0))
        if code == 0:
            self._end(Ending.EXITED_EARLY, f"exited through _exit(0) (from {self._caller()}) "
                      "before the run's end", 0)
        else:
            self._end(Ending.CRASHED, f"exited with status {code} through _exit "
                      f"(from {self._caller()})", code & 0xFF or 1)

    def _abort(self) -> None:
        if self._assertion is not None:
            self._end(Ending.CRASHED, self._assertion, 1)
        else:
            self._end(Ending.CRASHED, f"called abort() (from {self._caller()})", 1)

    def _assert(self) -> None:
        """newlib's ``__assert_func(file, line, func, expr)``: named now, ended by its
        ``abort`` once the message is printed."""
        file, line, func, expr = (self._arg(i) for i in range(4))
        where = f" in {self._string(func)}" if func else ""
        self._assertion = (f"failed an assertion: assert({self._string(expr)}){where} at "
                           f"{self._string(file)}:{_signed(line)}")

    def _main(self) -> None:
        back = self._lr() & ~1
        if back and back not in self._returns:
            self._returns.add(back)
            self._hook(back, self._main_returned)

    def _main_returned(self) -> None:
        code = _signed(self._arg(0))
        if code == 0:
            self._end(Ending.EXITED_EARLY, "returned 0 from main before the run's end", 0)
        else:
            self._end(Ending.CRASHED, f"returned {code} from main", code & 0xFF or 1)

    # --- the board's tick -------------------------------------------------------------
    def sample(self) -> None:
        """At the board's tick: a core awake with interrupts masked since the first sample
        that saw it so for ``masked_limit_s`` is hung: by PRIMASK or FAULTMASK anywhere
        (CubeMX's Error_Handler), by BASEPRI at one branch to itself (FreeRTOS's
        ``configASSERT``: ``taskDISABLE_INTERRUPTS(); for (;;);``, where a critical
        section's BASEPRI is short); so is a handler seen at the same branch to itself at
        every sample for as long."""
        board = self.board
        core = board.core
        self._handler_spin(board, core)
        self._held_back(board, core)
        pc = core.pc
        mask = ("PRIMASK" if core.reg(A.UC_ARM_REG_PRIMASK) & 1 else
                "FAULTMASK" if core.reg(A.UC_ARM_REG_FAULTMASK) & 1 else
                "BASEPRI" if core.reg(A.UC_ARM_REG_BASEPRI) and
                core.read16(pc) == BRANCH_TO_SELF else None)
        key = (mask, pc if mask == "BASEPRI" else None)
        if mask is None or core.sleeping or self.verdict is not None:
            self._masked_since = None
            return
        now = core.now_fs()
        if self._masked_since is None or self._masked_key != key:
            self._masked_since, self._masked_key = now, key
        elif now - self._masked_since >= self._limit_fs:
            self.ended_with(Verdict(
                Ending.HUNG, f"hung: it ran with interrupts masked ({mask}) for "
                f"{(now - self._masked_since) / FS_PER_S:g} s, at PC 0x{pc:08x} in "
                f"{board.image.function_at(pc)} (t={board.now_us() * 1e-6:.6f} s)", 1))

    def _handler_spin(self, board: Any, core: Any) -> None:
        pc = core.pc
        if not core.shared.nactive or core.sleeping or core.read16(pc) != BRANCH_TO_SELF:
            self._spin = None
            return
        now = core.now_fs()
        if self._spin is None or self._spin[0] != pc:
            self._spin = (pc, now)
        elif now - self._spin[1] >= self._limit_fs and self.verdict is None:
            what = _exception(core.active[-1])
            self.ended_with(Verdict(
                Ending.HUNG, f"hung: {board.image.function_at(pc)} ({what}) ran a loop that "
                f"branches to itself for {(now - self._spin[1]) / FS_PER_S:g} s, at PC "
                f"0x{pc:08x} (t={board.now_us() * 1e-6:.6f} s)", 1))

    def _held_back(self, board: Any, core: Any) -> None:
        """A handler seen at every sample for ``masked_limit_s`` with the same exception
        pending behind it (its priority cannot preempt) is hung."""
        ready = board.nvic.ready() if core.shared.nactive and not core.sleeping else []
        if not ready or self.verdict is not None:
            self._held = None
            return
        key = (core.active[-1], min(ready))
        now = core.now_fs()
        if self._held is None or self._held[0] != key:
            self._held = (key, now)
        elif now - self._held[1] >= self._limit_fs:
            pc = core.pc
            self.ended_with(Verdict(
                Ending.HUNG, f"hung: {_exception(key[0])}'s handler ran "
                f"{(now - self._held[1]) / FS_PER_S:g} s with {_exception(key[1])} pending "
                f"behind it, never taken, at PC 0x{pc:08x} in {board.image.function_at(pc)} "
                f"(t={board.now_us() * 1e-6:.6f} s)", 1))


def _exception(exc: int) -> str:
    return f"interrupt {exc - 16}" if exc >= 16 else {15: "SysTick", 14: "PendSV",
                                                      11: "SVCall"}.get(exc, f"exception {exc}")
