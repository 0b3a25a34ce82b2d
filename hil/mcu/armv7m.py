"""The ARMv7-M facts that the core's model (core.py, system.py, faults.py, verdicts.py) and
the compiled board (board_core.c, through board_layout.py) both act on: exception numbers,
EXC_RETURN's values, CONTROL's bits, the Thumb encodings the models recognize, and the
numbers Unicorn gives the core's interrupts. Plain integers, so the build can read them."""

# exception numbers (ARMv7-M ARM B1.5.2, table B1-4)
EXC_NMI, EXC_HARDFAULT, EXC_MEMMANAGE, EXC_BUSFAULT, EXC_USAGEFAULT = 2, 3, 4, 5, 6
EXC_SVCALL, EXC_DEBUGMON, EXC_PENDSV, EXC_SYSTICK = 11, 12, 14, 15
# EXC_RETURN (B1.5.8): back to handler mode, to thread mode on MSP or on PSP; its bit 4
# clear: the frame has the FP context
RETURN_HANDLER, RETURN_THREAD_MSP, RETURN_THREAD_PSP = 0xFFFFFFF1, 0xFFFFFFF9, 0xFFFFFFFD
RETURN_NO_FP = 0x10
CONTROL_SPSEL = 1 << 1       # thread mode runs on PSP (B1.4.4)
CONTROL_FPCA = 1 << 2        # an FP context is active: the extended frame at exception entry
XPSR_ALIGNED = 1 << 9        # the frame was aligned to 8 bytes with a padding word (B1.5.7)
XPSR_THUMB = 1 << 24         # the T bit, set in every stacked xPSR
# SysTick's CSR (B3.3.3): the counter on, its exception at each wrap, HCLK (else HCLK/8), a
# wrap since the last read
SYST_ENABLE, SYST_TICKINT, SYST_CLKSOURCE, SYST_COUNTFLAG = 1 << 0, 1 << 1, 1 << 2, 1 << 16
SYST_CONTROL = SYST_ENABLE | SYST_TICKINT | SYST_CLKSOURCE     # the bits a write sets
# Thumb encodings (A7.7): WFI, WFE, and `b .` (GCC's `for (;;) {}`)
WFI, WFE, BRANCH_TO_SELF = 0xBF30, 0xBF20, 0xE7FE
# Unicorn's numbers for the core's interrupts (its QEMU's EXCP_*)
INTR_UDEF, INTR_SWI, INTR_BKPT, INTR_EXC_EXIT, INTR_NOCP, INTR_INVSTATE = 1, 2, 7, 8, 17, 18
