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

from hexhil.hil.link import cores
from hexhil.trace.can_signals import json_default
from hexhil.trace.encoder_process import ChildWriteFailed, Command, EncoderProcess
from hexhil.trace.target import TraceTarget
from hexhil.trace.topics import METADATA_NAME
from hexhil.trace.writer import ChunkPacking, TraceWriter, software_version
from hexhil.protocol.errors import BadFile

Encoded = list[tuple[int, int, bytes]]   # (log_time_ns, channel id, data)


class EncodeIn(Enum):
    """Where the held messages are encoded and written: the same bytes either way."""

    CHILD_PROCESS = "child-process"   # a forked child, beside the run (the default)
    THIS_PROCESS = "this-process"     # in idle() and at each window's end


def encode_in_for(firmware_own_process: bool) -> EncodeIn:
    """Where a run's trace is best encoded. While a firmware in a process of its own
    computes, the run has nothing else to do and encodes then (``idle``; a child beside
    the two made a micropython run 8 % slower); any other run (the firmware in this
    process, none) hands it to a child, which made an in-process run 11 % faster, where
    the child has a CPU of its own: with fewer than two (``taskset``, a cgroup's quota,
    hil/link/cores.py) it takes the run's, and the encoding stays here (an in-process
    ``--out`` run on one core: 54x with a child, 58x without)."""
    if firmware_own_process or cores.usable() < 2:
        return EncodeIn.THIS_PROCESS
    return EncodeIn.CHILD_PROCESS


PACK_PER_MESSAGE = 8   # chunk records packed in the time one message is encoded (~0.3 us)
IDLE_SLICE = 4         # held messages encoded between looks at whether the firmware answered


def _encode_some(pending: list[tuple], out: Encoded, done: int, budget: int) -> int:
    """Encode up to ``budget`` held values after the first ``done`` (call order: parsers see
    bytes in order) into ``out``; how many are done now."""
    for t, encode, args in pending[done:done + budget]:
        encode(out, t, *args)
    return min(done + budget, len(pending))


class _ClosedWindow:
    """A window virtual time has left, finished a step at a time (``step``): its held
    values encoded in call order (``pending``, the first ``done`` of them in ``out``
    already), then sorted and packed into a chunk, then written."""

    def __init__(self, pending: list[tuple], out: Encoded, done: int) -> None:
        self.pending, self.out, self.done = pending, out, done
        self.packing: ChunkPacking | None = None
        self.packed = False

    def step(self, owner: "HeldWindows", budget: int) -> None:
        if self.done < len(self.pending):
            self.done = _encode_some(self.pending, self.out, self.done, budget)
        elif self.packing is None:
            self.out.sort(key=itemgetter(0))  # stable: equal times keep call order
            self.packing = ChunkPacking(self.out, owner._writer.messages)
        elif not self.packed:
            self.packed = self.packing.pack(budget * PACK_PER_MESSAGE)
        else:   # compressed and written: the one step that is not sliced (~50 us)
            owner._closed = None
            owner._write_chunk(self.out, self.packing)


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
        self._closed: _ClosedWindow | None = None  # left by virtual time, not written yet
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
        elif self._idle_seen:  # the owner calls idle() soon: finished there, off its path
            self._finish_closed()   # one window waits at most: the last still waiting, now
            self._closed = _ClosedWindow(self._pending, self._out, self._done)
            self._pending, self._out, self._done = [], [], 0
            self._new_window()
        else:
            self._write_chunk(self._encode_pending())
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
            raise BadFile(str(exc)) from None
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
        """Do a little of the held work, in order: a closed window's (encode up to
        ``budget`` of its messages, or pack ``PACK_PER_MESSAGE`` times as many into its
        chunk, or write it), else encode up to ``budget`` of the open window's; True while
        some is left. The simulator calls this while it waits for the firmware, slice after
        slice until the firmware answers, so the work overlaps the firmware's computing
        instead of adding to it (a closed window's chunk written whole took 150-330 us);
        the bytes written do not depend on when (or whether) it is called. A
        closed window is written before the next one closes. With a child there is
        nothing to do."""
        self._idle_seen = True
        if self._encoder is not None:
            return False
        w = self._closed
        if w is not None:
            w.step(self, max(budget, 1))
            return True
        if not budget:
            return self._done < len(self._pending)
        self._done = _encode_some(self._pending, self._out, self._done, budget)
        return self._done < len(self._pending)

    def work_while(self, waiting: Callable[[], bool]) -> None:
        """``idle`` slice by slice (``IDLE_SLICE`` messages, about 10 us) while ``waiting()``
        says the simulator still waits for the firmware's next message, or until nothing
        is left."""
        while waiting() and self.idle(IDLE_SLICE):
            pass

    def flush(self) -> None:
        """Write the held messages in log-time order as one chunk and hand it to the OS."""
        if self._encoder is not None:
            self._hand_over(Command.SYNC)
            return
        self._finish_closed()
        self._write_chunk(self._encode_pending())

    def _finish_closed(self) -> None:
        """The closed window's work that idle() has not done yet, now."""
        w = self._closed
        while w is not None and w is self._closed:
            w.step(self, 1 << 30)

    def _encode_pending(self) -> Encoded:
        """The held messages encoded, as (log_time_ns, channel, data) in log-time order."""
        out = self._out
        _encode_some(self._pending, out, self._done, len(self._pending))
        self._pending, self._out, self._done = [], [], 0
        self._new_window()
        out.sort(key=itemgetter(0))  # stable: equal times keep call order
        return out

    def _write_chunk(self, msgs: Encoded, packing: ChunkPacking | None = None) -> None:
        """``msgs`` as one chunk (``packing``: its records packed already)."""
        if msgs:
            try:
                if packing is None:
                    self._writer.chunk(msgs)
                else:
                    self._writer.end_chunk(packing)
            except OSError as exc:
                self._write_failed(exc)
            self.messages = self._writer.messages
            if self._live is not None:
                self._live.log(msgs)

    def _write_failed(self, exc: OSError) -> None:
        """A full disk or a file-size limit: stop recording, keep what is on disk, one line."""
        where = self._stop_writing()
        # a count of whole chunks: one whose index the disk refused is on disk too
        raise BadFile(f"{self.path}: cannot write trace ({exc.strerror or exc}); what was "
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
            self._finish_closed()
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
