"""Exception entry and return at the core's level (the ARMv7-M ARM's exception entry and
return, B1.5.6-B1.5.8), done by the board core: the frame stacked and unstacked exactly, and
what it cannot stack, fetch or return to a fault named in one line."""
import pytest
from unicorn import arm_const as A

from hexhil.hil.mcu.core import CoreFault
from hexhil.hil.mcu.elf_image import SRAM_BASE, SRAM_SIZE
from registers.bus import CODE, Bus

TOP = SRAM_BASE + SRAM_SIZE
SVCALL, PENDSV = 11, 14


def _core_with_handlers():
    """A core whose vector table is in SRAM (VTOR), SVCall and PendSV at CODE."""
    core = Bus().board.core
    core.vtor = SRAM_BASE
    for exc in (SVCALL, PENDSV):
        core.write32(SRAM_BASE + 4 * exc, CODE | 1)
    return core


def test_an_entry_stacks_the_frame_and_its_return_unstacks_it():
    core = _core_with_handlers()
    core.uc.reg_write(A.UC_ARM_REG_R0, 0x1234)
    core.pc = CODE + 8
    core.enter(SVCALL)
    assert core.pc == CODE and core.active == [SVCALL]
    sp = core.uc.reg_read(A.UC_ARM_REG_MSP)
    assert sp == TOP - 32                                    # 8 words, already aligned
    assert core.read32(sp) == 0x1234 and core.read32(sp + 24) == CODE + 8   # R0, the PC
    assert core.uc.reg_read(A.UC_ARM_REG_LR) == 0xFFFFFFF9    # to thread mode, MSP
    assert core.leave(0xFFFFFFF9) == SVCALL
    assert core.pc == CODE + 8 and core.active == []
    assert core.uc.reg_read(A.UC_ARM_REG_MSP) == TOP


def test_an_exception_without_a_handler_is_named_with_its_vector():
    core = Bus().board.core
    with pytest.raises(CoreFault, match=r"^exception 11 has no handler \(vector 0x00000000\)$"):
        core.enter(SVCALL)
    assert core.active == []


def test_a_frame_below_sram_is_a_stack_overflow_and_one_past_it_a_fault():
    core = _core_with_handlers()
    core.uc.reg_write(A.UC_ARM_REG_MSP, SRAM_BASE + 16)
    with pytest.raises(CoreFault, match=r"^a stack overflow: exception 11 stacks its frame at "
                                        r"0x1ffffff0, below SRAM$"):
        core.enter(SVCALL)
    core.uc.reg_write(A.UC_ARM_REG_MSP, TOP + 0x100)
    with pytest.raises(CoreFault, match=r"^exception 11 stacks its frame at 0x200200e0, past "
                                        r"SRAM$"):
        core.enter(SVCALL)
    assert core.active == []


def test_a_return_in_thread_mode_or_to_it_from_a_nested_handler_is_a_fault():
    core = _core_with_handlers()
    with pytest.raises(CoreFault, match=r"^an exception return \(0xfffffff9\) in thread mode$"):
        core.leave(0xFFFFFFF9)
    core.enter(SVCALL)
    core.enter(PENDSV)
    assert core.uc.reg_read(A.UC_ARM_REG_LR) == 0xFFFFFFF1    # handler to handler
    with pytest.raises(CoreFault, match=r"^an exception return to thread mode with 1 "
                                        r"exceptions still active \(a lockup\)$"):
        core.leave(0xFFFFFFF9)
