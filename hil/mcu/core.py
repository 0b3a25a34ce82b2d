"""The Cortex-M4F core on Unicorn: exact instruction counts, time, and the exception model.

Unicorn runs Thumb-2 and the FPU but has no NVIC: exception entry (the 8-word frame, or
26 words with the FPU's S0-S15 and FPSCR), EXC_RETURN and the return are the board core's
(hil/mcu/board_core.c ``bc_enter``, ``bc_unstack``); what they cannot do is a fault named
here.
Virtual time counts instructions, one instruction one cycle of HCLK (no wait states, no
pipeline refills, no stacking cycles: say it as it is). The count inside a chunk comes
from the board core's instruction hook (hil/mcu/engine.py), so a register read knows its
exact cycle.

Stopping: only a register *read* may stop a chunk (``stop``; the load is then executed
again on resume, so only side-effect-free reads stop), never a write (Unicorn executes the
store again: a UART byte sent twice).
"""
from __future__ import annotations

import ctypes
import struct

from unicorn import (UC_ARCH_ARM, UC_MODE_MCLASS, UC_MODE_THUMB, UC_PROT_ALL,
                     UC_PROT_EXEC, UC_PROT_READ, Uc, UcError)
from unicorn import arm_const as A, unicorn_const as U
from unicorn.unicorn_py3.unicorn import uclib

from hexhil.hil.mcu.armv7m import RETURN_THREAD_PSP
from hexhil.hil.mcu.board_core import Shared, SharedField, library
from hexhil.hil.mcu.board_layout import (ENTER_BELOW_SRAM, ENTER_NO_HANDLER, ENTER_NO_TABLE,
                                          ENTER_OFF_SRAM, LEAVE_LOCKUP, LEAVE_THREAD,
                                          LOOP_HOOK_FAILED, LOOP_NULL_JUMP)
from hexhil.hil.mcu.elf_image import FLASH_BASE, FLASH_SIZE, SRAM_BASE, SRAM_SIZE, ElfImage
from hexhil.hil.mcu.engine import Regs, attach_engine
from hexhil.hil.mcu.timebase import FS_PER_S, TimeBase

ERASED = 0xFF                # an erased flash byte (RM0383 3.5)
NULL_JUMP = ("null", 0)      # a CoreFault's origin: a call through a null pointer
FRAME_REGS = (A.UC_ARM_REG_R0, A.UC_ARM_REG_R1, A.UC_ARM_REG_R2, A.UC_ARM_REG_R3,
              A.UC_ARM_REG_R12, A.UC_ARM_REG_LR)
STATE_REGS = (A.UC_ARM_REG_XPSR, A.UC_ARM_REG_CONTROL, A.UC_ARM_REG_MSP, A.UC_ARM_REG_PSP)
CONTEXT_REGS = tuple(A.UC_ARM_REG_R0 + i for i in range(13)) + (A.UC_ARM_REG_SP,
                                                                   A.UC_ARM_REG_LR)


class CoreFault(Exception):
    """The firmware did what ends a run (a fault, a lockup, an access to nothing); the
    ``origin`` of one the chip takes as an exception (hil/mcu/faults.py ``CAUSES``)."""

    def __init__(self, text: str, origin: tuple[str, int] | None = None) -> None:
        super().__init__(text)
        self.origin = origin


class Core:
    """The CPU, its memory (flash aliased at 0 as with BOOT0 low, SRAM) and its time."""

    cyc = SharedField("cyc")
    sleeping = SharedField("sleeping", bool)   # WFI/WFE: asleep until an event or interrupt
    # the rest of the state between chunks, where board_core.c ``bc_loop`` runs them too
    pc = SharedField("pc_next")
    executed = SharedField("executed")
    running = SharedField("running", bool)
    stopped = SharedField("stopped", bool)     # a read asked for the chunk to end
    cut = SharedField("cut", bool)             # the chunk ends after the instruction running now
    vtor = SharedField("vtor")
    fpu_on = SharedField("fpu_on", bool)       # CPACR grants CP10/CP11: FP contexts exist

    def __init__(self, image: ElfImage, hz: int) -> None:
        self.image = image
        uc = self.uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        self._flash = ctypes.create_string_buffer(FLASH_SIZE)
        ctypes.memset(self._flash, ERASED, FLASH_SIZE)     # what the ELF leaves is erased
        uc.mem_map_ptr(0, FLASH_SIZE, UC_PROT_READ | UC_PROT_EXEC, self._flash)
        uc.mem_map_ptr(FLASH_BASE, FLASH_SIZE, UC_PROT_READ | UC_PROT_EXEC, self._flash)
        self._sram = ctypes.create_string_buffer(SRAM_SIZE)   # frames go in and out here
        # struct reads and writes go through memoryviews: a ctypes buffer works out its
        # buffer format at each access, several microseconds
        self._flash_mem = memoryview(self._flash).cast("B")
        self._sram_mem = memoryview(self._sram).cast("B")
        uc.mem_map_ptr(SRAM_BASE, SRAM_SIZE, UC_PROT_ALL, self._sram)
        for seg in image.segments:
            uc.mem_write(seg.addr, seg.data)
        self._context = Regs(uc, CONTEXT_REGS)
        self._one = ctypes.c_uint64(0)
        self._one_ref = ctypes.byref(self._one)
        self._h = uc._uch
        # the time and the chunk's origin live where the compiled board sees them
        self.shared = st = Shared(st_tid=-1, rx_tid=-1, next_at=-1)
        attach_engine(uc, st, library())     # hil/mcu/engine.py
        self._ctr = ctypes.c_uint64.from_address(st.ctr)
        self._limit = ctypes.c_uint64.from_address(st.ctr + 8)   # the chunk's length
        self.time = TimeBase(hz, st)
        self.cyc = 0                 # instructions run before the current chunk
        self._share_exceptions(st)
        # the exception model's entry and return (board_core.c)
        ref, lib = ctypes.byref(st), library()
        self._enter = lambda exc, pc, fpu, vtor: lib.bc_enter(ref, exc, pc, fpu, vtor)
        self._unstack = lambda exc_return: lib.bc_unstack(ref, exc_return)
        self._run = lambda n: lib.bc_run_chunk(ref, n)
        self._fpscr0 = uc.reg_read(A.UC_ARM_REG_FPSCR)
        self.reset()
        self._pc_word = ctypes.c_uint32.from_address(st.pc)   # the running instruction's

    def _share_exceptions(self, st: Shared) -> None:
        """What the compiled board's exception return (board_core.c) reads and writes: the
        active exceptions, the sleep flag, the engine, SRAM and libunicorn's batch calls."""
        st.uc = ctypes.cast(self.uc._uch, ctypes.c_void_p).value
        st.sram = ctypes.addressof(self._sram)
        st.flash = ctypes.addressof(self._flash)
        st.reg_read_batch = ctypes.cast(uclib.uc_reg_read_batch, ctypes.c_void_p).value
        st.reg_write_batch = ctypes.cast(uclib.uc_reg_write_batch, ctypes.c_void_p).value
        st.emu_start = ctypes.cast(uclib.uc_emu_start, ctypes.c_void_p).value
        st.mem_read = ctypes.cast(uclib.uc_mem_read, ctypes.c_void_p).value
        st.emu_stop = ctypes.cast(uclib.uc_emu_stop, ctypes.c_void_p).value
        st.regid[:] = list(FRAME_REGS + STATE_REGS) + [
            A.UC_ARM_REG_S0, A.UC_ARM_REG_FPSCR, A.UC_ARM_REG_IPSR, A.UC_ARM_REG_PC,
            A.UC_ARM_REG_FAULTMASK, A.UC_ARM_REG_PRIMASK, A.UC_ARM_REG_BASEPRI]

    @property
    def active(self) -> list[int]:
        """The active exceptions, innermost last (a copy: an entry or a return changes
        them)."""
        st = self.shared
        return st.active[:st.nactive]

    def reset(self) -> None:
        """The core's reset: thread mode on MSP from the vector table, the masks clear,
        FPSCR as at power-on, the PC at the reset vector (R0-R12 keep their values:
        UNKNOWN after a reset, the same ones every run)."""
        uc = self.uc
        self.shared.nactive = 0
        uc.reg_write(A.UC_ARM_REG_CONTROL, 0)
        uc.reg_write(A.UC_ARM_REG_MSP, self.read32(self.vtor_base()))
        uc.reg_write(A.UC_ARM_REG_PRIMASK, 0)
        uc.reg_write(A.UC_ARM_REG_FAULTMASK, 0)
        uc.reg_write(A.UC_ARM_REG_BASEPRI, 0)
        uc.reg_write(A.UC_ARM_REG_IPSR, 0)
        uc.reg_write(A.UC_ARM_REG_FPSCR, self._fpscr0)
        self.pc = self.read32(self.vtor_base() + 4)
        self.sleeping = False

    # --- time ---------------------------------------------------------------------
    def now(self) -> int:
        """The cycle of the instruction running now (inside a chunk) or next."""
        if self.running:
            return self.shared.chunk0 + self._ctr.value - 1
        return self.shared.cyc

    def now_fs(self) -> int:
        t = self.time
        cyc = self.shared.chunk0 + self._ctr.value - 1 if self.running else self.shared.cyc
        if t._fs_per_cyc:
            return t._fs0 + (cyc - t._cyc0) * t._fs_per_cyc
        return t._fs0 + (cyc - t._cyc0) * FS_PER_S // t.hz

    def jump(self, cycles: int) -> None:
        """Let ``cycles`` pass without running them (a skipped wait)."""
        if self.running:
            self.shared.chunk0 += cycles
        else:
            self.shared.cyc += cycles

    def set_hz(self, hz: int) -> None:
        self.time.set_hz(self.now(), hz)

    # --- memory -------------------------------------------------------------------
    def read32(self, addr: int) -> int:
        if FLASH_BASE <= addr <= FLASH_BASE + FLASH_SIZE - 4:
            return struct.unpack_from("<I", self._flash_mem, addr - FLASH_BASE)[0]
        if SRAM_BASE <= addr <= SRAM_BASE + SRAM_SIZE - 4:
            return struct.unpack_from("<I", self._sram_mem, addr - SRAM_BASE)[0]
        return int.from_bytes(self.uc.mem_read(addr, 4), "little")

    def read16(self, addr: int) -> int:
        if FLASH_BASE <= addr <= FLASH_BASE + FLASH_SIZE - 2:
            return struct.unpack_from("<H", self._flash_mem, addr - FLASH_BASE)[0]
        return int.from_bytes(self.uc.mem_read(addr, 2), "little")

    def sram_view(self) -> memoryview:   # SRAM's bytes as they are now (no copy)
        return self._sram_mem

    def store32(self, addr: int, value: int) -> None:
        """A word into SRAM's buffer inside a callback (the bit-band alias)."""
        struct.pack_into("<I", self._sram_mem, addr - SRAM_BASE, value & 0xFFFFFFFF)

    def write32(self, addr: int, value: int) -> None:
        self.uc.mem_write(addr, (value & 0xFFFFFFFF).to_bytes(4, "little"))

    def vtor_base(self) -> int:
        return self.vtor or FLASH_BASE

    # --- running ------------------------------------------------------------------
    def stop(self) -> None:
        """End the chunk at the instruction now running (a read: it runs again)."""
        if self.running and not self.stopped:
            self.stopped = True
            self.uc.emu_stop()

    def cut_after(self) -> None:
        """End the chunk after the instruction running now (a register write that made
        an exception ready: it is taken before the next instruction, as on the chip).
        Unicorn stops a chunk when its counter passes the count it was given; lowering
        that count to this instruction's stops it before the next one, with the store
        done once (``emu_stop`` in a write callback would run the store again)."""
        if self.running:
            self._limit.value = self._ctr.value
            self.cut = True

    def run(self, n: int) -> int:
        """Run up to ``n`` instructions from ``self.pc`` (board_core.c ``bc_run_chunk``);
        how many ran."""
        ran = self._run(n)
        if ran < 0:
            raise self.chunk_fault(self.shared.loop_exc)
        return ran

    def chunk_fault(self, code: int) -> BaseException:
        """What ended a chunk early (``bc_run_chunk``'s LOOP_* code): a callback's
        exception, a jump to 0, an error of Unicorn's."""
        if code == LOOP_HOOK_FAILED:      # what Unicorn's emu_start raises
            exc, self.uc._hook_exception = self.uc._hook_exception, None
            return exc
        if code == LOOP_NULL_JUMP:
            return CoreFault("a jump to address 0 (a null function pointer)", NULL_JUMP)
        err = self.shared.uc_err
        return CoreFault(error_text(UcError(err), self), ("uc", err))

    # --- exceptions ---------------------------------------------------------------
    def pc_now(self) -> int:
        """The PC of the instruction running now (inside a callback of a chunk), or the
        next one's (between chunks)."""
        return self._pc_word.value

    def reg(self, reg_id: int) -> int:
        one = self._one
        one.value = 0
        uclib.uc_reg_read(self._h, reg_id, self._one_ref)
        return one.value & 0xFFFFFFFF

    def enter(self, exc: int) -> None:
        """Take exception ``exc`` at ``self.pc``: stack the frame, jump to its vector
        (board_core.c ``bc_enter``); a frame or a vector it cannot have is a fault."""
        vector = self._enter(exc, self.pc, self.fpu_on, self.vtor_base())
        if vector < 0:
            at = self.shared.fault_at & 0xFFFFFFFF
            raise CoreFault({
                ENTER_BELOW_SRAM: f"a stack overflow: exception {exc} stacks its frame at "
                                  f"0x{at:08x}, below SRAM",
                ENTER_OFF_SRAM: f"exception {exc} stacks its frame at 0x{at:08x}, past SRAM",
                ENTER_NO_TABLE: f"exception {exc}'s vector at 0x{at:08x} is in no memory "
                                f"(VTOR 0x{self.vtor:08x})",
                ENTER_NO_HANDLER: f"exception {exc} has no handler (vector 0x{at:08x})",
            }.get(vector, f"libunicorn refused the registers of exception {exc}'s entry"))
        self.pc = vector & ~1

    def leave(self, exc_return: int) -> int:
        """Return from the innermost exception through ``exc_return`` (board_core.c
        ``bc_unstack``); its number."""
        n = self.shared.nactive
        exc = self._unstack(exc_return)
        if exc == LEAVE_THREAD:
            raise CoreFault(f"an exception return (0x{exc_return:08x}) in thread mode")
        if exc == LEAVE_LOCKUP:
            raise CoreFault(f"an exception return to thread mode with {n - 1} exceptions "
                            "still active (a lockup)")
        if exc < 0:
            sp = self.reg(A.UC_ARM_REG_PSP if exc_return & 0xF == RETURN_THREAD_PSP & 0xF
                          else A.UC_ARM_REG_MSP)
            raise CoreFault(f"an exception return unstacks its frame from 0x{sp:08x}, which "
                            "no memory holds")
        return exc

    def context(self) -> tuple[int, ...]:
        """The integer registers, to tell one pass of a poll loop from the next."""
        return tuple(self._context.read())


def error_text(error: UcError, core: Core) -> str:
    kinds = {U.UC_ERR_READ_UNMAPPED: "a read of nothing", U.UC_ERR_WRITE_UNMAPPED:
             "a write to nothing", U.UC_ERR_FETCH_UNMAPPED: "an instruction fetch from nothing",
             U.UC_ERR_WRITE_PROT: "a write to flash", U.UC_ERR_FETCH_PROT:
             "an instruction fetch from SRAM that is not executable",
             U.UC_ERR_INSN_INVALID: "an undefined instruction (UsageFault)",
             U.UC_ERR_READ_UNALIGNED: "an unaligned read", U.UC_ERR_WRITE_UNALIGNED:
             "an unaligned write", U.UC_ERR_EXCEPTION: "an unhandled CPU exception"}
    text = kinds.get(error.errno, str(error))
    sp = core.uc.reg_read(A.UC_ARM_REG_SP)
    if error.errno in (U.UC_ERR_WRITE_UNMAPPED, U.UC_ERR_READ_UNMAPPED) and \
            SRAM_BASE - 0x1000 <= sp <= SRAM_BASE + 64:
        return f"a stack overflow (SP 0x{sp:08x} ran below SRAM, {text})"
    return text
