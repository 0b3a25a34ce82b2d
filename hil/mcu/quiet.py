"""Waiting on RAM costs no host time: a loop that only reads memory is skipped to the next
event, the first moment an interrupt (or a DMA transfer) could change what it reads.

ST's ``HAL_Delay`` spins on ``uwTick``, which only SysTick's handler changes; a user's
``while (!flag) {}`` waits for an interrupt the same way. Neither touches a register, so
the poll skipper (hil/mcu/poll.py) never sees them. A chunk that ran its whole length
without a single register access is a candidate: its end state is recorded (every core and
FPU register, and SRAM), the next chunk runs exactly ``PASS`` instructions, and if the state
after it is the same, to the bit, the loop is a fixed point of its own code. Nothing but an
event can change it, so virtual time jumps to the next event, as a WFI would sleep. The
verdict is the state itself, never the loop's timing: each wait is checked again, and a loop
that counts (in a register, in RAM, in an FPU register) is never skipped.

``PASS`` is a whole number of passes of any loop of up to 10 instructions (and of 12, 14,
15, 18, 20, 21, 24, 28, 30, 35, 36 ...): a loop of another length runs instruction by
instruction, correct and only slower. A chunk that turns out not to be such a loop costs
Python a look; after a miss the next ones are let by (up to ``MAX_BACKOFF`` chunks), so
code that computes for a long time without touching a register pays almost nothing.

After a skip the state is held (``held``): the event at the end of the skip may change
nothing the loop sees (the link's millisecond tick, a timer whose interrupt is off), and
when no exception was taken and the state is still the confirmed one, to the bit, time
jumps to the following event at once, without running the two passes again.

The board core (hil/mcu/board_core.c) takes the same steps in its loop, on copies of its
own, so a quiet wait costs no call into Python; a trip the loop hands to Python (an
exception Python enters, a sleep with nothing scheduled) takes them here.
"""
from __future__ import annotations

import ctypes

from typing import Any

from unicorn import arm_const as A

from hexhil.hil.mcu.board_core import library
from hexhil.hil.mcu.board_layout import MAX_BACKOFF, QUIET_PASS as PASS   # C's too
from hexhil.hil.mcu.engine import Regs

STATE_REGS = (tuple(A.UC_ARM_REG_R0 + i for i in range(13))
              + (A.UC_ARM_REG_SP, A.UC_ARM_REG_LR, A.UC_ARM_REG_PC, A.UC_ARM_REG_XPSR,
                 A.UC_ARM_REG_CONTROL, A.UC_ARM_REG_MSP, A.UC_ARM_REG_PSP,
                 A.UC_ARM_REG_PRIMASK, A.UC_ARM_REG_BASEPRI, A.UC_ARM_REG_FAULTMASK,
                 A.UC_ARM_REG_FPSCR)
              + tuple(A.UC_ARM_REG_S0 + i for i in range(32)))


class QuietLoops:
    """The board's quiet-chunk check (``Board``'s chunks, in C or in Python)."""

    def __init__(self, board: Any) -> None:
        self.board = board
        self._st = board.core.shared
        self._regs = Regs(board.core.uc, STATE_REGS)
        self._seen: tuple[int, list[int], bytes] | None = None   # (cycle, registers, SRAM)
        self._held: tuple[list[int], bytes] | None = None        # a confirmed fixed point
        self._backoff = 1
        ids = (ctypes.c_int32 * len(STATE_REGS))(*STATE_REGS)   # the same steps in C
        if not library().bc_quiet_init(ctypes.byref(self._st), ids, len(STATE_REGS)):
            raise MemoryError("the board core got no buffers for quiet loops")

    def quiet_chunk(self, ran: int) -> None:
        """A chunk of ``ran`` instructions made no register access and did not sleep."""
        core, st = self.board.core, self._st
        state = self._regs.read()
        sram = bytes(core.sram_view())
        seen = self._seen
        if seen is None or ran != PASS or core.cyc - seen[0] != PASS:
            self._seen = (core.cyc, state, sram)
            st.quiet_n = PASS
            return
        self._seen = None
        if state != seen[1] or sram != seen[2]:
            self._miss()
            return
        self._backoff = 1
        if self._skip():
            self._held = (state, sram)
            st.quiet_hold = 1

    def _skip(self) -> bool:
        """Time jumps to the next event; whether it moved."""
        core = self.board.core
        nxt = self.board.events.next_fs()
        if nxt is None:
            return False
        cyc = core.time.cycle_of(nxt)
        if cyc <= core.cyc:
            return False
        self._st.skipped += cyc - core.cyc
        core.cyc = cyc
        return True

    def held(self) -> bool:
        """No exception was taken since the last skip and nothing has run: when the state
        is still the confirmed fixed point, skip again (True); else the hold ends."""
        held, st = self._held, self._st
        if held is not None and self._regs.read() == held[0] and \
                bytes(self.board.core.sram_view()) == held[1] and self._skip():
            return True
        self._held = None
        st.quiet_hold = 0
        return False

    def loud_chunk(self) -> None:
        """A chunk that touched a register or slept: no pass is being checked."""
        self._seen = None
        self._held = None
        self._st.q_seen = 0

    def _miss(self) -> None:
        st = self._st
        st.quiet_n = 0
        st.quiet_wait = self._backoff
        self._backoff = min(2 * self._backoff, MAX_BACKOFF)

    def forget(self) -> None:
        """A system reset: nothing recorded goes on."""
        self._seen = None
        self._held = None
        self._st.q_seen = 0
        self._st.quiet_hold = 0
        self._st.quiet_n = 0
        self._st.quiet_wait = 0
