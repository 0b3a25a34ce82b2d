"""The seam between the MCU and Unicorn: how a chunk's instructions are counted, where the
running instruction's PC is read, and how a chunk is cut after the instruction running now.

Two engines, chosen once per process (``engine_kind``):

- ``HOOKED``, Unicorn's public API only: a UC_HOOK_CODE before each instruction counts it,
  keeps its PC and stops the chunk past its length with ``uc_emu_stop``, the way Unicorn's
  own ``count`` does. In C (``bc_count``, hil/mcu/board_core.c) where the board core is
  compiled, so it costs what Unicorn's own count costs; in Python (slow) where it is not.
- ``CALIBRATED``, for the board in Python: Unicorn 2.1.4's own instruction counter and the
  CPU's PC word, found in its engine by calibration once per process (``counter_offset``,
  ``regs_place``). It is checked at start against the public engine on a program with a
  loop, an IT block, a cut store and a stopped load (``check_calibrated``): a Unicorn build
  that counts or keeps them elsewhere gets one warning line naming what differs, and the
  public engine instead, never a wrong count.

``HEXHIL_UNICORN_ENGINE=hooked`` or ``calibrated`` chooses one by hand. Beyond these, the MCU
calls libunicorn's public C functions through ctypes (``uclib``: the register batches, MMIO
maps, hooks) with the binding's handle ``Uc._uch``.
"""
from __future__ import annotations

import ctypes
import logging
import os
import struct
from enum import Enum

import unicorn
from unicorn import UC_ARCH_ARM, UC_HOOK_CODE, UC_MODE_MCLASS, UC_MODE_THUMB, Uc
from unicorn import arm_const as A
from unicorn.unicorn_py3.unicorn import MMIO_READ_CFUNC, MMIO_WRITE_CFUNC, uclib

A_PC = A.UC_ARM_REG_PC


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


_COUNTER: list[int] = []


def counter_offset() -> int:
    """Where Unicorn keeps the instructions run by the current ``emu_start``: the one
    8-byte word of its engine that equals what two runs of known length counted; the
    next word holds the count it was given, which its count hook compares before each
    instruction (hil/mcu/core.py ``cut_after`` lowers it: checked here too)."""
    if _COUNTER:
        return _COUNTER[0]
    uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
    uc.mem_map(0x1000, 0x1000)
    uc.mem_write(0x1000, bytes.fromhex("0130fde7"))        # adds r0, #1; b .-2
    base = ctypes.cast(uc._uch, ctypes.c_void_p).value
    words = (ctypes.c_uint64 * 4096).from_address(base)
    found = None
    for n in (12345, 777, 4321):
        uc.emu_start(0x1001, 0, 0, n)
        here = {i for i in range(4095) if words[i] == n + 1 and words[i + 1] == n}
        found = here if found is None else found & here
    if not found or len(found) != 1:
        raise RuntimeError("this Unicorn build keeps no instruction counter where 2.1.4 does")
    at = found.pop()

    def store(handle: int, offset: int, size: int, value: int, _ud: int) -> None:
        words[at + 1] = words[at]                           # stop after this store
    callback = MMIO_WRITE_CFUNC(store)
    uclib.uc_mmio_map(uc._uch, 0x40000000, 0x1000, None, None, callback, None)
    # movs r1, #0x40 ; lsls r1, r1, #24 ; str r0, [r1] ; nop ; nop ; b .
    uc.mem_map(0x2000, 0x1000)
    uc.mem_write(0x2000, bytes.fromhex("4021 0906 0860 00bf 00bf fee7"))
    uc.emu_start(0x2001, 0, 0, 50)
    if words[at] - 1 != 3 or uc.reg_read(A.UC_ARM_REG_PC) != 0x2006:
        raise RuntimeError("this Unicorn build does not stop where its count is lowered")
    _COUNTER.append(at * 8)
    return _COUNTER[0]


_REGS_PLACE: list[tuple[int, int] | None] = []


def _readable() -> list[tuple[int, int]]:
    """This process's readable memory (Linux); none known elsewhere."""
    spans = []
    try:
        with open("/proc/self/maps") as maps:
            for line in maps:
                span, perms = line.split()[:2]
                if perms[0] == "r":
                    lo, hi = span.split("-")
                    spans.append((int(lo, 16), int(hi, 16)))
    except OSError:
        return []
    return spans


def regs_place() -> tuple[int, int] | None:
    """Where the CPU's R0-R15 live: (the engine's word that points at the CPU state, the
    offset of R0 in it), found by calibration once per process like the counter; None
    where this Unicorn build keeps them elsewhere (then the PC is read through
    ``uc_reg_read``). With a count limit Unicorn stores the PC before every instruction
    (its count hook needs it), so an MMIO callback reads the PC of its own load here for
    ~0.1 us instead of a ctypes call's microseconds; the calibration checks just that."""
    if _REGS_PLACE:
        return _REGS_PLACE[0]
    uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
    uc.mem_map(0x1000, 0x1000)
    marks = [0x5A000000 + 0x1111 * i for i in range(13)]
    for i, v in enumerate(marks):
        uc.reg_write(A.UC_ARM_REG_R0 + i, v)
    pattern = struct.pack("<13I", *marks)
    spans = _readable()
    words = (ctypes.c_uint64 * 4096).from_address(ctypes.cast(uc._uch, ctypes.c_void_p).value)
    found = None
    for i in range(4096):
        w = words[i]
        if w and any(lo <= w and w + 0x10000 <= hi for lo, hi in spans):
            at = ctypes.string_at(w, 0x10000).find(pattern)
            if at >= 0 and at % 4 == 0:
                found = (i, at)
                break
    if found is not None:      # the PC there is the running load's own, as uc_reg_read says
        seen: list[tuple[int, int]] = []
        pc = ctypes.c_uint32.from_address(words[found[0]] + found[1] + 60)

        def read(handle: int, offset: int, size: int, _ud: int) -> int:
            one = ctypes.c_uint64(0)
            uclib.uc_reg_read(uc._uch, A.UC_ARM_REG_PC, ctypes.byref(one))
            seen.append((pc.value, one.value))
            return 0
        callback = MMIO_READ_CFUNC(read)
        uclib.uc_mmio_map(uc._uch, 0x40000000, 0x1000, callback, None, None, None)
        # movs r1, #0x40 ; lsls r1, r1, #24 ; ldr r0, [r1] ; nop ; ldr r0, [r1, #4] ; b .
        uc.mem_write(0x1000, bytes.fromhex("4021 0906 0868 00bf 4868 fee7"))
        uc.emu_start(0x1001, 0, 0, 8)
        if [s[0] for s in seen] != [0x1004, 0x1008] or any(a != b for a, b in seen):
            found = None
    _REGS_PLACE.append(found)
    return found


log = logging.getLogger(__name__)


class EngineKind(Enum):
    HOOKED = "hooked"            # Unicorn's public API: a code hook counts
    CALIBRATED = "calibrated"    # Unicorn 2.1.4's own counter, found by calibration


_KIND: list[EngineKind] = []


def engine_kind(compiled: bool) -> EngineKind:
    """The engine for a core made now: the public one where the board core is compiled,
    the calibrated one for the board in Python when it passes its check."""
    chosen = os.environ.get("HEXHIL_UNICORN_ENGINE")
    if chosen:
        return EngineKind(chosen)
    if compiled:
        return EngineKind.HOOKED
    if not _KIND:
        why = check_calibrated()
        if why is not None:
            log.warning("unicorn %s: %s; the board runs through Unicorn's public API instead "
                        "(slower)", unicorn.__version__, why)
        _KIND.append(EngineKind.HOOKED if why else EngineKind.CALIBRATED)
    return _KIND[0]


# the check's program: movs r1, #0x40 ; lsls r1, r1, #24 (r1 = 0x40000000: the MMIO page)
# loop: adds r0, #1 ; cmp r0, #3 ; ite lo ; addlo r2, #1 ; addhs r3, #1 ; str r0, [r1] ;
# ldr r4, [r1, #4] ; b loop
_CHECK_CODE = bytes.fromhex("4021 0906 0130 0328 34bf 0132 0133 0860 4c68 f7e7")
_CHECK_LENGTHS = (1, 2, 3, 5, 7, 11, 13, 40)


def _check_run(calibrated: bool) -> list[tuple[int, int]]:
    """(instructions counted, PC) after each chunk of the check program, with a store that
    cuts the chunk after it (the limit lowered) and a load that stops it (``uc_emu_stop``)
    on alternate passes, counted by one engine."""
    uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
    uc.mem_map(0x1000, 0x1000)
    uc.mem_write(0x1000, _CHECK_CODE)
    state = (ctypes.c_uint64 * 3)()            # count, limit, PC
    if calibrated:
        base = ctypes.cast(uc._uch, ctypes.c_void_p).value + counter_offset()
        count = ctypes.c_uint64.from_address(base)
        limit = ctypes.c_uint64.from_address(base + 8)
    else:
        count = ctypes.c_uint64.from_address(ctypes.addressof(state))
        limit = ctypes.c_uint64.from_address(ctypes.addressof(state) + 8)

        def counted(uc_: Uc, address: int, size: int, _data: object) -> None:
            state[2] = address
            count.value += 1
            if count.value > limit.value:
                uc_.emu_stop()
        uc.hook_add(UC_HOOK_CODE, counted)
    passes, stop = [0], [False]

    def store(handle: int, offset: int, size: int, value: int, _ud: int) -> None:
        passes[0] += 1
        if passes[0] % 2:
            limit.value = count.value          # cut after this store
        else:
            stop[0] = True

    def load(handle: int, offset: int, size: int, _ud: int) -> int:
        if stop[0]:
            stop[0] = False
            uclib.uc_emu_stop(handle)          # stop: the load runs again
        return 0
    callbacks = (MMIO_READ_CFUNC(load), MMIO_WRITE_CFUNC(store))
    uclib.uc_mmio_map(uc._uch, 0x40000000, 0x1000, callbacks[0], None, callbacks[1], None)
    seen, pc = [], 0x1000
    for n in _CHECK_LENGTHS * 3:
        if calibrated:
            uc.emu_start(pc | 1, 0, 0, n)
        else:
            count.value, limit.value = 0, n
            uc.emu_start(pc | 1, 0, 0, 0)
        pc = uc.reg_read(A_PC)
        seen.append((count.value, pc))
    return seen


def check_calibrated() -> str | None:
    """How the calibrated engine differs from the public one on the check program, in
    words, or None when they count every chunk alike."""
    try:
        calibrated = _check_run(True)
    except RuntimeError as exc:
        return str(exc)
    public = _check_run(False)
    for i, (mine, theirs) in enumerate(zip(calibrated, public)):
        if mine != theirs:
            return (f"its own instruction count ends chunk {i + 1} of the check at "
                    f"{mine[0]} instructions, PC 0x{mine[1]:x}; its public hook at "
                    f"{theirs[0]}, PC 0x{theirs[1]:x}")
    return None


def attach_engine(uc: Uc, st: ctypes.Structure, lib: object | None) -> EngineKind:
    """Point the shared state's count (``st.ctr``, the chunk's length beside it) and, for
    the public engine, its PC word (``st.pc``) where this engine keeps them; install the
    public engine's UC_HOOK_CODE: the compiled ``bc_count`` where ``lib`` (the board core)
    is loaded, else the same in Python (each instruction a Python call: slow)."""
    kind = engine_kind(lib is not None)
    if kind is EngineKind.CALIBRATED:
        st.ctr = ctypes.cast(uc._uch, ctypes.c_void_p).value + counter_offset()
        st.engine_counts = 1
        return kind
    base = ctypes.addressof(st)
    st.ctr = base + type(st).pub_count.offset
    st.pc = base + type(st).pub_pc.offset
    if lib is not None:
        handle = ctypes.c_size_t(0)
        if uclib.uc_hook_add(uc._uch, ctypes.byref(handle), UC_HOOK_CODE,
                             ctypes.cast(lib.bc_count, ctypes.c_void_p), base, 1, 0):
            raise RuntimeError("libunicorn refused the compiled instruction count")
        return kind

    def counted(uc_: Uc, address: int, size: int, _data: object) -> None:
        st.pub_pc = address
        st.pub_count += 1
        if st.pub_count > st.pub_limit:
            uc_.emu_stop()
    uc.hook_add(UC_HOOK_CODE, counted)
    return kind
