"""What an execution reached, as features (CRC-32s, the same in every process, unlike
``hash`` of a string): the firmware's lines run (in process, line_probes.py; an ELF's from
its LCOV) and the bus master's packet sequences. An input that reaches a feature no other
reached joins the corpus (campaign.py)."""
from __future__ import annotations

import zlib
from pathlib import Path
from typing import Any

from hexhil.hil.seams import ServoLine


def feature(*parts: object) -> int:
    """A feature's number: the CRC-32 of its parts."""
    return zlib.crc32(":".join(map(str, parts)).encode())


def line_features(lines: set[tuple[str, int]]) -> set[int]:
    """The firmware's lines run (file name, line) as features."""
    return {feature("line", name, n) for name, n in lines}


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
