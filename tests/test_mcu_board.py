"""The emulated STM32F411 (hil/mcu/) on bare-metal ELFs of its own
(tests/mcu/*.c, registers from RM0383): clocks, SysTick, DWT, the servo line through the
PA1 buffer at the baud the firmware sets, USART IDLE, the console, timers, EXTI, bxCAN."""
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from hexhil.hil.run_result import Ending
from mcu_elf import build, console, run_elf


def test_bare_metal_pings_18_servos_at_100_mhz_the_same_twice(tmp_path):
    elf = build(tmp_path, "ping.c", "BAUD_BRR=50", "RAISE_A1=1")
    (a, _), (b, _) = run_elf(elf, 1.2), run_elf(elf, 1.2)
    words = console(a)[-1].split()
    assert words[:2] == ["ping", "18"]
    # DWT: 100 M cycles a virtual second (the WFI loop waits 1000 SysTicks of 1 ms)
    assert 99_900_000 <= int(words[2]) <= 100_000_000
    assert a.serial_digest == b.serial_digest and a.firmware == b.firmware
    assert a.firmware.other["mcu"]["hclk_hz"] == 100_000_000
    assert not a.faults


def test_without_the_direction_pin_the_servos_never_hear_it(tmp_path):
    r, _ = run_elf(build(tmp_path, "ping.c", "BAUD_BRR=50", "RAISE_A1=0"), 1.2)
    assert console(r)[-1].split()[:2] == ["ping", "0"]
    assert r.faults["tx_while_receiving"] == 18


def test_a_wrong_baud_gets_no_replies_and_the_run_says_so(tmp_path):
    r, _ = run_elf(build(tmp_path, "ping.c", "BAUD_BRR=100", "RAISE_A1=1"), 1.2)   # 500 kbps
    assert console(r)[-1].split()[:2] == ["ping", "0"]
    assert r.faults["uart_baud"] == 1


def test_timer_switch_and_can_interrupts(tmp_path):
    pressed_us = (50_000, 80_000, 120_000)        # leg switch 0 pressed three times

    def switches(t_us):
        return int(any(t <= t_us < t + 10_000 for t in pressed_us))

    r, sim = run_elf(build(tmp_path, "irq.c"), 0.25, switches=switches,
                     can_in=[(0x120, b"\x01\x02\x03\x04")])
    tim, falls, can_rx, last_id, pb0 = map(int, console(r)[-1].split())
    assert 199 <= tim <= 200            # TIM2 at 1 kHz for the 200 SysTicks
    assert falls == 3 and pb0 == 1      # EXTI0 on each press; released reads 1 (pull-up)
    assert can_rx == 1 and last_id == 0x120
    assert r.can_frames == {0x321: 1, 0x121: 1}   # by arbitration id, as python-can keys them


def test_semihosting_console_and_exit(tmp_path):
    r, _ = run_elf(build(tmp_path, "faults.c", "FAULT=4"), 0.1)   # SYS_EXIT 3: a crash
    assert r.ending.kind is Ending.CRASHED and r.exit_code == 3
    assert re.search(r"crashed at t=0\.0\d+ s \(exit 3\)", r.ending.reason), r.ending
    r, _ = run_elf(build(tmp_path, "faults.c", "FAULT=7"), 0.1)   # SYS_EXIT 0: too early
    assert r.ending.kind is Ending.EXITED_EARLY and "before the run's end (0.1 s)" in \
        r.ending.reason, r.ending
    r, _ = run_elf(build(tmp_path, "faults.c", "FAULT=5"), 0.05)
    assert console(r) == ["semihosting says hi", "unmodelled reads 0"]


def test_a_poll_loop_that_counts_in_ram_is_not_skipped(tmp_path):
    """The skipper watches a loop's stores: a counter in RAM makes each pass differ."""
    r, _ = run_elf(build(tmp_path, "faults.c", "FAULT=6"), 0.05)
    spins = int(console(r)[-1].split()[1])
    # two waits of one byte at 115200 baud (86.8 us) at 16 MHz, a few instructions a pass
    assert spins > 100


def test_a_system_reset_reboots_the_core_and_its_peripherals_and_the_world_goes_on(tmp_path):
    """SCB AIRCR SYSRESETREQ: the firmware starts again from its reset vector with every
    peripheral in its reset state (RCC at HSI, SysTick off, VTOR 0, DWT stopped); SRAM
    keeps what the first boot left there, and the run goes on to its end."""
    elf = build(tmp_path, "reset.c")
    r, _ = run_elf(elf, 0.05)
    lines = console(r)
    assert lines[0] == "boot 1: resetting"
    assert lines[1] == ("boot 00000002 cfgr 00000000 apb2enr 00000000 systick 00000000 "
                        "vtor 00000000 cyccnt 00000000"), lines
    assert r.firmware.other["mcu"]["resets"] == 1
    assert not r.faults and r.sim_time_s == pytest.approx(0.05)
    again, _ = run_elf(elf, 0.05)
    assert again.serial_digest == r.serial_digest and again.firmware == r.firmware


def test_an_interrupt_a_write_pends_is_taken_after_that_store(tmp_path):
    """NVIC ISPR pends an enabled IRQ: the handler runs before the next instruction (a
    few cycles: the handler's own, reading DWT), not thousands later at a chunk's end."""
    r, _ = run_elf(build(tmp_path, "pend.c"), 0.02)
    cycles = int(console(r)[-1].split()[2])
    assert cycles < 20, console(r)


def test_bit_band_aliases_reach_sram_bits_and_peripheral_registers(tmp_path):
    """PM0214's bit-band: an SRAM bit set or cleared alone, the alias reading 0 or 1; a
    peripheral register's bit set through its alias as ST's HAL sets PLLON and LSION (the
    oscillators start, their ready bits read through the alias); unwritten flash erased."""
    r, _ = run_elf(build(tmp_path, "bitband.c"), 0.02)
    assert console(r)[-1].split() == ["00800011", "00000001", "03000000", "00000023",
                                      "00000003", "ffffffff"], console(r)
    assert r.ending.kind is Ending.COMPLETED and not r.faults


def test_the_independent_watchdog_resets_a_firmware_that_stops_refreshing_it(tmp_path):
    """IWDG at 10 ms, never refreshed: the MCU resets as by SYSRESETREQ, the run names the
    cause and counts it, and the second boot finds RCC CSR's IWDGRSTF (cleared by RMVF)."""
    r, _ = run_elf(build(tmp_path, "iwdg.c"), 0.05)
    assert console(r) == ["iwdg started", "iwdg reset seen"], console(r)
    assert r.firmware.other["mcu"]["resets"] == 1
    assert r.firmware.other["mcu"]["reset_causes"] == {"IWDG": 1}
    r, _ = run_elf(build(tmp_path, "iwdg.c", "REFRESH=1"), 0.05)
    assert console(r) == ["iwdg started"] and r.firmware.other["mcu"]["resets"] == 0


def test_tim1_as_the_hal_timebase_with_a_compare_at_ccr_0(tmp_path):
    """TIM1's update interrupt at 1 kHz from APB2's timer clock (IRQ 25), its channel 1
    compare at CCR1 = 0 each period on TIM1_CC (IRQ 27): 100 ticks in 100 ms of DWT."""
    r, _ = run_elf(build(tmp_path, "tim1.c"), 0.15)
    words = console(r)[-1].split()
    assert words[:4] == ["tim1", "100", "cc", "100"], console(r)
    assert 9_990_000 <= int(words[5]) <= 10_010_000


def test_a_wait_on_ram_is_skipped_to_the_interrupt_and_a_counting_loop_is_not(tmp_path):
    """HAL_Delay's kind of wait (a loop reading a tick only SysTick's handler changes) and
    `while (!flag) {}` cost no host time: virtual time jumps to each SysTick, and the wait
    lasts what it lasts on the chip. A loop that counts its passes in RAM runs pass by pass."""
    quiet, _ = run_elf(build(tmp_path, "ram_wait.c", "WAIT=1"), 0.35)
    ticks, cycles, passes = map(int, console(quiet)[-1].split())
    assert ticks == 300 and passes == 0
    assert 199 * 100_000 <= cycles <= 201 * 100_000          # 200 ms at 100 MHz
    assert quiet.firmware.other["mcu"]["skipped_cycles"] > 0.9 * 300 * 100_000
    counting, _ = run_elf(build(tmp_path, "ram_wait.c", "WAIT=2"), 0.35)
    ticks, cycles, passes = map(int, console(counting)[-1].split())
    assert ticks == 300 and 199 * 100_000 <= cycles <= 201 * 100_000
    assert passes > 1_000_000            # every pass ran
    skipped = counting.firmware.other["mcu"]["skipped_cycles"]
    assert skipped < 0.4 * 300 * 100_000  # only the flag wait after it was skipped


def test_the_window_watchdog_refreshed_in_its_window_then_left_to_reset(tmp_path):
    """WWDG's counter polled down into the window (a poll of it is not skipped: it moves
    between events) and refreshed five times, then not: its reset is named and counted."""
    r, _ = run_elf(build(tmp_path, "wwdg.c"), 0.03)
    assert console(r) == ["5f 5f 5f 5f 5f refreshed", "wwdg reset seen"], console(r)
    assert r.firmware.other["mcu"]["reset_causes"] == {"WWDG": 1}


def test_conditional_stores_in_it_blocks_survive_a_watched_interrupt_read(tmp_path):
    """MicroPython's gc.collect() crash: its SysTick handler reads SysTick->CTRL, the poll
    skipper watches the pass after such a read, and the watch must not change how the code
    around it runs. gc_mark_subtree's `itte ls; strhls; addls; strhi` push went astray
    while a Unicorn store hook watched SRAM; here every push of every round lands."""
    r, _ = run_elf(build(tmp_path, "it_store.c"), 0.06)
    assert r.ending.kind is Ending.COMPLETED, r.ending
    rounds, bad = map(int, console(r)[-1].split())
    assert rounds > 1000 and bad == 0


EXCEPTION_RULES = {   # tests/mcu/exceptions.c: what the ARMv7-M ARM (B1.5) gives on the chip
    "control_before_fp": 0,                 # no FP instruction yet: CONTROL.FPCA 0
    "lr_thread_basic": 0xFFFFFFF9,          # EXC_RETURN: thread, MSP, basic frame
    "control_after_basic_return": 0,        # FPCA back as EXC_RETURN bit 4 says
    "lr_thread_extended": 0xFFFFFFE9,       # an FP context active: the extended frame
    "float_kept": 3000,                     # S0-S15 restored though the handler used floats
    "fpscr_kept": 0x00C00001,               # FPSCR too (RMode, IOC)
    "fpccr": 0xC0000000,                    # ASPEN and LSPEN, as at reset
    "lr_nested": 0xFFFFFFF1,                # handler to handler, the handler had no FP context
    "icsr_nested": 22,                      # VECTACTIVE: EXTI0
    "rettobase_nested": 0,                  # another exception is active
    "rettobase_outer": 1,
    "masked_counts": 0,                     # PRIMASK holds both back
    "taken_at_cpsie": 2,                    # both taken right after CPSIE; ISB
    "order_tim2": 2,                        # EXTI0 (0x40) before TIM2 (0x80), tail-chained
    "vectpending_in_first": 44,             # VECTPENDING: TIM2 while EXTI0 runs
    "basepri_counts": 1,                    # BASEPRI 0x60: CAN (0x20) in, TIM2 (0x80) waits
    "basepri_released": 1,                  # BASEPRI 0: TIM2 right after the MSR
    "same_group_lr": 0xFFFFFFE9,            # PRIGROUP 5: 0x40 does not preempt 0x60
    "sp_before_mod8": 4,
    "frame_mod8": 0,                        # the frame aligned to 8 bytes ...
    "frame_xpsr_bit9": 1,                   # ... and the stacked xPSR says so
    "sp_back": 1,                           # the return gives SP back exactly
    "lr_naked": 0xFFFFFFE9,
}


def test_exceptions_follow_the_armv7m_rules(tmp_path, monkeypatch):
    """Frames with and without the FP context (CONTROL.FPCA, EXC_RETURN), FPSCR and S0-S15
    across a handler, nesting and tail-chaining by priority, PRIMASK and BASEPRI (taken
    right after the unmasking), priority grouping, ICSR's VECTACTIVE, VECTPENDING and
    RETTOBASE, and the stack alignment bit, each as the chip gives it."""
    import hexhil.hil.mcu.board as board_module
    monkeypatch.setattr(board_module, "CONSOLE_TAIL", 64)
    r, _ = run_elf(build(tmp_path, "exceptions.c"), 0.05)
    lines = console(r)
    assert lines[-1] == "done", lines
    seen = {name: int(value, 16) for name, value in (line.split() for line in lines[:-1])}
    assert seen == EXCEPTION_RULES


def test_flash_unlocks_programs_erases_and_refuses_as_rm0383_says(tmp_path, caplog):
    """The FLASH interface: LOCK until the two keys; a word programmed and ANDed with a
    second program; sector 1 erased to 0xFF, BSY for the datasheet's 250 ms (16 KB at x32),
    EOP's interrupt with EOPIE; a store without PG gets PGSERR and leaves flash as it was,
    a byte at PSIZE x32 PGPERR; the flags clear by writing 1; a wrong key locks CR for
    good. Each refused kind of store is named once in the log."""
    r, _ = run_elf(build(tmp_path, "flash.c"), 0.4)
    assert console(r)[-1].split() == [
        "80000000", "00000000", "12345678", "12340000", "00010000", f"{250:08x}",
        "ffffffff", "00000001", "00000080", "00000040", "00000000", "ffffffff",
        "80000000"], console(r)
    assert r.ending.kind is Ending.COMPLETED and not r.faults
    said = caplog.text
    assert said.count("PGSERR") == 1 and said.count("PGPERR") == 1, said
    assert "is not the unlock sequence" in said


def test_rtc_counts_the_calendar_from_lsi_in_virtual_time(tmp_path):
    """The RTC as ST's HAL and MicroPython start it: INIT ignored without WPR's key, INITF
    after the key, the calendar set in the initialisation mode, then two seconds on LSI
    with PRER 128 x 250: the date rolls over into the next year and weekday; RSF comes
    back after a clear; a backup register keeps its word."""
    r, _ = run_elf(build(tmp_path, "rtc.c"), 2.1)
    assert console(r)[-1].split() == ["00000007", "00000000", "0027a101",
                                      "00000030", "00001234", "00000000"], console(r)


def test_the_backup_domain_survives_a_system_reset(tmp_path):
    """The RTC on LSE, a backup register and RCC BDCR go on through SYSRESETREQ, as on the
    chip: boot 2 finds the register, LSEON/LSERDY/RTCSEL/RTCEN and the calendar one second
    on (the CubeMX way to keep the time across a reset)."""
    r, _ = run_elf(build(tmp_path, "backup.c"), 1.4)
    assert console(r) == ["b0075afe 00008103 00100001 "], console(r)
    assert r.firmware.other["mcu"]["resets"] == 1


@pytest.mark.parametrize("mode", ["it", "dma"])
def test_receive_to_idle_gets_every_ping_as_one_burst(tmp_path, mode):
    """USART2's IDLE (the board core's, board_core.c) and USART1's (usart.py), as
    ``HAL_UARTEx_ReceiveToIdle_IT`` and ``_DMA`` use it, through the command line."""
    elf = build(tmp_path, "idle.c", *(("USE_DMA=1",) if mode == "dma" else ()))
    root = Path(__file__).resolve().parent.parent
    proc = subprocess.run([sys.executable, "-m", "hexhil.cli", "run",
                           "scenarios/flat-tripod.toml", "--firmware", str(elf),
                           "--duration", "0.15", "--json", "--quiet"], cwd=root,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    lines = [c["text"] for c in json.loads(proc.stdout.splitlines()[-1])["console"]]
    said = re.fullmatch(rf"idle {mode}: (\d+) pings, (\d+) bursts, gap (\d+) (\d+)",
                        lines[0])
    assert said and said.group(1, 2) == ("18", "18"), lines
    if mode == "it":   # one frame (10 bits at 1 Mbps) after the last byte's RXNE
        assert 900 <= int(said[3]) <= int(said[4]) <= 1100, lines
    assert lines[1] == "usart1 idle ok", lines


def test_a_wait_on_ram_runs_nothing_across_events_that_change_nothing(tmp_path):
    """With a switch interrupt armed the board meets an event each millisecond between
    SysTick's 10 ms ticks (its sleep to now): a wait confirmed as a fixed point stays
    skipped across each one, no instruction run, since the state is the confirmed one."""
    r, _ = run_elf(build(tmp_path, "ram_wait.c", "WAIT=3"), 0.35)
    ticks, cycles, passes = map(int, console(r)[-1].split())
    assert ticks == 30 and passes == 0
    assert 199 * 100_000 <= cycles <= 201 * 100_000
    mcu = r.firmware.other["mcu"]
    # two passes of 2520 instructions a SysTick, none at the 320 events between them
    assert mcu["instructions"] < 30 * 2 * 2520 + 200_000, mcu
    assert mcu["link_requests"] > 300, mcu       # the events were there: a sleep each ms


def test_a_run_with_a_switch_interrupt_armed_replays_identically(tmp_path):
    """Every sleep the board makes while a switch interrupt waits is in the trace's /link,
    and replay's board, which has no world, makes the same ones: when it asks depends on
    its own time only."""
    from hexhil import Run
    from hexhil.replay import replay_firmware
    elf = build(tmp_path, "ram_wait.c", "WAIT=3")
    trace = tmp_path / "run.mcap"
    Run("scenarios/flat-tripod.toml", seed=1, duration_s=0.1, firmware=elf, trace=trace).run()
    r = replay_firmware(trace, firmware=str(elf))
    assert r.identical and r.divergence is None and r.exchanges > 90, r
