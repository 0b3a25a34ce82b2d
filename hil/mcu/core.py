"""The Cortex-M4F core on Unicorn: exact instruction counts, time, and the exception model.

Unicorn runs Thumb-2 and the FPU but has no NVIC: exception entry (the 8-word frame, or
26 words with the FPU's S0-S15 and FPSCR), EXC_RETURN and the return are done here.
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
from typing import Callable

from unicorn import (UC_ARCH_ARM, UC_MODE_MCLASS, UC_MODE_THUMB, UC_PROT_ALL,
                     UC_PROT_EXEC, UC_PROT_READ, Uc, UcError)
from unicorn import arm_const as A, unicorn_const as U
from unicorn.unicorn_py3.unicorn import uclib

from hexhil.hil.mcu.armv7m import (CONTROL_FPCA, CONTROL_SPSEL, RETURN_HANDLER, RETURN_NO_FP,
                                   RETURN_THREAD_MSP, RETURN_THREAD_PSP, WFE, WFI, XPSR_ALIGNED,
                                   XPSR_THUMB)
from hexhil.hil.mcu.board_core import Shared, SharedField, library
from hexhil.hil.mcu.elf_image import FLASH_BASE, FLASH_SIZE, SRAM_BASE, SRAM_SIZE, ElfImage
from hexhil.hil.mcu.engine import Regs, attach_engine
from hexhil.hil.mcu.timebase import FS_PER_S, TimeBase

ERASED = 0xFF                # an erased flash byte (RM0383 3.5)
FRAME_REGS = (A.UC_ARM_REG_R0, A.UC_ARM_REG_R1, A.UC_ARM_REG_R2, A.UC_ARM_REG_R3,
              A.UC_ARM_REG_R12, A.UC_ARM_REG_LR)
FP_REGS = tuple(A.UC_ARM_REG_S0 + i for i in range(16)) + (A.UC_ARM_REG_FPSCR,)
STATE_REGS = (A.UC_ARM_REG_XPSR, A.UC_ARM_REG_CONTROL, A.UC_ARM_REG_MSP, A.UC_ARM_REG_PSP)
_ENTER_MSP = (A.UC_ARM_REG_MSP, A.UC_ARM_REG_CONTROL, A.UC_ARM_REG_IPSR, A.UC_ARM_REG_LR)
_ENTER_PSP = (A.UC_ARM_REG_PSP, A.UC_ARM_REG_CONTROL, A.UC_ARM_REG_IPSR, A.UC_ARM_REG_LR)
_LEAVE = {(fpu, psp): FRAME_REGS + STATE_REGS + (FP_REGS if fpu else ()) + (A.UC_ARM_REG_IPSR,)
          + ((A.UC_ARM_REG_CONTROL, A.UC_ARM_REG_PSP) if psp else (A.UC_ARM_REG_MSP,))
          + (A.UC_ARM_REG_PC,) for fpu in (False, True) for psp in (False, True)}
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
        self._state = Regs(uc, FRAME_REGS + STATE_REGS)
        self._state_fp = Regs(uc, FRAME_REGS + STATE_REGS + FP_REGS)
        self._stacks = Regs(uc, STATE_REGS[1:])
        self._context = Regs(uc, CONTEXT_REGS)
        self._one = ctypes.c_uint64(0)
        self._one_ref = ctypes.byref(self._one)
        self._h = uc._uch
        self._batches: dict[tuple[int, ...], Regs] = {}
        # the time and the chunk's origin live where the compiled board sees them
        self.shared = st = Shared(st_tid=-1, rx_tid=-1, next_at=-1)
        attach_engine(uc, st, library())     # hil/mcu/engine.py
        self._ctr = ctypes.c_uint64.from_address(st.ctr)
        self._limit = ctypes.c_uint64.from_address(st.ctr + 8)   # the chunk's length
        self.time = TimeBase(hz, st)
        self.cyc = 0                 # instructions run before the current chunk
        self._share_exceptions(st)
        # the board core's exception entry (board_loop.py ``exception_entry``)
        self.enter_c: Callable[[int, int, int, int], int] | None = None
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
        """The active exceptions, innermost last (a copy: ``_push``/``_pop`` change them)."""
        st = self.shared
        return st.active[:st.nactive]

    def _push(self, exc: int) -> None:
        self.shared.active[self.shared.nactive] = exc
        self.shared.nactive += 1

    def _pop(self) -> int:
        self.shared.nactive -= 1
        return self.shared.active[self.shared.nactive]

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
        """Run up to ``n`` instructions from ``self.pc``; how many ran."""
        uc, st = self.uc, self.shared
        st.chunk0 = st.cyc
        st.chunk_mmio = st.mmio_n
        st.stopped = st.cut = 0
        st.running = 1
        try:
            st.pub_count, st.pub_limit = 0, n
            uc.emu_start(self.pc | 1, 0, 0, 0)
            error = None
        except UcError as exc:
            error = exc
        finally:
            st.running = 0
        ran = self._ctr.value - 1
        self.pc = self.reg(A.UC_ARM_REG_PC)
        if error is None and ran < n and not self.stopped and not self.cut:
            if self.pc == 0:
                raise CoreFault("a jump to address 0 (a null function pointer)", ("null", 0))
            op = self.read16(self.pc - 2)
            if op in (WFI, WFE):
                ran += 1
                self.sleeping = True
        ran = max(0, min(ran, n))
        st.cyc = st.chunk0 + ran          # chunk0 has moved by any jump inside the chunk
        self.executed += ran
        if error is not None:
            raise CoreFault(error_text(error, self), ("uc", error.errno))
        return ran

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

    def _set(self, ids: tuple[int, ...], values: list[int]) -> None:
        regs = self._batches.get(ids)
        if regs is None:
            regs = self._batches[ids] = Regs(self.uc, ids)
        regs.write(values)

    def enter(self, exc: int) -> None:
        """Take exception ``exc`` at ``self.pc``: stack the frame, jump to its vector."""
        if self.enter_c is not None:
            vector = self.enter_c(exc, self.pc, self.fpu_on, self.vtor or FLASH_BASE)
            if vector >= 0:
                self.pc = vector & ~1
                return
        r = self._state_fp.read() if self.fpu_on else self._state.read()
        xpsr, control, msp, psp_value = r[6:10]
        fpu = self.fpu_on and bool(control & CONTROL_FPCA)    # an FP context is active
        psp = not self.active and bool(control & CONTROL_SPSEL)
        sp = psp_value if psp else msp
        values = r[:6] + [self.pc & ~1, xpsr | XPSR_THUMB]
        if fpu:
            values += r[10:] + [0]
        if sp & 4:
            sp -= 4
            values[7] |= XPSR_ALIGNED
        sp -= 4 * len(values)
        if sp < SRAM_BASE:
            raise CoreFault(f"a stack overflow: exception {exc} stacks its frame at "
                            f"0x{sp:08x}, below SRAM")
        self._store(sp, values)
        vector = self.read32(self.vtor_base() + 4 * exc)
        if vector == 0 or not vector & 1:
            raise CoreFault(f"exception {exc} has no handler (vector 0x{vector:08x})")
        exc_return = RETURN_HANDLER if self.active else (RETURN_THREAD_PSP if psp else
                                                         RETURN_THREAD_MSP)
        if fpu:
            exc_return &= ~RETURN_NO_FP
        control &= ~CONTROL_FPCA                 # the handler starts with no FP context
        if psp:
            ids, values = _ENTER_PSP, [sp, control & ~CONTROL_SPSEL, exc, exc_return]
        else:
            ids, values = _ENTER_MSP, [sp, control, exc, exc_return]
        if self.running:
            ids, values = ids + (A.UC_ARM_REG_PC,), values + [vector | 1]
        self._set(ids, values)
        self._push(exc)
        self.pc = vector & ~1
        self.sleeping = False

    def leave(self, exc_return: int) -> int:
        """Return from the innermost exception through ``exc_return``; its number."""
        if not self.active:
            raise CoreFault(f"an exception return (0x{exc_return:08x}) in thread mode")
        exc = self._pop()
        to_thread = exc_return & 0xF in (RETURN_THREAD_MSP & 0xF, RETURN_THREAD_PSP & 0xF)
        if to_thread and self.active:
            raise CoreFault(f"an exception return to thread mode with {len(self.active)} "
                            "exceptions still active (a lockup)")
        control, msp, psp_value = self._stacks.read()
        psp = exc_return & 0xF == RETURN_THREAD_PSP & 0xF
        sp = psp_value if psp else msp
        fpu = not exc_return & RETURN_NO_FP
        n = 26 if fpu else 8
        control = control & ~CONTROL_FPCA | (CONTROL_FPCA if fpu else 0)   # as EXC_RETURN says
        if SRAM_BASE <= sp <= SRAM_BASE + SRAM_SIZE - 4 * n:
            values = list(struct.unpack_from(f"<{n}I", self._sram_mem, sp - SRAM_BASE))
        else:
            words = self.uc.mem_read(sp, 4 * n)
            values = [int.from_bytes(words[4 * i:4 * i + 4], "little") for i in range(n)]
        xpsr = values[7]
        sp = (sp + 4 * n + (4 if xpsr & XPSR_ALIGNED else 0)) & 0xFFFFFFFF
        ipsr = self.active[-1] if self.active else 0
        regs = values[:6] + [(xpsr & ~0x3FF), control, msp, psp_value]
        if fpu:
            regs += values[8:25]
        regs.append(ipsr)
        if psp:
            regs += [control | CONTROL_SPSEL, sp, values[6] | 1]
        else:
            regs += [sp, values[6] | 1]
        self._set(_LEAVE[fpu, psp], regs)
        self.pc = values[6] & ~1
        return exc

    def _store(self, sp: int, values: list[int]) -> None:
        """An exception frame (32-bit values) at ``sp``: straight into SRAM's buffer, else
        through Unicorn (which faults where nothing is mapped)."""
        n = len(values)
        if SRAM_BASE <= sp <= SRAM_BASE + SRAM_SIZE - 4 * n:
            struct.pack_into(f"<{n}I", self._sram_mem, sp - SRAM_BASE, *values)
        else:
            self.uc.mem_write(sp, b"".join((v & 0xFFFFFFFF).to_bytes(4, "little")
                                           for v in values))

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
