"""The peripherals beyond the core's, the clocks, GPIO and the USARTs: TIM2-5, DMA1/2 and
bxCAN1, each at its RM0383 base address (hil/mcu/board.py maps them).

* TIM2-5 (RM0383 13), and TIM1 and TIM9-11 (RM0383 12, 14; built from hil/mcu/platform.py,
  ``apb2_timer``): up-counting at TIMxCLK / (PSC + 1), the update event at ARR (UIF, its
  interrupt, one-pulse mode, UG), the compare flags CCxIF when the counter reaches CCRx
  (at the update for CCR = 0) and their interrupts. Not modelled: down/centre counting,
  input capture, PWM outputs, slave modes, TIM1's repetition counter and break, preload
  timing (PSC and ARR take effect at once).
* DMA1/DMA2 (RM0383 9): the streams and channels the USARTs use (USART2: DMA1 stream 6
  channel 4 TX, stream 5 channel 4 RX; USART1: DMA2 stream 7 / 2 and 5, channel 4; USART6:
  DMA2 stream 6 and 7 / 1 and 2, channel 5), byte transfers, MINC, circular mode, HT/TC
  flags and interrupts. Not modelled: memory-to-memory, FIFO mode and bursts, double
  buffer, transfer errors.
* bxCAN1 at 0x4000_6400, the F4 family's address. The STM32F411 itself has **no** bxCAN:
  it is modelled so that a CAN firmware for a bigger F4 runs on the robot's virtual CAN
  bus. Initialisation and sleep handshakes, three TX mailboxes (sent at once), FIFO 0 of
  three frames with FMP/FULL/FOVR and the FMPIE0 interrupt. Not modelled: filters (every
  frame reaches FIFO 0), FIFO 1, bit timing, error counters, extended IDs on the link.
"""
from __future__ import annotations

import logging
from typing import Any

from hexhil.hil.mcu.timebase import FS_PER_S
from hexhil.hil.mcu.system import IRQS

log = logging.getLogger(__name__)
UIF, UIE, CEN, OPM = 1, 1, 1, 1 << 3


CCR = (0x34, 0x38, 0x3C, 0x40)      # CCR1-CCR4; their flags are SR bits 1-4, DIER's too


class BasicTimer:
    """TIM1-5 and TIM9-11 as up-counters with update interrupts and compare flags
    (``apb2``: clocked from APB2, as TIM1 and TIM9-11). ``irqs`` maps "update" and "cc"
    to IRQ numbers; IRQs shared with another timer go through the board's ``irq_lines``."""

    pollable = frozenset({0x00, 0x0C, 0x10})

    def __init__(self, board: Any, name: str, irq: int, bits: int, apb2: bool = False,
                 cc_irq: int | None = None, channels: int = 4) -> None:
        self.board, self.name, self.irq = board, name, irq
        self.cc_irq = irq if cc_irq is None else cc_irq
        self.apb2, self.channels = apb2, channels
        self.top = (1 << bits) - 1
        self.regs = {0x00: 0, 0x0C: 0, 0x10: 0, 0x28: 0, 0x2C: self.top}
        self._c0 = 0
        self._t0 = 0
        self.update = board.events.timer(self._overflow)
        self.compare = board.events.timer(self._compared)

    def _hz(self) -> int:
        return self.board.rcc.timer_hz(self.apb2) // (self.regs[0x28] + 1)

    def count(self) -> int:
        return self._count_at(self.board.core.now_fs())

    def _count_at(self, at_fs: int) -> int:
        if not self.regs[0x00] & CEN:
            return self._c0
        ticks = (at_fs - self._t0) * self._hz() // FS_PER_S
        return (self._c0 + ticks) % (self.regs[0x2C] + 1)

    def _anchor(self, value: int) -> None:
        self._c0, self._t0 = value, self.board.core.now_fs()
        if self.regs[0x00] & CEN and self.regs[0x2C]:
            left = self.regs[0x2C] + 1 - value
            self.update.set(self._t0 + -(-left * FS_PER_S // self._hz()))
        else:
            self.update.clear()
        self._next_compare(value)

    def _ccrs(self) -> list[int]:
        return [self.regs.get(CCR[i], 0) for i in range(self.channels)]

    def _next_compare(self, now: int) -> None:
        """The next instant the counter reaches a CCR above ``now`` in this period (a CCR
        of 0 matches at the update, ``_overflow``)."""
        arr = self.regs[0x2C]
        ahead = [ccr - self._c0 for ccr in self._ccrs() if now < ccr <= arr]
        if ahead and self.regs[0x00] & CEN:
            self.compare.set(self._t0 + -(-min(ahead) * FS_PER_S // self._hz()))
        elif self.compare.at_fs is not None:
            self.compare.clear()

    def _matched(self, low: int, high: int) -> None:
        """CCxIF for each channel whose CCR the counter reached in ``low..high``."""
        for i, ccr in enumerate(self._ccrs()):
            if low <= ccr <= high:
                self.regs[0x10] |= 2 << i

    def _compared(self, at_fs: int) -> None:
        now = self._count_at(at_fs)
        self._matched(self._c0 + 1, now)
        self._line()
        self._next_compare(now)

    def _overflow(self, at_fs: int) -> None:
        self.regs[0x10] |= UIF
        self._matched(0, 0)
        self._line()
        if self.regs[0x00] & OPM:
            self.regs[0x00] &= ~CEN
            self._c0 = 0
            return
        self._c0, self._t0 = 0, at_fs
        period = self.regs[0x2C] + 1
        self.update.set(at_fs + -(-period * FS_PER_S // self._hz()))
        self._next_compare(0)

    def _line(self) -> None:
        sr, dier = self.regs[0x10], self.regs[0x0C]
        update, cc = bool(sr & dier & UIF), bool(sr & dier & 0x1E)
        lines = self.board.irq_lines
        if self.cc_irq == self.irq:
            lines(self.irq, self, update or cc)
        else:
            lines(self.irq, self, update)
            lines(self.cc_irq, self, cc)

    def rebase(self) -> None:
        self._anchor(self.count())

    def read(self, off: int) -> int:
        if off == 0x24:
            return self.count()
        return self.regs.get(off, 0)

    def write(self, off: int, value: int) -> None:
        now = self.count()
        if off == 0x10:
            self.regs[0x10] &= value
        elif off == 0x14:
            if value & 1:                 # UG: reload, and an update event unless URS
                now = 0
                if not self.regs[0x00] & 4:
                    self.regs[0x10] |= UIF
        elif off == 0x24:
            now = value & self.top
        else:
            self.regs[off] = value & (self.top if off in (0x2C, *CCR) else 0xFFFFFFFF)
        self._anchor(now)
        self._line()


class IrqLines:
    """Interrupt lines that several peripherals share (TIM1's update and TIM10's on IRQ
    25): an IRQ is high while any of its sources holds it high."""

    def __init__(self, line: Any) -> None:
        self.line = line
        self.high: dict[int, set[int]] = {}

    def __call__(self, irq: int, source: object, level: bool) -> None:
        held = self.high.setdefault(irq, set())
        if level:
            held.add(id(source))
        else:
            held.discard(id(source))
        self.line(irq, bool(held))


FLAG_SHIFT = (0, 6, 16, 22)
TCIF, HTIF, TEIF = 0x20, 0x10, 0x08
EN, TEIE, HTIE, TCIE, CIRC, MINC = 1, 1 << 2, 1 << 3, 1 << 4, 1 << 8, 1 << 10
# (DMA controller, stream, channel, direction bits: 1 memory->peripheral, 0 the other way)
USART_DMA = {"USART2": ((1, 6, 4, 1), (1, 5, 4, 0)),
             "USART1": ((2, 7, 4, 1), (2, 2, 4, 0), (2, 5, 4, 0)),
             "USART6": ((2, 6, 5, 1), (2, 7, 5, 1), (2, 1, 5, 0), (2, 2, 5, 0))}


class Dma:
    """One DMA controller's eight streams, serving the USARTs' requests."""

    pollable = frozenset({0x00, 0x04} | {0x10 + 0x18 * s + r for s in range(8) for r in (0, 4)})

    def __init__(self, board: Any, number: int) -> None:
        self.board, self.number = board, number
        self.name = f"DMA{number}"
        self.flags = [0] * 8
        self.regs = {0x10 + 0x18 * s + r: (0x21 if r == 0x14 else 0)
                     for s in range(8) for r in range(0, 0x18, 4)}
        self.done = [0] * 8          # items moved since EN
        self.irqs = IRQS[self.name]

    def _reg(self, s: int, r: int) -> int:
        return self.regs[0x10 + 0x18 * s + r]

    def _ready(self, s: int, channel: int, to_periph: int) -> bool:
        cr = self._reg(s, 0)
        return bool(cr & EN) and (cr >> 25) & 7 == channel and (cr >> 6) & 3 == to_periph \
            and self._reg(s, 4) > 0

    def _step(self, s: int) -> int:
        """Account one byte moved on stream ``s``; the memory address it used."""
        cr, base = self._reg(s, 0), 0x10 + 0x18 * s
        addr = self._reg(s, 0xC) + (self.done[s] if cr & MINC else 0)
        self.done[s] += 1
        left = self.regs[base + 4] - 1
        total = left + self.done[s]
        if left == total // 2:
            self.flags[s] |= HTIF
        if left == 0:
            self.flags[s] |= TCIF
            if cr & CIRC:
                left, self.done[s] = total, 0
            else:
                self.regs[base] &= ~EN
        self.regs[base + 4] = left
        self._line(s)
        return addr

    def pull(self, s: int, channel: int) -> int | None:
        if not self._ready(s, channel, 1):
            return None
        return self.board.core.uc.mem_read(self._step(s), 1)[0]

    def push(self, s: int, channel: int, byte: int) -> bool:
        if not self._ready(s, channel, 0):
            return False
        self.board.core.uc.mem_write(self._step(s), bytes((byte,)))
        return True

    def _line(self, s: int) -> None:
        cr, f = self._reg(s, 0), self.flags[s]
        level = bool((f & TCIF and cr & TCIE) or (f & HTIF and cr & HTIE) or (f & TEIF and cr & TEIE))
        self.board.nvic.line(self.irqs[s], level)

    def read(self, off: int) -> int:
        if off in (0x00, 0x04):
            first = 0 if off == 0 else 4
            return sum(self.flags[first + i] << FLAG_SHIFT[i] for i in range(4))
        return self.regs.get(off, 0)

    def write(self, off: int, value: int) -> None:
        if off in (0x08, 0x0C):
            first = 0 if off == 0x08 else 4
            for i in range(4):
                self.flags[first + i] &= ~(value >> FLAG_SHIFT[i]) & 0x3D
                self._line(first + i)
            return
        if off not in self.regs:
            return
        s, r = (off - 0x10) // 0x18, (off - 0x10) % 0x18
        was = self._reg(s, 0) & EN
        self.regs[off] = value
        if r == 0:
            if value & EN and not was:
                self.done[s] = 0
                self.board.dma_kick()
            self._line(s)


def wire_usart_dma(usart: Any, controllers: dict[int, Dma]) -> None:
    """Give ``usart`` its DMA requests (its TXE and RXNE served by these streams)."""
    routes = USART_DMA[usart.name]

    def tx() -> int | None:
        for ctl, s, ch, to_periph in routes:
            if to_periph:
                byte = controllers[ctl].pull(s, ch)
                if byte is not None:
                    return byte
        return None

    def rx(byte: int) -> bool:
        return any(controllers[ctl].push(s, ch, byte)
                   for ctl, s, ch, to_periph in routes if not to_periph)

    usart.dma_tx, usart.dma_rx = tx, rx


class BxCan:
    """bxCAN1 (see the module docstring: the F411 has none; modelled for F4 CAN firmware)."""

    name = "CAN1"
    pollable = frozenset({0x04, 0x08, 0x0C, 0x10})

    def __init__(self, board: Any) -> None:
        self.board = board
        self.regs: dict[int, int] = {0x00: 0x00010002, 0x04: 0x00000C02, 0x08: 0x1C000000,
                                     0x14: 0, 0x1C: 0x01230000}
        self.fifo: list[tuple[int, bytes]] = []
        self.overrun = False

    @property
    def normal(self) -> bool:
        return not self.regs[0x00] & 3

    def received(self, arb_id: int, data: bytes) -> None:
        if not self.normal:
            return
        if len(self.fifo) >= 3:
            self.overrun = True
        else:
            self.fifo.append((arb_id, data))
        self._lines()

    def _lines(self) -> None:
        ier, tsr = self.regs[0x14], self.regs[0x08]
        nvic = self.board.nvic
        nvic.line(IRQS["CAN1_RX0"], bool(ier & 2 and self.fifo))
        nvic.line(IRQS["CAN1_TX"], bool(ier & 1 and tsr & 0x010101))

    def _send(self, box: int) -> None:
        base = 0x180 + 0x10 * box
        tir = self.regs.get(base, 0)
        dlc = min(8, self.regs.get(base + 4, 0) & 0xF)
        data = (self.regs.get(base + 8, 0).to_bytes(4, "little")
                + self.regs.get(base + 12, 0).to_bytes(4, "little"))[:dlc]
        if tir & 4:
            log.warning("bxCAN: an extended-ID frame (0x%08x) is not carried by the link",
                        tir >> 3)
        else:
            self.board.link.can(tir >> 21, data)
        self.regs[base] = tir & ~1
        self.regs[0x08] |= (0x3 << 8 * box) | (1 << (26 + box))

    def read(self, off: int) -> int:
        if off == 0x0C:
            n = len(self.fifo)
            return n | (8 if n >= 3 else 0) | (0x10 if self.overrun else 0)
        if 0x1B0 <= off < 0x1C0:
            if not self.fifo:
                return 0
            arb_id, data = self.fifo[0]
            word = {0x1B0: arb_id << 21, 0x1B4: len(data),
                    0x1B8: int.from_bytes(data[:4].ljust(4, b"\0"), "little"),
                    0x1BC: int.from_bytes(data[4:8].ljust(4, b"\0"), "little")}
            return word[off]
        return self.regs.get(off, 0)

    def write(self, off: int, value: int) -> None:
        if off == 0x00:
            self.regs[0x00] = value
            self.regs[0x04] = (self.regs[0x04] & ~3) | (value & 1) | (value >> 1 & 1) << 1
            self.board.can_listening = self.normal
        elif off == 0x08:
            self.regs[0x08] &= ~(value & 0x0F0F0F)       # RQCP/TXOK... write 1 to clear
        elif off == 0x0C:
            if value & 0x20 and self.fifo:
                self.fifo.pop(0)
            if value & 0x10:
                self.overrun = False
        elif off in (0x180, 0x190, 0x1A0):
            self.regs[off] = value
            if value & 1 and self.normal:
                self._send((off - 0x180) // 0x10)
        elif off != 0x04:
            self.regs[off] = value
        self._lines()


TIMER_CHANNELS = {"TIM1": 4, "TIM9": 2, "TIM10": 1, "TIM11": 1}


def apb2_timer(board: Any, row: Any) -> BasicTimer:
    """TIM1 or TIM9-11 from its platform row (hil/mcu/platform.py): 16-bit on APB2, the
    update on the row's first IRQ, the compares on its second (TIM1_CC) or the same."""
    irqs = row.irq_numbers
    return BasicTimer(board, row.name, irqs[0], 16, apb2=True,
                      cc_irq=irqs[1] if len(irqs) > 1 else None,
                      channels=TIMER_CHANNELS[row.name])


def extra_peripherals(board: Any) -> list[Any]:
    """TIM2-5, the DMA controllers and bxCAN1 of ``board`` (mapped at their platform rows'
    bases, hil/mcu/platform.py); also wires the USARTs' DMA requests and the board's CAN input."""
    timers = [BasicTimer(board, name, IRQS[name], bits)
              for name, bits in (("TIM2", 32), ("TIM3", 16), ("TIM4", 16), ("TIM5", 32))]
    dmas = {1: Dma(board, 1), 2: Dma(board, 2)}
    for usart in board.usarts:
        wire_usart_dma(usart, dmas)
    board.can = BxCan(board)
    return [*timers, dmas[1], dmas[2], board.can]
