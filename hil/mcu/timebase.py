"""Virtual time on the MCU: cycles and femtoseconds at a clock the firmware may change, and
the board's millisecond with the world. The compiled board (board_core.c) takes the units
from here through board_layout.py."""
from __future__ import annotations

from typing import Protocol

FS_PER_S = 10 ** 15            # virtual time inside the MCU is in femtoseconds (exact)
FS_PER_US = 10 ** 9
TICK_US = 1000                 # a quiet millisecond: the board asks the world again
                               # (world_sync.py); a switch level older than this is stale


class SharedTime(Protocol):
    """Where the compiled board reads the time base (board_core.py ``Shared``)."""

    hz: int
    cyc0: int
    fs0: int
    fs_per_cyc: int


class TimeBase:
    """Cycles and femtoseconds at a clock that the firmware may change: exact integers.
    Where a cycle is a whole number of femtoseconds (``_fs_per_cyc``: 10 ns at 100 MHz,
    62.5 ns at 16 MHz) the conversions multiply or divide once, with the same results.
    ``shared`` gets a copy for the compiled board (hil/mcu/board_core.c)."""

    def __init__(self, hz: int, shared: SharedTime) -> None:
        self.shared = shared
        self.hz = hz
        self._cyc0 = 0
        self._fs0 = 0
        self._fs_per_cyc = FS_PER_S // hz if FS_PER_S % hz == 0 else 0
        self._share()

    def _share(self) -> None:
        st = self.shared
        st.hz, st.cyc0, st.fs0, st.fs_per_cyc = self.hz, self._cyc0, self._fs0, self._fs_per_cyc

    def fs_at(self, cyc: int) -> int:
        if self._fs_per_cyc:
            return self._fs0 + (cyc - self._cyc0) * self._fs_per_cyc
        return self._fs0 + (cyc - self._cyc0) * FS_PER_S // self.hz

    def cycle_of(self, fs: int) -> int:
        """The first cycle at or after time ``fs``."""
        if self._fs_per_cyc:
            return self._cyc0 - (self._fs0 - fs) // self._fs_per_cyc
        return self._cyc0 + -(-(fs - self._fs0) * self.hz // FS_PER_S)

    def set_hz(self, cyc: int, hz: int) -> None:
        self._fs0, self._cyc0, self.hz = self.fs_at(cyc), cyc, hz
        self._fs_per_cyc = FS_PER_S // hz if FS_PER_S % hz == 0 else 0
        self._share()
