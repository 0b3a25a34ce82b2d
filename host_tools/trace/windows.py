"""A trace written a window of virtual time at a time: the held raw values, where they are
encoded, and the file's lifecycle (host_tools/trace/recorder.py says why it is built so).

The parts hand raw values to ``_defer``; a window's values are encoded and written as one
chunk when virtual time leaves the window. ``EncodeIn`` says where: in a forked child
(host_tools/trace/encoder_process.py), or in this process, in ``idle()`` slices while the
owner waits for its firmware and at the window's end. The bytes are the same either way.
"""
from __future__ import annotations

import json
from enum import Enum
from operator import itemgetter
from pathlib import Path
from typing import Any, BinaryIO, Callable, Mapping

from host_tools.trace.can_signals import json_default
from host_tools.trace.encoder_process import ChildWriteFailed, Command, EncoderProcess
from host_tools.trace.target import TraceTarget
from host_tools.trace.topics import METADATA_NAME
from host_tools.trace.writer import TraceWriter, software_version
from protocol.errors import UserError

Encoded = list[tuple[int, int, bytes]]   # (log_time_ns, channel id, data)


class EncodeIn(Enum):
    """Where the held messages are encoded and written: the same bytes either way."""

    CHILD_PROCESS = "child-process"   # a forked child, beside the run (the default)
    THIS_PROCESS = "this-process"     # in idle() and at each window's end


def encode_in_for(firmware_own_process: bool) -> EncodeIn:
    """Where a run's trace is best encoded. While a firmware in a process of its own
    computes, the run has nothing else to do and encodes then (``idle``; a child beside
    the two made a micropython run 8 % slower); any other run (the firmware in this
    process, none) hands it to a child, which made an in-process run 11 % faster."""
    return EncodeIn.THIS_PROCESS if firmware_own_process else EncodeIn.CHILD_PROCESS


class HeldWindows:
    """The file, its windows and the held values; a subclass adds what the parts record,
    its encoders (``_encode_*(out, t_ns, *args)``), and calls ``_begin`` when its own
    state is set up (a child starts with that state)."""

    def __init__(self, path: str | Path, metadata: Mapping[str, Any] | None,
                 flush_interval_us: int, live: Any, overwrite: bool) -> None:
        self.path = Path(path)
        self._live = live  # a LiveServer (host_tools/trace/live.py) that sees what is written
        self.messages, self.closed = 0, False
        self._target = TraceTarget(self.path, overwrite)   # TARGET.partial, renamed at close
        self._file: BinaryIO = self._target.file
        meta = {"software_version": software_version()}
        for k, v in (metadata or {}).items():
            meta[str(k)] = v if isinstance(v, str) else json.dumps(v, sort_keys=True,
                                                                   default=json_default)
        try:
            self._writer = TraceWriter(self._file, f"hexhil {software_version()}")
            self._writer.metadata(METADATA_NAME, meta)
        except OSError as exc:
            self._write_failed(exc)
        self._flush_interval_us = int(flush_interval_us)
        self._window_end_us = self._flush_interval_us
        self._pending: list[tuple] = []  # (log_time_ns, encode, args) in call order
        self._out: Encoded = []  # the first _done of them, encoded
        self._done = 0
        self._ready: Encoded | None = None  # a closed window, unwritten
        self._idle_seen = False
        self._encoder: EncoderProcess | None = None

    def _begin(self, encode_in: EncodeIn) -> None:
        """Start the child, if encoding goes there (a live server reads the encoded
        messages in this process, so with one it stays here)."""
        if encode_in is EncodeIn.CHILD_PROCESS and self._live is None:
            try:
                self._file.flush()   # the child writes on from here
            except OSError as exc:
                self._write_failed(exc)
            self._encoder = EncoderProcess(self, self._file.fileno())

    @property
    def encode_in(self) -> EncodeIn:
        """Where this file's messages are encoded."""
        return EncodeIn.THIS_PROCESS if self._encoder is None else EncodeIn.CHILD_PROCESS

    def _defer(self, t_us: int, encode: Callable[..., None], args: tuple) -> None:
        """Hold the raw values; ``encode(out, t_ns, *args)`` appends the encoded messages
        in ``idle()``, when the window is written or in the child, so a call costs about
        1 us."""
        t_us = int(t_us)
        if t_us >= self._window_end_us:
            self._flush_window(t_us)
        self._pending.append((t_us * 1000, encode, args))

    def _new_window(self) -> None:
        """The held values went to be encoded: a subclass's per-window state starts over."""

    def _last(self, msgs: Encoded) -> None:
        """A subclass's messages that only the end of the run completes, added to ``msgs``."""

    def _flush_window(self, now_us: int) -> None:
        if self.closed:  # close() sets the window end to -1, so every later call lands here
            raise RuntimeError("recorder is closed")
        if self._encoder is not None:
            self._hand_over(Command.WRITE)
        else:
            self._write_ready()
            msgs = self._encode_pending()
            if self._idle_seen:  # the owner calls idle() soon, off its critical path
                self._ready = msgs
            else:
                self._write_chunk(msgs)
        step = self._flush_interval_us
        self._window_end_us = (now_us // step + 1) * step

    def _hand_over(self, command: Command) -> None:
        """The held values to the child, their encoders by name."""
        pending = [(t, encode.__name__, args) for t, encode, args in self._pending]
        self._pending = []
        self._new_window()
        try:
            self.messages = self._encoder.send(command, pending)
        except ChildWriteFailed as exc:   # the child's _write_failed, said here
            self.messages = exc.messages
            self._stop_writing()
            raise UserError(str(exc)) from None
        except RuntimeError:   # the child died: what it wrote stays in the partial file
            self._stop_writing()
            raise

    def _write_window(self, pending: list[tuple]) -> None:
        """The child's part: a window handed over, encoded and written."""
        self._write_chunk(self._encoded(pending))

    def _finish(self, pending: list[tuple]) -> None:
        """The child's part of ``close``: the last window and the summary."""
        self._finish_here(self._encoded(pending))

    def _encoded(self, pending: list[tuple]) -> Encoded:
        out: Encoded = []
        for t, name, args in pending:
            getattr(self, name)(out, t, *args)
        out.sort(key=itemgetter(0))
        return out

    def idle(self, budget: int) -> bool:
        """Do a little of the held work: write a closed window, or encode up to ``budget``
        held messages; True while some is left. The simulator calls this while it waits
        for the firmware, slice after slice until the firmware answers, so the encoding
        overlaps the firmware's computing instead of adding to it; the bytes written do not
        depend on when (or whether) it is called. With a child there is nothing to do."""
        self._idle_seen = True
        if self._encoder is not None:
            return False
        if self._ready is not None:
            self._write_ready()
            return self._done < len(self._pending)
        if not budget:
            return self._done < len(self._pending)
        pending, out, i = self._pending, self._out, self._done
        for t, encode, args in pending[i:i + budget]:
            encode(out, t, *args)
        self._done = min(i + budget, len(pending))
        return self._done < len(pending)

    def flush(self) -> None:
        """Write the held messages in log-time order as one chunk and hand it to the OS."""
        if self._encoder is not None:
            self._hand_over(Command.SYNC)
            return
        self._write_ready()
        self._write_chunk(self._encode_pending())

    def _write_ready(self) -> None:
        if self._ready is not None:
            msgs, self._ready = self._ready, None
            self._write_chunk(msgs)

    def _encode_pending(self) -> Encoded:
        """The held messages encoded, as (log_time_ns, channel, data) in log-time order."""
        pending, out = self._pending, self._out
        for t, encode, args in pending[self._done:]:  # call order: parsers see bytes in order
            encode(out, t, *args)
        self._pending, self._out, self._done = [], [], 0
        self._new_window()
        out.sort(key=itemgetter(0))  # stable: equal times keep call order
        return out

    def _write_chunk(self, msgs: Encoded) -> None:
        if msgs:
            try:
                self._writer.chunk(msgs)
            except OSError as exc:
                self._write_failed(exc)
            self.messages = self._writer.messages
            if self._live is not None:
                self._live.log(msgs)

    def _write_failed(self, exc: OSError) -> None:
        """A full disk or a file-size limit: stop recording, keep what is on disk, one line."""
        where = self._stop_writing()
        # a count of whole chunks: one whose index the disk refused is on disk too
        raise UserError(f"{self.path}: cannot write trace ({exc.strerror or exc}); what was "
                        f"written before (at least {self.messages} messages) stays in {where}"
                        ) from None

    def _stop_writing(self) -> str:
        """Close the file as it is; where what was written stays (one line's words)."""
        self.closed = True
        self._window_end_us = -1
        return self._target.abandon()

    def advance(self, t_us: int) -> None:
        """Tell the recorder virtual time has reached ``t_us`` (flushes a finished window)."""
        if int(t_us) >= self._window_end_us and not self.closed:
            self._flush_window(int(t_us))

    def close(self) -> None:
        """Write everything and the MCAP summary; the file is complete after this."""
        if self.closed:
            return
        if self._encoder is not None:
            self._hand_over(Command.CLOSE)
        else:
            self._write_ready()
            self._finish_here(self._encode_pending())
        self.closed = True
        self._window_end_us = -1
        self._target.commit()

    def _finish_here(self, msgs: Encoded) -> None:
        self._last(msgs)
        msgs.sort(key=itemgetter(0))
        self._write_chunk(msgs)
        try:
            self._writer.finish()
            self._file.flush()
        except OSError as exc:
            self._write_failed(exc)

    def discard(self) -> None:
        """Stop and remove what was written; the target stays as it was (a failed import)."""
        if not self.closed:
            if self._encoder is not None:
                self._encoder.kill()
            self.closed = True
            self._window_end_us = -1
            self._target.discard()

    def __enter__(self) -> "HeldWindows":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
