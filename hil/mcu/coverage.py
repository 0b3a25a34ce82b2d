"""``--coverage FILE.info``: line coverage of the firmware's own sources, as LCOV.

Unicorn reports every basic block it runs (address, size), counted in C
(board_core.c ``bc_cover_block``); at the
end each block's executions are given to the lines the ELF's DWARF line table places in
it. Every line the table knows is listed, a line never run with 0, so genhtml or a CI
report shows what a scenario leaves untested. The firmware's own sources are those of its
build: the compilation units compiled in the directory ``main``'s was (a CubeMX Makefile's
project folder, with its Core/ and Drivers/), and in them the files under that directory
or named relative to it; the toolchain's libraries (newlib, libgcc: compiled elsewhere)
and its headers are left out unless ``libraries`` asks for them. Skipped waits
(hil/mcu/board.py) count the poll loop's lines once per pass run.
"""
from __future__ import annotations

import bisect
import ctypes
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
from elftools.elf.elffile import ELFFile
from unicorn import UC_HOOK_BLOCK, Uc

from hexhil.hil.mcu.board_core import library
from hexhil.hil.mcu.board_layout import LAYOUT
from hexhil.hil.mcu.elf_image import ElfImage
from hexhil.protocol.errors import BadFile, BadValue, UserError

_U64 = ctypes.c_uint64


class _Cover(ctypes.Structure):
    """board_core.c's ``cover_t`` (hil/mcu/board_layout.py)."""
    _fields_ = LAYOUT.fields("cover")


def line_table(path: Path, libraries: bool = False,
               main: int | None = None) -> list[tuple[int, str, int]]:
    """(address, source file, line) of every statement row of the DWARF line table: the
    firmware's own sources (those of ``main``'s build, at address ``main``), or every
    compilation unit's with ``libraries`` (or where ``main`` is not known)."""
    units: list[tuple[str, str, list[tuple[int, str, int]]]] = []
    with open(path, "rb") as f:
        elf = ELFFile(f)
        if not elf.has_dwarf_info():
            raise BadValue(f"coverage: {path} has no DWARF line table (build it with -g)",
                           params=("coverage",))
        dwarf = elf.get_dwarf_info()
        own_dir = None if libraries or main is None else _own_dir(dwarf, main)
        for cu in dwarf.iter_CUs():
            top = cu.get_top_DIE()
            comp_dir = _comp_dir(top)
            if own_dir is not None and str(comp_dir) != own_dir:
                continue             # another build's (a library's): its lines are not read
            prog = dwarf.line_program_for_CU(cu)
            if prog is None:
                continue
            primary = top.attributes.get("DW_AT_name")
            rows: list[tuple[int, str, int]] = []
            units.append((str(comp_dir), str(comp_dir / primary.value.decode(
                errors="replace")) if primary else "", rows))
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
    own = next((u for u in units if main is not None and any(r[0] == main for r in u[2])),
               None)
    out: list[tuple[int, str, int]] = []
    for comp_dir, primary, rows in units:
        if libraries or own is None:
            out += rows
        elif comp_dir == own[0]:
            out += [r for r in rows if r[1] == primary or _inside(r[1], comp_dir)]
    out.sort()
    return out


def _comp_dir(top: Any) -> Path:
    comp = top.attributes.get("DW_AT_comp_dir")
    return Path(comp.value.decode(errors="replace")) if comp else Path(".")


def _own_dir(dwarf: Any, main: int) -> str | None:
    """The compilation directory of the unit holding ``main`` (from .debug_aranges; None
    without them: then every unit's lines are read and the unit found by its rows)."""
    aranges = dwarf.get_aranges()
    offset = aranges.cu_offset_at_addr(main) if aranges is not None else None
    if offset is None:
        return None
    return str(_comp_dir(dwarf.get_CU_at(offset).get_top_DIE()))


def _inside(name: str, comp_dir: str) -> bool:
    """``name`` (a path the line table built on ``comp_dir``) lies in that directory."""
    rel = Path(name).relative_to(comp_dir) if Path(name).is_relative_to(comp_dir) else None
    return rel is not None and ".." not in rel.parts


class LineCounter:
    """Counts the blocks ``uc`` runs; ``write`` turns them into LCOV for ``image`` (its
    own sources, or with ``libraries`` the toolchain's libraries too)."""

    def __init__(self, image: ElfImage, uc: Uc, libraries: bool = False) -> None:
        self.image = image
        self.libraries = libraries
        lib = library()
        code = sum(len(seg.data) for seg in image.segments)
        slots = 1 << max(12, (2 * code).bit_length())     # a block holds 2 bytes or more
        self._keys, self._counts = (_U64 * slots)(), (_U64 * slots)()
        self._cover = _Cover(self._keys, self._counts, slots - 1, 0, 0)
        from unicorn.unicorn_py3.unicorn import uclib
        handle = ctypes.c_size_t(0)
        if uclib.uc_hook_add(uc._uch, ctypes.byref(handle), UC_HOOK_BLOCK,
                             ctypes.cast(lib.bc_cover_block, ctypes.c_void_p),
                             ctypes.addressof(self._cover), 1, 0):
            raise RuntimeError("libunicorn refused the compiled block hook")

    @property
    def blocks(self) -> Counter[tuple[int, int]]:
        """How often each (address, size) block ran."""
        if self._cover.lost:
            raise UserError(f"coverage: {self._cover.lost} blocks found no room in the "
                            "count table", params=("coverage",))
        keys, counts = np.ctypeslib.as_array(self._keys), np.ctypeslib.as_array(self._counts)
        used = np.nonzero(keys)[0]
        return Counter({(int(key - 1) >> 32, int(key - 1) & 0xFFFFFFFF): int(n)
                        for key, n in zip(keys[used], counts[used])})

    def hits(self) -> dict[str, dict[int, int]]:
        main = self.image.symbols.get("main")
        rows = line_table(self.image.path, self.libraries,
                          None if main is None else main & ~1)
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
            raise BadFile(f"coverage {path}: {exc.strerror}", params=("coverage",)) from None


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
