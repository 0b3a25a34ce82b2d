"""The world steps on while the firmware finishes its cycle.

Under micropython a cycle has two exchanges: the status reads (R) and the sleep. After R's
reply the firmware checks its faults and sends its CAN telemetry, then asks to sleep; the
host had nothing to do meanwhile (170 us a cycle on this machine), and stepped the world
to the wake only once the sleep came. That batch almost never changes what the world does
until the wake: it holds CAN frames, events and the sleep, which take effect on the run's
clock, not the world's.

So after R's reply the world steps ahead, from a checkpoint, while the run's clock stays
where it is: up to the wake the sleeps' rhythm predicts, and never past the next host node
tick or ground-truth sample (they read the world at their instant), the next injected
fault (it may change the drives) or the run's end. When the batch comes, its messages are
carried out as before; first ``settle`` keeps the steps if the batch leads there (only CAN
frames and events, and a sleep no earlier than the world got), and otherwise puts the world
back at its checkpoint, so the run is the one it would have been: the same trace, byte for
byte, either way.
"""
from __future__ import annotations

import struct
from typing import Any, Callable

from hexhil.hil.seams import CheckpointWorld
from hexhil.protocol import sim_link

_CLOCK_ONLY = (sim_link.OP_CAN, sim_link.OP_EVENT)   # take effect on the run's clock alone


class Lookahead:
    """``step(end_us)`` after R's reply; ``settle(msgs)`` with the firmware's next batch,
    before it is carried out. ``now_us`` is the run's clock; ``next_due`` the next instant
    something else reads or changes the world (host node tick, ground-truth sample,
    injected fault), or None."""

    def __init__(self, world: CheckpointWorld, now_us: Callable[[], int],
                 next_due: Callable[[], int | None]) -> None:
        self.world, self.now_us, self.next_due = world, now_us, next_due
        self._saved: Any = None
        self._wake_us: int | None = None      # the last sleep's wake
        self._period_us: int | None = None    # between the last two wakes
        self.kept = self.restored = 0         # cycles stepped ahead and kept, or taken back

    def step(self, end_us: int) -> None:
        if self._period_us is None:
            return
        until = min(self._wake_us + self._period_us, end_us)
        due = self.next_due()
        if due is not None:
            until = min(until, due)
        if until < self.world.next_step_us() or until <= self.now_us():
            return
        self._saved = self.world.checkpoint()
        if self._saved is not None:
            self.world.advance_to(until)

    def settle(self, msgs: list[tuple[int, bytes]]) -> None:
        wake = None
        for op, payload in msgs:
            if op == sim_link.OP_SLEEP and len(payload) == 8:
                (wake,) = struct.unpack_from("<Q", payload, 0)
        if wake is not None:
            if self._wake_us is not None and wake > self._wake_us:
                self._period_us = wake - self._wake_us
            self._wake_us = wake
        if self._saved is None:
            return
        saved, self._saved = self._saved, None
        if (wake is not None and wake >= self.world.t_us
                and all(op in _CLOCK_ONLY for op, _ in msgs[:-1])):
            self.kept += 1
        else:
            self.world.restore(saved)
            self.restored += 1
