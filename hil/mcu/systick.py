"""SysTick, the Cortex-M4's 24-bit down counter (the private peripheral bus at 0xE000_E010):
COUNTFLAG, reload, the SysTick exception at each wrap. Its registers live in ``Shared``:
the board core (hil/mcu/board_core.c) fires the wrap and answers CSR's reads, which clear
COUNTFLAG; the counter's value, its reload and the writes are here."""
from __future__ import annotations

from typing import Callable

from hexhil.hil.mcu.armv7m import SYST_CLKSOURCE, SYST_CONTROL, SYST_ENABLE
from hexhil.hil.mcu.board_core import Events, SharedField
from hexhil.hil.mcu.core import Core
from hexhil.hil.mcu.timebase import FS_PER_S


class SysTick:
    """The 24-bit down counter: COUNTFLAG, reload, the SysTick exception at each wrap."""

    csr = SharedField("st_csr")
    rvr = SharedField("st_rvr")
    countflag = SharedField("st_countflag", bool)

    def __init__(self, core: Core, events: Events, hclk: Callable[[], int]) -> None:
        self.core, self.hclk = core, hclk
        self.shared = st = core.shared
        self.csr = 0
        self.rvr = 0
        self.countflag = False
        self._c0 = 0              # the counter's value at _t0
        self._t0 = 0
        self.wrap = events.timer(lambda at_fs: None)
        st.st_tid = self.wrap.tid     # fired in C (board_core.c ``systick_wrapped``)

    def _hz(self) -> int:
        return self.hclk() if self.csr & SYST_CLKSOURCE else self.hclk() // 8

    def _ticks(self, fs: int) -> int:
        return (fs - self._t0) * self._hz() // FS_PER_S

    def value(self) -> int:
        if not self.csr & SYST_ENABLE:
            return self._c0
        k = self._ticks(self.core.now_fs())
        if k < self._c0:
            return self._c0 - k
        m = (k - self._c0) % (self.rvr + 1)
        return 0 if m == 0 else self.rvr + 1 - m

    def _anchor(self, value: int) -> None:
        self._c0, self._t0 = value, self.core.now_fs()
        self._schedule()

    def _schedule(self) -> None:
        if not self.csr & SYST_ENABLE or (self.rvr == 0 and self._c0 == 0):
            self.wrap.clear()
            return
        k = self._ticks(self.core.now_fs())
        first = self._c0 if self._c0 > 0 else self.rvr + 1
        if k >= first:
            first += ((k - first) // (self.rvr + 1) + 1) * (self.rvr + 1)
        hz = self._hz()
        self.wrap.set(self._t0 + -(-first * FS_PER_S // hz))

    def rebase(self) -> None:
        """HCLK changed: the counter goes on from its value now at the new rate."""
        if self.csr & SYST_ENABLE:
            self._anchor(self.value())

    def read(self, off: int) -> int:
        """RVR, CVR and CALIB (CSR's reads are the board core's)."""
        if off == 4:
            return self.rvr
        if off == 8:
            return self.value()
        return 0x40000000 if off == 0xC else 0   # CALIB: no reference clock

    def write(self, off: int, value: int) -> None:
        if off == 0:
            was = self.csr & SYST_ENABLE
            value_now = self.value()
            self.csr = value & SYST_CONTROL
            if self.csr & SYST_ENABLE and not was:
                self._anchor(value_now)
            elif was and not self.csr & SYST_ENABLE:
                self._c0 = value_now
                self.wrap.clear()
            else:
                self._anchor(value_now)
        elif off == 4:
            value_now = self.value()
            self.rvr = value & 0xFFFFFF
            self._anchor(value_now)
        elif off == 8:
            self.countflag = False
            self._anchor(0)
