"""An ELF served in this process: the board's link goes straight to the run's link server
(hil/link/firmware_process.py ``DirectConnection``), no socket, no child process.

Ends as the other served firmwares do (hil/link/served_firmware.py): a fault is the run's
``FirmwareEnding`` (CRASHED, its one line naming the fault, the PC and the function), and
the trace recorded up to then is kept; an exit is judged by the caller.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from hexhil.hil.link.firmware_process import DirectConnection
from hexhil.hil.mcu import flash_fs
from hexhil.hil.mcu.board import Board
from hexhil.hil.mcu.board_core import MAX_US, too_long
from hexhil.hil.mcu.core import CoreFault
from hexhil.hil.mcu.elf_image import ElfImage
from hexhil.hil.mcu.gdb import SIGABRT, SIGINT, GdbServer, fault_signal
from hexhil.hil.run.limits import MASKED_LIMIT_S
from hexhil.hil.run_result import LAST_LINES, Ending, FirmwareEnding, RunTally
from hexhil.hil.seams import LinkHost


def serve_elf(image: ElfImage, server: LinkHost, end_us: int, result: RunTally,
              console_events: Callable[[str], list[tuple[int, str]]],
              gdb_port: int | None = None, coverage: Path | None = None,
              fs_image: bytes | None = None, fs_out: Path | None = None,
              masked_limit_s: float = MASKED_LIMIT_S,
              coverage_libraries: bool = False) -> Board:
    """Run ``image`` against ``server`` (hil/link/server.py) until ``end_us``; ``fs_image``
    is laid into flash before the boot, and the flash filesystem read back into ``fs_out``
    after the run (hil/mcu/flash_fs.py). A verdict of hil/mcu/verdicts.py (an exit, an
    abort, an assertion, a masked hang) is the run's ending, exit 1."""
    if end_us > MAX_US:
        raise too_long(end_us * 10**9)
    conn = DirectConnection(lambda c, msgs, closed: server.answer(c, msgs, closed, end_us,
                                                                  result))
    board = Board(image, conn.exchange, console_events, masked_limit_s=masked_limit_s)
    if fs_image is not None:
        board.core.uc.mem_write(flash_fs.FS_BASE, fs_image)
    tracer = None
    if coverage is not None:
        from hexhil.hil.mcu.coverage import LineCounter
        tracer = LineCounter(image, board.core.uc, coverage_libraries)
    if gdb_port is not None:
        board.debugger = GdbServer(board, gdb_port)
    fault = None
    try:
        board.run()
        verdict = board.endings.verdict
        if verdict is not None and board.debugger is not None and \
                verdict.kind is not Ending.EXITED_EARLY:
            board.debugger.halted_by(SIGINT if verdict.kind is Ending.HUNG else SIGABRT,
                                     f"{image.path.name}: {verdict.reason}")
    except CoreFault as exc:      # a verdict on the firmware, as a crashed process's
        fault = exc
        if board.debugger is not None:       # GDB inspects the faulting state first
            board.debugger.halted_by(fault_signal(str(exc)), f"{image.path.name}: {exc}")
        board.close()             # what the board had posted (a console line) is recorded
    finally:
        result.stderr_tail = "\n".join(board.console_tail)
        if tracer is not None:
            tracer.write(coverage)
        if board.debugger is not None:
            board.debugger.run_ended(board.exit_code or 0)
        result.firmware.setdefault("mcu", {"hclk_hz": board.rcc.hclk_hz,
                                           "cycles": board.core.cyc,
                                           "instructions": board.core.executed,
                                           "skipped_cycles": board.skipped_cycles,
                                           "link_requests": board.link.requests,
                                           "resets": board.resets,
                                           "reset_causes": dict(board.reset_causes),
                                           "faults": list(board.faults.lines),
                                           "deadline": board.cycles.figures()})
    if fs_out is not None:            # what the firmware left in /flash, also after a fault
        flash_fs.read_back(bytes(board.core.uc.mem_read(flash_fs.FS_BASE, flash_fs.FS_SIZE)),
                           fs_out)
    if fault is not None:
        result.exit_code = 1
        result.exceptions.append(f"{image.path.name}: {fault}")
        result.ending = FirmwareEnding(
            Ending.CRASHED, f"the firmware {image.path.name} faulted: {fault}",
            tuple(board.console_tail[-LAST_LINES:]), board.now_us() * 1e-6, 1)
        return board
    verdict = board.endings.verdict
    if verdict is not None:
        result.exit_code = 1
        if verdict.kind is not Ending.EXITED_EARLY:
            result.exceptions.append(f"{image.path.name}: {verdict.reason}")
        result.ending = FirmwareEnding(
            verdict.kind, f"the firmware {image.path.name} {verdict.reason}",
            tuple(board.console_tail[-LAST_LINES:]), board.now_us() * 1e-6, verdict.exit_code)
        board.close()
        return board
    result.exit_code = board.exit_code if board.exit_code is not None else 0
    board.close()
    return board
