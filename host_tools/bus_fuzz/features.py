"""What an execution reached, as features (CRC-32s, the same in every process, unlike
``hash`` of a string): the firmware's lines run (in process, ``sys.settrace``; an ELF's from
its LCOV) and the bus master's packet sequences. An input that reaches a feature no other
reached joins the corpus (campaign.py)."""
from __future__ import annotations

import os
import sys
import zlib
from pathlib import Path
from typing import Any, Sequence

from hil.seams import ServoLine


def feature(*parts: object) -> int:
    """A feature's number: the CRC-32 of its parts."""
    return zlib.crc32(":".join(map(str, parts)).encode())


class LineTracer:
    """The firmware's lines run (``sys.settrace``: CPython 3.11 has no ``sys.monitoring``),
    only in files under ``roots``."""

    def __init__(self, roots: Sequence[Path]) -> None:
        self.roots = tuple(str(r) + os.sep for r in roots)
        self.hits: set[tuple[str, int]] = set()
        self._ours: dict[Any, bool] = {}

    def _global(self, frame: Any, event: str, arg: Any) -> Any:
        code = frame.f_code
        ours = self._ours.get(code)
        if ours is None:
            ours = self._ours[code] = code.co_filename.startswith(self.roots)
        return self._local if ours else None

    def _local(self, frame: Any, event: str, arg: Any) -> Any:
        if event == "line":
            self.hits.add((frame.f_code.co_filename, frame.f_lineno))
        return self._local

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


class PacketSequence:
    """The bus master's packets in order, as features: each (instruction, ID) after the one
    before it. Stands in front of the master check (``bus.monitor``, if there is one) and
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
            if data[i] == 0xFF and data[i + 1] == 0xFF and data[i + 2] != 0xFF:
                now = (data[i + 4], data[i + 2])
                self.pairs.add(feature("packets", *self._last, *now))
                self._last = now
                i += 4 + data[i + 3]
            else:
                i += 1

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
