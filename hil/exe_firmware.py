"""A firmware that is an executable (a C firmware built against firmware/c_sdk/, or any
program that speaks docs/link.md), served in lockstep: ``hexhil run --firmware PATH``.

The executable is started with ``HEXHIL_LINK_PORT`` in its environment (hil/link.py
``FirmwareProcess``) and served like our firmware. How it ended is judged in one line
(``UserError``): a crash (a signal or a non-zero exit), a hang (no link message for
``hang_wall_s`` of wall time, or the C SDK's verdict: only polls for 2 virtual seconds) or
an exit before the run's end. The trace recorded up to
then is kept: the caller's recorder is closed as after any run.
"""
from __future__ import annotations

import os
import signal
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from hil.link import FirmwareProcess
from hil.run_result import RunResult
from protocol.errors import UserError

EXECUTABLE = "executable"   # the run's firmware_runtime
HANG_WALL_S = 20.0          # wall seconds without a link message: the firmware hung
BOARD_SAYS = "hexhil board: "   # the C SDK's one-line verdict on its firmware (hal_tick.c)


class ServedFirmware(Protocol):
    """A firmware the simulator starts and serves itself (hil/sim.py ``Simulator.run``)."""

    runtime: str

    def serve(self, server: Any, end_us: int, result: RunResult) -> None:
        """Start it, answer its link with ``server`` (hil/link_server.py) to the end."""


def _how(code: int) -> str:
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit {code}"


@dataclass(frozen=True)
class ExecutableFirmware:
    """An executable file that speaks the firmware link."""

    path: Path
    hang_wall_s: float = HANG_WALL_S
    runtime: str = EXECUTABLE

    @staticmethod
    def of(path: str | Path, hang_wall_s: float | None = None) -> "ExecutableFirmware":
        """``path`` checked: a file this user may execute (else ``UserError``);
        ``hang_wall_s`` defaults to ``HANG_WALL_S``."""
        p = Path(path)
        if not p.is_file():
            raise UserError(f"--firmware {path}: no such file")
        if not os.access(p, os.X_OK):
            raise UserError(f"--firmware {path}: not executable (build it with "
                            "`hexhil sdk build main.c -o fw`, or chmod +x)")
        return ExecutableFirmware(p.resolve(), HANG_WALL_S if hang_wall_s is None else hang_wall_s)

    def serve(self, server: Any, end_us: int, result: RunResult) -> None:
        # stdout to a file: a firmware that printf()s a lot never blocks on a full pipe
        with tempfile.TemporaryFile() as console:
            fw = FirmwareProcess(self.runtime, command=[str(self.path)], console=console)
            fw.conn.sock.settimeout(self.hang_wall_s)
            hung = False
            try:
                server.serve(fw.conn, end_us, result)
            except TimeoutError:
                hung = True
            finally:
                code, _, err = fw.finish(timeout_s=0.0 if hung else 10.0)
            console.seek(0)
            printed = console.read().decode(errors="replace")
        result.exit_code = code
        result.stderr_tail = "\n".join(err.strip().splitlines()[-5:])
        t_s = server.clock.t_us * 1e-6
        name = self.path.name
        if hung:
            raise UserError(f"the firmware {name} hung: no link message for "
                            f"{self.hang_wall_s:g} s of wall time (at t={t_s:.6f} s)")
        last = (err.strip().splitlines() or printed.strip().splitlines() or ["no message"])[-1]
        if code != 0 and last.startswith(BOARD_SAYS):   # the C SDK's own verdict (a hang)
            raise UserError(f"the firmware {name} {last[len(BOARD_SAYS):]}")
        if code != 0:
            raise UserError(f"the firmware {name} crashed at t={t_s:.6f} s ({_how(code)}): "
                            f"{last}")
        if server.clock.t_us < end_us:
            raise UserError(f"the firmware {name} exited at t={t_s:.6f} s, before the run's "
                            f"end ({end_us * 1e-6:g} s)")
