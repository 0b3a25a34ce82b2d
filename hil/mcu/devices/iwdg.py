"""IWDG, the independent watchdog (RM0383 17): a 12-bit down-counter on LSI (32 kHz)
divided by 4 * 2**PR; the key 0xCCCC starts it (from 0xFFF), 0xAAAA reloads it from RLR,
0x5555 unlocks PR and RLR. Reaching 0 resets the MCU as the chip does (the board's
``request_reset``). PVU and RVU stay set for 5 LSI periods after a write of PR or RLR.
Once started it runs until a reset; a write to PR or RLR while locked is ignored.
"""
from __future__ import annotations

from typing import Any

from hexhil.hil.mcu.timebase import FS_PER_S
from hexhil.hil.mcu.registers import Description, RegisterFile, reg

LSI_HZ = 32_000
UPDATE_LSI_PERIODS = 5
KEY_START, KEY_RELOAD, KEY_UNLOCK = 0xCCCC, 0xAAAA, 0x5555
PVU, RVU = 1, 2

IWDG = Description("IWDG", (
    reg("KR", 0x00, 0x0000, "KEY:0-15:w"),
    reg("PR", 0x04, 0x0000, "PR:0-2:rw"),
    reg("RLR", 0x08, 0x0FFF, "RL:0-11:rw"),
    reg("SR", 0x0C, 0x0000, "PVU:0:r RVU:1:r"),
))


class Iwdg(RegisterFile):
    def __init__(self, board: Any, row: Any) -> None:
        super().__init__(IWDG.renamed(row.name), board.noted)
        self.board = board
        self.unlocked = False
        self.running = False
        self._count0, self._t0 = 0xFFF, 0
        self.expiry = board.events.timer(self._expired)
        self.updated = board.events.timer(lambda at: self.clear_bits("SR", PVU | RVU))
        self.behave("KR", write=self._key)
        self.behave("PR", write=lambda old, new: self._locked_write("PR", old, new, PVU))
        self.behave("RLR", write=lambda old, new: self._locked_write("RLR", old, new, RVU))
        self.behave("SR", write=lambda old, new: None)

    def _tick_fs(self) -> int:
        return FS_PER_S * 4 * (1 << min(self.value("PR"), 6)) // LSI_HZ

    def counter(self) -> int:
        """The down-counter now."""
        if not self.running:
            return self._count0
        gone = (self.board.core.now_fs() - self._t0) // self._tick_fs()
        return max(0, self._count0 - gone)

    def _load(self, count: int) -> None:
        self._count0, self._t0 = count, self.board.core.now_fs()
        self.expiry.set(self._t0 + count * self._tick_fs())

    def _key(self, old: int, new: int) -> None:
        key = new & 0xFFFF
        self.unlocked = key == KEY_UNLOCK
        if key == KEY_START and not self.running:
            self.running = True
            self._load(0xFFF)
        elif key == KEY_RELOAD and self.running:
            self._load(self.value("RLR"))

    def _locked_write(self, name: str, old: int, new: int, flag: int) -> None:
        if not self.unlocked:
            self.regs[self.offset(name)] = old
            return
        if name == "PR" and self.running:       # the count so far at the old rate
            self.regs[self.offset(name)] = old
            count = self.counter()
            self.regs[self.offset(name)] = new
            self._load(count)
        self.set_bits("SR", flag)
        self.updated.set(self.board.core.now_fs() + UPDATE_LSI_PERIODS * FS_PER_S // LSI_HZ)

    def _expired(self, at_fs: int) -> None:
        self.board.request_reset(self.name)
