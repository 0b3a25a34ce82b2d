"""The ELF board's compiled hot path (hil/mcu/board_core.c) against its Python model: each
test firmware gives the same serial digest, the same console, the same cycle counts and the
same trace bytes either way: polled USART2 (the C tripod, the bare-metal pings at two bauds
and without PA1), interrupt- and DMA-driven USART2, half-duplex echo, SysTick and PendSV
(their exception returns done in C, on MSP and PSP, with and without the FPU's frame),
EXTI switch interrupts, pended exceptions, a reply cut by PA1 (``rx_while_transmitting``),
a system reset, a watchdog's reset and TIM1's interrupts."""
import dataclasses
from pathlib import Path

import pytest

from hexhil.hil.mcu import board_core, board_layout
from hexhil import c_sdk
from hexhil.run_summary import run
from tests.mcu_elf import MCU, build
from conftest import ROOT

FW = ROOT / "tests" / "elf_firmware"
FLAT = str(ROOT / "scenarios" / "flat-tripod.toml")
FIRMWARES = {  # name: (sources, flags, bare, seconds)
    "c_tripod": ([ROOT / "examples" / "c_tripod" / "main.c"], (), False, 1.5),
    "bare": ([FW / "bare_metal.c"], (), True, 0.6),
    "bare_no_direction": ([FW / "bare_metal.c"], ("-DNO_DIRECTION",), True, 0.1),
    "two_tasks": ([FW / "two_tasks.c"], (), False, 0.3),
    "uart_it": ([FW / "servo_async.c"], (), False, 0.2),
    "uart_dma": ([FW / "servo_async.c"], ("-DUSE_DMA",), False, 0.2),
    "switches_timer": ([FW / "switches_timer.c"], (), False, 0.5),
}


def test_the_library_is_built():
    assert board_core.native(), f"{board_core.LIBRARY} missing: run make"


def _both(elf: Path, seconds: float, tmp_path: Path, monkeypatch) -> list[tuple]:
    runs = []
    for compiled in (True, False):
        monkeypatch.setattr(board_core, "_LIB", board_core._LIB if compiled else None)
        trace = tmp_path / "run.mcap"     # one path: the trace names its firmware and file
        trace.unlink(missing_ok=True)
        summary, result = run(FLAT, duration_s=seconds, firmware=str(elf), out=str(trace))
        mcu = result.firmware.other["mcu"]
        runs.append((summary["serial_digest"], result.stderr_tail, mcu["cycles"],
                     mcu["instructions"], mcu["skipped_cycles"], trace.read_bytes(),
                     summary["faults"], result.ending))
        monkeypatch.undo()
    return runs


@pytest.mark.parametrize("name", FIRMWARES)
def test_a_firmware_runs_the_same_with_and_without_the_compiled_board(name, tmp_path,
                                                                      monkeypatch):
    sources, flags, bare, seconds = FIRMWARES[name]
    elf = c_sdk.build([str(s) for s in sources], tmp_path / f"{name}.elf", flags,
                      "stm32f411", bare)
    compiled, python = _both(elf, seconds, tmp_path, monkeypatch)
    assert compiled[:5] == python[:5]
    assert compiled[5] == python[5], "the traces differ"
    assert compiled[6] == python[6]
    assert compiled[2] > 0


@pytest.mark.parametrize("source,defines", [("ping.c", ("BAUD_BRR=100", "RAISE_A1=1")),
                                            ("ping.c", ("BAUD_BRR=50", "RAISE_A1=1",
                                                        "TURN_AT_TXE=1")),
                                            ("irq.c", ()), ("reset.c", ()),
                                            ("pend.c", ()), ("cut_reply.c", ()),
                                            ("faults.c", ("FAULT=1",)),
                                            ("faults.c", ("FAULT=2",)),
                                            ("faults.c", ("FAULT=3",)),
                                            ("faults.c", ("FAULT=8",)),
                                            ("iwdg.c", ()), ("tim1.c", ()),
                                            ("ram_wait.c", ("WAIT=3",))])
def test_the_board_tests_firmwares_run_the_same_both_ways(source, defines, tmp_path,
                                                         monkeypatch):
    assert (MCU / source).exists()
    compiled, python = _both(build(tmp_path, source, *defines), 0.3, tmp_path, monkeypatch)
    assert compiled == python
    if source == "cut_reply.c":     # the reply bytes queued in C are dropped as in Python
        assert compiled[6] == {"rx_while_transmitting": 1}
    if "TURN_AT_TXE=1" in defines:  # a turn with a byte on the wire: C hands it to Python
        assert compiled[6]["tx_while_receiving"] == 18


def test_a_library_built_from_other_sources_is_refused_in_one_line(monkeypatch):
    """bc_t, Shared and the constants they share are hil/mcu/board_layout.py's, written as
    the header the library is built with: a library whose fingerprint is another layout's
    (here one more constant) is refused where a board is made, never read wrong."""
    assert board_core.library() is not None
    header = board_layout.LAYOUT.header()
    assert "    uint32_t slot[256][3];\n" in header and "    struct set3 waits;\n" in header
    assert "    py_call_t py_call;\n" in header and "#define PY_SWITCHES 9\n" in header
    other = dataclasses.replace(board_layout.LAYOUT, constants=[("HX_OTHER", 1)])
    monkeypatch.setattr(board_core, "LAYOUT", other)
    lib, why = board_core._load()
    assert lib is None and "_board_core.so was built with other structs" in why, why
    monkeypatch.setattr(board_core, "_MISMATCH", why)
    with pytest.raises(board_core.UserError, match=r"other structs .* HEXHIL_BOARD_CORE=python$"):
        board_core.native()


def test_the_calibrated_engine_counts_as_the_public_one(tmp_path, monkeypatch):
    """engine.py's two engines: Unicorn's own counter found by calibration, and a public
    UC_HOOK_CODE. The start-up check agrees, and a firmware runs the same under either
    (console, cycles, instructions, serial digest), compiled and in Python."""
    from hexhil.hil.mcu import engine
    assert engine.check_calibrated() is None
    elf = build(tmp_path, "exceptions.c")
    seen = []
    for kind in ("hooked", "calibrated"):
        for compiled in (True, False):
            monkeypatch.setenv("HEXHIL_UNICORN_ENGINE", kind)
            monkeypatch.setattr(board_core, "_LIB", board_core._LIB if compiled else None)
            _, result = run(FLAT, duration_s=0.05, firmware=str(elf))
            mcu = result.firmware.other["mcu"]
            seen.append((result.stderr_tail, mcu["cycles"], mcu["instructions"],
                         result.serial_digest))
    assert all(s == seen[0] for s in seen), seen
    assert seen[0][0].splitlines()[-1] == "done"


def test_a_unicorn_whose_counter_moved_is_run_through_its_public_api(monkeypatch, caplog):
    """A Unicorn build that keeps its count elsewhere than 2.1.4 is never read wrong: the
    check names what differs in one warning line and the public engine runs the board."""
    from hexhil.hil.mcu import engine
    real = engine._check_run
    monkeypatch.setattr(engine, "_check_run",
                        lambda calibrated: [(n + calibrated, pc) for n, pc in real(calibrated)])
    monkeypatch.setattr(engine, "_KIND", [])
    monkeypatch.delenv("HEXHIL_UNICORN_ENGINE", raising=False)
    with caplog.at_level("WARNING", logger="hexhil.hil.mcu.engine"):
        assert engine.engine_kind(compiled=False) is engine.EngineKind.HOOKED
    (line,) = [r.getMessage() for r in caplog.records]
    assert "its own instruction count ends chunk 1 of the check at 3 instructions" in line
    assert "public API instead" in line and "\n" not in line
