"""A firmware that is not ours, started and served by the simulator in lockstep:
``hexhil run --firmware PATH`` (``Run(firmware=...)``).

* ``BoardFirmware``: a MicroPython main file run under the real ``micropython`` binary on
  the virtual STM32F411 board (firmware/virtual_board/, hil/link/board_line.py,
  docs/your-firmware.md);
* ``ExecutableFirmware``: any executable that speaks docs/link.md, such as a C firmware
  built against firmware/c_sdk/ (docs/c-firmware.md). It finds the link through
  ``HEXHIL_LINK_PORT`` in its environment (hil/link/firmware_child.py ``FirmwareProcess``);
* ``ElfFirmware``: an STM32F411 ELF (its header says ARM, 32-bit), run unchanged on the
  emulated board in this process (hil/mcu/, docs/elf-firmware.md).

Both end the same way (``serve_process``): a crash, a hang (no link message for
``HANG_WALL_S`` of wall time, or the board's own verdict: only polls for 2 virtual seconds),
an exit before the run's end or a failed start is the run's ``FirmwareEnding``
(hil/run_result.py), a verdict on the firmware and not an error of hexhil; the trace
recorded up to then is kept: the caller's recorder is closed as after any run.
"""
from __future__ import annotations

import os
import signal
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Callable, Protocol

from hexhil.hil.link.firmware_child import TAIL_BYTES, FirmwareProcess
from hexhil.hil.link.firmware_process import ROOT, FirmwareError, firmware_command, firmware_env
from hexhil.hil.mcu import flash_fs
from hexhil.hil.mcu.elf_image import ELF_MAGIC, ElfImage, is_arm_elf, load_elf
from hexhil.hil.mcu.flash_fs import FlashFiles
from hexhil.hil.run.limits import MASKED_LIMIT_S
from hexhil.hil.run_result import LAST_LINES, Ending, FirmwareEnding, RunTally
from hexhil.hil.seams import LinkHost
from hexhil.protocol import sim_link
from hexhil.protocol.errors import BadFile, BadValue, UserError

BOARD_DIR = ROOT / "firmware" / "virtual_board"
BOARD_RUNTIME = "micropython-board"   # a run's firmware_runtime
EXECUTABLE = "executable"
ELF_RUNTIME = "stm32f411-elf"
HANG_WALL_S = 20.0          # wall seconds without a link message: the firmware hung
# wall seconds a firmware has to exit once it closed the link (the board's SystemExit at
# the run's end); one still running then is ended by the host
EXIT_GRACE_S = 2.0
BOARD_SAYS = "hexhil board: "   # the C SDK's one-line verdict on its firmware (hal_board.c)
HUNG_SAYS = "the firmware hung"   # the board's verdict (hil/link/board_line.py)
MAIN_SUFFIXES = (".py",)    # a MicroPython main file; anything else is an executable
CONSOLE_TRACE_BYTES = 1 << 20   # of a firmware's prints, handed on to the trace's log lines
CONSOLE_CUT_BYTES = 8 << 20     # past the cap, its console file is cut back beyond this size


class ServedFirmware(Protocol):
    """A firmware the simulator starts and serves itself (hil/run/lockstep.py ``Simulator.run``)."""

    runtime: str
    own_process: bool   # it computes in a process of its own, while the host waits

    def command(self) -> list[str]:
        """The command line that starts it."""

    def env(self) -> dict[str, str]:
        """What its environment needs beyond the link's."""

    def serve(self, server: LinkHost, end_us: int, result: RunTally) -> None:
        """Start it, answer its link with ``server`` (hil/link/server.py) to the end."""


def served_firmware(path: str | Path, what: str = "firmware", gdb_port: int | None = None,
                    coverage: str | Path | None = None, flash_files: FlashFiles | None = None,
                    masked_limit_s: float = MASKED_LIMIT_S, coverage_libraries: bool = False
                    ) -> BoardFirmware | ExecutableFirmware | ElfFirmware:
    """``path`` checked: a MicroPython main file (``.py``) for the virtual board, an ARM
    ELF for the emulated STM32F411, else an executable file this user may run
    (``UserError`` naming ``what`` if neither). ``gdb_port``, ``coverage`` and
    ``flash_files`` (the MicroPython ELF's ``/flash``: hil/mcu/flash_fs.py) are an ELF's
    only and go to the ELF runtime, and so do ``masked_limit_s``, the virtual time an ELF
    may run with interrupts masked before it is hung (hil/mcu/verdicts.py), and
    ``coverage_libraries``, which counts the toolchain's libraries too (hil/mcu/coverage.py)."""
    p = Path(path)
    if (gdb_port is not None or coverage is not None) and not is_arm_elf(p):
        raise UserError(f"gdb_port and coverage need an STM32F411 ELF as {what}, not {path}",
                        params=("gdb_port", "coverage", what))
    if flash_files is not None and not is_arm_elf(p):
        raise UserError(f"main, fs and fs_out need a MicroPython STM32F411 ELF as {what}, "
                        f"not {path}", params=("main", "fs", "fs_out", what))
    if gdb_port is not None and not 1 <= gdb_port <= 65535:
        raise BadValue(f"gdb_port {gdb_port}: a port is 1-65535", params=("gdb_port",))
    if not p.is_file():
        raise BadFile(f"{what} {path}: not a file (give a MicroPython main file, an "
                      "STM32F411 ELF or an executable)", params=(what,))
    if p.suffix in MAIN_SUFFIXES:
        try:
            text = _is_text(p.read_bytes())
        except OSError as exc:
            raise BadFile(f"{what} {path}: cannot read it ({exc.strerror})",
                          params=(what,)) from None
        if not text:
            raise BadValue(f"{what} {path}: not a MicroPython source file (it holds binary "
                           "data, not UTF-8 text)", params=(what,))
        return BoardFirmware(p.resolve())
    if is_arm_elf(p):
        if not masked_limit_s > 0:
            raise BadValue(f"masked_limit_s {masked_limit_s}: give a time above 0 s",
                           params=("masked_limit_s",))
        elf = load_elf(p, what)
        return ElfFirmware(elf, gdb_port, Path(coverage) if coverage is not None else None,
                           flash_files, flash_fs.laid(elf, flash_files), masked_limit_s,
                           coverage_libraries)
    if not os.access(p, os.X_OK) and p.read_bytes()[:4] == ELF_MAGIC:
        load_elf(p, what)     # names what the ELF is for, in one line
    if not os.access(p, os.X_OK):
        raise BadFile(f"{what} {path}: neither a MicroPython main file (.py) nor "
                      "executable (build a C firmware with `hexhil sdk build main.c -o fw`, "
                      "or chmod +x)", params=(what,))
    return ExecutableFirmware(p.resolve())


def _is_text(data: bytes) -> bool:
    """A source micropython can parse: UTF-8 without NUL bytes (micropython itself only
    says ``SyntaxError: invalid syntax`` of a binary file)."""
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return b"\0" not in data


@dataclass(frozen=True)
class BoardFirmware:
    """A MicroPython main file to run on the virtual board."""

    main: Path
    runtime: str = BOARD_RUNTIME
    own_process: bool = True

    def command(self) -> list[str]:
        return [firmware_command("micropython")[0], str(self.main)]

    def env(self) -> dict[str, str]:
        return {"MICROPYPATH": f"{BOARD_DIR}:" + firmware_env(0)["MICROPYPATH"],
                sim_link.ENV_BOARD: sim_link.BOARD_NAME}

    def serve(self, server: LinkHost, end_us: int, result: RunTally) -> None:
        """The console's ``event KIND TEXT`` lines (hal/base.py ``Board.event``) are its
        events."""
        serve_process(self, self.main.name, server, end_us, result, _console_to(server, result))


@dataclass(frozen=True)
class ExecutableFirmware:
    """An executable file that speaks the firmware link."""

    path: Path
    runtime: str = EXECUTABLE
    own_process: bool = True

    def command(self) -> list[str]:
        return [str(self.path)]

    def env(self) -> dict[str, str]:
        return {}

    def serve(self, server: LinkHost, end_us: int, result: RunTally) -> None:
        """What it prints on stdout goes to ``/telemetry`` as log lines (the C SDK makes
        stdout line-buffered, so a line arrives when printed)."""
        serve_process(self, self.path.name, server, end_us, result, _console_to(server, result))


def _console_to(server: LinkHost, result: RunTally) -> Callable[[str], None]:
    def take_console(printed: str) -> None:
        for kind, text in console_events(printed):
            server.take_event(kind, text, result)
    return take_console


@dataclass(frozen=True)
class ElfFirmware:
    """An STM32F411 ELF on the emulated board (hil/mcu/); ``gdb_port`` waits for a GDB
    client before the first instruction, ``coverage`` writes LCOV line coverage there."""

    image: ElfImage
    gdb_port: int | None = None
    coverage: Path | None = None
    flash_files: FlashFiles | None = None
    fs_image: bytes | None = None     # laid at flash_fs.FS_BASE before the boot
    masked_limit_s: float = MASKED_LIMIT_S
    coverage_libraries: bool = False
    runtime: str = ELF_RUNTIME
    own_process: bool = False   # Unicorn, in the host's process

    @property
    def path(self) -> Path:
        return self.image.path

    def command(self) -> list[str]:
        return []

    def env(self) -> dict[str, str]:
        return {}

    def serve(self, server: LinkHost, end_us: int, result: RunTally) -> None:
        """A fault is its ending (hil/mcu/runtime.py); a semihosting SYS_EXIT before the
        run's end is judged as a process's exit."""
        from hexhil.hil.mcu.runtime import serve_elf   # Unicorn: only where an ELF runs

        board = serve_elf(self.image, server, end_us, result, console_events, self.gdb_port,
                          self.coverage, self.fs_image,
                          self.flash_files.out if self.flash_files is not None else None,
                          self.masked_limit_s, self.coverage_libraries)
        if result.ending.completed and board.exit_code is not None and not board.ended:
            result.ending = judge(self.path.name, board.exit_code, "",
                                  "\n".join(board.console_tail), board.link.t_us, end_us)


def _how(code: int) -> str:
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit {code}"


def serve_process(firmware: ServedFirmware, name: str, server: LinkHost, end_us: int,
                  result: RunTally, take_console: Callable[[str], None] | None = None
                  ) -> None:
    """Start ``firmware``, serve its link to ``end_us`` and judge how it ended
    (``result.ending``: a crash, a hang, an early exit or a failed start is the run's
    verdict, not an error). Its stdout goes to a file: a firmware that prints a lot never
    blocks on a full pipe; ``take_console`` reads what it printed, whole lines at each
    batch of its link messages (so each is stamped with the time of the host's last reply
    before it, the firmware's time where its clock is the link's), the rest at the end."""
    hang_wall_s = HANG_WALL_S
    with tempfile.TemporaryFile() as console:
        try:
            fw = FirmwareProcess(firmware.runtime, command=firmware.command(),
                                 extra_env=firmware.env(), console=console,
                                 watch=server.watch)
        except FirmwareError as exc:
            console.seek(0)
            printed = console.read().decode(errors="replace")
            result.exit_code = exc.exit_code
            result.ending = FirmwareEnding(
                Ending.FAILED_TO_START, f"the firmware {name} failed to start: {exc}",
                exc.last_lines or _last_lines("", printed), 0.0, exc.exit_code)
            return
        fw.conn.sock.settimeout(hang_wall_s)
        hung, broke, closed = False, None, False
        reader = _ConsoleReader(console, take_console)
        server.console = reader.lines if take_console is not None else None
        try:
            server.serve(fw.conn, end_us, result)
            closed = True
        except TimeoutError:
            hung = True
        except FirmwareError as exc:   # it broke the link's rules (hil/link/server.py)
            broke = exc
        finally:   # an interrupt or a limit ends it at once
            server.console = None
            code, _, err = fw.finish(timeout_s=EXIT_GRACE_S if closed else 0.0)
            printed = reader.rest()
    result.console_dropped_bytes = reader.dropped
    result.exit_code = code
    result.stderr_tail = "\n".join(err.strip().splitlines()[-LAST_LINES:])
    result.ending = judge(name, code, err, printed, server.clock.t_us, end_us,
                          hang_wall_s if hung else None, broke, fw.ended_by_host)


def _last_lines(err: str, printed: str) -> tuple[str, ...]:
    return tuple((err.strip().splitlines() or printed.strip().splitlines())[-LAST_LINES:])


def judge(name: str, code: int, err: str, printed: str, t_us: int, end_us: int,
          hung_after_s: float | None = None, broke: Exception | None = None,
          ended_by_host: bool = False) -> FirmwareEnding:
    """How a served firmware ended, in one line and its last lines. ``ended_by_host``:
    it closed the link but was still running ``EXIT_GRACE_S`` later, and the host ended
    it: at the run's end that is a completed run (a bare ``except:`` that catches the
    board's SystemExit carries on where a real board would), before it an early exit."""
    t_s = t_us * 1e-6
    last = _last_lines(err, printed)
    if ended_by_host and hung_after_s is None and broke is None:
        if t_us >= end_us:
            return FirmwareEnding(Ending.COMPLETED, "", (), t_s, code)
        return FirmwareEnding(Ending.EXITED_EARLY, f"the firmware {name} closed the link at "
                              f"t={t_s:.6f} s, before the run's end ({end_us * 1e-6:g} s), "
                              f"and did not exit (ended by hexhil {EXIT_GRACE_S:g} s later)",
                              last, t_s, code)
    if hung_after_s is not None:
        return FirmwareEnding(Ending.HUNG, f"the firmware {name} hung: no link message for "
                              f"{hung_after_s:g} s of wall time (at t={t_s:.6f} s)", last, t_s,
                              code)
    if broke is not None:   # hil/link/server.py's "firmware link: ..." (the board's hang)
        text = str(broke).removeprefix("firmware link: ")
        if text.startswith(HUNG_SAYS):
            return FirmwareEnding(Ending.HUNG, f"the firmware {name} hung"
                                  f"{text[len(HUNG_SAYS):]}", last, t_s, code)
        return FirmwareEnding(Ending.CRASHED, f"the firmware {name} broke the link at "
                              f"t={t_s:.6f} s: {text}", last, t_s, code)
    line = (last or ("no message",))[-1]
    if code != 0 and line.startswith(BOARD_SAYS):   # the C SDK's own verdict (a hang)
        return FirmwareEnding(Ending.HUNG, f"the firmware {name} {line[len(BOARD_SAYS):]}",
                              last, t_s, code)
    if code != 0:
        return FirmwareEnding(Ending.CRASHED, f"the firmware {name} crashed at t={t_s:.6f} s "
                              f"({_how(code)}): {line}", last, t_s, code)
    if t_us < end_us:
        return FirmwareEnding(Ending.EXITED_EARLY, f"the firmware {name} exited at "
                              f"t={t_s:.6f} s, before the run's end ({end_us * 1e-6:g} s)",
                              last, t_s, code)
    return FirmwareEnding(Ending.COMPLETED, "", (), t_s, code)


class _ConsoleReader:
    """A firmware's console file, read on as it grows (``os.pread``: the file offset the
    firmware writes at is shared, and stays untouched): whole lines to ``take``, up to
    ``CONSOLE_TRACE_BYTES``. Past that, bounded: nothing more is read or handed on
    (``dropped`` counts it), only the last ``TAIL_BYTES`` for the verdict, and the file
    is cut back to nothing now and then (the firmware's next write leaves a hole, which
    takes no disk)."""

    def __init__(self, console: IO[bytes], take: Callable[[str], None] | None) -> None:
        self._fd, self._take = console.fileno(), take
        self._pos = 0             # bytes of the file read (the firmware's offset, at most)
        self._line = b""          # a line begun, not ended yet
        self._tail = b""          # the last TAIL_BYTES read
        self.handed = 0           # bytes handed on
        self.dropped = 0          # bytes past the cap, never handed on

    def _read(self) -> bytes:
        """What was printed since, up to a little over the room left under the cap."""
        out = bytearray()
        most = CONSOLE_TRACE_BYTES - self.handed + 65536
        while len(out) < most and (chunk := os.pread(self._fd, 65536, self._pos)):
            self._pos += len(chunk)
            out += chunk
        self._tail = (self._tail + out)[-TAIL_BYTES:]
        return bytes(out)

    def lines(self) -> None:
        if self.handed >= CONSOLE_TRACE_BYTES:
            self._skip()
            return
        text = self._line + self._read()
        cut = text.rfind(b"\n") + 1
        if cut and self._take is not None:
            self._hand(text[:cut])
        self._line = text[cut:][-CONSOLE_TRACE_BYTES:]

    def _hand(self, data: bytes) -> None:
        room = CONSOLE_TRACE_BYTES - self.handed
        if len(data) > room:   # up to the last whole line that fits
            keep = data.rfind(b"\n", 0, room) + 1
            self.dropped += len(data) - keep
            data = data[:keep]
            self.handed = CONSOLE_TRACE_BYTES
        else:
            self.handed += len(data)
        if data:
            self._take(data.decode(errors="replace"))

    def _skip(self) -> None:
        """Past the cap: count what was printed since, keep only its tail."""
        size = os.fstat(self._fd).st_size
        if size > self._pos:
            start = max(self._pos, size - TAIL_BYTES)
            self.dropped += size - self._pos
            self._tail = (self._tail + os.pread(self._fd, size - start, start))[-TAIL_BYTES:]
            self._pos = size
        if size > CONSOLE_CUT_BYTES:
            os.ftruncate(self._fd, 0)

    def rest(self) -> str:
        """The last ``TAIL_BYTES`` printed (for the verdict); what was not handed on yet,
        handed on while under the cap."""
        if self.handed < CONSOLE_TRACE_BYTES:
            text = self._line + self._read()
            self._line = b""
            if text and self._take is not None:
                self._hand(text)
        self._skip()   # what is left past the cap: counted, its tail kept
        return self._tail.replace(b"\0", b"").decode(errors="replace")


def console_events(text: str) -> list[tuple[int, str]]:
    """(kind, text) of what a firmware printed: an ``event KIND TEXT`` line is that event
    (a traceback's following lines belong to it), any other line an ``EVENT_LOG``."""
    out: list[tuple[int, str]] = []
    for line in text.splitlines():
        parts = line.split(" ", 2)
        if len(parts) >= 2 and parts[0] == "event" and parts[1].isdigit():
            out.append((int(parts[1]), parts[2] if len(parts) > 2 else ""))
        elif out and out[-1][0] == sim_link.EVENT_EXCEPTION and line.startswith(" "):
            out[-1] = (out[-1][0], out[-1][1] + "\n" + line)
        else:
            out.append((sim_link.EVENT_LOG, line))
    return out
