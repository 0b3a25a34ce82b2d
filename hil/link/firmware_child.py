"""The firmware as a child process of the host: started in a process group of its own on a
Unix socket (ours) or a 127.0.0.1 port (a command of the caller's), its output to files,
ended whole at every stop. The link it speaks is hil/link/firmware_process.py's."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import tempfile
import time
from typing import Any

from hexhil.hil.link.firmware_process import (ROOT, Connection, FirmwareError, firmware_command,
                                      firmware_env, last_words)

ACCEPT_POLL_S = 0.1   # how often a firmware not connected yet is checked for having exited


def _listen(ours: bool) -> tuple[socket.socket, dict[str, str]]:
    """The socket the firmware connects to, and its environment. Our firmware (its HAL,
    firmware/hal/sim.py) gets a Unix socket in a directory of its own: a round trip about
    10 us cheaper than TCP's loopback, whose send also runs the receiving side's stack
    (docs/performance.md). A firmware not ours gets the documented 127.0.0.1 port,
    and so does ours where no Unix socket can be made."""
    srv = _unix_listener() if ours else None
    if srv is not None:
        return srv, firmware_env(0, srv.getsockname())
    srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)
    return srv, firmware_env(srv.getsockname()[1])


def _unix_listener() -> socket.socket | None:
    """A Unix socket listening in a new temporary directory, or None where none can be
    made there (a path too long for a socket's, a directory not writable)."""
    try:
        where = tempfile.mkdtemp(prefix="hexhil-link-")
    except OSError:
        return None
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        srv.bind(os.path.join(where, "link"))
    except OSError:
        srv.close()
        os.rmdir(where)
        return None
    srv.listen(1)
    return srv


def _close_listener(srv: socket.socket) -> None:
    """Close the listening socket; a Unix one's file and directory go with it (the
    accepted connection lives on)."""
    path = srv.getsockname() if srv.family == socket.AF_UNIX else None
    srv.close()
    if path:
        os.unlink(path)
        os.rmdir(os.path.dirname(path))


class FirmwareProcess:
    """The firmware as a child process connected to this one: our firmware on a Unix
    socket, a command of the caller's on an ephemeral 127.0.0.1 port (``_listen``).

    It runs in a process group of its own, ended whole at every stop (``finish``, ``kill``,
    a timeout): a wrapper script's children go with it. Its stdout and stderr go to
    temporary files, never pipes, so a chatty firmware never blocks on a full pipe and a
    child holding one open never keeps this side waiting; only their last ``TAIL_BYTES``
    are read back."""

    def __init__(self, python: str = "micropython", connect_timeout_s: float = 30.0,
                 command: list[str] | None = None, extra_env: dict[str, str] | None = None,
                 console: Any = None, watch: Any = None) -> None:
        """``extra_env`` is set over ``firmware_env``'s; ``console``, a file, takes the
        firmware's stdout (the caller reads it as it grows); ``watch``, the run's
        hil/run/limits.py ``RunWatch``, counts its memory and ends it at a limit."""
        self.python = python
        self._console = console
        self._stdout = console if console is not None else tempfile.TemporaryFile()
        self.ended_by_host = False   # still running when ``finish`` stopped waiting
        self._stderr = tempfile.TemporaryFile()
        self._watch = None
        cmd = command or firmware_command(python)
        srv, env = _listen(ours=command is None)
        srv.settimeout(ACCEPT_POLL_S)
        env.update(extra_env or {})
        try:
            self.proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdin=subprocess.DEVNULL,
                                         stdout=self._stdout, stderr=self._stderr,
                                         process_group=0)
        except OSError as exc:
            _close_listener(srv)
            self._close_files()
            raise FirmwareError(f"cannot start the firmware ({' '.join(cmd)}): {exc.strerror}",
                                started=False) from None
        self._watch = watch
        if watch is not None:
            watch.watch(self.proc.pid)
        try:
            sock = self._accept(srv, cmd, connect_timeout_s)
        except BaseException:
            self._end_group()
            self._close_files()
            raise
        finally:
            _close_listener(srv)
        sock.settimeout(None)
        self.conn = Connection(sock, self.proc.pid)

    def _accept(self, srv: socket.socket, cmd: list[str], timeout_s: float) -> socket.socket:
        """The firmware's connection; one line if it exits first or takes too long."""
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                return srv.accept()[0]
            except socket.timeout:
                code = self.proc.poll()
                if code is None and time.monotonic() < deadline:
                    continue
            self._end_group()
            out, err = self._outputs()
            lines = (err.strip() + "\n" + out.strip()).strip().splitlines()
            tail = last_words(err, out)
            what = (f"did not connect within {timeout_s:g} s" if code is None
                    else f"exited with code {code} before it connected to the link")
            raise FirmwareError(f"the firmware ({' '.join(cmd)}) {what}: {tail}",
                                tuple(lines[-5:]), started=False,
                                exit_code=self.proc.returncode) from None

    def _end_group(self) -> None:
        """SIGKILL to the firmware's whole process group, then reap the process itself."""
        end_group(self.proc.pid)
        self.proc.wait()
        if self._watch is not None:
            self._watch.forget(self.proc.pid)

    def _outputs(self) -> tuple[str, str]:
        """The last ``TAIL_BYTES`` of what it wrote on stdout and on stderr."""
        return _tail(self._stdout), _tail(self._stderr)

    def _close_files(self) -> None:
        if self._console is None:
            self._stdout.close()
        self._stderr.close()

    def finish(self, timeout_s: float = 10.0) -> tuple[int, str, str]:
        """Wait up to ``timeout_s`` for the process to exit, then end its process group;
        (return code, the tails of stdout and stderr)."""
        try:
            self.proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            self.ended_by_host = True
        self._end_group()
        out, err = self._outputs()
        self.conn.close()
        self._close_files()
        return self.proc.returncode, out, err

    def kill(self) -> None:
        """End it now, its process group with it."""
        self._end_group()
        self.conn.close()
        self._close_files()


def end_group(pgid: int) -> None:
    """SIGKILL to what is left of process group ``pgid`` (a child started with
    ``process_group=0``: a wrapper script's children go with it)."""
    try:
        os.killpg(pgid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass   # every process of the group has exited


TAIL_BYTES = 65536   # of a firmware's stdout and stderr, read back for its verdict


def _tail(f: Any) -> str:
    """The last ``TAIL_BYTES`` of file ``f`` (written by the firmware), as text."""
    size = os.fstat(f.fileno()).st_size
    return os.pread(f.fileno(), TAIL_BYTES, max(0, size - TAIL_BYTES)).decode(errors="replace")
