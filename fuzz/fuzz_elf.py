"""The STM32F411 ELF loader (hil/mcu/elf_image.py) on mutated ELFs: every mutant gives a
one-line UserError or loads, never another exception. The seed ELF is built here byte by
byte (a vector table, a Thumb function, a symbol table), so the target needs no toolchain."""
from __future__ import annotations

import random
import struct
import tempfile
from pathlib import Path

from fuzz.fuzz_trace import mutate
from fuzz.tally import Budget, Tally
from hexhil.hil.mcu.elf_image import load_elf
from hexhil.protocol.errors import UserError

FLASH = 0x08000000


def sample_elf() -> bytes:
    """A linked Cortex-M4 ELF: one PT_LOAD in flash (SP, reset vector, ``b .``), with
    .text, .symtab, .strtab and .shstrtab sections."""
    text = struct.pack("<II", 0x20020000, FLASH + 9) + b"\xfe\xe7\x00\xbf"
    strtab = b"\0Reset_Handler\0"
    symtab = bytes(16) + struct.pack("<IIIBBH", 1, FLASH + 9, 4, 0x12, 0, 1)
    shstr = b"\0.text\0.symtab\0.strtab\0.shstrtab\0"
    off_text = 52 + 32
    off_sym = off_text + len(text)
    off_str = off_sym + len(symtab)
    off_shs = off_str + len(strtab)
    off_sh = off_shs + len(shstr)
    off_sh += -off_sh % 4
    head = b"\x7fELF\x01\x01\x01" + bytes(9) + struct.pack(
        "<HHIIIIIHHHHHH", 2, 40, 1, FLASH + 9, 52, off_sh, 0x05000400, 52, 32, 1, 40, 5, 4)
    phdr = struct.pack("<IIIIIIII", 1, off_text, FLASH, FLASH, len(text), len(text), 5, 4)
    sections = [bytes(40),
                struct.pack("<10I", 1, 1, 6, FLASH, off_text, len(text), 0, 0, 4, 0),
                struct.pack("<10I", 7, 2, 0, 0, off_sym, len(symtab), 3, 1, 4, 16),
                struct.pack("<10I", 15, 3, 0, 0, off_str, len(strtab), 0, 0, 1, 0),
                struct.pack("<10I", 23, 3, 0, 0, off_shs, len(shstr), 0, 0, 1, 0)]
    body = head + phdr + text + symtab + strtab + shstr
    return body + bytes(off_sh - len(body)) + b"".join(sections)


def run(seed: int, budget_s: float | None, limit: int | None) -> list[Tally]:
    rng = random.Random(seed)
    tally = Tally("STM32F411 ELF loader", "files")
    budget = Budget(budget_s, limit)
    base = sample_elf()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "mutant.elf"
        path.write_bytes(base)
        load_elf(path)                      # the seed itself loads
        while budget.more(tally.inputs):
            tally.inputs += 1
            data = base
            for _ in range(rng.randrange(1, 4)):
                data = mutate(rng, data) or b"\x7fELF"
            path.write_bytes(data)
            try:
                image = load_elf(path)
                image.function_at(image.reset)
            except UserError as exc:
                if "\n" in str(exc):
                    tally.escape(f"file {tally.inputs}: UserError over several lines: {exc!r}")
                tally.notes["refused"] = tally.notes.get("refused", 0) + 1
            except Exception as exc:    # an escape is what the fuzzer is for
                tally.escape(f"file {tally.inputs}: {exc.__class__.__name__}: {exc}")
    tally.wall_s = budget.elapsed_s()
    return [tally]
