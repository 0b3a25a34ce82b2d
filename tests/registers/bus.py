"""The emulated board's peripheral space without an ELF, poked the way QEMU's qtest pokes
a device model: each access is one LDR or STR run by the core, so it goes through the same
MMIO callbacks, clock gates, bit-band aliases and events as a firmware's. ``advance`` lets
virtual time pass (the timers due fire, a watchdog's reset is made)."""
from __future__ import annotations

import struct
from pathlib import Path

from unicorn import arm_const as A

from hexhil.hil.mcu.board import Board
from hexhil.hil.mcu.timebase import FS_PER_S
from hexhil.hil.mcu.elf_image import FLASH_BASE, ElfImage, Segment

CODE = FLASH_BASE + 0x100
# Thumb: b . ; then r1 = [r0] or [r0] = r1 at 4, 2 and 1 bytes
OPS = {"idle": 0xE7FE, ("r", 4): 0x6801, ("w", 4): 0x6001, ("r", 2): 0x8801,
       ("w", 2): 0x8001, ("r", 1): 0x7801, ("w", 1): 0x7001}
RCC = 0x40023800
ENABLE = {"AHB1ENR": RCC + 0x30, "AHB2ENR": RCC + 0x34, "APB1ENR": RCC + 0x40,
          "APB2ENR": RCC + 0x44}


def _image() -> ElfImage:
    vectors = struct.pack("<2I", 0x20020000, CODE | 1).ljust(0x100, b"\0")
    code = b"".join(struct.pack("<H", op) for op in OPS.values())
    return ElfImage(Path("registers.elf"), (Segment(FLASH_BASE, vectors + code),),
                    0x20020000, CODE | 1, (), (), (), {})


class Bus:
    """A board at reset with interrupts masked (PRIMASK): pending IRQs stay pending."""

    def __init__(self) -> None:
        self.board = board = Board(_image(), self._exchange, lambda text: [])
        board.sync.tick.clear()            # no link: nothing asks the world
        board.core.uc.reg_write(A.UC_ARM_REG_PRIMASK, 1)

    @staticmethod
    def _exchange(message: bytes, wait: bool) -> bytes:
        raise AssertionError("the register tests have no link")

    def _access(self, kind: str, addr: int, value: int, size: int) -> int:
        core = self.board.core
        uc = core.uc
        uc.reg_write(A.UC_ARM_REG_R0, addr)
        uc.reg_write(A.UC_ARM_REG_R1, value)
        core.pc = CODE + 2 * list(OPS).index((kind, size))
        self.board.poll.other_access()     # one access is not a poll loop: no skipping
        core.run(1)
        self.board.after_chunk()
        return uc.reg_read(A.UC_ARM_REG_R1)

    def read(self, addr: int, size: int = 4) -> int:
        return self._access("r", addr, 0, size)

    def write(self, addr: int, value: int, size: int = 4) -> None:
        self._access("w", addr, value, size)

    def enable(self, name: str) -> None:
        """The peripheral's RCC clock on (its row's gate, hil/mcu/platform.py)."""
        from hexhil.hil.mcu.platform import row
        reg, bit = row(name).clock
        self.write(ENABLE[reg], self.read(ENABLE[reg]) | 1 << bit)

    def now_s(self) -> float:
        return self.board.core.now_fs() / FS_PER_S

    def advance(self, seconds: float) -> None:
        """Let ``seconds`` of virtual time pass without running instructions, firing each
        event at its instant."""
        board = self.board
        core, events = board.core, board.events
        end = core.now_fs() + round(seconds * FS_PER_S)
        while True:
            nxt = events.next_fs()
            at = end if nxt is None or nxt > end else nxt
            cycles = core.time.cycle_of(at) - core.now()
            if cycles > 0:
                core.jump(cycles)
            events.fire_due(core.now_fs())
            board.reset_if_asked()
            if at >= end:
                return

    def pending(self, irq: int) -> bool:
        """NVIC ISPR's bit for ``irq``."""
        return bool(self.read(0xE000E200 + 4 * (irq // 32)) >> (irq % 32) & 1)
