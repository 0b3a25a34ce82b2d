"""The real-time clock and its backup registers (RM0383 17), as ST's HAL and MicroPython's
stm32 port use them.

The calendar (TR, DR, SSR) runs in virtual time from RTCCLK, chosen by RCC BDCR RTCSEL
(LSE 32.768 kHz, LSI 32 kHz, HSE / CFGR RTCPRE) once RTCEN is set and the oscillator is
ready: ck_apre = RTCCLK / (PREDIV_A + 1), one second every PREDIV_S + 1 of them; SSR counts
down from PREDIV_S. It is worked out at each read, not ticked: no event, no host time.
Writes need PWR CR DBP (the backup domain's write protection), and every register but the
ISR flags and the backup registers also needs the key 0xCA, 0x53 in WPR (any other value
locks again). ISR INIT enters the initialisation mode: INITF follows two RTCCLK periods
later, the calendar stops, TR, DR and PRER take writes; clearing INIT starts it again from
what was written. RSF (write 0 to clear) comes back two RTCCLK periods after a clear, as the
shadow registers are copied; INITS says the year is not 0. Reading SSR or TR freezes TR and
DR until DR is read, as the shadow registers do.

Not modelled: alarms and the wake-up timer (their registers keep what is written, the
write flags read 1 while the unit is off), timestamps and tamper, the smooth calibration,
the 12-hour format, BDRST. The backup domain survives a system reset (SYSRESETREQ, a
watchdog) as on the chip: the calendar, its prescalers, the backup registers and RCC BDCR
(LSE, RTCSEL, RTCEN) go on; PWR's DBP and LSI do not (an RTC on LSI stops until the
firmware turns LSI on again). RCC BDCR takes writes without DBP.
"""
from __future__ import annotations

import datetime as dt
from typing import Any

from hexhil.hil.mcu import platform
from hexhil.hil.mcu.timebase import FS_PER_S

TR, DR, CR, ISR, PRER, WUTR, WPR, SSR = 0x00, 0x04, 0x08, 0x0C, 0x10, 0x14, 0x24, 0x28
BKP0R, BKP_COUNT = 0x50, 20
RESET = {TR: 0, DR: 0x00002101, CR: 0, PRER: 0x007F00FF, WUTR: 0xFFFF}
LSE_HZ, LSI_HZ = 32_768, 32_000
# ISR (RM0383 17.6.4)
ALRAWF, ALRBWF, WUTWF, INITS, RSF, INITF, INIT = 1, 2, 4, 1 << 4, 1 << 5, 1 << 6, 1 << 7
FLAGS_RC_W0 = 0x3F00              # ALRAF .. TAMP2F: not write-protected
ALRAE, ALRBE, WUTE = 1 << 8, 1 << 9, 1 << 10
DBP = 1 << 8                      # PWR CR
KEYS = (0xCA, 0x53)
EPOCH = dt.date(2000, 1, 1)


def _bcd(n: int) -> int:
    return (n // 10) << 4 | n % 10


def _unbcd(b: int) -> int:
    return (b >> 4) * 10 + (b & 0xF)


class Rtc:
    """RTC at 0x4000_2800: the calendar against ``board.core``'s virtual time, the clock
    from ``board.rcc``, DBP from ``board.pwr``."""

    name = "RTC"
    pollable = frozenset()      # the calendar changes with no event to skip a poll to

    def __init__(self, board: Any) -> None:
        self.board = board
        self.regs = dict(RESET)
        self.isr = 0                 # INIT and the rc_w0 flags as written
        self.bkp = [0] * BKP_COUNT
        self._keys = 0               # how much of the WPR key was written
        self._init_fs: int | None = None    # when INITF rises (INIT set)
        self._rsf_fs: int | None = None     # when RSF rises (None: not since reset or a clear)
        self._frozen: tuple[int, int] | None = None    # TR, DR held until DR is read
        self._clock: tuple[int, int, int] = (0, 0, 0)  # (RTCCLK Hz, PREDIV_A, PREDIV_S)
        self._base_fs = 0
        self._base = (EPOCH, 1, 0, 0)   # (date, weekday 1-7, seconds of day, ck_apre ticks)

    def survive_reset(self, board: Any, bdcr: int) -> None:
        """A system reset: this RTC and RCC BDCR's ``bdcr`` go on in ``board``'s new
        peripherals (the calendar counted up to now on the clock it had)."""
        board.rcc.regs[0x70] = bdcr
        board.rtc = self
        board.space.map(platform.row(self.name).base, self)
        self._frozen, self._keys = None, 0      # the shadow registers copy again; locked
        self._calendar()

    # --- clock -------------------------------------------------------------------
    def rtcclk_hz(self) -> int:
        """RTCCLK now: 0 unless RTCEN and the selected oscillator runs."""
        rcc = self.board.rcc.regs
        bdcr, csr = rcc.get(0x70, 0), rcc.get(0x74, 0)
        if not bdcr & 1 << 15:
            return 0
        sel = (bdcr >> 8) & 3
        if sel == 1:
            return LSE_HZ if bdcr & 2 else 0
        if sel == 2:
            return LSI_HZ if csr & 2 else 0
        if sel == 3:
            rtcpre = (rcc.get(0x08, 0) >> 16) & 0x1F
            return 25_000_000 // rtcpre if rtcpre >= 2 and rcc.get(0, 0) & 1 << 17 else 0
        return 0

    def _now(self) -> int:
        return self.board.core.now_fs()

    def _running_clock(self) -> tuple[int, int, int]:
        prer = self.regs[PRER]
        hz = 0 if self.isr & INIT else self.rtcclk_hz()
        return hz, (prer >> 16) & 0x7F, prer & 0x7FFF

    def _calendar(self) -> tuple[dt.date, int, int, int]:
        """(date, weekday, seconds of day, ck_apre ticks into the second) now; the base
        moves here when the clock or the prescalers changed since the last look."""
        clock = self._running_clock()
        now = self._now()
        if clock != self._clock:
            self._base = self._advance(now)
            self._base_fs, self._clock = now, clock
        return self._advance(now)

    def _advance(self, now_fs: int) -> tuple[dt.date, int, int, int]:
        date, wd, secs, sub = self._base
        hz, pa, ps = self._clock
        if not hz:
            return self._base
        ticks = sub + (now_fs - self._base_fs) * hz // (FS_PER_S * (pa + 1))
        more, sub = divmod(ticks, ps + 1)
        days, secs = divmod(secs + more, 86_400)
        return date + dt.timedelta(days=days), (wd - 1 + days) % 7 + 1, secs, sub

    def _periods_fs(self, n: int) -> int | None:
        hz = self.rtcclk_hz()
        return self._now() + -(-n * FS_PER_S // hz) if hz else None

    # --- registers ---------------------------------------------------------------
    def _tr_dr(self) -> tuple[int, int]:
        date, wd, secs, _ = self._calendar()
        h, rest = divmod(secs, 3600)
        tr = _bcd(h) << 16 | _bcd(rest // 60) << 8 | _bcd(rest % 60)
        dr = _bcd(date.year % 100) << 16 | wd << 13 | _bcd(date.month) << 8 | _bcd(date.day)
        return tr, dr

    def read(self, off: int) -> int:
        if off in (TR, SSR) and self._frozen is None:
            self._frozen = self._tr_dr()
        if off == TR:
            return self._frozen[0]
        if off == DR:
            value = (self._frozen or self._tr_dr())[1]
            self._frozen = None
            return value
        if off == SSR:
            return self._clock[2] - self._calendar()[3] if self._clock[0] else \
                self.regs[PRER] & 0x7FFF
        if off == ISR:
            return self._isr()
        if BKP0R <= off < BKP0R + 4 * BKP_COUNT:
            return self.bkp[(off - BKP0R) // 4]
        return self.regs.get(off, 0)

    def _isr(self) -> int:
        now, cr = self._now(), self.regs[CR]
        value = self.isr & (INIT | FLAGS_RC_W0)
        value |= (0 if cr & ALRAE else ALRAWF) | (0 if cr & ALRBE else ALRBWF)
        value |= 0 if cr & WUTE else WUTWF
        if self._calendar()[0].year % 100:
            value |= INITS
        if self.isr & INIT and self._init_fs is not None and now >= self._init_fs:
            value |= INITF
        if self._rsf_fs is not None and now >= self._rsf_fs and not self.isr & INIT:
            value |= RSF
        return value

    def write(self, off: int, value: int) -> None:
        if not self.board.pwr.regs.get(0x00, 0) & DBP:
            return                       # the backup domain is write-protected
        if BKP0R <= off < BKP0R + 4 * BKP_COUNT:
            self.bkp[(off - BKP0R) // 4] = value
            return
        if off == WPR:
            key = value & 0xFF
            self._keys = self._keys + 1 if self._keys < 2 and key == KEYS[self._keys] else 0
            return
        if off == ISR:               # bits 13:8 need no key; RSF and INIT do
            self.isr &= ~(FLAGS_RC_W0 & ~value)
            if self._keys == 2:
                if not value & RSF:
                    self._rsf_fs = self._periods_fs(2)
                self._init(bool(value & INIT))
            return
        if self._keys != 2:
            return                       # write-protected (WPR)
        if off in (TR, DR, PRER):
            if not self._isr() & INITF:
                return                   # only in the initialisation mode
            if off == PRER:
                self.regs[PRER] = value
            else:
                tr, dr = self._tr_dr()
                self._set_calendar(value if off == TR else tr, value if off == DR else dr)
            return
        self.regs[off] = value

    def _init(self, on: bool) -> None:
        was = bool(self.isr & INIT)
        if on and not was:
            self._calendar()                       # the count so far, then it stops
            self.isr |= INIT
            self._init_fs = self._periods_fs(2)
            self._calendar()
        elif was and not on:
            self.isr &= ~INIT
            self._init_fs = None
            self._calendar()                       # counts again from what was written
            self._rsf_fs = self._periods_fs(2)

    def _set_calendar(self, tr: int, dr: int) -> None:
        year = 2000 + _unbcd((dr >> 16) & 0xFF)
        try:
            date = dt.date(year, _unbcd((dr >> 8) & 0x1F) or 1, _unbcd(dr & 0x3F) or 1)
        except ValueError:
            date = EPOCH
        secs = (_unbcd((tr >> 16) & 0x3F) * 3600 + _unbcd((tr >> 8) & 0x7F) * 60
                + _unbcd(tr & 0x7F)) % 86_400
        self._base = (date, (dr >> 13) & 7 or 1, secs, 0)
        self._base_fs = self._now()
