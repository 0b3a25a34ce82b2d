"""The Cortex-M4's own peripherals (the private peripheral bus at 0xE000_0000): NVIC, SCB,
SysTick, DWT's cycle counter, CPACR and the FPU's context registers.

The NVIC decides which exception runs: enable, pending (set by a peripheral's interrupt
line, by ISPR, or by the SCB for PendSV and SysTick), 4 priority bits as on the F411,
AIRCR's PRIGROUP for preemption, PRIMASK/BASEPRI/FAULTMASK, tail-chaining (a pending
exception is taken at a return before the interrupted code runs again). A peripheral's
line is a level: an IRQ whose flag is still set when its handler returns is pending again.
"""
from __future__ import annotations

import ctypes
import logging

from typing import Any, Callable, Iterator


from hexhil.hil.mcu import platform
from hexhil.hil.mcu.armv7m import EXC_PENDSV, EXC_SYSTICK
from hexhil.hil.mcu.board_core import SharedField, library
from hexhil.hil.mcu.core import Core
from hexhil.hil.mcu.device_id import DBGMCU_IDCODE, IDCODE
from hexhil.hil.mcu.faults import FaultStatus
from hexhil.hil.mcu.platform import NUM_IRQS

CPUID = 0x410FC241            # Cortex-M4 r0p1
NVIC, SYSTICK, SCB, DWT = (platform.row(n).base for n in ("NVIC", "SysTick", "SCB", "DWT"))
CPACR, DEMCR, STIR, FPCCR = 0xE000ED88, 0xE000EDFC, 0xE000EF00, 0xE000EF34
SCR_SLEEPONEXIT, SCR_SLEEPDEEP, SCR_SEVONPEND = 0x2, 0x4, 0x10

log = logging.getLogger(__name__)


class SharedBits:
    """A set of small numbers, a bit each in a ``Shared`` array with their count beside it,
    where the compiled board (hil/mcu/board_core.c) reads them: the pending exceptions
    (C pends SysTick there, and asks Python whether one is ready only while one is
    pending), the enabled IRQs (C chooses the next exception) and the IRQ lines held high
    (C returns from an IRQ whose line is low)."""

    def __init__(self, shared: Any, words: str, count: str) -> None:
        self._st, self._words, self._count = shared, getattr(shared, words), count
        self._words[:] = [0, 0, 0, 0]
        setattr(shared, count, 0)

    def add(self, n: int) -> None:
        words, w, bit = self._words, n >> 5, 1 << (n & 31)
        if not words[w] & bit:
            words[w] |= bit
            setattr(self._st, self._count, getattr(self._st, self._count) + 1)

    def discard(self, n: int) -> None:
        words, w, bit = self._words, n >> 5, 1 << (n & 31)
        if words[w] & bit:
            words[w] &= ~bit
            setattr(self._st, self._count, getattr(self._st, self._count) - 1)

    def __contains__(self, n: int) -> bool:
        return bool(self._words[n >> 5] >> (n & 31) & 1)

    def __len__(self) -> int:
        return getattr(self._st, self._count)

    def __iter__(self) -> Iterator[int]:
        if not len(self):
            return iter(())
        return iter([32 * w + i for w, word in enumerate(self._words) if word
                     for i in range(32) if word >> i & 1])


class Nvic:
    """Which exception is pending, enabled, active, and which one runs next."""

    prigroup = SharedField("prigroup")                    # AIRCR PRIGROUP
    sleep_on_exit = SharedField("sleep_on_exit", bool)    # SCR SLEEPONEXIT

    def __init__(self, core: Core) -> None:
        self.core, self.shared = core, core.shared
        # the rules (priorities, grouping, the masks, the choice) are board_core.c's
        self._lib, self._ref = library(), ctypes.byref(core.shared)
        self.enabled = SharedBits(core.shared, "ena", "ena_n")        # IRQ numbers
        self.pending = SharedBits(core.shared, "pend", "pending_n")   # exception numbers
        self.lines = SharedBits(core.shared, "lines", "lines_n")   # IRQ lines held high
        self.prio = bytearray(16 + NUM_IRQS)
        self.set_priorities(0, bytes(16 + NUM_IRQS))
        self.prigroup = 0
        self.sleep_on_exit = False

    def set_priorities(self, exc: int, data: bytes) -> None:
        """Priority bytes from exception ``exc`` on, copied where C reads them."""
        self.prio[exc:exc + len(data)] = data
        ctypes.memmove(self.shared.prio, bytes(self.prio), len(self.prio))

    def line(self, irq: int, level: bool) -> None:
        """A peripheral's interrupt line ``irq`` is now ``level``."""
        if not level and irq not in self.lines:
            return
        if level:
            self.lines.add(irq)
            if irq + 16 not in self.core.active:
                self.pending.add(irq + 16)
        else:
            self.lines.discard(irq)

    def group_priority(self, exc: int) -> int:
        """The preemption priority of exception ``exc`` (lower preempts)."""
        return self._lib.bc_group_priority(self._ref, exc)

    def execution_priority(self) -> int:
        return self._lib.bc_execution_priority(self._ref)

    def ready(self) -> list[int]:
        """The pending exceptions that are enabled (a system exception always is)."""
        found, pending_from = [], self._lib.bc_pending_from
        exc = pending_from(self._ref, 0) if self.shared.pending_n else -1
        while exc >= 0:
            found.append(exc)
            exc = pending_from(self._ref, exc + 1)
        return found

    def next_exception(self) -> int | None:
        """The pending exception that preempts what runs now, if any."""
        exc = self._lib.bc_next_exception(self._ref)
        return None if exc < 0 else exc

    def masked_ready(self) -> bool:
        """A pending exception would preempt the active ones but for PRIMASK, BASEPRI or
        FAULTMASK: the instruction that unmasks it (CPSIE, MSR) may come at any moment, and
        the exception is taken right after it, as on the chip (board_layout.py MASKED_STEPS)."""
        return bool(self._lib.bc_masked_ready(self._ref))

    def could_preempt(self, systick_running: bool) -> bool:
        """An exception could still preempt what runs now: one pending, an enabled IRQ, or
        SysTick's while it counts with its interrupt on."""
        level = self.execution_priority()
        could = set(self.pending) | {irq + 16 for irq in self.enabled}
        if systick_running:
            could.add(EXC_SYSTICK)
        return any(self.group_priority(e) < level for e in could)

    def take(self, exc: int) -> None:
        self.pending.discard(exc)
        self.core.enter(exc)

    def returned(self, exc: int) -> None:
        if exc >= 16 and exc - 16 in self.lines:
            self.pending.add(exc)
        if not self.core.active and self.sleep_on_exit:
            self.core.sleeping = True

    def wakes(self) -> bool:
        """WFI ends: an enabled exception is pending (whatever its priority)."""
        return bool(self._lib.bc_wakes(self._ref))


class SystemBlock:
    """The private peripheral bus: SCB, NVIC, SysTick, DWT, CPACR, FPU context registers."""

    def __init__(self, core: Core, nvic: Nvic, systick: Any,
                 on_reset: Callable[[], None]) -> None:
        self.core, self.nvic, self.systick = core, nvic, systick
        self.on_reset = on_reset
        self.regs: dict[int, int] = {CPACR: 0, FPCCR: 0xC0000000, SCB + 0x14: 0x200}
        self.cyccnt_on = False
        self._cyc_base = 0
        self._cyc_anchor = 0
        self.pollable = frozenset({SYSTICK, SCB + 0x04})
        self.faults = FaultStatus(core, nvic)     # SHCSR, CFSR, HFSR, MMFAR, BFAR
        self._deep_named = False

    def cyccnt(self) -> int:
        if not self.cyccnt_on:
            return self._cyc_base & 0xFFFFFFFF
        return (self._cyc_base + self.core.now() - self._cyc_anchor) & 0xFFFFFFFF

    def _icsr(self) -> int:
        nvic, active = self.nvic, self.core.active
        ready = nvic.ready()
        v = (active[-1] if active else 0) | ((min(ready) if ready else 0) << 12)
        if any(e >= 16 for e in nvic.pending):
            v |= 1 << 22
        if EXC_PENDSV in nvic.pending:
            v |= 1 << 28
        if EXC_SYSTICK in nvic.pending:
            v |= 1 << 26
        if len(active) <= 1:
            v |= 1 << 11   # RETTOBASE
        return v

    def read(self, addr: int) -> int:
        nvic = self.nvic
        if SYSTICK <= addr < SYSTICK + 0x10:
            return self.systick.read(addr - SYSTICK)
        if 0xE000E100 <= addr < 0xE000E500:
            return self._nvic_read(addr)
        if addr == DWT + 4:
            return self.cyccnt()
        if addr == DWT:
            return 0x40000000 | int(self.cyccnt_on)
        if addr == SCB:
            return CPUID
        if addr == SCB + 0x04:
            return self._icsr()
        if addr == SCB + 0x08:
            return self.core.vtor
        if addr == SCB + 0x0C:
            return 0xFA050000 | (nvic.prigroup << 8)
        if addr == SCB + 0x10:
            return (SCR_SLEEPONEXIT if nvic.sleep_on_exit else 0) | self.regs.get(addr, 0)
        if SCB + 0x18 <= addr < SCB + 0x24:
            e = addr - (SCB + 0x18) + 4
            return int.from_bytes(nvic.prio[e:e + 4], "little")
        if SCB + 0x24 <= addr < SCB + 0x40:
            return self.faults.read(addr - SCB)
        if addr == DBGMCU_IDCODE:
            return IDCODE
        return self.regs.get(addr, 0)

    def _nvic_read(self, addr: int) -> int:
        nvic = self.nvic
        if addr >= 0xE000E400:
            e = addr - 0xE000E400 + 16
            return int.from_bytes(nvic.prio[e:e + 4].ljust(4, b"\0"), "little")
        group, word = (addr - 0xE000E100) // 0x80, (addr & 0x7F) // 4
        if word > 2:
            return 0
        bits = range(32 * word, min(32 * word + 32, NUM_IRQS))
        if group in (0, 1):
            have = nvic.enabled
            return sum(1 << (i & 31) for i in bits if i in have)
        if group in (2, 3):
            return sum(1 << (i & 31) for i in bits if i + 16 in nvic.pending)
        if group == 4:
            return sum(1 << (i & 31) for i in bits if i + 16 in self.core.active)
        return 0

    def write(self, addr: int, value: int) -> None:
        nvic = self.nvic
        if SYSTICK <= addr < SYSTICK + 0x10:
            self.systick.write(addr - SYSTICK, value)
        elif 0xE000E100 <= addr < 0xE000E400:
            group, word = (addr - 0xE000E100) // 0x80, (addr & 0x7F) // 4
            irqs = [32 * word + i for i in range(32) if value >> i & 1 and 32 * word + i < NUM_IRQS]
            for i in irqs:
                if group == 0:
                    nvic.enabled.add(i)
                elif group == 1:
                    nvic.enabled.discard(i)
                elif group == 2:
                    nvic.pending.add(i + 16)
                elif group == 3:
                    nvic.pending.discard(i + 16)
        elif 0xE000E400 <= addr < 0xE000E400 + NUM_IRQS:
            e = addr - 0xE000E400 + 16
            nvic.set_priorities(e, (value & 0xF0F0F0F0).to_bytes(4, "little")[:len(nvic.prio) - e])
        elif addr == STIR:
            if (value & 0x1FF) < NUM_IRQS:
                nvic.pending.add((value & 0x1FF) + 16)
        elif addr == DWT:
            on = bool(value & 1)
            if on != self.cyccnt_on:
                self._cyc_base, self._cyc_anchor = self.cyccnt(), self.core.now()
                self.cyccnt_on = on
        elif addr == DWT + 4:
            self._cyc_base, self._cyc_anchor = value, self.core.now()
        elif addr == SCB + 0x04:
            self._icsr_write(value)
        elif addr == SCB + 0x08:
            self.core.vtor = value & 0xFFFFFE00
        elif addr == SCB + 0x0C:
            if value >> 16 == 0x05FA:
                nvic.prigroup = (value >> 8) & 7
                if value & 4:
                    self.on_reset()
        elif addr == SCB + 0x10:
            nvic.sleep_on_exit = bool(value & SCR_SLEEPONEXIT)
            self.regs[addr] = value & (SCR_SLEEPDEEP | SCR_SEVONPEND)
            if value & SCR_SLEEPDEEP and not self._deep_named:
                self._deep_named = True
                log.warning("firmware set SCB SCR SLEEPDEEP: Stop and Standby modes are not "
                            "modelled, WFI and WFE sleep as in Sleep mode (clocks and SysTick "
                            "keep running)")
        elif SCB + 0x18 <= addr < SCB + 0x24:
            e = addr - (SCB + 0x18) + 4
            nvic.set_priorities(e, (value & 0xF0F0F0F0).to_bytes(4, "little"))
        elif SCB + 0x24 <= addr < SCB + 0x40:
            self.faults.write(addr - SCB, value)
        elif addr == CPACR:
            self.regs[addr] = value
            self.core.fpu_on = (value >> 20) & 0xF == 0xF
        else:
            self.regs[addr] = value

    def _icsr_write(self, value: int) -> None:
        pending = self.nvic.pending
        if value & (1 << 28):
            pending.add(EXC_PENDSV)
        if value & (1 << 27):
            pending.discard(EXC_PENDSV)
        if value & (1 << 26):
            pending.add(EXC_SYSTICK)
        if value & (1 << 25):
            pending.discard(EXC_SYSTICK)


def irq_of(name: str) -> int:
    """The F411's IRQ position of ``name`` (RM0383 table 37), for the peripherals."""
    return IRQS[name]


IRQS: dict[str, Any] = {
    "EXTI0": 6, "EXTI1": 7, "EXTI2": 8, "EXTI3": 9, "EXTI4": 10, "EXTI9_5": 23,
    "EXTI15_10": 40, "TIM2": 28, "TIM3": 29, "TIM4": 30, "TIM5": 50,
    "USART1": 37, "USART2": 38, "USART6": 71,
    "CAN1_TX": 19, "CAN1_RX0": 20, "CAN1_RX1": 21, "CAN1_SCE": 22,
    "DMA1": (11, 12, 13, 14, 15, 16, 17, 47), "DMA2": (56, 57, 58, 59, 60, 68, 69, 70),
}
