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

The rules are the board core's (hil/mcu/board_core.c), for all three; ``Usart`` is what
the rest of the board asks of one. Where the bytes go is the board's: USART2's to the
servo line through the direction buffer (hil/mcu/servo_line.py), USART1's and USART6's to
the console, a byte at a time.
"""

from __future__ import annotations

from typing import Any, Callable

from hexhil.hil.mcu.board_core import Events, Timer, library
from hexhil.hil.mcu.board_layout import USARTS
from hexhil.hil.mcu.platform import VECTORS
from hexhil.hil.mcu.usart_registers import BRR, CR1, CR2, CR3, GTPR, SR


class Usart:
    """USART ``name`` in C: its registers, baud, DMA requests and the byte now on the wire
    (``shift_end``); ``dma_tx`` and ``dma_rx`` are set by the DMA controller."""

    pollable = frozenset({SR, CR1, CR2, CR3, BRR})

    def __init__(self, name: str, events: Events, pclk_hz: Callable[[], int]) -> None:
        self.name, self.irq, self.pclk_hz = name, VECTORS[name], pclk_hz
        self.index = USARTS.index(name)
        self._lib, self._ref, self._events = library(), events.ref, events
        self._st = events.shared.usart[self.index]
        self._lib.bc_usart_reset(self._ref, self.index)
        self.shift_end = Timer(events, lambda at: None, self._st.tid)
        self.dma_tx: Callable[[], int | None] | None = None
        self.dma_rx: Callable[[int], bool] | None = None

    def __setattr__(self, name: str, value: Any) -> None:
        object.__setattr__(self, name, value)
        if name in ("dma_tx", "dma_rx"):      # C asks Python only where a stream serves it
            setattr(self._st, name, value is not None)

    @property
    def regs(self) -> dict[int, int]:
        st = self._st
        return {SR: st.sr, BRR: st.brr, CR1: st.cr1, CR2: st.cr2, CR3: st.cr3, GTPR: st.gtpr}

    @property
    def tdr(self) -> int | None:
        """The byte waiting in DR for the shift register, or None."""
        return None if self._st.tdr < 0 else self._st.tdr

    @tdr.setter
    def tdr(self, value: int | None) -> None:
        self._st.tdr = -1 if value is None else value

    def baud(self) -> float:
        div = self._lib.bc_divider(self._ref, self.index)
        return self.pclk_hz() / div if div else 0.0

    def clock_changed(self) -> None:
        self._st.frame_fs = self._st.pclk = 0

    def dma_request(self) -> None:
        self._lib.bc_usart_dma_request(self._ref, self.index)
        self._raise()

    def read(self, off: int) -> int:
        value = self._lib.bc_usart_read(self._ref, self.index, off)
        self._raise()
        return value

    def write(self, off: int, value: int) -> None:
        self._lib.bc_usart_write(self._ref, self.index, off, value)
        self._raise()

    def _raise(self) -> None:
        """A Python call under C raised (a DMA stream's, the console's): raise it here."""
        if self._events.shared.err:
            self._events.raise_error()
