"""The clock tree (RCC), the flash interface's ACR and PWR, as the firmware configures them.

RCC (RM0383 6.3): HSI 16 MHz runs at reset; HSE is this board's 25 MHz crystal; the main
PLL takes either, divides by M, multiplies by N, divides by P. Each oscillator's ready bit
comes a little after its ON bit (HSE 100 us, PLL 100 us); SW switches SYSCLK only to a
source that is ready (SWS follows). HCLK = SYSCLK / HPRE is the core's clock, so it is the
rate virtual time runs at; PCLK1/PCLK2 = HCLK / PPRE1/PPRE2 clock the USARTs, and the
timers run at twice their APB clock when its prescaler is not 1. The enable bits gate the
peripherals' registers (hil/mcu/board.py: a register of a peripheral whose clock is off
reads 0 and ignores writes, as on the chip).
"""
from __future__ import annotations

from typing import Callable

from hexhil.hil.mcu.board_core import Events
from hexhil.hil.mcu.platform import clock_bits

HSI_HZ = 16_000_000
HSE_HZ = 25_000_000
READY_FS = 100 * 10 ** 9          # 100 us from ON to ready
MAX_SYSCLK_HZ = 100_000_000
CR, PLLCFGR, CFGR = 0x00, 0x04, 0x08
BDCR, CSR = 0x70, 0x74              # the backup domain (LSE) and LSI control
HPRE = {8: 2, 9: 4, 10: 8, 11: 16, 12: 64, 13: 128, 14: 256, 15: 512}
PPRE = {4: 2, 5: 4, 6: 8, 7: 16}
CLOCK_BITS = clock_bits()      # (enable register, bit) of each peripheral, from the platform
RMVF, RESET_FLAGS = 1 << 24, 0xFE000000      # CSR: remove the reset flags; the flags
RESET_FLAG = {"IWDG": 1 << 29, "WWDG": 1 << 30, "SYSRESETREQ": 1 << 28}
PINRSTF = 1 << 26


class Rcc:
    """Reset and clock control; ``on_clock`` hears every change of HCLK or an APB clock."""

    name = "RCC"
    pollable = frozenset({CR, CFGR})

    def __init__(self, events: Events, now_fs: Callable[[], int],
                 on_clock: Callable[[], None]) -> None:
        self.now_fs, self.on_clock = now_fs, on_clock
        self.regs = {CR: 0x00000083, PLLCFGR: 0x24003010, CFGR: 0, 0x74: 0x0E000000}
        self.hse_ready = events.timer(lambda at: self._ready(17))
        self.pll_ready = events.timer(lambda at: self._ready(25))
        self.lse_ready = events.timer(lambda at: self._low_ready(BDCR))
        self.lsi_ready = events.timer(lambda at: self._low_ready(CSR))
        self.sysclk_hz = HSI_HZ
        self.hclk_hz = self.pclk1_hz = self.pclk2_hz = HSI_HZ

    def enabled(self, name: str) -> bool:
        reg, bit = CLOCK_BITS[name]
        return bool(self.regs.get(reg, 0) >> bit & 1)

    def pll_hz(self) -> int:
        cfg = self.regs[PLLCFGR]
        m, n, p = cfg & 0x3F, (cfg >> 6) & 0x1FF, 2 * (((cfg >> 16) & 3) + 1)
        src = HSE_HZ if cfg & (1 << 22) else HSI_HZ
        return src * n // (m * p) if m and n else 0

    def _ready(self, bit: int) -> None:
        self.regs[CR] |= 1 << bit
        self._update()

    def _low_ready(self, off: int) -> None:
        """LSERDY (BDCR bit 1) or LSIRDY (CSR bit 1) after its ON bit (bit 0)."""
        self.regs[off] = self.regs.get(off, 0) | 2

    def _low_oscillator(self, off: int, old: int, value: int) -> int:
        """BDCR's LSEON or CSR's LSION: its ready bit (read-only) comes READY_FS later,
        and goes with the ON bit."""
        timer = self.lse_ready if off == BDCR else self.lsi_ready
        value = (value & ~2) | (old & 2)
        if value & 1 and not old & 1:
            timer.set(self.now_fs() + READY_FS)
        if not value & 1:
            value &= ~2
            timer.clear()
        return value

    def read(self, off: int) -> int:
        return self.regs.get(off, 0)

    def reset_by(self, cause: str, before: int) -> None:
        """After a system reset by ``cause``: CSR's reset flags as ``before`` left them
        (only a power-on clears them), the pin's and the cause's set."""
        self.regs[CSR] |= (before & RESET_FLAGS) | PINRSTF | RESET_FLAG[cause]

    def write(self, off: int, value: int) -> None:
        old = self.regs.get(off, 0)
        if off == CR:
            value = (value & ~0x0A020002) | (old & 0x0A020002)   # ready bits are read-only
            value |= 2 if value & 1 else 0
            if value & (1 << 16) and not old & (1 << 16):
                self.hse_ready.set(self.now_fs() + READY_FS)
            if not value & (1 << 16):
                value &= ~(1 << 17)
                self.hse_ready.clear()
            if value & (1 << 24) and not old & (1 << 24):
                self.pll_ready.set(self.now_fs() + READY_FS)
            if not value & (1 << 24):
                value &= ~(1 << 25)
                self.pll_ready.clear()
        elif off == CFGR:
            value = (value & ~0xC) | (old & 0xC)
        elif off in (BDCR, CSR):
            value = self._low_oscillator(off, old, value)
            if off == CSR:        # the reset flags are read-only; RMVF clears them
                value = (value & ~RESET_FLAGS) | (0 if value & RMVF else old & RESET_FLAGS)
        self.regs[off] = value
        self._update()

    def _update(self) -> None:
        cr, cfgr = self.regs[CR], self.regs[CFGR]
        sw = cfgr & 3
        ready = {0: cr & 2, 1: cr & (1 << 17), 2: cr & (1 << 25)}.get(sw, 0)
        if ready:
            self.regs[CFGR] = (cfgr & ~0xC) | (sw << 2)
        sws = (self.regs[CFGR] >> 2) & 3
        sysclk = {0: HSI_HZ, 1: HSE_HZ, 2: self.pll_hz()}.get(sws, HSI_HZ) or HSI_HZ
        hclk = sysclk // HPRE.get((cfgr >> 4) & 0xF, 1)
        p1 = hclk // PPRE.get((cfgr >> 10) & 7, 1)
        p2 = hclk // PPRE.get((cfgr >> 13) & 7, 1)
        if (sysclk, hclk, p1, p2) != (self.sysclk_hz, self.hclk_hz, self.pclk1_hz, self.pclk2_hz):
            self.sysclk_hz, self.hclk_hz, self.pclk1_hz, self.pclk2_hz = sysclk, hclk, p1, p2
            self.on_clock()

    def timer_hz(self, apb2: bool) -> int:
        ppre = (self.regs[CFGR] >> (13 if apb2 else 10)) & 7
        pclk = self.pclk2_hz if apb2 else self.pclk1_hz
        return pclk if ppre < 4 else 2 * pclk


class Plain:
    """Registers that only keep what is written (FLASH_ACR, PWR, ...): the HAL reads its
    own writes back. ``fixed`` bits always read set (PWR_CSR VOSRDY)."""

    pollable = frozenset(range(0, 0x400, 4))

    def __init__(self, name: str, reset: dict[int, int] | None = None,
                 fixed: dict[int, int] | None = None) -> None:
        self.name = name
        self.regs = dict(reset or {})
        self.fixed = fixed or {}

    def read(self, off: int) -> int:
        return self.regs.get(off, 0) | self.fixed.get(off, 0)

    def write(self, off: int, value: int) -> None:
        self.regs[off] = value


class Power(Plain):
    """PWR (RM0383 5.4): CR and CSR kept as written, VOSRDY always set, and the backup
    regulator ready (CSR BRR, bit 3) as soon as it is enabled (CSR BRE, bit 9)."""

    def write(self, off: int, value: int) -> None:
        if off == 0x04:
            value = (value & ~0x0F) | (1 << 3 if value & 1 << 9 else 0)
        self.regs[off] = value


def power() -> Power:
    return Power("PWR", {0x00: 0x4000}, {0x04: 1 << 14})    # CR VOS, CSR VOSRDY
