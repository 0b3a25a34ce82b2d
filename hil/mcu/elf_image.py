"""An STM32F411 ELF, read and checked before a single instruction runs.

What the core needs from the file: the bytes each loadable segment puts in flash or SRAM
(at its load address, as a programmer writes them), the vector table at the start of
flash (initial SP, reset vector), the function symbols (a fault names the function) and
the file itself for the DWARF line table (hil/mcu/coverage.py). A file that cannot be that
firmware is one ``UserError`` line: truncated, another architecture or class, no
loadable segment, nothing at the vector table, a reset vector outside flash, a segment
outside flash and SRAM (over the peripherals, say).
"""
from __future__ import annotations

import bisect
import io
import struct
from dataclasses import dataclass
from pathlib import Path

from elftools.common.exceptions import ELFError
from elftools.elf.elffile import ELFFile

from hexhil.protocol.errors import BadFile, BadValue, UserError

ELF_MAGIC = b"\x7fELF"
EM_ARM = 40
FLASH_BASE, FLASH_SIZE = 0x08000000, 512 * 1024     # RM0383 2.3: 512 KB main flash
SRAM_BASE, SRAM_SIZE = 0x20000000, 128 * 1024       # 128 KB SRAM
MAX_FILE_BYTES = 64 * 1024 * 1024                   # an ELF this large is not an F411's


def is_arm_elf(path: str | Path) -> bool:
    """The header says ELF, 32-bit, ARM: the file is meant for the emulated board."""
    try:
        with open(path, "rb") as f:
            head = f.read(20)
    except OSError:
        return False
    return (len(head) >= 20 and head[:4] == ELF_MAGIC and head[4] == 1
            and int.from_bytes(head[18:20], "little" if head[5] == 1 else "big") == EM_ARM)


@dataclass(frozen=True)
class Segment:
    addr: int
    data: bytes


@dataclass(frozen=True)
class ElfImage:
    path: Path
    segments: tuple[Segment, ...]
    initial_sp: int
    reset: int
    entry_names: tuple[str, ...]        # function names, sorted by address with ...
    entry_starts: tuple[int, ...]       # ... their start addresses
    entry_ends: tuple[int, ...]
    symbols: dict[str, int]             # every named symbol's value (stack limits, main)

    def function_at(self, pc: int) -> str:
        """The function holding ``pc`` (``?`` where no symbol covers it)."""
        pc &= ~1
        i = bisect.bisect_right(self.entry_starts, pc) - 1
        if i >= 0 and pc < self.entry_ends[i]:
            return self.entry_names[i]
        return "?"


def _inside(addr: int, size: int, base: int, span: int) -> bool:
    return base <= addr and addr + size <= base + span


def load_elf(path: str | Path, what: str = "firmware") -> ElfImage:
    """Read and check ``path`` (``UserError`` naming ``what`` and the problem)."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise BadFile(f"{what} {path}: {exc.strerror}", params=(what,)) from None
    if len(raw) > MAX_FILE_BYTES:
        raise BadValue(f"{what} {path}: {len(raw)} bytes, too large for an STM32F411 ELF", params=(what,))
    if raw[:4] != ELF_MAGIC:
        raise BadValue(f"{what} {path}: not an ELF file", params=(what,))
    try:
        return _read(p, raw, what)
    except UserError:   # _read's own line (a BadValue is a ValueError too)
        raise
    except (ELFError, ValueError, KeyError, IndexError, AssertionError, TypeError,
            AttributeError, OverflowError, RecursionError, UnicodeDecodeError) as exc:
        raise BadValue(f"{what} {path}: a broken ELF file ({type(exc).__name__}: "
                       f"{str(exc)[:80]})", params=(what,)) from None
    except Exception as exc:    # construct.StreamError and kin: a truncated file
        if type(exc).__module__.startswith(("elftools", "construct")):
            raise BadValue(f"{what} {path}: a truncated or broken ELF file "
                           f"({str(exc)[:80]})", params=(what,)) from None
        raise


def _read(p: Path, raw: bytes, what: str) -> ElfImage:
    elf = ELFFile(io.BytesIO(raw))
    name = f"{what} {p}"
    if elf.elfclass != 32 or elf["e_machine"] != "EM_ARM" or not elf.little_endian:
        raise BadValue(f"{name}: an ELF for {elf['e_machine']} ({elf.elfclass}-bit), not "
                       "a 32-bit little-endian ARM (Cortex-M4) one", params=(what,))
    if elf["e_type"] != "ET_EXEC":
        raise BadValue(f"{name}: not a linked executable ({elf['e_type']}): link it with a "
                       "linker script for the F411 (the C SDK's stm32f411 target links one)", params=(what,))
    segments: list[Segment] = []
    for seg in elf.iter_segments():
        if seg["p_type"] != "PT_LOAD" or seg["p_filesz"] == 0:
            continue
        addr, size = seg["p_paddr"], seg["p_filesz"]
        data = seg.data()
        if len(data) != size:
            raise BadValue(f"{name}: truncated (a segment at 0x{addr:08x} holds "
                           f"{len(data)} of its {size} bytes)", params=(what,))
        if not (_inside(addr, size, FLASH_BASE, FLASH_SIZE)
                or _inside(addr, size, SRAM_BASE, SRAM_SIZE)):
            raise BadValue(f"{name}: a segment of {size} bytes at 0x{addr:08x} lies outside "
                           f"flash (0x{FLASH_BASE:08x}, 512 KB) and SRAM (0x{SRAM_BASE:08x}, "
                           "128 KB): over the peripherals or nothing", params=(what,))
        segments.append(Segment(addr, data))
    if not segments:
        raise BadValue(f"{name}: no loadable segment (nothing to put in flash)", params=(what,))
    vectors = next((s for s in segments if s.addr == FLASH_BASE and len(s.data) >= 8), None)
    if vectors is None:
        raise BadValue(f"{name}: no vector table at the start of flash (0x{FLASH_BASE:08x}): "
                       "the startup file's .isr_vector must come first", params=(what,))
    sp = int.from_bytes(vectors.data[0:4], "little")
    reset = int.from_bytes(vectors.data[4:8], "little")
    if not _inside(reset & ~1, 2, FLASH_BASE, FLASH_SIZE) or not reset & 1:
        raise BadValue(f"{name}: the reset vector 0x{reset:08x} is not a Thumb address in "
                       "flash", params=(what,))
    if not _inside(sp - 4, 4, SRAM_BASE, SRAM_SIZE):
        raise BadValue(f"{name}: the initial stack pointer 0x{sp:08x} is not in SRAM", params=(what,))
    return ElfImage(p, tuple(segments), sp, reset, *_functions(elf, raw))


STT_FUNC, STB_WEAK = 2, 2
_SYM = struct.Struct("<IIIBBH")                     # Elf32_Sym, little-endian


def _functions(elf: ELFFile, raw: bytes) -> tuple[tuple[str, ...], tuple[int, ...],
                                                  tuple[int, ...], dict[str, int]]:
    """The symbol table read with one struct over the file's bytes (pyelftools parses each
    symbol through construct: a MicroPython ELF's 9,000 symbols took 0.2 s), each name as
    pyelftools reads it: from the string table to the next NUL byte, UTF-8 with
    replacement, empty where no NUL follows."""
    funcs: list[tuple[int, int, int, str]] = []
    symbols: dict[str, int] = {}
    tab = elf.get_section_by_name(".symtab")
    if tab is not None:
        off, size, step = tab["sh_offset"], tab["sh_size"], tab["sh_entsize"]
        strtab = tab.stringtable["sh_offset"]
        if size and off + size - step + _SYM.size > len(raw):
            raise ELFError(f"the symbol table ({size} bytes at {off}) runs past the file's end")
        for at in range(off, off + size, step):      # pyelftools checked size and step
            name_at, value, sym_size, info, _other, _shndx = _SYM.unpack_from(raw, at)
            end = raw.find(b"\0", strtab + name_at)
            if end <= strtab + name_at:
                continue
            name = raw[strtab + name_at:end].decode("utf-8", errors="replace")
            symbols.setdefault(name, value)
            if info & 0xF == STT_FUNC and value:
                start = value & ~1
                weak = info >> 4 == STB_WEAK              # an alias: Default_Handler wins
                funcs.append((start, not weak, start + max(2, sym_size), name))
    funcs.sort()                 # function_at takes the last of those at one address
    return (tuple(f[3] for f in funcs), tuple(f[0] for f in funcs),
            tuple(f[2] for f in funcs), symbols)
