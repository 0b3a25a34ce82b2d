"""Waiting costs no host time: a poll loop is skipped to the moment its flag can change.

When the same register read returns the same value twice with nothing else in between,
the next pass is watched (the same instruction count between the reads, the same core
registers, SRAM the same to the byte before and after it). Confirmed, virtual
time jumps to the next scheduled event (the only moment a register can change) and the
loop goes on from its read; a loop whose passes differ (a counter in a register or in RAM)
runs instruction by instruction. A loop once confirmed (its PC, register and pass length)
is skipped from then on inside the chunk, without stopping the core, at its first read of
the value it waited on.

SRAM is compared, never watched with a Unicorn store hook: with a UC_HOOK_MEM_WRITE hook
listed, Unicorn 2.1.4 mistranslates a conditional store inside an IT block (an ITTE whose
first instruction is a store goes astray), which is what MicroPython's gc_mark_subtree
runs while its SysTick handler's read of SysTick->CTRL is being watched.
"""
from __future__ import annotations

import ctypes
from typing import Any

from hexhil.hil.mcu.board_core import add_not_loop, add_wait, library


class PollSkipper:
    """A read's bookkeeping, the known waits and the jump are the board core's
    (board_core.c ``bc_polled``, ``bc_jump_here``); the watch of a loop's pass is here."""

    def __init__(self, board: Any) -> None:
        self.board = board
        self._st = board.core.shared     # the poll's state, shared with hil/mcu/board_core.c
        self._lib, self._ref = library(), ctypes.byref(self._st)
        self._watch: tuple | None = None
        self._sram: bytes | None = None   # SRAM when the watched pass began
        self._skip = False
        # a read site's verdict, keyed on what it reads (PC, register), not on how far
        # apart its repeats come: a site that is no wait is never watched again
        self._loops_ok: dict[tuple[int, int], bool] = {}

    def other_access(self) -> None:
        """A register access that is not a side-effect-free read: no poll goes on."""
        self._st.poll_valid = 0

    def polled(self, addr: int, value: int) -> bool:
        """A side-effect-free register read (hil/mcu/mmio.py's pages; the board core's own
        are its): True when the wait was skipped here, so the read is to be done again at
        the new time."""
        skipped = self._lib.bc_polled(self._ref, addr, value)
        if self._st.err:                 # a timer fired by the jump raised
            self.board.events.raise_error()
        return bool(skipped)

    def repeated(self, addr: int, value: int) -> bool:
        """The same read again, where no known wait or non-wait answers it (``bc_polled``
        asks): the pass since the last one is watched, and a pass confirmed pure makes the
        loop a known wait. True when the wait was skipped here."""
        core, st = self.board.core, self._st
        now = core.now()
        delta = now - st.poll_at
        st.poll_at = now
        loop = (core.pc_now(), addr, delta)
        watch = self._watch
        if watch is None:
            known = self._loops_ok.get(loop[:2])
            if known:                  # watched once: the same code, the same pass
                self._known_wait(loop[0], addr, value)
                return self._jump_here()
            if known is None:
                self._watch = (loop, value, core.context())
                st.watching = 1
                st.reread = 1
                core.stop()
        elif watch[0] == loop and watch[1] == value and self._sram_unchanged() \
                and core.context() == watch[2]:
            self._loops_ok[loop[:2]] = True
            self._known_wait(loop[0], addr, value)
            self._skip = True
            core.stop()
        else:
            self._loops_ok[watch[0][:2]] = False
            add_not_loop(self._st, *watch[0][:2])
            self._end_watch()
        return False

    def _known_wait(self, pc: int, addr: int, value: int) -> None:
        """From now on the loop at ``pc`` is skipped at its first read of ``value``: it
        was confirmed pure, so until the next event it could only read the same again."""
        add_wait(self._st, pc, addr, value)

    def _jump_here(self) -> bool:
        """Skip a known poll loop inside the chunk (board_core.c ``bc_jump_here``)."""
        return bool(self._lib.bc_jump_here(self._ref))

    def forget(self) -> None:
        """A system reset: no poll is under way (the loops learnt stay: the same code)."""
        self._end_watch()
        self._st.poll_valid = 0
        self._skip = False
        self._st.reread = 0

    def _end_watch(self) -> None:
        self._watch = None
        self._st.watching = 0
        self._sram = None

    def after_chunk(self) -> None:
        core = self.board.core
        if self._skip:
            self._skip = False
            self._end_watch()
            self._st.poll_valid = 0
            self._st.reread = 0
            self._lib.bc_skip_to_event(self._ref)
        elif self._watch is not None and self._sram is None and core.stopped:
            self._sram = bytes(core.sram_view())   # a loop seen for the first time
        elif self._watch is not None and not core.stopped:
            self._end_watch()

    def _sram_unchanged(self) -> bool:
        """The watched pass left SRAM as it found it (a copy and a memcmp, ~20 us)."""
        return self._sram is not None and bytes(self.board.core.sram_view()) == self._sram
