"""What the peripherals have scheduled, in virtual femtoseconds: the end of a UART byte, a
SysTick wrap, a timer update, a byte arriving from the servo line.

A chunk of instructions ends at the earliest one, so a flag changes at its exact cycle;
a poll of a flag whose change is scheduled can jump straight to it (hil/mcu/board.py).
"""
from __future__ import annotations

import heapq
import itertools
from typing import Callable

_push = heapq.heappush


class Timer:
    """One scheduled thing of a peripheral: ``set`` moves it, ``clear`` cancels it."""

    __slots__ = ("events", "fn", "at_fs", "_gen", "_heap", "_seq")

    def __init__(self, events: "Events", fn: Callable[[int], None]) -> None:
        self.events, self.fn = events, fn
        self.at_fs: int | None = None
        self._gen = 0
        self._heap, self._seq = events.heap, events.next_seq

    def set(self, at_fs: int) -> None:
        gen = self._gen = self._gen + 1
        self.at_fs = at_fs
        _push(self._heap, (at_fs, self._seq(), self, gen))

    def clear(self) -> None:
        self._gen += 1
        self.at_fs = None


class Events:
    def __init__(self) -> None:
        self.heap: list[tuple[int, int, Timer, int]] = []
        self.next_seq = itertools.count(1).__next__     # ties fire in the order set

    def timer(self, fn: Callable[[int], None]) -> Timer:
        """A timer that calls ``fn(at_fs)`` when it falls due."""
        return Timer(self, fn)

    def next_fs(self) -> int | None:
        heap = self.heap
        while heap and heap[0][2]._gen != heap[0][3]:
            heapq.heappop(heap)
        return heap[0][0] if heap else None

    def fire_due(self, now_fs: int) -> bool:
        """Call every timer due by ``now_fs``, in time order; whether any fired."""
        fired = False
        heap = self.heap
        while heap:
            at, _, timer, gen = heap[0]
            if timer._gen != gen:
                heapq.heappop(heap)
                continue
            if at > now_fs:
                break
            heapq.heappop(heap)
            timer.at_fs = None
            timer._gen += 1
            timer.fn(at)
            fired = True
        return fired
