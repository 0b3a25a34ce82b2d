"""The embedded flash's interface (RM0383 3): its registers, sector erase and programming.

The flash is a read-only Unicorn region backed by the core's buffer (hil/mcu/core.py); a
store to it reaches ``FlashInterface.store`` through a Unicorn write-protection hook
(``attach``, public API). With the interface unlocked (KEYR 0x45670123 then 0xCDEF89AB; a
wrong key locks CR until the next reset) and CR.PG set, the store programs the flash: bits
only go from 1 to 0. A store the chip refuses programs nothing and sets the flag the chip
sets (PGSERR without PG, PGPERR for an access size that is not PSIZE's, PGAERR across a
16-byte row, WRPERR for a 64-bit PSIZE, which needs VPP); the run's log names each kind
once. CR.STRT with SER erases sector SNB to 0xFF (the F411's map: four 16 KB, one 64 KB,
three 128 KB). BSY stays set for the operation's time in virtual time, then EOP (with EOPIE)
and the FLASH interrupt (IRQ 4, EOPIE or ERRIE). SR's flags are write-1-to-clear.

The times are the typical ones of the STM32F411xC/E datasheet (DS10314, "Flash memory
programming"): a word (any parallelism) 16 us; a sector erase at x8/x16/x32 parallelism
16 KB 400/300/250 ms, 64 KB 1200/700/550 ms, 128 KB 2000/1300/1000 ms; a mass erase
16/11/8 s (512 KB). Reading flash while BSY is set does not stall the core here.
Not modelled: option bytes (OPTCR keeps what is written), read protection, the ACR's
wait states and caches as timing (ACR keeps what is written).
"""
from __future__ import annotations

import logging
from typing import Any

from unicorn import UC_HOOK_MEM_WRITE_PROT

from hexhil.hil.mcu.elf_image import FLASH_BASE, FLASH_SIZE
from hexhil.hil.mcu.timebase import FS_PER_US

log = logging.getLogger(__name__)
ACR, KEYR, OPTKEYR, SR, CR, OPTCR = 0x00, 0x04, 0x08, 0x0C, 0x10, 0x14
KEY1, KEY2 = 0x45670123, 0xCDEF89AB
# SR (RM0383 3.8.4)
EOP, OPERR, WRPERR, PGAERR, PGPERR, PGSERR, BSY = 1, 1 << 1, 1 << 4, 1 << 5, 1 << 6, 1 << 7, 1 << 16
SR_W1C = EOP | OPERR | WRPERR | PGAERR | PGPERR | PGSERR
ERRORS = OPERR | WRPERR | PGAERR | PGPERR | PGSERR
# CR (RM0383 3.8.5)
PG, SER, MER, STRT, EOPIE, ERRIE, LOCK = 1, 1 << 1, 1 << 2, 1 << 16, 1 << 24, 1 << 25, 1 << 31
CR_WRITABLE = PG | SER | MER | (0xF << 3) | (3 << 8) | EOPIE | ERRIE
FLASH_IRQ = 4
SECTORS_KB = (16, 16, 16, 16, 64, 128, 128, 128)        # RM0383 3.3, table 4
PROGRAM_US = 16                                         # DS10314: word programming, typical
ERASE_MS = {16: (400, 300, 250), 64: (1200, 700, 550), 128: (2000, 1300, 1000)}
MASS_ERASE_MS = (16000, 11000, 8000)
ROW_BYTES = 16                                          # one 128-bit flash row
REFUSED = {PGSERR: "programming sequence error (PGSERR): a store to flash without CR.PG "
           "set (or with the interface locked)",
           PGPERR: "programming parallelism error (PGPERR): the store's size is not CR.PSIZE's",
           PGAERR: "programming alignment error (PGAERR): the store crosses a 16-byte row",
           WRPERR: "write protection error (WRPERR): PSIZE x64 needs an external VPP"}


def sector_of(addr: int) -> tuple[int, int, int]:
    """(sector, its start, its size in bytes) of flash address ``addr``."""
    start = FLASH_BASE
    for n, kb in enumerate(SECTORS_KB):
        if addr < start + kb * 1024:
            return n, start, kb * 1024
        start += kb * 1024
    raise ValueError(f"0x{addr:08x} is not in flash")


def sector_range(n: int) -> tuple[int, int]:
    """(start, size in bytes) of sector ``n``."""
    start = FLASH_BASE + 1024 * sum(SECTORS_KB[:n])
    return start, SECTORS_KB[n] * 1024


class FlashInterface:
    """The FLASH registers at 0x4002_3C00 and the program and erase operations on the
    core's flash (``board.core``); ``attach`` makes stores to flash reach ``store``."""

    name = "FLASH"
    pollable = frozenset({ACR, SR, CR, OPTCR})

    def __init__(self, board: Any) -> None:
        self.board = board
        self.regs = {ACR: 0, SR: 0, CR: LOCK, OPTCR: 0x0FFFAAED}
        self._key = 0               # KEY1 seen: KEY2 unlocks next
        self._jammed = False        # a wrong key: locked until reset
        self._said: set[int] = set()
        self._op = board.events.timer(self._done)
        self._erase: tuple[int, int] | None = None      # (start, size) when BSY ends
        self._stale: list[tuple[int, int]] = []          # code to retranslate (start, end)
        self._fixes: list[tuple[int, bytes]] = []        # what a store left wrong

    # --- registers --------------------------------------------------------------
    def read(self, off: int) -> int:
        return self.regs.get(off, 0)

    def write(self, off: int, value: int) -> None:
        regs = self.regs
        if off == KEYR:
            self._unlock(value)
        elif off == SR:
            regs[SR] &= ~(value & SR_W1C)
            self._irq()
        elif off == CR:
            if regs[CR] & LOCK:
                return                   # CR is write-protected while locked
            if regs[SR] & BSY:
                self._say(BSY, "FLASH.CR written while BSY: the chip stalls the write; "
                          "here it takes effect at once")
            cr = (regs[CR] & ~CR_WRITABLE) | (value & CR_WRITABLE)
            if value & LOCK:
                cr |= LOCK
            regs[CR] = cr
            if value & STRT:
                self._start(cr)
            self._irq()
        elif off in (ACR, OPTCR):
            regs[off] = value
        # OPTKEYR: the option bytes are not modelled

    def _unlock(self, value: int) -> None:
        regs = self.regs
        if self._jammed or not regs[CR] & LOCK:
            self._jam(value)
        elif self._key == 0 and value == KEY1:
            self._key = 1
        elif self._key == 1 and value == KEY2:
            self._key = 0
            regs[CR] &= ~LOCK
        else:
            self._jam(value)

    def _jam(self, value: int) -> None:
        """A wrong key (or a key while unlocked): CR stays locked until the next reset."""
        if not self._jammed:
            log.warning("FLASH.KEYR: 0x%08x is not the unlock sequence; FLASH.CR stays locked "
                        "until the next reset", value)
        self._jammed = True
        self._key = 0
        self.regs[CR] |= LOCK

    def _start(self, cr: int) -> None:
        """CR.STRT: a sector erase (SER, SNB) or a mass erase (MER) at CR.PSIZE."""
        psize = min((cr >> 8) & 3, 2)
        if cr & MER:
            self._erase = (FLASH_BASE, FLASH_SIZE)
            ms = MASS_ERASE_MS[psize]
        elif cr & SER:
            snb = (cr >> 3) & 0xF
            if snb >= len(SECTORS_KB):
                self._error(PGSERR, f"FLASH.CR.SNB {snb}: the F411 has sectors 0-7")
                return
            self._erase = sector_range(snb)
            ms = ERASE_MS[SECTORS_KB[snb]][psize]
        else:
            return
        self._busy(ms * 1000)

    def _busy(self, us: int) -> None:
        self.regs[SR] |= BSY
        start = max(self.board.core.now_fs(), self._op.at_fs or 0)
        self._op.set(start + us * FS_PER_US)

    def _done(self, at_fs: int) -> None:
        """The operation ends: an erase fills its sector with 0xFF; BSY falls, EOP rises
        where EOPIE asks for it (RM0383 3.8.4)."""
        regs = self.regs
        if self._erase is not None:
            start, size = self._erase
            self._erase = None
            self.board.core.uc.mem_write(start, b"\xff" * size)
            self._stale.append((start, start + size))
        regs[SR] &= ~BSY
        regs[CR] &= ~STRT
        if regs[CR] & EOPIE:
            regs[SR] |= EOP
        self._irq()

    def _irq(self) -> None:
        sr, cr = self.regs[SR], self.regs[CR]
        level = bool(sr & EOP and cr & EOPIE or sr & ERRORS and cr & ERRIE)
        self.board.nvic.line(FLASH_IRQ, level)

    def _error(self, flag: int, text: str) -> None:
        self.regs[SR] |= flag
        self._say(flag, text)
        self._irq()

    def _say(self, kind: int, text: str) -> None:
        if kind not in self._said:
            self._said.add(kind)
            log.warning("firmware %s: %s (at t=%.6f s)", self.board.image.path.name, text,
                        self.board.now_us() * 1e-6)

    # --- stores to flash ----------------------------------------------------------
    def store(self, addr: int, size: int, value: int, old: bytes) -> None:
        """A store of ``size`` bytes of ``value`` to flash at ``addr`` (its 0x0800_0000
        address), whose bytes were ``old``: what the chip keeps is written here, and again
        after the instruction (``settle``), since Unicorn may write ``value`` itself once
        the hook returns (it does when the store runs from another region)."""
        cr = self.regs[CR]
        psize = (cr >> 8) & 3
        flag = 0
        if cr & LOCK or not cr & PG:
            flag = PGSERR
        elif psize == 3:
            flag = WRPERR
        elif size != 1 << psize:
            flag = PGPERR
        elif addr // ROW_BYTES != (addr + size - 1) // ROW_BYTES:
            flag = PGAERR
        new = (value & ((1 << 8 * size) - 1)).to_bytes(size, "little")
        if flag:
            self._error(flag, f"{REFUSED[flag]}, 0x{int.from_bytes(new, 'little'):0{2 * size}x} "
                        f"to 0x{addr:08x} at PC 0x{self.board.core.pc_now():08x}")
            kept = old
        else:
            kept = bytes(a & b for a, b in zip(old, new))
            if kept != new:
                self._say(0, f"a program of 0x{addr:08x} asked for 0->1 bits: flash bits "
                          "only go from 1 to 0 (an erase sets them)")
            self._busy(PROGRAM_US)
            self._stale.append((addr, addr + size))
        core = self.board.core
        core.uc.mem_write(addr, kept)
        self._fixes.append((addr, kept))
        core.cut_after()            # settled before the next instruction reads it
        core.shared.touched += 1     # Python takes part: the compiled loop hands over

    def settle(self) -> None:
        """After the chunk that stored to flash: the bytes the chip keeps put back, and the
        code Unicorn translated from the changed range dropped (``ctl_remove_cache``)."""
        if not self._fixes and not self._stale:
            return
        uc = self.board.core.uc
        for addr, kept in self._fixes:
            uc.mem_write(addr, kept)
        for start, end in self._stale:
            uc.ctl_remove_cache(start, end)
            uc.ctl_remove_cache(start - FLASH_BASE, end - FLASH_BASE)
        self._fixes, self._stale = [], []


def attach(board: Any) -> list[int]:
    """Stores to flash (at 0x0800_0000 and its alias at 0) go to ``board.flash``'s
    ``store`` through Unicorn's write-protection hook (the interface of the moment: a
    reset makes a new one); returns the two hooks' handles."""
    uc = board.core.uc

    def hook(_uc: Any, _access: int, addr: int, size: int, value: int, _data: Any) -> bool:
        try:
            at = addr if addr >= FLASH_BASE else addr + FLASH_BASE
            board.flash.store(at, size, value, bytes(uc.mem_read(addr, size)))
            return True
        except BaseException as exc:      # noqa: B036 -- handed to emu_start
            board.space.failed(exc)
            return False
    return [uc.hook_add(UC_HOOK_MEM_WRITE_PROT, hook, begin=base, end=base + FLASH_SIZE - 1)
            for base in (0, FLASH_BASE)]
