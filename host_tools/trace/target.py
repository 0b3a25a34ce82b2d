"""Where a trace is written, so that no trace is ever lost: every trace hexhil
writes (``--out`` of run, bus, beams, an experiment's folder, ``test --keep-traces``,
``trace import-csv``) is opened here.

* The bytes go to ``TARGET.partial`` beside the target, renamed onto it only once the file
  is finished: a run killed with SIGKILL leaves the partial file, which ``hexhil trace
  recover TARGET OUT`` finds (host_tools/trace/recover.py), and never a damaged target.
* An existing target is refused unless ``overwrite``; so is an unfinished ``.partial``
  left by a killed run (it holds that run's trace until it is recovered or removed).
* The partial file is locked (``flock``) while it is written: a second run onto the same
  target is refused at once instead of both writing one file.
* A target that is not a regular file (``/dev/null``, ``/dev/full``) is written directly.
"""
from __future__ import annotations

import fcntl
import os
from pathlib import Path
from typing import Any, BinaryIO

from hexhil.protocol.errors import BadFile, UserError

PARTIAL_SUFFIX = ".partial"


def partial_of(path: str | Path) -> Path:
    """The unfinished file a run writes before it renames it onto ``path``."""
    p = Path(path)
    return p.with_name(p.name + PARTIAL_SUFFIX)


class TraceTarget:
    """``file`` is where the trace's bytes go; ``commit()`` puts the finished file at
    ``path``; ``abandon()`` closes it and leaves the partial file for ``trace recover``."""

    def __init__(self, path: str | Path, overwrite: bool = False) -> None:
        self.path = Path(path)
        self.overwrite = overwrite
        self.partial: Path | None = None
        if self.path.exists() and not self.path.is_file():
            if self.path.is_dir():
                raise BadFile(f"{self.path}: is a directory, not a trace file")
            self.file = self._open_direct()   # a device: /dev/null, /dev/full
            return
        if self.path.exists() and not overwrite:
            raise BadFile(f"{self.path} exists: pass overwrite to replace it "
                          "(or write the trace elsewhere)", params=("overwrite",))
        self.partial = partial_of(self.path)
        self.file = self._open_partial(self.partial)

    def _open_direct(self) -> BinaryIO:
        try:
            return open(self.path, "wb")
        except OSError as exc:
            raise BadFile(f"{self.path}: cannot write trace ({exc.strerror})") from None

    def _open_partial(self, partial: Path) -> BinaryIO:
        try:
            fd = os.open(partial, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:
            raise BadFile(f"{self.path}: cannot write trace ({exc.strerror})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise UserError(f"{self.path}: another run is writing this trace now "
                            f"({partial.name} is locked); write this one elsewhere") from None
        try:
            same = os.stat(partial).st_ino == os.fstat(fd).st_ino
        except OSError:
            same = False
        if not same:   # the run before renamed it onto the target meanwhile
            os.close(fd)
            raise UserError(f"{self.path}: another run has just written this trace; pass "
                            "overwrite to replace it", params=("overwrite",))
        if os.fstat(fd).st_size and not self.overwrite:
            os.close(fd)
            raise UserError(f"{partial}: the unfinished trace of a run that was killed; "
                            f"'hexhil trace recover {self.path} OUT.mcap' salvages it "
                            "(remove it, or pass overwrite, to write over it)",
                            params=("overwrite",))
        os.ftruncate(fd, 0)
        return os.fdopen(fd, "wb")

    def commit(self) -> None:
        """Close the finished file and put it at ``path`` (the lock held to the rename)."""
        if self.partial is None:
            self.file.close()
            return
        try:
            self.file.flush()
            if self.overwrite:
                os.replace(self.partial, self.path)
            else:   # no clobber: a file made at the target meanwhile stays
                os.link(self.partial, self.path)
                os.unlink(self.partial)
        except FileExistsError:
            raise UserError(f"{self.path} appeared while this run wrote its trace: the trace "
                            f"is in {self.partial}") from None
        except OSError as exc:
            raise BadFile(f"{self.path}: cannot finish the trace ({exc.strerror}); it is "
                          f"in {self.partial}") from None
        finally:
            try:
                self.file.close()
            except OSError:
                pass

    def abandon(self) -> str:
        """Close after a failed write; where what was written stays (one line's words)."""
        try:
            self.file.close()
        except OSError:
            pass   # the buffered tail is what the disk refused
        if self.partial is None:
            return f"{self.path}"
        return f"{self.partial} ('hexhil trace recover {self.path} OUT.mcap' salvages it)"

    def discard(self) -> None:
        """Close and remove what was written (a conversion that failed): the target, if
        there was one, stays as it was."""
        try:
            self.file.close()
        except OSError:
            pass
        if self.partial is not None:
            self.partial.unlink(missing_ok=True)

    def __enter__(self) -> BinaryIO:
        return self.file

    def __exit__(self, exc_type: Any, *_: Any) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.abandon()
