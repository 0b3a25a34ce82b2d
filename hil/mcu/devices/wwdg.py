"""WWDG, the window watchdog (RM0383 18): a 7-bit down-counter (CR T) on PCLK1 / 4096 /
2**WDGTB. Once WDGA is set (it cannot be cleared but by a reset) the MCU resets when T6
falls (the counter passes 0x40 to 0x3F) or when CR is written while the counter is still
above the window (CFR W), as the chip does (the board's ``request_reset``). The early
wakeup flag EWIF (and its interrupt, with EWI) comes as the counter reaches 0x40.
"""
from __future__ import annotations

from typing import Any

from hexhil.hil.mcu.timebase import FS_PER_S
from hexhil.hil.mcu.registers import Description, RegisterFile, reg

WWDG = Description("WWDG", (
    reg("CR", 0x00, 0x7F, "T:0-6:rw WDGA:7:rs"),
    reg("CFR", 0x04, 0x7F, "W:0-6:rw WDGTB:7-8:rw EWI:9:rs"),
    reg("SR", 0x08, 0x00, "EWIF:0:rc_w0"),
))
WDGA, EWI, EWIF = 1 << 7, 1 << 9, 1


class Wwdg(RegisterFile):
    def __init__(self, board: Any, row: Any) -> None:
        super().__init__(WWDG.renamed(row.name), board.noted)
        self.board, self.irq = board, row.irq_numbers[0]
        self._count0, self._t0 = 0x7F, 0
        self.expiry = board.events.timer(lambda at: board.request_reset(self.name))
        self.early = board.events.timer(self._early)
        self.behave("CR", read=lambda: WDGA & self.value("CR") | self.counter(),
                    write=self._cr)
        self.behave("CFR", write=lambda old, new: self.rebase())
        self.behave("SR", write=lambda old, new: self._line())
        # CR's counter moves between events: a poll of it runs, it is not skipped
        self.pollable = frozenset({self.offset("CFR"), self.offset("SR")})

    @property
    def running(self) -> bool:
        return bool(self.value("CR") & WDGA)

    def _tick_fs(self) -> int:
        divider = 4096 << self.field_value("CFR", "WDGTB")
        return divider * FS_PER_S // self.board.rcc.pclk1_hz

    def counter(self) -> int:
        if not self.running:
            return self.value("CR") & 0x7F
        gone = (self.board.core.now_fs() - self._t0) // self._tick_fs()
        return max(0x3F, self._count0 - gone)

    def _cr(self, old: int, new: int) -> None:
        was_running = bool(old & WDGA)
        if was_running and self.counter() > self.field_value("CFR", "W"):
            self.board.request_reset(self.name)      # refreshed outside the window
            return
        self._anchor(new & 0x7F)

    def _anchor(self, count: int) -> None:
        self._count0, self._t0 = count, self.board.core.now_fs()
        if not self.running:
            return
        tick = self._tick_fs()
        if count < 0x40:
            self.board.request_reset(self.name)
            return
        self.expiry.set(self._t0 + (count - 0x3F) * tick)
        self.early.set(self._t0 + (count - 0x40) * tick)

    def rebase(self) -> None:
        """PCLK1 or WDGTB changed: the count so far kept."""
        if self.running:
            self._anchor(self.counter())

    def _early(self, at_fs: int) -> None:
        self.set_bits("SR", EWIF)
        self._line()

    def _line(self) -> None:
        level = bool(self.value("SR") & EWIF and self.value("CFR") & EWI)
        self.board.irq_lines(self.irq, self, level)
