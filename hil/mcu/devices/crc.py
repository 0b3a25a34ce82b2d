"""CRC, the CRC-32 calculation unit (RM0383 4): each word written to DR is fed MSB first
through the Ethernet polynomial 0x04C11DB7 (no reflection, no final XOR); CR RESET sets DR
back to 0xFFFFFFFF; IDR is a byte of scratch. ST's ``HAL_CRC_Calculate`` works on it.
"""
from __future__ import annotations

from typing import Any

from hexhil.hil.mcu.registers import Description, RegisterFile, reg

POLY = 0x04C11DB7

CRC = Description("CRC", (
    reg("DR", 0x00, 0xFFFFFFFF, "DR:0-31:rw"),
    reg("IDR", 0x04, 0x00, "IDR:0-7:rw"),
    reg("CR", 0x08, 0x00, "RESET:0:w"),
))


def crc32_word(crc: int, word: int) -> int:
    """``crc`` after one 32-bit word, as the unit computes it."""
    crc ^= word
    for _ in range(32):
        crc = (crc << 1) ^ POLY if crc & 0x80000000 else crc << 1
    return crc & 0xFFFFFFFF


class Crc(RegisterFile):
    def __init__(self, board: Any, row: Any) -> None:
        super().__init__(CRC.renamed(row.name), board.noted)
        self.behave("DR", write=self._fed)
        self.behave("CR", write=self._cr)

    def _fed(self, old: int, new: int) -> None:
        self.regs[self.offset("DR")] = crc32_word(old, new)

    def _cr(self, old: int, new: int) -> None:
        if new & 1:
            self.regs[self.offset("DR")] = 0xFFFFFFFF
