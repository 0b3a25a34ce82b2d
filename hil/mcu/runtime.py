"""An ELF served in this process: the board's link goes straight to the run's link server
(hil/link/firmware_process.py ``DirectConnection``), no socket, no child process.

Ends as the other served firmwares do (hil/link/served_firmware.py): a fault, or an exit
before the run's end, is one ``UserError`` line and the trace recorded up to then is kept.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from hil.link.firmware_process import DirectConnection
from hil.mcu.board import Board
from hil.mcu.core import CoreFault
from hil.mcu.elf_image import ElfImage
from hil.mcu.gdb import GdbServer
from hil.run_result import RunTally
from hil.seams import LinkHost
from protocol.errors import UserError


class FirmwareFault(UserError):
    """The firmware faulted (one line): a failing case in ``hexhil test``, exit 2 in
    ``hexhil run``; ``t_s`` is when."""

    def __init__(self, text: str, t_s: float) -> None:
        super().__init__(text)
        self.t_s = t_s


def serve_elf(image: ElfImage, server: LinkHost, end_us: int, result: RunTally,
              console_events: Callable[[str], list[tuple[int, str]]],
              gdb_port: int | None = None, coverage: Path | None = None) -> Board:
    """Run ``image`` against ``server`` (hil/link/server.py) until ``end_us``."""
    conn = DirectConnection(lambda c, msgs, closed: server.answer(c, msgs, closed, end_us,
                                                                  result))
    board = Board(image, conn.exchange, console_events)
    tracer = None
    if coverage is not None:
        from hil.mcu.coverage import LineCounter
        tracer = LineCounter(image, board.core.uc)
    if gdb_port is not None:
        board.debugger = GdbServer(board, gdb_port)
    name = image.path.name
    try:
        board.run()
    except CoreFault as exc:
        result.exit_code = 1
        result.exceptions.append(f"{name}: {exc}")
        board.close()           # what the board had posted (a console line) is recorded
        raise FirmwareFault(f"the firmware {name} faulted: {exc}",
                            board.now_us() * 1e-6) from None
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
                                           "resets": board.resets})
    result.exit_code = board.exit_code if board.exit_code is not None else 0
    t_s = board.link.t_us * 1e-6
    if board.exit_code is not None and not board.ended:
        board.close()
        if board.exit_code != 0:
            raise UserError(f"the firmware {name} exited with code {board.exit_code} at "
                            f"t={t_s:.6f} s (semihosting SYS_EXIT)")
        raise UserError(f"the firmware {name} exited at t={t_s:.6f} s, before the run's end "
                        f"({end_us * 1e-6:g} s)")
    board.close()
    return board
