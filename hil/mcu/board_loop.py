"""The board's run loop and its exceptions in C (hil/mcu/board_core.c), through ctypes.

Each trip fires the timers due, takes the exception that preempts, sleeps through WFI or
runs a chunk, then looks for a lockup and the poll skipper's next step. ``bc_loop`` does
those trips in C, calling ``uc_emu_start`` itself, for as long as no Python callback took
part; it hands the trip to Python (board.py ``run``) where one did (a Python timer in the
head, a Python register or link call in the chunk, a poll loop watched), where a lockup may
be starting, and for everything Python names (a fault, an entry off SRAM); a quiet wait
(hil/mcu/quiet.py) it checks and skips itself. Under GDB, which stops between any two
instructions, it hands over before each chunk (the debugger serves GDB and limits the
chunk) and after it. A run has about 20,000 trips, most of them a wake-up, a short handler
and WFI again.
"""
from __future__ import annotations

import ctypes
from typing import Any, Callable

from hexhil.hil.mcu.board_core import Shared, library
from hexhil.hil.mcu.board_layout import (LOOP_AFTER_CHUNK, LOOP_AFTER_HEAD,
                                          LOOP_BEFORE_CHUNK, LOOP_ENTER, LOOP_HOOK_FAILED,
                                          LOOP_NULL_JUMP, LOOP_RAISED, LOOP_RESUME,
                                          LOOP_UC_ERROR)
from hexhil.hil.mcu.core import CoreFault

_P = ctypes.c_void_p


def hook_interrupts(shared: Shared, uc: Any) -> None:
    """Unicorn's interrupt hook in C (``bc_intr``): an exception return that nothing
    follows in Python is done there, everything else calls the board's ``intr``."""
    from unicorn import UC_HOOK_INTR
    from unicorn.unicorn_py3.unicorn import uclib
    handle = ctypes.c_size_t(0)
    if uclib.uc_hook_add(uc._uch, ctypes.byref(handle), UC_HOOK_INTR,
                         ctypes.cast(library().bc_intr, _P), ctypes.addressof(shared), 1, 0):
        raise RuntimeError("libunicorn refused the compiled interrupt hook")


def trips(core: Any) -> Callable[[int, int], int]:
    """``bc_loop`` for ``core``: (the longest chunk, the length of a trip whose head Python
    saw or -1) -> the LOOP_* code of where Python goes on."""
    ref, loop = ctypes.byref(core.shared), library().bc_loop
    return lambda max_chunk, n: loop(ref, max_chunk, n)


def handed_over(board: Any, where: int) -> int:
    """Python's part of a trip ``bc_loop`` handed over at ``where`` (board.py ``run``): the
    length of the chunk to go on with, its head done, or -1 for a new trip."""
    core = board.core
    st = core.shared
    if where == LOOP_AFTER_CHUNK:
        board.quiet.loud_chunk()
        board.after_chunk()
    elif where == LOOP_AFTER_HEAD:
        if board.ended or board.reset_if_asked():
            return -1
        if board.fault is not None:
            board.faulted(board.fault)
            return -1
        return st.loop_n
    elif where == LOOP_ENTER:            # the entry failed in C: the same call names it
        core.enter(st.loop_exc)
    elif where == LOOP_RAISED:
        board.events.raise_error()
    elif where == LOOP_HOOK_FAILED:      # a callback's exception, as emu_start raises it
        exc = core.chunk_fault(where)
        if isinstance(exc, CoreFault):
            raise CoreFault(board.fault_line(str(exc))) from None
        raise exc
    elif where in (LOOP_NULL_JUMP, LOOP_UC_ERROR):   # the chip's fault, or the run's end
        board.faulted(core.chunk_fault(where))
    elif where == LOOP_BEFORE_CHUNK:     # GDB has the core, or limits the chunk
        st.debug_n = board.debugger.chunk_limit(st.loop_n)
        return LOOP_RESUME
    else:                                # asleep, nothing pending, nothing scheduled
        raise CoreFault(board.fault_line("asleep (WFI/WFE) with no exception pending and "
                                         "nothing scheduled to wake the core"))
    return -1
