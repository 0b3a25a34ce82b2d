"""The firmware's deadline in chip cycles: for every control cycle, how long the core was
busy (not asleep in WFI/WFE).

A control cycle runs from one servo burst to the next: a burst is the first line request
after the servo line was quiet for ``QUIET_MS`` (a loop's SYNC_WRITE and its pings, back to
back, are one burst). A firmware that sends SYNC_WRITEs has its cycles from one SYNC_WRITE
to the next, whatever it reads in between and however long it computes before those reads;
the bursts before its first SYNC_WRITE (the boot's scan and configuration) are no cycles.
Busy cycles are the instructions run plus the cycles of poll loops the
emulator skipped (hil/mcu/poll.py: the core spins there on the chip); asleep is the rest.
At one instruction a cycle of HCLK and no flash wait states, busy time is a lower bound
of the chip's (docs/micropython-on-the-chip.md).
"""
from __future__ import annotations

from typing import Any

from hexhil.hil.mcu.timebase import FS_PER_S
from hexhil.protocol.dynamixel.stream import SYNC_WRITE
from hexhil.protocol.dynamixel.v1 import BROADCAST_ID

QUIET_MS = 2.0          # a gap on the servo line this long starts a new control cycle
LATE = 1.1              # a cycle this much longer than the median period is late
FS_PER_MS = FS_PER_S // 1000


def is_sync_write(tx: bytes) -> bool:
    """``tx`` starts with a broadcast SYNC_WRITE, in Protocol 1.0 or 2.0."""
    if tx[:3] == b"\xff\xff\xfd":
        return len(tx) > 7 and tx[4] == BROADCAST_ID and tx[7] == SYNC_WRITE
    return len(tx) > 4 and tx[:2] == b"\xff\xff" and tx[2] == BROADCAST_ID and tx[4] == SYNC_WRITE


def _quantile(sorted_values: list[float], q: float) -> float:
    """The nearest-rank ``q`` quantile of ``sorted_values``."""
    rank = max(1, -(-round(q * 1000) * len(sorted_values) // 1000))
    return sorted_values[min(rank, len(sorted_values)) - 1]


class ControlCycles:
    """Busy time per control cycle of ``core`` (hil/mcu/core.py), fed each servo burst."""

    def __init__(self, core: Any) -> None:
        self.core = core
        self._last_end_fs: int | None = None
        self._start: tuple[int, int, int] | None = None     # (burst fs, busy cycles, Hz)
        self.cycles: list[tuple[float, float]] = []         # (period ms, busy ms)
        self._synced = False                                 # a SYNC_WRITE went out

    def busy(self) -> int:
        st = self.core.shared
        return self.core.executed + st.skipped

    def burst(self, start_fs: int, hz: int, tx: bytes) -> None:
        """A servo burst ``tx`` that began at ``start_fs`` went out (it ends now)."""
        now_fs = self.core.now_fs()
        quiet = self._last_end_fs is None or start_fs - self._last_end_fs >= QUIET_MS * FS_PER_MS
        self._last_end_fs = now_fs
        if is_sync_write(tx):
            if not self._synced:
                self._synced, self._start = True, None
                self.cycles.clear()
        elif self._synced or not quiet:
            return
        busy = self.busy()
        if self._start is not None:
            t0, b0, hz0 = self._start
            self.cycles.append(((start_fs - t0) / FS_PER_MS, (busy - b0) * 1000 / hz0))
        self._start = (start_fs, busy, hz)

    def figures(self) -> dict[str, Any] | None:
        """The busy time's p50, p99 and maximum (ms), the median period, the count of
        cycles and of late ones (longer than LATE x the median period); None without a
        whole cycle."""
        if not self.cycles:
            return None
        periods = sorted(p for p, _ in self.cycles)
        busy = sorted(b for _, b in self.cycles)
        period = _quantile(periods, 0.5)
        return {"cycles": len(self.cycles), "period_ms": round(period, 3),
                "busy_p50_ms": round(_quantile(busy, 0.5), 3),
                "busy_p99_ms": round(_quantile(busy, 0.99), 3),
                "busy_max_ms": round(busy[-1], 3),
                "late": sum(p > LATE * period for p in periods)}
