"""A run's limits: a wall-clock cap and a memory cap that end a run as a verdict
(``Ending.LIMIT``, in the summary and ``--json``) instead of running on for ever or
leaving it to the kernel's out-of-memory kill.

``RunWatch`` checks them from a thread of its own every ``CHECK_S``: the wall time since
the run began, and the resident memory of this process and of the firmware's processes
it was given (``watch``). When one is over, it ends those processes' groups (the host's
read of the link then sees it closed) and raises ``LimitHit`` in the thread the run is in
(an asynchronous exception, whatever the signal handlers are: a ``KeyboardInterrupt``
that ``Simulator.run`` tells from a person's by ``hit``), so the trace is finished as
after Ctrl-C.
"""
from __future__ import annotations

import ctypes
import os
import threading
import time
import weakref
from dataclasses import dataclass
from typing import Any

from hexhil.hil.link.firmware_child import end_group
from hexhil.protocol.errors import BadValue

DEFAULT_MEMORY_MB = 4096.0   # this process and its firmware's, resident
MASKED_LIMIT_S = 0.5         # an ELF awake this many virtual seconds with interrupts masked: a hang
WALL_BASE_S = 120.0          # the wall-clock cap, unless given: this, plus
WALL_PER_SIM_S = 20.0        # this many wall seconds a simulated second (a 0.05x run)
CHECK_S = 0.05


class LimitHit(KeyboardInterrupt):
    """Raised in a run's thread when one of its caps is hit (``RunWatch``)."""


@dataclass(frozen=True)
class RunLimits:
    """``max_wall_s``: wall seconds a run may take (None: ``WALL_BASE_S`` plus
    ``WALL_PER_SIM_S`` a simulated second of it); ``max_memory_mb``: the resident memory,
    in MiB, of hexhil's process and its firmware's together. Infinity turns a cap off."""

    max_wall_s: float | None = None
    max_memory_mb: float = DEFAULT_MEMORY_MB

    def __post_init__(self) -> None:
        for name in ("max_wall_s", "max_memory_mb"):
            v = getattr(self, name)
            if v is None and name == "max_wall_s":
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0:
                raise BadValue(f"{name} must be a positive number (inf: no cap), not {v!r}",
                               params=(name,))

    def wall_s(self, duration_s: float) -> float:
        """The wall-clock cap of a run of ``duration_s`` simulated seconds."""
        if self.max_wall_s is not None:
            return float(self.max_wall_s)
        return WALL_BASE_S + WALL_PER_SIM_S * duration_s

    def as_dict(self, duration_s: float, hit: str | None) -> dict[str, Any]:
        """The summary's ``limits``: the caps this run had, and which one ended it."""
        return {"max_wall_s": round(self.wall_s(duration_s), 3),
                "max_memory_mb": self.max_memory_mb, "hit": hit}


def _rss_mb(pid: int | str) -> float:
    """A process's resident memory in MiB (0 once it is gone)."""
    try:
        with open(f"/proc/{pid}/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, IndexError, ValueError):
        return 0.0


class RunWatch:
    """Watches one run's limits while it is entered (``with``): ``hit`` is None, or
    ``"wall"`` or ``"memory"`` with ``reason``, the verdict's line. A process forked
    during the run (the bus fuzzer's children) has no watch thread, and the locks that
    thread may have held at the fork are made anew there (``_forked``)."""

    def __init__(self, limits: RunLimits, duration_s: float) -> None:
        self.limits, self.duration_s = limits, duration_s
        self.hit: str | None = None
        self.reason = ""
        self._pids: set[int] = set()
        self._lock = threading.Lock()
        self._armed = False
        self._stop = threading.Event()
        self._run_thread = threading.get_ident()   # where the run is: LimitHit goes there
        self._thread: threading.Thread | None = None

    def watch(self, pid: int) -> None:
        """A firmware process (the leader of its own group) whose memory counts, and
        whose group ends when a limit is hit."""
        self._pids.add(pid)

    def forget(self, pid: int) -> None:
        self._pids.discard(pid)

    def __enter__(self) -> "RunWatch":
        self._t0 = time.monotonic()
        self._wall_s = self.limits.wall_s(self.duration_s)
        self._armed = True
        self._thread = threading.Thread(target=self._loop, name="hexhil-run-watch",
                                        daemon=True)
        _WATCHED.add(self)
        self._thread.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        _WATCHED.discard(self)
        with self._lock:
            self._armed = False
        self._stop.set()
        if self._thread is not None:
            self._thread.join()

    def _forked(self) -> None:
        """In a forked child: no watch thread, and its locks free (a lock the thread held
        at the fork stays held for ever in the child: ending the run would wait on it)."""
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = None

    def _loop(self) -> None:
        cap_mb = self.limits.max_memory_mb
        while not self._stop.wait(CHECK_S):
            wall = time.monotonic() - self._t0
            if wall > self._wall_s:
                self._end("wall", f"the run took more than its wall-clock cap of "
                          f"{self._wall_s:g} s (max_wall_s)")
                return
            mb = _rss_mb("self") + sum(_rss_mb(p) for p in list(self._pids))
            if mb > cap_mb:
                self._end("memory", f"hexhil and its firmware held {mb:,.0f} MiB, over the "
                          f"run's memory cap of {cap_mb:g} MiB (max_memory_mb)")
                return

    def _end(self, hit: str, reason: str) -> None:
        with self._lock:
            if not self._armed:
                return
            self.hit, self.reason = hit, reason
            for pid in list(self._pids):
                end_group(pid)
            ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(self._run_thread),
                                                       ctypes.py_object(LimitHit))


_WATCHED: "weakref.WeakSet[RunWatch]" = weakref.WeakSet()   # the runs being watched


def _after_fork_in_child() -> None:
    for watch in list(_WATCHED):
        watch._forked()


os.register_at_fork(after_in_child=_after_fork_in_child)
