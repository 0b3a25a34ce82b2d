"""Waiting on RAM costs no host time: a loop that only reads memory is skipped to the next
event, the first moment an interrupt (or a DMA transfer) could change what it reads.

ST's ``HAL_Delay`` spins on ``uwTick``, which only SysTick's handler changes; a user's
``while (!flag) {}`` waits for an interrupt the same way. Neither touches a register, so
the poll skipper (hil/mcu/poll.py) never sees them. A chunk that ran its whole length
without a single register access is a candidate: its end state is recorded (every core and
FPU register, and SRAM), the next chunk runs exactly ``QUIET_PASS`` instructions
(hil/mcu/board_layout.py), and if the state after it is the same, to the bit, the loop is a
fixed point of its own code. Nothing but an event can change it, so virtual time jumps to
the next event, as a WFI would sleep. The verdict is the state itself, never the loop's
timing: each wait is checked again, and a loop that counts (in a register, in RAM, in an
FPU register) is never skipped.

``QUIET_PASS`` is a whole number of passes of any loop of up to 10 instructions (and of 12,
14, 15, 18, 20, 21, 24, 28, 30, 35, 36 ...): a loop of another length runs instruction by
instruction, correct and only slower. A chunk that turns out not to be such a loop costs a
look; after a miss the next ones are let by (up to ``MAX_BACKOFF`` chunks), so code that
computes for a long time without touching a register pays almost nothing.

After a skip the state is held (``held``): the event at the end of the skip may change
nothing the loop sees (the link's millisecond tick, a timer whose interrupt is off), and
when no exception was taken and the state is still the confirmed one, to the bit, time
jumps to the following event at once, without running the two passes again.

The steps are the board core's, in its loop (hil/mcu/board_core.c ``quiet_chunk``,
``quiet_held``), on copies of its own, so a quiet wait costs no call into Python; a chunk
Python saw (one that called Python) only ends a pass being checked (``loud_chunk``).
"""
from __future__ import annotations

import ctypes

from typing import Any

from unicorn import arm_const as A

from hexhil.hil.mcu.board_core import library

STATE_REGS = (tuple(A.UC_ARM_REG_R0 + i for i in range(13))
              + (A.UC_ARM_REG_SP, A.UC_ARM_REG_LR, A.UC_ARM_REG_PC, A.UC_ARM_REG_XPSR,
                 A.UC_ARM_REG_CONTROL, A.UC_ARM_REG_MSP, A.UC_ARM_REG_PSP,
                 A.UC_ARM_REG_PRIMASK, A.UC_ARM_REG_BASEPRI, A.UC_ARM_REG_FAULTMASK,
                 A.UC_ARM_REG_FPSCR)
              + tuple(A.UC_ARM_REG_S0 + i for i in range(32)))


class QuietLoops:
    """The board core's quiet-loop state: its buffers, and what Python ends."""

    def __init__(self, board: Any) -> None:
        self._st = board.core.shared
        self._lib, self._ref = library(), ctypes.byref(self._st)
        ids = (ctypes.c_int32 * len(STATE_REGS))(*STATE_REGS)
        if not self._lib.bc_quiet_init(self._ref, ids, len(STATE_REGS)):
            raise MemoryError("the board core got no buffers for quiet loops")

    def loud_chunk(self) -> None:
        """A chunk that touched a register or slept: no pass is being checked."""
        self._st.q_seen = 0

    def forget(self) -> None:
        """A system reset: nothing recorded goes on."""
        st = self._st
        st.q_seen = st.quiet_hold = st.quiet_n = st.quiet_wait = 0
