"""The recorder's encoding in a child process, off the run's critical path.

The run hands each closed window's raw values (what ``Recorder`` held) to a forked child,
which encodes and writes them with the same ``Recorder`` code on its copy of the recorder:
the bytes do not depend on where they were encoded. On two or more cores the encoding
then overlaps the world step and the firmware instead of adding to the run.

Why a fork and a pipe: the child starts with the recorder's state as it is (channels,
parsers, the open file and its lock) in milliseconds, and a pickled window of raw values
costs the run a few microseconds a cycle where encoding it cost about two hundred.

Crash safety stays the recorder's: the child writes every window it was sent. When the run
dies (SIGKILL) the pipe reaches its end and the child leaves the partial file as it is, for
``hexhil trace recover``. Ctrl-C and SIGTERM are the run's to handle: the child blocks
them and finishes the file when the run closes the recorder.
"""
from __future__ import annotations

import gc
import os
import pickle
import signal
import struct
import traceback
from enum import Enum
from typing import Any, Protocol

from hexhil.protocol.errors import UserError

_LEN = struct.Struct("<I")
_STOP = {signal.SIGINT, signal.SIGTERM}


class Command(Enum):
    """What the child does with a window's raw values."""

    WRITE = 1    # encode and write them as a chunk
    SYNC = 2     # the same, the run waiting until it is written
    CLOSE = 3    # the same, then the summary: the file is complete


class Owner(Protocol):
    """The child's copy of the recorder: what it does with a window."""

    messages: int

    def _write_window(self, pending: list[tuple]) -> None: ...
    def _finish(self, pending: list[tuple]) -> None: ...


class ChildWriteFailed(Exception):
    """The child could not write the file (a full disk): the recorder's one line, and how
    many ``messages`` were written."""

    def __init__(self, line: str, messages: int) -> None:
        super().__init__(line)
        self.messages = messages


class EncoderProcess:
    """A forked child that encodes and writes what ``send`` hands it; ``keep_fd`` is the
    trace file's descriptor, the one inherited descriptor the child keeps (the rest point
    at /dev/null there, so a firmware's socket or a pty sees its peer close)."""

    def __init__(self, owner: Owner, keep_fd: int) -> None:
        down_r, down_w = os.pipe()
        up_r, up_w = os.pipe()
        pid = os.fork()
        if pid == 0:
            code = 1
            try:
                gc.freeze()   # the run's objects: never scanned here, so never copied
                signal.pthread_sigmask(signal.SIG_BLOCK, _STOP)
                _quiet_other_fds({keep_fd, down_r, up_w})
                code = _serve(owner, down_r, up_w)
            finally:
                os._exit(code)
        os.close(down_r)
        os.close(up_w)
        self.pid, self._down, self._up = pid, down_w, up_r
        self.closed = False
        self._unacknowledged = False   # a window sent that the child has not reported on
        self._messages = 0

    def send(self, command: Command, pending: list[tuple]) -> int:
        """Hand a window over; return how many messages the file held when the window
        before it was written (for SYNC and CLOSE: with this one). Waiting for the window
        before keeps the child at most one window behind, so a run killed together with
        its child loses at most the window being written and the one still open. Raises
        ChildWriteFailed once the child could not write."""
        messages = self._acknowledged()
        frame = pickle.dumps((command, pending), protocol=pickle.HIGHEST_PROTOCOL)
        old = signal.pthread_sigmask(signal.SIG_BLOCK, _STOP)   # never half a frame
        try:
            _write_all(self._down, _LEN.pack(len(frame)) + frame)
        except BrokenPipeError:
            pass   # the child ended: its report, read next, says why
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
        self._unacknowledged = True
        if command is Command.WRITE:
            return messages
        messages = self._acknowledged()
        if command is Command.CLOSE:
            self._end()
        return messages

    def kill(self) -> None:
        """Stop the child now (the trace is being discarded)."""
        if not self.closed:
            os.kill(self.pid, signal.SIGKILL)
            self._end()

    def _end(self) -> None:
        self.closed = True
        os.close(self._down)
        os.close(self._up)
        os.waitpid(self.pid, 0)

    def _acknowledged(self) -> int:
        """The child's report on the last window sent: the messages written by then, or its
        failure raised here."""
        if not self._unacknowledged:
            return self._messages
        self._unacknowledged = False
        report = _read_frame(self._up)
        if report is None:
            self._end()
            raise RuntimeError("the trace encoder process ended unexpectedly")
        kind, value, messages = pickle.loads(report)
        if kind == "ok":
            self._messages = messages
            return messages
        self._end()
        if kind == "failed":
            raise ChildWriteFailed(value, messages)
        raise RuntimeError(f"the trace encoder process failed:\n{value}")


def _serve(owner: Owner, down: int, up: int) -> int:
    while True:
        frame = _read_frame(down)
        if frame is None:   # the run died: what was sent is written, the file stays partial
            return 0
        command, pending = pickle.loads(frame)
        try:
            if command is Command.CLOSE:
                owner._finish(pending)
            else:
                owner._write_window(pending)
        except UserError as exc:   # the recorder's own line for a file it cannot write
            _report(up, "failed", str(exc), owner.messages)
            return 0
        except BaseException:
            _report(up, "bug", traceback.format_exc(), owner.messages)
            return 1
        _report(up, "ok", None, owner.messages)
        if command is Command.CLOSE:
            return 0


def _report(fd: int, kind: str, value: Any, messages: int) -> None:
    frame = pickle.dumps((kind, value, messages))
    _write_all(fd, _LEN.pack(len(frame)) + frame)


def _quiet_other_fds(keep: set[int]) -> None:
    """Point every inherited descriptor but ``keep`` at /dev/null (numbers stay taken, so
    an inherited object that closes its own later closes only that)."""
    null = os.open(os.devnull, os.O_RDWR)
    for name in os.listdir("/proc/self/fd"):
        fd = int(name)
        if fd not in keep and fd != null:
            try:
                os.dup2(null, fd)
            except OSError:
                pass   # the listing's own descriptor, closed by now
    os.close(null)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def _read_frame(fd: int) -> bytes | None:
    head = _read_exactly(fd, _LEN.size)
    if head is None:
        return None
    return _read_exactly(fd, _LEN.unpack(head)[0])


def _read_exactly(fd: int, n: int) -> bytes | None:
    parts, left = [], n
    while left:
        part = os.read(fd, left)
        if not part:
            return None
        parts.append(part)
        left -= len(part)
    return b"".join(parts)
