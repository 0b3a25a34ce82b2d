"""What an execution reached, as features (CRC-32s, the same in every process, unlike
``hash`` of a string): the firmware's lines run (in process, ``sys.settrace``; an ELF's from
its LCOV) and the bus master's packet sequences. An input that reaches a feature no other
reached joins the corpus (campaign.py)."""
from __future__ import annotations

import os
import sys
import zlib
from pathlib import Path
from typing import Any, Callable, Sequence

from hil.seams import ServoLine


def feature(*parts: object) -> int:
    """A feature's number: the CRC-32 of its parts."""
    return zlib.crc32(":".join(map(str, parts)).encode())


class LineTracer:
    """The firmware's lines run (``sys.settrace``: CPython 3.11 has no ``sys.monitoring``),
    only in files under ``roots``, and not in the functions of ``done`` (ids of code
    objects every line of which ran already, ``complete``): in those no line can be new,
    and leaving them untraced spares most of the line events a firmware's hot loop makes."""

    def __init__(self, roots: Sequence[Path], done: frozenset[int] = frozenset()) -> None:
        self.roots = tuple(str(r) + os.sep for r in roots)
        self.done = done
        self.hits: set[tuple[str, int]] = set()
        self._ours: dict[int, bool] = {}       # by the code object's id (a code's hash is slow)
        self._codes: list[Any] = []            # ... so each code stays alive, its id its own
        self._local = self._line_tracer()

    def _global(self, frame: Any, event: str, arg: Any) -> Any:
        code = frame.f_code
        ours = self._ours.get(id(code))
        if ours is None:
            ours = self._ours[id(code)] = (code.co_filename.startswith(self.roots)
                                           and id(code) not in self.done)
            self._codes.append(code)
        return self._local if ours else None

    def _line_tracer(self) -> Callable[[Any, str, Any], Any]:
        """The local trace function: a closure, no attribute look-ups (a call a line)."""
        add = self.hits.add

        def local(frame: Any, event: str, arg: Any) -> Any:
            if event == "line":
                add((frame.f_code.co_filename, frame.f_lineno))
            return local
        return local

    def start(self) -> None:
        sys.settrace(self._global)
        frame = sys._getframe(1)
        while frame is not None:       # the frames already running (the firmware's loop)
            if frame.f_code.co_filename.startswith(self.roots):
                frame.f_trace = self._local
            frame = frame.f_back

    def stop(self) -> set[int]:
        sys.settrace(None)
        return {feature("line", Path(f).name, n) for f, n in self.hits}

    def complete(self) -> frozenset[int]:
        """After ``stop``: the ids of the traced functions every line of which ran."""
        by_file: dict[str, set[int]] = {}
        for f, n in self.hits:
            by_file.setdefault(f, set()).add(n)
        out = set(self.done)
        for code in self._codes:
            if not self._ours[id(code)]:
                continue
            lines = {n for _, _, n in code.co_lines() if n is not None}
            lines.discard(code.co_firstlineno)      # the def line runs no line event
            if lines <= by_file.get(code.co_filename, set()):
                out.add(id(code))
        return frozenset(out)


class PacketSequence:
    """The bus master's packets in order, as features: each (instruction, ID) after the one
    before it, in Protocol 1.0 or 2.0 (told by the header). Stands in front of the master check (``bus.monitor``, if there is one) and
    passes all on."""

    def __init__(self, check: Any) -> None:
        self.check = check
        self.pairs: set[int] = set()
        self._last = (0, 0)

    def master_bytes(self, bus: ServoLine, t0_us: int, data: bytes) -> None:
        if self.check is not None:
            self.check.master_bytes(bus, t0_us, data)
        i, n = 0, len(data)
        while i + 4 < n:
            if data[i] != 0xFF or data[i + 1] != 0xFF or data[i + 2] == 0xFF:
                i += 1
                continue
            if data[i + 2] == 0xFD and data[i + 3] == 0x00:     # Protocol 2.0's header
                if i + 7 >= n:
                    return
                now = (data[i + 7], data[i + 4])
                step = 7 + (data[i + 5] | data[i + 6] << 8)
            else:                                                # Protocol 1.0's
                now, step = (data[i + 4], data[i + 2]), 4 + data[i + 3]
            self.pairs.add(feature("packets", *self._last, *now))
            self._last = now
            i += step

    def direction_mistake(self, t_us: int, kind: str, detail: str) -> None:
        """The virtual board's direction pin was wrong (hil/link/server.py ``run_fault``)."""
        if self.check is not None:
            self.check.direction_mistake(t_us, kind, detail)


def elf_lines(info: Path) -> set[int]:
    """The lines an ELF run reached, from its LCOV file (hil/mcu/coverage.py)."""
    out, name = set(), ""
    if not info.exists():
        return out
    for row in info.read_text().splitlines():
        if row.startswith("SF:"):
            name = Path(row[3:]).name
        elif row.startswith("DA:"):
            line, n = row[3:].split(",")[:2]
            if int(n):
                out.add(feature("elf", name, int(line)))
    return out
