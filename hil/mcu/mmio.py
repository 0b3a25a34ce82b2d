"""The MCU's address space of registers as Unicorn MMIO callbacks: the peripherals at
0x4000_0000 (APB1, APB2, AHB1, a page of 1 KB each) and the core's private peripheral bus
at 0xE000_0000 (hil/mcu/system.py).

Every access first fires what fell due by its cycle, so a read sees the state of its own
instant. The peripheral callbacks go straight through ctypes (Unicorn's Python wrapper
costs two more Python frames an access) and find their peripheral in one dict of the
pages that answer now: a peripheral whose RCC clock is off is not there (the access is
logged once and reads 0), and the dict is rebuilt at each RCC write. A side-effect-free
read of a pollable register goes to the poll skipper (hil/mcu/poll.py). The board core's
callbacks (hil/mcu/board_core.c) front the region: the USARTs' pages, GPIOA's ODR and BSRR,
GPIOB's IDR and SysTick's CSR are served in C, every other register here.
"""
from __future__ import annotations

import ctypes
import logging
from typing import Any

from unicorn import Uc
from unicorn.unicorn_py3.unicorn import MMIO_READ_CFUNC, MMIO_WRITE_CFUNC, uclib

from hexhil.hil.mcu import platform
from hexhil.hil.mcu.bitband import BitBandAlias
from hexhil.hil.mcu.board_core import front
from hexhil.hil.mcu.elf_image import SRAM_BASE, SRAM_SIZE
from hexhil.hil.mcu.rcc import CLOCK_BITS

log = logging.getLogger(__name__)
PERIPH_BASE, PERIPH_SIZE = 0x40000000, 0x80000      # APB1, APB2, AHB1
PPB_BASE, PPB_SIZE = platform.row("PPB").base, platform.row("PPB").size
SRAM_ALIAS, PERIPH_ALIAS = 0x22000000, 0x42000000    # PM0214 2.2.5: the bit-band aliases
GPIOA = 0x40020000           # GPIOB and C in the next pages


class PeripheralSpace:
    """The register pages of ``board`` (hil/mcu/board.py) and Unicorn's view of them."""

    def __init__(self, board: Any) -> None:
        self.board = board
        self.unmodelled: set[int] = set()      # pages logged once
        self._pages: dict[int, Any] = {}
        self._gates: dict[int, tuple[int, int]] = {}
        self._live: dict[int, Any] = {}
        self._callbacks: tuple = ()

    def attach(self, uc: Uc) -> None:
        self._callbacks = (MMIO_READ_CFUNC(self.read), MMIO_WRITE_CFUNC(self.write),
                           MMIO_READ_CFUNC(self.ppb_read), MMIO_WRITE_CFUNC(self.ppb_write))
        shared = self.board.core.shared
        read, write, ppb_read = front(shared, *self._callbacks[:3])
        data = ctypes.addressof(shared)
        if uclib.uc_mmio_map(uc._uch, PERIPH_BASE, PERIPH_SIZE, read, data, write, data):
            raise RuntimeError("Unicorn refused to map the peripherals")
        if uclib.uc_mmio_map(uc._uch, PPB_BASE, PPB_SIZE, ppb_read, data,
                             self._callbacks[3], None):
            raise RuntimeError("Unicorn refused to map the private peripheral bus")
        for alias in self.aliases():
            alias.attach(uc, self.failed)

    def aliases(self) -> tuple[BitBandAlias, BitBandAlias]:
        """The bit-band aliases of SRAM and of the peripherals: an SRAM bit changes in
        place, a peripheral's register is read and written back whole, through the same
        callbacks as a plain access (its clock gate, its events due, the poll skipper)."""
        core = self.board.core
        return (BitBandAlias("SRAM", SRAM_BASE, SRAM_SIZE, SRAM_ALIAS,
                             core.read32, core.store32),
                BitBandAlias("peripherals", PERIPH_BASE, PERIPH_SIZE, PERIPH_ALIAS,
                             lambda addr: self.read(0, addr - PERIPH_BASE, 4, 0),
                             lambda addr, value: self.write(0, addr - PERIPH_BASE, 4,
                                                            value, 0)))

    def clear(self) -> None:
        """No peripheral mapped (a reset maps new ones)."""
        self._pages, self._gates, self._live = {}, {}, {}

    def map(self, base: int, periph: Any) -> None:
        page = (base - PERIPH_BASE) >> 10
        self._pages[page] = periph
        name = getattr(periph, "name", None)
        if name in CLOCK_BITS:
            self._gates[page] = CLOCK_BITS[name]

    def relive(self) -> None:
        """The pages whose peripheral answers now (its RCC clock on, or not gated): looked
        up once per access instead of the clock gate each time; rebuilt at each RCC write."""
        regs = self.board.rcc.regs
        self._live = {page: p for page, p in self._pages.items()
                      if page not in self._gates
                      or regs.get(self._gates[page][0], 0) >> self._gates[page][1] & 1}
        shared = self.board.core.shared
        for usart in self.board.usarts:       # board_core.c serves a USART's page if live
            shared.usart[usart.index].live = self._live.get(
                (platform.row(usart.name).base - PERIPH_BASE) >> 10) is usart
        shared.gpio_live = sum(1 << i for i, port in enumerate(self.board.gpio)
                               if self._live.get(((GPIOA - PERIPH_BASE) >> 10) + i) is port)

    def _unmodelled(self, addr: int, kind: str) -> None:
        page = addr & ~0x3FF
        if page not in self.unmodelled:
            self.unmodelled.add(page)
            log.warning("firmware %s an unmodelled peripheral at 0x%08x (reads 0, writes are "
                        "dropped)", kind, addr)

    def _dead(self, offset: int, kind: str) -> None:
        """An access to a page without a live peripheral: its clock is off, or nothing
        is modelled there (logged once a page)."""
        page = offset >> 10
        if page in self._pages:
            self._unmodelled(PERIPH_BASE + offset, f"used {self._pages[page].name} with "
                             "its RCC clock off:")
        else:
            self._unmodelled(PERIPH_BASE + offset, kind)

    @staticmethod
    def taken_next(board: Any) -> None:
        """A write that made an exception ready (an interrupt enable, a pending bit, a
        flag's interrupt): it is taken after this instruction, not at the chunk's end. One
        that only a mask holds back ends the chunk too: from here the core goes an
        instruction at a time until the unmasking (board_core.c ``bc_loop``)."""
        nvic = board.nvic
        if nvic.pending and (nvic.next_exception() is not None or nvic.masked_ready()):
            board.core.cut_after()

    def _due(self) -> None:
        """Fire what fell due by the instruction running now."""
        self.board.events.fire_due(self.board.core.now_fs())

    def failed(self, exc: BaseException) -> None:
        """An exception inside a callback: the chunk stops and ``emu_start`` raises it
        (what Unicorn's own callback wrapper does, which these callbacks bypass)."""
        core = self.board.core
        if core.uc._hook_exception is None:
            core.uc._hook_exception = exc
        core.shared.hook_failed = 1
        core.uc.emu_stop()

    def read(self, handle: int, offset: int, size: int, _ud: int) -> int:
        """Unicorn's MMIO read callback for the peripheral space, called through ctypes
        directly (Unicorn's Python wrapper costs two more Python frames a register)."""
        try:
            board = self.board
            board.core.shared.mmio_n += 1
            board.events.fire_due(board.core.now_fs())
            p = self._live.get(offset >> 10)
            if p is None:
                board.poll.other_access()
                self._dead(offset, "read")
                return 0
            off = offset & 0x3FC
            value = p.read(off)
            if size != 4 or offset & 3:
                value = (value >> 8 * (offset & 3)) & ((1 << 8 * size) - 1)
            if off not in p.pollable:
                board.poll.other_access()
            elif board.poll.polled(PERIPH_BASE + offset, value):
                value = (p.read(off) >> 8 * (offset & 3)) & ((1 << 8 * size) - 1)
            return value
        except BaseException as exc:      # noqa: B036 -- handed to emu_start, as Unicorn does
            self.failed(exc)
            return 0

    def write(self, handle: int, offset: int, size: int, value: int, _ud: int) -> None:
        try:
            board = self.board
            board.core.shared.mmio_n += 1
            board.events.fire_due(board.core.now_fs())
            board.poll.other_access()
            p = self._live.get(offset >> 10)
            if p is None:
                self._dead(offset, "wrote")
                return
            if size < 4:
                shift = 8 * (offset & 3)
                mask = ((1 << 8 * size) - 1) << shift
                value = (p.read(offset & 0x3FC) & ~mask) | ((value << shift) & mask) \
                    if p.pollable and (offset & 0x3FC) in p.pollable else value << shift
            p.write(offset & 0x3FC, value & 0xFFFFFFFF)
            if p is board.rcc:
                self.relive()
            self.taken_next(board)
        except BaseException as exc:      # noqa: B036
            self.failed(exc)

    def ppb_read(self, handle: int, offset: int, size: int, _ud: int) -> int:
        try:
            board = self.board
            board.core.shared.touched += 1      # Python took part (board_loop.py)
            board.core.shared.mmio_n += 1
            self._due()
            addr = PPB_BASE + offset
            value = (board.ppb.read(addr & ~3) >> 8 * (addr & 3)) & ((1 << 8 * size) - 1)
            if addr & ~3 not in board.ppb.pollable:
                board.poll.other_access()
            elif board.poll.polled(addr, value):
                value = (board.ppb.read(addr & ~3) >> 8 * (addr & 3)) & ((1 << 8 * size) - 1)
            return value
        except BaseException as exc:      # noqa: B036
            self.failed(exc)
            return 0

    def ppb_write(self, handle: int, offset: int, size: int, value: int, _ud: int) -> None:
        try:
            board = self.board
            board.core.shared.touched += 1
            board.core.shared.mmio_n += 1
            self._due()
            board.poll.other_access()
            addr = PPB_BASE + offset
            if size < 4 and (0xE000E400 <= addr < 0xE000E500 or
                             0xE000ED18 <= addr < 0xE000ED24):
                word = board.ppb.read(addr & ~3)
                shift = 8 * (addr & 3)
                mask = ((1 << 8 * size) - 1) << shift
                value = (word & ~mask) | ((value << shift) & mask)
            board.ppb.write(addr & ~3, value)
            self.taken_next(board)
        except BaseException as exc:      # noqa: B036
            self.failed(exc)
