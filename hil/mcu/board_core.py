"""The ELF board's hot path compiled (hil/mcu/board_core.c), through ctypes: the event heap,
the USARTs with their byte timing (hil/mcu/usart.py), the servo line's outgoing burst,
PA1's turns and PB's switch reads, SysTick's CSR reads and wraps, the exception model's
entry, return and choice, and the poll skipper's known waits and known non-waits.

A firmware sending servo packets spends its time on USART2: a byte written to DR, a poll of
TXE skipped to the byte's end, the next byte. The C code fronts the peripherals' MMIO region
and does them without Python, which it calls only where the board's Python state takes part
(a Python timer due, a USART's interrupt line high, USART2's transmitter idle: the burst
goes to the link, a console byte, a DMA request, a poll loop seen for the first time, a
USART's bus clock after a clock change). ``Shared`` is the state both sides read: the
core's time and its state between chunks (hil/mcu/core.py; a jump in C moves the chunk's
origin), the poll skipper's (hil/mcu/poll.py), the NVIC's bits, the USARTs' registers and
GPIO's (MODER, PUPDR, ODR), the switches and PA1's turns not yet posted to the link. The
board's loop runs in C too (hil/mcu/board_loop.py). The package builds ``_board_core.so``
beside this file; without it no ELF board is made (``require``).
"""
from __future__ import annotations

import ctypes
import os
from array import array
import weakref
from pathlib import Path
from typing import Any, Callable

from hexhil.hil.mcu.board_layout import (LAYOUT, PY_CALL, PY_DMA_RX, PY_DMA_TX, PY_FAILED,
                                          PY_IDLE, PY_INTR, PY_LINE, PY_PCLK, PY_POLLED,
                                          PY_RAISED, PY_SENT, PY_SWITCHES, PY_TIMER)
from hexhil.hil import native
from hexhil.hil.native import load_library
from hexhil.protocol.errors import BadFile, UserError

LIBRARY = Path(__file__).with_name("_board_core.so")
_P, _I32, _I64 = ctypes.c_void_p, ctypes.c_int32, ctypes.c_int64
# virtual time in C is int64 femtoseconds: 9,223 s; a longer ELF run is refused at its start
MAX_US = 9_000_000_000


class Shared(ctypes.Structure):
    """bc_t in board_core.c (hil/mcu/board_layout.py)."""
    _fields_ = LAYOUT.fields("bc")


class SharedField:
    """An attribute of an object whose ``shared`` (a ``Shared``) holds it, so that the C
    code reads and writes the same value; ``kind`` converts what the struct returns."""

    def __init__(self, field: str, kind: Callable[[int], Any] | None = None) -> None:
        self.field, self.kind = field, kind

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:
            return self
        value = getattr(obj.shared, self.field)
        return value if self.kind is None else self.kind(value)

    def __set__(self, obj: Any, value: int) -> None:
        setattr(obj.shared, self.field, int(value))


def _load() -> tuple[Any, str | None]:
    """The library, or None; and why a library that is there cannot run, or None."""
    try:   # its calls call back into Python
        lib = load_library(LIBRARY, keep_gil=True, layout=LAYOUT)
    except BadFile as exc:   # built from other sources: refused where a board is made
        return None, str(exc)
    if lib is None:
        return None, None
    sig = {"bc_timer_new": (_I32, [_P]), "bc_timer_set": (None, [_P, _I32, _I64]),
           "bc_timer_clear": (None, [_P, _I32]), "bc_timer_at": (_I64, [_P, _I32]),
           "bc_fire_due": (_I32, [_P, _I64]), "bc_now_fs": (_I64, [_P]),
           "bc_divider": (_I64, [_P, _I32]), "bc_usart_dma_request": (None, [_P, _I32]),
           "bc_usart_read": (ctypes.c_uint32, [_P, _I32, _I32]),
           "bc_usart_write": (None, [_P, _I32, _I32, ctypes.c_uint32]),
           "bc_usart_reset": (None, [_P, _I32]),
           "bc_add_wait": (_I32, [_P, ctypes.c_uint32, ctypes.c_uint32, ctypes.c_uint32]),
           "bc_add_not_loop": (_I32, [_P, ctypes.c_uint32, ctypes.c_uint32, ctypes.c_uint32]),
           "bc_quiet_init": (_I32, [_P, _P, _I32]), "bc_free": (None, [_P])}
    lib.bc_intr.restype, lib.bc_intr.argtypes = None, [_P, ctypes.c_uint32, _P]
    lib.bc_count.restype, lib.bc_count.argtypes = None, [_P, ctypes.c_uint64, ctypes.c_uint32, _P]
    lib.bc_rx_queue.restype, lib.bc_rx_queue.argtypes = None, [_P, _P, _P, _I32]
    lib.bc_rx_deliver.restype, lib.bc_rx_deliver.argtypes = _I32, [_P, _I64]
    for name in ("bc_next_exception", "bc_execution_priority", "bc_masked_ready", "bc_wakes"):
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = _I32, [_P]
    for name in ("bc_group_priority", "bc_pending_from"):
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = _I32, [_P, _I32]
    lib.bc_enter.restype = _I64
    lib.bc_enter.argtypes = [_P, _I32, ctypes.c_uint32, _I32, ctypes.c_uint32]
    lib.bc_unstack.restype, lib.bc_unstack.argtypes = _I32, [_P, ctypes.c_uint32]
    lib.bc_loop.restype, lib.bc_loop.argtypes = _I32, [_P, _I64, _I64]
    lib.bc_run_chunk.restype, lib.bc_run_chunk.argtypes = _I64, [_P, _I64]
    lib.bc_idr.restype, lib.bc_idr.argtypes = ctypes.c_uint32, [ctypes.c_uint32] * 4
    lib.bc_odr_after.restype = ctypes.c_uint32
    lib.bc_odr_after.argtypes = [ctypes.c_uint32, _I32, ctypes.c_uint32]
    lib.bc_polled.restype = _I32
    lib.bc_polled.argtypes = [_P, ctypes.c_uint32, ctypes.c_uint32]
    lib.bc_jump_here.restype, lib.bc_jump_here.argtypes = _I32, [_P]
    lib.bc_skip_to_event.restype, lib.bc_skip_to_event.argtypes = _I32, [_P]
    for name, (res, args) in sig.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = res, args
    return lib, None


_LIB, _MISMATCH = _load()


def require() -> None:
    """An ELF board is made only where its core is compiled and was built from these
    sources (one line otherwise)."""
    if _MISMATCH is not None:
        raise BadFile(_MISMATCH)
    native.require(_LIB, LIBRARY, "an ELF board")


def library() -> Any:
    """The loaded ``_board_core.so`` (None where it is not built)."""
    return _LIB


def too_long(at_fs: int) -> UserError:
    return UserError(f"the ELF board counts virtual time to {MAX_US // 10**6} s "
                     f"(64-bit femtoseconds); t={at_fs // 10**15} s is beyond it")


class Timer:
    """One scheduled thing of a peripheral on the C heap (the end of a UART byte, a SysTick
    wrap, a timer update): ``set`` moves it, ``clear`` cancels it."""

    __slots__ = ("fn", "tid", "_events")

    def __init__(self, events: "Events", fn: Callable[[int], None], tid: int) -> None:
        self.fn, self.tid, self._events = fn, tid, events

    @property
    def at_fs(self) -> int | None:
        at = _LIB.bc_timer_at(self._events.ref, self.tid)
        return None if at < 0 else at

    def set(self, at_fs: int) -> None:
        if at_fs > MAX_US * 10**9:
            raise too_long(at_fs)
        _LIB.bc_timer_set(self._events.ref, self.tid, at_fs)

    def clear(self) -> None:
        _LIB.bc_timer_clear(self._events.ref, self.tid)


class Events:
    """What the peripherals have scheduled, in virtual femtoseconds, on one C heap: the
    Python timers and C's own (a USART's byte end, SysTick's wrap, the servo line's reply
    bytes), ties fired in the order set. A chunk of instructions ends at the earliest, so a
    flag changes at its exact cycle; a poll of a flag whose change is scheduled can jump
    straight to it (hil/mcu/poll.py)."""

    def __init__(self, shared: Shared) -> None:
        self.shared = shared
        self.ref = ctypes.byref(shared)
        self._timers: dict[int, Timer] = {}
        self._error: BaseException | None = None
        self._fire = PY_TIMER(self._fired)
        shared.py_timer = self._fire
        shared.next_at = -1
        weakref.finalize(self, _LIB.bc_free, self.ref)

    def timer(self, fn: Callable[[int], None]) -> Timer:
        t = Timer(self, fn, _LIB.bc_timer_new(self.ref))
        self._timers[t.tid] = t
        return t

    def _fired(self, tid: int, at_fs: int) -> int:
        try:
            self._timers[tid].fn(at_fs)
            return 0
        except BaseException as exc:      # noqa: B036 -- raised again by fire_due's caller
            self._error = exc
            return 1

    def raise_error(self) -> None:
        """A Python callback under C raised: raise it here, once."""
        exc, self._error = self._error, None
        self.shared.err = 0
        if exc is not None:
            raise exc

    def now_fs(self) -> int:
        """The core's time in one C call (``bc_now_fs``)."""
        return _LIB.bc_now_fs(self.ref)

    def next_fs(self) -> int | None:
        at = self.shared.next_at
        return None if at < 0 else at

    def fire_due(self, now_fs: int) -> bool:
        fired = _LIB.bc_fire_due(self.ref, now_fs)
        if fired < 0:
            self.raise_error()
        return fired > 0


class NativeBoard:
    """The C side's calls into the board (hil/mcu/board.py): one dispatcher."""

    def __init__(self, board: Any) -> None:
        self.board = board
        self._call = PY_CALL(self._dispatch)
        board.core.shared.py_call = self._call

    def _dispatch(self, kind: int, a: int, b: int) -> int:
        board = self.board
        try:
            if kind == PY_SENT:
                board.sent(a, b)
            elif kind == PY_LINE:
                board.nvic.line(board.usarts[b].irq, bool(a))
            elif kind == PY_IDLE:
                board.line.flush()      # USART2's transmitter idle (TC)
            elif kind == PY_DMA_TX:
                byte = board.usarts[a].dma_tx()
                return -1 if byte is None else byte
            elif kind == PY_DMA_RX:
                return int(bool(board.usarts[b].dma_rx(a)))
            elif kind == PY_POLLED:
                return int(board.poll.repeated(a & 0xFFFFFFFF, b & 0xFFFFFFFF))
            elif kind == PY_PCLK:
                return board.usarts[a].pclk_hz()
            elif kind == PY_INTR:
                board.intr(a)
            elif kind == PY_SWITCHES:
                board.sync.fresh_switches()
            elif kind == PY_FAILED:
                exc, board.events._error = board.events._error, None
                if exc is not None:
                    board.space.failed(exc)
            return 0
        except BaseException as exc:      # noqa: B036 -- handed on by the C side
            board.events._error = exc
            return PY_RAISED   # C unwinds; the error is handed on

    def turns(self) -> list[tuple[int, int]]:
        """PA1's turns C made since the last call, (time in µs, level): the link's
        direction messages, posted before anything Python posts after them."""
        st = self.board.core.shared
        n = st.turns_n
        if not n:
            return []
        st.turns_n = 0
        return list(zip(st.turn_us[:n], st.turn_level[:n]))

    def queue_rx(self, queue: list[tuple[int, int]]) -> None:
        """A reply burst's bytes with their arrival times, delivered to USART2 in C."""
        at = array("q", [t for t, _ in queue])
        data = bytes([b for _, b in queue])
        _LIB.bc_rx_queue(ctypes.byref(self.board.core.shared),
                         (ctypes.c_int64 * len(at)).from_buffer(at), data, len(at))

    def deliver(self, at_fs: int) -> None:
        if _LIB.bc_rx_deliver(ctypes.byref(self.board.core.shared), at_fs) < 0:
            self.board.events.raise_error()

    def rx_waiting(self) -> int:
        st = self.board.core.shared
        return st.rx_n - st.rx_head

    def clear_rx(self) -> None:
        st = self.board.core.shared
        st.rx_n = st.rx_head = 0

    def burst(self) -> tuple[bytes, int, int] | None:
        """The bytes USART2 sent since the last take: (bytes, first byte's start, PA1),
        or None."""
        st = self.board.core.shared
        if not st.burst_n:
            return None
        data = ctypes.string_at(st.burst, st.burst_n)
        st.burst_n = 0
        return data, st.burst_fs, st.burst_dir


def front(shared: Shared, py_read: Any, py_write: Any, ppb_read: Any) -> tuple[Any, ...]:
    """The C MMIO callbacks (peripherals, PPB reads), Python's behind them for all but the
    USARTs, PA1's turns, PB's switches and SysTick's CSR."""
    pairs = (("py_read", "bc_mmio_read", py_read), ("py_write", "bc_mmio_write", py_write),
             ("py_ppb_read", "bc_ppb_read", ppb_read))
    for field, _, fn in pairs:
        setattr(shared, field, ctypes.cast(fn, _P).value)
    return tuple(ctypes.cast(getattr(_LIB, c), type(fn)) for _, c, fn in pairs)


def add_wait(shared: Shared, pc: int, addr: int, value: int) -> None:
    """A known poll wait (a full table takes no more: such a loop is skipped at its second
    read, by the watch's verdict)."""
    _LIB.bc_add_wait(ctypes.byref(shared), pc, addr, value)


def add_not_loop(shared: Shared, pc: int, addr: int) -> None:
    """A read at ``pc`` that waits on nothing (poll.py ``_loops_ok`` False): C answers it
    without Python, however far apart its repeats come."""
    if shared.nots.n >= 0 and _LIB.bc_add_not_loop(ctypes.byref(shared), pc, addr, 0) < 0:
        shared.nots.n = -1
