"""The firmware under this CPython, in the host's own process: the runtime of sweeps.

``firmware/main.py`` runs unchanged on the simulator HAL (``firmware/hal/sim.py``), whose
link writes to ``Wire`` instead of a socket. A link call hands the written frames to the
simulator (hil/link/firmware_process.py ``DirectConnection``) and reads its reply back, so a run trades two
process wake-ups a round trip for one function call. Same frames, same answers: the
serial digest is micropython's (tests/test_in_process.py). micropython stays the
reference and the default of ``hexhil run``; this lives on the top floor because it joins
firmware/ and hil/, which never import each other.
"""
from __future__ import annotations

import contextlib
import importlib.util
import itertools
import sys
from pathlib import Path
from typing import Callable

from hexhil import chip_names
from hexhil.firmware import main as firmware_main
from hexhil.firmware.hal import sim as sim_hal
from hexhil.firmware.hal.sim import Board
from hexhil.lifecycle import ctrl_c_behind
from hexhil.hil.link.firmware_process import IN_PROCESS
from hexhil.hil.run.limits import RunLimits
from hexhil.hil.run_result import RunResult
from hexhil.hil.run.lockstep import Simulator
from hexhil.protocol import sim_link
from hexhil.protocol.errors import BadValue


class Wire:
    """File-like end of the link for the firmware's ``Link(io=...)``: writes collect until
    the firmware reads, which is when it waits for a reply.

    An exception in the simulator (a host node's, a Ctrl-C) must not reach the firmware's
    own ``except Exception``, which would report it as the firmware's: the wire keeps it,
    answers as a closed link from then on (so the firmware winds down), and
    ``run_firmware`` raises it."""

    def __init__(self, exchange: Callable[[bytes, bool], bytes]) -> None:
        self._exchange = exchange
        self.pending = bytearray()
        self.reply = b""
        self.pos = 0
        self.error: BaseException | None = None

    def exchange(self, closed: bool) -> bytes:
        data = bytes(self.pending)
        self.pending.clear()
        if self.error is not None:
            return b""
        try:
            return self._exchange(data, closed)
        except BaseException as exc:  # re-raised by run_firmware, outside the firmware
            self.error = exc
            return b""

    def write(self, data: memoryview) -> int:
        self.pending += data
        return len(data)

    def readinto(self, buf: memoryview) -> int:
        if self.pos >= len(self.reply):
            self.reply, self.pos = self.exchange(False), 0
        n = min(len(buf), len(self.reply) - self.pos)
        buf[:n] = self.reply[self.pos:self.pos + n]
        self.pos += n
        return n

    def close(self) -> None:
        self.exchange(True)


class Printed:
    """The firmware's ``print`` in process, as a child's stdout is: each line a log event
    on the link (the run's console: live on stderr, ``--json``'s console, ``/telemetry``)."""

    def __init__(self, board: Board) -> None:
        self.board, self._line = board, ""

    def write(self, text: str) -> int:
        *lines, self._line = (self._line + text).split("\n")
        for line in lines:
            self.board.event(sim_link.EVENT_LOG, line)
        return len(text)

    def flush(self) -> None:
        """Nothing waits: a line goes with the link's next message."""


Exchange = Callable[[bytes, bool], bytes]
FirmwareMain = Callable[[Board], None]


def run_firmware(exchange: Exchange, main: FirmwareMain | None = None) -> None:
    """Boot and run the firmware (``main``, default ours: ``firmware/main.py``'s) until the
    simulator ends the run (``Simulator.run``'s ``in_process``); the simulator's own
    exception, if it raised one, is raised here, and so is a Ctrl-C, even where the
    firmware's clean-up raised something else on its way out."""
    wire = Wire(exchange)
    try:
        board = Board(io=wire)              # its hello is the link's first exchange
        with contextlib.redirect_stdout(Printed(board)):
            (main or firmware_main.main)(board)
    except BaseException as exc:   # the dead link's error, or a clean-up's after a Ctrl-C
        cause = wire.error or ctrl_c_behind(exc)
        if cause is None:
            raise
        raise cause from None
    if wire.error is not None:
        raise wire.error


def counted_profiling_clock() -> Callable[[], None]:
    """The sim HAL's profiling clock (``perf_us``: wall microseconds, for telemetry's compute
    time) made to count its calls, so that nothing the firmware runs hangs on the machine's
    load (the bus fuzzer's lines: host_tools/bus_fuzz/). Control reads ``ticks_us``, the
    virtual time, as before. Returns what puts the wall clock back."""
    wall = sim_hal._perf_us
    sim_hal._perf_us = itertools.count().__next__

    def undo() -> None:
        sim_hal._perf_us = wall
    return undo


def load_main(path: str | Path) -> FirmwareMain:
    """``main(board)`` of a Python file: a firmware run in process like ours (a variant of
    it, e.g. tests/fuzz_targets/trusting_ids.py; ``hexhil test --in-process``)."""
    p = Path(path)
    spec = importlib.util.spec_from_file_location(f"hexhil_in_process_{p.stem}", p)
    if spec is None or spec.loader is None or not p.is_file():
        raise BadValue(f"main_file {path}: not a Python file", params=("main_file",))
    module = chip_names.chip_module(importlib.util.module_from_spec(spec))
    sys.path.insert(0, str(p.parent))
    try:
        spec.loader.exec_module(module)
    except Exception as exc:
        raise BadValue(f"main_file {path}: it raised {exc!r} on import",
                        params=("main_file",)) from None
    finally:
        sys.path.remove(str(p.parent))
    main = getattr(module, "main", None)
    if not callable(main):
        raise BadValue(f"main_file {path}: defines no main(board)", params=("main_file",))
    return main


def run(sim: Simulator, duration_s: float | None, python: str | None,
        limits: RunLimits | None = None, wrap: Callable[[Exchange], Exchange] | None = None,
        main: FirmwareMain | None = None) -> RunResult:
    """``sim.run`` under the runtime named ``python``: this module's ``run_firmware`` for
    ``cpython-inprocess``, else a child process (hil/ cannot import the firmware, so the
    choice is made here, on the top floor); ``limits``, the run's caps. In process,
    ``wrap`` sees every exchange of the link (the bus fuzzer forks there:
    host_tools/bus_fuzz/) and ``main`` is the firmware run (default ours)."""
    if python == IN_PROCESS:
        if wrap is None and main is None:
            return sim.run(duration_s, in_process=run_firmware, limits=limits)
        return sim.run(duration_s, in_process=lambda exchange: run_firmware(
            wrap(exchange) if wrap is not None else exchange, main), limits=limits)
    return sim.run(duration_s, python=python, limits=limits)
