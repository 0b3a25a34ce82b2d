"""``--gdb PORT``: a GDB server on the emulated core (udbserver), on 127.0.0.1.

The run waits for the client before the first instruction. While GDB holds the core
(a breakpoint, a step), the emulator is blocked inside Unicorn: no instruction runs, so
virtual time, the bus and the world stand still, and a debugged run's trace equals an
undebugged one. Breakpoints, stepping, registers and memory are udbserver's.
"""
from __future__ import annotations

import socket
from typing import Any

from unicorn import arm_const as A

from protocol.errors import UserError


class Debugger:
    def detach(self) -> None:
        """Nothing to undo: udbserver's hooks end with the Unicorn instance."""


def attach(board: Any, port: int) -> Debugger:
    """Wait for a GDB client on 127.0.0.1:``port``, the core at its reset vector."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:   # one clear line
        try:
            probe.bind(("127.0.0.1", port))
        except OSError as exc:
            raise UserError(f"--gdb {port}: cannot listen on 127.0.0.1:{port} "
                            f"({exc.strerror})") from None
    from udbserver import udbserver
    core = board.core
    core.uc.reg_write(A.UC_ARM_REG_PC, core.pc | 1)
    udbserver(core.uc, port, 0)
    return Debugger()
