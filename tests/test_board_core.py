"""The ELF board's compiled hot path (hil/mcu/board_core.c) against its Python model: each
test firmware gives the same serial digest, the same console, the same cycle counts and the
same trace bytes either way: polled USART2 (the C tripod, the bare-metal pings at two bauds
and without PA1), interrupt- and DMA-driven USART2, half-duplex echo, SysTick and PendSV
(their exception returns done in C, on MSP and PSP, with and without the FPU's frame),
EXTI switch interrupts, pended exceptions, a reply cut by PA1 (``rx_while_transmitting``)
and a system reset."""
import subprocess
import sys
from pathlib import Path

import pytest

from hil.mcu import board_core
from host_tools import c_sdk
from host_tools.run_summary import run
from tests.mcu_elf import MCU, build

ROOT = Path(__file__).resolve().parent.parent
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
                                            ("faults.c", ("FAULT=8",))])
def test_the_board_tests_firmwares_run_the_same_both_ways(source, defines, tmp_path,
                                                         monkeypatch):
    assert (MCU / source).exists()
    compiled, python = _both(build(tmp_path, source, *defines), 0.3, tmp_path, monkeypatch)
    assert compiled == python
    if source == "cut_reply.c":     # the reply bytes queued in C are dropped as in Python
        assert compiled[6] == {"rx_while_transmitting": 1}
    if "TURN_AT_TXE=1" in defines:  # a turn with a byte on the wire: C hands it to Python
        assert compiled[6]["tx_while_receiving"] == 18


def test_a_library_whose_layout_differs_from_shared_is_refused_in_one_line(tmp_path,
                                                                           monkeypatch):
    """Shared restates bc_t: the library says how its compiler laid bc_t out, and a build of
    another board_core.c (here one more field in the middle) is refused, never read wrong."""
    assert board_core.layout_mismatch(board_core.library()) is None
    source = board_core.LIBRARY.with_name("board_core.c").read_text()
    marker = "    int64_t skipped;"
    assert marker in source
    changed = tmp_path / "board_core.c"
    changed.write_text(source.replace(marker, "    int64_t extra;\n" + marker, 1))
    lib_path = tmp_path / "_board_core.so"
    subprocess.run([sys.executable, "-m", "ziglang", "cc", "-O1", "-shared", "-fPIC", "-o",
                    str(lib_path), str(changed)], check=True)
    import ctypes
    lib = ctypes.PyDLL(str(lib_path))
    lib.bc_layout.restype = ctypes.c_int32
    why = board_core.layout_mismatch(lib)
    assert why is not None and "bytes" in why, why
    monkeypatch.setattr(board_core, "_MISMATCH", why)
    with pytest.raises(board_core.UserError, match=r"does not match .* HEXHIL_BOARD_CORE=python"):
        board_core.native()
