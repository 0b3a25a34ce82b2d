"""The robot's STM32F411 board: the core, its peripherals at their RM0383 addresses, the
wiring to the servo line, the switches, the console and CAN, and the run loop.

The loop runs the core in chunks that end at the next scheduled event, so every flag
changes at its exact cycle. Waiting costs no host time: WFI/WFE sleep to the next event,
and a poll loop is skipped to it (hil/mcu/poll.py). The registers are Unicorn MMIO
callbacks (hil/mcu/mmio.py). SCB AIRCR SYSRESETREQ resets the MCU and the firmware starts
again from its reset vector while the world goes on (``reset_if_asked``).
"""
from __future__ import annotations

import logging
from collections import Counter
from typing import Any, Callable

from unicorn import arm_const as A

from hexhil.hil.mcu.armv7m import BRANCH_TO_SELF, EXC_SVCALL, INTR_BKPT, INTR_EXC_EXIT, INTR_SWI
from hexhil.hil.mcu.board_core import Events, NativeBoard, SharedField, Timer, require
from hexhil.hil.mcu.board_loop import handed_over, hook_interrupts, trips
from hexhil.hil.mcu.console import Console, semihost
from hexhil.hil.mcu.core import Core, CoreFault
from hexhil.hil.mcu.deadline import ControlCycles
from hexhil.hil.mcu.elf_image import ElfImage
from hexhil.hil.mcu.faults import Faults, intr_fault
from hexhil.hil.mcu.gpio import Exti, GpioPort, Syscfg
from hexhil.hil.mcu.gpio_registers import DIRECTION_PIN, SWITCH_PINS
from hexhil.hil.mcu.mmio import PeripheralSpace
from hexhil.hil.mcu.link_client import LinkClient
from hexhil.hil.mcu.poll import PollSkipper
from hexhil.hil.mcu.quiet import QuietLoops
from hexhil.hil.mcu.servo_line import ServoLine
from hexhil.hil.mcu.peripherals import IrqLines, extra_peripherals
from hexhil.hil.mcu import device_id, flash, platform
from hexhil.hil.mcu.rcc import CSR, HSI_HZ, Rcc, power
from hexhil.hil.mcu.rtc import Rtc
from hexhil.hil.mcu.system import Nvic, SystemBlock
from hexhil.hil.mcu.systick import SysTick
from hexhil.hil.mcu.timebase import FS_PER_US
from hexhil.hil.mcu.usart import Usart
from hexhil.hil.mcu.verdicts import Endings
from hexhil.hil.run.limits import MASKED_LIMIT_S
from hexhil.hil.mcu.world_sync import WorldSync

log = logging.getLogger(__name__)
MAX_CHUNK = 20_000           # instructions: the most an interrupt unmasked by CPSIE/MSR waits
CONSOLE_TAIL = 5             # console lines a run result keeps (its stderr_tail)


class Board:
    """One run of an ELF; ``run`` serves it until the host ends the run."""

    switches = SharedField("switches")                # pressed, a bit each (PB0-PB5)

    def __init__(self, image: ElfImage, exchange: Callable[[bytes, bool], bytes],
                 console_events: Callable[[str], list[tuple[int, str]]],
                 masked_limit_s: float = MASKED_LIMIT_S) -> None:
        require()                     # the hot path in C (hil/mcu/board_core.py)
        self.image = image
        self.console_events = console_events
        self.link = LinkClient(exchange)
        self.core = core = Core(image, HSI_HZ)
        self.shared = core.shared
        self.native = NativeBoard(self)
        self.events = Events(core.shared)
        # in C: PA1's turns, the clock
        self.link.turns = self.native.turns     # out before the next message
        core.now_fs = self.events.now_fs        # one C call (a callback asks it often)
        self.console = Console(self._console_line)
        self.console_tail: list[str] = []
        self.switches = 0
        self.exit_code: int | None = None
        self.ended = False
        self.fault: CoreFault | None = None   # raised in a hook, taken after the chunk
        self.resets = 0                # system resets taken (SYSRESETREQ, a watchdog)
        self.reset_causes: Counter[str] = Counter()
        self._reset_pending: str | None = None     # what asked for the reset
        self.noted: set[str] = set()   # registers without behaviour the log named
        self.debugger: Any = None      # hil/mcu/gdb.py, with --gdb
        self.cycles = ControlCycles(core)   # busy time per control cycle (deadline.py)
        self.line = ServoLine(self)
        self.space = PeripheralSpace(self)
        self._peripherals()
        self.sync = WorldSync(self)   # the link's replies, its sleeps
        self.space.attach(core.uc)
        flash.attach(self)            # stores to flash reach self.flash (hil/mcu/flash.py)
        self._system_memory = device_id.attach(core.uc)   # the unique ID, the flash size
        hook_interrupts(core.shared, core.uc)    # exception returns in C
        self.poll = PollSkipper(self)
        self.quiet = QuietLoops(self)
        self.endings = Endings(self, masked_limit_s)    # _exit, abort, assert, main's return
        self.faults = Faults(self, masked_limit_s)      # fault exceptions and their handlers

    @property
    def skipped_cycles(self) -> int:
        """Cycles that waits skipped (poll loops jumped over, hil/mcu/poll.py)."""
        return self.core.shared.skipped

    def _peripherals(self) -> None:
        """The MCU's peripherals in their reset state (power-on, and a system reset)."""
        core, ev = self.core, self.events
        self.nvic = Nvic(core)
        self.rcc = Rcc(ev, core.now_fs, self._clock_changed)
        self.systick = SysTick(core, ev, lambda: self.rcc.hclk_hz)
        self.ppb = SystemBlock(core, self.nvic, self.systick, self.request_reset)
        self.exti = Exti(self.nvic.line)
        self.irq_lines = IrqLines(self.nvic.line)
        space = self.space
        space.clear()
        gpio = [GpioPort(n, i, self._gpio_out, self._grounded(i), core.shared)
                for i, n in enumerate(("GPIOA", "GPIOB", "GPIOC"))]
        gpio[1].before_input = lambda: self.sync.fresh_switches()
        self.gpio = gpio
        self.usart1 = Usart("USART1", ev, lambda: self.rcc.pclk2_hz)
        self.usart2 = Usart("USART2", ev, lambda: self.rcc.pclk1_hz)
        self.usart6 = Usart("USART6", ev, lambda: self.rcc.pclk2_hz)
        self.usarts = (self.usart1, self.usart2, self.usart6)   # board_layout.py USARTS
        self.flash, self.pwr, self.rtc = flash.FlashInterface(self), power(), Rtc(self)
        self.can_listening = False     # bxCAN1 in normal mode: CAN input each millisecond
        self.extra = [*extra_peripherals(self), *platform.build(self)]
        for p in (*gpio, self.rcc, self.flash, self.pwr, self.rtc, self.exti, Syscfg(self.exti),
                  *self.usarts, *self.extra):
            space.map(platform.row(p.name).base, p)      # at its row's address
        space.relive()

    # --- the world ----------------------------------------------------------------
    def _grounded(self, port: int) -> Callable[[], int]:
        """The pins of ``port`` a pressed switch shorts to ground (PB0-PB5)."""
        if port != 1:
            return lambda: 0
        return lambda: self.switches & ((1 << SWITCH_PINS) - 1)

    def now_us(self) -> int:
        return self.core.now_fs() // FS_PER_US

    def can_received(self, arb_id: int, data: bytes) -> None:
        self.can.received(arb_id, data)

    def dma_kick(self) -> None:
        """A DMA stream was enabled: a USART whose request is already up is served."""
        for usart in self.usarts:
            usart.dma_request()

    # --- the console (USART1 and USART6) ----------------------------------------------
    def sent(self, byte: int, end_fs: int) -> None:
        """A console byte went out on the wire: it reaches the console at its end."""
        self.console.put(bytes((byte,)), end_fs // FS_PER_US)

    def _gpio_out(self, port: GpioPort, old_odr: int) -> None:
        if port.index == 0:
            self.line.pin(port.output(DIRECTION_PIN))

    def _console_line(self, at_us: int, text: str) -> None:
        self.console_tail = self.console_tail[-(CONSOLE_TAIL - 1):] + [text]
        for kind, body in self.console_events(text):
            self.link.event_at(at_us, kind, body)

    # --- clocks and reset -------------------------------------------------------------
    def _clock_changed(self) -> None:
        self.core.set_hz(self.rcc.hclk_hz)
        for usart in self.usarts:
            usart.clock_changed()
        self.systick.rebase()
        for p in self.extra:
            if hasattr(p, "rebase"):
                p.rebase()

    def request_reset(self, cause: str = "SYSRESETREQ") -> None:
        """SCB AIRCR SYSRESETREQ or a watchdog's timeout (``cause``: IWDG, WWDG): the chunk
        ends at this access (a write callback may stop the core: the store would run again
        on resume, but the core resumes at the reset vector instead), and the loop resets
        the MCU there, or at its head when a timer asked (``reset_if_asked``)."""
        self._reset_pending = cause
        self.core.stop()

    def reset_if_asked(self) -> bool:
        """The system reset asked for, if one was, as the chip's: the core and every
        peripheral back to their reset state (HSI 16 MHz, no clocks enabled, GPIO inputs,
        USARTs off, NVIC and SysTick cleared, VTOR 0, the FPU off), what they had scheduled
        dropped, the firmware again from its reset vector. SRAM keeps its contents (the
        startup code sets .data and .bss); virtual time, the link and the world go on. The
        bytes already on the servo line go out as sent, and PA1 falls (an input now)."""
        if not self._reset_pending:
            return False
        cause, self._reset_pending = self._reset_pending, None
        self.resets += 1
        self.reset_causes[cause] += 1
        flags = self.rcc.regs.get(CSR, 0)
        self.line.flush()
        old = [self.nvic, self.rcc, self.systick, self.ppb, self.exti, self.flash, *self.gpio,
               *self.usarts, *self.extra]
        for periph in old:
            for value in vars(periph).values():
                if isinstance(value, Timer):
                    value.clear()
        self.poll.forget()
        self.quiet.forget()
        rtc, bdcr = self.rtc, self.rcc.regs.get(0x70, 0)    # the backup domain goes on
        self._peripherals()
        rtc.survive_reset(self, bdcr)
        self.rcc.reset_by(cause, flags)
        self.core.vtor = 0
        self.core.fpu_on = False
        self.core.set_hz(self.rcc.hclk_hz)
        self.core.reset()
        self.line.pin(0)
        after = self.faults.reset()      # a fault handler's reset says which fault
        (log.info if cause == "SYSRESETREQ" and not after else log.warning)(
            "firmware %s: system reset (%s)%s at t=%.6f s, restarting from the reset vector",
            self.image.path.name, cause if cause == "SYSRESETREQ" else f"{cause} timeout",
            after, self.now_us() * 1e-6)
        return True

    # --- exceptions ---------------------------------------------------------------
    def intr(self, intno: int) -> None:
        """Unicorn's interrupt hook: an exception return, SVC, a breakpoint, a fault."""
        core = self.core
        uc = core.uc
        pc = core.reg(A.UC_ARM_REG_PC)    # an exception return's EXC_RETURN, SVC's next
        try:
            if intno == INTR_EXC_EXIT:
                exc = core.leave(pc | 1)
                self.nvic.returned(exc)
                nxt = self.nvic.next_exception()
                if nxt is not None:
                    self.nvic.take(nxt)     # tail-chained: the interrupted code waits
                elif core.sleeping:
                    core.stop()
            elif intno == INTR_SWI:
                core.pc = pc
                self.nvic.take(EXC_SVCALL)
            elif intno == INTR_BKPT:
                self._breakpoint(pc)
            else:
                raise intr_fault(intno)
        except CoreFault as exc:
            self.fault = exc
            uc.emu_stop()

    def _breakpoint(self, pc: int) -> None:
        core = self.core
        op = int.from_bytes(core.uc.mem_read(pc, 2), "little")
        if op != 0xBEAB:
            raise CoreFault(f"a breakpoint (BKPT 0x{op & 0xFF:02x}) with no debugger attached",
                            ("intr", INTR_BKPT))
        code = semihost(core, self.console)
        core.uc.reg_write(A.UC_ARM_REG_PC, (pc + 2) | 1)
        if code is not None:
            self.exit_code = code
            self.console.flush()
            core.uc.emu_stop()

    # --- the run --------------------------------------------------------------------
    def faulted(self, fault: CoreFault) -> None:
        """A fault: taken as its exception where the chip takes one (hil/mcu/faults.py),
        else the run's end in its one line."""
        self.fault = None
        if not self.faults.take(fault):
            raise CoreFault(self.fault_line(str(fault))) from None

    def fault_line(self, text: str) -> str:
        pc = self.core.pc
        return (f"{text} at PC 0x{pc:08x} in {self.image.function_at(pc)} "
                f"(t={self.now_us() * 1e-6:.6f} s)")

    def run(self) -> None:
        """Boot and run until the host ends the run, the firmware exits or faults
        (``CoreFault`` carrying the one line). The trips run in C (hil/mcu/board_loop.py)
        and come here where Python takes part; under GDB, before and after each chunk."""
        loop = trips(self.core)
        self.core.shared.debug = self.debugger is not None
        self.link.hello()
        n = -1
        while not self.ended and self.exit_code is None and self.endings.verdict is None:
            n = handed_over(self, loop(MAX_CHUNK, n))
        self.console.flush()
        self.line.flush()

    def after_chunk(self) -> None:
        """A chunk ran: its fault, a system reset, a lockup, the poll skipper's next step."""
        core = self.core
        if self.fault is not None:
            self.faulted(self.fault)
            return
        self.flash.settle()
        if self.reset_if_asked():
            return
        if core.shared.nactive and self.debugger is None and \
                core.read16(core.pc) == BRANCH_TO_SELF:
            self.faults.at_branch_to_self()
        self.poll.after_chunk()
        if self.debugger is not None:
            self.debugger.after_chunk()

    def close(self) -> None:
        self.link.close()
