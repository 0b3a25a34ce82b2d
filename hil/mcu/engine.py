"""The seam between the MCU and Unicorn, through Unicorn's public API only: how a chunk's
instructions are counted, where the running instruction's PC is read, and how a chunk is
cut after the instruction running now.

A UC_HOOK_CODE before each instruction (``bc_count``, hil/mcu/board_core.c) counts it,
keeps its PC and stops the chunk past its length with ``uc_emu_stop``, the way Unicorn's
own ``count`` does, at what that count costs. Beyond it, the MCU calls libunicorn's public
C functions through ctypes (``uclib``: the register batches, MMIO maps, hooks) with the
binding's handle ``Uc._uch``.
"""
from __future__ import annotations

import ctypes
import struct

from unicorn import UC_HOOK_CODE, Uc
from unicorn.unicorn_py3.unicorn import uclib


class Regs:
    """A fixed list of registers read or written in one call into libunicorn: its Python
    binding costs ~10 us a register, a batch of 30 here ~2 us: the values go in and out
    of the ctypes array with one struct call through a memoryview, and the call passes
    ready-made pointers (``uc_reg_*_batch`` without argument types: ctypes' checks of
    typed pointer arguments cost more than the call). Every register here is 32 bits
    wide: each value fills the low half of its 8-byte slot, the upper half stays zero, so
    a read needs no clearing first; values written are 0 .. 2**32 - 1."""

    def __init__(self, uc: Uc, ids: tuple[int, ...]) -> None:
        n = len(ids)
        self._ids = (ctypes.c_int * n)(*ids)
        self._vals = (ctypes.c_uint64 * n)()
        self._mem = memoryview(self._vals).cast("B")
        self._fmt = struct.Struct("<" + "I4x" * n)
        base = ctypes.addressof(self._vals)
        self._ptrs = (ctypes.c_void_p * n)(*[base + 8 * i for i in range(n)])
        self._args = (ctypes.c_void_p(ctypes.cast(uc._uch, ctypes.c_void_p).value),
                      ctypes.c_void_p(ctypes.addressof(self._ids)),
                      ctypes.c_void_p(ctypes.addressof(self._ptrs)), ctypes.c_int(n))

    def read(self) -> list[int]:
        _READ_BATCH(*self._args)
        return list(self._fmt.unpack_from(self._mem))

    def write(self, values: list[int]) -> None:
        self._fmt.pack_into(self._mem, 0, *values)
        _WRITE_BATCH(*self._args)


def _untyped(name: str):
    """A libunicorn function called with ctypes objects only (no argument conversion)."""
    fn = uclib[name]                     # a fresh function object: the binding's keeps its types
    fn.restype, fn.argtypes = ctypes.c_int, None
    return fn


_READ_BATCH, _WRITE_BATCH = _untyped("uc_reg_read_batch"), _untyped("uc_reg_write_batch")


def attach_engine(uc: Uc, st: ctypes.Structure, lib: object) -> None:
    """Point the shared state's count (``st.ctr``, the chunk's length beside it) and its PC
    word (``st.pc``) at the board core's, and install its UC_HOOK_CODE (``bc_count``)."""
    base = ctypes.addressof(st)
    st.ctr = base + type(st).pub_count.offset
    st.pc = base + type(st).pub_pc.offset
    handle = ctypes.c_size_t(0)
    if uclib.uc_hook_add(uc._uch, ctypes.byref(handle), UC_HOOK_CODE,
                         ctypes.cast(lib.bc_count, ctypes.c_void_p), base, 1, 0):
        raise RuntimeError("libunicorn refused the compiled instruction count")
