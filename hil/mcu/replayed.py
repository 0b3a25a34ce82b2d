"""An ELF under ``hexhil replay``: the board runs in a thread of this process and its link
messages are handed to the replay loop as a firmware process's would be
(host_tools/replay.py reads ``conn.batch()``, answers with ``conn.sock.sendall``). The
board's whole view of the world is the link's replies, so the logged replies make it send
the same messages again, or show where a changed ELF differs."""
from __future__ import annotations

import queue
import threading
from pathlib import Path
from typing import Callable

from hexhil.hil.link.firmware_process import split_messages
from hexhil.hil.mcu.board import Board
from hexhil.hil.mcu.core import CoreFault
from hexhil.hil.mcu.elf_image import ElfImage
from hexhil.hil.mcu import flash_fs
from hexhil.protocol.errors import TimedOut, UserError

WAIT_S = 60.0


class _Socket:
    def __init__(self, replies: "queue.Queue[bytes]") -> None:
        self._replies = replies

    def sendall(self, data: bytes) -> None:
        self._replies.put(bytes(data))


class _Connection:
    def __init__(self, batches: "queue.Queue", replies: "queue.Queue[bytes]") -> None:
        self._batches = batches
        self.sock = _Socket(replies)

    def batch(self) -> tuple[list[tuple[int, bytes]], bool]:
        try:
            return self._batches.get(timeout=WAIT_S)
        except queue.Empty:
            raise TimedOut(f"the ELF sent nothing for {WAIT_S:g} s of wall time") from None

    def close(self) -> None:
        self.sock.sendall(b"")


class _Process:
    returncode: int | None = None


class ReplayedElf:
    """The ELF on a thread, with ``FirmwareProcess``'s ``conn``, ``kill``, ``finish``."""

    def __init__(self, image: ElfImage,
                 console_events: Callable[[str], list[tuple[int, str]]],
                 fs_image: bytes | None = None, fs_out: Path | None = None) -> None:
        self._batches: queue.Queue = queue.Queue()
        self._replies: queue.Queue[bytes] = queue.Queue()
        self.conn = _Connection(self._batches, self._replies)
        self.proc = _Process()
        self._error = ""
        self._board = Board(image, self._exchange, console_events)
        if fs_image is not None:      # the /flash the run had (hil/mcu/flash_fs.py)
            self._board.core.uc.mem_write(flash_fs.FS_BASE, fs_image)
        self._fs_out = fs_out         # where /flash goes once the board stopped
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _exchange(self, data: bytes, closed: bool) -> bytes:
        self._batches.put((split_messages(data), closed))
        if closed:
            return b""
        return self._replies.get()

    def _run(self) -> None:
        try:
            self._board.run()
            self._board.close()
            self.proc.returncode = 0
        except (CoreFault, UserError) as exc:
            self._error = str(exc)
            self.proc.returncode = 1
            self._batches.put(([], True))

    def _stopped(self, timeout_s: float) -> None:
        """The board's next request finds the link closed; then its /flash is read back."""
        self._replies.put(b"")
        self._thread.join(timeout=timeout_s)
        if self._fs_out is not None and not self._thread.is_alive():
            uc = self._board.core.uc
            flash_fs.read_back(bytes(uc.mem_read(flash_fs.FS_BASE, flash_fs.FS_SIZE)),
                               self._fs_out)

    def kill(self) -> None:
        self._stopped(10.0)

    def finish(self, timeout_s: float = 10.0) -> tuple[int, str, str]:
        self._stopped(timeout_s)
        return (self.proc.returncode if self.proc.returncode is not None else 1, "",
                self._error)
