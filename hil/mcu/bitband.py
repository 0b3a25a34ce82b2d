"""The Cortex-M4's bit-band aliases (PM0214 2.2.5): one word of alias per bit of SRAM and of
the peripherals.

A read of an alias word gives its bit (0 or 1); a write of an alias word sets or clears that
bit alone. For SRAM the bit is changed in place. For a peripheral the bus does what the
chip's bus matrix does: it reads the register word, changes the bit, and writes the word
back, so the peripheral's model sees an ordinary read and an ordinary write of its register
(and, as on the chip, a write-1-to-clear flag that reads 1 is written back as 1).
ST's HAL sets the PLL, HSI, LSI, CSS, RTC and PWR enables this way, and MicroPython's
EXTI code its interrupt masks.
"""
from __future__ import annotations

from typing import Any, Callable

from unicorn import Uc

WORDS_PER_BYTE = 8          # an alias word (4 bytes) for each of a byte's 8 bits
ALIAS_SCALE = 4 * WORDS_PER_BYTE


def alias_of(region_base: int, alias_base: int, addr: int, bit: int) -> int:
    """The alias word of ``bit`` of the byte at ``addr`` (PM0214's formula)."""
    return alias_base + (addr - region_base) * ALIAS_SCALE + 4 * bit


class BitBandAlias:
    """One alias region over ``size`` bytes at ``base``: ``read_word(addr)`` and
    ``write_word(addr, value)`` reach the bytes it aliases."""

    def __init__(self, name: str, base: int, size: int, alias_base: int,
                 read_word: Callable[[int], int],
                 write_word: Callable[[int, int], None]) -> None:
        self.name = name
        self.base, self.size, self.alias_base = base, size, alias_base
        self.read_word, self.write_word = read_word, write_word

    @property
    def alias_size(self) -> int:
        return self.size * ALIAS_SCALE

    def _target(self, offset: int) -> tuple[int, int]:
        """The aliased word's address and the bit in it, from an offset into the alias."""
        byte, bit = divmod(offset // 4, 8)
        addr = self.base + byte
        return addr & ~3, 8 * (addr & 3) + bit

    def read(self, offset: int) -> int:
        word, bit = self._target(offset)
        return self.read_word(word) >> bit & 1

    def write(self, offset: int, value: int) -> None:
        word, bit = self._target(offset)
        old = self.read_word(word)
        new = old | 1 << bit if value & 1 else old & ~(1 << bit)
        self.write_word(word, new & 0xFFFFFFFF)

    def attach(self, uc: Uc, failed: Callable[[BaseException], None]) -> None:
        """Map the alias with Unicorn's public MMIO API; an exception in a callback goes
        to ``failed`` (the run's fault), as the peripherals' callbacks do."""
        def read(_uc: Any, offset: int, size: int, _data: Any) -> int:
            try:
                return self.read(offset)
            except BaseException as exc:      # noqa: B036 -- handed to emu_start
                failed(exc)
                return 0

        def write(_uc: Any, offset: int, size: int, value: int, _data: Any) -> None:
            try:
                self.write(offset, value)
            except BaseException as exc:      # noqa: B036
                failed(exc)
        uc.mmio_map(self.alias_base, self.alias_size, read, None, write, None)
