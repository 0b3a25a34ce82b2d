"""The ELF board core's structs and constants as hil/mcu/board_core.c and its Python side
(board_core.py ``Shared``, coverage.py's block table) share them: written once here;
setup.py generates the C header from them (hil/native.py ``Layout``)."""
from __future__ import annotations

import ctypes

from hexhil.hil.mcu import armv7m, gpio_registers as gpio, platform, timebase, usart_registers
from hexhil.hil.native import Layout

WAITS = 256                  # an open-addressed set of (pc, register, value)
TURNS = 64                   # PA1's turns made in C before the link takes them
N_EXC = 16 + platform.NUM_IRQS   # the F411's exceptions: the core's 16 and the IRQs
ACTIVE_MAX = 128             # each exception is active at most once
N_REGID = 17                 # the registers an exception return writes (board_core.c REG_*)
# the kinds of the C code's one call into Python (board_core.py ``NativeBoard``)
(PY_LINE, PY_IDLE, PY_DMA_TX, PY_DMA_RX, PY_POLLED, PY_PCLK, PY_FAILED, PY_INTR,
 PY_SWITCHES, PY_SENT) = range(1, 11)
PY_RAISED = -2               # that call's answer where Python raised: C unwinds
# quiet loops (quiet.py): a pass's instructions, lcm(1..10); the quiet chunks let by after
# repeated misses at most
QUIET_PASS = 2520
MAX_BACKOFF = 64
# instructions run one at a time while a masked exception waits for its unmasking (then the
# chunks grow again: a core that spins with interrupts masked runs at full speed; system.py)
MASKED_STEPS = 256
# the USARTs the C code serves, in the order of ``bc_t.usart``; the servo line's (the others
# are the consoles)
USARTS = ("USART1", "USART2", "USART6")
SERVO_USART = USARTS.index("USART2")
# the memory map from the platform table: the peripherals' 1 KB pages the C code fronts
# from APB1's base on (the USARTs', GPIOA's and GPIOB's)
_SRAM, _FLASH, _PERIPH = platform.row("SRAM"), platform.row("Flash"), platform.row("APB1")
MEMORY_MAP = (("SRAM_BASE", _SRAM.base), ("SRAM_SIZE", _SRAM.size),
              ("FLASH_BASE", _FLASH.base), ("FLASH_SIZE", _FLASH.size),
              ("PERIPH_BASE", _PERIPH.base),
              *((f"USART_PAGE_{i}", (platform.row(n).base - _PERIPH.base) >> 10)
                for i, n in enumerate(USARTS)),
              ("GPIOA_PAGE", (platform.row("GPIOA").base - _PERIPH.base) >> 10),
              ("PPB_BASE", platform.row("PPB").base),
              ("SYSTICK_BASE", platform.row("SysTick").base))
# why an exception's entry failed (bc_enter's answer; ``fault_at`` says where) and its
# return (bc_unstack's), named by core.py
(ENTER_BELOW_SRAM, ENTER_OFF_SRAM, ENTER_NO_TABLE, ENTER_NO_HANDLER,
 ENTER_UNREAD) = range(-1, -6, -1)
(LEAVE_THREAD, LEAVE_LOCKUP, LEAVE_UNREAD) = range(-1, -4, -1)
# where the C run loop hands back to Python (board_loop.py)
(LOOP_AFTER_HEAD, LOOP_AFTER_CHUNK, LOOP_ENTER, LOOP_RAISED, LOOP_HOOK_FAILED, LOOP_NULL_JUMP,
 LOOP_UC_ERROR, LOOP_NO_EVENT, LOOP_BEFORE_CHUNK) = range(9)
LOOP_RESUME = -2             # bc_loop's ``n``: run the chunk a debugger allowed (``debug_n``)

_P, _I32, _I64 = ctypes.c_void_p, ctypes.c_int32, ctypes.c_int64
_U8, _U32, _U64 = ctypes.c_uint8, ctypes.c_uint32, ctypes.c_uint64
PY_CALL = ctypes.CFUNCTYPE(ctypes.c_int64, ctypes.c_int, ctypes.c_int64, ctypes.c_int64)
PY_TIMER = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_int, ctypes.c_int64)

# an open-addressed set of triples; n is -1 once full (the non-waits' set: C asks Python)
SET3 = [("slot", (_U32 * 3) * WAITS), ("n", _I32)]


class Set3(ctypes.Structure):
    _fields_ = SET3


# a USART (usart.py): its clock on; its interrupt line high; a DMA stream serves TXE, RXNE;
# its registers, DR's byte waiting (-1: none), the byte received, the byte HDSEL hears back
# (-1: none); its timers (the byte's end, IDLE) once made; SR read with IDLE set (a DR
# read clears it); a frame's length and the bus clock (0: to be asked again), when the
# line will have been idle a frame (0: no byte since)
USART = [("live", _I32), ("line", _I32), ("dma_tx", _I32), ("dma_rx", _I32),
         ("sr", _I32), ("brr", _I32), ("cr1", _I32), ("cr2", _I32), ("cr3", _I32),
         ("gtpr", _I32), ("tdr", _I32), ("rdr", _I32), ("echo", _I32),
         ("tid", _I32), ("idle_tid", _I32), ("made", _I32), ("idle_seen", _I32), ("_pad", _I32),
         ("frame_fs", _I64), ("pclk", _I64), ("idle_at", _I64)]


class UsartState(ctypes.Structure):
    _fields_ = USART


# --coverage's block table (coverage.py ``LineCounter``): (address, size) keys and counts
COVER = [("keys", ctypes.POINTER(_U64), "uint64_t *"),
         ("counts", ctypes.POINTER(_U64), "uint64_t *"),
         ("mask", _U64), ("used", _U64), ("lost", _U64)]

BC = [
    # time: the core's (hil/mcu/core.py): Unicorn's instructions run by this emu_start, + 1;
    # the running instruction's PC in Unicorn's CPU state
    ("ctr", _P, "uint64_t *"), ("pc", _P, "uint32_t *"),
    ("chunk0", _I64), ("cyc", _I64), ("fs0", _I64), ("cyc0", _I64), ("fs_per_cyc", _I64),
    ("hz", _I64), ("running", _I32), ("_pad", _I32),
    ("skipped", _I64),                       # cycles skipped by poll jumps
    # the poll skipper's state (hil/mcu/poll.py)
    ("poll_valid", _I32), ("poll_addr", _I32), ("poll_value", _I32), ("reread", _I32),
    ("watching", _I32), ("pending_n", _I32), ("poll_at", _I64),
    ("usart", UsartState * len(USARTS), "struct usart"),   # USART1, USART2, USART6
    # the servo line's burst
    ("direction", _I32), ("burst_dir", _I32), ("burst_n", _I32), ("burst_cap", _I32),
    ("burst_fs", _I64), ("burst", _P, "uint8_t *"),
    # the event heap: the earliest live timer's time (NONE when none)
    ("next_at", _I64), ("seq", _U64), ("n", _I32), ("cap", _I32), ("ntimers", _I32),
    ("err", _I32),
    ("heap", _P, "entry_t *"), ("gen", _P, "uint32_t *"), ("tat", _P, "int64_t *"),
    # Python
    ("py_call", PY_CALL, "py_call_t"), ("py_timer", PY_TIMER, "py_timer_t"),
    ("py_read", _P, "mmio_read_t"), ("py_write", _P, "mmio_write_t"),
    ("waits", Set3, "struct set3"),          # known waits: (pc, register, value)
    # the exception model (core.py): the active exceptions, innermost last
    ("active", _I32 * ACTIVE_MAX), ("nactive", _I32), ("sleeping", _I32),
    ("sleep_on_exit", _I32), ("_pad2", _I32),
    # the engine, SRAM's and flash's buffers, libunicorn's batch calls
    ("uc", _P, "void *"), ("sram", _P, "uint8_t *"), ("flash", _P, "uint8_t *"),
    ("reg_read_batch", _P, "reg_batch_t"), ("reg_write_batch", _P, "reg_batch_t"),
    ("regid", _I32 * N_REGID),               # Unicorn's ids of the registers (REG_*)
    ("fast_returns", _I64),                  # exception returns done in the hook
    ("fault_at", _I64),                      # where an entry failed (bc_enter)
    # the NVIC's pending exceptions (a bit each; pending_n counts them) and SysTick
    ("pend", _U32 * 4), ("st_tid", _I32), ("st_csr", _I32), ("st_rvr", _I32),
    ("st_countflag", _I32),
    # the NVIC's enabled IRQs (a bit each), priorities and PRIGROUP
    ("ena", _U32 * 4), ("ena_n", _I32), ("prigroup", _I32),
    ("prio", _U8 * (-(-N_EXC // 4) * 4)),   # a byte each, to a whole word
    # the servo line's reply bytes on their way to USART2 (servo_line.py ``deliver``)
    ("rx_tid", _I32), ("rx_n", _I32), ("rx_head", _I32), ("rx_cap", _I32),
    ("rx_at", _P, "int64_t *"), ("rx_byte", _P, "uint8_t *"),
    # the run loop (board.py ``run``, core.py ``run``): the core's state between chunks;
    # touched: calls into Python (a chunk that made one ends the loop); loop_n: the chunk
    # length an iteration handed to Python had
    ("pc_next", _I64), ("vtor", _I64), ("executed", _I64), ("touched", _I64),
    ("loop_n", _I64), ("fpu_on", _I32), ("stopped", _I32), ("cut", _I32),
    ("hook_failed", _I32), ("uc_err", _I32), ("loop_exc", _I32),
    ("debug", _I32), ("debug_n", _I64),      # a debugger attached; the chunk it allows
    ("emu_start", _P, "emu_start_t"), ("mem_read", _P, "mem_read_t"),   # libunicorn's
    ("lines", _U32 * 4), ("lines_n", _I32),  # the IRQ lines a peripheral holds high
    ("emu_stop", _P, "emu_stop_t"),
    # GPIOA-C (gpio.py, gpio_registers.py): what PA1's turns and a read of PB's switches need, served in C;
    # gpio_live bit i: port i's clock is on; the pressed switches, a bit each (board.py);
    # the link's last request (the switches' age); PA1's turns made in C (link_client.py)
    ("gpio_moder", _U32 * 3), ("gpio_pupdr", _U32 * 3), ("gpio_odr", _U32 * 3),
    ("gpio_live", _I32), ("switches", _I32), ("last_request_us", _I64),
    ("turns_n", _I32), ("_pad3", _I32), ("turn_us", _I64 * TURNS),
    ("turn_level", _I32 * TURNS),
    ("nots", Set3, "struct set3"),           # repeated reads that are no wait: (pc, reg, 0)
    # quiet loops (poll.py ``QuietLoops``): a chunk without a register access. Register
    # accesses so far, and when the chunk began; > 0: chunks no longer than this (a pass
    # being checked); quiet chunks to let by before Python looks again; chunks with
    # register accesses since the last quiet one; one-instruction chunks while a masked
    # exception waits
    ("mmio_n", _I64), ("chunk_mmio", _I64), ("quiet_n", _I64), ("quiet_wait", _I64),
    ("quiet_loud", _I64), ("masked_steps", _I64),
    # the instruction count (engine.py): a UC_HOOK_CODE counts here what Unicorn's own
    # count would, the count given right after it, as Unicorn keeps the two; the running
    # instruction's PC
    ("pub_count", _U64), ("pub_limit", _U64), ("pub_pc", _U32), ("_pad4", _I32),
    # quiet.py ``held``: 1 while the state is a fixed point a skip confirmed and no
    # instruction has run since; 1: ``q`` holds the state at the end of a quiet chunk;
    # quiet.py's steps done in C (bc_quiet_init)
    ("quiet_hold", _I32), ("q_seen", _I32), ("q", _P, "struct quiet *"),
    ("py_ppb_read", _P, "mmio_read_t")]      # mmio.py ``ppb_read``: the PPB's but SysTick's

LAYOUT = Layout("HX_BOARD_LAYOUT_H", [("set3", SET3), ("cover", COVER), ("usart", USART),
                                      ("bc", BC)], [
    ("N_USART", len(USARTS)), ("SERVO_USART", SERVO_USART),
    ("WAITS", WAITS), ("TURNS", TURNS), ("N_EXC", N_EXC), ("ACTIVE_MAX", ACTIVE_MAX),
    ("N_REGID", N_REGID),
    ("QUIET_PASS", QUIET_PASS), ("MAX_BACKOFF", MAX_BACKOFF), ("MASKED_STEPS", MASKED_STEPS),
    *MEMORY_MAP,
    *((n, v) for n, v in vars(usart_registers).items()   # the USARTs' registers
      if n.isupper() and isinstance(v, int)),
    *((f"STOP_HALF_BITS_{i}", v) for i, v in enumerate(usart_registers.STOP_HALF_BITS)),
    *((f"GPIO_{n}", getattr(gpio, n)) for n in ("MODER", "PUPDR", "IDR", "ODR", "BSRR")),
    ("PRIORITY_BITS", platform.PRIORITY_BITS), ("DIRECTION_PIN", gpio.DIRECTION_PIN),
    ("SWITCH_MASK", (1 << gpio.SWITCH_PINS) - 1),
    *((n, getattr(timebase, n)) for n in ("FS_PER_S", "FS_PER_US", "TICK_US")),
    *((n, v) for n, v in vars(armv7m).items() if n.isupper()),   # the core's numbers
    *((n, v) for n, v in tuple(globals().items())   # the call's kinds, the loop's ends
      if n.startswith(("PY_", "LOOP_", "ENTER_", "LEAVE_")) and isinstance(v, int))])
