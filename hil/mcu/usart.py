"""USART1/2/6 at register level (RM0383 19.6), bytes timed at the baud the firmware set.

The baud comes from BRR and the APB clock (OVER8 honoured); a frame is start + 8 or 9
data bits + the stop bits of CR2. A byte written to DR moves into the shift register at
once when it is free (TXE stays set), else waits in DR (TXE clear) until the shift
register takes it; TC sets when the last stop bit has gone. A byte received sets RXNE,
or ORE when RXNE was still set (the byte is lost). IDLE sets one frame after the last byte
received (an idle line for a character's time), once per burst, and clears by a read of
SR then DR; read without IDLEIE it is worked out at the read (no event is scheduled for
it, so a firmware that ignores it runs as before). Interrupts (TXEIE, TCIE, RXNEIE,
IDLEIE, EIE) and DMA requests (CR3 DMAT/DMAR, served by hil/mcu/peripherals.py ``Dma``)
as on the chip, so ``HAL_UARTEx_ReceiveToIdle_IT`` and ``_DMA`` get their bursts. HDSEL
(single wire): the receiver hears the transmitter's own bytes. Not modelled: parity
errors, framing/noise errors, LIN break detection, synchronous mode, smartcard, IrDA.

Where the bytes go is the board's (``UsartWiring``): USART1 and USART6 to the console.
USART2, on the servo line through the direction buffer, is the board core's
(hil/mcu/board_core.c, ``NativeUsart``): these rules in C.
"""
from __future__ import annotations

from typing import Callable, Protocol

from hexhil.hil.mcu.core import Core
from hexhil.hil.mcu.board_core import Events
from hexhil.hil.mcu.timebase import FS_PER_S
from hexhil.hil.mcu.usart_registers import (BRR, CR1, CR2, CR3, CTS, DMAR, DMAT, DR, EIE,
                                            GTPR, HDSEL, IDLE, IDLEIE, LBD, M_9BIT, ORE, OVER8,
                                            RE, RXNE, RXNEIE, SR, STOP_HALF_BITS, STOP_SHIFT, TC,
                                            TCIE, TE, TXE, TXEIE, UE)



class UsartWiring(Protocol):
    def sent(self, usart: "Usart", byte: int, start_fs: int, end_fs: int) -> None:
        """A byte started leaving the shift register at ``start_fs``."""

    def idle(self, usart: "Usart", at_fs: int) -> None:
        """The transmitter went idle (TC) at ``at_fs``."""


class Usart:
    pollable = frozenset({SR, CR1, CR2, CR3, BRR})

    def __init__(self, name: str, irq: int, core: Core, events: Events,
                 pclk_hz: Callable[[], int], line: Callable[[int, bool], None],
                 wiring: UsartWiring) -> None:
        self.name, self.irq, self.core = name, irq, core
        self.pclk_hz, self.line, self.wiring = pclk_hz, line, wiring
        self.regs = {SR: TXE | TC, BRR: 0, CR1: 0, CR2: 0, CR3: 0, GTPR: 0}
        self.tdr: int | None = None
        self.rdr = 0
        self._echo: int | None = None        # HDSEL: the byte on the wire comes back
        self._frame_fs = 0                   # 0: to be worked out (CR1, CR2, BRR, PCLK)
        self.shift_end = events.timer(self._shifted)
        self.idle_end = events.timer(self._idle)   # scheduled only with IDLEIE
        self._idle_at: int | None = None     # when the line will have been idle a frame
        self._idle_seen = False              # SR was read with IDLE: a DR read clears it
        self.dma_tx: Callable[[], int | None] | None = None     # set by the DMA controller
        self.dma_rx: Callable[[int], bool] | None = None

    # --- timing -------------------------------------------------------------------
    def divider(self) -> int:
        brr = self.regs[BRR] & 0xFFFF
        if self.regs[CR1] & OVER8:
            return (brr >> 4) * 8 + (brr & 7)
        return brr

    def baud(self) -> float:
        div = self.divider()
        return self.pclk_hz() / div if div else 0.0

    def frame_fs(self) -> int:
        """A frame's length; kept until CR1, CR2, BRR or the bus clock change."""
        if not self._frame_fs:
            regs = self.regs
            half_bits = 2 + 2 * (9 if regs[CR1] & M_9BIT else 8) \
                + STOP_HALF_BITS[(regs[CR2] >> STOP_SHIFT) & 3]
            self._frame_fs = half_bits * FS_PER_S * max(1, self.divider()) // (2 * self.pclk_hz())
        return self._frame_fs

    def clock_changed(self) -> None:
        self._frame_fs = 0

    # --- transmit -----------------------------------------------------------------
    def _transmit(self, byte: int, at_fs: int) -> None:
        regs = self.regs
        end = at_fs + (self._frame_fs or self.frame_fs())
        self.shift_end.set(end)
        regs[SR] &= ~TC
        self.wiring.sent(self, byte, at_fs, end)
        if regs[CR3] & HDSEL and regs[CR1] & RE:
            self._echo = byte

    def _shifted(self, at_fs: int) -> None:
        echo = self._echo
        if echo is not None:
            self._echo = None
            self.received(echo)
        if self.tdr is not None:
            byte, self.tdr = self.tdr, None
            self.regs[SR] |= TXE
            self._transmit(byte, at_fs)
            if self.regs[CR3] & DMAT:
                self.dma_request()
        else:
            self.regs[SR] |= TC
            self.wiring.idle(self, at_fs)
        self._irq()

    def _write_dr(self, byte: int) -> None:
        cr1 = self.regs[CR1]
        if not (cr1 & UE and cr1 & TE):
            return
        if self.shift_end.at_fs is None:
            self._transmit(byte, self.core.now_fs())
        else:
            self.tdr = byte
            self.regs[SR] &= ~TXE

    def dma_request(self) -> None:
        """TXE with DMAT: the DMA fills DR (twice when the shift register is free too)."""
        while self.regs[CR3] & DMAT and self.dma_tx is not None and self.regs[SR] & TXE \
                and self.regs[CR1] & UE and self.regs[CR1] & TE:
            byte = self.dma_tx()
            if byte is None:
                return
            self._write_dr(byte)

    # --- receive ------------------------------------------------------------------
    def received(self, byte: int) -> None:
        """A byte arrived at the RX pin now."""
        cr1 = self.regs[CR1]
        if not (cr1 & UE and cr1 & RE):
            return
        if self.regs[SR] & RXNE:
            self.regs[SR] |= ORE
        else:
            self.rdr = byte
            self.regs[SR] |= RXNE
            if self.regs[CR3] & DMAR and self.dma_rx is not None and self.dma_rx(byte):
                self.regs[SR] &= ~RXNE
        self._idle_at = self.core.now_fs() + (self._frame_fs or self.frame_fs())
        if cr1 & IDLEIE:
            self.idle_end.set(self._idle_at)
        self._irq()

    def _idle(self, at_fs: int | None = None) -> None:
        """The line has been idle a frame since the last byte received: IDLE."""
        self._idle_at = None
        self.idle_end.clear()
        self.regs[SR] |= IDLE
        self._irq()

    def _idle_now(self) -> None:
        """IDLE as of now (read without IDLEIE, nothing was scheduled for it)."""
        if self._idle_at is not None and self.core.now_fs() >= self._idle_at:
            self._idle()

    def _irq(self) -> None:
        sr, cr1 = self.regs[SR], self.regs[CR1]
        if not cr1 & (TXEIE | TCIE | RXNEIE | IDLEIE) and not self.regs[CR3] & EIE:
            self.line(self.irq, False)
            return
        level = bool(cr1 & UE) and bool(
            (cr1 & TXEIE and sr & TXE) or (cr1 & TCIE and sr & TC)
            or (cr1 & RXNEIE and sr & (RXNE | ORE)) or (cr1 & IDLEIE and sr & IDLE)
            or (self.regs[CR3] & EIE and sr & ORE))
        self.line(self.irq, level)

    # --- registers ----------------------------------------------------------------
    def read(self, off: int) -> int:
        if off == DR:
            self.regs[SR] &= ~(RXNE | ORE | (IDLE if self._idle_seen else 0))
            self._idle_seen = False
            self._irq()
            return self.rdr
        if off == SR:
            self._idle_now()
            self._idle_seen = bool(self.regs[SR] & IDLE)
        return self.regs.get(off, 0)

    def write(self, off: int, value: int) -> None:
        if off == DR:
            self._write_dr(value & 0x1FF)
        elif off == SR:
            self.regs[SR] &= value | ~(TC | RXNE | LBD | CTS)
        elif off in self.regs:
            self.regs[off] = value & 0xFFFF
            if off in (CR1, CR2, BRR):
                self._frame_fs = 0
            if off == CR1 and not value & UE:
                self.regs[SR] = TXE | TC
                self.tdr = None
                self.shift_end.clear()
                self._idle_at, self._idle_seen = None, False
            if off == CR1:
                self.idle_end.clear()
                if value & IDLEIE and self._idle_at is not None:
                    self._idle_now()
                    if self._idle_at is not None:
                        self.idle_end.set(self._idle_at)
            if off == CR3:
                self.dma_request()
        self._irq()
