"""``--coverage FILE.info``: line coverage of the firmware's own sources, as LCOV.

Unicorn reports every basic block it runs (address, size); at the end each block's
executions are given to the lines the ELF's DWARF line table places in it. Every line the
table knows is listed, a line never run with 0, so genhtml or a CI report shows what a
scenario leaves untested. Counting blocks costs a callback each: a run with coverage is
slower. Skipped waits (hil/mcu/board.py) count the poll loop's lines once per pass run.
"""
from __future__ import annotations

import bisect
from collections import Counter
from pathlib import Path

from elftools.elf.elffile import ELFFile
from unicorn import UC_HOOK_BLOCK, Uc

from hil.mcu.elf_image import ElfImage
from protocol.errors import UserError


def line_table(path: Path) -> list[tuple[int, str, int]]:
    """(address, source file, line) of every statement row of the DWARF line table."""
    rows: list[tuple[int, str, int]] = []
    with open(path, "rb") as f:
        elf = ELFFile(f)
        if not elf.has_dwarf_info():
            raise UserError(f"coverage: {path} has no DWARF line table (build it with -g)",
                            params=("coverage",))
        dwarf = elf.get_dwarf_info()
        for cu in dwarf.iter_CUs():
            prog = dwarf.line_program_for_CU(cu)
            if prog is None:
                continue
            top = cu.get_top_DIE()
            comp = top.attributes.get("DW_AT_comp_dir")
            comp_dir = Path(comp.value.decode(errors="replace")) if comp else Path(".")
            dirs = [d.decode(errors="replace") if isinstance(d, bytes) else str(d)
                    for d in prog["include_directory"]]
            files = prog["file_entry"]
            v5 = prog.header["version"] >= 5
            for entry in prog.get_entries():
                st = entry.state
                if st is None or st.end_sequence or not st.is_stmt:
                    continue
                index = st.file if v5 else st.file - 1
                if not 0 <= index < len(files):
                    continue
                fe = files[index]
                name = fe.name.decode(errors="replace")
                d = fe.dir_index if v5 else fe.dir_index - 1
                base = Path(dirs[d]) if 0 <= d < len(dirs) else (comp_dir if v5 or
                                                                  fe.dir_index == 0 else Path("."))
                full = base / name
                if not full.is_absolute():
                    full = comp_dir / full
                rows.append((st.address, str(full), st.line))
    rows.sort()
    return rows


class LineCounter:
    """Counts the blocks ``uc`` runs; ``write`` turns them into LCOV for ``image``."""

    def __init__(self, image: ElfImage, uc: Uc) -> None:
        self.image = image
        self.blocks: Counter[tuple[int, int]] = Counter()
        uc.hook_add(UC_HOOK_BLOCK, self._block)

    def _block(self, uc: Uc, address: int, size: int, _: object) -> None:
        self.blocks[(address, size)] += 1

    def hits(self) -> dict[str, dict[int, int]]:
        rows = line_table(self.image.path)
        addrs = [r[0] for r in rows]
        out: dict[str, dict[int, int]] = {}
        for _, name, line in rows:
            out.setdefault(name, {}).setdefault(line, 0)
        for (address, size), n in self.blocks.items():
            lines = {(rows[i][1], rows[i][2])
                     for i in range(bisect.bisect_left(addrs, address),
                                    bisect.bisect_left(addrs, address + size))}
            for name, line in lines:
                out[name][line] += n
        return out

    def write(self, path: Path) -> None:
        try:
            path.write_text(lcov(self.hits()))
        except OSError as exc:
            raise UserError(f"coverage {path}: {exc.strerror}", params=("coverage",)) from None


def lcov(hits: dict[str, dict[int, int]]) -> str:
    """LCOV tracefile text of ``hits`` (file -> line -> count)."""
    out = ["TN:"]
    for name in sorted(hits):
        lines = hits[name]
        out.append(f"SF:{name}")
        out += [f"DA:{line},{lines[line]}" for line in sorted(lines)]
        out += [f"LF:{len(lines)}", f"LH:{sum(1 for n in lines.values() if n)}",
                "end_of_record"]
    return "\n".join(out) + "\n"


def merge(texts: list[str]) -> str:
    """One LCOV tracefile from several (``hexhil test`` over its cases): counts add."""
    hits: dict[str, dict[int, int]] = {}
    name = ""
    for text in texts:
        for row in text.splitlines():
            if row.startswith("SF:"):
                name = row[3:]
                hits.setdefault(name, {})
            elif row.startswith("DA:"):
                line, n = row[3:].split(",")[:2]
                hits[name][int(line)] = hits[name].get(int(line), 0) + int(n)
    return lcov(hits)
